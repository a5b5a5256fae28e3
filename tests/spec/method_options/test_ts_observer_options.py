"""Options of ``ts_observer``: the LMI structure (blocks, gain pattern) is checked with the
other options, so a bad one is a spec error naming its key before any design runs (it was a
DimensionError raised by the solver set-up, keyed only ``design[i]``)."""

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
[[design]]
name = "obs"
method = "ts_observer"
psi = 0.05
"""


def _parse(extra: str):
    return parse_spec_text(_SPEC + extra)


@pytest.mark.parametrize("extra, key, match", [
    ('pattern = [[1, 0], [0, 1], [1, 0]]\n', "pattern", "needs blocks"),
    ('blocks = [["h1", "h3"], ["h2"]]\npattern = [[1, 0], [0, 1], [0, 0]]\n', "pattern",
     r"rows differ inside block \['h1', 'h3'\]"),
    ('blocks = [["h1", "h3"], ["h2"]]\npattern = [[1, 0], [0, 0.5], [1, 0]]\n', "pattern", "0/1"),
    ('blocks = [["h1"], ["h2"]]\n', "blocks", "partition"),
    ('blocks = [["h1", "h3"], ["h2", "h1"]]\n', "blocks", "partition"),
])
def test_bad_structure_is_a_spec_error_on_its_key(extra, key, match):
    with pytest.raises(SpecError, match=match) as info:
        _parse(extra)
    assert info.value.key == f"design[0].{key}"


def test_good_structures_are_kept():
    spec = _parse('blocks = [["h1", "h3"], ["h2"]]\npattern = [[1, 0], [0, 1], [1, 0]]\n')
    opts = spec.designs[0].config
    assert opts.blocks == (("h1", "h3"), ("h2",))
    assert opts.pattern.tolist() == [[1, 0], [0, 1], [1, 0]]
    assert _parse('pattern = [[1, 1], [1, 1], [1, 1]]\n').designs[0].config.blocks is None
