"""Adaptive Kalman filters on a linear model: adaptive Q (seed 000) and adaptive scaling (seed 004).

`AdaptiveKalmanFilter` (seed 000 eq. 29-37, Mohamed & Schwarz 1999): the
CKF of `KalmanFilter` whose process noise covariance is re-estimated from a
window of ``Psi`` innovations, with ``R`` known::

    C_v(k) = 1/Psi sum_{i=k-Psi+1..k} v_i v_i'                  (35)
    Q(k)   = 1/Psi sum dx_i dx_i' + P(k) - F P(k-1) F'           (36), dx_i = K_i v_i
    Q(k)  ~= K(k) C_v(k) K(k)'                                   (37, steady state)

`AdaptiveScalingKalmanFilter` (seed 004 eq. 30-41, Efe et al. 1999): the
process noise is scaled by ``phi_k >= 0`` matched to the innovation::

    beta  = C A P A' C' + R,  gamma = C G Q G' C'                (34b, 34c at phi = 1)
    Y_k   = a phi_0 + b phi_(k-1) + c (v'v - tr beta) / tr gamma (36), a, b, c >= 0, a+b+c = 1
    phi_k = max(Y_k, 0)                                          (38)
    P(k|k-1) = A P A' + phi_k G Q G'                             (32)

then the Kalman correction (39-41) in Joseph form.

Errata (recorded in the diagnostics):

* seed 000 eq. 35 writes ``v_k = y_k - H x_k`` with the *updated* estimate
  (a residual, whose covariance is ``R - H P H'``); the innovation of
  Mohamed & Schwarz, used here, is ``y_k - H x_k^+`` with the prediction.
* seed 004 eq. 36 divides the innovation ``nu_k`` (a vector) by
  ``gamma_theta``, which itself contains ``phi_k``; read as the trace
  equation ``v'v = tr(beta) + phi tr(C G Q G' C')`` solved for ``phi`` (the
  text says ``|nu|^2`` is matched to the diagonal of ``P_bar``). Eq. 37 is
  the special case ``v'v = tr(alpha_theta)`` of eq. 36.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from tanksynth.analysis.matrices import symmetrize
from tanksynth.errors import SpecError
from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.base import (ArrayEstimator, DiscreteModel, discrete_model,
                                               joseph_update, mv, per_run)
from tanksynth.runtime.estimators.tuning import (agree_on_states, artefact_gains, choice,
                                                 fits_plant, noise_covariances, noise_input,
                                                 operating_point, positive_float, positive_int,
                                                 require_tuning, set_fields)

__all__ = [
    "AdaptiveKalmanTuning",
    "AdaptiveKalmanFilter",
    "AdaptiveScalingTuning",
    "AdaptiveScalingKalmanFilter",
    "linear_model_for",
]

_AKF_FORMS = ("full", "steady_state")


def linear_model_for(plant: Plant, tuning: Any) -> DiscreteModel:
    """The linear `DiscreteModel` of a linear-filter tuning (ts, operating point), checked.

    Parameters
    ----------
    plant : Plant
        The plant (its linearisation at the tuning's operating point when nonlinear).
    tuning : object
        A linear-filter tuning with ``ts`` (s), ``x0``, ``P0`` and optionally ``operating_point``.

    Raises
    ------
    SpecError
        The plant is nonlinear and the tuning has no operating point.
    DimensionError
        ``x0`` or ``P0`` do not fit the plant.
    """
    fits_plant(tuning, plant, P0=(plant.n, plant.n))
    model = discrete_model(plant, tuning.ts, operating_point=tuning.operating_point)
    if model.kind != "linear":
        raise SpecError(f"plant '{plant.name}' is nonlinear: this filter runs on a linear model; "
                        "give operating_point = (x0, u0) to linearise about", key="operating_point")
    return model


@dataclass(frozen=True, eq=False)
class AdaptiveKalmanTuning:
    """Tuning of the adaptive-Q Kalman filter (seed 000 section III): the artefact.

    Attributes
    ----------
    Q0 : ndarray, shape (n, n)
        Initial process noise covariance (state units^2), PSD.
    R : ndarray, shape (q, q)
        Known measurement noise covariance (output units^2), PD.
    P0 : ndarray, shape (n, n)
        Initial covariance (state units^2), PD.
    x0 : ndarray, shape (n,)
        Initial estimate (state units).
    ts : float
        Sampling period (s).
    window : int
        Innovation window ``Psi`` (samples), >= 1. ``Q`` is first adapted
        once the window is full.
    form : {"full", "steady_state"}
        Eq. 36 (``Q = Q_alpha + P(k) - F P(k-1) F'``, consistent) or eq. 37
        (``Q = K C_v K'``, the steady-state approximation).
    q_floor : float
        Eigenvalues of the adapted ``Q`` are clipped from below at this value
        (state units^2, >= 0), keeping it positive semidefinite.
    operating_point : (x0, u0) or None
        Linearise a nonlinear plant here (seed 000 eq. 8-11).
    """

    Q0: np.ndarray
    R: np.ndarray
    P0: np.ndarray
    x0: np.ndarray
    ts: float
    window: int
    form: str = "full"
    q_floor: float = 0.0
    operating_point: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        set_fields(self, **noise_covariances(self, process="Q0"))
        agree_on_states(self.x0, Q0=self.Q0, P0=self.P0)
        set_fields(self, ts=positive_float(self.ts, "ts"),
                   window=positive_int(self.window, "window"),
                   form=choice(self.form, "form", _AKF_FORMS),
                   q_floor=positive_float(self.q_floor, "q_floor", allow_zero=True),
                   operating_point=operating_point(self.operating_point))

    def gains(self) -> dict[str, np.ndarray]:
        """Tuning arrays for the artefact; the initial estimate ``x0`` is stored as ``x_hat0``."""
        return artefact_gains(self, Q0=self.Q0, R=self.R, P0=self.P0, x_hat0=self.x0,
                              window=np.array([float(self.window)]),
                              q_floor=np.array([self.q_floor]))


class AdaptiveKalmanFilter(ArrayEstimator):
    """Adaptive-Q Kalman filter (seed 000 eq. 29-37) on a linear model.

    Parameters
    ----------
    plant : Plant
    tuning : AdaptiveKalmanTuning
    runs : int, optional
        Number of parallel runs (None: a single run).

    Attributes
    ----------
    model : DiscreteModel
    Q : ndarray
        Current process noise covariance, (n, n) or (M, n, n) (property), in
        squared units of the noise.
    """

    method = "adaptive_kalman"

    def __init__(self, plant: Plant, tuning: AdaptiveKalmanTuning, runs: int | None = None):
        require_tuning(self, tuning, AdaptiveKalmanTuning)
        super().__init__(plant, tuning, runs)
        self.model = linear_model_for(plant, tuning)
        fits_plant(tuning, plant, R=(plant.q, plant.q))
        self.reset()

    def _clone_args(self) -> tuple[tuple, dict]:
        return (self.plant, self.tuning), {}

    def _reset_arrays(self) -> None:
        M, n, q, W = self._M, self.n, self.q, self.tuning.window
        self._P = per_run(self.tuning.P0, M)
        self._Q = per_run(self.tuning.Q0, M)
        self._v = np.zeros((M, W, q))
        self._dx = np.zeros((M, W, n))
        self._filled = 0
        self._head = 0

    @property
    def Q(self) -> np.ndarray:
        """Current (adapted) process noise covariance (a copy)."""
        return self._Q[0].copy() if self.runs is None else self._Q.copy()

    @property
    def covariance(self) -> np.ndarray:
        """``P(k|k)`` (a copy)."""
        return self._P[0].copy() if self.runs is None else self._P.copy()

    def _advance(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        tun = self.tuning
        F, Bd, cd, H, dy = self.model.linear_matrices()
        R = tun.R
        P_prev = self._P
        xp = mv(F, self._x) + mv(Bd, U) + cd                               # (30)
        Pp = symmetrize(F @ P_prev @ F.T + self._Q)                             # (31)
        self._check_spd(Pp, "predicted covariance P(k|k-1)")
        S = symmetrize(H @ Pp @ H.T + R)
        self._check_spd(S, "innovation covariance S(k)")
        K = np.swapaxes(np.linalg.solve(S, H @ np.swapaxes(Pp, -1, -2)), -1, -2)   # (32)
        v = Y - (mv(H, xp) + dy)                                           # innovation (35, erratum)
        dx = np.einsum("mij,mj->mi", K, v)
        x = xp + dx                                                       # (33)
        P = joseph_update(Pp, K, H, R)                                    # (34), Joseph
        self._check_spd(P, "updated covariance P(k|k)")
        self._check_state(x)
        W = tun.window
        self._v[:, self._head] = v
        self._dx[:, self._head] = dx
        self._head = (self._head + 1) % W
        self._filled = min(self._filled + 1, W)
        if self._filled == W:
            if tun.form == "full":                                        # (36)
                Qa = np.einsum("mwi,mwj->mij", self._dx, self._dx) / W
                Qh = Qa + P - F @ P_prev @ F.T
            else:                                                         # (37)
                Cv = np.einsum("mwi,mwj->mij", self._v, self._v) / W
                Qh = K @ Cv @ np.swapaxes(K, -1, -2)
            w, V = np.linalg.eigh(symmetrize(Qh))
            w = np.maximum(w, tun.q_floor)
            self._Q = symmetrize((V * w[:, None, :]) @ np.swapaxes(V, -1, -2))
        self._x = x
        self._P = P
        return x


@dataclass(frozen=True, eq=False)
class AdaptiveScalingTuning:
    """Tuning of the adaptive-scaling Kalman filter (seed 004 section II-D): the artefact.

    Attributes
    ----------
    Q : ndarray, shape (r, r)
        Nominal process noise covariance (PSD, squared units of the noise
        entering through ``G``), scaled by ``phi_k``.
    R : ndarray, shape (q, q)
        Measurement noise covariance (PD, squared output units).
    P0 : ndarray, shape (n, n)
        Initial estimate covariance (squared state units).
    x0 : ndarray, shape (n,)
        Initial estimate (state units).
    ts : float
        Sampling period (s).
    a, b, c : float
        Weights of ``phi_0``, ``phi_(k-1)`` and the innovation match; each
        >= 0 and ``a + b + c = 1`` (within 1e-12).
    G : ndarray, shape (n, r) or None
        Process noise input matrix (the seed's ``B_k``); default identity.
    phi0 : float
        Initial scaling ``phi_0`` (seed: 1), >= 0.
    operating_point : (x0, u0) or None
    """

    Q: np.ndarray
    R: np.ndarray
    P0: np.ndarray
    x0: np.ndarray
    ts: float
    a: float
    b: float
    c: float
    G: np.ndarray | None = None
    phi0: float = 1.0
    operating_point: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        set_fields(self, **noise_covariances(self))
        n = self.x0.size
        set_fields(self, G=noise_input(self.G, n, self.Q.shape[0]),
                   ts=positive_float(self.ts, "ts"),
                   **{name: positive_float(getattr(self, name), name, allow_zero=True)
                      for name in ("a", "b", "c")})
        if abs(self.a + self.b + self.c - 1.0) > 1e-12:
            raise SpecError(f"a + b + c must equal 1, got {self.a} + {self.b} + {self.c} = "
                            f"{self.a + self.b + self.c!r}", key="a")
        set_fields(self, phi0=positive_float(self.phi0, "phi0", allow_zero=True),
                   operating_point=operating_point(self.operating_point))

    def gains(self) -> dict[str, np.ndarray]:
        """Tuning arrays for the artefact; the initial estimate ``x0`` is stored as ``x_hat0``."""
        G = cast(np.ndarray, self.G)   # an array after __post_init__ (the identity for None)
        return artefact_gains(self, Q=self.Q, R=self.R, P0=self.P0, x_hat0=self.x0, G=G,
                              abc=np.array([self.a, self.b, self.c]),
                              phi0=np.array([self.phi0]))


class AdaptiveScalingKalmanFilter(ArrayEstimator):
    """Adaptive-scaling Kalman filter (seed 004 eq. 30-41) on a linear model.

    Parameters
    ----------
    plant : Plant
    tuning : AdaptiveScalingTuning
    runs : int, optional

    Attributes
    ----------
    model : DiscreteModel
    state_noise_covariance : ndarray, shape (n, n)
        ``G Q G'``: the nominal process noise in the states (squared state units), scaled
        by ``phi_k``.
    output_noise_trace : float
        ``tr(C G Q G' C')`` (squared output units), the divisor of eq. 36.

    Raises
    ------
    SpecError
        ``C G Q G' C'`` has zero trace: the scaled noise is invisible in the
        output and eq. 36 divides by zero (e.g. seed 004 with ``G = B =
        e1`` and ``C = [0 0 0.5]``).
    """

    method = "adaptive_scaling_kalman"

    def __init__(self, plant: Plant, tuning: AdaptiveScalingTuning, runs: int | None = None):
        require_tuning(self, tuning, AdaptiveScalingTuning)
        super().__init__(plant, tuning, runs)
        self.model = linear_model_for(plant, tuning)
        fits_plant(tuning, plant, R=(plant.q, plant.q))
        C = self.model.linear_matrices().C
        G = cast(np.ndarray, tuning.G)   # an array after __post_init__ (the identity for None)
        self.state_noise_covariance = G @ tuning.Q @ G.T
        self.output_noise_trace = float(np.trace(C @ self.state_noise_covariance @ C.T))
        if not self.output_noise_trace > 0:
            raise SpecError("C G Q G' C' has zero trace: the scaled process noise does not reach "
                            "the output, so phi cannot be matched to the innovation (eq. 36); "
                            "choose G (noise input) and Q so that C G Q G' C' != 0", key="G")
        self.reset()

    def _clone_args(self) -> tuple[tuple, dict]:
        return (self.plant, self.tuning), {}

    def _reset_arrays(self) -> None:
        self._P = per_run(self.tuning.P0, self._M)
        self._phi = np.full(self._M, self.tuning.phi0)

    @property
    def phi(self) -> np.ndarray | float:
        """Current scaling ``phi_k`` (float or (M,))."""
        return float(self._phi[0]) if self.runs is None else self._phi.copy()

    @property
    def covariance(self) -> np.ndarray:
        """``P(k|k)`` (a copy)."""
        return self._P[0].copy() if self.runs is None else self._P.copy()

    def _advance(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        tun = self.tuning
        A, Bd, cd, C, dy = self.model.linear_matrices()
        R = tun.R
        xp = mv(A, self._x) + mv(Bd, U) + cd                               # (30)
        v = Y - (mv(C, xp) + dy)                                           # innovation
        APA = A @ self._P @ A.T
        beta = C @ APA @ C.T + R                                          # (34b)
        tr_beta = np.trace(beta, axis1=-2, axis2=-1)
        match = (np.einsum("mi,mi->m", v, v) - tr_beta) / self.output_noise_trace
        ups = tun.a * tun.phi0 + tun.b * self._phi + tun.c * match        # (36)/(37)
        phi = np.maximum(ups, 0.0)                                        # (38)
        Pp = symmetrize(APA + phi[:, None, None] * self.state_noise_covariance)  # (32)
        self._check_spd(Pp, "predicted covariance P(k|k-1)")
        Pbar = symmetrize(C @ Pp @ C.T + R)                                     # (33)
        self._check_spd(Pbar, "innovation covariance P_bar(k)")
        K = np.swapaxes(np.linalg.solve(Pbar, C @ np.swapaxes(Pp, -1, -2)), -1, -2)  # (39)
        x = xp + np.einsum("mij,mj->mi", K, v)                            # (40)
        P = joseph_update(Pp, K, C, R)                                    # (41), Joseph
        self._check_spd(P, "updated covariance P(k|k)")
        self._check_state(x)
        self._x, self._P, self._phi = x, P, phi
        return x
