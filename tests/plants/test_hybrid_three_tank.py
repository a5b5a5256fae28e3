"""Hybrid three-tank (seed 002): structure, compile, mode logic, sanity steady states."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.optimize import fsolve

from tanksynth.errors import SpecError
from tanksynth.plants.hybrid_three_tank import LPH, hybrid_three_tank, mode_vector_field

K = dict(k1=2.6363e-5, k2=2.4891e-5, k3=3.7984e-5, k4=3.4316e-5, k5=0.0, k6=2.2538e-5, k7=0.0)
AREA = math.pi * 0.15 ** 2 / 4
G, H0 = 9.81, 0.30


@pytest.fixture(scope="module")
def plant():
    return hybrid_three_tank()


def reference_rhs(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Equations (1)-(12) of notes/plants.md 1.3 written independently in numpy."""
    h1, h2, h3 = x.T
    q1in, q2in = u.T

    def link(k, dh):
        return k * np.sign(dh) * np.sqrt(2 * G * np.abs(dh))

    a, b, c = (h1 > H0), (h2 > H0), (h3 > H0)
    # z1, z2 and the heads by the explicit case table (11)-(12)
    head1 = np.where(a & c, h1 - h3, np.where(a, h1 - H0, np.where(c, H0 - h3, 0.0)))
    head2 = np.where(b & c, h2 - h3, np.where(b, h2 - H0, np.where(c, H0 - h3, 0.0)))
    Q1, Q2 = link(K["k1"], h1 - h3), link(K["k2"], h2 - h3)
    Q3, Q4 = link(K["k3"], head1), link(K["k4"], head2)
    Q5 = K["k5"] * np.sqrt(2 * G * np.maximum(h1, 0))
    Q6 = K["k6"] * np.sqrt(2 * G * np.maximum(h3, 0))
    Q7 = K["k7"] * np.sqrt(2 * G * np.maximum(h2, 0))
    return np.stack([q1in - Q1 - Q3 - Q5, q2in - Q2 - Q4 - Q7, Q1 + Q2 + Q3 + Q4 - Q6], axis=1) / AREA


def test_structure_and_units(plant):
    assert plant.name == "hybrid_three_tank"
    assert (plant.n, plant.m, plant.q) == (3, 2, 1)
    assert [s.unit for s in plant.states] == ["m"] * 3
    assert [s.unit for s in plant.inputs] == ["m^3/s"] * 2
    assert plant.outputs[0].unit == "m"
    assert plant.h == sp.Matrix([plant.x[2]])
    units = {p.name: p.unit for p in plant.parameters}
    for name in ["k1", "k2", "k3", "k4", "k5", "k6", "k7", "A"]:
        assert units[name] == "m^2"
    for name in ["h0", "hd1", "hd2", "hz", "hmax"]:
        assert units[name] == "m"
    assert units["g"] == "m/s^2"
    assert plant.parameter("A").value == pytest.approx(0.0176715, rel=1e-5)
    assert plant.parameter("h0").value == 0.30
    assert plant.region.bounds == ((0.0, 0.55),) * 3
    assert plant.region.orderings == ()
    assert plant.input_limits.tolist() == [[0.0, pytest.approx(6.6667e-5, rel=1e-4)]] * 2
    kinds = {a.kind for a in plant.assumptions}
    assert {"reconstructed", "omitted"} <= kinds
    text = " ".join(a.text for a in plant.assumptions)
    for item in ["hd1", "hz", "pump law", "sampling time", "noise"]:
        assert item in text
    assert all(a.source for a in plant.assumptions)
    # the switching functions use the same h0 symbol as the parameters
    assert plant.hybrid.switching == tuple(xi - plant.p["h0"] for xi in plant.x)


