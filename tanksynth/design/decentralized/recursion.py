"""Joseph-form covariance recursion and the sparse gain kernels (seed 003).

The kernels behind `tanksynth.design.decentralized.gains`: the gain equation on a
sparsity pattern (`GainPattern`), one Kalman step with a sparse gain (`one_step_update`,
`joseph_update`), the covariance pass over a window for given gains (`covariance_pass`,
`CovarianceTrajectory`), and the two finite-horizon routes (`ipopt_gains`: IPOPT through
CasADi; `iterative_gains`: Pedroso & Batista's backward/forward sweeps), each started from the
one-step gains of the window (`RouteResult`). Inputs are validated by the callers, once.

The sweeps (the default route) run on `_Kernels`: how ``K C`` is applied
(diagonal, through the selection ``C``, or dense) is decided once per window,
the gain equation on the free entries is solved by Cholesky (LAPACK
``posv``; LU if that fails), and the covariances are symmetrised once, in the
returned trajectory, not at every step (the round-off asymmetry a step adds
is not amplified: it is carried by congruences). Issue 15: at least as fast
as the same iteration written plainly in numpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from scipy.linalg.lapack import dposv as _POSV, dpotrf as _POTRF

from tanksynth.analysis.blas import small_dense
from tanksynth.design.matrices import symmetrized
from tanksynth.errors import InfeasibleDesign

__all__ = ["CovarianceTrajectory", "GainPattern", "RouteResult", "joseph_update", "one_step_update",
           "require_positive_definite", "covariance_pass", "iterative_gains", "ipopt_gains"]

_BLOCK_SCALING_MAX = 400  # free entries per step up to which the casadi route scales by blocks


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
class RouteResult:
    """What a finite-horizon route returns (`iterative_gains`, `ipopt_gains`).

    Attributes
    ----------
    K : list of ndarray, each (n, o)
        Gains ``K(1) .. K(T)`` (state unit per output unit); 0 off the pattern.
    trajectory : CovarianceTrajectory
        Their covariances, recomputed from the gains (symmetric).
    iterations : int
        Outer iterations (sweeps) or IPOPT iterations.
    converged : bool
        The route met its tolerance within ``max_iter``.
    status : str
        ``"converged"``, ``"max_iter"``, IPOPT's return status, or why the one-step gains were
        kept.
    history : list of float
        Cost after each outer iteration (squared state unit); for IPOPT the warm-start and final
        costs.
    start : CovarianceTrajectory
        The covariances of the one-step gains the route started from.
    """

    K: list[np.ndarray]
    trajectory: CovarianceTrajectory
    iterations: int
    converged: bool
    status: str
    history: list[float]
    start: CovarianceTrajectory


# ====================================================================== kernels
def _predict(A: np.ndarray, Pf: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """``P(k+1|k) = A P(k|k) A' + Q``, symmetrised (in place: ``(X + X') / 2``, ``X = A P A' + Q``)."""
    X = A @ Pf @ A.T
    X += Q
    X += X.T
    X *= 0.5
    return X


def joseph_update(K: np.ndarray, C: np.ndarray, R: np.ndarray, P_pred: np.ndarray) -> np.ndarray:
    """``P(k|k) = (I - K C) P(k|k-1) (I - K C)' + K R K'`` (Joseph form, valid for any gain),
    symmetrised.

    Parameters
    ----------
    K : ndarray, shape (n, o)
        Filter gain (state unit per output unit).
    C : ndarray, shape (o, n)
        Output matrix (output unit per state unit).
    R : ndarray, shape (o, o)
        Measurement-noise covariance (squared output unit).
    P_pred : ndarray, shape (n, n)
        ``P(k|k-1)`` (squared state unit).

    Returns
    -------
    ndarray, shape (n, n)
        ``P(k|k)`` (squared state unit).
    """
    IKC = -(K @ C)
    IKC[np.diag_indices_from(IKC)] += 1.0                 # I - K C without building I
    return symmetrized(IKC @ P_pred @ IKC.T + K @ R @ K.T)


