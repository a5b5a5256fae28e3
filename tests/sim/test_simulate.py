"""Batch simulator: agreement with the compiled model and a tight reference,
determinism, per-run independence of the batch, clipping, saturation, hybrid
switching without chattering, faults and jumps."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tanksynth.errors import DimensionError
from tanksynth.plants import hybrid_three_tank, hydraulic_fault, three_tank
from tanksynth.plants.hybrid_three_tank import LPH
from tanksynth.sim.simulate import (ConstantInput, EstimatorAdapter, InputSequence, ParameterChange,
                                    SimulationError, StateJump, run_seeds, simulate,
                                    simulate_inputs)
from tanksynth.sim.tape import numpy_model

HYBRID = hybrid_three_tank()
TANK = three_tank()


@pytest.mark.parametrize("plant", [HYBRID, TANK, hydraulic_fault()], ids=lambda p: p.name)
def test_numpy_model_matches_compiled_casadi(plant):
    pts = plant.region.sample(300, plant.x, seed=3)
    lim = plant.input_limits
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], 3.0)
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], 0.0)
    u = np.random.default_rng(1).uniform(lo, hi, size=(300, plant.m))
    values = {p.name: p.value for p in plant.parameters}
    model = numpy_model(plant)
    ref = plant.compiled.rhs(pts, u)
    assert np.allclose(model.rhs(pts, u, values), ref, rtol=1e-12, atol=1e-15 * np.abs(ref).max())
    assert np.allclose(model.output(pts, values), plant.compiled.output(pts), rtol=1e-14, atol=0)
    assert numpy_model(plant.with_parameters({})) is model  # one compile per structure


@pytest.mark.slow
def test_hybrid_crossings_are_located_and_accurate():
    """Filling through h0: each level crosses once (no chattering), matches a tight solve_ivp."""
    x0, u = [0.25, 0.25, 0.2], [110 * LPH, 100 * LPH]
    res = simulate(HYBRID, ts=1.0, steps=600, x0=x0, seeds=[0], u_init=u, substeps=2)
    c = HYBRID.compiled
    sol = solve_ivp(lambda t, x: c.rhs(x[None], np.array([u]))[0], (0, 600), x0, method="DOP853",
                    rtol=1e-11, atol=1e-13, t_eval=np.arange(601.0))
    assert np.max(np.abs(res.x[0] - sol.y.T)) < 2e-6
    assert res.events == 3 and res.mode_switches()[0] == 3   # a, b, c each switch once
    bits = res.modes[0]
    assert np.all(np.diff(bits.astype(int), axis=0) >= 0)   # monotone: never back and forth
    # Without event location, one RK4 step straddling h0 is an order of magnitude less accurate.
    coarse = simulate(HYBRID, ts=1.0, steps=600, x0=x0, seeds=[0], u_init=u, substeps=1,
                      event_iterations=0, max_splits=1)
    located = simulate(HYBRID, ts=1.0, steps=600, x0=x0, seeds=[0], u_init=u, substeps=1)
    assert np.max(np.abs(located.x[0] - sol.y.T)) < 0.3 * np.max(np.abs(coarse.x[0] - sol.y.T))


def test_resting_on_the_switching_surface_does_not_chatter():
    """Equilibrium input that holds h3 a hair above h0: modes settle, no switching back and forth."""
    from tanksynth.analysis.linearize import equilibrium_input

    x_eq = np.array([0.31918677, 0.3209075, 0.30968861])
    u0 = equilibrium_input(HYBRID, x_eq).u0
    res = simulate(HYBRID, ts=1.0, steps=400, x0=x_eq - [0.02, 0.02, 0.02], seeds=[1], u_init=u0)
    assert res.mode_switches()[0] == res.events == 2             # h1, h2 cross h0 once each
    assert np.all(np.diff(res.modes[0].astype(int), axis=0) >= 0)  # and never cross back
    assert np.all(res.modes[0, -1] == 1)


def test_determinism_and_batch_independence():
    kw = dict(ts=1.0, steps=200, x0=[0.3, 0.3, 0.29], u_init=[100 * LPH, 100 * LPH],
              process_std=1e-4, measurement_std=1e-3)
    seeds = run_seeds(7, 5)
    a = simulate(HYBRID, seeds=seeds, **kw)
    b = simulate(HYBRID, seeds=seeds, **kw)
    for name in ("x", "y", "u", "x_hat", "modes"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    alone = simulate(HYBRID, seeds=seeds[3:4], **kw)
    assert np.array_equal(alone.x[0], a.x[3]) and np.array_equal(alone.y[0], a.y[3])
    assert not np.array_equal(a.x[0], a.x[1])     # different seeds, different noise
    assert list(run_seeds(7, [3])) == [seeds[3]]   # a run's seed does not depend on its chunk
    with pytest.raises(ValueError):
        a.x[0, 0, 0] = 1.0                         # results are read-only


def test_levels_clipped_and_pumps_saturated():
    lo, hi = HYBRID.state_bounds()
    assert np.all(lo == 0) and np.all(hi == 0.55)
    full = simulate(HYBRID, ts=1.0, steps=400, x0=[0.5, 0.5, 0.5], seeds=[0],
                    controller=ConstantInput((1.0, 1.0)))          # asks for 1 m^3/s
    assert np.all(full.u <= 240 * LPH + 1e-18)                     # saturated at Qmax
    assert full.x.max() <= 0.55 and full.clipped_high > 0           # overflow height
    empty = simulate(TANK, ts=1.0, steps=300, x0=[0.05, 0.01, 0.03], seeds=[0],
                     u_init=[0.0, 0.0], process_std=1e-3)
    assert empty.x.min() >= 0.0 and empty.clipped_low > 0           # never below zero
    assert np.all(np.isfinite(empty.x))


def test_parameter_change_and_jump_at_their_samples():
    from tanksynth.analysis.linearize import equilibrium_input

    x_eq = np.array([0.31918677, 0.3209075, 0.30968861])
    u0 = equilibrium_input(HYBRID, x_eq).u0
    res = simulate(HYBRID, ts=1.0, steps=200, x0=x_eq, seeds=[0], u_init=u0,
                   changes=[ParameterChange(100, {"k5": 0.25 * 2.6363e-5})],
                   jumps=[StateJump(50, (0.0, 0.02, 0.0))])
    h1 = res.x[0, :, 0]
    assert np.max(np.abs(h1[:50] - x_eq[0])) < 1e-6
    assert res.x[0, 50, 1] - res.x[0, 49, 1] > 0.019                 # water added at sample 50
    assert np.all(np.diff(h1[101:]) < 0)                             # the leak drains tank 1
    per_run = simulate(HYBRID, ts=1.0, steps=5, x0=x_eq, seeds=[0, 1], u_init=u0,
                       parameters={"A": np.array([0.0176715, 0.03])})
    assert not np.array_equal(per_run.x[0], per_run.x[1])


def test_estimator_and_controller_protocols():
    class Echo:
        def reset(self, x_hat0):
            self.x = x_hat0.copy()
            self.calls = []

        def step(self, y, u):
            self.calls.append(u.copy())
            return self.x + 0.0

    class Integral:
        def reset(self, runs):
            self.z = np.zeros((runs, 2))

        def __call__(self, x_hat, reference, t):
            self.z += reference - x_hat[:, :2]
            return np.full((x_hat.shape[0], 2), 5e-5) + 1e-5 * self.z

    est, law = Echo(), Integral()
    ref = np.full((31, 2), 0.3)
    res = simulate(HYBRID, ts=1.0, steps=30, x0=[0.2, 0.2, 0.1], x_hat0=[0.0, 0.0, 0.1], seeds=[0, 1],
                   estimator=est, controller=law, reference=ref, u_init=[1e-5, 2e-5])
    assert np.allclose(res.x_hat[:, 0], [0.0, 0.0, 0.1])
    assert np.allclose(est.calls[0], [[1e-5, 2e-5]] * 2)             # u_{-1} = u_init at k = 0
    assert np.array_equal(est.calls[5], res.u[:, 4])                 # then u_{k-1}
    assert res.timing["calls"] == 30 and res.timing["estimator"] > 0
    with pytest.raises(DimensionError):
        simulate(HYBRID, ts=1.0, steps=3, x0=[0.2, 0.2], seeds=[0])


def test_estimator_adapter_wraps_design_estimators():
    kalman = pytest.importorskip("tanksynth.runtime.estimators.kalman")
    tuning = kalman.KalmanTuning(Q=1e-9 * np.eye(3), R=[[2.5e-7]], P0=1e-2 * np.eye(3),
                                 x0=[0.3, 0.3, 0.3], ts=1.0, clip=True)
    ekf = EstimatorAdapter(kalman.ExtendedKalmanFilter(HYBRID, tuning))
    res = simulate(HYBRID, ts=1.0, steps=150, x0=[0.31, 0.32, 0.305], x_hat0=[0.25, 0.25, 0.3],
                   seeds=run_seeds(0, 3), estimator=ekf, u_init=[100 * LPH, 100 * LPH],
                   measurement_std=5e-4)
    err = np.abs(res.x_hat[:, -20:] - res.x[:, -20:]).max()
    assert err < 0.01


def test_non_finite_state_is_an_error():
    with pytest.raises(SimulationError, match="run 0"):
        simulate(TANK, ts=1.0, steps=3, x0=[np.nan, 0.1, 0.1], seeds=[5])


def test_open_loop_input_sequences():
    """`simulate_inputs`: one sequence per run, saturated, noise-free, the simulator's states."""
    rng = np.random.default_rng(5)
    U = rng.uniform(50 * LPH, 300 * LPH, (80, 3, 2))               # above Qmax at times
    x0 = np.array([[0.297, 0.29, 0.25], [0.31, 0.32, 0.305], [0.1, 0.2, 0.15]])
    res = simulate_inputs(HYBRID, x0, U, 1.0, substeps=4)
    assert res.x.shape == (3, 81, 3) and np.array_equal(res.x[:, 0], x0)
    np.testing.assert_array_equal(res.u, np.minimum(U.transpose(1, 0, 2), 240 * LPH))
    for r in range(3):                                             # each run alone: same states
        alone = simulate(HYBRID, ts=1.0, steps=80, x0=x0[r], seeds=[0], substeps=4,
                         controller=InputSequence(U[:, r]))
        assert np.array_equal(alone.x[0], res.x[r])
    same = simulate_inputs(HYBRID, x0[0], U[:, 0], 1.0, substeps=4)   # (N, m): all runs
    assert np.array_equal(same.x[0], res.x[0])
    with pytest.raises(DimensionError, match="runs"):
        simulate(HYBRID, ts=1.0, steps=5, x0=x0[0], seeds=[0, 1], controller=InputSequence(U))
    with pytest.raises(DimensionError, match="periods"):
        simulate(HYBRID, ts=1.0, steps=90, x0=x0[0], seeds=[0], controller=InputSequence(U[:, 0]))


