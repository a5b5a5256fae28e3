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

The models, patterns and noise discretisation live in
`tanksynth.design.decentralized.models`, the covariance recursion and the
finite-horizon solvers in `tanksynth.design.decentralized.recursion`; every
name of the table is importable from here.

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

from tanksynth.analysis.blas import small_dense
from tanksynth.design.decentralized.models import (DiscreteModel, discretize_noise,
                                                   equicorrelated_intensity, linear_model,
                                                   lower_tank_equilibrium, own_tank_pattern,
                                                   window_models)
from tanksynth.design.decentralized.recursion import (CovarianceTrajectory, GainPattern,
                                                      covariance_pass, iterative_gains, ipopt_gains,
                                                      joseph_update, one_step_update,
                                                      require_positive_definite)
from tanksynth.design.decentralized.validation import (checked_matrix, positive_definite,
                                                       positive_semidefinite)
from tanksynth.design.matrices import symmetrized
from tanksynth.errors import DimensionError, SpecError

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
class FiniteHorizonResult:
    """Finite-horizon decentralised gains of one window.

    Attributes
    ----------
    K : list of ndarray, each (n, o)
        Gains ``K(1) .. K(T)`` (state units per output unit); masked entries
        exactly 0.
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
        starting point of both routes), in squared state units.
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


def _stacked(items: list, name: str, shape: tuple[int, int]) -> list[np.ndarray]:
    """The matrices of a sequence as float arrays of ``shape``, finite (checked in one pass).

    The whole sequence is converted and checked at once; only when that
    fails is every matrix checked on its own, so that the error names it.
    """
    try:
        arr = np.array(items, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is not None and arr.shape == (len(items), *shape) and np.isfinite(arr).all():
        return list(arr)
    return [checked_matrix(m, f"{name}[{k}]", shape) for k, m in enumerate(items)]


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
    A0 = checked_matrix(seqs["A_seq"][0], "A_seq[0]")
    n = A0.shape[0]
    C0 = checked_matrix(seqs["C_seq"][0], "C_seq[0]", (None, n))
    o = C0.shape[0]
    A = _stacked(seqs["A_seq"], "A_seq", (n, n))
    C = _stacked(seqs["C_seq"], "C_seq", (o, n))
    # a window relinearised every few steps repeats its matrices: each distinct one is checked once
    seen: dict[tuple, np.ndarray] = {}

    def once(check: Any, M: np.ndarray, name: str) -> np.ndarray:
        key = (check.__name__, M.shape, M.tobytes())
        if key not in seen:
            seen[key] = check(M, name)
        return seen[key]

    Q = [once(positive_semidefinite, q, f"Q_seq[{k}]")
         for k, q in enumerate(_stacked(seqs["Q_seq"], "Q_seq", (n, n)))]
    R = [once(positive_definite, r, f"R_seq[{k}]")
         for k, r in enumerate(_stacked(seqs["R_seq"], "R_seq", (o, o)))]
    mask = np.ones((n, o), dtype=bool) if E is None else _mask(E, n, o)
    P0 = positive_definite(checked_matrix(P0_pred, "P0_pred", (n, n)), "P0_pred")
    return A, C, Q, R, mask, P0


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
    S = symmetrized(C @ P @ C.T + R)
    K = np.linalg.solve(S, (P @ C.T).T).T
    P_filt = joseph_update(K, C, R, P)
    require_positive_definite(P_filt, "P(k|k)")
    return KalmanStep(K, P_filt, symmetrized(A @ P_filt @ A.T + Q))


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
        Sparsity pattern: nonzero = free gain entry, 0 = entry fixed at 0
        (dimensionless).
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
    K, P_filt, P_next = one_step_update(A_[0], C_[0], Q_[0], R_[0], GainPattern(mask), P)
    require_positive_definite(P_filt, "P(k|k)")
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
        Gains ``K_k`` (n, o), any (not necessarily optimal or sparse), in state
        units per output unit.
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
    with small_dense():   # as finite_horizon_gains: the checks and the pass on one BLAS thread
        A, C, Q, R, _, P0 = _window(A_seq, C_seq, Q_seq, R_seq, None, P0_pred)
        n, o = A[0].shape[0], C[0].shape[0]
        Ks = _sequence(K_seq, "K_seq")
        if len(Ks) != len(A):
            raise DimensionError(f"K_seq has {len(Ks)} gains, expected T = {len(A)}")
        K = [checked_matrix(k, f"K_seq[{i}]", (n, o)) for i, k in enumerate(Ks)]
        return covariance_pass(A, C, Q, R, K, P0)


def finite_horizon_gains(A_seq: Any, C_seq: Any, Q_seq: Any, R_seq: Any, E: Any, P0_pred: Any, *,
                         method: str = "iterative", tol: float = 1e-6,
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
        The predicted covariance ``P(1|0)``, positive definite (squared state units).
    method : {"iterative", "casadi"}
        Default ``"iterative"``: the same cost as ``"casadi"`` (to 1e-15
        relative at N = 64 in the benchmark), an order of magnitude faster.
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
    # the input checks too (eigenvalues and Cholesky factors of every n x n matrix of the window)
    # on one BLAS thread: outside it, OpenBLAS's threads made one call in five 3-20x slower at
    # N = 128 and 256 on the loaded 2-core machine (issue 29)
    with small_dense():
        A, C, Q, R, mask, P0 = _window(A_seq, C_seq, Q_seq, R_seq, E, P0_pred)
        route = iterative_gains if method == "iterative" else ipopt_gains
        res = route(A, C, Q, R, GainPattern(mask), P0, float(tol), int(max_iter))
    K, traj, init, iters, converged, status = (res.K, res.trajectory, res.start, res.iterations,
                                               res.converged, res.status)
    if not converged:
        warnings.warn(f"finite-horizon gains ({method}) did not converge within max_iter = "
                      f"{max_iter} ({status}); returning the last iterate (cost {traj.cost:.6g}, "
                      f"one-step cost {init.cost:.6g})", RuntimeWarning, stacklevel=2)
    return FiniteHorizonResult(K=K, P=traj.P_filt, cost=traj.cost, iterations=iters,
                               converged=converged, method=method, P_pred=traj.P_pred,
                               P_pred_next=traj.P_pred_next, one_step_cost=init.cost,
                               history=tuple(res.history), status=status,
                               seconds=time.perf_counter() - start, E=mask)


