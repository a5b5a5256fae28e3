"""Takagi-Sugeno design support: selection rules, Lipschitz bounds, weighting search (seed 001).

The multiple model itself (quasi-LPV form, premise bounds, vertex matrices,
exactness and vertex observability) is `tanksynth.analysis.takagi_sugeno`.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import sympy as sp
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from tanksynth.analysis import blas as _blas
from tanksynth.analysis.interval import branch_and_bound, interval_evaluate
from tanksynth.analysis.quasi_lpv import FormEvaluator, lambdify_cached
from tanksynth.analysis.symbolic import jacobian_by_form
from tanksynth.analysis.takagi_sugeno import Domain, QuasiLPV, TSModel, ts_model, vertex_observability
from tanksynth.design.bisection import bisect_feasible
from tanksynth.design.observer_lmi.conic_form import sweep_problem
from tanksynth.errors import SpecError

__all__ = [
    "SelectionRules",
    "selection_rules",
    "LipschitzBound",
    "lipschitz_bound",
    "WeightSearch",
    "search_weightings",
    "candidate_weights",
]


@dataclass(frozen=True)
class SelectionRules:
    """Seed 001's three rules for choosing a quasi-LPV form.

    Attributes
    ----------
    null_rows_A, null_cols_A : tuple of int
        Rows/columns of ``A(z)`` identically zero (rule 1 eliminates the form).
    null_rows_B, null_cols_B : tuple of int
        Same for ``B`` (structural for the three-tank: tank 3 has no pump,
        so it cannot discriminate between forms; reported, not used).
    rule1_passed : bool
        No null row or column in ``A(z)``.
    premise_count : int
        Rule 2: fewer premise variables is better.
    shared_premises : tuple of str
        Premises entering more than one state equation.
    premise_states : int
        Rule 3: number of distinct states the premises depend on (fewer is
        better).
    states_per_premise : tuple of int
    """

    null_rows_A: tuple[int, ...]
    null_cols_A: tuple[int, ...]
    null_rows_B: tuple[int, ...]
    null_cols_B: tuple[int, ...]
    rule1_passed: bool
    premise_count: int
    shared_premises: tuple[str, ...]
    premise_states: int
    states_per_premise: tuple[int, ...]

    def as_dict(self) -> dict:
        """JSON-friendly form (1-based indices)."""
        return dict(self.__dict__)


def selection_rules(qlpv: QuasiLPV) -> SelectionRules:
    """Evaluate seed 001's selection rules 1-3 on a quasi-LPV form.

    Parameters
    ----------
    qlpv : QuasiLPV

    Returns
    -------
    SelectionRules
    """
    n, p = qlpv.n, qlpv.p
    support = (qlpv.A_lin != 0).astype(int)
    for k in range(p):
        support |= np.outer(qlpv.incidence[:, k] != 0, qlpv.weights[k] != 0).astype(int)
    rows = tuple(i + 1 for i in range(n) if not support[i].any())
    cols = tuple(j + 1 for j in range(n) if not support[:, j].any())
    brows = tuple(i + 1 for i in range(n) if not np.any(qlpv.B[i]))
    bcols = tuple(j + 1 for j in range(qlpv.B.shape[1]) if not np.any(qlpv.B[:, j]))
    shared = tuple(f"z{k + 1}" for k in range(p) if np.count_nonzero(qlpv.incidence[:, k]) > 1)
    per = []
    used: set[int] = set()
    for k in range(p):
        st = set(qlpv.atom_states[k]) | set(np.flatnonzero(qlpv.weights[k]).tolist())
        per.append(len(st))
        used |= st
    return SelectionRules(rows, cols, brows, bcols, not rows and not cols, p, shared, len(used),
                          tuple(per))


# ------------------------------------------------------------------- Lipschitz
@dataclass(frozen=True)
class LipschitzBound:
    """Lipschitz constant ``psi`` of ``Delta(x, xhat)`` over the domain (1/s).

    Attributes
    ----------
    value : float
        The bound used (``inf`` when ``f`` is not Lipschitz on the domain).
    form : str
        ``"jacobian"``: ``sup ||df/dx - A0||_2`` (exact constant on the convex
        domain, by the mean-value theorem); ``"eq27"``: seed 001 eq. (27)
        ``sum_i sigma(Abar_i) omega_i + sigma(Bbar_i) tau_i phi``.
    method : str
        ``"interval"`` (guaranteed) or ``"sampling"`` (sampled maximum times
        ``1 + margin``).
    sampled : float
        Largest value seen at sample points (a lower bound of the constant).
    detail : dict
    """

    value: float
    form: str
    method: str
    sampled: float
    detail: dict

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"value": self.value, "form": self.form, "method": self.method,
                "sampled": self.sampled, **self.detail}


def _jacobian_exprs(qlpv: QuasiLPV) -> sp.Matrix:
    """``df/dx`` of ``f = A_lin x + M n(x)`` (symbolic, parameters substituted).

    Built row by row from the nonzero entries of ``A_lin`` and ``M`` (a dense
    sympy matrix product costs ``n^2`` symbolic products, 4,096 at n = 64).
    """
    terms: list[list[sp.Expr]] = [[] for _ in range(qlpv.n)]
    for (i, j), c in sorted(qlpv.exact_A_lin.todok().items()):
        terms[i].append(c * qlpv.states[j])
    for (i, k), c in sorted(qlpv.exact_incidence.todok().items()):
        terms[i].append(c * qlpv.atoms[k])
    return jacobian_by_form(sp.Matrix([sp.Add(*t) for t in terms]), qlpv.states)


@dataclass(frozen=True)
class _JacobianParts:
    """``df/dx`` as its constant entries plus the non-constant ones compiled once.

    ``base`` holds the constant entries; ``rows``, ``cols`` locate the
    non-constant entries, whose values at M points ``values(P)`` returns as
    an (M, k) array (`FormEvaluator`: one compiled function per distinct
    form of entry, e.g. per tank type).
    """

    base: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    fn: FormEvaluator | None

    def values(self, P: np.ndarray) -> np.ndarray:
        """Non-constant entries at the points ``P`` (M, n): (M, k), NaN/inf where singular."""
        P = np.atleast_2d(np.asarray(P, dtype=float))
        if self.fn is None:
            return np.empty((len(P), 0))
        return self.fn(P)

    def dense(self, P: np.ndarray) -> np.ndarray:
        """``df/dx`` at the points ``P`` (M, n): (M, n, n)."""
        out = np.empty((len(P), *self.base.shape))
        out[:] = self.base
        if len(self.rows):
            out[:, self.rows, self.cols] = self.values(P)
        return out


def _jacobian_parts(q: QuasiLPV, J: sp.Matrix) -> _JacobianParts:
    base = np.zeros((q.n, q.n))
    where, exprs = [], []
    for i in range(q.n):
        for j in range(q.n):
            e = J[i, j]
            if e.free_symbols:
                where.append((i, j))
                exprs.append(e)
            elif e != 0:
                base[i, j] = float(e)
    fn = FormEvaluator(exprs, q.states) if exprs else None
    rows = np.array([w[0] for w in where], dtype=int)
    cols = np.array([w[1] for w in where], dtype=int)
    return _JacobianParts(base, rows, cols, fn)


def _jacobian_function(q: QuasiLPV, J: sp.Matrix) -> Callable[[np.ndarray], np.ndarray]:
    """Vectorised ``df/dx`` at M points: (M, n) -> (M, n, n); inf where singular.

    The constant entries are evaluated once; the others are compiled once
    per distinct form (`FormEvaluator`), not one per entry.
    """
    return _jacobian_parts(q, J).dense


def _spectral_norms(parts: _JacobianParts, A0: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``||df/dx - A0||_2`` at M points from the non-constant entries ``values`` (M, k).

    The rows and columns of ``D = df/dx - A0`` split into the connected
    components of its sparsity pattern (bipartite graph of rows and columns):
    ``D`` is, up to permutations, block diagonal, and its spectral norm is the
    largest of the blocks' (two blocks per tank pair of the tank network, not
    one n x n SVD per point). Blocks with one row or column: Euclidean norm;
    with two: the larger eigenvalue of the 2 x 2 Gram matrix in closed form;
    larger ones: batched SVD. NaN where an entry is not finite.
    """
    n = A0.shape[0]
    M = len(values)
    const = parts.base - A0
    pattern = const != 0
    pattern[parts.rows, parts.cols] = True
    r_idx, c_idx = np.nonzero(pattern)
    graph = coo_matrix((np.ones(len(r_idx)), (r_idx, n + c_idx)), shape=(2 * n, 2 * n))
    _, label = connected_components(graph, directed=False)
    entry = {(int(i), int(j)): k for k, (i, j) in enumerate(zip(parts.rows, parts.cols))}
    groups: dict[tuple[int, int], list[tuple[np.ndarray, np.ndarray]]] = {}
    for comp in np.unique(label):
        R = np.flatnonzero(label[:n] == comp)
        C = np.flatnonzero(label[n:] == comp)
        if R.size and C.size:
            groups.setdefault((R.size, C.size), []).append((R, C))
    finite = np.all(np.isfinite(values), axis=1) & bool(np.all(np.isfinite(const)))
    best = np.zeros(M)
    for (r, c), comps in groups.items():
        Rg = np.array([R for R, _ in comps])            # (g, r)
        Cg = np.array([C for _, C in comps])            # (g, c)
        blocks = np.empty((M, len(comps), r, c))
        blocks[:] = const[Rg[:, :, None], Cg[:, None, :]]
        for g, (R, C) in enumerate(comps):
            for a, i in enumerate(R):
                for b, j in enumerate(C):
                    k = entry.get((int(i), int(j)))
                    if k is not None:
                        blocks[:, g, a, b] = values[:, k] - A0[i, j]
        with np.errstate(invalid="ignore", over="ignore"):
            if min(r, c) == 1:
                norms = np.sqrt(np.sum(blocks.reshape(M, len(comps), -1) ** 2, axis=2))
            elif min(r, c) == 2:
                G = blocks @ np.swapaxes(blocks, 2, 3) if r == 2 else \
                    np.swapaxes(blocks, 2, 3) @ blocks
                p, q, o = G[..., 0, 0], G[..., 1, 1], G[..., 0, 1]
                norms = np.sqrt(0.5 * (p + q) + np.hypot(0.5 * (p - q), o))
            else:
                flat = blocks.reshape(-1, r, c)
                ok = np.all(np.isfinite(flat), axis=(1, 2))
                norms = np.full(len(flat), np.nan)
                if ok.any():
                    norms[ok] = np.linalg.svd(flat[ok], compute_uv=False)[:, 0]
                norms = norms.reshape(M, len(comps))
        best = np.maximum(best, np.max(norms, axis=1))
    return np.where(finite, best, np.nan)


