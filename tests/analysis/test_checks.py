"""Issue 12 items 9-11: what the rank verdicts of `tanksynth check` say."""

from __future__ import annotations

from pathlib import Path

import pytest
import numpy as np
import sympy as sp

from tanksynth.analysis.checks import rank_conditions
from tanksynth.methods import parse_spec_text

UNOBSERVABLE = """
title = "x2 is invisible"
[plant]
model = "custom"
[plant.states]
x1 = {unit = "m", min = 0.0, max = 1.0}
x2 = {unit = "m", min = 0.0, max = 1.0}
[plant.inputs]
u = {unit = "m/s", min = -1.0, max = 1.0}
[plant.parameters]
a = {value = 1.0, unit = "1/s", min = 0.0}
[plant.equations]
x1 = "-a*x1 + u"
x2 = "-2*x2 + u"
[plant.outputs]
y = "x1"
[operating_point]
x = [0.5, 0.25]
"""

# DTS200 three-tank measuring the middle tank h3 (seed 000 Table I values).
DTS200_H3 = """
title = "DTS200 measuring h3"
[plant]
model = "custom"
orderings = ["h1 > h3", "h3 > h2"]
[plant.states]
h1 = {unit = "m", min = 0.0, max = 0.62}
h2 = {unit = "m", min = 0.0, max = 0.62}
h3 = {unit = "m", min = 0.0, max = 0.62}
[plant.inputs]
q1 = {unit = "m^3/s", min = 0.0, max = 1.2e-4}
q2 = {unit = "m^3/s", min = 0.0, max = 1.2e-4}
[plant.parameters]
A = {value = 0.0154, unit = "m^2", min = 0.0}
Phi = {value = 5e-5, unit = "m^2", min = 0.0}
g = {value = 9.81, unit = "m/s^2", min = 0.0}
[plant.equations]
h1 = "(q1 - 0.5*Phi*sqrt(2*g*(h1 - h3)))/A"
h2 = "(q2 + 0.5*Phi*sqrt(2*g*(h3 - h2)) - 0.675*Phi*sqrt(2*g*h2))/A"
h3 = "(0.5*Phi*sqrt(2*g*(h1 - h3)) - 0.5*Phi*sqrt(2*g*(h3 - h2)))/A"
[plant.outputs]
y = {expr = "h3", unit = "m"}
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
"""


def _checks(text, **kw):
    spec = parse_spec_text(text)
    return {c.name: c for c in rank_conditions(spec.plant, spec.x0, spec.ts, spec.given_u0, **kw)}


def test_structurally_unobservable_plant_is_named():
    """Item 9: det O is identically zero, whatever a is; the message says so and names x2."""
    a, s = sp.symbols("a s")
    O = sp.Matrix([[1, 0], [-a, 0]])                 # [C; C A] with C = [1 0], A = diag(-a, -2)
    assert sp.simplify(O.det()) == 0
    c = _checks(UNOBSERVABLE)
    sym = c["symbolic_observability"]
    assert "unobservable for every parameter value" in sym.detail and "x2" in sym.detail
    assert "no parameter values make" not in sym.detail
    nl = c["nonlinear_observability"]
    assert nl.passed is False and "unobservable direction there in x2" in nl.detail


@pytest.mark.slow
def test_equilibrium_verdict_names_tolerance_equation_and_bounds():
    """Item 10."""
    c = _checks(DTS200_H3.replace("h3 = 0.30}", "h3 = 0.25}"))
    eq = c["equilibrium"]
    assert eq.passed is False and "tolerance" in eq.detail and "dh3/dt" in eq.detail
    # independent: no input enters tank 3 and q13 != q32 at (0.40, 0.20, 0.25)
    dh3 = 0.5 * 5e-5 * (np.sqrt(2 * 9.81 * 0.15) - np.sqrt(2 * 9.81 * 0.05)) / 0.0154
    assert f"{dh3:.3g}" in eq.detail
    ok = _checks(DTS200_H3.replace("max = 1.2e-4}\nq2", "max = 1e-5}\nq2"))
    bounds = ok["equilibrium_input_bounds"]
    assert bounds.passed is False and "q1" in bounds.detail and "VIOLATED" in bounds.detail


