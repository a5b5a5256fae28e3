"""Consensus (information-form) Kalman filter with N sensors (seed 004 eq. 42-51).

Olfati-Saber's micro-Kalman filter with the average-consensus sums taken as
exact (all nodes agree; the seed stops at eq. 51 without the consensus
dynamics). Sensor ``i`` measures ``y_i = C_i x + d_i + noise`` with
covariance ``R_i``. One step (``u`` held over the interval)::

    x_bar = A x(k-1) + B u + c ,   P = A M(k-1) A' + G Q G'          (50)-(51)
    H     = 1/N sum C_i' R_i^-1 C_i                                  (43)
    Pcal  = ((N P)^-1 + H)^-1                                        (44)
    z     = 1/N sum C_i' R_i^-1 (y_i - d_i)                          (48)
    x(k)  = x_bar + Pcal (z - H x_bar)                               (49)
    M(k)  = Pcal / N            (Joseph form of the stacked update, symmetrised)

``x(k)`` equals the centralised Kalman filter on the stacked measurements.
Erratum: eq. 50 propagates ``Pcal`` itself; with ``N > 1`` that is ``N``
times the posterior covariance (``Pcal = N (P^-1 + sum H_i)^-1``), so the
filter would inflate its covariance ``N``-fold every step. The node
covariance ``N P`` and the central ``P`` are kept apart here; for ``N = 1``
(Algorithm 1 of the seed) both readings agree.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from tanksynth.analysis.matrices import symmetrize
from tanksynth.errors import DimensionError, SpecError
from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.adaptive import linear_model_for
from tanksynth.runtime.estimators.base import ArrayEstimator, joseph_update, mv, per_run
from tanksynth.runtime.estimators.tuning import (artefact_gains, as_matrix, noise_covariances,
                                                 noise_input, operating_point, positive_float,
                                                 require_tuning, set_fields)

__all__ = ["ConsensusTuning", "ConsensusFilter"]


@dataclass(frozen=True, eq=False)
class ConsensusTuning:
    """Tuning of the consensus filter: the artefact.

    Attributes
    ----------
    Q : ndarray, shape (r, r)
        Process noise covariance (PSD, squared units of the noise entering
        through ``G``).
    R : tuple of ndarray
        ``R_i`` (q_i x q_i, PD, squared output units) of each sensor; ``N = len(R)``.
    P0 : ndarray, shape (n, n)
        Initial (central) covariance (squared state units).
    x0 : ndarray, shape (n,)
        Initial estimate (state units).
    ts : float
        Sampling period (s).
    C : tuple of ndarray or None
        ``C_i`` (q_i x n) of each sensor, in the linear model's state
        coordinates (offset ``d_i = 0``). None: every sensor measures the
        plant output (``C_i = C``, ``d_i = dy`` of the model).
    G : ndarray, shape (n, r) or None
        Process noise input matrix; default identity.
    operating_point : (x0, u0) or None
    """

    Q: np.ndarray
    R: tuple
    P0: np.ndarray
    x0: np.ndarray
    ts: float
    C: tuple | None = None
    G: np.ndarray | None = None
    operating_point: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        set_fields(self, **noise_covariances(self, sensors=True))
        n = self.x0.size
        if self.C is not None:
            if not isinstance(self.C, (tuple, list)) or len(self.C) != len(self.R):
                raise SpecError(f"C must list one matrix per sensor ({len(self.R)})", key="C")
            Cs = tuple(as_matrix(Ci, f"C[{i}]") for i, Ci in enumerate(self.C))
            for i, (Ci, Ri) in enumerate(zip(Cs, self.R)):
                if Ci.shape != (Ri.shape[0], n):
                    raise DimensionError(f"C[{i}] must be {Ri.shape[0]} x {n}, got {Ci.shape}")
            set_fields(self, C=Cs)
        set_fields(self, G=noise_input(self.G, n, self.Q.shape[0]),
                   ts=positive_float(self.ts, "ts"),
                   operating_point=operating_point(self.operating_point))

    @property
    def sensors(self) -> int:
        """Number of sensors ``N``."""
        return len(self.R)

    def gains(self) -> dict[str, np.ndarray]:
        """Tuning arrays for the artefact (``R_i``, ``C_i`` as ``R0, R1, ...``); the initial
        estimate ``x0`` is stored as ``x_hat0``."""
        sensors = {f"R{i}": Ri for i, Ri in enumerate(self.R)}
        sensors.update({f"C{i}": Ci for i, Ci in enumerate(self.C or ())})
        G = cast(np.ndarray, self.G)   # an array after __post_init__ (the identity for None)
        return artefact_gains(self, Q=self.Q, P0=self.P0, x_hat0=self.x0, G=G, **sensors)


class ConsensusFilter(ArrayEstimator):
    """Information-form consensus Kalman filter (seed 004 eq. 42-51).

    ``step(y, u)`` takes the stacked measurements of all sensors
    (``y`` of size ``sum q_i``, sensor 0 first).

    Parameters
    ----------
    plant : Plant
    tuning : ConsensusTuning
    runs : int, optional

    Attributes
    ----------
    prior : ndarray
        ``x_bar`` of the last step, (n,) or (M, n) (property).
    model : DiscreteModel
    stacked_C : ndarray, shape (sum q_i, n)
        ``C_i`` of the sensors, stacked (output per state units).
    stacked_offset : ndarray, shape (sum q_i,)
        Output offsets ``d_i``, stacked (output units).
    stacked_R : ndarray, shape (sum q_i, sum q_i)
        Block diagonal of the ``R_i`` (squared output units).
    information_matrix : ndarray, shape (n, n)
        ``H = 1/N sum C_i' R_i^-1 C_i`` (eq. 43; 1 / squared state units).
    information_gain : ndarray, shape (n, sum q_i)
        ``1/N [C_1' R_1^-1, ..., C_N' R_N^-1]`` (eq. 48), taking the stacked measurements
        to ``z``.
    state_noise_covariance : ndarray, shape (n, n)
        ``G Q G'`` (squared state units).
    """

    method = "consensus_filter"

    def __init__(self, plant: Plant, tuning: ConsensusTuning, runs: int | None = None):
        require_tuning(self, tuning, ConsensusTuning)
        super().__init__(plant, tuning, runs)
        self.model = linear_model_for(plant, tuning)
        sampled = self.model.linear_matrices()
        if tuning.C is None:
            Cs = [sampled.C] * tuning.sensors
            ds = [sampled.dy] * tuning.sensors
        else:
            Cs = list(tuning.C)
            ds = [np.zeros(Ci.shape[0]) for Ci in Cs]
        for i, (Ci, Ri) in enumerate(zip(Cs, tuning.R)):
            if Ri.shape[0] != Ci.shape[0] or Ci.shape[1] != plant.n:
                raise DimensionError(f"sensor {i}: C is {Ci.shape} and R is {Ri.shape} for "
                                     f"n = {plant.n}")
        self.stacked_C = np.vstack(Cs)
        self.stacked_offset = np.concatenate(ds)
        self.stacked_R = np.zeros((len(self.stacked_offset),) * 2)
        self._Rinv_stack = np.zeros_like(self.stacked_R)
        i0 = 0
        for Ri in tuning.R:
            k = Ri.shape[0]
            self.stacked_R[i0:i0 + k, i0:i0 + k] = Ri
            self._Rinv_stack[i0:i0 + k, i0:i0 + k] = np.linalg.inv(Ri)
            i0 += k
        N = tuning.sensors
        self.information_matrix = self.stacked_C.T @ self._Rinv_stack @ self.stacked_C / N  # (43)
        self.information_gain = self.stacked_C.T @ self._Rinv_stack / N  # (48)
        G = cast(np.ndarray, tuning.G)   # an array after __post_init__ (the identity for None)
        self.state_noise_covariance = G @ tuning.Q @ G.T
        self._qy = self._q = self.stacked_C.shape[0]
        self.reset()

    @property
    def q(self) -> int:
        """Size of the stacked measurement ``sum q_i``."""
        return self._qy

    def _clone_args(self) -> tuple[tuple, dict]:
        return (self.plant, self.tuning), {}

    def _reset_arrays(self) -> None:
        self._Mc = per_run(self.tuning.P0, self._M)
        self._prior = self._x.copy()
        self._first = True

    @property
    def covariance(self) -> np.ndarray:
        """Central posterior covariance ``M(k)`` (a copy)."""
        return self._Mc[0].copy() if self.runs is None else self._Mc.copy()

    @property
    def prior(self) -> np.ndarray:
        """``x_bar`` used by the last step (a copy)."""
        return self._prior[0].copy() if self.runs is None else self._prior.copy()

    def _advance(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        A, Bd, cd, _, _ = self.model.linear_matrices()
        N = self.tuning.sensors
        xbar = mv(A, self._x) + mv(Bd, U) + cd                               # (51)
        P = symmetrize(A @ self._Mc @ A.T + self.state_noise_covariance)  # (50), central
        self._check_spd(P, "predicted covariance P(k|k-1)")
        info = symmetrize(np.linalg.inv(N * P) + self.information_matrix)  # (44)
        self._check_spd(info, "information matrix (N P)^-1 + H")
        Pcal = symmetrize(np.linalg.inv(info))
        z = mv(self.information_gain, Y - self.stacked_offset)            # (48)
        x = xbar + np.einsum("mij,mj->mi", Pcal, z - mv(self.information_matrix, xbar))  # (49)
        K = Pcal @ self.information_gain                  # stacked gain = M C' R^-1
        Mc = joseph_update(P, K, self.stacked_C, self.stacked_R)
        self._check_spd(Mc, "updated covariance M(k)")
        self._check_state(x)
        self._x, self._Mc, self._prior = x, Mc, xbar
        return x
