"""Issue 30: a spec missing several required options was refused one option per run; now one
line names every missing required option (with the choices of a choice option)."""

from __future__ import annotations

import pytest

from tanksynth.errors import SpecError
from tanksynth.methods import METHODS, parse_spec_text

HEAD = """
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "d"
"""


def test_every_missing_option_in_one_line():
    required = METHODS["lmi_placement"].options.required()
    assert {"target", "region"} <= set(required)
    with pytest.raises(SpecError) as info:
        parse_spec_text(HEAD + 'method = "lmi_placement"\n')
    text = str(info.value)
    assert "\n" not in text
    assert "missing options" in text
    for name in required:
        assert repr(name) in text, name
    choices = text.split("target: one of ")[1]
    assert "'state_feedback'" in choices and "'observer'" in choices
    assert info.value.key == f"design[0].{required[0]}"


def test_one_missing_option_keeps_its_message():
    with pytest.raises(SpecError) as info:
        parse_spec_text(HEAD + 'method = "lmi_placement"\ntarget = "observer"\n')
    assert "missing option 'region'" in str(info.value) and info.value.key == "design[0].region"
