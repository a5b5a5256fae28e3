"""Polytopic robust state feedback and observers (LMI regions, H-infinity, saturation).

The vertex models of the uncertain box: `tanksynth.design.robust.vertices`.

Synthesis (one gain, one common Lyapunov matrix ``X``)
    region at every vertex ``i`` (Chilali-Gahinet):
    ``L (x) X + M (x) (A_i X - B_i Y) + M' (x) (.)' < 0``, ``K = Y X^-1``;
    optional H-infinity bound (bounded real lemma at every vertex, continuous
    ``[[He(A_i X - B_i Y), Bw_i, (Cz X - Dzu Y)'], [Bw_i', -g I, 0], [Cz X -
    Dzu Y, 0, -g I]] < 0``, discrete ``[[X, A_cl X, Bw, 0], [., X, 0, (C_cl
    X)'], [., ., g I, 0], [., ., ., g I]] > 0``, both written congruence-scaled
    by ``a = 1/sqrt(max(g, 1))`` on the ``w`` and ``z`` rows: ``a Bw``, ``a Cz``,
    ``min(g, 1) I``, so the data stay O(1) for any ``gamma`` up to 1e12; a
    bound that the design without it already meets is not imposed, see
    `_without_bound`); optional saturation bound
    (`SaturationBound`): the ellipsoid ``x' X^-1 x <= 1`` (deviation
    coordinates) is invariant at every vertex (implied by the region LMI with
    the same ``X``, imposed explicitly as the Lyapunov LMI too) and
    ``[[umax_j^2, Y_j], [Y_j', X]] >= 0`` gives ``|K_j x| <= umax_j`` on it;
    it contains the corners ``v`` of a box, ``[[tau, v'], [v, X]] >= 0``.
    Observers solve the dual (``A_i'``, ``C_i'``; ``L = K'``).

Solved with Clarabel (the LMIs written straight in its conic form by
`tanksynth.design.conic`; with ``solver = "SCS"`` through cvxpy) on a
scaled problem (diagonal balancing of the
states, inputs normalised by ``umax`` or by the columns of ``B``, time
scaling in continuous time), phase 1 the largest margin (its optimum below
``margin`` is the certificate of infeasibility), phase 2 the smallest gain
(or the largest ellipsoid), then re-checked in numpy in the plant's units.
"""

from __future__ import annotations

import dataclasses
import itertools
import time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import scipy.linalg as sla

from tanksynth.analysis.lmi_region import LMIRegion
from tanksynth.analysis.statespace import hinf_norm
from tanksynth.design.conic import modelling
from tanksynth.design.lmi_checks import LMICheck
from tanksynth.design.result import FeedbackGain
from tanksynth.design.matrices import symmetrized
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError

__all__ = ["HinfBound", "SaturationBound", "RobustResult", "robust_state_feedback",
           "robust_observer", "ellipsoid_axes"]


# ====================================================================== bounds
@dataclass(frozen=True)
class HinfBound:
    """An H-infinity bound ``||T_zw||_inf < gamma`` imposed at every vertex.

    Attributes
    ----------
    gamma : float
        Units of ``z`` per unit of ``w``.
    Bw : ndarray, shape (V, n, nw)
        Disturbance input matrix of each vertex (same time domain as ``A``; state
        units per disturbance unit, per s in continuous time).
    Cz : ndarray, shape (nz, n) or (V, nz, n)
    Dzu : ndarray, shape (nz, m)
    """

    gamma: float
    Bw: np.ndarray
    Cz: np.ndarray
    Dzu: np.ndarray


@dataclass(frozen=True)
class SaturationBound:
    """Input limits ``|u_j - u0_j| <= umax_j`` on an invariant ellipsoid (usable with any design
    of this module's state feedback).

    Attributes
    ----------
    umax : ndarray, shape (m,)
        Input units.
    box : ndarray, shape (n_box,) or None
        Half-widths of the box of initial deviations to contain (state
        units; the first ``n_box`` states, the others, e.g. integrators,
        start at 0). None: the cube of unit half-width is scaled as large
        as possible.
    n_box : int
        Number of leading states the box and the half-spaces are about (0: all).
    halfspaces : ndarray, shape (h, n_box), optional
        Rows ``c`` of half-spaces ``c' x <= b`` the ellipsoid must lie in
        (e.g. the operating region where the model holds), ``c' X c <= b^2``.
    limits : ndarray, shape (h,), optional
        The ``b`` of the half-spaces (> 0, units of ``c' x``).
    """

    umax: np.ndarray
    box: np.ndarray | None = None
    n_box: int = 0
    halfspaces: np.ndarray | None = None
    limits: np.ndarray | None = None