def _prod(a: float | np.floating, b: float | np.floating) -> float:
    """``a * b`` with ``0 * inf = 0`` (a zero matrix contributes nothing)."""
    return 0.0 if a == 0 or b == 0 else float(a * b)


def lipschitz_bound(ts: TSModel, form: str = "jacobian", method: str = "interval",
                    samples: int = 5000, margin: float = 0.05, seed: int = 0,
                    input_bound: float | None = None, max_boxes: int = 4096,
                    max_rounds: int = 30, rtol: float = 0.05) -> LipschitzBound:
    """Lipschitz constant of ``Delta`` (seed 001 eq. 24-27) over the domain.

    Parameters
    ----------
    ts : TSModel
    form : {"jacobian", "eq27"}
        Direct bound ``sup ||df/dx - A0||_2`` (tight; ``Delta`` does not
        depend on ``u`` since ``B`` is constant), or the paper's eq. (27)
        (sampling only; always at least the direct bound).
    method : {"interval", "sampling"}
        For ``"jacobian"``: interval enclosure of the Jacobian entries with
        branch-and-bound on the Frobenius bound (guaranteed), or the sampled
        spectral norm times ``1 + margin``.
    samples : int
    margin : float
        Relative safety factor of sampled values (>= 0).
    seed : int
    input_bound : float, optional
        ``phi`` of eq. (24), ``|u| < phi``; default the largest input norm in
        the actuator box (eq27 only).
    max_boxes, max_rounds : int
        Branch-and-bound limits.
    rtol : float
        Branch-and-bound stopping gap (relative).

    Returns
    -------
    LipschitzBound
        ``value = inf`` when ``f`` is not Lipschitz on the domain (e.g. the
        ``sqrt(|h1 - h3|)`` flows when ``h1 = h3`` is allowed).
    """
    if form not in ("jacobian", "eq27"):
        raise SpecError(f"unknown Lipschitz form {form!r}; expected 'jacobian' or 'eq27'",
                        key="lipschitz")
    if form == "eq27" and not ts.enumerated:
        raise SpecError(f"eq. (27) sums over the 2^{ts.qlpv.p} vertices, which are not enumerated; "
                        "use lipschitz = 'jacobian'", key="lipschitz")
    if method not in ("interval", "sampling"):
        raise SpecError(f"unknown method {method!r}; expected 'interval' or 'sampling'",
                        key="lipschitz_method")
    q = ts.qlpv
    X = np.vstack([ts.domain.sample(samples, seed), ts.domain.corners()])
    J = _jacobian_exprs(q)
    parts = _jacobian_parts(q, J)
    A0 = ts.A0
    # sampled sup of ||df/dx - A0||_2, block by block (`_spectral_norms`), in chunks
    finite = np.ones(len(X), dtype=bool)
    sampled = -np.inf
    chunk = max(1, 2 ** 20 // max(len(parts.rows), 1))
    with _blas.small_dense(), np.errstate(divide="ignore", invalid="ignore"):
        for start in range(0, len(X), chunk):
            norms = _spectral_norms(parts, A0, parts.values(X[start:start + chunk]))
            ok = np.isfinite(norms)
            finite[start:start + chunk] = ok
            if ok.any():
                sampled = max(sampled, float(np.max(norms[ok])))
    if not finite.any():
        sampled = np.inf
    if not finite.all():
        sampled = np.inf
    if not np.isfinite(sampled):
        bad = X[~finite][:3]
        return LipschitzBound(np.inf, form, method, np.inf,
                              {"samples": int(len(X)),
                               "text": "f is not Lipschitz on the domain: df/dx is unbounded at "
                                       f"sampled points such as {bad.tolist()} (e.g. sqrt(|h1 - h3|) "
                                       "at h1 = h3); restrict the domain (orderings with a gap)"})
    if form == "jacobian":
        if method == "sampling":
            return LipschitzBound(sampled * (1 + margin), form, method, sampled,
                                  {"samples": int(len(X)), "margin": margin,
                                   "text": f"sampled max of ||df/dx - A0||_2 times (1 + {margin:g}); "
                                           "not guaranteed"})
        entries = [(i, j, J[i, j]) for i in range(q.n) for j in range(q.n) if J[i, j].free_symbols]
        # constant entries: a point interval, their share of the Frobenius bound computed once
        fixed = sum((float(J[i, j]) - A0[i, j]) ** 2 for i in range(q.n) for j in range(q.n)
                    if not J[i, j].free_symbols)

        def upper(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
            tot = np.full(len(lo), fixed)
            for i, j, e in entries:
                a, b = interval_evaluate(e, q.states, lo, hi)
                a, b = a - A0[i, j], b - A0[i, j]
                tot = tot + np.maximum(np.abs(a), np.abs(b)) ** 2
            return np.sqrt(tot)

        varying = np.zeros(A0.shape, dtype=bool)
        varying[parts.rows, parts.cols] = True
        fixed_sq = float(np.sum(np.where(varying, 0.0, parts.base - A0) ** 2))
        A0_varying = A0[parts.rows, parts.cols]

        def point(P: np.ndarray) -> np.ndarray:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                v = np.sqrt(fixed_sq + np.sum((parts.values(P) - A0_varying) ** 2, axis=1))
            return np.where(np.isfinite(v), v, np.inf)

        outer, inner, boxes, rounds = branch_and_bound(upper, point, ts.domain, X, rtol, max_boxes,
                                                        max_rounds)
        value = outer * (1 + 1e-12) if np.isfinite(outer) else np.inf
        return LipschitzBound(value, form, method, sampled,
                              {"boxes": boxes, "rounds": rounds, "frobenius_sampled": inner,
                               "text": "interval enclosure of df/dx - A0 entries, Frobenius bound of "
                                       "the spectral norm, branch-and-bound (guaranteed)"})
    # eq. (27): tau_i, omega_i by sampling
    Z = q.premise_values(X)
    span = ts.bounds.upper - ts.bounds.lower
    F1 = np.where(span > 0, (Z - ts.bounds.lower) / np.where(span > 0, span, 1.0), 1.0)
    F = np.stack([F1, 1.0 - F1], axis=2)
    grads = []
    for e in q.premise_expressions():
        row = []
        for s in q.states:
            de = sp.diff(e, s)
            fn = lambdify_cached([q.states], de)
            with np.errstate(divide="ignore", invalid="ignore"):
                row.append(np.broadcast_to(np.asarray(fn(X.T), dtype=float), (len(X),)))
        grads.append(np.column_stack(row))
    gz = np.stack(grads, axis=1)                         # (N, p, n)
    Abar = ts.A - A0
    Bbar = np.zeros((ts.r, *ts.B.shape))
    if input_bound is None:
        corners = np.array(list(itertools.product(*q.input_bounds)), dtype=float)
        phi = float(np.max(np.linalg.norm(corners, axis=1)))
    else:
        phi = float(input_bound)
    tau, omega = np.zeros(ts.r), np.zeros(ts.r)
    terms, with_full_B = 0.0, 0.0
    for i, sig in enumerate(ts.sigmas):
        mu = np.ones(len(X))
        grad = np.zeros((len(X), q.n))
        for k, s in enumerate(sig):
            mu = mu * F[:, k, s - 1]
        for k, s in enumerate(sig):
            others = np.ones(len(X))
            for l, sl in enumerate(sig):
                if l != k:
                    others = others * F[:, l, sl - 1]
            dF = (1.0 if s == 1 else -1.0) / span[k] if span[k] > 0 else 0.0
            grad += (others * dF)[:, None] * gz[:, k, :]
        with np.errstate(invalid="ignore", over="ignore"):
            Mi = mu[:, None, None] * np.eye(q.n) + X[:, :, None] * grad[:, None, :]
        if not (np.all(np.isfinite(grad)) and np.all(np.isfinite(Mi))):
            tau[i] = omega[i] = np.inf
        else:
            tau[i] = np.max(np.linalg.norm(grad, axis=1)) * (1 + margin)
            omega[i] = np.max(np.linalg.norm(Mi, 2, axis=(1, 2))) * (1 + margin)
        terms += _prod(np.linalg.norm(Abar[i], 2), omega[i]) + _prod(np.linalg.norm(Bbar[i], 2) * phi,
                                                                      tau[i])
        with_full_B += _prod(np.linalg.norm(Abar[i], 2), omega[i]) + _prod(np.linalg.norm(ts.B, 2) * phi,
                                                                        tau[i])
    value = float(terms) if np.isfinite(terms) else np.inf
    return LipschitzBound(value, form, "sampling", sampled,
                          {"tau": tau.tolist(), "omega": omega.tolist(), "phi": phi,
                           "margin": margin, "samples": int(len(X)),
                           "value_with_full_B_term": float(with_full_B),
                           "text": "seed 001 eq. (27) with tau_i, omega_i from sampled gradient norms "
                                   f"times (1 + {margin:g}); the input term uses Bbar_i = B_i - B0 "
                                   "(sum_i (mu_i(x) - mu_i(xhat)) = 0), the printed form with B_i "
                                   "is in value_with_full_B_term"})


# ------------------------------------------------------------------------ search
def candidate_weights(n: int, values: Sequence[float] = (-1.0, 0.0, 1.0)) -> np.ndarray:
    """Weight vectors with entries in ``values``, one per direction.

    ``w`` and ``c w`` give the same TS model (the premise scales by ``1/c``
    and its bounds with it), so vectors are kept up to a non-zero factor.

    Parameters
    ----------
    n : int
        Number of states.
    values : sequence of float
        Allowed entries.

    Returns
    -------
    ndarray, shape (K, n)
    """
    out, seen = [], set()
    for combo in itertools.product(sorted(set(float(v) for v in values)), repeat=n):
        w = np.array(combo)
        if not np.any(w):
            continue
        lead = w[np.flatnonzero(w)[0]]
        key = tuple(np.round(w / lead, 12))
        if key in seen:
            continue
        seen.add(key)
        out.append(w)
    return np.array(out).reshape(-1, n)


@dataclass(frozen=True)
class WeightSearch:
    """Automatic search over premise weightings (beyond seed 001).

    Attributes
    ----------
    candidates : tuple of dict
        One record per weighting tried: weights, outcome (``"unbounded"``,
        ``"unobservable"``, ``"infeasible"``, ``"pruned"`` or ``"ok"``),
        ``psi_max`` (1/s) and the sampled Lipschitz estimate.
    best : dict or None
        Record with the largest admissible ``psi``.
    searched : dict
        What was searched: premises varied, entry values, counts.
    best_certified : dict or None
        Among the records whose ``psi_max`` reaches their sampled Lipschitz
        constant (``certified``), the one with the largest ratio
        ``psi_max / psi_lipschitz``.
    """

    candidates: tuple[dict, ...]
    best: dict | None
    searched: dict
    best_certified: dict | None = None

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        counts: dict[str, int] = {}
        for c in self.candidates:
            counts[c["outcome"]] = counts.get(c["outcome"], 0) + 1
        return {"searched": self.searched, "outcomes": counts, "best": self.best,
                "best_certified": self.best_certified, "candidates": list(self.candidates)}


def search_weightings(qlpv: QuasiLPV, domain: Domain, *, values: Sequence[float] = (-1.0, 0.0, 1.0),
                      premises: Sequence[int] | None = None, include: Sequence[np.ndarray] = (),
                      variant: str = "qI", margin: float = 1e-6, kappa: float = 1e4,
                      bounds_method: str = "sampling", samples: int = 4000,
                      bounds_margin: float = 0.01,
                      seed: int = 0, rtol: float = 1e-2, solver: str = "CLARABEL") -> WeightSearch:
    """Search weightings whose vertices are observable and whose LMI is feasible.

    Every premise that depends on more than one state (or those listed in
    ``premises``) gets every direction of `candidate_weights`; the other
    premises keep their weights. Each combination is kept if its weighted
    sums never vanish on the domain, every vertex is observable and the
    observer LMI (28) is feasible; the one with the largest admissible
    ``psi`` (bisection; combinations that cannot beat the current best are
    pruned with one solve) is returned.

    Parameters
    ----------
    qlpv : QuasiLPV
    domain : Domain
    values : sequence of float
        Entries of the candidate weight vectors.
    premises : sequence of int, optional
        0-based premises to vary; default those depending on > 1 state.
    include : sequence of ndarray
        Extra full weight matrices (p, n) to try (e.g. the paper's).
    variant, margin, kappa, solver
        Observer LMI options (`tanksynth.design.observer_lmi.lmi.observer_lmi`).
    bounds_method, samples, bounds_margin, seed
        Premise bounds options (sampling is the fast default here).
    rtol : float
        Relative accuracy of each ``psi_max``.

    Returns
    -------
    WeightSearch
    """
    if premises is None:
        premises = [k for k in range(qlpv.p) if len(qlpv.atom_states[k]) > 1]
    premises = list(premises)
    cands = candidate_weights(qlpv.n, values)
    combos: list[np.ndarray] = []
    for choice in itertools.product(range(len(cands)), repeat=len(premises)):
        W = qlpv.weights.copy()
        for k, c in zip(premises, choice):
            W[k] = cands[c]
        combos.append(W)
    for W in include:
        W = np.asarray(W, dtype=float)
        if not any(np.array_equal(W, V) for V in combos):
            combos.append(W)
    C = qlpv.C
    # Clarabel: the eliminated form without cvxpy (rebuilt per trial); else the cvxpy problem
    prob = sweep_problem(None, C, variant, kappa, None, None, solver, "auto", 1e-6)
    Xs = np.vstack([domain.sample(samples, seed), domain.corners()])
    parts: _JacobianParts | None = None
    jac_values: np.ndarray | None = None
    records: list[dict] = []
    best: dict | None = None
    for W in combos:
        rec: dict = {"weights": W.tolist()}
        q2 = qlpv.with_weights(W)
        try:
            ts = ts_model(q2, domain, method=bounds_method, samples=samples, margin=bounds_margin,
                          seed=seed)
        except SpecError as exc:
            rec.update(outcome="unbounded", reason=exc.detail)
            records.append(rec)
            continue
        obs = vertex_observability(ts, symbolic=False)
        if not obs.all_observable:
            rec.update(outcome="unobservable", vertices=list(obs.unobservable))
            records.append(rec)
            continue
        A0 = ts.A0
        omega = prob.time_scale(A0, 0.0)
        if parts is None or jac_values is None:
            parts = _jacobian_parts(qlpv, _jacobian_exprs(qlpv))
            jac_values = parts.values(Xs)
        norms = _spectral_norms(parts, A0, jac_values)
        lip = float(np.max(norms)) if np.all(np.isfinite(norms)) else float("inf")
        rec["psi_lipschitz_sampled"] = lip

        def feasible(psi: float, A0=A0, omega=omega) -> bool:
            return prob.solve(A0, psi, omega)["t"] >= margin

        if best is not None and not feasible(best["psi_max"]):
            rec.update(outcome="pruned", reason=f"infeasible at the current best psi "
                                                f"{best['psi_max']:.4g}")
            records.append(rec)
            continue
        if not feasible(0.0):
            rec.update(outcome="infeasible", psi_max=0.0)
            records.append(rec)
            continue
        lo, hi, hist = bisect_feasible(feasible, start=(best["psi_max"] if best else 1e-2 * omega),
                                       rtol=rtol)
        rec.update(outcome="ok", psi_max=lo, trials=len(hist),
                   ratio=lo / lip if np.isfinite(lip) and lip > 0 else 0.0,
                   certified=bool(np.isfinite(lip) and lo >= lip))
        records.append(rec)
        if best is None or lo > best["psi_max"]:
            best = rec
    searched = {"premises_varied": [f"z{k + 1}" for k in premises], "entry_values": list(values),
                "directions_per_premise": int(len(cands)), "combinations": len(combos),
                "variant": variant, "bounds_method": bounds_method, "criterion":
                "largest psi for which LMI (28) is feasible with the margin (bisection, rtol "
                f"{rtol:g}); 'certified' when psi_max >= the sampled Lipschitz constant of Delta"}
    certified = [r for r in records if r.get("certified")]
    best_cert = max(certified, key=lambda r: r["ratio"]) if certified else None
    return WeightSearch(tuple(records), best, searched, best_cert)