def require_positive_definite(P: np.ndarray, what: str) -> None:
    """Refuse a covariance of the recursion that lost positive definiteness (LAPACK Cholesky).

    Parameters
    ----------
    P : ndarray, shape (n, n)
        A covariance of the recursion (squared state unit).
    what : str
        Which one, for the message (``"P(3|3) at window step 3"``).

    Raises
    ------
    InfeasibleDesign
        Not finite or not positive definite (naming ``what`` and its smallest eigenvalue).
    """
    try:
        if not np.isfinite(P).all():
            raise np.linalg.LinAlgError
        if _POTRF(P, lower=1, clean=0)[1] != 0:     # LAPACK Cholesky, no copy of the result
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        low = float(np.linalg.eigvalsh(P)[0]) if np.all(np.isfinite(P)) else float("nan")
        raise InfeasibleDesign(f"{what} is not positive definite (smallest eigenvalue {low:.3g}); "
                               "the covariance recursion broke down numerically") from None


class GainPattern:
    """Index arrays of the free entries of a gain's sparsity pattern, in row-major order.

    Parameters
    ----------
    mask : ndarray of bool, shape (n, o)
        True where a gain entry is free (dimensionless).

    Attributes
    ----------
    mask : ndarray of bool, shape (n, o)
    full : bool
        Every entry is free.
    rows, cols : ndarray of int
        Row and column of each free entry.
    shape : tuple of int
        ``(n, o)``.
    rr, cc : tuple of ndarray
        ``numpy.ix_`` of the free entries' rows (columns) with themselves: the principal
        submatrices of the gain equation (indices, dimensionless).
    """

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

        Parameters
        ----------
        L : ndarray, shape (n, n), or None
            Left weighting (the cost-to-go ``Lambda_k`` of the sweeps; dimensionless), None for
            the identity.
        S : ndarray, shape (o, o)
            Innovation covariance ``C P C' + R`` (squared output unit).
        rhs : ndarray, shape (n, o)
            Right-hand side ``L P C'`` (state unit times output unit).

        Returns
        -------
        ndarray, shape (n, o)
            The gain (state unit per output unit), 0 off the pattern.

        Raises
        ------
        InfeasibleDesign
            The equation on the free entries is singular.
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


