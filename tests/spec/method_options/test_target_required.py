"""Issue 30 item 7: a method that designs both a state feedback and an observer has no default
``target`` (``lmi_placement`` defaulted to the observer, ``pole_placement`` to the state feedback):
a spec says which, and a misspelt one gets a "did you mean"."""

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
#: Each method's other required options (the documented TOML form).
OPTIONS = {"pole_placement": "poles = [0.90, 0.91, 0.92]\n",
           "lmi_placement": 'region = [{type = "disk", center = 0.9, radius = 0.08}]\n',
           "multiobjective": 'region = [{type = "disk", center = 0.9, radius = 0.08}]\n'}
#: The rows whose kinds are both a controller and an observer (read from the table itself).
BOTH = sorted(name for name, row in METHODS.items()
              if {"controller", "observer"} <= set(row.kinds))


def test_the_methods_that_design_both_are_the_ones_tested():
    assert BOTH == sorted(OPTIONS)


@pytest.mark.parametrize("method", BOTH)
def test_target_is_required_where_a_method_designs_both(method):
    assert "target" in METHODS[method].options.required()
    with pytest.raises(SpecError) as info:
        parse_spec_text(HEAD + f'method = "{method}"\n' + OPTIONS[method])
    assert info.value.key == "design[0].target"
    assert "missing option 'target'" in str(info.value)
    assert "'state_feedback'" in str(info.value) and "'observer'" in str(info.value)


@pytest.mark.parametrize("method", BOTH)
def test_a_misspelt_target_gets_a_did_you_mean(method):
    with pytest.raises(SpecError) as info:
        parse_spec_text(HEAD + f'method = "{method}"\ntarget = "observr"\n' + OPTIONS[method])
    assert info.value.key == "design[0].target"
    assert "did you mean 'observer'" in str(info.value)


@pytest.mark.parametrize("method", BOTH)
@pytest.mark.parametrize("target", ["state_feedback", "observer"])
def test_either_target_written_is_kept(method, target):
    spec = parse_spec_text(HEAD + f'method = "{method}"\ntarget = "{target}"\n' + OPTIONS[method])
    assert spec.designs[0].config.target == target
