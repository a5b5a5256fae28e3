"""Horizon kernels (issue 29): an estimator's step over whole sequences in native calls.

The reference is the one-step path (``TANKSYNTH_ESTIMATOR_BACKEND=step``: one kernel call per
sample, the path before horizon kernels): the horizon kernel runs the same C code of the same
step, so the numbers agree to 1e-14 relative (measured: bit for bit on this machine).
"""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.errors import CovarianceError
from tanksynth.native_cache import find_compiler
from tanksynth.runtime.estimators import (ExtendedKalmanFilter, KalmanTuning, NARXEstimator,
                                         NARXTuning, UKFTuning, UnscentedKalmanFilter)
from tanksynth.runtime.estimators.horizon import BUILD_STEPS, CHUNK, horizon_backend
from tanksynth.runtime.estimators.kernels import cache_info, clear_cache
from tanksynth.sim.inputs import EstimatorAdapter
from tanksynth.sim.simulate import simulate, simulate_inputs

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="horizon kernels need a C compiler")

LPH = 1e-3 / 3600.0
#: Samples: not a multiple of the chunk (a padded last chunk).
N = 2 * CHUNK + 77
RTOL = 1e-14


def _ekf(plant):
    return ExtendedKalmanFilter(plant, KalmanTuning(Q=1e-9 * np.eye(3), R=1e-6 * np.eye(plant.q),
                                                    P0=1e-3 * np.eye(3), x0=[0.25, 0.15, 0.2],
                                                    ts=1.0))


def _ukf(plant):
    return UnscentedKalmanFilter(plant, UKFTuning(Q=1e-9 * np.eye(3), R=1e-6 * np.eye(plant.q),
                                                  P0=1e-3 * np.eye(3), x0=[0.25, 0.15, 0.2],
                                                  ts=1.0))


def _narx(plant):
    rng = np.random.default_rng(11)
    return NARXEstimator(plant, NARXTuning(
        W1=rng.normal(0, 0.3, (5, 10)), b1=rng.normal(0, 0.1, 5), W2=rng.normal(0, 0.3, (3, 5)),
        b2=rng.normal(0, 0.1, 3), in_mean=np.r_[[0.3] * 3, 0.0, [0.3] * 6],
        in_scale=np.r_[[0.05] * 3, 1e-3, [0.05] * 6], out_mean=[0.3] * 3, out_scale=[0.05] * 3,
        x0=[0.3] * 3, ts=1.0))


FAMILIES = {"ekf": _ekf, "ukf": _ukf, "narx": _narx}


def _data(plant, runs, seed=0, samples=N):
    """Measurements of the plant (N, runs, q) with sensor noise and the inputs before them."""
    rng = np.random.default_rng(seed)
    U = (70 + 40 * rng.random((samples, runs, 2))) * LPH
    res = simulate_inputs(plant, [0.3, 0.2, 0.25], U, 1.0, substeps=2)
    Y = res.y[:, 1:].transpose(1, 0, 2) + 1e-3 * rng.standard_normal((samples, runs, plant.q))
    return np.ascontiguousarray(Y), U


def _agree(a, b):
    scale = max(1.0, float(np.abs(b).max()))
    assert np.abs(np.asarray(a) - np.asarray(b)).max() <= RTOL * scale


def _both(monkeypatch, est, *args, method="run"):
    """(horizon result, estimator state, extra), (step result, state, extra)."""
    out = []
    for mode in ("step", "horizon"):
        monkeypatch.setenv("TANKSYNTH_ESTIMATOR_BACKEND", mode)
        assert horizon_backend() == mode
        est.reset()
        res = getattr(est, method)(*args)
        out.append((res, est.state, est.extra, est.k))
    monkeypatch.delenv("TANKSYNTH_ESTIMATOR_BACKEND")
    return out[1], out[0]


@pytest.mark.parametrize("family", ["ekf", "ukf", "narx"])
def test_single_run_equals_the_steps(monkeypatch, hybrid_plant, family):
    est = FAMILIES[family](hybrid_plant)
    Y, U = _data(hybrid_plant, 1)
    (x_h, s_h, e_h, k_h), (x_s, s_s, e_s, k_s) = _both(monkeypatch, est, Y[:, 0], U[:, 0])
    assert x_h.shape == (N, 3) and k_h == k_s == N
    _agree(x_h, x_s)
    _agree(s_h, s_s)
    _agree(e_h, e_s)           # the extra outputs of the last step (innovation, gain, ...)
    assert est._horizons[False].runs == 1    # the horizon kernel ran (not the fallback)


