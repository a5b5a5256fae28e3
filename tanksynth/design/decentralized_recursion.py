"""Joseph-form covariance recursion and the sparse gain kernels (seed 003).

The kernels behind `tanksynth.design.decentralized`: the gain equation on a
sparsity pattern (`_Pattern`), one Kalman step with a sparse gain, the
covariance pass over a window for given gains (`CovarianceTrajectory`), and
the two finite-horizon routes (IPOPT through CasADi, Pedroso & Batista's
backward/forward sweeps). Inputs are validated by the callers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tanksynth.errors import InfeasibleDesign
from tanksynth.design.decentralized_models import _sym

__all__ = ["CovarianceTrajectory"]

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


# ====================================================================== kernels
def _joseph(K: np.ndarray, C: np.ndarray, R: np.ndarray, P_pred: np.ndarray) -> np.ndarray:
    IKC = -(K @ C)
    IKC[np.diag_indices_from(IKC)] += 1.0                 # I - K C without building I
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
        if not np.isfinite(np.stack(K)).all():
            raise InfeasibleDesign(f"the finite-horizon iteration produced non-finite gains "
                                   f"(outer iteration {it})")
        new = _forward(A, C, Q, R, K, P0, check=False)   # checked once, below
        if not np.isfinite(new.traces).all():
            traj = new                                   # broke down: the check below names the step
            break
        rel = float(np.max(np.abs(new.traces - traj.traces) / np.abs(traj.traces)))
        traj = new
        history.append(new.cost)
        if rel < tol:
            converged = True
            break
    # the covariances the gains give, positive definite (one Cholesky per step, at the end only)
    for k, Pf in enumerate(traj.P_filt):
        _require_pd(Pf, f"P({k + 1}|{k + 1}) at window step {k + 1}")
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

