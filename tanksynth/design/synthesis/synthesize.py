"""H2 and H-infinity synthesis by LMIs (Clarabel; SCS through cvxpy): building blocks and solvers.

Generalised plant (continuous time: ``x' = dx/dt``; discrete time: ``x' = x(k+1)``)::

    x' = A x + Bw w + B u          w: declared disturbances
    z  = Cz x + Dzu u              z: performance outputs (no direct term from w)

State feedback ``u = -K x`` gives ``Acl = A - B K``, ``Bw``, ``Ccl = Cz - Dzu K``.
The LMIs are written in ``X = X' > 0`` and ``Y = K X`` (``K = Y X^-1``); every
block builder below returns a matrix that must be NEGATIVE definite and works
on affine expressions (for solving) and on numpy arrays (for re-checking): `h2_lmis`,
`hinf_lmis`, `region_lmi` (their formulas: `tanksynth.design.synthesis.lmis`).

`synthesize_state_feedback` solves any combination (H2 and/or H-infinity
objective or bound, LMI region) with ONE ``X`` and ``Y`` shared by every
objective and by every model given (vertices of a polytope: robust designs),
which is conservative (the bounds returned are guaranteed, the achieved norms
are recomputed). Observers are the duals (`observer_plant`): the error
``e' = (A - L C) e + Bw w - L Dv v``, ``z = Cz e``, has the same norms as its
transpose, a state-feedback problem in ``(A', C')`` with gain ``L'``.

Numerics: the problem is scaled before solving (diagonal balancing of ``A``,
unit input columns, scalar scaling of ``w`` and ``z``, time scaling by
``||A||`` in continuous time); the solver status is never trusted: the gain
is re-checked in numpy in the original units (closed-loop eigenvalues,
region, H2 norm from the Gramian, H-infinity norm by a Hamiltonian test and
bisection) and refused (`InfeasibleDesign`) when a claim fails.

Route: a pure H2 / H-infinity design (one model, no region, no bounds) is
solved by default with its Riccati equation (`tanksynth.design.synthesis.riccati`),
which has the same optimum and scales (N = 64 tanks in about a second, where
Clarabel's dense factorisation of the LMI takes minutes); ``route = "lmi"``
forces the LMIs. Both routes' gains get the same re-check.

Solver: with Clarabel the LMIs are written straight in its conic form
(`tanksynth.design.conic`: no cvxpy import, no canonicalisation);
SCS solves the same LMIs through cvxpy.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import scipy.linalg as sla

from tanksynth.analysis.blas import small_dense
from tanksynth.analysis.lmi_region import LMIRegion, check_region, variable_of
from tanksynth.analysis.statespace import h2_norm, hinf_below, hinf_norm, statespace_matrices
from tanksynth.design.conic import modelling
from tanksynth.design.lmi_checks import SOLVERS, LMICheck, check_solver
from tanksynth.design.result import FeedbackGain
from tanksynth.design.matrices import symmetrized
from tanksynth.design.synthesis.lmis import (DOMAINS, GeneralizedPlant, generalized_plant, h2_lmis,
                                            hinf_lmis, hinf_lmis_reduced, observer_plant, region_lmi)
from tanksynth.design.synthesis.riccati import riccati_applicable, riccati_h2, riccati_hinf
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError

__all__ = [
    "DOMAINS", "OBJECTIVES", "SOLVERS", "ROUTES", "NORM_RTOL", "CERTIFICATE_RTOL", "distinct_digits",
    "GeneralizedPlant", "generalized_plant", "observer_plant", "statespace_matrices",
    "h2_lmis", "hinf_lmis", "hinf_lmis_reduced", "region_lmi",
    "h2_norm", "hinf_norm", "hinf_below",
    "SynthesisResult", "synthesize_state_feedback", "synthesize_observer",
]

#: What `synthesize_state_feedback` minimises (``"none"``: feasibility, well-conditioned point).
OBJECTIVES = ("h2", "hinf", "none")
#: How a pure H2 / H-infinity design is solved: ``"auto"`` (Riccati when it applies, else LMI),
#: ``"riccati"`` (required; refused when it does not apply) or ``"lmi"``.
ROUTES = ("auto", "riccati", "lmi")
#: Relative tolerance of the re-check: achieved norm <= claimed bound (1 + NORM_RTOL).
NORM_RTOL = 1e-6
#: Clarabel settings (tighter than the defaults: the H2 optimum is compared with Riccati to 1e-6).
_CLARABEL = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10, "max_iter": 400}


# ===================================================================== the solver
@dataclass(frozen=True, eq=False)
class SynthesisResult(FeedbackGain):
    """A solved and re-checked H2 / H-infinity / region synthesis.

    Attributes
    ----------
    gain_matrix : ndarray
        Read as ``K`` / ``L`` (`FeedbackGain`; ``gain`` is deprecated): ``K`` (m, n) for ``u = -K x``, or ``L`` (n, q) for an observer (``dual``).
    kind : str
        ``"state_feedback"`` or ``"observer"``.
    objective : str
        One of `OBJECTIVES`.
    domain : str
    X : ndarray, shape (n, n)
        The common Lyapunov variable mapped back to the original coordinates
        (``T Xs T'``, up to a positive scalar per objective): certificate of
        the region LMI in original units (of the dual for an observer).
    h2 : float or None
        Guaranteed bound on the H2 norm of every model's closed loop
        (z unit per w unit, times s^-1/2 in continuous time); None when no H2
        objective or bound was part of the problem.
    gamma : float or None
        Guaranteed bound on the H-infinity norm (z unit per w unit).
    h2_optimum, gamma_optimum : float or None
        The optimum before the back-off: LMI phase 1, or (Riccati route) the
        LQR's H2 norm / the upper end of the gamma bisection's final bracket
        (``as_dict`` keeps the keys ``h2_lmi_optimum``, ``gamma_lmi_optimum``).
    achieved_h2, achieved_hinf : tuple of float
        Norms of each model's closed loop recomputed in numpy (Gramian;
        Hamiltonian bisection), whether or not they were part of the problem.
    closed_loop_eigenvalues : tuple of ndarray
        Of each model (1/s or z-plane).
    region : LMIRegion or None
    region_margins : tuple of float
        Smallest ``-lambda_max(f_D(lambda))`` of each model's eigenvalues (1/s in
        continuous time, dimensionless in discrete time).
    solver, status : str
    solve_time : float
        s.
    checks : tuple of LMICheck
        The independent re-check (all passed, or the design was refused).
    scaling : dict
    route : str
        ``"lmi"`` (cvxpy) or ``"riccati"`` (scipy ARE; one model, no region or
        bounds): see `synthesize_state_feedback`.
    """

    gain_matrix: np.ndarray
    kind: str
    objective: str
    domain: str
    X: np.ndarray
    h2: float | None
    gamma: float | None
    h2_optimum: float | None
    gamma_optimum: float | None
    achieved_h2: tuple[float, ...]
    achieved_hinf: tuple[float, ...]
    closed_loop_eigenvalues: tuple[np.ndarray, ...]
    region: LMIRegion | None
    region_margins: tuple[float, ...]
    solver: str
    status: str
    solve_time: float
    checks: tuple[LMICheck, ...]
    scaling: dict = field(default_factory=dict)
    route: str = "lmi"

    def as_dict(self) -> dict:
        """JSON-friendly diagnostics (no gains)."""
        def num(v):
            return None if v is None else float(v)
        return {"kind": self.kind, "objective": self.objective, "domain": self.domain,
                "h2_bound": num(self.h2), "gamma": num(self.gamma),
                "h2_lmi_optimum": num(self.h2_optimum), "gamma_lmi_optimum": num(self.gamma_optimum),
                "achieved_h2": [float(v) for v in self.achieved_h2],
                "achieved_hinf": [float(v) for v in self.achieved_hinf],
                "closed_loop_eigenvalues": [[[float(z.real), float(z.imag)]
                                             for z in np.sort_complex(e)]
                                            for e in self.closed_loop_eigenvalues],
                "region": None if self.region is None else self.region.as_dict(),
                "region_margins": [float(v) for v in self.region_margins],
                "min_boundary_distance": None if self.region is None else float(min(
                    (self.region.boundary_distance(z) for e in self.closed_loop_eigenvalues for z in e),
                    default=np.inf)),
                "models": len(self.closed_loop_eigenvalues),
                "route": self.route,
                "solver": self.solver, "status": self.status, "solve_time_s": self.solve_time,
                "checks": [c.as_dict() for c in self.checks],
                "condition_X": float(np.linalg.cond(self.X)),
                "gain_norm": float(np.linalg.norm(self.gain_matrix, 2)), "scaling": self.scaling}


def _solve(lib: Any, problem: Any, solver: str) -> str:
    """``lib.solve_status`` with this module's tight tolerances (the Riccati comparison needs them)."""
    settings = _CLARABEL if solver == "CLARABEL" else {"eps": 1e-9, "max_iters": 200000}
    return lib.solve_status(problem, solver, **settings)