@dataclass(frozen=True)
class RobustResult(FeedbackGain):
    """One gain meeting the region (and bounds) at every vertex, with its evidence.

    Attributes
    ----------
    gain_matrix : ndarray
        Read as ``K`` / ``L`` (`FeedbackGain`; ``gain`` is deprecated): ``K`` (m, n) for ``u = -K x`` or ``L`` (n, q).
    P, X : ndarray, shape (n, n)
        Common Lyapunov matrix (state feedback ``P = X^-1``; observer ``P = X``).
    kind : str
    region : LMIRegion
    domain : str
    margin, achieved_margin, largest_margin : float
        Requested, achieved (normalised LMIs) and phase-1 optimum.
    solver, status : str
    solve_time : float
        s.
    vertex_eigenvalues : ndarray, shape (V, n)
    vertex_margins : ndarray, shape (V,)
        ``min_i -lambda_max f_D(lambda_i)`` per vertex (> 0 inside).
    worst_vertex : int
    checks : tuple of dict
        The numpy re-check (name, value, limit, passed).
    hinf : dict or None
        ``gamma``, ``vertices``, ``worst_lmi_eigenvalue`` (normalised bounded
        real blocks, < 0), ``imposed`` (False: the design without the bound
        already meets it, certified with its Lyapunov matrix times
        ``lyapunov_scale``), ``congruence_scale`` (``a`` of the scaled blocks).
    saturation : dict or None
    scaling : dict
    """

    gain_matrix: np.ndarray
    P: np.ndarray
    X: np.ndarray
    kind: str
    region: LMIRegion
    domain: str
    margin: float
    achieved_margin: float
    largest_margin: float
    solver: str
    status: str
    solve_time: float
    vertex_eigenvalues: np.ndarray
    vertex_margins: np.ndarray
    worst_vertex: int
    checks: tuple[dict, ...]
    hinf: dict | None = None
    saturation: dict | None = None
    scaling: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """JSON-friendly diagnostics (no gains)."""
        return {"kind": self.kind, "region": self.region.as_dict(), "domain": self.domain,
                "vertices": int(self.vertex_margins.size), "margin": self.margin,
                "achieved_margin": self.achieved_margin, "largest_margin_t": self.largest_margin,
                "solver": self.solver, "status": self.status, "solve_time_s": self.solve_time,
                "vertex_eigenvalues": [[[float(z.real), float(z.imag)] for z in np.sort_complex(e)]
                                       for e in self.vertex_eigenvalues],
                "vertex_region_margins": self.vertex_margins.tolist(),
                "worst_vertex": self.worst_vertex,
                "min_region_margin": float(np.min(self.vertex_margins)),
                "min_boundary_distance": float(min(self.region.boundary_distance(z)
                                                   for e in self.vertex_eigenvalues for z in e)),
                "checks": list(self.checks), "hinf": self.hinf, "saturation": self.saturation,
                "condition_P": float(np.linalg.cond(self.P)),
                "gain_norm": float(np.linalg.norm(self.gain_matrix, 2)), "scaling": self.scaling}


def ellipsoid_axes(P: np.ndarray, names: Sequence[str]) -> dict:
    """Semi-axes of ``{x : x' P x <= 1}`` (lengths in the states' units, unit directions).

    Parameters
    ----------
    P : ndarray, shape (k, k)
        The ellipsoid's matrix restricted to the states named (e.g. the
        section ``z = 0`` of an augmented ellipsoid).
    names : sequence of str
        State names.

    Returns
    -------
    dict
        ``lengths`` (ascending), ``directions`` (columns), ``extent`` (largest
        ``|x_i|`` on the ellipsoid, per state) and ``names``.
    """
    w, V = np.linalg.eigh(symmetrized(P))
    lengths = 1.0 / np.sqrt(w)
    order = np.argsort(lengths)
    extent = np.sqrt(np.diag(np.linalg.inv(P)))
    return {"names": list(names), "lengths": lengths[order].tolist(),
            "directions": V[:, order].tolist(), "extent": extent.tolist()}


# ================================================================== synthesis
def _region_block(reg: LMIRegion, AX: Any, X: Any, kron) -> Any:
    out = kron(reg.L, X) + kron(reg.M, AX) + kron(reg.M.T, AX.T)
    return symmetrized(out)


