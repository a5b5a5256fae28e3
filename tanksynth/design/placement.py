"""Pole placement: LMI regions (Chilali-Gahinet), exact placement, canonical form.

Three routes to a state-feedback gain ``K`` (``u = -K x``) or an observer gain
``L`` (error dynamics ``A - L C``):

LMI regions
    ``D = {z : L_D + M_D z + M_D' conj(z) < 0}``: half-plane ``Re z < -alpha``,
    disk (centre, radius; the natural region in discrete time), conic sector,
    and intersections of these. ``A - B K`` has all its eigenvalues in ``D``
    iff there is ``X > 0`` with ``L_D (x) X + M_D (x) (A X - B Y) + M_D' (x)
    (A X - B Y)' < 0``, ``K = Y X^-1``. Observers use the dual ``(A', C')``.
    Solved with cvxpy + Clarabel after scaling (diagonal balancing of ``A``,
    input normalisation, time scaling in continuous time), with an explicit
    margin, and re-checked in numpy (LMI eigenvalues, closed-loop
    eigenvalues inside the region).
Exact placement
    python-control ``place`` (Tits-Yang, MIMO) or ``acker`` (SISO) with an
    accuracy report: achieved poles, largest pole error, condition number of
    the closed-loop eigenvector matrix.
Observer canonical form (seed 004 eq. 27-29)
    ``Delta = Q_O^-1 Qbar_O``, ``Psi = Delta Psi_o``, in exact arithmetic.

Integral action for tracking (seed 000 eq. 13-16) augments ``(A_d, B_d)``
with ``z(k+1) = z(k) + ts (y_r - C1 x)``; the gain is ``K = [K1 K2]``.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Any, Sequence

import control
import cvxpy as cp
import numpy as np
import scipy.linalg as sla
import sympy as sp
from scipy.optimize import linear_sum_assignment

from tanksynth.analysis.lmi_region import LMIRegion
from tanksynth.errors import (DimensionError, InfeasibleDesign, SpecError, UncontrollableError,
                      UnobservableError)
from tanksynth.plants.base import exact
# Module import (not names): tanksynth.analysis.rank imports tanksynth.design, so
# this module may be loaded while verify.rank is still initialising.
from tanksynth.analysis import rank as _rank
from tanksynth.design.lmi import SOLVERS, LMICheck

__all__ = [
    "LMIPlacementResult",
    "lmi_state_feedback",
    "lmi_observer",
    "PlacementResult",
    "place_state_feedback",
    "place_observer",
    "AugmentedSystem",
    "integral_augmentation",
    "CanonicalObserver",
    "canonical_observer",
    "pole_errors",
]


# ------------------------------------------------------------------------ regions


# -------------------------------------------------------------------- helpers
def _matrix(value: Any, name: str) -> np.ndarray:
    try:
        arr = np.atleast_2d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a real 2-D array") from None
    if arr.ndim != 2 or not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be a finite 2-D array")
    return arr


def _pair(A: Any, B: Any, nameB: str = "B") -> tuple[np.ndarray, np.ndarray]:
    A = _matrix(A, "A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise DimensionError(f"A must be square, got shape {A.shape}")
    B = _matrix(B, nameB)
    if B.shape[0] != n:
        raise DimensionError(f"{nameB} has {B.shape[0]} rows, expected n = {n}")
    return A, B


def _refuse_uncontrollable(A: np.ndarray, B: np.ndarray, names: Sequence[str] | None,
                           dual: bool) -> None:
    rank = _rank.controllability_rank(A, B)
    if rank.full:
        return
    pbh = _rank.pbh_test(A, B=B, state_names=names)
    modes = "; ".join(f"eigenvalue {m.eigenvalue:.4g} in states {list(m.states)}" for m in pbh.modes)
    if dual:
        raise UnobservableError(f"(A, C) is not observable (rank {rank.rank} < {rank.n}); "
                                f"unobservable modes: {modes or 'not isolated by PBH'}")
    raise UncontrollableError(f"(A, B) is not controllable (rank {rank.rank} < {rank.n}); "
                              f"uncontrollable modes: {modes or 'not isolated by PBH'}")


def _poles(poles: Any, n: int) -> np.ndarray:
    try:
        p = np.asarray(poles, dtype=complex).reshape(-1)
    except (TypeError, ValueError):
        raise SpecError(f"poles must be numbers, got {poles!r}", key="poles") from None
    if p.size != n:
        raise DimensionError(f"{p.size} poles given, expected n = {n}")
    if not np.all(np.isfinite(p)):
        raise SpecError("poles must be finite", key="poles")
    a = np.sort_complex(p)
    b = np.sort_complex(np.conj(p))
    if not np.allclose(a, b, rtol=0, atol=1e-12 * max(1.0, float(np.max(np.abs(p))))):
        raise SpecError("complex poles must come in conjugate pairs", key="poles")
    return p


def pole_errors(requested: Any, achieved: Any) -> tuple[np.ndarray, float]:
    """Match achieved to requested poles (assignment) and return the errors.

    Parameters
    ----------
    requested, achieved : array_like of complex, same length

    Returns
    -------
    errors : ndarray
        ``|achieved - requested|`` after the best one-to-one matching.
    max_error : float
    """
    r = np.asarray(requested, dtype=complex).reshape(-1)
    a = np.asarray(achieved, dtype=complex).reshape(-1)
    cost = np.abs(r[:, None] - a[None, :])
    rows, cols = linear_sum_assignment(cost)
    err = cost[rows, cols]
    return err, float(err.max()) if err.size else 0.0


def _complex_list(values: np.ndarray) -> list[list[float]]:
    return [[float(v.real), float(v.imag)] for v in np.sort_complex(np.asarray(values, dtype=complex))]


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


# -------------------------------------------------------------- exact placement
@dataclass(frozen=True)
class PlacementResult:
    """Exact pole placement with its accuracy report.

    Attributes
    ----------
    gain : ndarray
        ``K`` (m, n) or ``L`` (n, q).
    kind : str
        ``"state_feedback"`` or ``"observer"``.
    method : str
        ``"place"`` (python-control, Tits-Yang) or ``"acker"``.
    requested, achieved : ndarray of complex
        Requested poles and eigenvalues of the closed loop.
    errors : ndarray
        Matched ``|achieved - requested|``.
    max_pole_error : float
    eigenvector_condition : float
        2-norm condition number of the closed-loop eigenvector matrix
        (large: poles sensitive to perturbations of the gain).
    closed_loop : ndarray, shape (n, n)
        ``A - B K`` or ``A - L C``.
    """

    gain: np.ndarray
    kind: str
    method: str
    requested: np.ndarray
    achieved: np.ndarray
    errors: np.ndarray
    max_pole_error: float
    eigenvector_condition: float
    closed_loop: np.ndarray

    def as_dict(self) -> dict:
        """JSON-friendly accuracy report."""
        return {"kind": self.kind, "method": self.method,
                "requested": _complex_list(self.requested), "achieved": _complex_list(self.achieved),
                "max_pole_error": self.max_pole_error,
                "eigenvector_condition": self.eigenvector_condition,
                "gain_norm": float(np.linalg.norm(self.gain, 2))}


def place_state_feedback(A: Any, B: Any, poles: Any, method: str = "auto", tol: float = 1e-6,
                         state_names: Sequence[str] | None = None,
                         _dual: bool = False) -> PlacementResult:
    """Exact pole placement ``eig(A - B K) = poles`` with python-control.

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, m)
    poles : array_like of complex, length n
        Complex poles in conjugate pairs (1/s in continuous time).
    method : {"auto", "place", "acker"}
        ``auto``: ``acker`` for one input, ``place`` (Tits-Yang) otherwise.
    tol : float
        Largest accepted pole error relative to ``max(1, |pole|)``.
    state_names : sequence of str, optional

    Returns
    -------
    PlacementResult

    Raises
    ------
    UncontrollableError
        Before placing, naming the modes.
    SpecError
        Poles not in conjugate pairs, or a pole repeated more than
        ``rank(B)`` times for ``place``.
    InfeasibleDesign
        The achieved poles miss the requested ones by more than ``tol``.
    """
    A, B = _pair(A, B, "C'" if _dual else "B")
    n, m = B.shape
    p = _poles(poles, n)
    if method not in ("auto", "place", "acker"):
        raise SpecError(f"unknown placement method {method!r}; expected auto, place or acker",
                        key="method")
    if method == "auto":
        method = "acker" if m == 1 else "place"
    if method == "acker" and m != 1:
        raise DimensionError(f"acker needs a single input (column), got {m}")
    _refuse_uncontrollable(A, B, state_names, _dual)
    try:
        K = np.asarray(control.acker(A, B, p) if method == "acker" else control.place(A, B, p),
                       dtype=float)
    except ValueError as exc:
        raise SpecError(f"{method} cannot place these poles: {exc}", key="poles") from None
    K = K.reshape(m, n)
    Acl = A - B @ K
    ach, V = np.linalg.eig(Acl)
    err, emax = pole_errors(p, ach)
    rel = float(np.max(err / np.maximum(1.0, np.abs(p))))
    if rel > tol:
        raise InfeasibleDesign(f"pole placement inaccurate: largest pole error {emax:.3g} "
                               f"(relative {rel:.3g} > {tol:g}); eigenvector condition "
                               f"{np.linalg.cond(V):.3g}")
    kind = "observer" if _dual else "state_feedback"
    gain = K.T if _dual else K
    cl = Acl.T if _dual else Acl
    return PlacementResult(gain, kind, method, p, np.linalg.eigvals(cl), err, emax,
                           float(np.linalg.cond(V)), cl)


def place_observer(A: Any, C: Any, poles: Any, method: str = "auto", tol: float = 1e-6,
                   state_names: Sequence[str] | None = None) -> PlacementResult:
    """Exact observer placement ``eig(A - L C) = poles`` (dual of state feedback).

    Parameters
    ----------
    A : array_like, shape (n, n)
    C : array_like, shape (q, n)
    poles : array_like of complex, length n
    method : {"auto", "place", "acker"}
    tol : float
    state_names : sequence of str, optional

    Returns
    -------
    PlacementResult
        ``gain`` is ``L`` (n, q).

    Raises
    ------
    UnobservableError
        Before placing, naming the modes.
    """
    A = _matrix(A, "A")
    C = _matrix(C, "C")
    if C.shape[1] != A.shape[0]:
        raise DimensionError(f"C has {C.shape[1]} columns, expected n = {A.shape[0]}")
    return place_state_feedback(A.T, C.T, poles, method, tol, state_names, _dual=True)


# ------------------------------------------------------------- integral action
@dataclass(frozen=True)
class AugmentedSystem:
    """Discrete plant augmented with tracking integrators (seed 000 eq. 14-15).

    ``x_e = [x; z]``, ``x_e(k+1) = A x_e + B u + Br y_r``.

    Attributes
    ----------
    A : ndarray, shape (n+p, n+p)
        ``[[A_d, 0], [-ts C1, I]]``.
    B : ndarray, shape (n+p, m)
        ``[[B_d], [0]]``.
    Br : ndarray, shape (n+p, p)
        ``[[0], [ts I]]``.
    C1 : ndarray, shape (p, n)
        Tracked outputs.
    ts : float
        Sampling period (s).
    """

    A: np.ndarray
    B: np.ndarray
    Br: np.ndarray
    C1: np.ndarray
    ts: float

    @property
    def n(self) -> int:
        """Plant states."""
        return self.C1.shape[1]

    @property
    def p(self) -> int:
        """Integrators."""
        return self.C1.shape[0]


def integral_augmentation(Ad: Any, Bd: Any, C1: Any, ts: float) -> AugmentedSystem:
    """Augment ``(A_d, B_d)`` with ``z(k+1) = z(k) + ts (y_r - C1 x)`` (seed 000 eq. 13-15).

    Parameters
    ----------
    Ad : array_like, shape (n, n)
    Bd : array_like, shape (n, m)
        State unit per input unit.
    C1 : array_like, shape (p, n)
        Tracked outputs, ``p <= m``.
    ts : float
        Sampling period (s, > 0).

    Returns
    -------
    AugmentedSystem
    """
    Ad, Bd = _pair(Ad, Bd, "Bd")
    C1 = _matrix(C1, "C1")
    n, m = Bd.shape
    p = C1.shape[0]
    if C1.shape[1] != n:
        raise DimensionError(f"C1 has {C1.shape[1]} columns, expected n = {n}")
    if p > m:
        raise DimensionError(f"{p} tracked outputs but only {m} inputs (seed 000 needs p <= m)")
    if not (isinstance(ts, (int, float)) and np.isfinite(ts) and ts > 0):
        raise SpecError(f"sampling period must be > 0 s, got {ts!r}", key="sampling.ts")
    A = np.block([[Ad, np.zeros((n, p))], [-ts * C1, np.eye(p)]])
    B = np.vstack([Bd, np.zeros((p, m))])
    Br = np.vstack([np.zeros((n, p)), ts * np.eye(p)])
    return AugmentedSystem(A, B, Br, C1, float(ts))


# ------------------------------------------------------------ canonical form
@dataclass(frozen=True)
class CanonicalObserver:
    """Observer gain through the observer canonical form (seed 004 eq. 27-29).

    All matrices are exact sympy matrices.

    Attributes
    ----------
    A, C : sympy.Matrix
    Q_O : sympy.Matrix
        Observability matrix ``[C; CA; ...]``.
    char_coefficients : tuple
        ``(a_0, ..., a_{n-1})`` of ``det(sI - A) = s^n + a_{n-1} s^{n-1} + ... + a_0``.
    A_o, C_o : sympy.Matrix
        Observer canonical form (companion matrix, ``C_o = [0 ... 0 1]``).
    Q_O_bar : sympy.Matrix
        Observability matrix of ``(A_o, C_o)``.
    Delta : sympy.Matrix
        ``Q_O^-1 Qbar_O`` (eq. 27).
    desired_coefficients : tuple
        ``(alpha_0, ..., alpha_{n-1})`` of ``prod (s - p_i)``.
    Psi_o : sympy.Matrix
        ``alpha - a`` (eq. 28).
    Psi : sympy.Matrix
        ``Delta Psi_o`` (eq. 29), the observer gain ``L``.
    Gamma_d : sympy.Matrix
        ``A - Psi C``.
    exact : bool
        ``det(sI - Gamma_d)`` equals the desired polynomial exactly.
    """

    A: sp.Matrix
    C: sp.Matrix
    Q_O: sp.Matrix
    char_coefficients: tuple
    A_o: sp.Matrix
    C_o: sp.Matrix
    Q_O_bar: sp.Matrix
    Delta: sp.Matrix
    desired_coefficients: tuple
    Psi_o: sp.Matrix
    Psi: sp.Matrix
    Gamma_d: sp.Matrix
    exact: bool

    @property
    def gain(self) -> np.ndarray:
        """``Psi`` as a float array, shape (n, 1)."""
        return np.array(self.Psi.evalf(17), dtype=float).reshape(-1, 1)

    def as_dict(self) -> dict:
        """JSON-friendly form (exact values as strings)."""
        s = lambda M: [[str(v) for v in M.row(i)] for i in range(M.rows)]  # noqa: E731
        return {"Q_O": s(self.Q_O), "A_o": s(self.A_o), "C_o": s(self.C_o), "Q_O_bar": s(self.Q_O_bar),
                "Delta": s(self.Delta), "char_coefficients": [str(v) for v in self.char_coefficients],
                "desired_coefficients": [str(v) for v in self.desired_coefficients],
                "Psi_o": [str(v) for v in self.Psi_o], "Psi": [str(v) for v in self.Psi],
                "Gamma_d": s(self.Gamma_d), "characteristic_polynomial_exact": self.exact}


def _exact_matrix(M: Any, name: str) -> sp.Matrix:
    if isinstance(M, sp.MatrixBase):
        out = sp.Matrix(M)
    else:
        arr = np.atleast_2d(np.asarray(M, dtype=float))
        if not np.all(np.isfinite(arr)):
            raise DimensionError(f"{name} has non-finite entries")
        out = sp.Matrix([[exact(v) for v in row] for row in arr])
    if out.free_symbols:
        names = sorted(map(str, out.free_symbols))
        raise DimensionError(f"{name} must be numeric, has symbols {names}")
    return out


def _exact_pole(p: Any) -> sp.Expr:
    if isinstance(p, sp.Expr):
        return p
    c = complex(p)
    return exact(c.real) + (sp.I * exact(c.imag) if c.imag else 0)


def canonical_observer(A: Any, C: Any, poles: Sequence[Any]) -> CanonicalObserver:
    """Observer gain by the observer canonical form, in exact arithmetic (seed 004).

    Parameters
    ----------
    A : array_like or sympy.Matrix, shape (n, n)
        Floats are converted to exact rationals of their decimal form.
    C : array_like or sympy.Matrix, shape (1, n)
        Single output.
    poles : sequence
        Desired observer poles (numbers or sympy numbers; complex ones in
        conjugate pairs).

    Returns
    -------
    CanonicalObserver

    Raises
    ------
    DimensionError
        Not square, not single-output, wrong number of poles.
    UnobservableError
        ``Q_O`` singular.
    """
    A = _exact_matrix(A, "A")
    C = _exact_matrix(C, "C")
    n = A.rows
    if A.shape != (n, n):
        raise DimensionError(f"A must be square, got shape {A.shape}")
    if C.shape != (1, n):
        raise DimensionError(f"the canonical-form route needs a single output: C must be (1, {n}), "
                             f"got {C.shape}")
    if len(poles) != n:
        raise DimensionError(f"{len(poles)} poles given, expected n = {n}")
    _poles([complex(sp.N(_exact_pole(p))) for p in poles], n)
    s = sp.Symbol("s")
    Q_O = sp.Matrix.vstack(*[C * A ** k for k in range(n)])
    if Q_O.det() == 0:
        raise UnobservableError(f"(A, C) is not observable: Q_O is singular (rank {Q_O.rank()} < {n})")
    a = A.charpoly(s).all_coeffs()[::-1][:n]            # a_0 .. a_{n-1}
    A_o = sp.zeros(n, n)
    for i in range(1, n):
        A_o[i, i - 1] = 1
    for i in range(n):
        A_o[i, n - 1] = -a[i]
    C_o = sp.zeros(1, n)
    C_o[0, n - 1] = 1
    Q_bar = sp.Matrix.vstack(*[C_o * A_o ** k for k in range(n)])
    Delta = Q_O.inv() * Q_bar
    desired = sp.Poly(sp.expand(sp.prod([s - _exact_pole(p) for p in poles])), s)
    alpha = [sp.nsimplify(sp.expand(c)) for c in desired.all_coeffs()[::-1][:n]]
    if any(sp.im(c) != 0 for c in alpha):
        raise SpecError("complex poles must come in conjugate pairs", key="poles")
    Psi_o = sp.Matrix([alpha[i] - a[i] for i in range(n)])
    Psi = (Delta * Psi_o).applyfunc(sp.nsimplify)
    Gamma = (A - Psi * C).applyfunc(sp.nsimplify)
    ok = sp.expand(Gamma.charpoly(s).as_expr() - desired.as_expr()) == 0
    return CanonicalObserver(A, C, Q_O, tuple(a), A_o, C_o, Q_bar, Delta, tuple(alpha), Psi_o, Psi,
                             Gamma, bool(ok))