def _ok(status: str) -> bool:
    return status in ("optimal", "optimal_inaccurate")


@dataclass(frozen=True)
class _Scaling:
    s: np.ndarray       # state balancing, x = diag(s) xs
    su: np.ndarray      # input scaling, u = diag(su) us
    cw: float           # disturbance: ws = w / cw
    cz: float           # performance: zs = cz z
    omega: float        # time scale (continuous): tau = omega t

    def plant(self, P: GeneralizedPlant) -> GeneralizedPlant:
        Ti, s, w = 1.0 / self.s, self.s, self.omega
        return GeneralizedPlant(Ti[:, None] * P.A * s[None, :] / w,
                                Ti[:, None] * P.B * self.su[None, :] / w,
                                Ti[:, None] * P.Bw * self.cw / w,
                                self.cz * P.Cz * s[None, :], self.cz * P.Dzu * self.su[None, :],
                                P.domain, P.dt)

    def hinf_factor(self) -> float:
        """original norm = scaled norm * factor."""
        return 1.0 / (self.cz * self.cw)

    def h2_factor(self, domain: str) -> float:
        return (np.sqrt(self.omega) if domain == "continuous" else 1.0) / (self.cz * self.cw)

    def as_dict(self) -> dict:
        return {"state_balance": self.s.tolist(), "input_scale": self.su.tolist(),
                "disturbance_scale": self.cw, "performance_scale": self.cz, "time_scale": self.omega}


