"""Takagi-Sugeno controllers: PDC state feedback, its dual observer, certified regions.

Deviation TS model
    Around an equilibrium ``(x0, u0)`` (``f(x0) + B u0 = 0``) the deviations
    ``e = x - x0``, ``v = u - u0`` obey ``de/dt = A_lin e + sum_k M_k (n_k(x)
    - n_k(x0)) + B v``, with the atoms ``n_k`` and incidence ``M`` of
    `tanksynth.analysis.quasi_lpv`. Every atom of the tank plants is a
    function of one linear form of the states, ``n_k(x) = phi_k(a_k . x)``
    (``sqrt(h2)``, ``sgn(h1 - h3) sqrt|h1 - h3|``), so the sector
    rewriting of the *increment*::

        n_k(x) - n_k(x0) = z_k(x) a_k . e,   z_k = (phi_k(t) - phi_k(t0)) / (t - t0),

    (``t = a_k . x``, ``t0 = a_k . x0``; ``z_k = phi_k'(t0)`` at ``t = t0``) is
    exact and bounded wherever ``phi_k`` is (the secant slope of a square root
    from ``t0 != 0`` stays finite even across a flow reversal). With ``z_k in
    [lo_k, hi_k]`` on the domain this gives ``2^p`` vertices ``A_i`` (Table I
    order of seed 001) and ``de/dt = sum_i mu_i(x) (A_i e + B v)`` exactly.
    The bounds come from dense sampling of the 1-D secant on the exact range
    of ``a_k . x`` over the domain (LP), widened by a relative margin.

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
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import sympy as sp

from tanksynth.analysis.quasi_lpv import _NUMPY, Domain, QuasiLPV, lambdify_cached
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError

__all__ = ["RELAXATIONS", "DeviationTSModel", "deviation_ts_model", "linear_argument",
           "condition_weights", "PDCResult", "pdc_lmi", "relaxed_conditions", "certified_decay",
           "max_decay_rate"]

#: LMI relaxations of the PDC conditions.
RELAXATIONS = ("vertex", "tuan", "all_pairs")


# ----------------------------------------------------------------------------- model
def linear_argument(atom: sp.Expr, states: Sequence[sp.Symbol], seed: int = 0) -> np.ndarray:
    """The linear form ``a`` with ``atom(x) = phi(a . x)``.

    One state: its unit vector. Several: the argument of the atom's
    ``Abs``/``sign``/``sqrt``, checked numerically (the atom must not change
    along random directions orthogonal to ``a``). The result does not depend
    on the order sympy keeps its sets in (``PYTHONHASHSEED``): the candidate
    arguments are tried in `sympy.default_sort_key` order, and the sign is
    canonical, the first nonzero coefficient positive (``h2 - h3``, never
    ``h3 - h2``; the premise ``z_k`` and its bounds change sign with ``a``,
    the vertex matrices ``z_k M_k a'`` do not).

    Parameters
    ----------
    atom : sympy.Expr
        A nonlinear atom of the model.
    states : sequence of sympy.Symbol
        The state symbols.
    seed : int, optional
        Seed of the random directions of the numerical check.

    Raises
    ------
    SpecError
        The atom is not a function of one linear form of the states.
    """
    states = list(states)
    free = [s for s in states if s in atom.free_symbols]
    n = len(states)
    if len(free) == 1:
        a = np.zeros(n)
        a[states.index(free[0])] = 1.0
        return a
    # atoms() is a set (hash order): sort, so that the first linear argument is always the same
    args = sorted((f.args[0] for f in atom.atoms(sp.Abs, sp.sign)), key=sp.default_sort_key)
    args += sorted((p.base for p in atom.atoms(sp.Pow) if p.exp == sp.Rational(1, 2)),
                   key=sp.default_sort_key)
    cand = None
    for arg in args:
        try:
            poly = sp.Poly(sp.expand(arg), *states)
        except sp.PolynomialError:
            continue
        if poly.total_degree() == 1 and poly.coeff_monomial(1) == 0:
            cand = np.array([float(poly.coeff_monomial(s)) for s in states])
            if cand[np.flatnonzero(cand)[0]] < 0:    # canonical sign: first nonzero coefficient > 0
                cand = -cand + 0.0    # no -0.0 in the artefact
            break
    fail = SpecError(f"atom {atom} is not a function of one linear combination of the states: the "
                     "deviation TS model of ts_state_feedback needs n_k(x) = phi(a . x)", key="plant")
    if cand is None:
        raise fail
    fn = sp.lambdify([states], atom, modules=_NUMPY)
    rng = np.random.default_rng(seed)
    X = rng.uniform(0.1, 0.6, size=(64, n))
    D = rng.normal(size=(64, n))
    D -= np.outer(D @ cand, cand) / (cand @ cand)
    with np.errstate(invalid="ignore"):
        v1 = np.asarray(fn(X.T), dtype=float)
        v2 = np.asarray(fn((X + 0.05 * D).T), dtype=float)
    if not np.allclose(v1, v2, rtol=1e-9, atol=1e-12, equal_nan=True):
        raise fail
    return cand


def _atom_on_points(qlpv: QuasiLPV, k: int, X: np.ndarray) -> np.ndarray:
    """Atom ``n_k`` alone at M points (M, n) -> (M,), NaN where it is undefined (no warning).

    The design's own lines through ``x0`` may leave the domain where the
    *other* atoms are defined; `QuasiLPV.atom_values` would warn about a
    state leaving the domain, which is not what happens there.
    """
    fn = lambdify_cached([qlpv.states], qlpv.atoms[k])
    X = np.atleast_2d(np.asarray(X, dtype=float))
    with np.errstate(invalid="ignore", divide="ignore"):
        vals = fn(X.T)
    return np.broadcast_to(np.asarray(vals, dtype=float), (X.shape[0],)).copy()


@dataclass(frozen=True)
class DeviationTSModel:
    """Exact TS model of the deviations ``e = x - x0`` (see the module docstring).

    Attributes
    ----------
    x0 : ndarray, shape (n,)
        Operating point (state units).
    u0 : ndarray, shape (m,)
        Equilibrium input (input units).
    forms : ndarray, shape (p, n)
        Linear forms ``a_k``.
    lower, upper : ndarray, shape (p,)
        Bounds of the premises ``z_k`` (state units per second per state unit).
    sampled_lower, sampled_upper : ndarray, shape (p,)
    A : ndarray, shape (r, n, n)
        Vertex matrices (1/s), Table I order (``sigma`` 1 = upper bound).
    B : ndarray, shape (n, m)
    C : ndarray, shape (q, n)
    sigmas : tuple of tuple of int
    domain : Domain
    qlpv : QuasiLPV
    method : str
        How the bounds were obtained.
    """

    x0: np.ndarray
    u0: np.ndarray
    forms: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    sampled_lower: np.ndarray
    sampled_upper: np.ndarray
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    sigmas: tuple[tuple[int, ...], ...]
    domain: Domain
    qlpv: QuasiLPV
    method: str
    _fn: Any = field(default=None, repr=False, compare=False)

    @property
    def r(self) -> int:
        """Number of vertices ``2^p``."""
        return int(self.A.shape[0])

    @property
    def A0(self) -> np.ndarray:
        """Mean vertex matrix (1/s)."""
        return self.A.mean(axis=0)

    def premises(self, X: np.ndarray) -> np.ndarray:
        """``z_k(x)`` at M points (M, n) -> (M, p) (secant slopes; tangent at ``t = t0``).

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units, m).
        """
        X = np.atleast_2d(np.asarray(X, dtype=float))
        atoms = self.qlpv.atom_values(X)
        at0 = self.qlpv.atom_values(self.x0[None, :])[0]
        dt = (X - self.x0) @ self.forms.T
        slope0 = self._tangent()
        with np.errstate(divide="ignore", invalid="ignore"):
            z = (atoms - at0) / dt
        small = np.abs(dt) <= 1e-12 * np.maximum(1.0, np.abs(self.x0 @ self.forms.T))
        return np.where(small, slope0, z)

    def _tangent(self) -> np.ndarray:
        h = 1e-7
        out = []
        for k in range(self.forms.shape[0]):
            d = self.forms[k] / (self.forms[k] @ self.forms[k])
            vals = _atom_on_points(self.qlpv, k, np.array([self.x0 + h * d, self.x0 - h * d]))
            out.append((vals[0] - vals[1]) / (2 * h))
        return np.array(out)

    def memberships(self, X: np.ndarray) -> np.ndarray:
        """``mu_i(x)`` at M points (M, n) -> (M, r).

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units, m).
        """
        Z = self.premises(X)
        span = self.upper - self.lower
        F1 = np.where(span > 0, (Z - self.lower) / np.where(span > 0, span, 1.0), 1.0)
        F = np.stack([F1, 1.0 - F1], axis=2)
        mu = np.ones((F1.shape[0], self.r))
        for i, sig in enumerate(self.sigmas):
            for k, s in enumerate(sig):
                mu[:, i] *= F[:, k, s - 1]
        return mu

    def rhs(self, X: np.ndarray, U: np.ndarray) -> np.ndarray:
        """``dx/dt = sum_i mu_i (A_i e + B v)`` at M points (state units/s).

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units, m).
        U : ndarray, shape (M, m)
            Inputs (input units).
        """
        X = np.atleast_2d(np.asarray(X, dtype=float))
        U = np.atleast_2d(np.asarray(U, dtype=float))
        mu = self.memberships(X)
        E = X - self.x0
        return np.einsum("mi,inj,mj->mn", mu, self.A, E) + (U - self.u0) @ self.B.T

    def as_dict(self) -> dict:
        """JSON-friendly description (enough to rebuild the model from the plant)."""
        return {"x0": self.x0.tolist(), "u0": self.u0.tolist(), "forms": self.forms.tolist(),
                "atoms": [str(a) for a in self.qlpv.atoms],
                "incidence": self.qlpv.incidence.tolist(),
                "lower": self.lower.tolist(), "upper": self.upper.tolist(),
                "sampled_lower": self.sampled_lower.tolist(),
                "sampled_upper": self.sampled_upper.tolist(), "method": self.method,
                "r": self.r, "sigmas": [list(s) for s in self.sigmas],
                "A_vertices": self.A.tolist(), "B": self.B.tolist(), "C": self.C.tolist(),
                "domain": self.domain.as_dict()}


def deviation_ts_model(qlpv: QuasiLPV, domain: Domain, x0: Sequence[float], u0: Sequence[float],
                       samples: int = 20001, margin: float = 1e-3) -> DeviationTSModel:
    """Exact TS model of the deviations from ``(x0, u0)`` on ``domain``.

    Parameters
    ----------
    qlpv : QuasiLPV
        Atoms and incidence of the plant (its weights are not used).
    domain : Domain
        Where the model must be exact (must contain ``x0``).
    x0 : sequence of float
        Operating point (state units).
    u0 : sequence of float
        Equilibrium input (input units).
    samples : int
        Points of the 1-D grid of each secant slope.
    margin : float
        Relative widening of each sampled premise range (>= 0).

    Returns
    -------
    DeviationTSModel

    Raises
    ------
    SpecError
        ``x0`` outside the domain, an atom not of the form ``phi(a . x)``,
        or a secant unbounded on the domain.
    """
    x0 = np.asarray(x0, dtype=float).reshape(qlpv.n)
    u0 = np.asarray(u0, dtype=float).reshape(qlpv.B.shape[1])
    if not bool(domain.contains(x0)[0]):
        raise SpecError(f"operating point {x0.tolist()} is outside the TS domain "
                        f"({domain.description})", key="domain")
    if qlpv.p > 12:
        raise SpecError(f"{qlpv.p} premises: 2^{qlpv.p} vertices are too many for the PDC LMIs",
                        key="plant")
    forms = np.array([linear_argument(a, qlpv.states) for a in qlpv.atoms]).reshape(qlpv.p, qlpv.n)
    model = DeviationTSModel(x0, u0, forms, np.zeros(qlpv.p), np.zeros(qlpv.p), np.zeros(qlpv.p),
                             np.zeros(qlpv.p), np.zeros((1, qlpv.n, qlpv.n)), qlpv.B, qlpv.C, (),
                             domain, qlpv, "")
    slope0 = model._tangent()
    lo, hi, slo, shi = [], [], [], []
    for k in range(qlpv.p):
        a = forms[k]
        tmin, tmax = domain.linear_range(a)
        t0 = float(a @ x0)
        grid = np.unique(np.concatenate([np.linspace(tmin, tmax, samples), [tmin, tmax]]))
        # the line x0 + s a covers the exact range of a . x but may leave the domain (h2 < 0 on
        # the line of h3 - h2): atom k depends on a . x only, so it alone is evaluated there
        X = x0 + np.outer(grid - t0, a / (a @ a))
        vals = _atom_on_points(qlpv, k, X)
        at0 = float(_atom_on_points(qlpv, k, x0[None, :])[0])
        dt = grid - t0
        ok = np.abs(dt) > 1e-9 * max(1.0, abs(t0))
        z = np.concatenate([(vals[ok] - at0) / dt[ok], [slope0[k]]])
        if not np.all(np.isfinite(z)):
            raise SpecError(f"premise z{k + 1} (secant of {qlpv.atoms[k]}) is unbounded on the domain",
                            key="domain")
        zl, zh = float(z.min()), float(z.max())
        w = margin * max(zh - zl, 1e-12 * max(abs(zl), abs(zh), 1e-300))
        slo.append(zl)
        shi.append(zh)
        lo.append(zl - w)
        hi.append(zh + w)
    lower, upper = np.array(lo), np.array(hi)
    sigmas = tuple(itertools.product((1, 2), repeat=qlpv.p))
    A = np.array([qlpv.A_lin + sum((upper[k] if s == 1 else lower[k])
                                   * np.outer(qlpv.incidence[:, k], forms[k])
                                   for k, s in enumerate(sig)) for sig in sigmas])
    method = (f"secant slopes on a 1-D grid of {samples} points over the exact (LP) range of each "
              f"linear form, widened by {margin:g} of the sampled range on each side")
    return DeviationTSModel(x0, u0, forms, lower, upper, np.array(slo), np.array(shi), A, qlpv.B,
                            qlpv.C, sigmas, domain, qlpv, method)


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
        out.append(0.5 * (S + S.T))
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
    Lc = np.linalg.cholesky(0.5 * (P + P.T))
    Li = np.linalg.inv(Lc)
    best = np.inf
    conds = condition_weights(relaxation, A.shape[0])
    mats = relaxed_conditions(P, A, B, K, 0.0, relaxation)
    for cond, N in zip(conds, mats):
        s = 2.0 * sum(cond.values())
        lam = np.linalg.eigvalsh(Li @ (-N) @ Li.T)[0] / s
        best = min(best, float(lam))
    return best


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
        Decay rate the returned matrices certify (`certified_decay`), 1/s.
    t : float
        Size of the ellipsoid achieved (scaled; 0 without constraints).
    status : str
    max_condition_eigenvalue : float
        Largest eigenvalue of the condition matrices (original units), < 0.
    scaling : dict
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

    def as_dict(self) -> dict:
        """JSON-friendly diagnostics."""
        return {"relaxation": self.relaxation, "alpha": self.alpha, "decay_rate": self.decay,
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
    import cvxpy as cp

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
    X = cp.Variable((n, n), symmetric=True)
    Ms = [cp.Variable((m, n)) for _ in range(r)]
    t = cp.Variable()
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
        cons.append(0.5 * (S + S.T) << -margin * np.eye(n))
    bounded = False
    Gs = G @ Tx
    for l in range(len(g)):
        cons.append(Gs[l] @ X @ Gs[l] <= g[l] ** 2)
        bounded = True
    if um is not None:
        for Mi in Ms:
            for j in range(m):
                blk = cp.bmat([[np.ones((1, 1)), Mi[j:j + 1, :]], [Mi[j:j + 1, :].T, X]])
                cons.append(0.5 * (blk + blk.T) >> 0)
        bounded = True
    if bounded:
        cons.append(X >> t * np.eye(n))
        prob = cp.Problem(cp.Maximize(t), cons)
    else:
        cons += [X << kappa * np.eye(n)]
        prob = cp.Problem(cp.Minimize(0), cons)
        t = None
    try:
        prob.solve(solver=solver)
    except cp.error.SolverError as exc:
        raise InfeasibleDesign(f"PDC LMI ({relaxation}): solver {solver} failed: {exc}") from None
    status = str(prob.status)
    if status not in ("optimal", "optimal_inaccurate") or X.value is None:
        raise InfeasibleDesign(f"PDC LMI ({relaxation}, alpha = {alpha:g} 1/s): solver status "
                               f"{status}")
    tval = float(t.value) if t is not None else 0.0
    if t is not None and tval <= margin:
        raise InfeasibleDesign(f"PDC LMI ({relaxation}, alpha = {alpha:g} 1/s): the certified "
                               f"ellipsoid is degenerate (size t = {tval:.3g})")
    Xo = Tx @ X.value @ Tx
    Xo = 0.5 * (Xo + Xo.T)
    P = np.linalg.inv(Xo)
    P = 0.5 * (P + P.T)
    K = np.array([Tu @ Mi.value @ Tx @ P for Mi in Ms])
    # ---- independent re-check in the original units
    mats = relaxed_conditions(P, A, B, K, alpha, relaxation)
    worst = max(float(np.linalg.eigvalsh(Mx)[-1]) for Mx in mats)
    pmin = float(np.linalg.eigvalsh(P)[0])
    if not (worst < 0 and pmin > 0):
        raise InfeasibleDesign(f"PDC LMI ({relaxation}, alpha = {alpha:g} 1/s): the solver said "
                               f"{status} but the re-check fails (largest condition eigenvalue "
                               f"{worst:.3g}, smallest eigenvalue of P {pmin:.3g})")
    decay = certified_decay(P, A, B, K, relaxation)
    scaling = {"state_scale": dist.tolist(), "input_scale": np.diag(Tu).tolist(),
               "time_scale": omega}
    return PDCResult(P, K, relaxation, float(alpha), decay, tval, status, worst, scaling)


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
    from tanksynth.design.lmi import bisect_feasible

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


