"""Decentralised Kalman gains under a sparsity pattern (seed 003, DECENTER).

Linear time-varying model over a window of ``T`` steps::

    x(k+1) = A_k x(k) + w(k),   w ~ N(0, Q_k)
    y(k)   = C_k x(k) + v(k),   v ~ N(0, R_k)

with the filter ``xhat(k|k) = xhat(k|k-1) + K_k (y(k) - C_k xhat(k|k-1))``.
Covariances follow the Joseph form (valid for any gain, not only the
optimal one) and are symmetrised after every step::

    P(k|k)   = (I - K_k C_k) P(k|k-1) (I - K_k C_k)' + K_k R_k K_k'
    P(k+1|k) = A_k P(k|k) A_k' + Q_k

A sparsity pattern ``E`` (n x o) says which gain entries are free: entries
where ``E`` is 0 are exactly 0 in every gain returned here (Pedroso, Batista,
Oliveira & Silvestre, IJSS 2021, doi:10.1080/00207721.2021.2002461).

=========================  ==================================================
`centralized_gain`         unconstrained LTV Kalman step
`one_step_gains`           gain minimising ``tr P(k|k)`` under ``E`` (one
                           linear system in the free entries)
`finite_horizon_gains`     gains minimising ``sum_k tr P(k|k)`` over a window:
                           ``method="casadi"`` (IPOPT on the covariance
                           recursion) or ``method="iterative"`` (the
                           backward/forward sweeps of Pedroso & Batista)
`covariance_recursion`     the Joseph-form pass for given gains (re-check)
`discretize_noise`         Van Loan: exact ``(A_d, Q_d)`` of ``(F, Qc)``
`linear_model`             discrete affine model of a plant at a point
                           (DECENTER's lower-tank-equilibrium scheme for the
                           N-tank network)
`window_models`            models along a predicted trajectory, relinearised
                           every ``relinearize_every`` steps
=========================  ==================================================

Units: covariances are in the squared state unit (cm^2 for the tank
network), ``R`` in the squared output unit, process-noise intensities
``Qc`` in squared state unit per second, gains in state unit per output unit
(cm/cm for the tank network, i.e. dimensionless).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla

from tanksynth.errors import DimensionError, InfeasibleDesign, RegionError, SpecError
from tanksynth.plants.base import Plant
from tanksynth.analysis.linearize import discretize_zoh

__all__ = [
    "KalmanStep",
    "CovarianceTrajectory",
    "FiniteHorizonResult",
    "DiscreteModel",
    "FH_METHODS",
    "centralized_gain",
    "one_step_gains",
    "finite_horizon_gains",
    "covariance_recursion",
    "own_tank_pattern",
    "equicorrelated_intensity",
    "discretize_noise",
    "lower_tank_equilibrium",
    "linear_model",
    "window_models",
]

#: Routes of `finite_horizon_gains`.
FH_METHODS = ("casadi", "iterative")

_SYM_RTOL = 1e-8          # relative asymmetry accepted (then symmetrised) in inputs
_PSD_RTOL = 1e-10         # relative negative eigenvalue accepted in Q (rounding)
_BLOCK_SCALING_MAX = 400  # free entries per step up to which the casadi route scales by blocks


# ============================================================== result objects
@dataclass(frozen=True, eq=False)
class KalmanStep:
    """One filter step: gain and the covariances it produces.

    Array-like as its gain: ``np.asarray(step)`` is ``step.K``.

    Attributes
    ----------
    K : ndarray, shape (n, o)
        Filter gain ``K(k)`` (state unit per output unit). Entries outside
        the sparsity pattern are exactly 0.
    P_filt : ndarray, shape (n, n)
        ``P(k|k)``, Joseph form, symmetric (squared state unit).
    P_pred_next : ndarray, shape (n, n)
        ``P(k+1|k) = A P(k|k) A' + Q`` (squared state unit).
    """

    K: np.ndarray
    P_filt: np.ndarray
    P_pred_next: np.ndarray

    @property
    def cost(self) -> float:
        """``tr P(k|k)`` (squared state unit)."""
        return float(np.trace(self.P_filt))

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        return np.asarray(self.K, dtype=dtype)


@dataclass(frozen=True, eq=False)
class CovarianceTrajectory:
    """Covariances of a window for given gains (`covariance_recursion`).

    Attributes
    ----------
    P_filt : list of ndarray
        ``P(k|k)``, k = 1..T (squared state unit).
    P_pred : list of ndarray
        ``P(k|k-1)``, k = 1..T (``P_pred[0]`` is the given ``P(1|0)``).
    P_pred_next : ndarray
        ``P(T+1|T)``.
    traces : ndarray, shape (T,)
        ``tr P(k|k)``.
    cost : float
        ``sum_k tr P(k|k)``.
    """

    P_filt: list[np.ndarray]
    P_pred: list[np.ndarray]
    P_pred_next: np.ndarray
    traces: np.ndarray
    cost: float


@dataclass(frozen=True, eq=False)
class FiniteHorizonResult:
    """Finite-horizon decentralised gains of one window.

    Attributes
    ----------
    K : list of ndarray, each (n, o)
        Gains ``K(1) .. K(T)``; masked entries exactly 0.
    P : list of ndarray, each (n, n)
        ``P(k|k)``, k = 1..T, recomputed in numpy (Joseph form) from ``K``
        whatever the route.
    cost : float
        ``sum_k tr P(k|k)`` over the window (squared state unit).
    iterations : int
        Outer iterations (``"iterative"``) or IPOPT iterations (``"casadi"``).
    converged : bool
        The route met its tolerance within ``max_iter``. When False a
        `RuntimeWarning` was issued; the gains are the last (finite)
        iterate, never worse than the one-step gains.
    method : str
        ``"casadi"`` or ``"iterative"``.
    P_pred : list of ndarray
        ``P(k|k-1)``, k = 1..T.
    P_pred_next : ndarray
        ``P(T+1|T)``: the prediction the next window starts from.
    one_step_cost : float
        ``sum_k tr P(k|k)`` of the one-step gains on the same window (the
        starting point of both routes).
    history : tuple of float
        Cost after each outer iteration (``"iterative"``); for ``"casadi"``
        the warm-start and final costs.
    status : str
        Route status (IPOPT's return status, or ``"converged"`` /
        ``"max_iter"``).
    seconds : float
        Wall-clock time of the design (s).
    E : ndarray of bool, shape (n, o)
        Sparsity pattern used (True = free entry).
    """

    K: list[np.ndarray]
    P: list[np.ndarray]
    cost: float
    iterations: int
    converged: bool
    method: str
    P_pred: list[np.ndarray] = field(default_factory=list)
    P_pred_next: np.ndarray | None = None
    one_step_cost: float = float("nan")
    history: tuple[float, ...] = ()
    status: str = ""
    seconds: float = 0.0
    E: np.ndarray | None = None

    @property
    def T(self) -> int:
        """Window length (steps)."""
        return len(self.K)

    @property
    def gains(self) -> np.ndarray:
        """The gains stacked as one array of shape (T, n, o)."""
        return np.stack(self.K)


# ================================================================== validation
def _array2(value: Any, name: str, shape: tuple[int | None, int | None] | None = None) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a matrix of numbers, got {type(value).__name__}") from None
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim != 2:
        raise DimensionError(f"{name} must be a 2-D matrix, got an array of shape {arr.shape}")
    if shape is not None:
        for got, want in zip(arr.shape, shape):
            if want is not None and got != want:
                raise DimensionError(f"{name} has shape {arr.shape}, expected "
                                     f"({shape[0] if shape[0] is not None else '*'}, "
                                     f"{shape[1] if shape[1] is not None else '*'})")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} has non-finite entries")
    return arr


def _symmetric(M: np.ndarray, name: str) -> np.ndarray:
    scale = max(1.0, float(np.max(np.abs(M))))
    if float(np.max(np.abs(M - M.T))) > _SYM_RTOL * scale:
        raise SpecError(f"{name} is not symmetric (max |M - M'| = {np.max(np.abs(M - M.T)):.3g})",
                        key=name)
    return 0.5 * (M + M.T)


def _check_pd(M: np.ndarray, name: str) -> np.ndarray:
    """Symmetrise and require positive definiteness (Cholesky)."""
    M = _symmetric(M, name)
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        low = float(np.linalg.eigvalsh(M)[0])
        raise SpecError(f"{name} is not positive definite (smallest eigenvalue {low:.3g})",
                        key=name) from None
    return M


def _check_psd(M: np.ndarray, name: str) -> np.ndarray:
    M = _symmetric(M, name)
    slack = _PSD_RTOL * max(1.0, float(np.max(np.abs(M))))
    try:
        np.linalg.cholesky(M + slack * np.eye(M.shape[0]))
        return M
    except np.linalg.LinAlgError:
        low = float(np.linalg.eigvalsh(M)[0])
    if low < -slack:
        raise SpecError(f"{name} is not positive semidefinite (smallest eigenvalue {low:.3g})",
                        key=name)
    return M


def _mask(E: Any, n: int, o: int) -> np.ndarray:
    try:
        arr = np.array(E, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"E must be an (n, o) = ({n}, {o}) matrix of 0/1 entries, "
                             f"got {type(E).__name__}") from None
    if arr.shape != (n, o):
        raise DimensionError(f"E has shape {arr.shape}, expected (n, o) = ({n}, {o}): one row per "
                             "state, one column per output")
    if not np.all(np.isfinite(arr)):
        raise DimensionError("E has non-finite entries")
    mask = arr != 0
    if not mask.any():
        raise DimensionError("E has no free entry: every gain would be 0 (no state is corrected "
                             "by any measurement); mark at least one entry free")
    return mask


def _sequence(seq: Any, name: str) -> list[np.ndarray]:
    if isinstance(seq, np.ndarray):
        if seq.ndim != 3:
            raise DimensionError(f"{name} must be a sequence of matrices (an array of shape "
                                 f"(T, rows, cols)), got an array of shape {seq.shape}")
        items = list(seq)
    else:
        try:
            items = list(seq)
        except TypeError:
            raise DimensionError(f"{name} must be a sequence of matrices, got "
                                 f"{type(seq).__name__}") from None
    return items


def _window(A_seq: Any, C_seq: Any, Q_seq: Any, R_seq: Any, E: Any, P0_pred: Any
            ) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray], list[np.ndarray],
                       np.ndarray, np.ndarray]:
    seqs = {name: _sequence(s, name) for name, s in
            (("A_seq", A_seq), ("C_seq", C_seq), ("Q_seq", Q_seq), ("R_seq", R_seq))}
    T = len(seqs["A_seq"])
    if T < 1:
        raise DimensionError("the window must have at least one step (T >= 1); got empty A_seq")
    for name, items in seqs.items():
        if len(items) != T:
            raise DimensionError(f"{name} has {len(items)} matrices, expected T = {T} (the length "
                                 "of A_seq)")
    A0 = _array2(seqs["A_seq"][0], "A_seq[0]")
    n = A0.shape[0]
    C0 = _array2(seqs["C_seq"][0], "C_seq[0]", (None, n))
    o = C0.shape[0]
    A = [_array2(a, f"A_seq[{k}]", (n, n)) for k, a in enumerate(seqs["A_seq"])]
    C = [_array2(c, f"C_seq[{k}]", (o, n)) for k, c in enumerate(seqs["C_seq"])]
    Q = [_check_psd(_array2(q, f"Q_seq[{k}]", (n, n)), f"Q_seq[{k}]")
         for k, q in enumerate(seqs["Q_seq"])]
    R = [_check_pd(_array2(r, f"R_seq[{k}]", (o, o)), f"R_seq[{k}]")
         for k, r in enumerate(seqs["R_seq"])]
    mask = np.ones((n, o), dtype=bool) if E is None else _mask(E, n, o)
    P0 = _check_pd(_array2(P0_pred, "P0_pred", (n, n)), "P0_pred")
    return A, C, Q, R, mask, P0


# ====================================================================== kernels
def _sym(M: np.ndarray) -> np.ndarray:
    return 0.5 * (M + M.T)


def _joseph(K: np.ndarray, C: np.ndarray, R: np.ndarray, P_pred: np.ndarray) -> np.ndarray:
    IKC = np.eye(K.shape[0]) - K @ C
    return _sym(IKC @ P_pred @ IKC.T + K @ R @ K.T)


def _require_pd(P: np.ndarray, what: str) -> None:
    try:
        if not np.all(np.isfinite(P)):
            raise np.linalg.LinAlgError
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        low = float(np.linalg.eigvalsh(P)[0]) if np.all(np.isfinite(P)) else float("nan")
        raise InfeasibleDesign(f"{what} is not positive definite (smallest eigenvalue {low:.3g}); "
                               "the covariance recursion broke down numerically") from None


class _Pattern:
    """Index arrays of the free entries of a mask, in row-major order."""

    def __init__(self, mask: np.ndarray):
        self.mask = mask
        self.full = bool(mask.all())
        self.rows, self.cols = np.nonzero(mask)
        self.shape = mask.shape
        self.rr = np.ix_(self.rows, self.rows)
        self.cc = np.ix_(self.cols, self.cols)

    def solve(self, L: np.ndarray | None, S: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """Gain K on the pattern with ``[L K S]_E = [rhs]_E`` and ``K = 0`` off ``E``.

        ``L`` (n x n, None for the identity) and ``S`` (o x o) symmetric
        positive definite. In ``vec`` form this is the principal submatrix of
        ``S kron L`` on the free entries: entry ``(p, q)`` of the system is
        ``L[r_p, r_q] S[c_q, c_p]``, assembled by fancy indexing (no loop)
        and solved directly (LAPACK ``gesv`` through numpy; the system is
        symmetric positive definite). With every entry free the solution is
        ``K = L^-1 rhs S^-1`` (one ``o x o`` solve instead of ``n o``).
        """
        K = np.zeros(self.shape)
        if self.full:  # every entry free: L K S = rhs
            target = rhs if L is None else np.linalg.solve(L, rhs)
            K[:] = np.linalg.solve(S, target.T).T
            return K
        Lrr = (self.rows[:, None] == self.rows[None, :]).astype(float) if L is None else L[self.rr]
        M = Lrr * S[self.cc]
        b = rhs[self.rows, self.cols]
        try:
            values = np.linalg.solve(M, b)
        except np.linalg.LinAlgError:
            raise InfeasibleDesign("the sparse gain equation is singular (R or the weighting "
                                   "lost positive definiteness)") from None
        K[self.rows, self.cols] = values
        return K


def _one_step(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray, pat: _Pattern,
              P_pred: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    S = _sym(C @ P_pred @ C.T + R)
    K = pat.solve(None, S, P_pred @ C.T)
    P_filt = _joseph(K, C, R, P_pred)
    return K, P_filt, _sym(A @ P_filt @ A.T + Q)


def _forward(A: list[np.ndarray], C: list[np.ndarray], Q: list[np.ndarray], R: list[np.ndarray],
             K: list[np.ndarray], P0: np.ndarray, check: bool = True) -> CovarianceTrajectory:
    P_filt, P_pred = [], []
    Pp = P0
    for k in range(len(A)):
        P_pred.append(Pp)
        Pf = _joseph(K[k], C[k], R[k], Pp)
        if check:
            _require_pd(Pf, f"P({k + 1}|{k + 1}) at window step {k + 1}")
        P_filt.append(Pf)
        Pp = _sym(A[k] @ Pf @ A[k].T + Q[k])
    traces = np.array([np.trace(P) for P in P_filt])
    return CovarianceTrajectory(P_filt, P_pred, Pp, traces, float(traces.sum()))


# ================================================================== public API
def centralized_gain(A: Any, C: Any, Q: Any, R: Any, P_pred: Any) -> KalmanStep:
    """Unconstrained (centralised) LTV Kalman filter step.

    ``K = P C' (C P C' + R)^-1`` with ``P = P(k|k-1)``; ``P(k|k)`` in Joseph
    form, ``P(k+1|k) = A P(k|k) A' + Q``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State transition ``A_k`` used for the prediction to ``k+1``.
    C : array_like, shape (o, n)
        Output matrix ``C_k`` (output unit per state unit).
    Q : array_like, shape (n, n)
        Process-noise covariance ``Q_k``, positive semidefinite (squared
        state unit).
    R : array_like, shape (o, o)
        Measurement-noise covariance ``R_k``, positive definite (squared
        output unit).
    P_pred : array_like, shape (n, n)
        ``P(k|k-1)``, positive definite (squared state unit).

    Returns
    -------
    KalmanStep
        ``K`` (n, o), ``P_filt`` = ``P(k|k)``, ``P_pred_next`` = ``P(k+1|k)``.

    Raises
    ------
    DimensionError
        Shapes that do not fit, non-finite entries.
    SpecError
        ``R`` or ``P_pred`` not positive definite, ``Q`` not positive
        semidefinite, or an input that is not symmetric.
    """
    As, Cs, Qs, Rs, _, P = _window([A], [C], [Q], [R], None, P_pred)
    A, C, Q, R = As[0], Cs[0], Qs[0], Rs[0]
    S = _sym(C @ P @ C.T + R)
    K = np.linalg.solve(S, (P @ C.T).T).T
    P_filt = _joseph(K, C, R, P)
    _require_pd(P_filt, "P(k|k)")
    return KalmanStep(K, P_filt, _sym(A @ P_filt @ A.T + Q))


def one_step_gains(A: Any, C: Any, Q: Any, R: Any, E: Any, P_pred: Any) -> KalmanStep:
    """One-step decentralised gain: minimise ``tr P(k|k)`` with ``K`` on ``E``.

    The stationarity condition of ``tr P(k|k)`` restricted to the free
    entries is the linear system ``[K (C P C' + R)]_E = [P C']_E`` (``K = 0``
    off ``E``), solved directly in the free entries only: its matrix is the
    principal submatrix of ``(C P C' + R) kron I`` on the free entries,
    assembled without loops. With ``E`` all ones this is the centralised
    gain.

    Parameters
    ----------
    A : array_like, shape (n, n)
        ``A_k`` (for ``P(k+1|k)``).
    C : array_like, shape (o, n)
        ``C_k``.
    Q : array_like, shape (n, n)
        ``Q_k`` (squared state unit), positive semidefinite.
    R : array_like, shape (o, o)
        ``R_k`` (squared output unit), positive definite.
    E : array_like, shape (n, o)
        Sparsity pattern: nonzero = free gain entry, 0 = entry fixed at 0.
    P_pred : array_like, shape (n, n)
        ``P(k|k-1)`` (squared state unit), positive definite.

    Returns
    -------
    KalmanStep
        ``K`` (masked entries exactly 0), ``P_filt`` = ``P(k|k)``,
        ``P_pred_next`` = ``P(k+1|k)``.

    Raises
    ------
    DimensionError
        ``E`` not (n, o) or without any free entry, shapes that do not fit.
    SpecError
        Covariances that are not symmetric / positive (semi)definite.
    InfeasibleDesign
        ``P(k|k)`` not positive definite (numerical breakdown).
    """
    A_, C_, Q_, R_, mask, P = _window([A], [C], [Q], [R], E, P_pred)
    K, P_filt, P_next = _one_step(A_[0], C_[0], Q_[0], R_[0], _Pattern(mask), P)
    _require_pd(P_filt, "P(k|k)")
    return KalmanStep(K, P_filt, P_next)


def covariance_recursion(A_seq: Any, C_seq: Any, Q_seq: Any, R_seq: Any, K_seq: Any,
                         P0_pred: Any) -> CovarianceTrajectory:
    """Joseph-form covariance pass over a window for given gains.

    Parameters
    ----------
    A_seq, C_seq, Q_seq, R_seq : sequence of array_like, length T
        ``A_k`` (n, n), ``C_k`` (o, n), ``Q_k`` (n, n, squared state unit),
        ``R_k`` (o, o, squared output unit), k = 1..T.
    K_seq : sequence of array_like, length T
        Gains ``K_k`` (n, o), any (not necessarily optimal or sparse).
    P0_pred : array_like, shape (n, n)
        ``P(1|0)`` (squared state unit).

    Returns
    -------
    CovarianceTrajectory

    Raises
    ------
    DimensionError, SpecError, InfeasibleDesign
        As `finite_horizon_gains`; ``InfeasibleDesign`` names the step whose
        ``P(k|k)`` is not positive definite.
    """
    A, C, Q, R, _, P0 = _window(A_seq, C_seq, Q_seq, R_seq, None, P0_pred)
    n, o = A[0].shape[0], C[0].shape[0]
    Ks = _sequence(K_seq, "K_seq")
    if len(Ks) != len(A):
        raise DimensionError(f"K_seq has {len(Ks)} gains, expected T = {len(A)}")
    K = [_array2(k, f"K_seq[{i}]", (n, o)) for i, k in enumerate(Ks)]
    return _forward(A, C, Q, R, K, P0)


def finite_horizon_gains(A_seq: Any, C_seq: Any, Q_seq: Any, R_seq: Any, E: Any, P0_pred: Any, *,
                         method: str = "casadi", tol: float = 1e-6,
                         max_iter: int = 100) -> FiniteHorizonResult:
    """Finite-horizon decentralised gains: minimise ``sum_k tr P(k|k)``.

    Both routes start from the one-step gains of the window and return gains
    whose cost is recomputed in numpy (Joseph form) from the gains alone.

    ``method="casadi"``
        The window problem is built in CasADi (MX): the masked gains are the
        only decision variables, the covariance recursion is the model and
        the objective is ``sum_k tr P(k|k)``. IPOPT (limited-memory BFGS)
        solves it, warm-started from the one-step gains. The problem is
        scaled before the solve: the objective by the one-step cost, and the
        free entries of each ``K_k`` by the Cholesky factor of the cost's
        Hessian in ``K_k`` alone at the warm start (``2 [S_k kron
        Lambda_k]_EE``; its diagonal only above 400 free entries per step),
        so that IPOPT sees a nearly identity-scaled problem (one variable
        per free entry still). IPOPT's ``tol`` is
        ``tol * 1e-2``; ``max_iter`` bounds IPOPT's iterations. Should IPOPT
        end above the warm start's cost, the one-step gains are returned
        with ``converged=False``.
    ``method="iterative"``
        Pedroso & Batista's finite-horizon algorithm: a backward sweep over
        the window sets each ``K_k`` to the minimiser of the cost given the
        later gains, ``[Lambda_k K_k S_k]_E = [Lambda_k P(k|k-1) C_k']_E``
        with ``Lambda_k = I + M' Lambda_{k+1} M``, ``M = (I - K_{k+1}
        C_{k+1}) A_k`` built incrementally, then a forward covariance pass;
        it stops when the relative change of every ``tr P(k|k)`` is below
        ``tol`` (at most ``max_iter`` outer iterations). Each update is an
        exact block-coordinate minimisation, so the cost never increases.

    Parameters
    ----------
    A_seq : sequence of array_like (n, n), length T
        ``A_k``, k = 1..T; ``A_k`` maps step k to k+1 (``A_T`` only enters
        ``P_pred_next``). A 3-D array (T, n, n) is accepted.
    C_seq : sequence of array_like (o, n), length T
        ``C_k`` (output unit per state unit).
    Q_seq : sequence of array_like (n, n), length T
        ``Q_k``, positive semidefinite (squared state unit).
    R_seq : sequence of array_like (o, o), length T
        ``R_k``, positive definite (squared output unit).
    E : array_like, shape (n, o)
        Sparsity pattern (nonzero = free entry).
    P0_pred : array_like, shape (n, n)
        The predicted covariance ``P(1|0)``, positive definite.
    method : {"casadi", "iterative"}
    tol : float
        Relative tolerance (> 0).
    max_iter : int
        Iteration limit (>= 1).

    Returns
    -------
    FiniteHorizonResult
        ``K`` (list), ``P`` (list of ``P(k|k)``), ``cost``, ``iterations``,
        ``converged`` and diagnostics.

    Raises
    ------
    DimensionError
        Sequences of different lengths, an empty window (T < 1), ``E`` not
        (n, o) or without any free entry, matrices of the wrong shape.
    SpecError
        Unknown ``method``, bad ``tol``/``max_iter``, covariances that are
        not symmetric / positive (semi)definite.
    InfeasibleDesign
        A covariance of the recursion lost positive definiteness (the
        message names the step) or the solver returned non-finite gains.

    Warns
    -----
    RuntimeWarning
        Not converged within ``max_iter`` (``converged=False``).
    """
    if method not in FH_METHODS:
        raise SpecError(f"method must be one of {list(FH_METHODS)}, got {method!r}", key="method")
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not (np.isfinite(tol) and tol > 0):
        raise SpecError(f"tol must be a positive number, got {tol!r}", key="tol")
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise SpecError(f"max_iter must be an integer >= 1, got {max_iter!r}", key="max_iter")
    start = time.perf_counter()
    A, C, Q, R, mask, P0 = _window(A_seq, C_seq, Q_seq, R_seq, E, P0_pred)
    pat = _Pattern(mask)
    K0, P_filt, P_pred = [], [], []
    Pp = P0
    for k in range(len(A)):
        P_pred.append(Pp)
        K, Pf, Pp = _one_step(A[k], C[k], Q[k], R[k], pat, Pp)
        _require_pd(Pf, f"P({k + 1}|{k + 1}) at window step {k + 1}")
        K0.append(K)
        P_filt.append(Pf)
    traces = np.array([np.trace(P) for P in P_filt])
    init = CovarianceTrajectory(P_filt, P_pred, Pp, traces, float(traces.sum()))
    if method == "iterative":
        K, traj, iters, converged, status, history = _fh_iterative(A, C, Q, R, pat, P0, K0, init,
                                                                    float(tol), int(max_iter))
    else:
        K, traj, iters, converged, status, history = _fh_casadi(A, C, Q, R, pat, P0, K0, init,
                                                                 float(tol), int(max_iter))
    if not converged:
        warnings.warn(f"finite-horizon gains ({method}) did not converge within max_iter = "
                      f"{max_iter} ({status}); returning the last iterate (cost {traj.cost:.6g}, "
                      f"one-step cost {init.cost:.6g})", RuntimeWarning, stacklevel=2)
    return FiniteHorizonResult(K=K, P=traj.P_filt, cost=traj.cost, iterations=iters,
                               converged=converged, method=method, P_pred=traj.P_pred,
                               P_pred_next=traj.P_pred_next, one_step_cost=init.cost,
                               history=tuple(history), status=status,
                               seconds=time.perf_counter() - start, E=mask)


def _fh_iterative(A, C, Q, R, pat: _Pattern, P0, K0, init: CovarianceTrajectory, tol: float,
                  max_iter: int):
    T, n = len(A), A[0].shape[0]
    eye = np.eye(n)
    K = list(K0)
    traj = init
    history = [init.cost]
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        L = eye
        for k in range(T - 1, -1, -1):
            if k < T - 1:
                M = (eye - K[k + 1] @ C[k + 1]) @ A[k]
                L = _sym(eye + M.T @ L @ M)
            Pp = traj.P_pred[k]
            S = _sym(C[k] @ Pp @ C[k].T + R[k])
            K[k] = pat.solve(L, S, L @ Pp @ C[k].T)
        if not all(np.all(np.isfinite(k_)) for k_ in K):
            raise InfeasibleDesign(f"the finite-horizon iteration produced non-finite gains "
                                   f"(outer iteration {it})")
        new = _forward(A, C, Q, R, K, P0)
        rel = float(np.max(np.abs(new.traces - traj.traces) / np.abs(traj.traces)))
        traj = new
        history.append(new.cost)
        if rel < tol:
            converged = True
            break
    status = "converged" if converged else "max_iter"
    return K, traj, it, converged, status, history


def _block_hessians(A, C, R, pat: _Pattern, K, P_pred) -> list[np.ndarray]:
    """Hessian blocks ``2 [S_k kron Lambda_k]_EE`` of the cost in each ``K_k`` alone."""
    T, n = len(A), A[0].shape[0]
    eye = np.eye(n)
    out: list[np.ndarray] = [np.empty(0)] * T
    L = eye
    for k in range(T - 1, -1, -1):
        if k < T - 1:
            M = (eye - K[k + 1] @ C[k + 1]) @ A[k]
            L = _sym(eye + M.T @ L @ M)
        S = _sym(C[k] @ P_pred[k] @ C[k].T + R[k])
        out[k] = L[pat.rr] * S[pat.cc]
    return out


def _fh_casadi(A, C, Q, R, pat: _Pattern, P0, K0, init: CovarianceTrajectory, tol: float,
               max_iter: int):
    import casadi as ca

    T = len(A)
    n, o = pat.shape
    nf = len(pat.rows)
    # vec(K) (column-major, as casadi reshapes) = Z k, Z selects the free entries.
    lin = (pat.rows + n * pat.cols).astype(np.int64)
    Z = ca.DM(ca.Sparsity.triplet(n * o, nf, lin.tolist(), list(range(nf))), 1.0)
    w0 = [k_[pat.rows, pat.cols] for k_ in K0]
    # Change of variables z_k = U_k (k_k - k0_k), U_k' U_k the Hessian block of the cost in
    # K_k alone at the warm start: the problem IPOPT sees is close to identity-scaled. Above
    # _BLOCK_SCALING_MAX free entries per step only the diagonal of each block is used.
    Uinv = []
    for H in _block_hessians(A, C, R, pat, K0, init.P_pred):
        H = H / init.cost
        if nf > _BLOCK_SCALING_MAX:
            Uinv.append(np.diag(1.0 / np.sqrt(np.diag(H))))
            continue
        try:
            U = np.linalg.cholesky(H).T
        except np.linalg.LinAlgError:
            raise InfeasibleDesign("the window's Hessian blocks lost positive definiteness") from None
        Uinv.append(np.linalg.inv(U))
    z = ca.MX.sym("z", nf * T)
    parts = ca.vertsplit(z, [i * nf for i in range(T + 1)])
    P = ca.DM(P0)
    eye = ca.DM.eye(n)
    J = 0
    for k in range(T):
        kk = ca.DM(w0[k]) + ca.mtimes(ca.DM(Uinv[k]), parts[k])
        Kk = ca.reshape(ca.mtimes(Z, kk), n, o)
        IKC = eye - ca.mtimes(Kk, ca.DM(C[k]))
        Pf = ca.mtimes([IKC, P, IKC.T]) + ca.mtimes([Kk, ca.DM(R[k]), Kk.T])
        J = J + ca.trace(Pf)
        if k < T - 1:
            Ak = ca.DM(A[k])
            P = ca.mtimes([Ak, Pf, Ak.T]) + ca.DM(Q[k])
    opts = {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": tol * 1e-2,
        "ipopt.max_iter": int(max_iter),
        "ipopt.hessian_approximation": "limited-memory",
        "ipopt.limited_memory_max_history": 20,
    }
    solver = ca.nlpsol("decentralized_fh", "ipopt", {"x": z, "f": J / init.cost}, opts)
    sol = solver(x0=np.zeros(nf * T))
    stats = solver.stats()
    zs = np.asarray(sol["x"], dtype=float).ravel()
    if not np.all(np.isfinite(zs)):
        raise InfeasibleDesign(f"IPOPT returned non-finite gains ({stats.get('return_status')})")
    K = []
    for k in range(T):
        Kk = np.zeros((n, o))
        Kk[pat.rows, pat.cols] = w0[k] + Uinv[k] @ zs[k * nf:(k + 1) * nf]
        K.append(Kk)
    traj = _forward(A, C, Q, R, K, P0)
    status = str(stats.get("return_status", "unknown"))
    converged = bool(stats.get("success", False)) or status == "Solved_To_Acceptable_Level"
    if traj.cost > init.cost:  # never hand back something worse than the warm start
        K, traj, converged = list(K0), init, False
        status += " (worse than the one-step warm start; kept the one-step gains)"
    return K, traj, int(stats.get("iter_count", 0)), converged, status, [init.cost, traj.cost]


# ============================================================ sparsity patterns
def own_tank_pattern(plant: Plant) -> np.ndarray:
    """Sparsity pattern "own tank": state ``i`` uses only the outputs measuring it alone.

    ``E[i, j] = 1`` when output ``j`` depends on state ``i`` only (its row of
    ``dh/dx`` has a single nonzero entry, in column ``i``), at a point inside
    the operating region. For the N-tank network (``y = h``) this is the
    identity (each tank runs a local filter on its own level, DECENTER's
    ``E = I``).

    Parameters
    ----------
    plant : Plant

    Returns
    -------
    ndarray of float, shape (n, q)
        0/1 pattern.

    Raises
    ------
    DimensionError
        A state is measured by no output of its own: it would have no free
        gain entry (name the states; give ``E`` explicitly instead).
    """
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    mid = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi),
                   np.where(np.isfinite(lo), lo + 1.0, np.where(np.isfinite(hi), hi - 1.0, 0.0)))
    H = np.asarray(plant.compiled.jac_h(mid), dtype=float).reshape(plant.q, plant.n)
    E = np.zeros((plant.n, plant.q))
    for j in range(plant.q):
        nz = np.flatnonzero(H[j] != 0)
        if len(nz) == 1:
            E[nz[0], j] = 1.0
    missing = [plant.states[i].name for i in range(plant.n) if not E[i].any()]
    if missing:
        raise DimensionError("E = 'own_tank' needs every state measured by an output of its own; "
                             f"no output measures {', '.join(missing)} alone, so these states would "
                             "have no free gain entry: give E explicitly")
    return E


# ============================================================ noise and models
def equicorrelated_intensity(n: int, intensity: float, correlation: float = 0.0) -> np.ndarray:
    """Dense process-noise intensity ``q ((1 - rho) I + rho 1 1')``.

    Parameters
    ----------
    n : int
        Number of states.
    intensity : float
        Diagonal ``q`` (squared state unit per s), ``q >= 0``.
    correlation : float
        Correlation ``rho`` between any two states' noises, ``0 <= rho < 1``
        (positive definite for ``q > 0``).

    Returns
    -------
    ndarray, shape (n, n)
        Intensity ``Qc`` (squared state unit per s).

    Raises
    ------
    DimensionError
        ``n`` not a positive integer.
    SpecError
        ``q < 0`` or ``rho`` outside [0, 1).
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise DimensionError(f"n must be a positive integer, got {n!r}")
    q, rho = float(intensity), float(correlation)
    if not (np.isfinite(q) and q >= 0):
        raise SpecError(f"process-noise intensity must be >= 0, got {intensity!r}", key="process_noise")
    if not (np.isfinite(rho) and 0 <= rho < 1):
        raise SpecError(f"correlation must be in [0, 1), got {correlation!r}",
                        key="process_noise_correlation")
    return q * ((1 - rho) * np.eye(n) + rho * np.ones((n, n)))


def discretize_noise(F: Any, Qc: Any, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of ``dx = F x dt + dw``, ``E[dw dw'] = Qc dt`` (Van Loan, 1978).

    ``Q_d = int_0^ts exp(F s) Qc exp(F' s) ds``, read off one matrix
    exponential of ``[[-F, Qc], [0, F']] ts``: with ``[[., G12], [0, G22]]``
    the result, ``A_d = G22'`` and ``Q_d = A_d G12`` (symmetrised).

    Parameters
    ----------
    F : array_like, shape (n, n)
        Continuous-time state matrix (1/s).
    Qc : array_like, shape (n, n)
        Process-noise intensity, positive semidefinite (squared state unit
        per s); for noise entering through ``G`` pass ``G Qc G'``.
    ts : float
        Sampling period (s), > 0.

    Returns
    -------
    A_d : ndarray, shape (n, n)
        ``exp(F ts)``.
    Q_d : ndarray, shape (n, n)
        Discrete process-noise covariance (squared state unit).
    """
    F = _array2(F, "F")
    n = F.shape[0]
    if F.shape != (n, n):
        raise DimensionError(f"F must be square, got shape {F.shape}")
    Qc = _check_psd(_array2(Qc, "Qc", (n, n)), "Qc")
    if isinstance(ts, bool) or not isinstance(ts, (int, float)) or not (np.isfinite(ts) and ts > 0):
        raise SpecError(f"sampling period must be a positive number of seconds, got {ts!r}",
                        key="sampling.ts")
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = Qc
    M[n:, n:] = F.T
    G = sla.expm(M * ts)
    Ad = G[n:, n:].T
    return Ad, _sym(Ad @ G[:n, n:])


@dataclass(frozen=True, eq=False)
class DiscreteModel:
    """Discrete affine model about a linearisation point.

    ``x(k+1) = x_lin + A (x(k) - x_lin) + B (u(k) - u_lin) + d + w``,
    ``y(k) = y_lin + C (x(k) - x_lin) + v``.

    Attributes
    ----------
    A : ndarray, shape (n, n)
        ``exp(F ts)``.
    B : ndarray, shape (n, m)
        ZOH input matrix (state unit per input unit).
    C : ndarray, shape (o, n)
        Output Jacobian.
    Q : ndarray, shape (n, n)
        Van Loan process-noise covariance (squared state unit).
    R : ndarray, shape (o, o)
        Measurement-noise covariance (squared output unit).
    x_lin, u_lin, y_lin : ndarray
        Linearisation point and its output.
    d : ndarray, shape (n,)
        ZOH integral of ``f(x_lin, u_lin)`` (zero at an equilibrium).
    ts : float
        Sampling period (s).
    scheme : str
        ``"lower_tank_equilibrium"`` or ``"jacobian"``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    x_lin: np.ndarray
    u_lin: np.ndarray
    y_lin: np.ndarray
    d: np.ndarray
    ts: float
    scheme: str

    def predict(self, x: Any, u: Any) -> np.ndarray:
        """One-step prediction of the mean (state unit)."""
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        return self.x_lin + self.A @ (x - self.x_lin) + self.B @ (u - self.u_lin) + self.d

    def output(self, x: Any) -> np.ndarray:
        """Predicted output at ``x`` (output unit)."""
        return self.y_lin + self.C @ (np.asarray(x, dtype=float) - self.x_lin)


def _is_tank_network(plant: Plant) -> bool:
    return plant.name == "tank_network" and plant.option("N") is not None


def lower_tank_equilibrium(plant: Plant, lower_levels: Any) -> tuple[np.ndarray, np.ndarray]:
    """Equilibrium of the N-tank network for given lower-tank levels.

    With ``s_i = sqrt(2 g h_i)``, the balances of the network are linear in
    the pump commands: lower tank ``i`` needs ``a_i s_i = (1 - gamma_p) k_p
    u_p + gamma_i k_i u_i`` (``p`` the pump feeding the upper tank that
    drains into ``i``), which fixes ``u``; each upper tank then sits at
    ``h = ((1 - gamma_p) k_p u_p / a)^2 / (2 g)``. DECENTER's
    ``computeEquilibriumLevels``, derived from the model rather than from
    its symbolic-toolbox tables.

    Parameters
    ----------
    plant : Plant
        A `tank_network` plant (any parameter set).
    lower_levels : array_like, shape (N/2,)
        Levels of tanks 1..N/2 (cm), > 0.

    Returns
    -------
    x_eq : ndarray, shape (N,)
        Levels (cm).
    u_eq : ndarray, shape (N/2,)
        Pump commands (V).

    Raises
    ------
    SpecError
        The plant is not a tank network.
    RegionError
        Non-positive lower levels, or levels that no nonnegative pump
        commands hold.
    """
    if not _is_tank_network(plant):
        raise SpecError(f"lower_tank_equilibrium needs a tank_network plant, got '{plant.name}'",
                        key="plant.model")
    N = plant.n
    half = N // 2
    hl = np.asarray(lower_levels, dtype=float).reshape(-1)
    if hl.size != half:
        raise DimensionError(f"lower_levels has {hl.size} entries, expected N/2 = {half}")
    if not np.all(np.isfinite(hl)) or np.any(hl <= 0):
        raise RegionError(f"lower-tank levels must be positive, got {hl.tolist()}",
                          key="lower_levels")
    val = {p.name: p.value for p in plant.parameters}
    g = val["g"]
    a = np.array([val[f"a{i}"] for i in range(1, N + 1)])
    gam = np.array([val[f"gamma{j}"] for j in range(1, half + 1)])
    kp = np.array([val[f"k{j}"] for j in range(1, half + 1)])
    # pump feeding upper tank half+i (0-based i): pump half-1 for i = 0, else i-1
    feeder = np.array([half - 1] + list(range(half - 1)))
    M = np.diag(gam * kp)
    M[np.arange(half), feeder] += (1 - gam[feeder]) * kp[feeder]
    u = np.linalg.solve(M, a[:half] * np.sqrt(2 * g * hl))
    upper_flow = (1 - gam[feeder]) * kp[feeder] * u[feeder]
    if np.any(u < 0) or np.any(upper_flow < 0):
        raise RegionError(f"no equilibrium with nonnegative pump commands holds the lower tanks at "
                          f"{np.round(hl, 4).tolist()} cm (pumps would need {np.round(u, 4).tolist()} V)",
                          key="lower_levels")
    hu = (upper_flow / a[half:]) ** 2 / (2 * g)
    return np.concatenate([hl, hu]), u


def linear_model(plant: Plant, x: Any, u: Any, ts: float, Qc: Any, R: Any, *,
                 scheme: str = "auto") -> DiscreteModel:
    """Discrete affine model of a plant about ``x`` (ZOH, Van Loan noise).

    Parameters
    ----------
    plant : Plant
    x : array_like, shape (n,)
        Current (estimated or predicted) state (state unit).
    u : array_like, shape (m,)
        Current input (input unit); used by the ``"jacobian"`` scheme.
    ts : float
        Sampling period (s).
    Qc : array_like, shape (n, n)
        Process-noise intensity (squared state unit per s).
    R : array_like, shape (o, o)
        Measurement-noise covariance (squared output unit).
    scheme : {"auto", "lower_tank_equilibrium", "jacobian"}
        ``"lower_tank_equilibrium"``: DECENTER's ``getDiscreteDynamics``,
        linearise at the equilibrium whose lower-tank levels are those of
        ``x`` (`lower_tank_equilibrium`; tank network only, ``d = 0``).
        ``"jacobian"``: linearise at ``(x, u)`` itself, the drift
        ``f(x, u)`` kept as the ZOH offset ``d``. ``"auto"`` picks the first
        for a tank network, the second otherwise.

    Returns
    -------
    DiscreteModel

    Raises
    ------
    DimensionError, SpecError, RegionError
        Bad shapes, bad ``ts``/noise matrices, a point where the model is
        not differentiable (e.g. an empty tank under Torricelli's law).
    """
    if scheme not in ("auto", "lower_tank_equilibrium", "jacobian"):
        raise SpecError(f"scheme must be 'auto', 'lower_tank_equilibrium' or 'jacobian', got "
                        f"{scheme!r}", key="scheme")
    if scheme == "auto":
        scheme = "lower_tank_equilibrium" if _is_tank_network(plant) else "jacobian"
    xv = np.asarray(x, dtype=float).reshape(-1)
    uv = np.asarray(u, dtype=float).reshape(-1)
    if xv.size != plant.n or uv.size != plant.m:
        raise DimensionError(f"x has {xv.size} entries and u {uv.size}, expected {plant.n} and "
                             f"{plant.m}")
    comp = plant.compiled
    if scheme == "lower_tank_equilibrium":
        x_lin, u_lin = lower_tank_equilibrium(plant, xv[: plant.n // 2])
    else:
        x_lin, u_lin = xv, uv
    F, B = comp.jacobians(x_lin[None], u_lin[None])
    F, B = F[0], B[0]
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(B))):
        raise RegionError(f"the model is not differentiable at {np.round(x_lin, 6).tolist()} "
                          "(an empty tank?)", key="x")
    f0 = np.zeros(plant.n) if scheme == "lower_tank_equilibrium" else comp.rhs(x_lin[None], u_lin[None])[0]
    Ad, BD = discretize_zoh(F, np.column_stack([B, f0]), ts)
    _, Qd = discretize_noise(F, Qc, ts)
    C = np.asarray(comp.jac_h(x_lin), dtype=float).reshape(plant.q, plant.n)
    y_lin = np.asarray(comp.h(x_lin), dtype=float).reshape(-1)
    Rm = _check_pd(_array2(R, "R", (plant.q, plant.q)), "R")
    return DiscreteModel(Ad, BD[:, : plant.m], C, Qd, Rm, x_lin, u_lin, y_lin, BD[:, plant.m],
                         float(ts), scheme)


def window_models(plant: Plant, x_start: Any, inputs: Any, ts: float, Qc: Any, R: Any, *,
                  relinearize_every: int = 10, scheme: str = "auto"
                  ) -> tuple[list[DiscreteModel], np.ndarray]:
    """Models along the trajectory predicted from ``x_start`` (DECENTER's FH window).

    ``model_k`` is linearised at the predicted ``x(k)`` when ``k`` is a
    multiple of ``relinearize_every`` and repeated otherwise; ``x(k+1) =
    model_k.predict(x(k), u(k))``.

    Parameters
    ----------
    plant : Plant
    x_start : array_like, shape (n,)
        State at step 0 (state unit), e.g. the last filtered estimate.
    inputs : array_like, shape (T, m)
        ``u(0) .. u(T-1)`` (input unit), ``u(k)`` held over ``[k, k+1)``.
    ts : float
        Sampling period (s).
    Qc, R : array_like
        Process-noise intensity (squared state unit per s) and
        measurement-noise covariance (squared output unit).
    relinearize_every : int
        Steps between linearisations (DECENTER's ``dTlin``), >= 1.
    scheme : str
        See `linear_model`.

    Returns
    -------
    models : list of DiscreteModel, length T
    x_pred : ndarray, shape (T + 1, n)
        Predicted states ``x(0) .. x(T)``.
    """
    if (isinstance(relinearize_every, bool) or not isinstance(relinearize_every, (int, np.integer))
            or relinearize_every < 1):
        raise SpecError(f"relinearize_every must be an integer >= 1, got {relinearize_every!r}",
                        key="relinearize_every")
    U = np.asarray(inputs, dtype=float)
    if U.ndim != 2 or U.shape[1] != plant.m or U.shape[0] < 1:
        raise DimensionError(f"inputs must have shape (T, m) with T >= 1 and m = {plant.m}, got "
                             f"{U.shape}")
    x = np.asarray(x_start, dtype=float).reshape(-1)
    if x.size != plant.n:
        raise DimensionError(f"x_start has {x.size} entries, expected {plant.n}")
    models: list[DiscreteModel] = []
    xs = [x]
    for k in range(U.shape[0]):
        if k % relinearize_every == 0:
            model = linear_model(plant, xs[-1], U[k], ts, Qc, R, scheme=scheme)
        models.append(model)
        xs.append(model.predict(xs[-1], U[k]))
    return models, np.array(xs)