def one_step_update(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray, pat: GainPattern,
                    P_pred: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One filter step with the one-step optimal gain on a pattern (``min tr P(k|k)``).

    Parameters
    ----------
    A : ndarray, shape (n, n)
        ``A_k``, for the prediction (dimensionless).
    C : ndarray, shape (o, n)
        ``C_k`` (output unit per state unit).
    Q : ndarray, shape (n, n)
        Process-noise covariance (squared state unit).
    R : ndarray, shape (o, o)
        Measurement-noise covariance (squared output unit).
    pat : GainPattern
        The free entries of the gain.
    P_pred : ndarray, shape (n, n)
        ``P(k|k-1)`` (squared state unit).

    Returns
    -------
    K : ndarray, shape (n, o)
        The gain (state unit per output unit).
    P_filt : ndarray, shape (n, n)
        ``P(k|k)`` (squared state unit).
    P_pred_next : ndarray, shape (n, n)
        ``P(k+1|k)`` (squared state unit).
    """
    S = symmetrized(C @ P_pred @ C.T + R)
    K = pat.solve(None, S, P_pred @ C.T)
    P_filt = joseph_update(K, C, R, P_pred)
    return K, P_filt, symmetrized(A @ P_filt @ A.T + Q)


def covariance_pass(A: list[np.ndarray], C: list[np.ndarray], Q: list[np.ndarray],
                    R: list[np.ndarray], K: list[np.ndarray], P0: np.ndarray, check: bool = True,
                    kernels: "_Kernels | None" = None) -> CovarianceTrajectory:
    """The Joseph-form covariances of a window for given gains.

    Parameters
    ----------
    A, C, Q, R : list of ndarray, length T
        ``A_k`` (n, n, dimensionless), ``C_k`` (o, n, output unit per state unit), ``Q_k``
        (n, n, squared state unit), ``R_k`` (o, o, squared output unit).
    K : list of ndarray, length T
        Gains (n, o), state unit per output unit.
    P0 : ndarray, shape (n, n)
        ``P(1|0)`` (squared state unit).
    check : bool
        Refuse a ``P(k|k)`` that is not positive definite (`require_positive_definite`), step by
        step.
    kernels : optional
        The iterative route's product kernels for this window (its own products, covariances
        left unsymmetrised); None: the dense products, symmetrised at every step.

    Returns
    -------
    CovarianceTrajectory
    """
    kern = kernels
    P_filt, P_pred = [], []
    Pp = P0
    for k in range(len(A)):
        P_pred.append(Pp)
        Pf = (joseph_update(K[k], C[k], R[k], Pp) if kern is None
              else kern.joseph(K[k], C[k], R[k], Pp, k))
        if check:
            require_positive_definite(Pf, f"P({k + 1}|{k + 1}) at window step {k + 1}")
        P_filt.append(Pf)
        Pp = _predict(A[k], Pf, Q[k]) if kern is None else A[k] @ Pf @ A[k].T + Q[k]
    traces = np.array([P.trace() for P in P_filt])
    return CovarianceTrajectory(P_filt, P_pred, Pp, traces, float(traces.sum()))


# ============================================== lean kernels of the iterative route
_GATHER_MIN_N = 32   # states from which K C is applied through the selection C (fewer flops)


def _rows(X: np.ndarray, idx: Any) -> np.ndarray:
    """``X[idx]`` (a view for a slice, one gather for indices)."""
    return X[idx] if isinstance(idx, slice) else X.take(idx, axis=0)


def _cols(X: np.ndarray, idx: Any) -> np.ndarray:
    """``X[:, idx]``."""
    return X[:, idx] if isinstance(idx, slice) else X.take(idx, axis=1)


def _selection(C: np.ndarray) -> tuple[np.ndarray, np.ndarray | None] | None:
    """``(sel, scale)``, ``C[j] = scale[j] e_sel[j]'``, when every output measures one state.

    ``scale`` is None when every entry is 1 (no multiplication needed).
    """
    nz = C != 0
    if not np.all(nz.sum(axis=1) == 1):
        return None
    sel = np.argmax(nz, axis=1)
    scale = C[np.arange(C.shape[0]), sel]
    return sel, (None if np.all(scale == 1.0) else scale)


def _spd_solve(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``M x = b`` for a symmetric positive definite ``M`` (LAPACK ``posv``).

    Should the Cholesky factorisation fail (``M`` not numerically positive
    definite), the general LU solve decides; a singular ``M`` raises
    `InfeasibleDesign`. (No ``overwrite_*`` flags: with them f2py's
    write-back makes the call several times slower.)
    """
    _, x, info = _POSV(M, b)
    if info == 0:
        return x
    try:
        return np.linalg.solve(M, b)
    except np.linalg.LinAlgError:
        raise InfeasibleDesign("the sparse gain equation is singular (R or the weighting "
                               "lost positive definiteness)") from None