@pytest.mark.parametrize("backend", ["native", "numpy"])
@pytest.mark.parametrize("how", ["held", "sequence"])
def test_a_non_finite_input_is_an_error_on_every_backend(monkeypatch, backend, how):
    """NaN inputs raise SimulationError naming run and sample (the CasADi route's fmin/fmax would
    saturate NaN to a bound and return a finite, wrong trajectory: breaker's case)."""
    from tanksynth.analysis.linearize import equilibrium_input
    from tanksynth.errors import SimulationError
    from tanksynth.plants import three_tank
    from tanksynth.sim.simulate import InputSequence, simulate

    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", backend)
    plant = three_tank()
    x0 = np.array([0.30, 0.20, 0.25])
    u0 = equilibrium_input(plant, x0).u0
    nan_u = np.full(plant.m, np.nan)
    kw = (dict(u_init=nan_u) if how == "held"
          else dict(u_init=u0, controller=InputSequence(np.tile(nan_u, (50, 1)))))
    with pytest.raises(SimulationError, match="run 0 .*non-finite input at sample 0"):
        simulate(plant, x0=x0, ts=2.0, steps=50, seeds=[0], **kw)
    ok = simulate(plant, x0=x0, ts=2.0, steps=5, seeds=[0], u_init=u0)   # finite input: no error
    assert np.isfinite(ok.x).all()
