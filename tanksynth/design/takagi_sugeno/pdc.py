"""Takagi-Sugeno controllers: PDC state feedback, its dual observer, certified regions.

The deviation TS model the PDC is designed on: `tanksynth.design.takagi_sugeno.deviation`.

PDC (Tanaka & Wang)
    ``v = -sum_j mu_j K_j e``. With ``X = P^-1``, ``M_j = K_j X`` and
    ``Y_ij = He(A_i X - B M_j) + 2 alpha X`` the closed loop satisfies
    ``dV/dt <= -2 alpha V`` (``V = e' P e``) if

    * ``"vertex"`` (basic conditions): ``Y_ii < 0`` and ``Y_ij + Y_ji < 0``
      (``i < j``);
    * ``"tuan"`` (Tuan, Apkarian, Narikiyo, Yamamoto 2001):
      ``Y_ii < 0`` and ``2/(r-1) Y_ii + Y_ij + Y_ji < 0`` (``i != j``);
    * ``"all_pairs"``: ``Y_ij < 0`` for every ``(i, j)``, needed when the
      controller's premises differ from the plant's (estimated premises).

    The certified ellipsoid ``{e' P e <= 1}`` is kept in the domain
    (``a' X a <= b^2`` per face ``a' e <= b``) and the pumps unsaturated on
    it (``[[umargin_j^2, m_ij], [m_ij', X]] >= 0``); ``X >= t S`` with ``t``
    maximised (``S`` the squared distances to the faces) enlarges it.
    Scaled before solving (states by the distances to the faces, inputs by
    their margins, time by the largest ``|A_i|``); every solution is
    re-checked in numpy in the original units, and refused if a check fails.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from tanksynth.design.bisection import bisect_feasible
from tanksynth.design.conic import modelling
from tanksynth.design.matrices import symmetrized
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError

__all__ = ["RELAXATIONS", "condition_weights", "PDCResult", "pdc_lmi", "relaxed_conditions",
           "certified_decay", "decay_bracket", "DECAY_RTOL", "max_decay_rate"]

#: LMI relaxations of the PDC conditions.
RELAXATIONS = ("vertex", "tuan", "all_pairs")


# ----------------------------------------------------------------------------- model


# ------------------------------------------------------------------------------ LMIs
def condition_weights(relaxation: str, r: int) -> list[dict[tuple[int, int], float]]:
    """The PDC conditions as weighted sums of ``Y_ij`` (each sum must be negative definite).

    Parameters
    ----------
    relaxation : {"vertex", "tuan", "all_pairs"}
    r : int
        Number of vertices.

    Returns
    -------
    list of dict
        ``{(i, j): weight}`` per condition (0-based indices).
    """
    if relaxation not in RELAXATIONS:
        raise SpecError(f"unknown relaxation {relaxation!r}; expected one of {RELAXATIONS}",
                        key="relaxation")
    if relaxation == "all_pairs":
        return [{(i, j): 1.0} for i in range(r) for j in range(r)]
    out: list[dict[tuple[int, int], float]] = [{(i, i): 1.0} for i in range(r)]
    for i, j in itertools.combinations(range(r), 2):
        if relaxation == "vertex":
            out.append({(i, j): 1.0, (j, i): 1.0})
        else:
            c = 2.0 / (r - 1)
            out.append({(i, i): c, (i, j): 1.0, (j, i): 1.0})
            out.append({(j, j): c, (i, j): 1.0, (j, i): 1.0})
    return out


def relaxed_conditions(P: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray, alpha: float,
                       relaxation: str) -> list[np.ndarray]:
    """The condition matrices ``sum w_ij (He(P (A_i - B K_j)) + 2 alpha P)`` in numpy.

    Congruent (by ``P``) to the LMIs in ``X = P^-1``, so they are negative
    definite exactly when the design's conditions hold.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Lyapunov matrix.
    A : ndarray, shape (r, n, n)
        Vertex state matrices [1/s].
    B : ndarray, shape (n, m)
        Input matrix (state units per input unit and s).
    K : ndarray, shape (r, m, n)
        PDC gains (input units per state unit).
    alpha : float
        Decay rate [1/s].
    relaxation : str
        Relaxation of the PDC conditions: one of ``RELAXATIONS`` (``"vertex"``, ``"tuan"``, ``"all_pairs"``).
    """
    r = A.shape[0]
    N = {}
    out = []
    for cond in condition_weights(relaxation, r):
        S = np.zeros_like(P)
        for (i, j), w in cond.items():
            if (i, j) not in N:
                G = P @ (A[i] - B @ K[j])
                N[i, j] = G + G.T + 2.0 * alpha * P
            S = S + w * N[i, j]
        out.append(symmetrized(S))
    return out


def certified_decay(P: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray,
                    relaxation: str) -> float:
    """Largest ``alpha`` for which the conditions of ``relaxation`` hold on ``(P, K_j)`` (1/s).

    Each condition is ``N_w + 2 alpha (sum w) P``; the bound is the smallest
    generalised eigenvalue of ``(-N_w, 2 (sum w) P)`` (negative: not stable).

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Lyapunov matrix.
    A : ndarray, shape (r, n, n)
        Vertex state matrices [1/s].
    B : ndarray, shape (n, m)
        Input matrix (state units per input unit and s).
    K : ndarray, shape (r, m, n)
        PDC gains (input units per state unit).
    relaxation : str
        Relaxation of the PDC conditions: one of ``RELAXATIONS`` (``"vertex"``, ``"tuan"``, ``"all_pairs"``).
    """
    Lc = np.linalg.cholesky(symmetrized(P))
    Li = np.linalg.inv(Lc)
    best = np.inf
    conds = condition_weights(relaxation, A.shape[0])
    mats = relaxed_conditions(P, A, B, K, 0.0, relaxation)
    for cond, N in zip(conds, mats):
        s = 2.0 * sum(cond.values())
        lam = np.linalg.eigvalsh(Li @ (-N) @ Li.T)[0] / s
        best = min(best, float(lam))
    return best


#: Relative step below the supremum of the certified decay rate at which the conditions are
#: re-checked strictly (the supremum itself is where they hold with equality).
DECAY_RTOL = 1e-3


def decay_bracket(P: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray, relaxation: str,
                  imposed: float = 0.0) -> dict:
    """What ``(P, K_j)`` certify of the decay rate: at least ``at_least``, where the conditions
    hold strictly (``margin`` minus their largest eigenvalue there, > 0), at most ``at_most``
    (`certified_decay`, the supremum, where they hold with equality).

    ``at_least`` is the larger of the imposed rate and ``(1 - DECAY_RTOL) at_most`` at which the
    conditions hold strictly; the interval ``[at_least, at_most]`` is the bracket reported.

    Parameters
    ----------
    P, A, B, K, relaxation
        As `certified_decay`.
    imposed : float
        The decay rate the LMIs were solved for (1/s).

    Returns
    -------
    dict
        ``at_least``, ``at_most`` (1/s) and ``margin`` (minus the largest eigenvalue of the
        conditions at ``at_least``, units of ``P`` per s; positive).
    """
    sup = certified_decay(P, A, B, K, relaxation)

    def worst(alpha: float) -> float:
        return max(float(np.linalg.eigvalsh(Mx)[-1]) for Mx in relaxed_conditions(P, A, B, K, alpha, relaxation))

    low, m = float(imposed), worst(float(imposed))
    trial = (1.0 - DECAY_RTOL) * sup
    if trial > low:
        mt = worst(trial)
        if mt < 0:
            low, m = trial, mt
    return {"at_least": low, "at_most": float(sup), "margin": -m}


@dataclass(frozen=True)
class PDCResult:
    """A solved and re-checked PDC LMI.

    Attributes
    ----------
    P : ndarray, shape (n, n)
        Lyapunov matrix; ``{e' P e <= 1}`` is the designed ellipsoid.
    K : ndarray, shape (r, m, n)
        Gains ``K_j`` (input units per state unit).
    relaxation : str
    alpha : float
        Decay rate imposed (1/s).
    decay : float
        Supremum of the decay rate the returned matrices certify (`certified_decay`) (1/s): the
        conditions hold with equality there.
    t : float
        Size of the ellipsoid achieved (scaled, dimensionless; 0 without constraints).
    status : str
    max_condition_eigenvalue : float
        Largest eigenvalue of the condition matrices (original units), < 0.
    scaling : dict
    decay_certified : dict or None
        `decay_bracket`: the decay rate certified strictly (``at_least``, with its ``margin``)
        and the supremum (``at_most``).
    """

    P: np.ndarray
    K: np.ndarray
    relaxation: str
    alpha: float
    decay: float
    t: float
    status: str
    max_condition_eigenvalue: float
    scaling: dict
    decay_certified: dict | None = None

    def as_dict(self) -> dict:
        """JSON-friendly diagnostics (``decay_rate_bracket``: `decay_bracket`)."""
        return {"relaxation": self.relaxation, "alpha": self.alpha, "decay_rate": self.decay,
                "decay_rate_bracket": self.decay_certified,
                "size_t": self.t, "status": self.status,
                "max_condition_eigenvalue": self.max_condition_eigenvalue,
                "condition_P": float(np.linalg.cond(self.P)), "scaling": self.scaling}


def pdc_lmi(A: Any, B: Any, *, alpha: float = 0.0, relaxation: str = "tuan",
            faces: tuple[np.ndarray, np.ndarray] | None = None,
            input_margins: Sequence[float] | None = None, margin: float = 1e-6,
            kappa: float = 1e4, solver: str = "CLARABEL", inner_radius: float = 0.0) -> PDCResult:
    """Solve the PDC LMIs and re-check the result in numpy.

    Parameters
    ----------
    A : array_like, shape (r, n, n)
        Vertex matrices (1/s).
    B : array_like, shape (n, m)
        Input matrix (state units/s per input unit).
    alpha : float
        Decay rate ``dV/dt <= -2 alpha V`` (1/s, >= 0).
    relaxation : {"vertex", "tuan", "all_pairs"}
    faces : (G, g), optional
        Domain faces in deviation coordinates ``G e <= g`` (``g > 0``, state
        units): the ellipsoid ``e' P e <= 1`` must lie inside.
    input_margins : sequence of float, optional
        ``|v_j| <= margin_j`` on the ellipsoid (input units).
    margin : float
        Strictness margin of the scaled problem (> 0).
    kappa : float
        ``X <= kappa I`` (scaled) when no face or input margin bounds the problem.
    solver : str
    inner_radius : float
        The ellipsoid must contain the ball of this radius (``X >= r^2 I``,
        state units): without it a high decay rate is bought with a vanishing
        region.

    Returns
    -------
    PDCResult

    Raises
    ------
    InfeasibleDesign
        Solver failure, or the re-check fails.
    """
    A = np.asarray(A, dtype=float)
    B = np.atleast_2d(np.asarray(B, dtype=float))
    if A.ndim != 3 or A.shape[1] != A.shape[2] or B.shape[0] != A.shape[1]:
        raise DimensionError(f"A must be (r, n, n) and B (n, m); got {A.shape}, {B.shape}")
    r, n, _ = A.shape
    m = B.shape[1]
    if not (np.isfinite(alpha) and alpha >= 0):
        raise SpecError(f"alpha must be >= 0, got {alpha}", key="decay_rate")
    conds = condition_weights(relaxation, r)
    # ---- scaling: states by the distance to the faces, inputs by their margins, time by |A|
    if faces is not None:
        G, g = np.atleast_2d(np.asarray(faces[0], float)), np.asarray(faces[1], float).reshape(-1)
        if np.any(g <= 0):
            raise InfeasibleDesign("the operating point is on or outside a face of the domain "
                                   f"(distances {g.tolist()}): no region around it")
        dist = np.array([min((g[l] / abs(G[l, i]) for l in range(len(g)) if G[l, i] != 0),
                             default=1.0) for i in range(n)])
    else:
        G, g, dist = np.zeros((0, n)), np.zeros(0), np.ones(n)
    um = None if input_margins is None else np.asarray(input_margins, float).reshape(m)
    if um is not None and np.any(um <= 0):
        raise InfeasibleDesign(f"the equilibrium input sits on a pump limit (margins {um.tolist()}): "
                               "no input is left for feedback")
    Tx = np.diag(dist)
    Tu = np.diag(um if um is not None else np.ones(m))
    As = np.array([np.linalg.solve(Tx, Ai @ Tx) for Ai in A])
    Bs = np.linalg.solve(Tx, B @ Tu)
    omega = max(float(max(np.linalg.norm(Ai, 2) for Ai in As)), float(alpha), 1e-12)
    As, Bs, al = As / omega, Bs / omega, alpha / omega
    # Clarabel: the LMIs written straight in its conic form (design.conic); others through cvxpy
    lib = modelling(solver)
    X = lib.variable((n, n), symmetric=True)
    Ms = [lib.variable((m, n)) for _ in range(r)]
    t = lib.variable()
    cons = [X >> margin * np.eye(n)]
    if inner_radius > 0:
        cons.append(X >> inner_radius ** 2 * np.diag(dist ** -2.0))
    Y = {}
    for cond in conds:
        S = 0
        for (i, j), w in cond.items():
            if (i, j) not in Y:
                Gij = As[i] @ X - Bs @ Ms[j]
                Y[i, j] = Gij + Gij.T + 2 * al * X
            S = S + w * Y[i, j]
        cons.append(symmetrized(S) << -margin * np.eye(n))
    bounded = False
    Gs = G @ Tx
    for l in range(len(g)):
        cons.append(Gs[l][None, :] @ X @ Gs[l][:, None] <= g[l] ** 2)
        bounded = True
    if um is not None:
        for Mi in Ms:
            for j in range(m):
                blk = lib.bmat([[np.ones((1, 1)), Mi[j:j + 1, :]], [Mi[j:j + 1, :].T, X]])
                cons.append(symmetrized(blk) >> 0)
        bounded = True
    if bounded:
        cons.append(X >> t * np.eye(n))
        prob = lib.Problem(lib.Maximize(t), cons)
    else:
        cons += [X << kappa * np.eye(n)]
        prob = lib.Problem(lib.Minimize(0), cons)
        t = None
    status = lib.solve_status(prob, solver)
    if status.startswith("solver_error"):
        raise InfeasibleDesign(f"PDC LMI ({relaxation}): solver {solver} failed: "
                               f"{status.removeprefix('solver_error ')}")
    if status not in ("optimal", "optimal_inaccurate") or X.value is None:
        raise InfeasibleDesign(f"PDC LMI ({relaxation}, alpha = {alpha:g} 1/s): solver status "
                               f"{status}")
    tval = float(t.value) if t is not None else 0.0
    if t is not None and tval <= margin:
        raise InfeasibleDesign(f"PDC LMI ({relaxation}, alpha = {alpha:g} 1/s): the certified "
                               f"ellipsoid is degenerate (size t = {tval:.3g})")
    Xo = Tx @ X.value @ Tx
    Xo = symmetrized(Xo)
    P = np.linalg.inv(Xo)
    P = symmetrized(P)
    K = np.array([Tu @ Mi.value @ Tx @ P for Mi in Ms])
    # ---- independent re-check in the original units
    mats = relaxed_conditions(P, A, B, K, alpha, relaxation)
    worst = max(float(np.linalg.eigvalsh(Mx)[-1]) for Mx in mats)
    pmin = float(np.linalg.eigvalsh(P)[0])
    if not (worst < 0 and pmin > 0):
        raise InfeasibleDesign(f"PDC LMI ({relaxation}, alpha = {alpha:g} 1/s): the solver said "
                               f"{status} but the re-check fails (largest condition eigenvalue "
                               f"{worst:.3g}, smallest eigenvalue of P {pmin:.3g})")
    bracket = decay_bracket(P, A, B, K, relaxation, float(alpha))
    scaling = {"state_scale": dist.tolist(), "input_scale": np.diag(Tu).tolist(),
               "time_scale": omega}
    return PDCResult(P, K, relaxation, float(alpha), bracket["at_most"], tval, status, worst, scaling,
                     bracket)


def max_decay_rate(A: Any, B: Any, relaxation: str, *, start: float | None = None,
                   rtol: float = 0.05, **kwargs: Any) -> tuple[float, list]:
    """Largest decay rate ``alpha`` (1/s) for which `pdc_lmi` is feasible (bisection).

    Parameters
    ----------
    A, B, relaxation, **kwargs
        As `pdc_lmi`.
    start : float, optional
        First trial (1/s); default the decay rate certified by the solution at
        ``alpha = 0``.
    rtol : float
        Relative width of the final bracket.

    Returns
    -------
    (float, list)
        The largest feasible ``alpha`` found (0.0 if only 0 is, -1.0 if none)
        and the trials ``(alpha, feasible)``.
    """
    def feasible(a: float) -> bool:
        try:
            pdc_lmi(A, B, alpha=a, relaxation=relaxation, **kwargs)
            return True
        except InfeasibleDesign:
            return False

    try:
        first = pdc_lmi(A, B, alpha=0.0, relaxation=relaxation, **kwargs)
    except InfeasibleDesign:
        return -1.0, [(0.0, False)]
    if start is None:
        start = max(first.decay, 1e-9)
    lo, _, hist = bisect_feasible(feasible, start=start, rtol=rtol, max_doublings=30)
    return lo, [(0.0, True)] + hist


# ---------------------------------------------------------------------------- region


# -------------------------------------------------------------------- output feedback


