"""Adaptive Kalman (seed 000), adaptive scaling and consensus filters (seed 004)."""

from __future__ import annotations

import numpy as np
import pytest
from estimator_helpers import linear_data

from tanksynth.runtime.estimators import (AdaptiveKalmanFilter, AdaptiveKalmanTuning,
                                         AdaptiveScalingKalmanFilter, AdaptiveScalingTuning,
                                         ConsensusFilter, ConsensusTuning, KalmanFilter,
                                         KalmanTuning)
from tanksynth.analysis.linearize import equilibrium_input

X_OP = np.array([0.40, 0.20, 0.30])
Q_TRUE = np.diag([4e-6, 1e-6, 2.25e-6])       # m^2 per sample
R_TRUE = 1e-6 * np.eye(3)                     # 1 mm level sensors


@pytest.fixture(scope="module")
def seed000_model(tank_plant):
    u_op = equilibrium_input(tank_plant, X_OP).u0
    return u_op


def _akf(tank_plant, u_op, window, form="full"):
    tun = AdaptiveKalmanTuning(Q0=1e-10 * np.eye(3), R=R_TRUE, P0=1e-4 * np.eye(3), x0=X_OP,
                               ts=1.0, window=window, form=form, q_floor=1e-12,
                               operating_point=(X_OP, u_op))
    return AdaptiveKalmanFilter(tank_plant, tun)


@pytest.mark.slow
def test_akf_recovers_a_known_q_within_20_percent(tank_plant, seed000_model):
    """Seed 000 eq. 36 with window 800 on synthetic data from the linearised three-tank."""
    u_op = seed000_model
    akf = _akf(tank_plant, u_op, window=800)
    X, Y, U = linear_data(akf.model, 5000, Q_TRUE, R_TRUE, X_OP, seed=0,
                          u=np.tile(u_op, (5000, 1)))
    akf.run(Y, U)
    Qh = akf.Q
    rel = np.abs(np.diag(Qh) / np.diag(Q_TRUE) - 1)
    assert rel.max() < 0.2, rel
    off = Qh - np.diag(np.diag(Qh))
    assert np.abs(off).max() < 0.1 * Q_TRUE.max()
    assert np.all(np.linalg.eigvalsh(Qh) >= 1e-12 * (1 - 1e-9))
    # the adapted filter tracks the states better than the initial (far too small) Q would
    kf = KalmanFilter(tank_plant, KalmanTuning(Q=1e-10 * np.eye(3), R=R_TRUE, P0=1e-4 * np.eye(3),
                                               x0=X_OP, ts=1.0, operating_point=(X_OP, u_op)))
    akf.reset()
    e_akf = akf.run(Y, U)[2500:] - X[2500:]
    e_kf = kf.run(Y, U)[2500:] - X[2500:]
    assert np.sqrt(np.mean(e_akf ** 2)) < 0.8 * np.sqrt(np.mean(e_kf ** 2))


@pytest.mark.slow
def test_akf_steady_state_form_is_biased(tank_plant, seed000_model):
    """Eq. 37 (K C_v K') drops P(k) - F P(k-1) F': not within 20% here (report finding)."""
    u_op = seed000_model
    akf = _akf(tank_plant, u_op, window=800, form="steady_state")
    X, Y, U = linear_data(akf.model, 5000, Q_TRUE, R_TRUE, X_OP, seed=0,
                          u=np.tile(u_op, (5000, 1)))
    akf.run(Y, U)
    ratio = np.diag(akf.Q) / np.diag(Q_TRUE)
    assert np.abs(ratio - 1).max() > 0.3


def test_akf_before_the_window_fills_is_the_kf(fault_plant):
    Q, R, P0 = np.diag([1e-3, 2e-3, 1e-3]), np.array([[1e-2]]), np.eye(3)
    akf = AdaptiveKalmanFilter(fault_plant, AdaptiveKalmanTuning(Q0=Q, R=R, P0=P0, x0=[1, 1, 1],
                                                                 ts=0.1, window=60))
    kf = KalmanFilter(fault_plant, KalmanTuning(Q=Q, R=R, P0=P0, x0=[1, 1, 1], ts=0.1))
    X, Y, U = linear_data(kf.model, 59, Q, R, [4, 4 / 3, 4], seed=1, u=np.ones((59, 1)))
    np.testing.assert_allclose(akf.run(Y, U), kf.run(Y, U), rtol=0, atol=1e-12)
    akf.step(Y[-1], U[-1])                                     # window full: Q adapts
    assert not np.allclose(akf.Q, Q)


def test_adaptive_scaling_with_a_one_is_the_kf(fault_plant):
    """a = 1: phi_k = phi_0 = 1 for all k, i.e. the Kalman filter (seed 004 eq. 36-38)."""
    Q, R, P0 = np.diag([1e-3, 2e-3, 1e-3]), np.array([[1e-2]]), np.eye(3)
    askf = AdaptiveScalingKalmanFilter(fault_plant, AdaptiveScalingTuning(
        Q=Q, R=R, P0=P0, x0=[1, 1, 1], ts=0.1, a=1.0, b=0.0, c=0.0))
    kf = KalmanFilter(fault_plant, KalmanTuning(Q=Q, R=R, P0=P0, x0=[1, 1, 1], ts=0.1))
    X, Y, U = linear_data(kf.model, 200, Q, R, [4, 4 / 3, 4], seed=2, u=np.ones((200, 1)))
    np.testing.assert_allclose(askf.run(Y, U), kf.run(Y, U), rtol=0, atol=1e-12)
    assert askf.phi == 1.0


