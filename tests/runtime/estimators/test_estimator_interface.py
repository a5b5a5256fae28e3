"""One interface for every estimator: batch = single runs, shapes, bad tunings, PD errors."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.runtime.estimators import (AdaptiveKalmanFilter, AdaptiveKalmanTuning,
                                         AdaptiveScalingKalmanFilter, AdaptiveScalingTuning,
                                         ConsensusFilter, ConsensusTuning, CovarianceError,
                                         ExtendedKalmanFilter, KalmanFilter, KalmanTuning,
                                         LuenbergerObserver, LuenbergerTuning, NARXEstimator,
                                         NARXTuning, UKFTuning, UnscentedKalmanFilter)
from tanksynth.errors import DimensionError, SpecError
from tanksynth.plants.hybrid_three_tank import LPH

M = 4
STEPS = 25
Q3 = np.diag([1e-3, 2e-3, 1e-3])
R1 = np.array([[1e-2]])


def _narx_tuning(n=3, q=1, delays=2, hidden=5, ts=1.0, x0=(0.3, 0.3, 0.3)):
    rng = np.random.default_rng(0)
    nin = n + q + delays * n
    return NARXTuning(W1=0.3 * rng.standard_normal((hidden, nin)), b1=np.zeros(hidden),
                      W2=0.3 * rng.standard_normal((n, hidden)), b2=np.zeros(n),
                      in_mean=np.full(nin, 0.3), in_scale=np.full(nin, 0.1),
                      out_mean=np.full(n, 0.3), out_scale=np.full(n, 0.01), x0=x0, ts=ts,
                      delays=delays)


def _estimators(fault_plant, hybrid_plant):
    x0 = [1.0, 1.0, 1.0]
    hyb = KalmanTuning(Q=1e-8 * np.eye(3), R=[[1e-6]], P0=1e-3 * np.eye(3),
                       x0=[0.3, 0.3, 0.3], ts=1.0)
    return {
        "kf": (fault_plant, KalmanFilter(fault_plant, KalmanTuning(Q=Q3, R=R1, P0=np.eye(3), x0=x0,
                                                                   ts=0.1))),
        "ekf_hybrid": (hybrid_plant, ExtendedKalmanFilter(hybrid_plant, hyb)),
        "ukf_hybrid": (hybrid_plant, UnscentedKalmanFilter(hybrid_plant, UKFTuning(
            Q=hyb.Q, R=hyb.R, P0=hyb.P0, x0=hyb.x0, ts=1.0))),
        "narx_hybrid": (hybrid_plant, NARXEstimator(hybrid_plant, _narx_tuning())),
        "akf": (fault_plant, AdaptiveKalmanFilter(fault_plant, AdaptiveKalmanTuning(
            Q0=Q3, R=R1, P0=np.eye(3), x0=x0, ts=0.1, window=5))),
        "askf": (fault_plant, AdaptiveScalingKalmanFilter(fault_plant, AdaptiveScalingTuning(
            Q=Q3, R=R1, P0=np.eye(3), x0=x0, ts=0.1, a=0.3, b=0.5, c=0.2))),
        "consensus": (fault_plant, ConsensusFilter(fault_plant, ConsensusTuning(
            Q=Q3, R=(R1, 2 * R1), P0=np.eye(3), x0=x0, ts=0.1))),
        "luenberger_current": (fault_plant, LuenbergerObserver(fault_plant, LuenbergerTuning(
            L=[[0.5], [0.3], [0.9]], x0=x0, ts=0.1))),
        "luenberger_continuous": (fault_plant, LuenbergerObserver(fault_plant, LuenbergerTuning(
            L=[[855.0], [509 / 3], [41.0]], x0=x0, ts=0.01, form="continuous"))),
        "luenberger_nonlinear": (hybrid_plant, LuenbergerObserver(hybrid_plant, LuenbergerTuning(
            L=[[0.01], [0.01], [0.05]], x0=[0.3, 0.3, 0.3], ts=1.0, form="continuous",
            substeps=2))),
    }


def _data(plant, est, seed):
    rng = np.random.default_rng(seed)
    q = est.q
    if plant.name == "hybrid_three_tank":
        Y = 0.3 + 0.01 * rng.standard_normal((STEPS, M, q))
        U = 100 * LPH * (1 + 0.2 * rng.standard_normal((STEPS, M, plant.m)))
        X0 = 0.3 + 0.02 * rng.standard_normal((M, plant.n))
    else:
        Y = 2.0 + 0.1 * rng.standard_normal((STEPS, M, q))
        U = 1.0 + 0.1 * rng.standard_normal((STEPS, M, plant.m))
        X0 = 1.0 + 0.1 * rng.standard_normal((M, plant.n))
    return Y, U, X0


@pytest.fixture(scope="module")
def estimators(fault_plant, hybrid_plant):
    return _estimators(fault_plant, hybrid_plant)


@pytest.mark.parametrize("name", ["kf", "ekf_hybrid", "ukf_hybrid", "narx_hybrid", "akf", "askf",
                                  "consensus", "luenberger_current", "luenberger_continuous",
                                  "luenberger_nonlinear"])
def test_batch_equals_single_runs_exactly(estimators, name):
    plant, est = estimators[name]
    Y, U, X0 = _data(plant, est, seed=len(name))
    batch = est.batch(M)
    batch.reset(X0)
    XB = batch.run(Y, U)
    assert XB.shape == (STEPS, M, plant.n)
    for r in range(M):
        est.reset(X0[r])
        XS = est.run(Y[:, r], U[:, r])
        np.testing.assert_array_equal(XB[:, r], XS, err_msg=f"{name}: run {r}")
    assert batch.k == STEPS


def test_native_and_vm_kernels_agree(hybrid_plant):
    tk = KalmanTuning(Q=1e-8 * np.eye(3), R=[[1e-6]], P0=1e-3 * np.eye(3), x0=[0.3, 0.3, 0.3],
                      ts=1.0)
    vm = ExtendedKalmanFilter(hybrid_plant, tk, backend="vm")
    auto = ExtendedKalmanFilter(hybrid_plant, tk, backend="auto")
    assert vm.backend == "vm" and auto.backend in ("vm", "native")
    rng = np.random.default_rng(1)
    for _ in range(20):
        y = 0.3 + 0.01 * rng.standard_normal(1)
        u = 100 * LPH * np.ones(2)
        np.testing.assert_allclose(vm.step(y, u), auto.step(y, u), rtol=1e-14, atol=0)


def test_step_returns_copies_and_counts(estimators):
    plant, ekf = estimators["ekf_hybrid"]
    ekf.reset()
    x = ekf.step([0.3], [100 * LPH] * 2)
    x[:] = -1
    assert np.all(ekf.x_hat > 0) and ekf.k == 1
    ekf.reset([0.31, 0.32, 0.33])
    assert ekf.k == 0
    np.testing.assert_array_equal(ekf.x_hat, [0.31, 0.32, 0.33])


@pytest.mark.parametrize("y, u, match", [
    ([0.3, 0.3], [1e-5, 1e-5], "y must have shape"),
    ([0.3], [1e-5], "u must have shape"),
    ([0.3], [[1e-5, 1e-5]], "u must have shape"),
    ([np.nan], [1e-5, 1e-5], "finite"),
    ([0.3], [np.inf, 1e-5], "finite"),
])
def test_wrong_shapes_and_values_are_clear_errors(estimators, y, u, match):
    _, ekf = estimators["ekf_hybrid"]
    with pytest.raises(DimensionError, match=match):
        ekf.step(y, u)


def test_batch_shape_errors(estimators):
    _, ekf = estimators["ekf_hybrid"]
    batch = ekf.batch(3)
    with pytest.raises(DimensionError, match=r"\(3, 1\)"):
        batch.step(np.zeros((2, 1)), [1e-5, 1e-5])
    with pytest.raises(DimensionError, match=r"\(3, 2\) or \(2,\)"):
        batch.step(np.zeros((3, 1)), np.zeros((3, 3)))
    with pytest.raises(DimensionError, match="x0"):
        batch.reset(np.zeros((2, 3)))
    out = batch.step(np.full((3, 1), 0.3), [1e-5, 1e-5])      # (m,) broadcasts to every run
    assert out.shape == (3, 3)


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(Q=-np.eye(3)), SpecError, "Q must be positive semidefinite"),
    (dict(R=[[0.0]]), SpecError, "R must be positive definite"),
    (dict(P0=np.diag([1.0, 0.0, 1.0])), SpecError, "P0 must be positive definite"),
    (dict(P0=[[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), SpecError, "symmetric"),
    (dict(Q=np.eye(2)), DimensionError, "agree on the number of states"),
    (dict(ts=0.0), SpecError, "ts must be > 0"),
    (dict(substeps=0), SpecError, "substeps"),
    (dict(jacobian_eps=-1.0), SpecError, "jacobian_eps"),
    (dict(x0=[0.3, np.nan, 0.3]), DimensionError, "non-finite"),
])
def test_bad_kalman_tunings(kwargs, error, match):
    base = dict(Q=1e-8 * np.eye(3), R=[[1e-6]], P0=1e-3 * np.eye(3), x0=[0.3, 0.3, 0.3], ts=1.0)
    with pytest.raises(error, match=match):
        KalmanTuning(**{**base, **kwargs})


def test_tuning_that_does_not_fit_the_plant(hybrid_plant):
    tk = KalmanTuning(Q=1e-8 * np.eye(3), R=1e-6 * np.eye(2), P0=1e-3 * np.eye(3),
                      x0=[0.3, 0.3, 0.3], ts=1.0)
    with pytest.raises(DimensionError, match="R must be 1 x 1"):
        ExtendedKalmanFilter(hybrid_plant, tk)


@pytest.mark.parametrize("abc", [(0.5, 0.5, 0.5), (0.2, 0.2, 0.2), (1.2, -0.1, -0.1)])
def test_adaptive_scaling_weights_must_be_a_convex_combination(abc):
    a, b, c = abc
    with pytest.raises(SpecError, match=r"a \+ b \+ c must equal 1|must be >= 0"):
        AdaptiveScalingTuning(Q=Q3, R=R1, P0=np.eye(3), x0=[1, 1, 1], ts=0.1, a=a, b=b, c=c)


@pytest.mark.parametrize("window", [0, -3, 2.5, True])
def test_akf_window_must_be_a_positive_integer(window):
    with pytest.raises(SpecError, match="window must be an integer >= 1"):
        AdaptiveKalmanTuning(Q0=Q3, R=R1, P0=np.eye(3), x0=[1, 1, 1], ts=0.1, window=window)


def test_akf_form_and_ukf_alpha_checked():
    with pytest.raises(SpecError, match="form"):
        AdaptiveKalmanTuning(Q0=Q3, R=R1, P0=np.eye(3), x0=[1, 1, 1], ts=0.1, window=5,
                             form="magic")
    with pytest.raises(SpecError, match="alpha"):
        UKFTuning(Q=Q3, R=R1, P0=np.eye(3), x0=[1, 1, 1], ts=0.1, alpha=2.0)


def test_adaptive_scaling_refuses_invisible_process_noise(fault_plant):
    # seed 004 with the noise through B = e1 only: C B Q B' C' = 0 (eq. 36 divides by zero)
    tun = AdaptiveScalingTuning(Q=[[1e-3]], R=R1, P0=np.eye(3), x0=[1, 1, 1], ts=0.1,
                                a=0.2, b=0.5, c=0.3, G=[[1.0], [0.0], [0.0]])
    with pytest.raises(SpecError, match="zero trace"):
        AdaptiveScalingKalmanFilter(fault_plant, tun)


def test_consensus_needs_a_list_of_sensor_covariances():
    with pytest.raises(SpecError, match="R must be a non-empty list"):
        ConsensusTuning(Q=Q3, R=R1, P0=np.eye(3), x0=[1, 1, 1], ts=0.1)


def test_luenberger_gain_shape(fault_plant):
    with pytest.raises(DimensionError, match="L must be 3 x 1"):
        LuenbergerObserver(fault_plant, LuenbergerTuning(L=np.ones((3, 2)), x0=[1, 1, 1], ts=0.1))
    with pytest.raises(SpecError, match="form"):
        LuenbergerTuning(L=np.ones((3, 1)), x0=[1, 1, 1], ts=0.1, form="other")


def test_non_pd_covariance_is_an_error_naming_the_step(fault_plant):
    """A collapsing covariance raises CovarianceError at the step it happens, never NaN."""
    # process noise zero, a contracting model and a huge measurement weight: P -> 0 until the
    # rounding makes it indefinite
    tun = KalmanTuning(Q=np.zeros((3, 3)), R=R1, P0=np.eye(3), x0=[1, 1, 1], ts=0.5)
    kf = KalmanFilter(fault_plant, tun, backend="vm")
    last = None
    with pytest.raises(CovarianceError) as info:
        for _ in range(5000):
            last = kf.step([2.0], [1.0])
    err = info.value
    assert err.step == kf.k + 1 and err.run is None
    assert f"step {err.step}" in str(err) and "covariance" in err.matrix
    assert np.all(np.isfinite(last)) and np.all(np.isfinite(kf.x_hat))
    np.testing.assert_array_equal(kf.x_hat, last)              # state of the last good step


def test_batch_covariance_error_names_the_run(fault_plant):
    tun = AdaptiveKalmanTuning(Q0=Q3, R=R1, P0=np.eye(3), x0=[1, 1, 1], ts=0.1, window=5)
    batch = AdaptiveKalmanFilter(fault_plant, tun, runs=3)
    batch._Q[1] = -2 * np.eye(3)                              # corrupt run 1 on purpose
    with pytest.raises(CovarianceError, match=r"predicted covariance .* step 1 \(run 1\)") as info:
        batch.step(np.full((3, 1), 2.0), [1.0])
    assert info.value.run == 1 and info.value.step == 1


@pytest.mark.parametrize("name", ["kf", "akf", "askf", "consensus", "luenberger_current",
                                  "luenberger_nonlinear"])
def test_batch_run_equals_its_steps(estimators, name):
    """`run` on batch arrays checks them once and calls `_advance`: the numbers of `step`; a
    non-finite measurement still fails at its own step (the step-by-step route)."""
    plant, est = estimators[name]
    Y, U, X0 = _data(plant, est, seed=3)
    a, b = est.batch(M), est.batch(M)
    a.reset(X0)
    b.reset(X0)
    XA = a.run(Y, U)
    XB = np.array([b.step(Y[i], U[i]) for i in range(STEPS)])
    np.testing.assert_array_equal(XA, XB)
    assert a.k == b.k == STEPS
    bad = Y.copy()
    bad[7, 1, 0] = np.nan
    a.reset(X0)
    with pytest.raises(DimensionError, match="step 8"):
        a.run(bad, U)
    assert a.k == 7
