"""The one integrator: the plant's clipping rule, the numeric step, its symbolic twin and the
linear (matrix) form, all one RK4 scheme."""

import math

import casadi as ca
import numpy as np
import pytest
import scipy.linalg as sla

from tanksynth.errors import DimensionError
from tanksynth.plants import custom_plant, hybrid_three_tank, tank_network, three_tank
from tanksynth.plants.compile import rk4_step
from tanksynth.plants.hybrid_three_tank import LPH
from tanksynth.sim.integrate import Integrator, casadi_step, param_arrays, rk4_matrix, symbolic_rk4
from tanksynth.sim.simulate import simulate

HYBRID = hybrid_three_tank()
TANK = three_tank()
X_EQ = np.array([0.31918677, 0.3209075, 0.30968861])       # hybrid, 100/100 lph


def test_clipping_rule_is_the_plants():
    lo, hi = HYBRID.state_bounds()
    assert lo.tolist() == [0.0] * 3 and hi.tolist() == [0.55] * 3
    assert TANK.state_bounds()[1].tolist() == [0.62] * 3
    assert TANK.state_bounds({"hmax": 0.5})[1].tolist() == [0.5] * 3
    net = tank_network(4)                                    # no overflow height parameter
    assert np.all(net.state_bounds()[0] == 0) and np.all(np.isinf(net.state_bounds()[1]))
    with pytest.raises(DimensionError, match="hmax"):
        TANK.state_bounds({"hmax": np.array([0.5, 0.6])})


def test_integrator_is_the_simulators_step():
    """`Integrator.advance` is one sample of `simulate` without noise, bit for bit."""
    x0 = np.array([[0.297, 0.29, 0.25], [0.31, 0.32, 0.305]])
    u = np.array([[110 * LPH, 100 * LPH], [90 * LPH, 95 * LPH]])
    res = simulate(HYBRID, ts=1.0, steps=40, x0=x0, seeds=[0, 1], u_init=u, substeps=3)
    integ = Integrator.for_plant(HYBRID)
    p = param_arrays(HYBRID, None, 2)
    x = integ.clip(x0)
    for k in range(40):
        x = integ.advance(x, u, p, 1.0, 3)
        assert np.array_equal(x, res.x[:, k + 1])
    assert integ.events == res.events > 0


@pytest.mark.parametrize("plant, x0, u", [
    (HYBRID, X_EQ, [100 * LPH, 100 * LPH]),                       # mode (1, 1, 1), no crossing
    (TANK, [0.40, 0.20, 0.30], [3.5e-5, 3.2e-5]),
    (TANK, [0.002, 0.001, 0.0015], [0.0, 0.0]),                   # draining: clipped at 0
    (HYBRID, [0.54, 0.54, 0.5], [1.0, 1.0]),                      # saturated pumps, overflow
], ids=["hybrid", "tank", "empty", "full"])
def test_symbolic_step_agrees_with_the_numeric_integrator(plant, x0, u):
    """Same scheme, same clipping, same saturation: CasADi and numpy to rounding."""
    step = casadi_step(plant, 5.0, None, substeps=5)
    integ = Integrator.for_plant(plant)
    p = param_arrays(plant, None, 1)
    lo, hi = plant.input_limits.T
    x_num = np.asarray(x0, dtype=float)[None]
    x_sym = np.asarray(x0, dtype=float)
    for _ in range(30):
        x_num = integ.advance(x_num, np.clip(np.asarray(u, float), lo, hi)[None], p, 5.0, 5)
        out, crossed = step(x_sym, u)
        x_sym = np.asarray(out, dtype=float).reshape(-1)
        assert float(crossed) == 0.0
    np.testing.assert_allclose(x_sym, x_num[0], rtol=1e-12, atol=1e-15)
    lower, upper = plant.state_bounds()
    assert np.all(x_sym >= lower) and np.all(x_sym <= upper)


def test_symbolic_step_flags_a_switching_surface():
    """Filling through h0: the symbolic step flags the crossing the numeric one locates."""
    x0, u = np.array([0.299, 0.25, 0.29]), [240 * LPH, 0.0]
    step = casadi_step(HYBRID, 10.0, None, substeps=2)
    integ = Integrator.for_plant(HYBRID)
    x_num = integ.advance(x0[None], np.array([u]), param_arrays(HYBRID, None, 1), 10.0, 2)
    out, crossed = step(x0, u)
    assert float(crossed) == 1.0 and integ.events == 1
    assert HYBRID.mode_of(x_num[0])[0] == 1 and HYBRID.mode_of(x0)[0] == 0
    # unlocated, the symbolic step straddles the surface: not the numeric result any more
    assert np.max(np.abs(np.asarray(out).reshape(-1) - x_num[0])) > 1e-12