def test_adaptive_scaling_inflates_under_a_model_mismatch(fault_plant):
    """A leak (delta_bar) the model does not know makes the innovations large: phi grows."""
    Q, R, P0 = 1e-6 * np.eye(3), np.array([[1e-4]]), 1e-2 * np.eye(3)
    faulty = fault_plant.with_parameters({"delta_bar": 1.0})
    truth = KalmanFilter(faulty, KalmanTuning(Q=Q, R=R, P0=P0, x0=[4, 4 / 3, 4], ts=0.1)).model
    X, Y, U = linear_data(truth, 300, Q, R, [4, 4 / 3, 4], seed=4, u=np.full((300, 1), 2.0))
    tun = dict(Q=Q, R=R, P0=P0, x0=[4, 4 / 3, 4], ts=0.1)
    askf = AdaptiveScalingKalmanFilter(fault_plant, AdaptiveScalingTuning(**tun, a=0.1, b=0.6,
                                                                         c=0.3))
    kf = KalmanFilter(fault_plant, KalmanTuning(**tun))
    e_as = askf.run(Y, U) - X
    e_kf = kf.run(Y, U) - X
    assert askf.phi > 10
    assert np.sqrt(np.mean(e_as[100:, 2] ** 2)) < np.sqrt(np.mean(e_kf[100:, 2] ** 2))


def test_consensus_equals_the_central_kf_on_stacked_sensors(fault_plant):
    Q, P0 = np.diag([1e-3, 2e-3, 1e-3]), np.eye(3)
    Rs = (np.array([[1e-2]]), np.array([[4e-2]]), np.array([[2.5e-3]]))
    cf = ConsensusFilter(fault_plant, ConsensusTuning(Q=Q, R=Rs, P0=P0, x0=[1, 1, 1], ts=0.1))
    base = KalmanFilter(fault_plant, KalmanTuning(Q=Q, R=Rs[0], P0=P0, x0=[1, 1, 1], ts=0.1))
    mdl = base.model
    rng = np.random.default_rng(5)
    x = np.array([4.0, 4 / 3, 4.0])
    # the central KF on the stacked measurement, in numpy
    C = np.vstack([mdl.C] * 3)
    R = np.diag([r[0, 0] for r in Rs])
    xh, P = np.ones(3), P0.copy()
    for k in range(150):
        u = np.array([2.0 if k < 50 else 1.0])
        x = mdl.Ad @ x + mdl.Bd @ u + rng.multivariate_normal(np.zeros(3), Q)
        y = C @ x + mdl.dy[0] + rng.normal(0, np.sqrt(np.diag(R)))
        xp = mdl.Ad @ xh + mdl.Bd @ u + mdl.cd
        Pp = mdl.Ad @ P @ mdl.Ad.T + Q
        K = Pp @ C.T @ np.linalg.inv(C @ Pp @ C.T + R)
        xh = xp + K @ (y - C @ xp - mdl.dy[0])
        P = (np.eye(3) - K @ C) @ Pp @ (np.eye(3) - K @ C).T + K @ R @ K.T
        np.testing.assert_allclose(cf.step(y, u), xh, rtol=0, atol=1e-10)
        np.testing.assert_allclose(cf.prior, xp, rtol=0, atol=1e-10)
    np.testing.assert_allclose(cf.covariance, P, rtol=1e-8, atol=1e-14)
    assert cf.q == 3


def test_consensus_with_one_sensor_is_the_printed_algorithm(fault_plant):
    """N = 1: (NP)^-1 + H = P^-1 + C'R^-1C and eq. 50 propagates Pcal itself (Algorithm 1)."""
    Q, R, P0 = np.diag([1e-3, 2e-3, 1e-3]), np.array([[1e-2]]), np.eye(3)
    cf = ConsensusFilter(fault_plant, ConsensusTuning(Q=Q, R=(R,), P0=P0, x0=[1, 1, 1], ts=0.1))
    mdl = cf.model
    X, Y, U = linear_data(mdl, 60, Q, R, [4, 4 / 3, 4], seed=6, u=np.ones((60, 1)))
    xh, P = np.ones(3), P0.copy()
    H = mdl.C.T @ np.linalg.inv(R) @ mdl.C
    for k in range(60):
        xbar = mdl.Ad @ xh + mdl.Bd @ U[k] + mdl.cd                       # (51)
        Pk = mdl.Ad @ P @ mdl.Ad.T + Q                                    # (50)
        Pcal = np.linalg.inv(np.linalg.inv(Pk) + H)                       # (44), N = 1
        z = mdl.C.T @ np.linalg.inv(R) @ (Y[k] - mdl.dy)                  # (48)
        xh = xbar + Pcal @ (z - H @ xbar)                                 # (49)
        P = Pcal
        np.testing.assert_allclose(cf.step(Y[k], U[k]), xh, rtol=0, atol=1e-10)
    np.testing.assert_allclose(cf.covariance, P, rtol=1e-8)