@pytest.mark.slow
def test_region_rank_verdict_finds_the_singular_surface():
    """Item 11: rank 3 at every sampled point, yet det d(L_f^k h) vanishes on a surface of
    the region (through (0.4254, 0.2, 0.3))."""
    c = _checks(DTS200_H3)
    nl = c["nonlinear_observability"]
    assert "rank 3 at 200 sampled points" in nl.detail
    zeros = nl.data["determinant_zeros"]
    assert zeros["meets_region"] and nl.passed is False
    # independent (sympy, written here): the codistribution d(h, L_f h, L_f^2 h) at the input the
    # check uses (middle of the pump range, 6e-5 m^3/s each) is singular at h1 = 0.4254 on the
    # line (h2, h3) = (0.2, 0.3): its determinant changes sign there
    h1, h2, h3 = sp.symbols("h1 h2 h3", positive=True)
    q = sp.Float(6e-5)
    k = 5e-5 * sp.sqrt(2 * 9.81) / 0.0154
    f = sp.Matrix([q / 0.0154 - 0.5 * k * sp.sqrt(h1 - h3),
                   q / 0.0154 + 0.5 * k * sp.sqrt(h3 - h2) - 0.675 * k * sp.sqrt(h2),
                   0.5 * k * sp.sqrt(h1 - h3) - 0.5 * k * sp.sqrt(h3 - h2)])
    x = sp.Matrix([h1, h2, h3])
    L = [h3]
    for _ in range(2):
        L.append((sp.Matrix([L[-1]]).jacobian(x) * f)[0])
    det = sp.lambdify((h1, h2, h3), sp.Matrix(L).jacobian(x).det())
    assert det(0.425, 0.2, 0.3) * det(0.426, 0.2, 0.3) < 0
    # every zero the check reports is a point where this determinant vanishes (sign change
    # within 0.1 % of the point along h1)
    for z in zeros["zeros"][:5]:
        a, b, c = z
        assert det(a * 0.999, b, c) * det(a * 1.001, b, c) <= 0 or abs(det(a, b, c)) < 1e-12


def test_kalman_detail_names_the_blocks_that_decide():
    """Both states measured: observability is decided by C alone and the detail says so; the
    controllability of x1, x2 (decoupled, one input) needs the whole [B, AB]."""
    text = UNOBSERVABLE.replace('y = "x1"', 'y1 = "x1"\ny2 = "x2"').replace(
        'title = "x2 is invisible"', 'title = "both measured"')
    checks = _checks(text, samples=20)
    obs, ctrb = checks["observability"], checks["controllability"]
    assert obs.passed and obs.data["blocks"] == 1 and "C alone" in obs.detail
    np.testing.assert_allclose(obs.data["singular_values"], [1.0, 1.0], rtol=1e-12)
    # [B, AB] = [[1, -1], [1, -2]] (a = 1): the whole Kalman matrix, computed by hand
    s = np.linalg.svd(np.array([[1.0, -1.0], [1.0, -2.0]]), compute_uv=False)
    assert ctrb.passed and ctrb.data["blocks"] == 2 and "full Kalman matrix" in ctrb.detail
    np.testing.assert_allclose(ctrb.data["singular_values"], s, rtol=1e-12)


def test_row_by_row_jacobians_decide_as_the_whole_ones():
    """The early-stopping Jacobians give the whole `symbolic_jacobians` on a smooth model, and
    None exactly when the whole ones keep a non-smooth term (the hybrid three-tank)."""
    from tanksynth.analysis.checks import _NONSMOOTH, _analytic_jacobians
    from tanksynth.analysis.linearize import symbolic_jacobians
    from tanksynth.methods import load_spec

    smooth = parse_spec_text(DTS200_H3).plant
    F, _, C = symbolic_jacobians(smooth)
    assert not (F.has(*_NONSMOOTH) or C.has(*_NONSMOOTH))
    F2, C2 = _analytic_jacobians(smooth)
    assert F2 == F and C2 == C
    hybrid = load_spec(Path(__file__).resolve().parents[2] / "examples" / "hybrid_three_tank.toml").plant
    F, _, C = symbolic_jacobians(hybrid)
    assert F.has(*_NONSMOOTH) or C.has(*_NONSMOOTH)
    assert _analytic_jacobians(hybrid) is None


def test_equilibrium_check_names_the_level_that_balances_the_plant():
    """A wrong operating point (h3 = 0.35 m where tank 3 balances at (h1 + h2)/2 = 0.325 m) fails
    the equilibrium check, and its detail says which single level fixes it."""
    from tanksynth.analysis.checks import equilibrium_checks
    from tanksynth.analysis.linearize import equilibrium_input
    from tanksynth.plants import three_tank

    p = three_tank()
    eq_check = equilibrium_checks(p, equilibrium_input(p, [0.50, 0.15, 0.35]))[0]
    assert eq_check.passed is False
    assert "the plant balances with h3 = 0.325 m" in eq_check.detail
    ok = equilibrium_checks(p, equilibrium_input(p, [0.50, 0.15, 0.325]))[0]
    assert ok.passed and "balances" not in ok.detail
