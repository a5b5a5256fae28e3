"""Kalman and extended Kalman filters (seed 000 eq. 29-34, seed 002 eq. 13-22).

One step, with ``u`` the input held over the interval that ends at ``y``::

    x(k|k-1) = F(x(k-1), u(k))                         (seed 000 eq. 30; seed 002 eq. 13)
    P(k|k-1) = Phi P(k-1) Phi' + Q                     (31; 14)
    S        = H P(k|k-1) H' + R                        (18)
    K        = P(k|k-1) H' S^-1                         (32; 20)
    x(k)     = x(k|k-1) + K (y - h(x(k|k-1)))           (33; 21)
    P(k)     = (I - K H) P(k|k-1) (I - K H)' + K R K'   (Joseph form of 34; 22), symmetrised

``F``/``Phi`` come from the `DiscreteModel`: the exact ZOH of a linear
plant or of the linearisation at an operating point (the CKF of seed 000),
or Runge-Kutta and the regularised Jacobian frozen at ``x(k-1)`` for a
nonlinear plant (the EKF of seed 002). On a hybrid plant the previous
``Phi`` is kept when ``x(k-1)`` lies on a switching surface (seed 002
section 3: "the Jacobian of the previous sampling instant is taken").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
import scipy.linalg as sla

from tanksynth.errors import SpecError
from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.base import (CovarianceKernelEstimator, DiscreteModel, column_major,
                                               discrete_model)
from tanksynth.runtime.estimators.kernels import sx_cholesky, sx_min, sx_spd_inverse, sx_symmetrize
from tanksynth.runtime.estimators.tuning import (agree_on_states, artefact_gains, as_spd,
                                                 fits_plant, noise_covariances, operating_point,
                                                 positive_float, positive_int, require_tuning,
                                                 set_fields)

__all__ = [
    "KalmanTuning",
    "ExtendedKalmanFilter",
    "KalmanFilter",
    "steady_state_gain",
    "model_from_tuning",
]


@dataclass(frozen=True, eq=False)
class KalmanTuning:
    """Tuning of a (extended) Kalman filter: the artefact.

    Attributes
    ----------
    Q : ndarray, shape (n, n)
        Process noise covariance (state units^2), symmetric positive
        semidefinite.
    R : ndarray, shape (q, q)
        Measurement noise covariance (output units^2), positive definite.
    P0 : ndarray, shape (n, n)
        Initial estimate covariance (state units^2), positive definite.
    x0 : ndarray, shape (n,)
        Initial estimate (state units).
    ts : float
        Sampling period (s).
    substeps : int
        Runge-Kutta steps per period (nonlinear model).
    jacobian_eps : float
        Torricelli-derivative regularisation (state units, m).
    switch_tol : float
        Switching-surface tolerance on hybrid plants (0 = exactly on it).
    clip : bool
        Clamp estimates to the plant's region box.
    operating_point : tuple of ndarray or None
        ``(x0, u0)``: filter on the ZOH linearisation there (seed 000 CKF)
        instead of the nonlinear model.
    """

    Q: np.ndarray
    R: np.ndarray
    P0: np.ndarray
    x0: np.ndarray
    ts: float
    substeps: int = 1
    jacobian_eps: float = 1e-6
    switch_tol: float = 0.0
    clip: bool = False
    operating_point: tuple[np.ndarray, np.ndarray] | None = field(default=None)

    def __post_init__(self) -> None:
        set_fields(self, **noise_covariances(self))
        agree_on_states(self.x0, Q=self.Q, P0=self.P0)
        set_fields(self, ts=positive_float(self.ts, "ts"),
                   substeps=positive_int(self.substeps, "substeps"),
                   jacobian_eps=positive_float(self.jacobian_eps, "jacobian_eps"),
                   switch_tol=positive_float(self.switch_tol, "switch_tol", allow_zero=True),
                   operating_point=operating_point(self.operating_point))

    def gains(self) -> dict[str, np.ndarray]:
        """The tuning matrices as float arrays (artefact gains); the initial
        estimate ``x0`` is stored as ``x_hat0``."""
        return artefact_gains(self, Q=self.Q, R=self.R, P0=self.P0, x_hat0=self.x0)


def model_from_tuning(plant: Plant, tuning: Any, operating_point: Any = None) -> DiscreteModel:
    """The `DiscreteModel` a Kalman-type tuning asks for, with shapes checked against the plant.

    Parameters
    ----------
    plant : Plant
        The plant.
    tuning : object
        A Kalman-type tuning (``Q``, ``R``, ``P0``, ``x0``, ``ts`` in s, model options).
    operating_point : tuple of ndarray, optional
        ``(x0, u0)`` (state, input units): the ZOH linearisation there; default the tuning's.

    Raises
    ------
    DimensionError
        ``Q``, ``R``, ``P0`` or ``x0`` do not fit the plant.
    """
    n, q = plant.n, plant.q
    fits_plant(tuning, plant, Q=(n, n), P0=(n, n), R=(q, q))
    op = operating_point if operating_point is not None else getattr(tuning, "operating_point", None)
    return discrete_model(plant, tuning.ts, operating_point=op,
                          substeps=getattr(tuning, "substeps", 1),
                          jacobian_eps=getattr(tuning, "jacobian_eps", 1e-6),
                          switch_tol=getattr(tuning, "switch_tol", 0.0),
                          clip=getattr(tuning, "clip", False))


class ExtendedKalmanFilter(CovarianceKernelEstimator):
    """Extended Kalman filter (Kalman filter on a linear model), Joseph form.

    Parameters
    ----------
    plant : Plant
    tuning : KalmanTuning
    runs : int, optional
        Number of parallel runs (None: a single run).
    backend : {"auto", "native", "vm"}
        Kernel evaluation (see `tanksynth.runtime.estimators.base`).

    Attributes
    ----------
    model : DiscreteModel
    backend : str
        The back end actually used.

    Notes
    -----
    ``extra`` after a step holds the innovation ``y - h(x(k|k-1))`` (q),
    the gain ``K`` (n q, column-major), the prediction ``x(k|k-1)`` (n)
    and, on hybrid plants, 1 when the previous Jacobian was kept.

    Examples
    --------
    >>> import numpy as np
    >>> from tanksynth.plants import hybrid_three_tank
    >>> plant = hybrid_three_tank()
    >>> tuning = KalmanTuning(Q=1e-8 * np.eye(3), R=[[1e-6]], P0=1e-3 * np.eye(3),
    ...                       x0=[0.3, 0.3, 0.3], ts=1.0)
    >>> ekf = ExtendedKalmanFilter(plant, tuning)
    >>> ekf.step([0.31], [2.8e-5, 2.8e-5]).shape
    (3,)
    """

    method = "ekf"
    noise_in_parameters = True
    check_names = ("predicted covariance P(k|k-1)", "innovation covariance S(k)",
                   "updated covariance P(k|k)")

    def __init__(self, plant: Plant, tuning: KalmanTuning, runs: int | None = None,
                 backend: str = "auto", *, model: DiscreteModel | None = None):
        require_tuning(self, tuning, KalmanTuning)
        model = model if model is not None else model_from_tuning(plant, tuning)
        self._check_model(model)
        super().__init__(plant, tuning, model, runs, backend)

    def _check_model(self, model: DiscreteModel) -> None:
        """Hook for subclasses restricting the model kind."""

    # -- kernel ------------------------------------------------------------------------
    def _layout(self) -> tuple[int, int]:
        n = self.n
        return n + n * n, (n * n + 1 if self.model.hybrid else 0)

    def _build(self) -> ca.Function:
        mdl = self.model
        n, m, q = self.n, self.m, self.q
        base, hyb = self._layout()
        S = ca.SX.sym("state", base + hyb)
        y = ca.SX.sym("y", q)
        u = ca.SX.sym("u", m)
        p = ca.SX.sym("params", n * n + q * q)
        x = S[:n]
        P = ca.reshape(S[n:base], n, n)
        Q = ca.reshape(p[:n * n], n, n)
        R = ca.reshape(p[n * n:], q, q)
        Phi = mdl.transition_jacobian_sx(x, u)
        on_surface = mdl.on_surface_sx(x)   # None without switching surfaces (hyb == 0)
        kept = ca.SX(0)                     # the previous Jacobian kept (hybrid plants only)
        if on_surface is not None:
            Phi_prev = ca.reshape(S[base:base + n * n], n, n)
            kept = ca.logic_and(on_surface, S[base + n * n] > 0)
            Phi = ca.if_else(kept, Phi_prev, Phi)
        xp = mdl.predict_sx(x, u)
        Pp = sx_symmetrize(Phi @ P @ Phi.T + Q)
        _, piv_p = sx_cholesky(Pp)
        H = mdl.output_jacobian_sx(xp)
        Sm = sx_symmetrize(H @ Pp @ H.T + R)
        Si, piv_s = sx_spd_inverse(Sm)
        K = Pp @ H.T @ Si
        nu = y - mdl.output_sx(xp)
        xn = mdl.clip_sx(xp + K @ nu)
        IKH = ca.SX.eye(n) - K @ H
        Pn = sx_symmetrize(IKH @ Pp @ IKH.T + K @ R @ K.T)
        _, piv_n = sx_cholesky(Pn)
        new = [xn, ca.reshape(Pn, n * n, 1)]
        extra = [nu, ca.reshape(K, n * q, 1), xp]
        if hyb:
            new += [ca.reshape(Phi, n * n, 1), ca.SX(1)]
            extra.append(ca.if_else(kept, 1, 0))
        checks = ca.vertcat(sx_min(piv_p), sx_min(piv_s), sx_min(piv_n), ca.sum1(xn))
        return ca.Function(f"{self.method}_step", [S, y, u, p],
                           [ca.densify(ca.vertcat(*new)), ca.densify(checks),
                            ca.densify(ca.vertcat(*extra))],
                           ["state", "y", "u", "params"], ["state_new", "checks", "extra"])

    def _params(self) -> np.ndarray:
        return np.concatenate([column_major(self.tuning.Q), column_major(self.tuning.R)])

    def _initial_state(self, X0: np.ndarray) -> np.ndarray:
        base, hyb = self._layout()
        M = X0.shape[0]
        out = np.zeros((M, base + hyb))
        out[:, :self.n] = X0
        out[:, self.n:base] = column_major(self.tuning.P0)
        return out

    # -- views -------------------------------------------------------------------------
    @property
    def gain(self) -> np.ndarray:
        """Gain ``K(k)`` of the last step, shape (n, q) or (M, n, q)."""
        n, q = self.n, self.q
        K = self._extra[:, q:q + n * q].reshape(-1, q, n).transpose(0, 2, 1)
        return K[0].copy() if self.runs is None else K.copy()

    @property
    def prediction(self) -> np.ndarray:
        """Prediction ``x(k|k-1)`` of the last step, shape (n,) or (M, n)."""
        n, q = self.n, self.q
        xp = self._extra[:, q + n * q:q + n * q + n]
        return xp[0].copy() if self.runs is None else xp.copy()

    @property
    def innovation(self) -> np.ndarray:
        """Innovation ``y(k) - h(x(k|k-1))`` of the last step, shape (q,) or (M, q)."""
        nu = self._extra[:, :self.q]
        return nu[0].copy() if self.runs is None else nu.copy()

    @property
    def kept_jacobian(self) -> np.ndarray | bool:
        """Hybrid plants: the last step kept the previous Jacobian (per run)."""
        if not self.model.hybrid:
            return False if self.runs is None else np.zeros(self._M, dtype=bool)
        flag = self._extra[:, -1] > 0
        return bool(flag[0]) if self.runs is None else flag.copy()


class KalmanFilter(ExtendedKalmanFilter):
    """Linear Kalman filter (seed 000 CKF, eq. 29-34) on a linear model.

    The model is the exact ZOH of a linear plant, or of the plant's
    linearisation at ``tuning.operating_point`` (absolute coordinates: it
    takes and returns levels, not deviations). Same interface and kernel as
    `ExtendedKalmanFilter`.

    Parameters
    ----------
    plant : Plant
        The plant.
    tuning : KalmanTuning
        ``Q``, ``R``, ``P0``, ``x0``, ``ts`` and the operating point.
    runs : int, optional
        Number of parallel runs (None: a single run).
    backend : {"auto", "native", "vm"}
        Kernel backend.
    model : DiscreteModel, optional
        A model to use instead of the tuning's.

    Raises
    ------
    SpecError
        The plant is nonlinear and the tuning has no operating point.
    """

    method = "kalman"

    def _check_model(self, model: DiscreteModel) -> None:
        if model.kind != "linear":
            raise SpecError(f"plant '{model.plant.name}' is nonlinear: a linear Kalman filter "
                            "needs tuning.operating_point = (x0, u0) to linearise about",
                            key="operating_point")


def steady_state_gain(model: DiscreteModel, Q: Any, R: Any) -> tuple[np.ndarray, np.ndarray]:
    """Steady-state Kalman gain of a linear model from the discrete Riccati equation.

    Parameters
    ----------
    model : DiscreteModel
        Linear (``kind == "linear"``).
    Q : array_like, shape (n, n)
        Process-noise covariance (squared state units).
    R : array_like, shape (q, q)
        Measurement-noise covariance (squared output units).

    Returns
    -------
    K : ndarray, shape (n, q)
        ``P C' (C P C' + R)^-1`` (filter form, the gain of eq. 32), in state
        units per output unit.
    P : ndarray, shape (n, n)
        Stabilising solution of ``P = A P A' - A P C' (C P C' + R)^-1 C P A' + Q``
        (predicted covariance, squared state units), from
        ``scipy.linalg.solve_discrete_are``.

    Raises
    ------
    SpecError
        The model is not linear.
    """
    if model.kind != "linear":
        raise SpecError("steady_state_gain needs a linear model", key="model")
    Q = as_spd(Q, "Q", model.n, semidefinite=True)
    R = as_spd(R, "R", model.q)
    Ad, _, _, C, _ = model.linear_matrices()
    P = sla.solve_discrete_are(Ad.T, C.T, Q, R)
    K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    return K, P
