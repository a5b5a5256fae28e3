"""Options of ``feedback_linearization`` (spec/method_options/control.py): the outer loop
needs exactly one of ``poles`` / ``bandwidth``, and the message says which mistake was made.
(Named ``test_control_options`` so as not to clash with tests/design/test_control.py.)"""

from __future__ import annotations

import pytest

from tanksynth.errors import SpecError
from tanksynth.methods import parse_spec_text

_SPEC = """
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "fl"
method = "feedback_linearization"
"""


@pytest.mark.parametrize("extra, says", [("", "neither is given"),
                                         ("poles = [-0.1, -0.1]\nbandwidth = 0.1\n", "not both")])
def test_outer_loop_needs_poles_or_bandwidth(extra, says):
    with pytest.raises(SpecError, match=says) as info:
        parse_spec_text(_SPEC + extra)
    assert info.value.key == "design[0].poles"


def test_bandwidth_alone_is_accepted():
    assert parse_spec_text(_SPEC + "bandwidth = 0.1\n").designs[0].method == "feedback_linearization"