def _hinf_block(domain: str, AclX: Any, X: Any, Bw: np.ndarray, CclX: Any, gamma: float, lib) -> Any:
    """Bounded real lemma block: ``< 0`` (continuous) or ``> 0`` (discrete) certifies ``gamma``."""
    n, nw = Bw.shape
    nz = CclX.shape[0]
    Zw, Zz, Zwz = np.zeros((n, nw)), np.zeros((nw, nz)), np.zeros((n, nz))
    if domain == "continuous":
        blocks = [[AclX + AclX.T, Bw, CclX.T], [Bw.T, -gamma * np.eye(nw), Zz],
                  [CclX, Zz.T, -gamma * np.eye(nz)]]
    else:
        blocks = [[X, AclX, Bw, Zwz], [AclX.T, X, Zw, CclX.T], [Bw.T, Zw.T, gamma * np.eye(nw), Zz],
                  [Zwz.T, CclX, Zz.T, gamma * np.eye(nz)]]
    M = lib(blocks)
    return symmetrized(M)


def _brl_worst(domain: str, As: np.ndarray, Bs: np.ndarray, Ks: np.ndarray, Xs: np.ndarray,
               hs: tuple) -> float:
    """Largest eigenvalue of the normalised bounded-real blocks over the vertices, as ``<= 0``."""
    worst = -np.inf
    for i in range(As.shape[0]):
        AclX = (As[i] - Bs[i] @ Ks) @ Xs
        CclX = (hs[1][i] - hs[2] @ Ks) @ Xs
        ev = np.linalg.eigvalsh(_hinf_block(domain, AclX, Xs, hs[0][i], CclX, hs[3], np.block))
        worst = max(worst, float(ev.max()) if domain == "continuous" else float(-ev.min()))
    return worst


def _lyapunov_block(domain: str, AclX: Any, X: Any, lib) -> Any:
    """``He(A_cl X) <= 0`` (continuous) or ``[[X, A_cl X], [., X]] >= 0`` (discrete), as ``<= 0``."""
    if domain == "continuous":
        return symmetrized(AclX) * 2
    M = lib([[X, AclX], [AclX.T, X]])
    return -symmetrized(M)


