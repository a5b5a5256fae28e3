"""Pole placement in LMI regions (Chilali-Gahinet), with Clarabel (SCS through cvxpy).

    ``D = {z : L_D + M_D z + M_D' conj(z) < 0}``: half-plane ``Re z < -alpha``,
    disk (centre, radius; the natural region in discrete time), conic sector,
    and intersections of these. ``A - B K`` has all its eigenvalues in ``D``
    iff there is ``X > 0`` with ``L_D (x) X + M_D (x) (A X - B Y) + M_D' (x)
    (A X - B Y)' < 0``, ``K = Y X^-1``. Observers use the dual ``(A', C')``.
    Solved with Clarabel (conic form written directly) after scaling (diagonal balancing of ``A``,
    input normalisation, time scaling in continuous time), with an explicit
    margin, and re-checked in numpy (LMI eigenvalues, closed-loop
    eigenvalues inside the region).

Stabilisability relative to the region: an uncontrollable (unobservable)
mode cannot be moved, so the design is refused only when such a mode lies
outside the region (named with the states its PBH direction lives in); modes
already inside are kept and listed in the diagnostics.

The conditioning bound ``I <= X <= kappa I`` (`tanksynth.design.lmi_checks`): when a refused
LMI has ``X`` at the bound (``lambda_max(X) >= (1 - 1e-3) kappa``), the bound, not the
region, limits the margin; the LMI is retried with ``kappa`` multiplied by
``KAPPA_STEP`` up to ``kappa_max`` before refusing, and a refusal says the
bound is active and names the option.

The routes are collected in `tanksynth.design.placement.canonical`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import scipy.linalg as sla

# Module import (not names), so that a test may replace the rank functions.
from tanksynth.analysis import rank as _rank
from tanksynth.analysis.lmi_region import LMIRegion, check_region, variable_of
from tanksynth.design.conic import modelling
from tanksynth.design.lmi_checks import KAPPA_STEP, LMICheck, check_solver, kappa_active
from tanksynth.design.result import FeedbackGain
from tanksynth.design.matrices import complex_pairs, matrix_pair, real_matrix, symmetrized
from tanksynth.errors import (DimensionError, InfeasibleDesign, SpecError, UncontrollableError,
                              UnobservableError)

__all__ = [
    "LMIPlacementResult",
    "lmi_state_feedback",
    "lmi_observer",
    "fixed_modes",
]


def fixed_modes(A: Any, B: Any, state_names: Sequence[str] | None = None
                ) -> list[tuple[complex, tuple[str, ...]]]:
    """Uncontrollable modes of ``(A, B)`` and the states they live in (Kalman decomposition).

    With ``U = [U_c, U_n]`` from the SVD of the controllability matrix
    (``U_c`` spans the controllable subspace), the modes no gain moves are the
    eigenvalues of ``U_n' A U_n``; for each, ``U_n w`` (``w`` a left
    eigenvector) is a PBH direction (``v' A = lambda v'``, ``v' B = 0``), and
    the states carrying at least 10% of its largest entry are named. For an
    observer pass ``(A', C')``: the modes are the unobservable ones.

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, m)
    state_names : sequence of str, optional

    Returns
    -------
    list of (complex, tuple of str)
        Empty when the pair is controllable.
    """
    A, B = matrix_pair(A, B)
    n = A.shape[0]
    names = list(state_names) if state_names is not None else [f"x{i + 1}" for i in range(n)]
    rank = _rank.controllability_rank(A, B)
    if rank.full:
        return []
    U, _, _ = np.linalg.svd(rank.matrix)
    Un = U[:, rank.rank:]
    lam, W = sla.eig(Un.T @ A @ Un, left=True, right=False)
    out = []
    for k, z in enumerate(lam):
        v = np.abs(Un @ W[:, k])
        out.append((complex(z), tuple(nm for nm, x in zip(names, v) if x >= 0.1 * v.max())))
    return out


def _refuse_outside_region(A: np.ndarray, B: np.ndarray, region: LMIRegion,
                           names: Sequence[str] | None, dual: bool) -> list[dict]:
    """Refuse an uncontrollable (unobservable) mode outside the region; list those inside."""
    modes = fixed_modes(A, B, names)
    outside = [(z, st) for z, st in modes if not region.margin(z) > 0]
    what = "unobservable" if dual else "uncontrollable"
    text = lambda ms: "; ".join(f"eigenvalue {z:.4g} in states {list(st)}" for z, st in ms)  # noqa: E731
    if outside:
        cls = UnobservableError if dual else UncontrollableError
        pair = "(A, C) is not detectable" if dual else "(A, B) is not stabilisable"
        raise cls(f"{pair} relative to the region {region.describe()}: {what} mode(s) outside it "
                  f"({text(outside)}) cannot be moved by any gain")
    return [{"eigenvalue": [z.real, z.imag], "states": list(st), "region_margin": region.margin(z),
             "note": f"{what} mode already inside the region: kept, not moved"} for z, st in modes]


# ---------------------------------------------------------------- LMI placement
@dataclass(frozen=True)
class LMIPlacementResult(FeedbackGain):
    """State feedback or observer gain with eigenvalues in an LMI region.

    Attributes
    ----------
    gain_matrix : ndarray
        Read as ``K`` / ``L`` (`FeedbackGain`; ``gain`` is deprecated): ``K`` (m, n) for ``A - B K`` or ``L`` (n, q) for ``A - L C``.
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
        ``-lambda_max(f_D(lambda_i))`` of each closed-loop eigenvalue (> 0; 1/s in
        continuous time, dimensionless in discrete time).
    scaling : dict
        State balancing, input normalisation and time scale applied; the
        ``kappa`` used and every try of the relaxation (``kappa_tries``).
    fixed_modes : tuple of dict
        Uncontrollable (unobservable) modes already inside the region.
    """

    gain_matrix: np.ndarray
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
    fixed_modes: tuple = ()

    def as_dict(self) -> dict:
        """JSON-friendly diagnostics (no gains)."""
        return {"kind": self.kind, "region": self.region.as_dict(), "domain": self.domain,
                "margin": self.margin, "achieved_margin": self.achieved_margin,
                "solver": self.solver, "status": self.status, "solve_time_s": self.solve_time,
                "checks": [c.as_dict() for c in self.checks],
                "closed_loop_eigenvalues": complex_pairs(self.closed_loop_eigenvalues),
                "min_region_margin": float(np.min(self.region_margins)),
                "min_boundary_distance": float(min(self.region.boundary_distance(z)
                                                   for z in self.closed_loop_eigenvalues)),
                "condition_P": float(np.linalg.cond(self.P)),
                "gain_norm": float(np.linalg.norm(self.gain_matrix, 2)),
                "scaling": self.scaling, "fixed_modes": list(self.fixed_modes)}


def _d_lmi(region: LMIRegion, Acl_X: Any, X: Any, kron) -> Any:
    return kron(region.L, X) + kron(region.M, Acl_X) + kron(region.M.T, Acl_X.T)


def lmi_state_feedback(A: Any, B: Any, region: LMIRegion, *, domain: str = "continuous",
                       margin: float = 1e-6, kappa: float = 1e4, solver: str = "CLARABEL",
                       state_names: Sequence[str] | None = None, kappa_max: float | None = None,
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
    kappa_max : float, optional
        When phase 1 misses the margin with ``X`` at the bound ``kappa I``,
        retry with ``kappa`` times `KAPPA_STEP` up to ``kappa_max``
        (default: ``kappa``, no retry).

    Returns
    -------
    LMIPlacementResult

    Raises
    ------
    SpecError
        Region not inside the stability domain, bad options.
    UncontrollableError
        Before solving: an uncontrollable mode outside the region (named,
        with its states); modes inside the region are kept.
    InfeasibleDesign
        Solver infeasible/failed or re-check failed; says when the
        conditioning bound was active.
    """
    A, B = matrix_pair(A, B, "C'" if _dual else "B")
    n, m = B.shape[0], B.shape[1]
    if domain not in ("continuous", "discrete"):
        raise SpecError(f"domain must be 'continuous' or 'discrete', got {domain!r}", key="domain")
    if not isinstance(region, LMIRegion):
        raise SpecError("region must be an LMIRegion", key="region")
    check_region(region, domain)  # empty, or not stable: refused before any solve
    v = variable_of(domain)
    if not (isinstance(margin, (int, float)) and 0 < margin < 1):
        raise SpecError(f"margin must be in (0, 1), got {margin!r}", key="margin")
    check_solver(solver)
    kappa_max = float(kappa if kappa_max is None else max(kappa_max, kappa))
    fixed = _refuse_outside_region(A, B, region, state_names, _dual)
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
    start = time.perf_counter()
    tries: list[dict] = []
    kap = float(kappa)
    while True:
        X, Y, phase2, tstar, status, active = _phase1(As, Bs, reg, n, m, kap, solver)
        tries.append({"kappa": kap, "largest_margin_t": tstar, "status": status,
                      "bound_active": active})
        if tstar >= margin:
            break
        if active is not False and kap < kappa_max:
            kap = min(kap * KAPPA_STEP, kappa_max)
            continue
        if active:
            tried = ", ".join(f"{tr['kappa']:g}" for tr in tries)
            raise InfeasibleDesign(
                f"no gain places the eigenvalues in {region.describe(v)} with margin {margin:g} "
                f"within the conditioning bound I <= X <= kappa I: the bound is active at the "
                f"optimum (lambda_max(X) = kappa = {kap:g}; tried kappa = "
                f"{tried}), largest margin t* = {tstar:.3g}; "
                f"raise the option 'kappa_max' (or 'kappa') to allow a worse-conditioned Lyapunov "
                f"matrix (and larger gains)")
        raise InfeasibleDesign(
            f"no gain places the eigenvalues in {region.describe(v)} with margin {margin:g}: solver "
            f"{solver} status {status}, largest achievable margin t* = {tstar:.3g} (max t s.t. region "
            f"LMI <= -t I, I <= X <= {kap:g} I"
            + ("; the conditioning bound is not active, so the optimum certifies that no larger "
               "margin exists)" if active is False else "; the solver returned no point)"))
    Xv, Yv = X.value.copy(), Y.value.copy()
    status2 = phase2(max(margin, 0.5 * tstar))
    if status2 in ("optimal", "optimal_inaccurate") and X.value is not None:
        Xv, Yv, status = X.value, Y.value, f"{status} (phase 1), {status2} (phase 2)"
    else:
        status = f"{status} (phase 1), {status2} (phase 2 failed: phase-1 gain kept)"
    elapsed = time.perf_counter() - start
    Xs = symmetrized(Xv)
    Ks = np.linalg.solve(Xs.T, np.asarray(Yv).T).T           # Y X^-1
    K = (su[:, None] * Ks) / s[None, :]                            # S_u Ks T^-1
    # --- independent re-check (numpy) ---
    Acl_s = As - Bs @ Ks
    Mn = symmetrized(_d_lmi(reg, Acl_s @ Xs, Xs, np.kron))
    eig_n = np.linalg.eigvalsh(Mn)
    Xo = (s[:, None] * Xs) * s[None, :]                             # T Xs T'
    Acl = A - B @ K
    Mo = symmetrized(_d_lmi(region, Acl @ Xo, Xo, np.kron))
    eig_o = float(np.max(np.linalg.eigvalsh(Mo)))
    lam = np.linalg.eigvals(Acl)
    margins = np.array([region.margin(z) for z in lam])
    xmin = float(np.min(np.linalg.eigvalsh(Xs)))
    need = -0.5 * margin
    checks = (
        LMICheck.test("region LMI, normalised (max eigenvalue <= -margin/2)", float(eig_n.max()), "<=", need,
                      unit="normalised"),
        LMICheck.test("region LMI, original units (max eigenvalue < 0)", eig_o, "<", 0.0, unit="original units"),
        LMICheck.test("X > 0 (min eigenvalue, normalised)", xmin, ">", 0.0),
        LMICheck.test("closed-loop eigenvalues inside the region (min -lambda_max f_D)",
                      float(margins.min()), ">", 0.0),
    )
    failed = [c for c in checks if not c.passed]
    if failed:
        worst = "; ".join(f"{c.name}: {c.value:.4g} vs {c.limit:.4g}" for c in failed)
        raise InfeasibleDesign(f"LMI region placement fails the independent re-check ({worst}); "
                               f"solver {solver} status {status}")
    kind = "observer" if _dual else "state_feedback"
    P = Xo if _dual else np.linalg.inv(Xo)
    return LMIPlacementResult(
        gain_matrix=K.T if _dual else K, P=symmetrized(P), X=Xo, kind=kind, region=region, domain=domain,
        margin=float(margin), achieved_margin=float(-eig_n.max()), solver=solver, status=status,
        solve_time=elapsed, checks=checks, closed_loop_eigenvalues=lam, region_margins=margins,
        scaling={"state_balance": s.tolist(), "input_scale": su.tolist(), "time_scale": omega,
                 "normalisation": "I <= X <= kappa I", "kappa": kap, "kappa_requested": kappa,
                 "kappa_max": kappa_max, "kappa_tries": tries,
                 "kappa_relaxed": bool(kap > kappa), "largest_margin_t": tstar,
                 "objective": "phase 1: max margin t; phase 2: min ||Y||_F with LMI <= -max(margin, "
                              "t/2) I", "formulation": "dual (A', C')" if _dual else "primal"},
        fixed_modes=tuple(fixed))



