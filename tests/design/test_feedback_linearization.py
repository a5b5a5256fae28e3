"""Exact feedback linearisation: symbolic pins, outer loop, zero dynamics.

Bad input to the decoupling analysis is tested in test_decoupling.py.
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import sympy as sp

from tanksynth.analysis.region import region_points
from tanksynth.design.laws.feedback_linearization import decoupling_analysis, feedback_linearization, outer_loop
from tanksynth.errors import InfeasibleDesign, SpecError
from tanksynth.plants import three_tank
from tanksynth.methods import load_spec

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture(scope="module")
def tank():
    return three_tank(outputs="all")


@pytest.fixture(scope="module")
def seed000(tank):
    return feedback_linearization(tank, ["h1", "h2"], poles=[-0.05, -0.05])


def seed000_flows(plant):
    p = plant.p
    h1, h2, h3 = plant.x
    g = p["g"]
    q13 = p["mu13"] * p["Phi"] * sp.sqrt(2 * g * (h1 - h3))
    q32 = p["mu32"] * p["Phi"] * sp.sqrt(2 * g * (h3 - h2))
    q20 = p["mu20"] * p["Phi"] * sp.sqrt(2 * g * h2)
    return q13, q32, q20


def is_zero(expr) -> bool:
    return all(sp.simplify(e) == 0 for e in sp.Matrix(expr))


# --------------------------------------------------------------- seed 000 pins
def test_seed000_lambda_lambda0_alpha_beta(tank, seed000):
    dec = seed000.decoupling
    A = tank.p["A"]
    q13, q32, q20 = seed000_flows(tank)
    assert dec.degrees == (1, 1)
    assert dec.total == 2 < tank.n
    assert dec.Lambda == sp.diag(1 / A, 1 / A)                                # printed Lambda
    assert is_zero(dec.Lambda0 - sp.Matrix([-q13 / A, (q32 - q20) / A]))      # printed Lambda_0
    assert dec.beta == sp.diag(A, A)
    assert is_zero(dec.alpha - sp.Matrix([q13, q20 - q32]))                   # derived alpha
    # the printed law uses (1/A)[-q13; q32 - q20] = Lambda_0 as alpha: erratum
    assert not is_zero(dec.alpha - dec.Lambda0)


def test_seed000_internal_dynamics_tank3_stable(tank, seed000):
    zd = seed000.decoupling.zero_dynamics
    A = tank.p["A"]
    q13, q32, _ = seed000_flows(tank)
    assert zd.dimension == 1 and zd.coordinates == ("h3",)
    assert is_zero(zd.expressions - sp.Matrix([(q13 - q32) / A]))
    assert zd.stable and zd.skipped == 0
    assert len(zd.points) > 300
    ev = zd.eigenvalues.reshape(-1)
    assert np.all(np.abs(ev.imag) == 0)
    assert np.all(ev.real < 0)
    # d/dh3 of (q13 - q32)/A = -(g/A)(mu13 Phi / sqrt(2g(h1-h3)) + mu32 Phi / sqrt(2g(h3-h2)))
    h1, h2, h3 = zd.points.T
    g, Phi, Aval = 9.81, 5e-5, 0.0154
    exact = -(g / Aval) * (0.5 * Phi / np.sqrt(2 * g * (h1 - h3)) + 0.5 * Phi / np.sqrt(2 * g * (h3 - h2)))
    np.testing.assert_allclose(ev.real, exact, rtol=1e-10)
    d = seed000.diagnostics["zero_dynamics"]
    assert d["max_real_part"] == pytest.approx(float(exact.max()), rel=1e-10)
    assert d["max_real_part"] < -0.01        # -0.0132 1/s on the grid


def test_seed000_law_values(tank, seed000):
    x0 = np.array([0.4, 0.2, 0.3])
    u, zeta = (np.asarray(v, dtype=float).reshape(-1) for v in seed000.law(x0, [0.4, 0.2]))
    np.testing.assert_array_equal(zeta, [0.0, 0.0])
    q13 = 0.5 * 5e-5 * np.sqrt(2 * 9.81 * 0.1)
    q32 = 0.5 * 5e-5 * np.sqrt(2 * 9.81 * 0.1)
    q20 = 0.675 * 5e-5 * np.sqrt(2 * 9.81 * 0.2)
    np.testing.assert_allclose(u, [q13, q20 - q32], rtol=1e-13)
    u, zeta = (np.asarray(v, dtype=float).reshape(-1) for v in seed000.law(x0, [0.45, 0.2]))
    np.testing.assert_allclose(zeta, [0.05 * 0.05, 0.0], rtol=1e-13)
    np.testing.assert_allclose(u, [q13 + 0.0154 * 0.05 * 0.05, q20 - q32], rtol=1e-13)
    # saturation to 0 .. qmax
    u, _ = seed000.law(x0, [0.62, 0.0])
    np.testing.assert_array_equal(np.asarray(u).reshape(-1), [1.2e-4, 0.0])
    assert seed000.diagnostics["law_smooth_vs_general_max_relative_difference"] < 1e-13


def test_general_law_survives_flow_reversal(seed000):
    u, _ = seed000.law([0.25, 0.2, 0.3], [0.25, 0.2])        # h3 > h1: q13 reverses
    u = np.asarray(u, dtype=float).reshape(-1)
    assert np.all(np.isfinite(u))
    assert u[0] == 0.0                                       # would need a negative pump flow


def test_latex_fragments(seed000):
    tex = seed000.latex()
    assert {"Lambda", "Lambda0", "alpha", "beta", "u", "zero_dynamics"} <= set(tex)
    assert r"\frac{1}{A}" in tex["Lambda"]


# --------------------------------------------------------------- outer loop
def test_outer_loop_from_poles_and_bandwidth():
    ol = outer_loop((1, 2), poles=[-0.5, -1.0, -2.0])
    np.testing.assert_allclose(ol.coefficients[0], [0.5])
    np.testing.assert_allclose(ol.coefficients[1], [2.0, 3.0])      # (s+1)(s+2) = s^2 + 3 s + 2
    np.testing.assert_allclose(ol.matrix, [[0.5, 0.0], [2.0, 3.0]])
    ol = outer_loop((2,), poles=[complex(-1, 1), complex(-1, -1)])
    np.testing.assert_allclose(ol.coefficients[0], [2.0, 2.0])
    ol = outer_loop((1, 3), bandwidth=0.1)
    np.testing.assert_allclose(ol.coefficients[1], [1e-3, 3e-2, 0.3])
    ol = outer_loop((1, 1), bandwidth=[0.1, 0.2])
    np.testing.assert_allclose(ol.matrix.ravel(), [0.1, 0.2])


@pytest.mark.parametrize("kwargs, match", [
    ({}, "either"),
    ({"poles": [-1, -1], "bandwidth": 1.0}, "either"),
    ({"poles": [-1]}, "expected sum of relative degrees = 2"),
    ({"poles": [-1, 0.5]}, "negative real part"),
    ({"poles": [complex(-1, 1), -1]}, "conjugate pairs"),
    ({"bandwidth": -1.0}, "bandwidth must be > 0"),
    ({"bandwidth": [1.0, 2.0, 3.0]}, "one per output"),
])
def test_outer_loop_bad_input(kwargs, match):
    with pytest.raises(SpecError, match=match):
        outer_loop((1, 1), **kwargs)


# ---------------------------------------------------- higher relative degree
def test_relative_degree_two_law_gives_the_chosen_polynomial():
    spec = load_spec(EXAMPLES / "custom_two_tank.toml")
    plant = spec.plant
    fl = feedback_linearization(plant, None, poles=[-0.1, -0.2], saturate=False)
    assert fl.decoupling.degrees == (2,)
    assert fl.decoupling.zero_dynamics.dimension == 0
    c0, c1 = fl.outer.coefficients[0]
    assert (c0, c1) == pytest.approx((0.02, 0.3))
    # y'' computed from the plant under the law equals c0 (r - y) - c1 y'
    x = ca.SX.sym("x", 2)
    r = ca.SX.sym("r", 1)
    f = plant.compiled.f
    u = fl.law(x, r)[0]
    ydot = f(x, u)[1]
    yddot = ca.mtimes(ca.jacobian(ydot, x), f(x, u))
    check = ca.Function("check", [x, r], [ydot, yddot])
    for xv in region_points(plant, 0, 50, seed=3):
        rv = 0.3
        yd, ydd = (float(v) for v in check(xv, rv))
        assert ydd == pytest.approx(c0 * (rv - xv[1]) - c1 * yd, rel=1e-8, abs=1e-15)


# --------------------------------------------------------------- zero dynamics
@pytest.mark.slow
def test_quadruple_tank_minimum_phase_accepted_nonminimum_refused():
    good = load_spec(EXAMPLES / "quadruple_tank_min_phase.toml").plant
    fl = feedback_linearization(good, None, poles=[-0.1, -0.1], per_axis=6)
    assert fl.decoupling.zero_dynamics.dimension == 2
    assert fl.decoupling.zero_dynamics.stable
    bad = load_spec(EXAMPLES / "quadruple_tank_nonmin_phase.toml").plant
    dec = decoupling_analysis(bad, per_axis=6)
    with pytest.raises(InfeasibleDesign, match=r"zero dynamics .* unstable: Jacobian eigenvalue .* at x = "
                                               r"\(h1 = .*allow_unstable_zero_dynamics"):
        feedback_linearization(bad, None, poles=[-0.1, -0.1], analysis=dec)
    fl = feedback_linearization(bad, None, poles=[-0.1, -0.1], analysis=dec,
                                allow_unstable_zero_dynamics=True)
    assert fl.diagnostics["zero_dynamics_override"] is True
    assert fl.diagnostics["zero_dynamics"]["stable"] is False
    # (1 - g1)(1 - g2) > g1 g2 (gamma1 + gamma2 < 1): a positive real eigenvalue everywhere
    assert np.all(fl.decoupling.zero_dynamics.eigenvalues.real.max(axis=1) > 0)