@pytest.mark.parametrize("family", ["ekf", "ukf", "narx"])
def test_batch_of_37_equals_the_steps(monkeypatch, hybrid_plant, family):
    est = FAMILIES[family](hybrid_plant).batch(37)
    Y, U = _data(hybrid_plant, 37, seed=3)
    (x_h, s_h, e_h, _), (x_s, s_s, e_s, _) = _both(monkeypatch, est, Y, U)
    assert x_h.shape == (N, 37, 3)
    _agree(x_h, x_s)
    _agree(s_h, s_s)
    _agree(e_h, e_s)
    assert est._horizons[False].runs == 37


def test_kernel_built_once_serves_every_length_and_batch(monkeypatch, tank_plant):
    """One compiled horizon function per estimator structure: every N, every M, every instance."""
    monkeypatch.setenv("TANKSYNTH_ESTIMATOR_BACKEND", "horizon")
    est = _ekf(tank_plant)
    fns = []
    for samples, runs in ((300, 1), (CHUNK, 1), (1000, 1), (300, 5), (777, 37)):
        Y, U = _data(tank_plant, runs, seed=samples, samples=samples)
        e = est if runs == 1 else est.batch(runs)
        e.reset()
        X = e.run(Y[:, 0] if runs == 1 else Y, U[:, 0] if runs == 1 else U)
        assert X.shape[0] == samples
        fns.append(e._horizons[False].function)
    assert all(f is fns[0] for f in fns)
    assert est._shared["horizon_fns"][False] is fns[0]
    # the same plant and tuning structure in a new estimator: the library loaded, not rebuilt
    again = _ekf(tank_plant)
    again.run(*(a[:, 0] for a in _data(tank_plant, 1, samples=300)))
    assert again._horizons[False].function.name() == fns[0].name()


def test_covariance_failure_names_the_same_step(monkeypatch, tank_plant):
    """Measurements that make the next prediction's covariance NaN (an overflowing estimate, in a
    chunk after the first): the same error, at the same step, as stepping; the last valid state
    kept."""
    est = _ekf(tank_plant)
    Y, U = _data(tank_plant, 1)
    Y[400, 0] = [1.79e308, -1.79e308, 1.79e308]
    errors = []
    for mode in ("step", "horizon"):
        monkeypatch.setenv("TANKSYNTH_ESTIMATOR_BACKEND", mode)
        est.reset()
        with pytest.raises(CovarianceError) as info:
            est.run(Y[:, 0], U[:, 0])
        errors.append((str(info.value), est.k, est.state))
    assert errors[0][0] == errors[1][0] and "P(k|k-1)" in errors[0][0] and "step 402" in errors[0][0]
    assert errors[0][1] == errors[1][1] == 401
    _agree(errors[1][2], errors[0][2])      # the state kept: the last valid one


@pytest.mark.parametrize("family", ["ekf", "ukf"])
def test_observed_mask_equals_step_observed(monkeypatch, tank_plant, family):
    """`run_states` with missing outputs = `step_observed` fed the model's prediction there."""
    est = FAMILIES[family](tank_plant).batch(1)
    Y, U = _data(tank_plant, 1, seed=5)
    rng = np.random.default_rng(7)
    observed = rng.random((N, tank_plant.q)) > 0.25
    observed[:40] = True
    observed[100:130] = False                    # nothing observed: prediction only
    monkeypatch.setenv("TANKSYNTH_ESTIMATOR_BACKEND", "horizon")
    est.reset()
    states = est.run_states(np.where(observed[:, None, :], Y, 0.0), U, observed)
    assert est._horizons[True].masked
    # reference: one step_observed per sample, fed y(k|k-1) = h(F(x(k-1), u)) where unobserved
    monkeypatch.setenv("TANKSYNTH_ESTIMATOR_BACKEND", "step")
    est.reset()
    import casadi as ca
    x, u = ca.SX.sym("x", 3), ca.SX.sym("u", 2)
    model = est.model
    pred = ca.Function("pred", [x, u], [model.output_sx(model.predict_sx(x, u))])
    ref = np.empty_like(states)
    for k in range(N):
        yp = np.asarray(pred(est.x_hat[0], U[k, 0]), dtype=float).reshape(-1)
        y = np.where(observed[k], Y[k, 0], yp)
        est.step_observed(y[None], U[k], observed[k])
        ref[k] = est.state
    _agree(states, ref)


