"""Issue 30 item 4: the operating point asks for trim in the spec, and an operating point that is
not an equilibrium names the nearest one and the line that uses it.

Reference: Johansson's quadruple tank solved by hand. At steady state each outlet passes what
flows in, ``a_i sqrt(2 g h_i) = inflow_i``:
tank 3 gets ``(1 - gamma2) k2 v2``, tank 4 ``(1 - gamma1) k1 v1``, tank 1
``gamma1 k1 v1 + a3 sqrt(2 g h3)`` and tank 2 ``gamma2 k2 v2 + a4 sqrt(2 g h4)``,
so ``h_i = (inflow_i / a_i)^2 / (2 g)``; with the outputs ``y = kc (h1, h2)`` given, the two
lower balances are linear in ``(v1, v2)``.
"""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.analysis.checks import equilibrium_checks
from tanksynth.analysis.linearize import equilibrium_input
from tanksynth.errors import SpecError
from tanksynth.methods import parse_spec_text

# Johansson (2000), minimum-phase setting P-: cm, s, V
A_OUT = {"a1": 0.071, "a2": 0.057, "a3": 0.071, "a4": 0.057}
GAMMA1, GAMMA2, K1, K2, G, KC = 0.7, 0.6, 3.33, 3.35, 981.0, 0.5


def _levels(v1: float, v2: float) -> np.ndarray:
    q3 = (1 - GAMMA2) * K2 * v2
    q4 = (1 - GAMMA1) * K1 * v1
    inflow = (GAMMA1 * K1 * v1 + q3, GAMMA2 * K2 * v2 + q4, q3, q4)
    return np.array([(q / a) ** 2 / (2 * G) for q, a in zip(inflow, A_OUT.values())])


def _inputs_for_outputs(y1: float, y2: float) -> np.ndarray:
    out1 = A_OUT["a1"] * np.sqrt(2 * G * y1 / KC)
    out2 = A_OUT["a2"] * np.sqrt(2 * G * y2 / KC)
    M = np.array([[GAMMA1 * K1, (1 - GAMMA2) * K2],
                  [(1 - GAMMA1) * K1, GAMMA2 * K2]])
    return np.linalg.solve(M, [out1, out2])


HEAD = """
title = "quadruple tank, trimmed"
[plant]
model = "tank_network"
N = 4
parameter_set = "johansson_min_phase"
[operating_point]
{op}
[sampling]
ts = 1.0
[[design]]
name = "lin"
method = "linearize"
"""
PUBLISHED = "x = {h1 = 12.4, h2 = 12.7, h3 = 1.8, h4 = 1.4}"


def test_trim_states_solves_the_levels_of_the_given_inputs():
    spec = parse_spec_text(HEAD.format(op='u = {u1 = 3.0, u2 = 3.0}\ntrim = "states"'))
    np.testing.assert_allclose(spec.x0, _levels(3.0, 3.0), rtol=1e-8)
    np.testing.assert_allclose(spec.given_u0, [3.0, 3.0])
    assert spec.trim is not None and spec.trim.converged
    # the published levels kept as the solver's start reach the same equilibrium
    started = parse_spec_text(HEAD.format(op=PUBLISHED + '\nu = {u1 = 3.0, u2 = 3.0}\ntrim = "states"'))
    np.testing.assert_allclose(started.x0, _levels(3.0, 3.0), rtol=1e-8)
    eq = equilibrium_input(spec.plant, spec.x0, spec.given_u0)
    assert eq.is_equilibrium


def test_trim_inputs_solves_inputs_and_free_levels_from_the_outputs():
    y1, y2 = 6.2, 6.4
    spec = parse_spec_text(HEAD.format(op=f'y = {{y1 = {y1}, y2 = {y2}}}\ntrim = "inputs"'))
    v = _inputs_for_outputs(y1, y2)
    np.testing.assert_allclose(spec.given_u0, v, rtol=1e-7)
    np.testing.assert_allclose(spec.x0, _levels(*v), rtol=1e-7)
    np.testing.assert_allclose(KC * spec.x0[:2], [y1, y2], rtol=1e-9)


def test_published_levels_name_the_nearest_equilibrium_and_the_spec_line():
    spec = parse_spec_text(HEAD.format(op=PUBLISHED + "\nu = {u1 = 3.0, u2 = 3.0}"))
    check = next(c for c in equilibrium_checks(spec.plant, equilibrium_input(spec.plant, spec.x0,
                                                                             spec.given_u0))
                 if c.name == "equilibrium")
    assert not check.passed
    assert "nearest equilibrium for these inputs" in check.detail
    assert 'trim = "states"' in check.detail
    for name, h in zip(("h1", "h2", "h3", "h4"), _levels(3.0, 3.0)):
        assert f"{name} = {h:.6g} cm" in check.detail, check.detail


@pytest.mark.parametrize("op, key, says", [
    ('trim = "states"', "operating_point.u", "give u"),
    ('u = {u1 = 3.0, u2 = 3.0}\ny = {y1 = 6.0, y2 = 6.0}', "operating_point.y", 'trim = "inputs"'),
    ('u = {u1 = 3.0, u2 = 3.0}\ntrim = "inputs"', "operating_point.u", "remove u"),
    ('u = {u1 = 3.0, u2 = 3.0}\ntrim = "level"', "operating_point.trim", "'states'"),
    # not a string (found by the spec fuzzer: an internal error, unhashable list)
    ('u = {u1 = 3.0, u2 = 3.0}\ntrim = []', "operating_point.trim", "'states'"),
    ('u = {u1 = 3.0, u2 = 3.0}\ntrim = {a = 1}', "operating_point.trim", "'states'"),
    # 9.9 V on both pumps: tank 1 would settle above the region's 20 cm
    ('u = {u1 = 9.9, u2 = 9.9}\ntrim = "states"', "operating_point.trim", "no equilibrium inside"),
    ('y = {y1 = 12.0, y2 = 12.0}\ntrim = "inputs"', "operating_point.trim", "no equilibrium inside"),
])
def test_trim_refusals_name_the_key(op, key, says):
    with pytest.raises(SpecError, match=says) as info:
        parse_spec_text(HEAD.format(op=op))
    assert info.value.key == key


def test_unreachable_inputs_are_out_of_the_region_by_hand():
    assert _levels(9.9, 9.9)[0] > 20.0
    # y = 12 V is h = 24 cm, above the region's 20 cm
    assert 12.0 / KC > 20.0