def robust_state_feedback(A: Any, B: Any, region: LMIRegion, *, domain: str = "continuous",
                          hinf: HinfBound | None = None, saturation: SaturationBound | None = None,
                          margin: float = 1e-6, kappa: float = 1e4, solver: str = "CLARABEL",
                          nominal: int | None = None, _dual: bool = False,
                          _impose: bool = False) -> RobustResult:
    """One state feedback ``u = -K x`` putting ``eig(A_i - B_i K)`` in ``region`` at every vertex.

    Parameters
    ----------
    A : array_like, shape (V, n, n)
        Vertex matrices (1/s, or dimensionless in discrete time).
    B : array_like, shape (V, n, m)
    region : LMIRegion
        Must lie in the stability domain of ``domain``.
    domain : {"continuous", "discrete"}
    hinf : HinfBound, optional
    saturation : SaturationBound, optional
    margin : float
        Strictness margin of the normalised LMIs, in (0, 1).
    kappa : float
        ``X`` is kept within ``[1/kappa, kappa]`` (normalised; ``[1, kappa]``
        for the homogeneous region-only problem).
    solver : {"CLARABEL", "SCS"}
    nominal : int, optional
        Index of the nominal vertex (for the infeasibility diagnosis).

    Returns
    -------
    RobustResult

    Raises
    ------
    SpecError
        Bad shapes or options, a region outside the stability domain.
    InfeasibleDesign
        The phase-1 optimum is below ``margin`` (with the optimum, and the
        optimum of the region alone and of the nominal model as the reason),
        or the numpy re-check fails.
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim == 2:
        A, B = A[None], B[None]
    if A.ndim != 3 or B.ndim != 3 or A.shape[1] != A.shape[2] or B.shape[:2] != A.shape[:2]:
        raise DimensionError(f"vertex matrices A {A.shape} and B {B.shape} do not fit (V, n, n), (V, n, m)")
    if domain not in ("continuous", "discrete"):
        raise SpecError(f"domain must be 'continuous' or 'discrete', got {domain!r}", key="time_domain")
    if not region.stable_in(domain):
        raise SpecError(f"region {region.describe()} is not inside the {domain}-time stability domain",
                        key="region")
    if not (0 < margin < 1) or kappa <= 1:
        raise SpecError(f"margin must be in (0, 1) and kappa > 1, got {margin!r}, {kappa!r}", key="margin")
    V, n, m = B.shape
    # ---- scaling
    Amean = A.mean(axis=0)
    _, (s, _p) = sla.matrix_balance(Amean, permute=False, separate=True)
    s = np.asarray(s, dtype=float)
    Ab = A * (1.0 / s)[None, :, None] * s[None, None, :]
    Bb = B / s[None, :, None]
    if saturation is not None:
        su = np.asarray(saturation.umax, dtype=float).reshape(m)
    else:
        su = 1.0 / np.maximum(np.max(np.linalg.norm(Bb, axis=1), axis=0), 1e-300)
    Bb = Bb * su[None, None, :]
    omega = float(np.linalg.norm(Ab.mean(axis=0), 2)) if domain == "continuous" else 1.0
    omega = omega if omega > 0 else 1.0
    As, Bs, reg = Ab / omega, Bb / omega, region.scaled(omega)
    I = np.eye(n)
    # Clarabel: the LMIs written straight in its conic form (design.conic); SCS: through cvxpy
    lib = modelling(solver)
    X = lib.variable((n, n), symmetric=True)
    Y = lib.variable((m, n))
    tau = lib.variable(nonneg=True)
    t = lib.variable()
    lib.reserve_norm()
    d = reg.order * n
    homogeneous = hinf is None and saturation is None
    hs, free_norm = None, None
    if hinf is not None:
        Bw = np.asarray(hinf.Bw, dtype=float)
        Bws = Bw / s[None, :, None] / omega
        Cz = np.asarray(hinf.Cz, dtype=float)
        Czs = (np.broadcast_to(Cz, (V,) + Cz.shape[-2:]) if Cz.ndim == 3 else
               np.repeat(Cz[None], V, axis=0)) * s[None, None, :]
        Dzs = np.asarray(hinf.Dzu, dtype=float) * su[None, :]
        cw = 1.0 / max(float(np.max(np.linalg.norm(Bws, axis=1))), 1e-300)
        rz = 1.0 / max(float(np.max(np.linalg.norm(Czs, axis=2))),
                       float(np.max(np.linalg.norm(Dzs, axis=1))) if Dzs.size else 0.0, 1e-300)
        # congruence diag(I, a I, a I) of the bounded-real block, a = 1/sqrt(max(g, 1)): the data
        # stays O(1) for any gamma (gamma = 1e12 would put 1e12 next to O(1) terms otherwise)
        g = float(hinf.gamma) * cw * rz
        a = 1.0 / np.sqrt(max(g, 1.0))
        hs = (Bws * (cw * a), Czs * (rz * a), Dzs * (rz * a), g * a * a, a)
        if not _impose:
            free, free_norm = _without_bound(A, B, region, domain, saturation, margin, kappa, solver,
                                             nominal, _dual, As, Bs, s, su, hs, hinf)
            if free is not None:
                return free
    corners = None
    if saturation is not None:
        nb = saturation.n_box or n
        half = np.ones(nb) if saturation.box is None else np.asarray(saturation.box, dtype=float)
        corners = []
        for signs in itertools.product((-1.0, 1.0), repeat=nb):
            v = np.zeros(n)
            v[:nb] = np.asarray(signs) * half
            corners.append(v / s)
    def constraints(t: Any, regions_only: bool = False, vertices: Sequence[int] | None = None) -> list:
        out = []
        for i in (range(V) if vertices is None else vertices):
            AclX = As[i] @ X - Bs[i] @ Y
            out.append(_region_block(reg, AclX, X, lib.kron) << -t * np.eye(d))
            if regions_only:
                continue
            if hs is not None:
                CclX = hs[1][i] @ X - hs[2] @ Y
                blk = _hinf_block(domain, AclX, X, hs[0][i], CclX, hs[3], lib.bmat)
                size = blk.shape[0]
                out.append(blk << -t * np.eye(size) if domain == "continuous" else blk >> t * np.eye(size))
            if saturation is not None:
                out.append(_lyapunov_block(domain, AclX, X, lib.bmat) << 0)
        if saturation is not None and not regions_only:
            if saturation.halfspaces is not None:
                for c, b in zip(np.asarray(saturation.halfspaces, float),
                                np.asarray(saturation.limits, float)):
                    cc = np.zeros(n)
                    cc[:c.size] = c
                    cs = cc * s
                    out.append(cs[None, :] @ X @ cs[:, None] <= float(b) ** 2)
            for j in range(m):
                out.append(lib.bmat([[np.ones((1, 1)), Y[j:j + 1, :]], [Y[j:j + 1, :].T, X]]) >> 0)
        if homogeneous or regions_only:
            out += [X >> I, X << kappa * I]
        else:
            out += [X >> I / kappa, X << kappa * I]
        return out

    def box_constraints(bound: Any) -> list:
        corner = np.ones((1, 1)) * bound if isinstance(bound, float) else lib.reshape(bound, (1, 1), order="F")
        return [lib.bmat([[corner, v[None, :]], [v[:, None], X]]) >> 0 for v in corners]

    fixed = box_constraints(1.0) if saturation is not None and saturation.box is not None else []
    base = constraints(t) + fixed
    start = time.perf_counter()
    status = lib.solve_status(lib.Problem(lib.Maximize(t), base + [t <= 1.0]), solver)
    tstar = float(t.value) if status in ("optimal", "optimal_inaccurate") and t.value is not None else -np.inf
    if tstar < margin:
        raise InfeasibleDesign(_infeasible_reason(region, V, margin, tstar, status, solver, hinf,
                                                  saturation, constraints, t, nominal, lib, fixed,
                                                  free_norm, kappa))
    Xv, Yv, status1 = X.value.copy(), Y.value.copy(), status
    bound = max(margin, 0.5 * tstar)
    phase2 = constraints(bound)
    if saturation is not None and saturation.box is not None:
        phase2 += box_constraints(1.0)
        objective = lib.Minimize(lib.norm_fro(Y))
    elif saturation is not None:
        phase2 += box_constraints(tau)
        objective = lib.Minimize(tau)
    else:
        objective = lib.Minimize(lib.norm_fro(Y))
    status2 = lib.solve_status(lib.Problem(objective, phase2), solver)
    def gain_norm(Xa: np.ndarray, Ya: np.ndarray) -> float:
        with np.errstate(all="ignore"):
            try:
                return float(np.linalg.norm(np.linalg.solve(symmetrized(Xa), np.asarray(Ya).T)))
            except np.linalg.LinAlgError:
                return np.inf

    solved2 = status2 in ("optimal", "optimal_inaccurate") and X.value is not None
    # phase 2 exists to shrink the gain: an inaccurate phase 2 that does not is not taken
    worse = solved2 and status2 != "optimal" and gain_norm(X.value, Y.value) > gain_norm(Xv, Yv)
    first = (Xv, Yv, f"{status1} (phase 1), {status2} (phase 2 fails the re-check: phase-1 "
                     "solution kept)")
    if solved2 and not worse:
        Xv, Yv = X.value, Y.value
        status = f"{status1} (phase 1), {status2} (phase 2)"
    elif worse:
        status = (f"{status1} (phase 1), {status2} (phase 2 inaccurate and with a larger gain: "
                  "phase-1 solution kept)")
    else:
        status = f"{status1} (phase 1), {status2} (phase 2 failed: phase-1 solution kept)"
    elapsed = time.perf_counter() - start
    # a first-order solver (SCS) can end phase 2 'optimal' a few 1e-6 outside the constraints: the
    # phase-1 solution (margin t* >= 2 x phase 2's) is re-checked before the design is refused
    def finish(Xv: np.ndarray, Yv: np.ndarray, status: str) -> RobustResult:
        Xs = symmetrized(Xv)
        Ks = np.linalg.solve(Xs, np.asarray(Yv).T).T
        K = (su[:, None] * Ks) / s[None, :]
        Xo = (s[:, None] * Xs) * s[None, :]
        return _recheck(A, B, K, Xs, Xo, Ks, As, Bs, reg, region, domain, margin, tstar, solver,
                        status, elapsed, hinf, hs, saturation, corners, s, su, omega, kappa, _dual)

    try:
        return finish(Xv, Yv, status)
    except InfeasibleDesign as exc:
        if Xv is first[0]:
            raise
        try:
            return finish(*first)
        except InfeasibleDesign:
            raise exc from None


def _without_bound(A, B, region, domain, saturation, margin, kappa, solver, nominal, dual, As, Bs, s,
                   su, hs, hinf) -> tuple[RobustResult | None, float | None]:
    """The design without the H-infinity bound when it already meets it (else None), and that
    design's largest vertex H-infinity norm (None when there is no such design), which a refusal
    of the bound quotes.

    The bound is a constraint, not an objective: when the design without it
    (same region, saturation, margin) satisfies the normalised bounded real
    lemma at every vertex with ``c X`` (its own Lyapunov matrix times the best
    scalar ``c`` keeping ``c X`` in ``[I/kappa, kappa I]``; the block is affine
    in ``c``, so its largest eigenvalue is convex in ``c``) with the re-check's
    margin/2, that design is certified for ``gamma`` and the bound does not
    bind (a loose ``gamma`` such as 1e12 returns exactly the design without
    it). Otherwise the bound is imposed in the LMIs.
    """
    try:
        free = robust_state_feedback(A, B, region, domain=domain, saturation=saturation, margin=margin,
                                     kappa=kappa, solver=solver, nominal=nominal, _dual=dual)
    except InfeasibleDesign:
        return None, None    # the design with the bound says why (or finds the wider X range)
    K = free.gain_matrix.T if dual else free.gain_matrix
    norm = _vertex_hinf_norm(A, B, K, hinf, domain)
    Xs = free.X / np.outer(s, s)
    Ks = K * s[None, :] / su[:, None]
    Xs = symmetrized(Xs)
    ev = np.linalg.eigvalsh(Xs)
    lo, hi = np.log(1.0 / (kappa * ev[0])), np.log(kappa / ev[-1])
    def worst_at(u: float) -> float:
        return _brl_worst(domain, As, Bs, Ks, np.exp(u) * Xs, hs)

    u = 0.0
    if hi > lo:
        from scipy.optimize import minimize_scalar  # deferred: scipy.optimize imports in ~0.15 s

        u = float(minimize_scalar(worst_at, bounds=(lo, hi), method="bounded",
                                  options={"xatol": 1e-4}).x)
    u = min((u, 0.0), key=worst_at) if lo <= 0.0 <= hi else u
    worst = worst_at(u)
    if not worst <= -0.5 * margin:
        return None, norm
    check = LMICheck.test("bounded real lemma at every vertex, normalised (<= -margin/2)", worst, "<=",
                          -0.5 * margin).as_dict()
    return dataclasses.replace(
        free, checks=free.checks + (check,),
        status=free.status + "; H-infinity bound met without imposing it",
        hinf={"gamma": float(hinf.gamma), "vertices": int(As.shape[0]), "worst_lmi_eigenvalue": worst,
              "imposed": False, "congruence_scale": float(hs[4]), "lyapunov_scale": float(np.exp(u)),
              "note": ("the design without the bound already satisfies the bounded real lemma at "
                       "every vertex with its own Lyapunov matrix times lyapunov_scale: gamma "
                       "does not bind")}), norm


def _vertex_hinf_norm(A: np.ndarray, B: np.ndarray, K: np.ndarray, hinf: Any, domain: str) -> float:
    """Largest H-infinity norm from w to z of the closed loops A_i - B_i K (Hamiltonian bisection;
    the bilinear transform for discrete loops), inf when one is unstable."""
    Bw = np.asarray(hinf.Bw, dtype=float)
    Cz = np.asarray(hinf.Cz, dtype=float)
    Dzu = np.asarray(hinf.Dzu, dtype=float)
    dt = None if domain == "continuous" else 1.0
    worst = 0.0
    for i in range(A.shape[0]):
        Bwi = Bw[i] if Bw.ndim == 3 else Bw
        Czi = Cz[i] if Cz.ndim == 3 else Cz
        Ccl = Czi - Dzu @ K if Dzu.size else Czi
        worst = max(worst, hinf_norm(A[i] - B[i] @ K, Bwi, Ccl, None, dt=dt, rtol=1e-6))
    return float(worst)


def _infeasible_reason(region, V, margin, tstar, status, solver, hinf, saturation, constraints, t,
                       nominal, lib, fixed, free_norm=None, kappa=None) -> str:
    extra = []
    parts = ("region" + (", H-infinity bound" if hinf is not None else "")
             + (", saturation bound" if saturation is not None else ""))
    if hinf is not None or saturation is not None:
        st = lib.solve_status(lib.Problem(lib.Maximize(t), constraints(t, regions_only=True) + [t <= 1.0]),
                             solver)
        tr = float(t.value) if t.value is not None and st.startswith("optimal") else -np.inf
        extra.append(f"the region alone at the {V} vertices: t* = {tr:.3g}")
    if nominal is not None and V > 1:
        # the nominal model with every bound (region, H-infinity, saturation, box) of the request
        st = lib.solve_status(lib.Problem(lib.Maximize(t), constraints(t, False, [nominal]) + fixed
                                          + [t <= 1.0]), solver)
        tn = float(t.value) if t.value is not None and st.startswith("optimal") else -np.inf
        extra.append(f"the nominal model alone ({parts}): t* = {tn:.3g}"
                     + (" (feasible: the uncertainty makes the request infeasible)" if tn >= margin
                        else " (infeasible even without uncertainty" + (", within kappa" if kappa else "")
                        + ")"))
    hint = ""
    if free_norm is not None and np.isfinite(free_norm) and hinf is not None:
        # the unbounded design's norm is no lower limit: imposing the bound reaches less (the
        # scalar test of test_robust_gamma: above 2 without the bound, gamma = 2 met)
        hint = (f"gamma = {float(hinf.gamma):.4g} not met: without the bound the design reaches "
                f"||T_zw||inf = {free_norm:.4g} at its worst vertex model (not a lower limit: with the "
                f"bound imposed a gain can reach less: a gamma between {float(hinf.gamma):.4g} and that "
                "may be met); ")
    within = "" if kappa is None else f" with the Lyapunov matrix's conditioning bound kappa = {kappa:g}"
    if status == "optimal":
        how = f"the optimum certifies that no larger margin exists{within})"
    elif status.startswith("optimal"):
        how = (f"the solver's optimum is inaccurate ({status}): an indication, not a certificate "
               "that no larger margin exists)")
    else:
        how = ("no optimum was returned: the request could not be certified, which is no proof that it "
               "is infeasible)")
    return (hint + f"no single gain meets the {parts} at all {V} vertex model(s) with margin {margin:g} "
            f"(region {region.describe()}): largest achievable margin t* = {tstar:.3g} (solver {solver} "
            f"status {status}; max t s.t. every vertex LMI <= -t I with a common Lyapunov matrix, "
            + how + ("; " + "; ".join(extra) if extra else ""))


def _recheck(A, B, K, Xs, Xo, Ks, As, Bs, reg, region, domain, margin, tstar, solver, status, elapsed,
             hinf, hs, saturation, corners, s, su, omega, kappa, dual) -> RobustResult:
    V, n, m = B.shape
    checks = []

    def add(name: str, value: float, relation: str, limit: float, tolerance: float = 0.0) -> None:
        checks.append(LMICheck.test(name, value, relation, limit, tolerance).as_dict())

    worst_n, worst_o = -np.inf, -np.inf
    eigs, margins = [], []
    for i in range(V):
        Mn = _region_block(reg, (As[i] - Bs[i] @ Ks) @ Xs, Xs, np.kron)
        worst_n = max(worst_n, float(np.max(np.linalg.eigvalsh(Mn))))
        Mo = _region_block(region, (A[i] - B[i] @ K) @ Xo, Xo, np.kron)
        worst_o = max(worst_o, float(np.max(np.linalg.eigvalsh(Mo))))
        lam = np.linalg.eigvals(A[i] - B[i] @ K)
        eigs.append(lam)
        margins.append(min(region.margin(z) for z in lam))
    margins_arr = np.array(margins)
    add("region LMI at every vertex, normalised (max eigenvalue <= -margin/2)", worst_n, "<=", -0.5 * margin)
    add("region LMI at every vertex, original units (max eigenvalue < 0)", worst_o, "<", 0.0)
    xmin = float(np.min(np.linalg.eigvalsh(Xs)))
    add("X > 0 (min eigenvalue, normalised)", xmin, ">", 0.0)
    add("eigenvalues of every vertex closed loop inside the region (min margin)", margins_arr.min(), ">", 0.0)
    hinf_out = None
    if hinf is not None:
        worst_h = _brl_worst(domain, As, Bs, Ks, Xs, hs)
        add("bounded real lemma at every vertex, normalised (<= -margin/2)", worst_h, "<=", -0.5 * margin)
        hinf_out = {"gamma": float(hinf.gamma), "vertices": V, "worst_lmi_eigenvalue": worst_h,
                    "imposed": True, "congruence_scale": float(hs[4])}
    sat_out = None
    if saturation is not None:
        umax = np.asarray(saturation.umax, dtype=float)
        peak = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", K, Xo, K), 0.0))
        ratio = float(np.max(peak / umax))
        add("max over the ellipsoid of |K_j x| / umax_j (<= 1)", ratio, "<=", 1.0, 1e-6)
        P = np.linalg.inv(Xo)
        lyap = -np.inf
        for i in range(V):
            Acl = A[i] - B[i] @ K
            Lm = Acl.T @ P + P @ Acl if domain == "continuous" else Acl.T @ P @ Acl - P
            lyap = max(lyap, float(np.max(np.linalg.eigvalsh(symmetrized(Lm)))) / float(np.linalg.norm(P, 2)))
        if saturation.halfspaces is not None:
            Xp = Xo[:saturation.halfspaces.shape[1], :saturation.halfspaces.shape[1]]
            reach = np.sqrt(np.einsum("ij,jk,ik->i", saturation.halfspaces, Xp, saturation.halfspaces))
            worst_h = float(np.max(reach / np.asarray(saturation.limits, dtype=float)))
            add("ellipsoid inside the half-spaces c' x <= b (max sqrt(c' X c) / b)", worst_h, "<=", 1.0, 1e-6)
        add("ellipsoid invariant at every vertex (max eigenvalue of the Lyapunov form, relative)",
            lyap, "<=", 0.0, 1e-9)
        vs = [v * s for v in corners]
        tau_val = max(float(v @ P @ v) for v in vs)
        scale = 1.0 / np.sqrt(tau_val)
        if saturation.box is not None:
            add("requested box inside the ellipsoid (max v' P v over its corners)", tau_val, "<=", 1.0, 1e-6)
        nb = saturation.n_box or n
        half = np.ones(nb) if saturation.box is None else np.asarray(saturation.box, dtype=float)
        sat_out = {"umax": umax.tolist(), "peak_input_deviation": peak.tolist(),
                   "box": None if saturation.box is None else half.tolist(),
                   "box_scale": float(scale), "certified_box": (scale * half).tolist(),
                   "n_box": nb, "P": P.tolist()}
    failed = [c for c in checks if not c["passed"]]
    if failed:
        worst = "; ".join(f"{c['name']}: {c['value']:.4g} vs {c['limit']:.4g}" for c in failed)
        raise InfeasibleDesign(f"robust LMI design fails the independent re-check ({worst}); solver "
                               f"{solver} status {status}")
    P = Xo if dual else np.linalg.inv(Xo)
    wv = int(np.argmin(margins_arr))
    return RobustResult(
        gain_matrix=K.T if dual else K, P=symmetrized(P), X=Xo, kind="observer" if dual else "state_feedback",
        region=region, domain=domain, margin=float(margin), achieved_margin=float(-worst_n),
        largest_margin=float(tstar), solver=solver, status=status, solve_time=elapsed,
        vertex_eigenvalues=np.array(eigs), vertex_margins=margins_arr, worst_vertex=wv,
        checks=tuple(checks), hinf=hinf_out, saturation=sat_out,
        scaling={"state_balance": s.tolist(), "input_scale": su.tolist(), "time_scale": omega,
                 "kappa": kappa, "formulation": "dual (A_i', C_i')" if dual else "primal",
                 "objective": ("phase 1: max margin t; phase 2: "
                               + ("largest ellipsoid (min tau, box scale 1/sqrt(tau))"
                                  if saturation is not None and saturation.box is None
                                  else "min ||Y||_F")
                               + " with every LMI <= -max(margin, t*/2) I")})


def robust_observer(A: Any, C: Any, region: LMIRegion, *, domain: str = "continuous",
                    hinf: HinfBound | None = None, margin: float = 1e-6, kappa: float = 1e4,
                    solver: str = "CLARABEL", nominal: int | None = None) -> RobustResult:
    """One observer gain ``L`` putting ``eig(A_i - L C_i)`` in ``region`` at every vertex (dual).

    Parameters
    ----------
    A : array_like, shape (V, n, n)
    C : array_like, shape (V, q, n)
    region : LMIRegion
    domain : {"continuous", "discrete"}
    hinf : HinfBound, optional
        For the error ``e' = (A - L C) e + Bw w``, ``z = Cz e``: ``Bw`` (V, n,
        nw), ``Cz`` (nz, n); ``Dzu`` is ignored.
    margin, kappa : float
    solver : {"CLARABEL", "SCS"}
    nominal : int, optional

    Returns
    -------
    RobustResult
        ``gain`` is ``L`` (n, q), ``P`` the Lyapunov matrix of ``A_i - L C_i``.

    Raises
    ------
    InfeasibleDesign
    """
    A = np.asarray(A, dtype=float)
    C = np.asarray(C, dtype=float)
    if A.ndim == 2:
        A, C = A[None], C[None]
    At = np.transpose(A, (0, 2, 1))
    Ct = np.transpose(C, (0, 2, 1))
    dual = None
    if hinf is not None:
        Cz = np.asarray(hinf.Cz, dtype=float)
        Bw = np.asarray(hinf.Bw, dtype=float)
        dual = HinfBound(hinf.gamma, np.repeat(Cz.T[None], A.shape[0], axis=0),
                         np.transpose(Bw, (0, 2, 1)), np.zeros((Bw.shape[2], C.shape[1])))
    return robust_state_feedback(At, Ct, region, domain=domain, hinf=dual, margin=margin, kappa=kappa,
                                 solver=solver, nominal=nominal, _dual=True)

