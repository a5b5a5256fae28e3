"""Pole placement in LMI regions (Chilali-Gahinet), with cvxpy + Clarabel.

    ``D = {z : L_D + M_D z + M_D' conj(z) < 0}``: half-plane ``Re z < -alpha``,
    disk (centre, radius; the natural region in discrete time), conic sector,
    and intersections of these. ``A - B K`` has all its eigenvalues in ``D``
    iff there is ``X > 0`` with ``L_D (x) X + M_D (x) (A X - B Y) + M_D' (x)
    (A X - B Y)' < 0``, ``K = Y X^-1``. Observers use the dual ``(A', C')``.
    Solved with cvxpy + Clarabel after scaling (diagonal balancing of ``A``,
    input normalisation, time scaling in continuous time), with an explicit
    margin, and re-checked in numpy (LMI eigenvalues, closed-loop
    eigenvalues inside the region).

The routes are collected in `tanksynth.design.placement`.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Any, Sequence

import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from tanksynth.analysis.lmi_region import LMIRegion
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError
from tanksynth.design.lmi import SOLVERS, LMICheck
from tanksynth.design.placement_exact import _complex_list, _matrix, _pair, _refuse_uncontrollable

__all__ = [
    "LMIPlacementResult",
    "lmi_state_feedback",
    "lmi_observer",
]


# ---------------------------------------------------------------- LMI placement
@dataclass(frozen=True)
class LMIPlacementResult:
    """State feedback or observer gain with eigenvalues in an LMI region.

    Attributes
    ----------
    gain : ndarray
        ``K`` (m, n) for ``A - B K`` or ``L`` (n, q) for ``A - L C``.
    P : ndarray, shape (n, n)
        Lyapunov matrix of the closed loop (state feedback: ``X^-1``;
        observer: ``X`` of the dual problem, ``V = e' P e``).
    X : ndarray, shape (n, n)
        The LMI variable (original coordinates).
    kind : str
        ``"state_feedback"`` or ``"observer"`` (solved as the dual).
    region : LMIRegion
    domain : str
        ``"continuous"`` or ``"discrete"``.
    margin : float
        Required margin (normalised problem).
    achieved_margin : float
        ``-lambda_max`` of the re-computed normalised LMI.
    solver, status : str
    solve_time : float
        s.
    checks : tuple of LMICheck
    closed_loop_eigenvalues : ndarray
    region_margins : ndarray
        ``-lambda_max(f_D(lambda_i))`` of each closed-loop eigenvalue (> 0).
    scaling : dict
        State balancing, input normalisation and time scale applied.
    """

    gain: np.ndarray
    P: np.ndarray
    X: np.ndarray
    kind: str
    region: LMIRegion
    domain: str
    margin: float
    achieved_margin: float
    solver: str
    status: str
    solve_time: float
    checks: tuple[LMICheck, ...]
    closed_loop_eigenvalues: np.ndarray
    region_margins: np.ndarray
    scaling: dict

    def as_dict(self) -> dict:
        """JSON-friendly diagnostics (no gains)."""
        return {"kind": self.kind, "region": self.region.as_dict(), "domain": self.domain,
                "margin": self.margin, "achieved_margin": self.achieved_margin,
                "solver": self.solver, "status": self.status, "solve_time_s": self.solve_time,
                "checks": [c.as_dict() for c in self.checks],
                "closed_loop_eigenvalues": _complex_list(self.closed_loop_eigenvalues),
                "min_region_margin": float(np.min(self.region_margins)),
                "condition_P": float(np.linalg.cond(self.P)),
                "gain_norm": float(np.linalg.norm(self.gain, 2)),
                "scaling": self.scaling}


def _d_lmi(region: LMIRegion, Acl_X: Any, X: Any, kron) -> Any:
    return kron(region.L, X) + kron(region.M, Acl_X) + kron(region.M.T, Acl_X.T)


def lmi_state_feedback(A: Any, B: Any, region: LMIRegion, *, domain: str = "continuous",
                       margin: float = 1e-6, kappa: float = 1e4, solver: str = "CLARABEL",
                       state_names: Sequence[str] | None = None,
                       _dual: bool = False) -> LMIPlacementResult:
    """State feedback ``u = -K x`` placing ``eig(A - B K)`` in an LMI region.

    On the scaled problem, phase 1 maximises ``t`` in ``L (x) X + M (x) (A X -
    B Y) + M' (x) (A X - B Y)' <= -t I``, ``I <= X <= kappa I`` (the design
    is refused when ``t* < margin``); phase 2 minimises ``||Y||_F`` keeping
    ``-max(margin, t*/2) I`` (moderate gains). ``X`` and ``K = Y X^-1`` are
    then re-checked in numpy.

    Parameters
    ----------
    A : array_like, shape (n, n)
        1/s (continuous) or dimensionless (discrete).
    B : array_like, shape (n, m)
    region : LMIRegion
        Must lie in the stability domain of ``domain``.
    domain : {"continuous", "discrete"}
    margin : float
        Strictness margin of the normalised LMI (> 0).
    kappa : float
        Conditioning bound of ``X``.
    solver : {"CLARABEL", "SCS"}
    state_names : sequence of str, optional
        For naming uncontrollable modes.

    Returns
    -------
    LMIPlacementResult

    Raises
    ------
    SpecError
        Region not inside the stability domain, bad options.
    UncontrollableError
        Before solving, naming the modes.
    InfeasibleDesign
        Solver infeasible/failed or re-check failed.
    """
    A, B = _pair(A, B, "C'" if _dual else "B")
    n, m = B.shape[0], B.shape[1]
    if domain not in ("continuous", "discrete"):
        raise SpecError(f"domain must be 'continuous' or 'discrete', got {domain!r}", key="domain")
    if not isinstance(region, LMIRegion):
        raise SpecError("region must be an LMIRegion", key="region")
    if not region.stable_in(domain):
        raise SpecError(f"region {region.describe()} is not inside the {domain}-time stability "
                        "domain (continuous: add a half-plane alpha >= 0, a disk left of 0 or a "
                        "sector; discrete: add a disk with |centre| + radius <= 1)", key="region")
    if not (isinstance(margin, (int, float)) and 0 < margin < 1):
        raise SpecError(f"margin must be in (0, 1), got {margin!r}", key="margin")
    if solver not in SOLVERS:
        raise SpecError(f"unknown solver {solver!r}; expected one of {list(SOLVERS)}", key="solver")
    _refuse_uncontrollable(A, B, state_names, _dual)
    # scaling: diagonal balancing of A, unit input columns, time scale (continuous)
    _, (s, _perm) = sla.matrix_balance(A, permute=False, separate=True)
    s = np.asarray(s, dtype=float)
    Ab = A * (1.0 / s)[:, None] * s[None, :]
    Bb = B / s[:, None]
    su = 1.0 / np.maximum(np.linalg.norm(Bb, axis=0), 1e-300)
    Bb = Bb * su[None, :]
    omega = float(np.linalg.norm(Ab, 2)) if domain == "continuous" else 1.0
    omega = omega if omega > 0 else 1.0
    As, Bs, reg = Ab / omega, Bb / omega, region.scaled(omega)
    I = np.eye(n)
    X = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((m, n))
    t = cp.Variable()
    bound = cp.Parameter(nonneg=True)
    lmi = _d_lmi(reg, As @ X - Bs @ Y, X, cp.kron)
    lmi = 0.5 * (lmi + lmi.T)
    d = reg.order * n
    box = [X >> I, X << kappa * I]
    # Phase 1: largest margin t (certifies infeasibility when t* < margin).
    phase1 = cp.Problem(cp.Maximize(t), [lmi << -t * np.eye(d), t <= 1.0, *box])
    # Phase 2: smallest ||Y||_F keeping half of the achievable margin (moderate gains).
    phase2 = cp.Problem(cp.Minimize(cp.norm(Y, "fro")), [lmi << -bound * np.eye(d), *box])
    start = time.perf_counter()
    status = _solve(phase1, solver)
    tstar = float(t.value) if status in ("optimal", "optimal_inaccurate") and t.value is not None \
        else -np.inf
    if tstar < margin:
        raise InfeasibleDesign(
            f"no gain places the eigenvalues in {region.describe()} with margin {margin:g}: solver "
            f"{solver} status {status}, largest achievable margin t* = {tstar:.3g} (max t s.t. region "
            f"LMI <= -t I, I <= X <= {kappa:g} I; the optimum certifies that no larger margin exists)")
    Xv, Yv = X.value.copy(), Y.value.copy()
    bound.value = max(margin, 0.5 * tstar)
    status2 = _solve(phase2, solver)
    if status2 in ("optimal", "optimal_inaccurate") and X.value is not None:
        Xv, Yv, status = X.value, Y.value, f"{status} (phase 1), {status2} (phase 2)"
    else:
        status = f"{status} (phase 1), {status2} (phase 2 failed: phase-1 gain kept)"
    elapsed = time.perf_counter() - start
    Xs = 0.5 * (Xv + Xv.T)
    Ks = np.linalg.solve(Xs.T, np.asarray(Yv).T).T           # Y X^-1
    K = (su[:, None] * Ks) / s[None, :]                            # S_u Ks T^-1
    # --- independent re-check (numpy) ---
    Acl_s = As - Bs @ Ks
    Mn = _sym_np(_d_lmi(reg, Acl_s @ Xs, Xs, np.kron))
    eig_n = np.linalg.eigvalsh(Mn)
    Xo = (s[:, None] * Xs) * s[None, :]                             # T Xs T'
    Acl = A - B @ K
    Mo = _sym_np(_d_lmi(region, Acl @ Xo, Xo, np.kron))
    eig_o = float(np.max(np.linalg.eigvalsh(Mo)))
    lam = np.linalg.eigvals(Acl)
    margins = np.array([region.margin(z) for z in lam])
    xmin = float(np.min(np.linalg.eigvalsh(Xs)))
    need = -0.5 * margin
    checks = (
        LMICheck("region LMI, normalised (max eigenvalue <= -margin/2)", float(eig_n.max()), need,
                 bool(eig_n.max() <= need), "normalised"),
        LMICheck("region LMI, original units (max eigenvalue < 0)", eig_o, 0.0, bool(eig_o < 0),
                 "original units"),
        LMICheck("X > 0 (min eigenvalue, normalised)", xmin, 0.0, bool(xmin > 0), ""),
        LMICheck("closed-loop eigenvalues inside the region (min -lambda_max f_D)",
                 float(margins.min()), 0.0, bool(margins.min() > 0), ""),
    )
    failed = [c for c in checks if not c.passed]
    if failed:
        worst = "; ".join(f"{c.name}: {c.value:.4g} vs {c.limit:.4g}" for c in failed)
        raise InfeasibleDesign(f"LMI region placement fails the independent re-check ({worst}); "
                               f"solver {solver} status {status}")
    kind = "observer" if _dual else "state_feedback"
    P = Xo if _dual else np.linalg.inv(Xo)
    return LMIPlacementResult(
        gain=K.T if _dual else K, P=_sym_np(P), X=Xo, kind=kind, region=region, domain=domain,
        margin=float(margin), achieved_margin=float(-eig_n.max()), solver=solver, status=status,
        solve_time=elapsed, checks=checks, closed_loop_eigenvalues=lam, region_margins=margins,
        scaling={"state_balance": s.tolist(), "input_scale": su.tolist(), "time_scale": omega,
                 "normalisation": "I <= X <= kappa I", "kappa": kappa,
                 "largest_margin_t": tstar,
                 "objective": "phase 1: max margin t; phase 2: min ||Y||_F with LMI <= -max(margin, "
                              "t/2) I", "formulation": "dual (A', C')" if _dual else "primal"})


def _solve(problem: cp.Problem, solver: str) -> str:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver=solver)
    except cp.error.SolverError as exc:
        return f"solver_error ({exc})"
    return str(problem.status)


def _sym_np(M: np.ndarray) -> np.ndarray:
    return 0.5 * (M + M.T)


def lmi_observer(A: Any, C: Any, region: LMIRegion, *, domain: str = "continuous",
                 margin: float = 1e-6, kappa: float = 1e4, solver: str = "CLARABEL",
                 state_names: Sequence[str] | None = None) -> LMIPlacementResult:
    """Observer gain ``L`` placing ``eig(A - L C)`` in an LMI region (dual problem).

    Parameters
    ----------
    A : array_like, shape (n, n)
    C : array_like, shape (q, n)
    region : LMIRegion
    domain : {"continuous", "discrete"}
    margin, kappa : float
    solver : {"CLARABEL", "SCS"}
    state_names : sequence of str, optional

    Returns
    -------
    LMIPlacementResult
        ``gain`` is ``L`` (n, q); ``P`` is the Lyapunov matrix of ``A - L C``.

    Raises
    ------
    UnobservableError
        Before solving, naming the unobservable modes.
    InfeasibleDesign
    """
    A = _matrix(A, "A")
    C = _matrix(C, "C")
    if C.shape[1] != A.shape[0]:
        raise DimensionError(f"C has {C.shape[1]} columns, expected n = {A.shape[0]}")
    return lmi_state_feedback(A.T, C.T, region, domain=domain, margin=margin, kappa=kappa,
                              solver=solver, state_names=state_names, _dual=True)