def _scaling(P: GeneralizedPlant) -> _Scaling:
    _, (s, _perm) = sla.matrix_balance(P.A, permute=False, separate=True)
    s = np.asarray(s, dtype=float)
    Ti = 1.0 / s
    su = 1.0 / np.maximum(np.linalg.norm(Ti[:, None] * P.B, axis=0), 1e-300)
    bw = float(np.linalg.norm(Ti[:, None] * P.Bw, 2))
    cz_n = float(np.linalg.norm(np.hstack([P.Cz * s[None, :], P.Dzu * su[None, :]]), 2))
    omega = float(np.linalg.norm(Ti[:, None] * P.A * s[None, :], 2)) if P.domain == "continuous" else 1.0
    return _Scaling(s, su, 1.0 / bw if bw > 0 else 1.0, 1.0 / cz_n if cz_n > 0 else 1.0,
                    omega if omega > 0 else 1.0)


def _models(plants: Any) -> list[GeneralizedPlant]:
    models = [plants] if isinstance(plants, GeneralizedPlant) else list(plants)
    if not models or not all(isinstance(p, GeneralizedPlant) for p in models):
        raise SpecError("plants must be a GeneralizedPlant or a non-empty sequence of them", key="plants")
    first = models[0]
    for i, p in enumerate(models[1:], 1):
        if (p.A.shape, p.B.shape, p.Bw.shape, p.Cz.shape, p.domain) != \
                (first.A.shape, first.B.shape, first.Bw.shape, first.Cz.shape, first.domain):
            raise DimensionError(f"model {i} differs in dimensions or time domain from model 0")
    return models


