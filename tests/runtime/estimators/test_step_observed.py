"""`KernelEstimator.step_observed`: a Kalman step that leaves unmeasured outputs out of the
correction, against the hand-written Kalman equations on the ZOH model of a linear(ised) plant."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.errors import DimensionError
from tanksynth.plants import three_tank
from tanksynth.runtime.estimators import KalmanFilter, KalmanTuning, UKFTuning, UnscentedKalmanFilter

X0 = np.array([0.40, 0.20, 0.30])
U0 = np.array([3.5e-5, 3.75e-5])


def kalman():
    plant = three_tank()
    tuning = KalmanTuning(Q=1e-8 * np.eye(3), R=np.diag([4e-6, 9e-6, 1e-6]), P0=1e-4 * np.eye(3),
                          x0=X0 + [0.01, -0.01, 0.005], ts=1.0, operating_point=(X0, U0))
    return KalmanFilter(plant, tuning, backend="vm"), tuning


def by_hand(kf, tuning, y, observed):
    Ad, Bd, cd, C, dy = kf.model.linear_matrices()
    x, P = kf.x_hat, kf.covariance
    xp = Ad @ x + Bd @ U0 + cd
    Pp = Ad @ P @ Ad.T + tuning.Q
    if not observed.any():
        return xp, Pp
    H = C[observed]
    R = tuning.R[np.ix_(observed, observed)]
    S = H @ Pp @ H.T + R
    K = Pp @ H.T @ np.linalg.inv(S)
    I_KH = np.eye(3) - K @ H
    return xp + K @ (y[observed] - H @ xp - dy[observed]), I_KH @ Pp @ I_KH.T + K @ R @ K.T


@pytest.mark.parametrize("observed", [[True, False, True], [False, True, False], [False] * 3])
def test_matches_the_kalman_update_of_the_observed_outputs(observed):
    observed = np.array(observed)
    kf, tuning = kalman()
    kf.step(X0 + [0.002, 0.0, -0.001], U0)  # leave the initial state
    y = X0 + [0.003, -0.002, 0.001]
    x_ref, P_ref = by_hand(kf, tuning, y, observed)
    x = kf.step_observed(np.where(observed, y, 123.0), U0, observed)   # unobserved values unused
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(kf.covariance, P_ref, rtol=1e-8, atol=1e-18)
    # the nominal R is back: the next full step is the ordinary one
    x_ref, P_ref = by_hand(kf, tuning, y, np.ones(3, bool))
    np.testing.assert_allclose(kf.step(y, U0), x_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(kf.covariance, P_ref, rtol=1e-8, atol=1e-18)


def test_ukf_with_nothing_observed_ignores_y_and_reads_nothing():
    plant = three_tank()
    tuning = UKFTuning(Q=1e-8 * np.eye(3), R=1e-6 * np.eye(3), P0=1e-4 * np.eye(3), x0=X0, ts=1.0)
    a, b, full = (UnscentedKalmanFilter(plant, tuning, backend="vm") for _ in range(3))
    xa = a.step_observed(X0, U0, [False] * 3)
    xb = b.step_observed(X0 + 0.05, U0, [False] * 3)
    np.testing.assert_allclose(xa, xb, rtol=0, atol=1e-14)
    np.testing.assert_allclose(a.covariance, b.covariance, rtol=1e-10, atol=0)
    full.step(X0, U0)
    # nothing read: the covariance is the prediction's, larger than after a full update
    assert np.trace(a.covariance) > 10 * np.trace(full.covariance)


def test_a_mask_of_another_size_is_refused():
    kf, _ = kalman()
    with pytest.raises(DimensionError, match="observed must be 3 booleans"):
        kf.step_observed(X0, U0, [True, False])