def test_compiled_rhs_matches_reference(plant):
    rng = np.random.default_rng(2)
    x = rng.uniform(0.0, 0.55, size=(200, 3))
    # force points on each side of h0 and on the equal-level diagonal
    x[:8] = [[0.1, 0.1, 0.1], [0.4, 0.1, 0.2], [0.1, 0.4, 0.35], [0.45, 0.5, 0.4],
             [0.2, 0.35, 0.45], [0.5, 0.5, 0.5], [0.31, 0.29, 0.3], [0.0, 0.0, 0.0]]
    u = rng.uniform(0.0, 6.6667e-5, size=(200, 2))
    got = plant.compiled.rhs(x, u)
    assert got.shape == (200, 3)
    np.testing.assert_allclose(got, reference_rhs(x, u), rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(plant.compiled.output(x), x[:, 2:3])


def test_mass_balance(plant):
    """Without drains 5 and 7, d(total volume)/dt = inflow - Q6."""
    x = np.array([[0.4, 0.2, 0.33]])
    u = np.array([[3e-5, 2e-5]])
    dvol = AREA * plant.compiled.rhs(x, u).sum()
    assert dvol == pytest.approx(5e-5 - K["k6"] * math.sqrt(2 * G * 0.33), rel=1e-12)


def test_middle_pipe_flow_sign(plant):
    """z1 = 0 with both levels below h0, +1 / -1 above (equations (11)-(12))."""
    fn = plant.compiled.rhs
    u0 = np.zeros((1, 2))
    k1 = K["k1"]

    def q3(h1, h3):
        # A dh1/dt = -Q1 - Q3 with no inflow and closed drains: isolate Q3
        dh1 = fn(np.array([[h1, 0.1, h3]]), u0)[0, 0]
        q1 = k1 * np.sign(h1 - h3) * np.sqrt(2 * G * abs(h1 - h3))
        return -AREA * dh1 - q1

    assert q3(0.25, 0.10) == pytest.approx(0.0, abs=1e-15)        # a = c = 0
    assert q3(0.10, 0.25) == pytest.approx(0.0, abs=1e-15)
    assert q3(0.40, 0.10) > 0                                       # a = 1, c = 0: +1
    assert q3(0.40, 0.10) == pytest.approx(K["k3"] * math.sqrt(2 * G * 0.10), rel=1e-10)
    assert q3(0.10, 0.45) < 0                                       # a = 0, c = 1: -1
    assert q3(0.10, 0.45) == pytest.approx(-K["k3"] * math.sqrt(2 * G * 0.15), rel=1e-10)
    assert q3(0.40, 0.45) < 0 and q3(0.45, 0.40) > 0               # a = c = 1: sgn(h1 - h3)


def test_modes(plant):
    seen = set()
    for bits in np.ndindex(2, 2, 2):
        x = [0.42 if b else 0.17 for b in bits]
        mode = plant.mode_of(x)
        assert mode == bits
        seen.add(mode)
    assert len(seen) == 8
    # exactly at h0 the bit is 0 (strict inequality)
    assert plant.mode_of([0.30, 0.31, 0.29]) == (0, 1, 0)


@pytest.mark.parametrize("mode", list(np.ndindex(2, 2, 2)))
def test_mode_vector_field_agrees_inside_its_mode(plant, mode):
    fm = mode_vector_field(plant, mode)
    assert not any(e.has(plant.p["h0"]) for e in fm.atoms(sp.Max, sp.Piecewise))
    fm_num = fm.xreplace(plant.parameter_values)
    fn = sp.lambdify([plant.x, plant.u], fm_num, "numpy")
    rng = np.random.default_rng(sum(b << i for i, b in enumerate(mode)))
    for _ in range(5):
        x = [rng.uniform(0.31, 0.55) if b else rng.uniform(0.0, 0.29) for b in mode]
        u = rng.uniform(0, 6e-5, size=2)
        assert plant.mode_of(x) == mode
        want = plant.compiled.rhs(np.array([x]), np.array([u]))[0]
        got = np.asarray(fn(x, u), dtype=float).ravel()
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-14)
        # the per-mode Jacobian (what an EKF uses) equals the AD Jacobian of f there
        # d sign / dx = DiracDelta, zero off the (measure-zero) equal-level set
        jac_fn = sp.lambdify([plant.x, plant.u], fm_num.jacobian(plant.x),
                             [{"DiracDelta": lambda e: 0.0 * e}, "numpy"])
        jx, _ = plant.compiled.jacobians(np.array([x]), np.array([u]))
        np.testing.assert_allclose(np.asarray(jac_fn(x, u), dtype=float), jx[0],
                                   rtol=1e-9, atol=1e-12)


