"""Unscented Kalman filter (seed 002 eq. 23-40), additive noise.

Sigma points of ``x(k-1), P(k-1)`` (eq. 23-25, ``lambda = alpha^2 (n +
kappa) - n``), propagated through the sampled model (eq. 26); weighted
mean and covariance (eq. 28-30, 32-34, ``beta = 2`` for Gaussian priors);
output sigma points (eq. 27, 31); gain ``K = Pxy Pyy^-1`` (eq. 35-38);
correction (eq. 39-40)::

    x(k) = x(k|k-1) + K (y - y(k|k-1)),   P(k) = P(k|k-1) - K Pyy K'

The covariance update is symmetrised and checked for positive
definiteness (eq. 40 has no Joseph form: there is no ``H``; for a linear
model it coincides with the Joseph form of the Kalman filter). The square
root of ``(n + lambda) P`` is the lower Cholesky factor.

Erratum (seed 002 eq. 27): evaluating ``h`` at the *propagated* sigma
points leaves the process noise ``Q`` out of ``Pyy`` and ``Pxy``, so the
filter does not reduce to the Kalman filter on a linear plant. By default
(``redraw=True``, the additive-noise UKF of Julier-Uhlmann / Wan-van der
Merwe) the output sigma points are redrawn from ``x(k|k-1), P(k|k-1)``;
``redraw=False`` follows eq. 27 literally.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.base import CovarianceKernelEstimator, DiscreteModel, column_major
from tanksynth.runtime.estimators.kalman import model_from_tuning
from tanksynth.runtime.estimators.kernels import sx_cholesky, sx_min, sx_spd_inverse, sx_symmetrize
from tanksynth.runtime.estimators.tuning import (agree_on_states, artefact_gains,
                                                 noise_covariances, number_in, operating_point,
                                                 positive_float, positive_int, require_tuning,
                                                 set_fields)

__all__ = ["UKFTuning", "UnscentedKalmanFilter", "ukf_weights"]


@dataclass(frozen=True, eq=False)
class UKFTuning:
    """Tuning of the unscented Kalman filter: the artefact.

    Attributes
    ----------
    Q, R, P0, x0, ts, substeps, clip, operating_point
        As in `KalmanTuning` (state/output units).
    alpha : float
        Spread of the sigma points, 0 < alpha <= 1 (seed 002: 0.001 to 1);
        dimensionless.
    beta : float
        Prior-distribution parameter, 2 for Gaussian (seed 002).
    kappa : float
        Secondary scaling, 0 for state estimation (seed 002).
    redraw : bool
        Redraw the sigma points from the prediction before the output map
        (default; see the module notes) or use the propagated ones (eq. 27).
    """

    Q: np.ndarray
    R: np.ndarray
    P0: np.ndarray
    x0: np.ndarray
    ts: float
    alpha: float = 1e-3
    beta: float = 2.0
    kappa: float = 0.0
    redraw: bool = True
    substeps: int = 1
    clip: bool = False
    operating_point: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        set_fields(self, **noise_covariances(self))
        agree_on_states(self.x0, Q=self.Q, P0=self.P0)
        n = self.x0.size
        set_fields(self, ts=positive_float(self.ts, "ts"),
                   substeps=positive_int(self.substeps, "substeps"),
                   alpha=number_in(self.alpha, "alpha", above=0.0, at_most=1.0),
                   beta=positive_float(self.beta, "beta", allow_zero=True),
                   kappa=number_in(self.kappa, "kappa", above=-n,
                                   expected="finite with n + kappa > 0"),
                   operating_point=operating_point(self.operating_point))

    def gains(self) -> dict[str, np.ndarray]:
        """Tuning arrays for the artefact (``alpha, beta, kappa`` as 1-vectors); the initial
        estimate ``x0`` is stored as ``x_hat0``."""
        return artefact_gains(self, Q=self.Q, R=self.R, P0=self.P0, x_hat0=self.x0,
                              alpha=np.array([self.alpha]), beta=np.array([self.beta]),
                              kappa=np.array([self.kappa]), redraw=np.array([float(self.redraw)]))


def ukf_weights(n: int, alpha: float, beta: float, kappa: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Sigma-point weights of seed 002 eq. 25 and 32-34.

    Parameters
    ----------
    n : int
        State dimension.
    alpha : float
        Spread of the sigma points, in (0, 1] (dimensionless).
    beta : float
        Prior-distribution weight (>= 0, dimensionless).
    kappa : float
        Secondary scaling (dimensionless), n + kappa > 0.

    Returns
    -------
    Wm, Wc : ndarray, shape (2 n + 1,)
        Mean and covariance weights (dimensionless).
    gamma : float
        ``sqrt(n + lambda)``, the sigma-point spread (dimensionless).
    """
    lam = alpha ** 2 * (n + kappa) - n
    Wm = np.full(2 * n + 1, 1.0 / (2.0 * (n + lam)))
    Wc = Wm.copy()
    Wm[0] = lam / (n + lam)
    Wc[0] = lam / (n + lam) + (1.0 - alpha ** 2 + beta)
    return Wm, Wc, float(np.sqrt(n + lam))


