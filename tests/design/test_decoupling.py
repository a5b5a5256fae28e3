"""Input-output decoupling analysis: square plants, relative degrees, rank of Lambda (bad input)."""

from __future__ import annotations

import pytest

from tanksynth.design.laws.decoupling import decoupling_analysis, select_outputs
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError
from tanksynth.plants import three_tank
from tanksynth.plants.custom import custom_plant


@pytest.fixture(scope="module")
def tank():
    return three_tank(outputs="all")


# ------------------------------------------------------------------ bad input
def custom(equations, outputs, states=("x1", "x2")):
    return custom_plant({
        "model": "custom", "name": "bad",
        "states": {s: {"unit": "m", "min": 0.0, "max": 0.6} for s in states},
        "inputs": {u: {"unit": "m^3/s", "min": 0.0, "max": 1e-4} for u in ("u1", "u2")},
        "parameters": {"A": {"value": 0.0154, "unit": "m^2", "min": 0.0}},
        "equations": equations,
        "outputs": {k: {"expr": v, "unit": "m"} for k, v in outputs.items()}})


def test_more_outputs_than_inputs(tank):
    with pytest.raises(DimensionError, match=r"more outputs than inputs: 3 outputs \['h1', 'h2', 'h3'\] "
                                             r"but only 2 inputs"):
        decoupling_analysis(tank)


def test_fewer_outputs_than_inputs():
    with pytest.raises(DimensionError, match="fewer outputs than inputs"):
        decoupling_analysis(three_tank(outputs="h1"))


def test_unknown_output(tank):
    with pytest.raises(SpecError, match="unknown output 'h9'"):
        select_outputs(tank, ["h1", "h9"])


def test_relative_degree_undefined():
    plant = custom({"x1": "(u1 + u2)/A - x1", "x2": "-x2", "x3": "u2/A - x3"},
                   {"y1": "x1", "y2": "x2"}, states=("x1", "x2", "x3"))
    with pytest.raises(InfeasibleDesign, match=r"relative degree of output 2 \(x2\) is undefined: it does "
                                               r"not depend on the inputs at any order up to n = 3; .*"
                                               r"everywhere"):
        decoupling_analysis(plant)


def test_not_decouplable_identically():
    plant = custom({"x1": "(u1 + u2)/A - sqrt(x1)", "x2": "sqrt(x1) - sqrt(x2)"},
                   {"y1": "x1", "y2": "x2"})
    with pytest.raises(InfeasibleDesign, match=r"not decouplable: det Lambda\(x\) = 0 identically "
                                               r"\(rank Lambda < m = 2 everywhere"):
        decoupling_analysis(plant)


def test_not_decouplable_on_a_surface_named():
    plant = custom({"x1": "u1/A - x1", "x2": "(x1 - 0.31)*u2/A - x2"}, {"y1": "x1", "y2": "x2"})
    with pytest.raises(InfeasibleDesign, match=r"det Lambda\(x\) changes sign.*surface through "
                                               r"x = \(x1 = 0\.31, ") as info:
        decoupling_analysis(plant)
    assert "(x1 - 31/100)/A**2" in str(info.value)


def test_relative_degree_not_defined_at_a_point_named():
    plant = custom({"x1": "u1/A - x1", "x2": "(x1 - 0.3)**2*u2/A - x2"}, {"y1": "x1", "y2": "x2"})
    with pytest.raises(InfeasibleDesign, match=r"relative degree of output y2 is not defined at "
                                               r"x = \(x1 = 0\.3, "):
        decoupling_analysis(plant)