def _phase1(As: np.ndarray, Bs: np.ndarray, reg: LMIRegion, n: int, m: int, kappa: float,
            solver: str):
    """Build both phases for one ``kappa`` and solve phase 1.

    Returns ``(X, Y, phase2, t*, status, active)``; ``phase2(bound)`` solves
    phase 2 with the margin ``bound`` (dimensionless) and returns its status;
    ``active`` is whether ``X`` sits at ``kappa I`` (None when the solver
    returned no point). With Clarabel the LMIs are written straight in its
    conic form (`tanksynth.design.conic`), with SCS through cvxpy.
    """
    I = np.eye(n)
    lib = modelling(solver)
    X = lib.variable((n, n), symmetric=True)
    Y = lib.variable((m, n))
    t = lib.variable()
    lib.reserve_norm()
    lmi = _d_lmi(reg, As @ X - Bs @ Y, X, lib.kron)
    lmi = symmetrized(lmi)
    d = reg.order * n
    box = [X >> I, X << kappa * I]
    # Phase 1: largest margin t (certifies infeasibility when t* < margin and the box is slack).
    phase1 = lib.Problem(lib.Maximize(t), [lmi << -t * np.eye(d), t <= 1.0, *box])

    def phase2(bound: float) -> str:
        # Phase 2: smallest ||Y||_F keeping half of the achievable margin (moderate gains).
        prob = lib.Problem(lib.Minimize(lib.norm_fro(Y)), [lmi << -bound * np.eye(d), *box])
        return lib.solve_status(prob, solver)

    status = lib.solve_status(phase1, solver)
    solved = status in ("optimal", "optimal_inaccurate") and t.value is not None
    tstar = float(t.value) if solved else -np.inf
    active = None
    if solved and X.value is not None:
        active = kappa_active(X.value, kappa, bound="eigenvalue")
    return X, Y, phase2, tstar, status, active


def lmi_observer(A: Any, C: Any, region: LMIRegion, *, domain: str = "continuous",
                 margin: float = 1e-6, kappa: float = 1e4, solver: str = "CLARABEL",
                 state_names: Sequence[str] | None = None,
                 kappa_max: float | None = None) -> LMIPlacementResult:
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
    kappa_max : float, optional
        Ceiling of the relaxation of ``kappa`` (see `lmi_state_feedback`).

    Returns
    -------
    LMIPlacementResult
        ``gain`` is ``L`` (n, q); ``P`` is the Lyapunov matrix of ``A - L C``.

    Raises
    ------
    UnobservableError
        Before solving: an unobservable mode outside the region (named);
        modes inside it are kept.
    InfeasibleDesign
    """
    A = real_matrix(A, "A")
    C = real_matrix(C, "C")
    if C.shape[1] != A.shape[0]:
        raise DimensionError(f"C has {C.shape[1]} columns, expected n = {A.shape[0]}")
    return lmi_state_feedback(A.T, C.T, region, domain=domain, margin=margin, kappa=kappa,
                              solver=solver, state_names=state_names, kappa_max=kappa_max,
                              _dual=True)