class UnscentedKalmanFilter(CovarianceKernelEstimator):
    """Unscented Kalman filter (seed 002 eq. 23-40).

    Parameters
    ----------
    plant : Plant
    tuning : UKFTuning
    runs : int, optional
        Number of parallel runs (None: a single run).
    backend : {"auto", "native", "vm"}
    model : DiscreteModel, optional
        A model to use instead of the tuning's.

    Notes
    -----
    ``extra`` holds the innovation ``y - y(k|k-1)`` (q) and the gain
    (n q, column-major).
    """

    method = "ukf"
    noise_in_parameters = True
    check_names = ("covariance P(k-1) (sigma points)", "predicted covariance P(k|k-1)",
                   "innovation covariance Pyy(k)", "updated covariance P(k|k)")

    def __init__(self, plant: Plant, tuning: UKFTuning, runs: int | None = None,
                 backend: str = "auto", *, model: DiscreteModel | None = None):
        require_tuning(self, tuning, UKFTuning)
        model = model if model is not None else model_from_tuning(plant, tuning)
        super().__init__(plant, tuning, model, runs, backend)

    def _build(self) -> ca.Function:
        mdl, tun = self.model, self.tuning
        n, m, q = self.n, self.m, self.q
        S = ca.SX.sym("state", n + n * n)
        y = ca.SX.sym("y", q)
        u = ca.SX.sym("u", m)
        p = ca.SX.sym("params", n * n + q * q)
        x = S[:n]
        P = ca.reshape(S[n:], n, n)
        Q = ca.reshape(p[:n * n], n, n)
        R = ca.reshape(p[n * n:], q, q)
        Wm, Wc, gamma = ukf_weights(n, tun.alpha, tun.beta, tun.kappa)
        L, piv0 = sx_cholesky(P)                                     # eq. 24
        chi = [x] + [x + gamma * L[:, i] for i in range(n)] + [x - gamma * L[:, i] for i in range(n)]
        X = [mdl.predict_sx(c, u) for c in chi]                     # eq. 26
        xp = sum((Wm[i] * X[i] for i in range(1, 2 * n + 1)), Wm[0] * X[0])      # eq. 28
        dX = [Xi - xp for Xi in X]                                  # eq. 30
        Pp = sx_symmetrize(sum((Wc[i] * dX[i] @ dX[i].T for i in range(1, 2 * n + 1)),
                               Wc[0] * dX[0] @ dX[0].T) + Q)        # eq. 29
        Lp, piv_p = sx_cholesky(Pp)
        if tun.redraw:
            X = [xp] + [xp + gamma * Lp[:, i] for i in range(n)] + \
                [xp - gamma * Lp[:, i] for i in range(n)]
            dX = [Xi - xp for Xi in X]
        Yp = [mdl.output_sx(c) for c in X]                          # eq. 27
        yp = sum((Wm[i] * Yp[i] for i in range(1, 2 * n + 1)), Wm[0] * Yp[0])    # eq. 31
        dY = [Yi - yp for Yi in Yp]                                 # eq. 37
        Pyy = sx_symmetrize(sum((Wc[i] * dY[i] @ dY[i].T for i in range(1, 2 * n + 1)),
                                Wc[0] * dY[0] @ dY[0].T) + R)       # eq. 35
        Pxy = sum((Wc[i] * dX[i] @ dY[i].T for i in range(1, 2 * n + 1)), Wc[0] * dX[0] @ dY[0].T)
        Pyy_inv, piv_s = sx_spd_inverse(Pyy)
        K = Pxy @ Pyy_inv                                           # eq. 38
        nu = y - yp
        xn = mdl.clip_sx(xp + K @ nu)                               # eq. 39
        Pn = sx_symmetrize(Pp - K @ Pyy @ K.T)                      # eq. 40
        _, piv_n = sx_cholesky(Pn)
        checks = ca.vertcat(sx_min(piv0), sx_min(piv_p), sx_min(piv_s), sx_min(piv_n), ca.sum1(xn))
        return ca.Function("ukf_step", [S, y, u, p],
                           [ca.densify(ca.vertcat(xn, ca.reshape(Pn, n * n, 1))),
                            ca.densify(checks), ca.densify(ca.vertcat(nu, ca.reshape(K, n * q, 1)))],
                           ["state", "y", "u", "params"], ["state_new", "checks", "extra"])

    def _params(self) -> np.ndarray:
        return np.concatenate([column_major(self.tuning.Q), column_major(self.tuning.R)])

    def _initial_state(self, X0: np.ndarray) -> np.ndarray:
        out = np.zeros((X0.shape[0], self.n + self.n * self.n))
        out[:, :self.n] = X0
        out[:, self.n:] = column_major(self.tuning.P0)
        return out

    @property
    def gain(self) -> np.ndarray:
        """Gain of the last step, shape (n, q) or (M, n, q)."""
        n, q = self.n, self.q
        K = self._extra[:, q:q + n * q].reshape(-1, q, n).transpose(0, 2, 1)
        return K[0].copy() if self.runs is None else K.copy()
