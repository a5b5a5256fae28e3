"""Units of the printed gains (issue 30, item 9): K in input per state units, L in state per
output units (per second in continuous time), derived from the plant's signal units."""

from __future__ import annotations

import dataclasses

import numpy as np

from tanksynth.methods import STATEMENTS
from tanksynth.plants import BUILTIN_PLANTS
from tanksynth.reports.designs import design_view
from tanksynth.reports.gain_units import gain_unit, unit_ratio
from tanksynth.reports.latex import environment


def _plant_table(name: str) -> dict:
    """The plant record's ``plant`` table (signals with units) of a built-in plant."""
    plant = BUILTIN_PLANTS[name]()
    return {key: [dataclasses.asdict(q) for q in getattr(plant, key)]
            for key in ("states", "inputs", "outputs")}


def test_three_tank_gain_units_by_hand():
    table = _plant_table("three_tank")   # levels h in m, pump flows q in m^3/s, y = h in m
    assert gain_unit("K", table, None) == "(m^3/s)/m"
    assert gain_unit("L", table, False) == "m/m"            # per sample
    assert gain_unit("L", table, True) == "m/(m s)"         # per second
    assert gain_unit("L", table, None) is None              # time domain unknown: no unit
    assert gain_unit("Q", table, False) is None


def test_mixed_or_dimensionless_units():
    mixed = {"states": [{"unit": "m"}, {"unit": "V"}], "inputs": [{"unit": "V"}]}
    assert gain_unit("K", mixed, None) is None              # no single unit: none printed
    assert unit_ratio("V", "cm") == "V/cm"
    assert unit_ratio("1", "1") == "1"
    assert unit_ratio("1", "s") == "1/s"


def test_rendered_design_prints_the_unit_beside_K():
    art = {"name": "lqr", "method": "lqr", "gains": {"K": np.array([[1.0, 2.0, 3.0],
                                                                    [4.0, 5.0, 6.0]])},
           "diagnostics": {"time_domain": "discrete"}}
    view = design_view(art, None, STATEMENTS, _plant_table("three_tank"))
    (k,) = view.gains
    tex = str(environment().from_string(
        '((* from "macros.tex.j2" import gain *))((( gain(g)|tex )))').render(g=k))
    assert r"\text{in $(\mathrm{m}^{3}/\mathrm{s})/\mathrm{m}$}" in tex
    assert tex.index("K") < tex.index(r"\text{in ")


def test_integral_gain_has_no_single_unit():
    """Issue 30 (new-user pass): ``K = [K1 K2]`` of integral action printed "in V/cm" although
    ``K2`` acts on the integrated output error (V/(cm s) here): no unit line rather than a wrong one."""
    table = _plant_table("three_tank")
    assert gain_unit("K", table, None, columns=3) == "(m^3/s)/m"
    assert gain_unit("K", table, None, columns=5) is None
    art = {"name": "pi", "method": "pole_placement", "gains": {"K": np.ones((2, 5))},
           "diagnostics": {"time_domain": "discrete"}}
    view = design_view(art, None, STATEMENTS, table)
    assert [g.unit for g in view.gains if g.name == "K"] == [""], view.gains