class _Kernels:
    """The products of the iterative route, with as few numpy calls and flops as the algebra allows.

    Decided once per window (at entry), not per step, from ``E`` and each
    distinct ``C_k``:

    ``"diag"``
        Every output measures one state (``C_k`` a scaled selection) and each
        row of ``E`` has at most one free entry, on an output measuring that
        row's own state (DECENTER's ``E = I`` with ``C = I``): ``I - K C`` is
        diagonal, ``diag(d)``, so the Joseph form is ``(d d') * P + (k k') *
        R_cc`` elementwise (exactly symmetric) and ``(I - K C) A = d * A``.
    ``"select"``
        ``C_k`` a scaled selection, any ``E``: ``K C X = K (C X)`` with ``C X``
        a row gather, ``X C' K'`` likewise (no ``n x n`` product with ``K C``).
    ``"dense"``
        The dense products of `joseph_update`.

    The gain equation's right-hand side is formed on the free entries only
    (``O(n nf)``), ``[L]_rr`` is ``L`` itself when each row has one free
    entry in order, and its matrix ``[L]_rr * [S]_cc`` (symmetric positive
    definite) is solved by Cholesky (LAPACK ``posv``; LU if that fails).
    """

    def __init__(self, C: list[np.ndarray], pat: GainPattern):
        """``C`` the window's output matrices, ``pat`` the pattern of the gains."""
        self.pat = pat
        n, o = pat.shape
        self.n = n
        self.eye = np.eye(n)
        rows, cols = pat.rows, pat.cols
        nf = len(rows)
        self.rows_id = nf == n and np.array_equal(rows, np.arange(n))
        self.cols_id = nf == o and np.array_equal(cols, np.arange(o))
        one_per_row = nf == np.unique(rows).size
        # [X]_rr and [S]_cc in one gather each (flat indices into X and S)
        self._rr_flat = rows[:, None] * n + rows[None, :]
        self._cc_flat = cols[:, None] * o + cols[None, :]
        # gathers through C cost more numpy calls than they save flops below this size
        # (a contiguous selection is a slice: a view, no gather)
        gather = n >= _GATHER_MIN_N
        # column of each row's free entry (0 where none) for the "diag" mode
        self.col_of_row = np.zeros(n, dtype=int)
        self.col_of_row[rows] = cols
        cache: dict[bytes, tuple] = {}
        self.step = []
        for Ck in C:
            key = Ck.tobytes()
            if key not in cache:
                sv = _selection(Ck)
                if sv is None:
                    cache[key] = ("dense", None, None, None)
                else:
                    sel, scale = sv
                    diag = one_per_row and bool(np.all(sel[cols] == rows))
                    g_scale = None if scale is None else scale[cols]
                    o_ = sel.size
                    contiguous = bool(np.array_equal(sel, np.arange(sel[0], sel[0] + o_)))
                    idx = slice(int(sel[0]), int(sel[0]) + o_) if contiguous else sel
                    mode = "diag" if diag else ("select" if gather or contiguous else "dense")
                    cache[key] = (mode, idx, scale, g_scale)
            self.step.append(cache[key])
        self._rcc: dict[int, np.ndarray] = {}
        self._ar = np.arange(n)
        self._values = np.zeros(0)     # the free entries of the last gain solved
        self._dk: list = [None] * len(C)
        self._einsum = n >= 48          # below, one small matmul beats einsum's overhead

    def pct(self, k: int, Pp: np.ndarray, C: np.ndarray) -> np.ndarray:
        """``P C_k'``."""
        mode, sel, scale, _ = self.step[k]
        if mode == "dense":
            return Pp @ C.T
        PCt = _cols(Pp, sel)
        return PCt if scale is None else PCt * scale[None, :]

    def s_matrix(self, k: int, PCt: np.ndarray, C: np.ndarray, R: np.ndarray) -> np.ndarray:
        """``C_k P C_k' + R_k`` from ``P C_k'``."""
        mode, sel, scale, _ = self.step[k]
        if mode == "dense":
            return C @ PCt + R
        CPCt = _rows(PCt, sel)
        return (CPCt if scale is None else CPCt * scale[:, None]) + R

    def gain(self, L: np.ndarray | None, S: np.ndarray, PCt: np.ndarray,
             k: int | None = None) -> np.ndarray:
        """``K`` on ``E`` solving ``[L K S]_E = [L P C']_E`` (``L = None``: the identity).

        ``k``: the step, so that the "diag" mode keeps ``I - K C`` of the new gain.
        """
        K = self._solve_gain(L, S, PCt)
        if k is not None and self.step[k][0] == "diag":
            self._diag(k, K, self._values if self.rows_id else None)
        return K

    def _solve_gain(self, L: np.ndarray | None, S: np.ndarray, PCt: np.ndarray) -> np.ndarray:
        pat = self.pat
        if pat.full:                     # every entry free: K S = P C' whatever L
            K = _spd_solve(S, PCt.T).T
            self._values = K.ravel()
            return K
        rows, cols = pat.rows, pat.cols
        Scc = S if self.cols_id else S.take(self._cc_flat)
        if L is None:
            rhs = PCt[rows, cols]
            if self.rows_id:             # one free entry per row: the system is diagonal
                dg = Scc.diagonal()
                if (dg > 0).all():
                    K = np.zeros(pat.shape)
                    K[rows, cols] = self._values = rhs / dg
                    return K
                M = np.diag(dg)
            else:
                M = Scc * (rows[:, None] == rows[None, :])
        else:
            if self._einsum:     # [L P C']_E on the free entries only: O(n nf), not O(n^2 o)
                rhs = np.einsum("ij,ji->i", L if self.rows_id else L.take(rows, axis=0),
                                PCt if self.cols_id else PCt.take(cols, axis=1))
            elif self.rows_id and self.cols_id:
                rhs = (L @ PCt).diagonal()
            else:
                rhs = (L @ PCt)[rows, cols]
            M = (L if self.rows_id else L.take(self._rr_flat)) * Scc
        K = np.zeros(pat.shape)
        K[rows, cols] = self._values = _spd_solve(M, rhs)
        return K

    def _diag(self, k: int, K: np.ndarray, values: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
        """``d`` with ``I - K C_k = diag(d)`` and each row's gain entry ``kr`` ("diag" mode).

        Kept for the last ``K`` of each step (the sweeps use it twice).
        ``values``: the free entries of ``K`` when there is one per row, in
        row order (then ``kr``).
        """
        last = self._dk[k]
        if last is not None and last[0] is K:
            return last[1], last[2]
        kr = K[self._ar, self.col_of_row] if values is None else values
        g_scale = self.step[k][3]
        if self.rows_id:
            d = 1.0 - (kr if g_scale is None else kr * g_scale)
        else:
            g = np.zeros(self.n)
            g[self.pat.rows] = kr[self.pat.rows] * (1.0 if g_scale is None else g_scale)
            d = 1.0 - g
        self._dk[k] = (K, d, kr)
        return d, kr

    def joseph(self, K: np.ndarray, C: np.ndarray, R: np.ndarray, Pp: np.ndarray,
               k: int | None = None) -> np.ndarray:
        """``(I - K C) P (I - K C)' + K R K'`` (``k`` the step, None: dense).

        Exactly symmetric in the "diag" mode; otherwise symmetric up to
        round-off, as ``A P(k|k) A' + Q`` in the sweeps: every covariance the
        route returns is symmetrised once, at the end (`_symmetrised`).
        """
        mode, sel, scale, _ = ("dense", None, None, None) if k is None else self.step[k]
        if mode == "diag" and k is not None:      # "diag" is a step's mode: k is given
            d, kr = self._diag(k, K)
            Rcc = self._rcc.get(id(R))
            if Rcc is None:
                Rcc = self._rcc[id(R)] = R.take(self.col_of_row, 0).take(self.col_of_row, 1)
            Pf = np.multiply.outer(d, d)
            Pf *= Pp
            Pf += np.multiply.outer(kr, kr) * Rcc
            return Pf
        if mode == "select":
            CP = _rows(Pp, sel)
            Y = Pp - K @ (CP if scale is None else CP * scale[:, None])
            YCt = _cols(Y, sel)
            Y -= (YCt if scale is None else YCt * scale[None, :]) @ K.T
            Y += K @ R @ K.T
            return Y
        IKC = self.eye - K @ C
        return IKC @ Pp @ IKC.T + K @ R @ K.T

    def ikc_a(self, k: int, K: np.ndarray, C: np.ndarray, A: np.ndarray) -> np.ndarray:
        """``(I - K C_k) A``."""
        mode, sel, scale, _ = self.step[k]
        if mode == "diag":
            return self._diag(k, K)[0][:, None] * A
        if mode == "select":
            CA = _rows(A, sel)
            return A - K @ (CA if scale is None else CA * scale[:, None])
        return (self.eye - K @ C) @ A


def _one_step_start(A, C, Q, R, kern: _Kernels, P0) -> tuple[list[np.ndarray], CovarianceTrajectory]:
    """One-step gains of the window and their covariances (the start of the sweeps)."""
    K0, P_filt, P_pred = [], [], []
    Pp = P0
    for k in range(len(A)):
        P_pred.append(Pp)
        PCt = kern.pct(k, Pp, C[k])
        K = kern.gain(None, kern.s_matrix(k, PCt, C[k], R[k]), PCt, k)
        Pf = kern.joseph(K, C[k], R[k], Pp, k)
        K0.append(K)
        P_filt.append(Pf)
        Pp = A[k] @ Pf @ A[k].T + Q[k]
    traces = np.array([P.trace() for P in P_filt])
    return K0, CovarianceTrajectory(P_filt, P_pred, Pp, traces, float(traces.sum()))


def _fh_iterative(A, C, Q, R, kern: _Kernels, P0, K0: list[np.ndarray],
                  init: CovarianceTrajectory, tol: float, max_iter: int):
    """Pedroso & Batista's backward/forward sweeps (inputs validated once, at entry)."""
    T = len(A)
    eye = kern.eye
    K = list(K0)
    traj = init
    history = [init.cost]
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        L = eye
        for k in range(T - 1, -1, -1):
            if k < T - 1:
                M = kern.ikc_a(k + 1, K[k + 1], C[k + 1], A[k])
                L = eye + M.T @ L @ M           # symmetric up to round-off; only [L]_rr is used
            PCt = kern.pct(k, traj.P_pred[k], C[k])
            K[k] = kern.gain(L, kern.s_matrix(k, PCt, C[k], R[k]), PCt, k)
        if not np.isfinite(np.stack(K)).all():
            raise InfeasibleDesign(f"the finite-horizon iteration produced non-finite gains "
                                   f"(outer iteration {it})")
        new = covariance_pass(A, C, Q, R, K, P0, check=False, kernels=kern)   # checked once, below
        if not np.isfinite(new.traces).all():
            traj = new                                   # broke down: the check below names the step
            break
        rel = float(np.max(np.abs(new.traces - traj.traces) / np.abs(traj.traces)))
        traj = new
        history.append(new.cost)
        if rel < tol:
            converged = True
            break
    traj = _symmetrised(traj)
    # the covariances the gains give, positive definite (one Cholesky per step, at the end only)
    for k, Pf in enumerate(traj.P_filt):
        require_positive_definite(Pf, f"P({k + 1}|{k + 1}) at window step {k + 1}")
    status = "converged" if converged else "max_iter"
    return K, traj, it, converged, status, history


def _symmetrised(traj: CovarianceTrajectory) -> CovarianceTrajectory:
    """The trajectory with every covariance symmetrised (same traces, same cost)."""
    return CovarianceTrajectory([symmetrized(P) for P in traj.P_filt], [symmetrized(P) for P in traj.P_pred],
                                symmetrized(traj.P_pred_next), traj.traces, traj.cost)


def _block_hessians(A, C, R, pat: GainPattern, K, P_pred) -> list[np.ndarray]:
    """Hessian blocks ``2 [S_k kron Lambda_k]_EE`` of the cost in each ``K_k`` alone."""
    T, n = len(A), A[0].shape[0]
    eye = np.eye(n)
    out: list[np.ndarray] = [np.empty(0)] * T
    L = eye
    for k in range(T - 1, -1, -1):
        if k < T - 1:
            M = (eye - K[k + 1] @ C[k + 1]) @ A[k]
            L = symmetrized(eye + M.T @ L @ M)
        S = symmetrized(C[k] @ P_pred[k] @ C[k].T + R[k])
        out[k] = L[pat.rr] * S[pat.cc]
    return out


def _fh_casadi(A, C, Q, R, pat: GainPattern, P0, K0, init: CovarianceTrajectory, tol: float,
               max_iter: int):
    import casadi as ca     # here: only this route (not the default) builds a CasADi problem

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
    P: Any = ca.DM(P0)       # a constant, then an expression of the gains
    eye = ca.DM.eye(n)
    J: Any = 0
    for k in range(T):
        kk = ca.DM(w0[k]) + ca.mtimes(ca.DM(Uinv[k]), parts[k])
        Kk = ca.reshape(ca.mtimes(Z, kk), n, o)
        IKC = eye - ca.mtimes(Kk, ca.DM(C[k]))
        Pf = ca.mtimes([IKC, P, IKC.T]) + ca.mtimes([Kk, ca.DM(R[k]), Kk.T])
        J = J + ca.trace(Pf)
        if k < T - 1:
            Ak = ca.DM(A[k])
            P = ca.mtimes([Ak, Pf, Ak.T]) + ca.DM(Q[k])
    opts: dict[str, Any] = {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": tol * 1e-2,
        "ipopt.max_iter": int(max_iter),
        "ipopt.hessian_approximation": "limited-memory",
        "ipopt.limited_memory_max_history": 20,
    }
    problem: dict[str, Any] = {"x": z, "f": J / init.cost}
    solver = ca.nlpsol("decentralized_fh", "ipopt", problem, opts)
    sol = solver(x0=np.zeros(nf * T))
    stats = solver.stats()
    zs = np.asarray(sol["x"], dtype=float).ravel()
    if not np.all(np.isfinite(zs)):
        raise InfeasibleDesign(f"IPOPT returned non-finite gains ({stats.get('return_status')})")
    K: list[np.ndarray] = []
    for k in range(T):
        gain = np.zeros((n, o))
        gain[pat.rows, pat.cols] = w0[k] + Uinv[k] @ zs[k * nf:(k + 1) * nf]
        K.append(gain)
    traj = covariance_pass(A, C, Q, R, K, P0)
    status = str(stats.get("return_status", "unknown"))
    converged = bool(stats.get("success", False)) or status == "Solved_To_Acceptable_Level"
    if traj.cost > init.cost:  # never hand back something worse than the warm start
        K, traj, converged = list(K0), init, False
        status += " (worse than the one-step warm start; kept the one-step gains)"
    return K, traj, int(stats.get("iter_count", 0)), converged, status, [init.cost, traj.cost]


def _check_start(init: CovarianceTrajectory) -> None:
    """The one-step start broke down numerically: name the step (the sweeps check at the end)."""
    if not (np.isfinite(init.traces).all() and (init.traces > 0).all()):
        for k, Pf in enumerate(init.P_filt):
            require_positive_definite(Pf, f"P({k + 1}|{k + 1}) at window step {k + 1}")


def iterative_gains(A: list[np.ndarray], C: list[np.ndarray], Q: list[np.ndarray],
                    R: list[np.ndarray], pat: GainPattern, P0: np.ndarray, tol: float,
                    max_iter: int) -> RouteResult:
    """Finite-horizon gains by Pedroso & Batista's backward/forward sweeps, from the one-step gains.

    Runs under one BLAS thread (`tanksynth.analysis.blas.small_dense`). Should the sweeps break
    down numerically (non-finite gains, a covariance not positive definite, a cost above the
    start: round-off, e.g. ``P0`` 1e50 times ``R``), the one-step gains are kept when they are
    themselves sound.

    Parameters
    ----------
    A, C, Q, R : list of ndarray, length T
        The window's models, validated: ``A_k`` (n, n, dimensionless), ``C_k`` (o, n, output unit
        per state unit), ``Q_k`` (n, n, squared state unit), ``R_k`` (o, o, squared output unit).
    pat : GainPattern
        The free entries of the gains.
    P0 : ndarray, shape (n, n)
        ``P(1|0)`` (squared state unit).
    tol : float
        Relative change of every ``tr P(k|k)`` at which the sweeps stop (dimensionless).
    max_iter : int
        Largest number of outer iterations.

    Returns
    -------
    RouteResult

    Raises
    ------
    InfeasibleDesign
        The one-step start itself lost positive definiteness (naming the step).
    """
    with small_dense():
        kern = _Kernels(C, pat)
        K0, init = _one_step_start(A, C, Q, R, kern, P0)
        _check_start(init)
        try:
            K, traj, iters, converged, status, history = _fh_iterative(
                A, C, Q, R, kern, P0, K0, init, tol, max_iter)
            broke = not traj.cost <= init.cost * (1.0 + 1e-9)   # NaN too
        except InfeasibleDesign:   # non-finite gains, or a P(k|k) not positive definite
            broke, iters, history = True, 0, [init.cost]
        if broke:
            # An exact block-coordinate sweep never raises the cost: round-off did (e.g. P0
            # 1e50 times R): keep the one-step start when it is itself sound (else the
            # start's own breakdown is the error, naming its step).
            for k, Pf in enumerate(init.P_filt):
                require_positive_definite(Pf, f"P({k + 1}|{k + 1}) at window step {k + 1}")
            K, traj, converged = list(K0), _symmetrised(init), False
            status = "numerical breakdown of the sweeps; kept the one-step gains"
    return RouteResult(K, traj, iters, converged, status, history, init)


def ipopt_gains(A: list[np.ndarray], C: list[np.ndarray], Q: list[np.ndarray],
                R: list[np.ndarray], pat: GainPattern, P0: np.ndarray, tol: float,
                max_iter: int) -> RouteResult:
    """Finite-horizon gains by IPOPT (CasADi) on the covariance recursion, from the one-step gains.

    The one-step gains of the window are the warm start (each of their covariances checked);
    should IPOPT end above their cost, they are returned (``converged`` false).

    Parameters
    ----------
    A, C, Q, R : list of ndarray, length T
        The window's models, validated: ``A_k`` (n, n, dimensionless), ``C_k`` (o, n, output unit
        per state unit), ``Q_k`` (n, n, squared state unit), ``R_k`` (o, o, squared output unit).
    pat : GainPattern
        The free entries of the gains.
    P0 : ndarray, shape (n, n)
        ``P(1|0)`` (squared state unit).
    tol : float
        Relative tolerance (dimensionless); IPOPT's ``tol`` is ``tol * 1e-2``.
    max_iter : int
        Largest number of IPOPT iterations.

    Returns
    -------
    RouteResult

    Raises
    ------
    InfeasibleDesign
        A covariance of the start lost positive definiteness, or IPOPT returned non-finite gains.
    """
    K0, P_filt, P_pred = [], [], []
    Pp = P0
    for k in range(len(A)):
        P_pred.append(Pp)
        K, Pf, Pp = one_step_update(A[k], C[k], Q[k], R[k], pat, Pp)
        require_positive_definite(Pf, f"P({k + 1}|{k + 1}) at window step {k + 1}")
        K0.append(K)
        P_filt.append(Pf)
    traces = np.array([np.trace(P) for P in P_filt])
    init = CovarianceTrajectory(P_filt, P_pred, Pp, traces, float(traces.sum()))
    K, traj, iters, converged, status, history = _fh_casadi(A, C, Q, R, pat, P0, K0, init, tol,
                                                             max_iter)
    return RouteResult(K, traj, iters, converged, status, history, init)