def synthesize_state_feedback(plants: GeneralizedPlant | Sequence[GeneralizedPlant], *,
                              objective: str = "hinf", h2_bound: float | None = None,
                              hinf_bound: float | None = None, region: LMIRegion | None = None,
                              margin: float = 1e-9, backoff: float = 0.0, solver: str = "CLARABEL",
                              dual: bool = False, route: str = "auto") -> SynthesisResult:
    """State feedback ``u = -K x`` by LMIs: H2 / H-infinity objective or bounds, LMI region.

    One ``X`` and ``Y = K X`` serve every LMI and every model: with several
    models (the vertices of a polytope) the gain is robust for the whole
    polytope, with the common-Lyapunov conservatism.

    Phase 1 minimises the objective (``trace W`` for H2, ``gamma`` for
    H-infinity) with the strict inequalities imposed with ``margin`` on the
    scaled problem. With ``backoff > 0`` (or ``objective = "none"``) phase 2
    keeps the objective within ``(1 + backoff)`` of the phase-1 optimum and
    maximises the strictness margin of every LMI (a well-conditioned,
    moderate gain instead of the boundary of the feasible set).

    Route: a pure H2 or H-infinity objective for ONE model, with no region
    and no bounds, has a Riccati solution with the same optimum
    (`tanksynth.design.synthesis.riccati`: the LQR; gamma bisection on the
    game Riccati equation, the gain the central one at ``gamma_optimum (1 +
    backoff)``). ``route = "auto"`` takes it when it applies (``Dzu' Dzu``
    invertible) and falls back to the LMIs if scipy's ARE solver fails; the
    LMIs are used for regions, bounds and several models. Either way the
    gain goes through the same independent re-check.

    Parameters
    ----------
    plants : GeneralizedPlant or sequence of GeneralizedPlant
        Same dimensions and time domain.
    objective : {"h2", "hinf", "none"}
    h2_bound : float, optional
        Required ``||T_zw||_2 <= h2_bound`` (units of the H2 norm).
    hinf_bound : float, optional
        Required ``||T_zw||_inf <= hinf_bound`` (z unit per w unit).
    region : LMIRegion, optional
        Closed-loop eigenvalues in this region (units of the eigenvalues of ``A``).
    margin : float
        Strictness margin of the scaled LMIs, in (0, 1e-2).
    backoff : float
        Relative back-off from the optimum (>= 0).
    solver : {"CLARABEL", "SCS"}
    dual : bool
        The plants are observer duals (`observer_plant`): the gain returned is
        ``L = K'`` and the kind ``"observer"``.
    route : {"auto", "riccati", "lmi"}
        See above; ``"riccati"`` is refused (`SpecError`) where it does not apply.

    Returns
    -------
    SynthesisResult

    Raises
    ------
    SpecError
        Bad options (named).
    InfeasibleDesign
        The LMIs are infeasible (with the unconstrained optimum as
        certificate when a bound was given) or the gain fails the re-check.
    """
    models = _models(plants)
    domain = models[0].domain
    if objective not in OBJECTIVES:
        raise SpecError(f"objective must be one of {OBJECTIVES}, got {objective!r}", key="objective")
    use_h2 = objective == "h2" or h2_bound is not None
    use_hinf = objective == "hinf" or hinf_bound is not None
    if not (use_h2 or use_hinf or region is not None):
        raise SpecError("nothing to design: give an objective, a bound or a region", key="objective")
    for name, b in (("h2_bound", h2_bound), ("hinf_bound", hinf_bound)):
        if b is not None and not (np.isfinite(b) and b > 0):
            raise SpecError(f"{name} must be a positive number, got {b!r}", key=name)
    if region is not None:
        check_region(region, domain)  # empty, or not stable: refused before any solve
    if not (0 < margin < 1e-2):
        raise SpecError(f"margin must be in (0, 0.01), got {margin!r}", key="margin")
    if not (np.isfinite(backoff) and backoff >= 0):
        raise SpecError(f"backoff must be >= 0, got {backoff!r}", key="backoff")
    check_solver(solver)
    if route not in ROUTES:
        raise SpecError(f"route must be one of {ROUTES}, got {route!r}", key="route")
    if route != "lmi":
        why = _riccati_refusal(models, objective, h2_bound, hinf_bound, region)
        if why is None:
            try:
                with small_dense():
                    return _riccati_design(models[0], objective, backoff, dual)
            except np.linalg.LinAlgError as exc:
                why = f"scipy's Riccati solver failed ({exc})"
        if route == "riccati":
            raise SpecError(f"route = \"riccati\" does not apply: {why}; use route = \"lmi\" or "
                            "\"auto\"", key="route")
    sc = _scaling(models[0])
    scaled = [sc.plant(p) for p in models]
    reg_s = None if region is None else (region.scaled(sc.omega) if domain == "continuous" else region)
    f2, finf = sc.h2_factor(domain), sc.hinf_factor()
    n, m, nz = models[0].n, models[0].m, models[0].Cz.shape[0]
    # Clarabel: the LMIs written straight in its conic form (design.conic); SCS: through cvxpy.
    # Every variable first (the conic model's size is fixed by the first expression built).
    lib = modelling(solver)
    X = lib.variable((n, n), symmetric=True)
    Y = lib.variable((m, n))
    W: Any = lib.variable((nz, nz), symmetric=True) if use_h2 else None
    g: Any = lib.variable(nonneg=True) if use_hinf else None
    t = lib.variable()                                  # phase 2 margin
    # without an H2 LMI in the same X, the smaller bounded real lemma in (gamma X, mu = gamma^2)
    reduced = use_hinf and not use_h2

    def lmis(t: Any) -> list:
        cons = [X >> t * np.eye(n)]
        for P in scaled:
            blocks = []
            if use_h2:
                blocks += h2_lmis(P, X, Y, W)
            if use_hinf:
                blocks += hinf_lmis_reduced(P, X, Y, g) if reduced else hinf_lmis(P, X, Y, g)
            if reg_s is not None:
                blocks.append(region_lmi(reg_s, P, X, Y))
            cons += [B << -t * np.eye(B.shape[0]) for B in blocks]
        return cons

    bounds = []
    if h2_bound is not None:
        bounds.append(lib.trace(W) <= (h2_bound / f2) ** 2)
    if hinf_bound is not None:
        bounds.append(g <= (hinf_bound / finf) ** 2 if reduced else g <= hinf_bound / finf)
    goal = {"h2": lib.trace(W) if use_h2 else None, "hinf": g, "none": None}[objective]
    start = time.perf_counter()
    phase1 = lib.Problem(lib.Minimize(goal if goal is not None else 0), lmis(margin) + bounds)
    status = _solve(lib, phase1, solver)
    if not _ok(status) or X.value is None:
        raise InfeasibleDesign(_infeasible_reason(status, solver, lmis, margin, W, g, f2, finf,
                                                  h2_bound, hinf_bound, region, len(models), reduced,
                                                  lib, domain=domain)[0])
    opt = None if goal is None else float(goal.value)
    values = (X.value.copy(), Y.value.copy(), None if W is None else W.value.copy(),
              None if g is None else float(g.value))
    if backoff > 0 or objective == "none":
        cap = 10.0 * float(np.max(np.linalg.eigvalsh(values[0])))
        extra = [t <= 1.0, X << cap * np.eye(n)]
        if objective == "h2" and opt is not None:        # (the objective is then the goal)
            extra.append(lib.trace(W) <= (1.0 + backoff) ** 2 * opt)
        elif objective == "hinf" and opt is not None:
            extra.append(g <= (1.0 + backoff) ** (2 if reduced else 1) * opt)
        phase2 = lib.Problem(lib.Maximize(t), lmis(t) + bounds + extra)
        status2 = _solve(lib, phase2, solver)
        if _ok(status2) and X.value is not None and t.value is not None and t.value >= margin:
            values = (X.value.copy(), Y.value.copy(), None if W is None else W.value.copy(),
                      None if g is None else float(g.value))
            status = f"{status} (phase 1), {status2} (phase 2)"
        else:
            status = f"{status} (phase 1), {status2} (phase 2 failed: phase-1 point kept)"
    elapsed = time.perf_counter() - start
    Xs, Ys, Wv, gv = values
    Xs = symmetrized(Xs)
    Ks = np.linalg.solve(Xs.T, Ys.T).T
    K = (sc.su[:, None] * Ks) / sc.s[None, :]
    h2_claim = None if Wv is None else float(np.sqrt(max(np.trace(Wv), 0.0)) * f2)
    gamma_s = None if gv is None else (float(np.sqrt(max(gv, 0.0))) if reduced else gv)
    g_claim = None if gamma_s is None else float(gamma_s * finf)
    if reduced and opt is not None and objective == "hinf":
        opt = float(np.sqrt(max(opt, 0.0)))
    checks, eigs, margins, a_h2, a_hinf = _recheck(models, scaled, K, Xs, Ys, Wv, gv, region, reg_s,
                                                    h2_claim, g_claim, margin, reduced)
    failed = [c for c in checks if not c.passed]
    if failed:
        worst = "; ".join(f"{c.name}: {c.value:.4g} vs {c.limit:.4g}" for c in failed)
        recheck = f"the synthesised gain fails the independent re-check ({worst}); solver {solver} status {status}"
        if h2_bound is not None or hinf_bound is not None:
            # a bound at the optimum can end 'optimal_inaccurate' with a gain the re-check refuses:
            # a certificate that the bound is below the LMIs' own minimum says more than the re-check
            reason, certified = _infeasible_reason(status, solver, lmis, margin, W, g, f2, finf, h2_bound,
                                                   hinf_bound, region, len(models), reduced, lib, domain=domain)
            if certified:
                raise InfeasibleDesign(f"{reason}; {recheck}")
        raise InfeasibleDesign(recheck)
    Xo = (sc.s[:, None] * Xs) * sc.s[None, :]
    scaling = sc.as_dict()
    scaling.update({"margin": margin, "backoff": backoff,
                    "formulation": "dual (A', C'), L = K'" if dual else "primal, K = Y X^-1"})
    if route == "auto":
        scaling["route_note"] = f"LMI route: the Riccati route does not apply ({why})"
    return SynthesisResult(
        gain_matrix=K.T if dual else K, kind="observer" if dual else "state_feedback", objective=objective,
        domain=domain, X=symmetrized(Xo), h2=h2_claim, gamma=g_claim,
        h2_optimum=None if (objective != "h2" or opt is None) else float(np.sqrt(max(opt, 0.0)) * f2),
        gamma_optimum=None if (objective != "hinf" or opt is None) else float(opt * finf),
        achieved_h2=tuple(a_h2), achieved_hinf=tuple(a_hinf), closed_loop_eigenvalues=tuple(eigs),
        region=region, region_margins=tuple(margins), solver=solver, status=status,
        solve_time=elapsed, checks=tuple(checks), scaling=scaling, route="lmi")