def test_symbolic_step_with_a_law_at_every_stage_and_an_integrand():
    """A continuous law u = k (r - h1) and the integral of (r - h1)^2 on the RK4 grid."""
    plant = three_tank()
    x = ca.SX.sym("x", 3)
    r = 0.45
    out = symbolic_rk4(plant, x, lambda s: ca.vertcat(1e-3 * (r - s[0]), 3.2e-5), 2.0, 4,
                       integrand=lambda s: (r - s[0]) ** 2)
    F = ca.Function("F", [x], [out.x, out.integral])
    xn, ise = (np.asarray(v, dtype=float).reshape(-1) for v in F([0.40, 0.20, 0.30]))
    f = lambda s: np.asarray(plant.compiled.f(s, [1e-3 * (r - s[0]), 3.2e-5])).reshape(-1)  # noqa: E731
    s, ref = np.array([0.40, 0.20, 0.30]), 0.0
    for _ in range(4):
        e0 = (r - s[0]) ** 2
        s = rk4_step(f, s, 0.5)
        ref += 0.25 * (e0 + (r - s[0]) ** 2)
    np.testing.assert_allclose(xn, s, rtol=1e-14)
    assert ise[0] == pytest.approx(ref, rel=1e-14)


def test_states_below_zero_never_reach_the_vector_field():
    """A region extending below 0 keeps that state unbounded below; levels stay >= 0."""
    plant = custom_plant({"model": "custom",
                          "states": {"h": {"unit": "m", "min": 0.0, "max": 2.0},
                                     "z": {"unit": "m", "min": -1.0, "max": 1.0}},
                          "inputs": {"q": {"unit": "m/s", "min": 0.0, "max": 1.0}},
                          "parameters": {"k": 1.0},
                          "equations": {"h": "q - k*sqrt(h)", "z": "-z"},
                          "outputs": {"y": "h"}})
    lo, hi = plant.state_bounds()
    assert lo.tolist() == [0.0, -np.inf] and np.all(np.isinf(hi))
    res = simulate(plant, ts=1.0, steps=20, x0=[0.05, -0.5], seeds=[0], u_init=[0.0])
    assert np.all(res.x[0, :, 0] >= 0) and np.all(np.isfinite(res.x))
    assert res.clipped_low > 0 and res.x[0, -1, 1] < 0


def test_rk4_matrix_is_the_rk4_step_of_a_linear_system():
    rng = np.random.default_rng(0)
    M = rng.normal(size=(4, 4))
    h = 0.05
    R = rk4_matrix(M, h)
    hM = h * M
    taylor = np.eye(4) + hM + hM @ hM / 2 + hM @ hM @ hM / 6 + hM @ hM @ hM @ hM / 24
    np.testing.assert_allclose(R, taylor, rtol=1e-13, atol=1e-15)
    z = rng.normal(size=4)
    np.testing.assert_allclose(R @ z, rk4_step(lambda v: M @ v, z, h), rtol=1e-13)
    assert np.abs(R - sla.expm(hM)).max() < 1e-6
    with pytest.raises(DimensionError):
        rk4_matrix(np.ones((2, 3)), h)


def test_rk4_step_is_generic():
    """One formula for numpy arrays and CasADi expressions."""
    s = ca.SX.sym("s")
    expr = rk4_step(lambda v: -2 * v, s, 0.1)
    val = float(ca.Function("g", [s], [expr])(1.3))
    assert val == rk4_step(lambda v: -2 * v, 1.3, 0.1)
    assert val == pytest.approx(1.3 * sum((-0.2) ** k / math.factorial(k) for k in range(5)),
                                rel=1e-15)


def test_rk4_step_with_a_time_varying_field():
    """Stages at t, t + h/2, t + h/2, t + h: exact for dx/dt = t^3 (fourth order)."""
    out = rk4_step(lambda v, t: t ** 3, 0.0, 0.5, t=1.0)
    assert out == pytest.approx((1.5 ** 4 - 1.0) / 4, rel=1e-15)