def test_open_loop_noisy_simulation_estimates_after_the_plant(monkeypatch, hybrid_plant):
    """`simulate` with noise, no controller: the estimator over the measurements (horizon) gives
    the estimates of the per-period loop."""
    est = _ekf(hybrid_plant)
    kw = dict(ts=1.0, steps=N, x0=[0.3, 0.2, 0.25], seeds=np.arange(4), u_init=[90 * LPH, 80 * LPH],
              measurement_std=1e-3, process_std=1e-5)
    out = []
    for mode in ("step", "horizon"):
        monkeypatch.setenv("TANKSYNTH_ESTIMATOR_BACKEND", mode)
        out.append(simulate(hybrid_plant, estimator=EstimatorAdapter(est), **kw))
    np.testing.assert_array_equal(out[0].x, out[1].x)
    np.testing.assert_array_equal(out[0].y, out[1].y)
    _agree(out[1].x_hat, out[0].x_hat)
    assert np.abs(out[1].x_hat[:, 50:] - out[1].x[:, 50:]).max() < 0.02   # it does estimate


def test_auto_compiles_for_long_sequences_only(monkeypatch, tmp_path, tank_plant):
    """``auto``: a short sequence steps (no compiler run), a long one builds the library, which
    every sequence then uses; ``TANKSYNTH_SIM_BACKEND=numpy`` steps."""
    monkeypatch.setenv("TANKSYNTH_CACHE", str(tmp_path))
    monkeypatch.delenv("TANKSYNTH_ESTIMATOR_BACKEND", raising=False)
    clear_cache()                                   # nothing loaded, nothing on disk
    est = _ekf(tank_plant)
    Y, U = _data(tank_plant, 1, samples=300)
    est.run(Y[:, 0], U[:, 0])
    assert est._shared["horizon_fns"][False] == "absent" and not est._horizons
    files = cache_info()["files"]
    Yb, Ub = _data(tank_plant, 37, samples=600)
    assert 37 * 600 >= BUILD_STEPS
    big = est.batch(37)
    big.run(Yb, Ub)
    assert cache_info()["files"] == files + 1 and big._horizons[False].runs == 37
    est.run(Y[:, 0], U[:, 0])
    assert est._horizons[False].runs == 1
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "numpy")
    assert horizon_backend() == "step"
    fresh = est.batch(2)
    fresh.run(Yb[:, :2], Ub[:, :2])
    assert not fresh._horizons


def test_scenario_schedule_with_noise_estimates_as_the_step_loop(monkeypatch, hybrid_plant):
    """A noisy run under an open-loop input schedule (a scenario's law): the estimates equal one
    `step` per sample on the recorded measurements and the inputs held before them."""
    from tanksynth.sim.scenarios import InputSchedule
    monkeypatch.setenv("TANKSYNTH_ESTIMATOR_BACKEND", "horizon")
    est = _ekf(hybrid_plant)
    law = InputSchedule((0.0, 200.0), ((90 * LPH, 80 * LPH), (60 * LPH, 100 * LPH)))
    u0 = np.array([90 * LPH, 80 * LPH])
    res = simulate(hybrid_plant, ts=1.0, steps=N, x0=[0.3, 0.2, 0.25], seeds=np.arange(3),
                   controller=law, estimator=EstimatorAdapter(est), u_init=u0,
                   x_hat0=np.tile([0.25, 0.15, 0.2], (3, 1)), measurement_std=1e-3,
                   process_std=1e-5)
    ref = est.batch(3)
    monkeypatch.setenv("TANKSYNTH_ESTIMATOR_BACKEND", "step")
    ref.reset()
    u_prev = np.tile(u0, (3, 1))
    for k in range(N + 1):
        xh = ref.step(res.y[:, k], u_prev)
        _agree(res.x_hat[:, k], xh)
        if k < N:
            u_prev = res.u[:, k]
    assert np.abs(res.u[:, 250] - [60 * LPH, 100 * LPH]).max() == 0.0


@pytest.mark.parametrize("family", ["ekf", "ukf"])
def test_observed_mask_ignores_the_values_where_unobserved_on_both_paths(monkeypatch, tank_plant,
                                                                         family):
    """Issue 29 (break): `run_states` with missing outputs gave other numbers through the steps
    (``step``, or ``auto`` before a kernel is built) than through the masked horizon kernel
    when ``Y`` held anything but the model's prediction where unobserved (3e-10 measured on
    the UKF's states): `step_observed` now feeds the prediction there too, as the kernel does,
    so both paths agree bit for bit and the values there do not matter."""
    est = FAMILIES[family](tank_plant)
    Y, U = _data(tank_plant, 1, seed=5, samples=300)
    observed = np.random.default_rng(3).random((300, tank_plant.q)) > 0.3
    observed[0] = observed[150] = False                    # nothing observed at two samples
    runs = []
    for fill in (0.0, 5.0):
        Yf = np.where(observed, Y[:, 0], fill)
        (s_h, *_), (s_s, *_) = _both(monkeypatch, est, Yf, U[:, 0], observed, method="run_states")
        assert est._horizons[True].masked
        assert np.array_equal(s_h, s_s)
        runs.append(s_h)
    assert np.array_equal(runs[0], runs[1])