def _riccati_refusal(models, objective, h2_bound, hinf_bound, region) -> str | None:
    """Why the Riccati route does not apply (None if it does)."""
    if len(models) > 1:
        return f"{len(models)} models need one common Lyapunov matrix (robust design)"
    if region is not None:
        return "a pole region is requested"
    if h2_bound is not None or hinf_bound is not None:
        return "norm bounds are requested (multi-objective)"
    if objective not in ("h2", "hinf"):
        return f"objective {objective!r} is not h2 or hinf"
    return riccati_applicable(models[0])


def _riccati_design(P: GeneralizedPlant, objective: str, backoff: float, dual: bool) -> SynthesisResult:
    """The Riccati route (see `synthesize_state_feedback`), re-checked like the LMI route."""
    start = time.perf_counter()
    sol = riccati_h2(P) if objective == "h2" else riccati_hinf(P, backoff=backoff)
    elapsed = time.perf_counter() - start
    K = sol.K
    Acl, Bcl, Ccl = P.closed_loop(K)
    dt = None if P.domain == "continuous" else (P.dt or 1.0)
    # X: the closed loop's controllability Gramian (the H2 LMI's X at equality), or for
    # H-infinity gamma^2 P^-1 with P the game Riccati solution (the reduced bounded real lemma
    # at equality) when P is well conditioned
    X, certificate = None, "closed-loop controllability Gramian"
    if objective == "hinf" and sol.gamma is not None:   # (the game solution has a gamma)
        w = np.linalg.eigvalsh(sol.X)
        if w[0] > 1e-12 * w[-1] > 0:
            X, certificate = sol.gamma ** 2 * np.linalg.inv(sol.X), "gamma^2 P^-1 (P: game ARE solution)"
    if X is None:
        X = (sla.solve_continuous_lyapunov(Acl, -Bcl @ Bcl.T) if dt is None
             else sla.solve_discrete_lyapunov(Acl, Bcl @ Bcl.T))
    X = symmetrized(X)
    checks, eigs, _, a_h2, a_hinf = _recheck([P], [P], K, X, None, None, None, None, None,
                                             sol.h2, sol.gamma, 0.0, False)
    failed = [c for c in checks if not c.passed]
    if failed:
        worst = "; ".join(f"{c.name}: {c.value:.4g} vs {c.limit:.4g}" for c in failed)
        raise np.linalg.LinAlgError(f"the Riccati gain fails the independent re-check ({worst})")
    info: dict[str, Any]
    if objective == "h2":
        status = "optimal (stabilising ARE solution)"
        info = {"riccati": "solve_%s_are (LQR)" % P.domain}
    else:
        status = (f"optimal (gamma bisection: bracket [{sol.gamma_lower:.10g}, {sol.gamma_optimum:.10g}], "
                  f"{sol.iterations} Riccati solves)")
        info = {"riccati": "solve_%s_are (game, [u; w] weight diag(R, -gamma^2 I))" % P.domain,
                "gamma_bracket": [sol.gamma_lower, sol.gamma_optimum], "riccati_solves": sol.iterations}
    info.update({"certificate_X": certificate, "backoff": backoff, "route": "riccati",
                 "formulation": "dual (A', C'), L = K'" if dual else "primal, K from the ARE"})
    return SynthesisResult(
        gain_matrix=K.T if dual else K, kind="observer" if dual else "state_feedback", objective=objective,
        domain=P.domain, X=X, h2=sol.h2, gamma=sol.gamma, h2_optimum=sol.h2,
        gamma_optimum=sol.gamma_optimum, achieved_h2=tuple(a_h2), achieved_hinf=tuple(a_hinf),
        closed_loop_eigenvalues=tuple(eigs), region=None, region_margins=(), solver="scipy",
        status=status, solve_time=elapsed, checks=tuple(checks), scaling=info, route="riccati")