def test_mode_vector_field_is_mode_specific(plant):
    # outside its mode, the frozen field differs from the true one
    x = np.array([0.45, 0.1, 0.1])
    u = np.zeros(2)
    f000 = mode_vector_field(plant, (0, 0, 0)).xreplace(plant.parameter_values)
    fn = sp.lambdify([plant.x, plant.u], f000, "numpy")
    true = plant.compiled.rhs(x[None], u[None])[0]
    assert abs(np.asarray(fn(x, u), dtype=float).ravel()[0] - true[0]) > 1e-4


def test_mode_vector_field_rejects_bad_input(plant):
    with pytest.raises(SpecError):
        mode_vector_field(plant, (1, 0))
    with pytest.raises(SpecError):
        mode_vector_field(plant, (2, 0, 0))
    from tanksynth.plants.three_tank import three_tank

    with pytest.raises(SpecError):
        mode_vector_field(three_tank(), (0, 0, 0))


@pytest.mark.parametrize("q_lph, h_expected, mode", [
    ((60, 60), (0.132, 0.134, 0.112), (0, 0, 0)),
    ((100, 100), (0.319, 0.321, 0.310), (1, 1, 1)),
    ((120, 80), (0.323, 0.317, 0.310), (1, 1, 1)),
])
def test_sanity_steady_states(plant, q_lph, h_expected, mode):
    """notes/plants.md 1.5 sanity table, within 2 mm."""
    u = np.array(q_lph, dtype=float) * LPH
    fn = plant.compiled.rhs
    h = fsolve(lambda x: fn(x[None], u[None])[0] * 1e3, x0=np.array(h_expected) + 0.01, xtol=1e-12)
    assert np.max(np.abs(fn(h[None], u[None]))) < 1e-10
    np.testing.assert_allclose(h, h_expected, atol=2e-3)
    assert plant.mode_of(h) == mode


def test_sanity_steady_state_by_integration(plant):
    from scipy.integrate import solve_ivp

    u = np.array([100.0, 100.0]) * LPH
    fn = plant.compiled.rhs
    sol = solve_ivp(lambda t, x: fn(x[None], u[None])[0], (0.0, 20000.0), [0.05, 0.05, 0.05],
                    method="LSODA", rtol=1e-8, atol=1e-10)
    assert sol.success
    np.testing.assert_allclose(sol.y[:, -1], [0.319, 0.321, 0.310], atol=2e-3)


def test_hz_shifts_t3_equilibrium(plant):
    """h3* = hz + (Q_total/k6)^2 / (2 g): hz shifts the T3 level one-for-one."""
    shifted = plant.with_parameters({"hz": 0.02})
    u = np.array([60.0, 60.0]) * LPH
    h = fsolve(lambda x: shifted.compiled.rhs(x[None], u[None])[0] * 1e3, [0.15, 0.15, 0.13],
               xtol=1e-12)
    assert h[2] == pytest.approx(0.02 + (120 * LPH / K["k6"]) ** 2 / (2 * G), abs=1e-8)


def test_jacobians_finite_inside_a_mode(plant):
    """Also where both levels are below h0 (z = 0): no 0 * inf = NaN from AD."""
    x = np.array([[0.40, 0.35, 0.32], [0.2, 0.15, 0.1]])
    u = np.full((2, 2), 3e-5)
    jx, ju = plant.compiled.jacobians(x, u)
    assert jx.shape == (2, 3, 3) and ju.shape == (2, 3, 2)
    assert np.all(np.isfinite(jx))
    np.testing.assert_allclose(ju[0], np.array([[1, 0], [0, 1], [0, 0]]) / AREA)