#: Relative gap below the LMIs' own minimum at which a requested norm bound counts as certified
#: infeasible (the minimum is a solver's answer: a bound 5e-7 below it can still be met).
CERTIFICATE_RTOL = 5e-7


def distinct_digits(a: float, b: float, least: int = 6) -> tuple[str, str]:
    """``a`` and ``b`` printed with the fewest significant digits (at least ``least``, at most
    17) that tell them apart (``"0.05210725"``, ``"0.05210731"``); identical only when equal.

    Parameters
    ----------
    a, b : float
    least : int, optional
        Fewest significant digits (default 6).
    """
    for digits in range(least, 18):
        sa, sb = f"{a:.{digits}g}", f"{b:.{digits}g}"
        if sa != sb:
            return sa, sb
    return repr(float(a)), repr(float(b))


def _infeasible_reason(status, solver, lmis, margin, W, g, f2, finf, h2_bound, hinf_bound, region,
                       count, reduced=False, lib=None, domain="discrete") -> tuple[str, bool]:
    """Why the bounded LMIs have no solution, and whether a certificate says so.

    For each bound, the same LMIs without the bounds are solved for the smallest norm
    bound they admit; a requested bound below it is certified infeasible (said first,
    both numbers with the digits that tell them apart), the solver status of the bounded
    problem is then only reported. Returns the text and True when a bound is certified."""
    models = f" at all {count} models with one Lyapunov matrix" if count > 1 else ""
    certified, other = [], []
    for name, var, factor, bound, sq in (("H2", W, f2, h2_bound, True),
                                          ("H-infinity", g, finf, hinf_bound, reduced)):
        if bound is None or var is None:
            continue
        goal = lib.trace(var) if name == "H2" else var
        prob = lib.Problem(lib.Minimize(goal), lmis(margin))
        st = _solve(lib, prob, solver)
        if not (_ok(st) and goal.value is not None):
            other.append(f"without the bounds the LMIs are still {st}")
            continue
        best = (np.sqrt(max(float(goal.value), 0.0)) if sq else float(goal.value)) * factor
        asked, least = distinct_digits(bound, best)
        if bound < best * (1.0 - CERTIFICATE_RTOL):
            certified.append(f"the requested {name} bound {asked} is below {least}, the smallest the "
                             f"same LMIs admit (minimised without the bound, solver status {st}): no "
                             "gain certified by these LMIs meets it; ask for at least that")
        else:
            other.append(f"smallest {name} bound the LMIs admit without the bounds: {least} (requested "
                         f"{asked}, {(bound - best) / best:+.2g} relative to it: within the solver's "
                         f"accuracy ({CERTIFICATE_RTOL:g}) of the optimum; ask for a slightly larger bound)")
    what = []
    if h2_bound is not None:
        what.append(f"||T_zw||_2 <= {h2_bound:.10g}")
    if hinf_bound is not None:
        what.append(f"||T_zw||_inf <= {hinf_bound:.10g}")
    if region is not None:
        what.append(f"eigenvalues in {region.describe(variable_of(domain))}")
    head = f"no state-feedback gain meets {' and '.join(what) or 'the LMIs'}{models}"
    if certified:
        return (f"{head}: " + "; ".join(certified + other)
                + f" (the bounded problem itself ended with solver {solver} status {status})"), True
    return f"{head}: solver {solver} status {status}" + ("; " + "; ".join(other) if other else ""), False


def _recheck(models, scaled, K, Xs, Ys, Wv, gv, region, reg_s, h2_claim, g_claim, margin, reduced):
    checks: list[LMICheck] = []
    eigs, margins, a_h2, a_hinf = [], [], [], []
    xmin = float(np.min(np.linalg.eigvalsh(Xs)))
    checks.append(LMICheck.test("X > 0 (min eigenvalue, scaled)", xmin, ">", 0.0, unit="scaled"))
    for i, (P, Ps) in enumerate(zip(models, scaled)):
        tag = f" (model {i})" if len(models) > 1 else ""
        Acl, Bcl, Ccl = P.closed_loop(K)
        lam = np.linalg.eigvals(Acl)
        eigs.append(lam)
        dt = P.dt if P.domain == "discrete" else None
        if P.domain == "discrete" and dt is None:
            dt = 1.0
        rho = float(np.max(np.abs(lam))) if P.domain == "discrete" else float(np.max(lam.real))
        lim = 1.0 if P.domain == "discrete" else 0.0
        checks.append(LMICheck.test(f"closed loop stable{tag} ({'spectral radius' if lim else 'max Re'})",
                                    rho, "<", lim, unit="z-plane" if lim else "1/s"))
        a_h2.append(h2_norm(Acl, Bcl, Ccl, None, dt))
        a_hinf.append(hinf_norm(Acl, Bcl, Ccl, None, dt))
        if h2_claim is not None:
            checks.append(LMICheck.test(f"H2 norm (Gramian) <= claimed bound{tag}", a_h2[-1], "<=",
                                        h2_claim, h2_claim * NORM_RTOL, "relative tolerance 1e-6"))
        if g_claim is not None:
            ok = hinf_below(g_claim * (1 + NORM_RTOL), Acl, Bcl, Ccl, None, dt)
            checks.append(LMICheck(f"H-infinity norm (Hamiltonian test) < claimed gamma{tag}",
                                   a_hinf[-1], g_claim, bool(ok), "relative tolerance 1e-6", "<",
                                   g_claim * NORM_RTOL))
        if region is not None:
            mg = float(min(region.margin(z) for z in lam))
            margins.append(mg)
            inside = region.describe(variable_of(P.domain))
            checks.append(LMICheck.test(f"closed-loop eigenvalues inside {inside}{tag}", mg, ">",
                                        0.0, unit="-lambda_max f_D"))
        blocks = []
        if Wv is not None:
            blocks += h2_lmis(Ps, Xs, Ys, Wv)
        if gv is not None:
            blocks += hinf_lmis_reduced(Ps, Xs, Ys, gv) if reduced else hinf_lmis(Ps, Xs, Ys, gv)
        if reg_s is not None:
            blocks.append(region_lmi(reg_s, Ps, Xs, Ys))
        for B in blocks:
            e = np.linalg.eigvalsh(B)
            scale = max(1.0, float(np.max(np.abs(e))))
            checks.append(LMICheck(f"LMI block of size {B.shape[0]} negative (max eigenvalue / scale, "
                                   f"scaled){tag}", float(e.max()) / scale, 0.0,
                                   bool(e.max() / scale <= 1e-7), "scaled", "<=", 1e-7))
    return checks, eigs, margins, a_h2, a_hinf


def synthesize_observer(A: Any, C: Any, Bw: Any, Dv: Any, Cz: Any, *, domain: str = "continuous",
                        dt: float | None = None, **options: Any) -> SynthesisResult:
    """Observer gain ``L`` (``e' = (A - L C) e + Bw w - L Dv v``, ``z = Cz e``) by the dual LMIs.

    Continuous time: ``dxhat/dt = A xhat + B u + L (y - C xhat)``; discrete
    time: the predictor ``xhat+ = A xhat + B u + L (y - C xhat)``. The H2
    optimum is the steady Kalman filter (predictor) for process noise
    ``Bw w`` and measurement noise ``Dv v`` of unit intensity.

    Parameters
    ----------
    A, C, Bw, Dv, Cz : array_like
        See `observer_plant`; ``A`` may be a `control.StateSpace` (its
        ``A``, ``C`` and ``dt`` are used, ``C`` and ``dt`` arguments ignored).
    domain : {"continuous", "discrete"}
    dt : float, optional
        Sampling period (s) of a discrete-time model.
    **options
        `synthesize_state_feedback` options (objective, bounds, region, ...).

    Returns
    -------
    SynthesisResult
        ``gain`` is ``L`` (n, q); norms are those of the error system.
    """
    if hasattr(A, "A") and hasattr(A, "dt"):
        Am, _, Cm, _, sdt = statespace_matrices(A)
        A, C, dt, domain = Am, Cm, sdt, ("continuous" if sdt is None else "discrete")
    return synthesize_state_feedback(observer_plant(A, C, Bw, Dv, Cz, domain, dt), dual=True,
                                     **options)
