"""Takagi-Sugeno multiple models by exact sector rewriting (seed 001 eq. 7-17).

The plant's vector field (parameters substituted) is split, term by term,
into::

    f(x, u) = A_lin x + sum_k M[:, k] n_k(x) + B u + d

where the ``n_k`` ("atoms") are the distinct nonlinear functions of the
state (for the three-tank: the three Torricelli flows divided by the tank
section) and ``M`` is their constant incidence matrix. Following seed 001
(eq. 7-8), every atom is divided by a weighted sum of the states,
``z_k(x) = n_k(x) / (w_k . x)``, which gives the quasi-LPV form (eq. 9-11)::

    dx/dt = A(z) x + B u + d,     A(z) = A_lin + sum_k z_k M[:, k] w_k'.

With the bounds ``z_k in [z_k2, z_k1]`` over the operating domain (eq. 13),
the partition functions ``F_k1 = (z_k - z_k2)/(z_k1 - z_k2)``, ``F_k2 = 1 -
F_k1`` (eq. 12), the ``r = 2^p`` vertex matrices ``A_i = A(z_sigma_i)`` (eq. 15)
and the weights ``mu_i = prod_k F_k,sigma_i(k)`` (eq. 14, order of Table I)
give the exact multiple model (16): ``f = sum_i mu_i (A_i x + B_i u) + d``.

For seed 001 the atoms come out in the paper's order ``z1`` (flow T1-T3,
weights ``lambda``), ``z2`` (outflow of T2, weight ``e2``), ``z3`` (flow
T3-T2, weights ``gamma``).

Premise bounds are computed either by interval arithmetic with
branch-and-bound (a guaranteed enclosure) or by dense sampling plus an
explicit relative margin; the method is recorded in the diagnostics.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import scipy.optimize as sopt
import sympy as sp

from tanksynth.errors import DimensionError, RegionError, SpecError, TanksynthError
from tanksynth.plants.base import Plant, exact
# Module import (not names): tanksynth.analysis.rank imports tanksynth.design, so
# this module may be loaded while verify.rank is still initialising.
from tanksynth.analysis import rank as _rank
from tanksynth.analysis.symbolic import jacobian

__all__ = [
    "Domain",
    "domain_from_plant",
    "QuasiLPV",
    "quasi_lpv",
    "interval_evaluate",
    "PremiseBounds",
    "premise_bounds",
    "MAX_ENUMERATED_PREMISES",
    "TSModel",
    "ts_model",
    "ExactnessReport",
    "check_exactness",
    "VertexObservability",
    "vertex_observability",
    "SelectionRules",
    "selection_rules",
    "LipschitzBound",
    "lipschitz_bound",
    "WeightSearch",
    "search_weightings",
    "candidate_weights",
]


# --------------------------------------------------------------------------- domain
@dataclass(frozen=True)
class Domain:
    """A convex polytope of states: a box plus linear inequalities ``G x >= g``.

    Attributes
    ----------
    lower, upper : ndarray, shape (n,)
        Box bounds (state units).
    G : ndarray, shape (k, n)
    g : ndarray, shape (k,)
        Inequalities ``G x >= g`` (orderings ``h1 - h3 >= gap``).
    names : tuple of str
        State names.
    description : str
        How the domain was built (for reports).
    """

    lower: np.ndarray
    upper: np.ndarray
    G: np.ndarray
    g: np.ndarray
    names: tuple[str, ...]
    description: str = ""

    @property
    def n(self) -> int:
        """Number of states."""
        return int(self.lower.size)

    def contains(self, X: np.ndarray) -> np.ndarray:
        """Boolean mask of the rows of ``X`` (M, n) inside the domain."""
        X = np.atleast_2d(X)
        ok = np.all((X >= self.lower) & (X <= self.upper), axis=1)
        if self.G.size:
            ok &= np.all(X @ self.G.T >= self.g, axis=1)
        return ok

    def sample(self, count: int, seed: int = 0) -> np.ndarray:
        """``count`` uniform points of the domain (seeded rejection sampling).

        Parameters
        ----------
        count : int
            Number of points.
        seed : int
            Seed of the numpy generator.

        Returns
        -------
        ndarray, shape (count, n)
            State units.

        Raises
        ------
        RegionError
            If the domain is empty or too thin to sample.
        """
        rng = np.random.default_rng(seed)
        out = np.empty((0, self.n))
        for _ in range(200):
            cand = rng.uniform(self.lower, self.upper, size=(max(4 * count, 256), self.n))
            out = np.vstack([out, cand[self.contains(cand)]])
            if len(out) >= count:
                return out[:count]
        raise RegionError("the TS domain is empty or too thin to sample", key="region")

    def corners(self, limit: int = 4096, seed: int = 0) -> np.ndarray:
        """Corners of the box that satisfy the inequalities.

        All ``2^n`` corners when ``2^n <= limit``, otherwise ``limit`` seeded
        random corners.
        """
        if self.n <= int(np.log2(max(limit, 1))):
            pts = np.array(list(itertools.product(*zip(self.lower, self.upper))), dtype=float)
        else:
            bits = np.random.default_rng(seed).integers(0, 2, size=(limit, self.n)).astype(bool)
            pts = np.where(bits, self.upper, self.lower)
        return pts[self.contains(pts)]

    def linear_range(self, w: np.ndarray) -> tuple[float, float]:
        """Exact ``(min, max)`` of ``w . x`` over the (closed) domain, by LP.

        Parameters
        ----------
        w : array_like, shape (n,)
            Weights (the seed's ``lambda`` or ``gamma``).

        Returns
        -------
        (float, float)
            In state units times the weights' unit.

        Raises
        ------
        RegionError
            If the domain is empty.
        """
        w = np.asarray(w, dtype=float)
        bounds = list(zip(self.lower, self.upper))
        kw = dict(A_ub=-self.G, b_ub=-self.g) if self.G.size else {}
        vals = []
        for sgn in (1.0, -1.0):
            res = sopt.linprog(sgn * w, bounds=bounds, method="highs", **kw)
            if res.status != 0:
                raise RegionError(f"the TS domain is empty ({res.message})", key="region")
            vals.append(sgn * res.fun)
        return float(vals[0]), float(vals[1])

    def as_dict(self) -> dict:
        """JSON-friendly description."""
        return {"lower": self.lower.tolist(), "upper": self.upper.tolist(),
                "inequalities": [{"G": row.tolist(), "g": float(b)} for row, b in zip(self.G, self.g)],
                "states": list(self.names), "description": self.description}


def domain_from_plant(plant: Plant, bounds: Sequence[Sequence[float]] | None = None,
                      use_orderings: bool = True, gap: float = 0.0) -> Domain:
    """The TS domain of a plant: its region box, optionally with its orderings.

    Parameters
    ----------
    plant : Plant
    bounds : sequence of (float, float), optional
        Box ``(lower, upper)`` per state (state units); default the plant's
        region.
    use_orderings : bool
        Keep the region's flow-direction orderings ``a > b`` as ``a - b >=
        gap`` (they must be linear in the states).
    gap : float
        Minimum separation in each ordering (state units, >= 0).

    Returns
    -------
    Domain
    """
    box = plant.region.bounds if bounds is None else bounds
    box = [tuple(map(float, b)) for b in box]
    if len(box) != plant.n:
        raise DimensionError(f"{len(box)} bounds given, expected {plant.n}")
    for (lo, hi), s in zip(box, plant.states):
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise SpecError(f"bounds of {s.name} must be finite with min < max, got [{lo}, {hi}]",
                            key=f"region.{s.name}")
    if not (np.isfinite(gap) and gap >= 0):
        raise SpecError(f"ordering gap must be >= 0, got {gap}", key="ordering_gap")
    rows, rhs, text = [], [], []
    if use_orderings:
        for a, b in plant.region.orderings:
            expr = sp.expand(a - b)
            poly = sp.Poly(expr, *plant.x)
            if poly.total_degree() > 1:
                raise SpecError(f"ordering {a} > {b} is not linear in the states", key="region")
            row = [float(poly.coeff_monomial(s)) for s in plant.x]
            const = float(poly.coeff_monomial(1))
            rows.append(row)
            rhs.append(gap - const)
            text.append(f"{a} - {b} >= {gap:g}")
    names = tuple(s.name for s in plant.states)
    desc = "box " + ", ".join(f"{nm} in [{lo:g}, {hi:g}]" for nm, (lo, hi) in zip(names, box))
    desc += ("; " + "; ".join(text)) if text else "; no orderings (all flow directions)"
    G = np.array(rows, dtype=float).reshape(len(rows), plant.n)
    return Domain(np.array([b[0] for b in box]), np.array([b[1] for b in box]), G,
                  np.array(rhs, dtype=float), names, desc)


# ------------------------------------------------------------------------ quasi-LPV
@dataclass(frozen=True)
class QuasiLPV:
    """Quasi-LPV form ``dx/dt = A(z) x + B u + d`` with ``z_k = n_k(x)/(w_k . x)``.

    Attributes
    ----------
    states, inputs : tuple of sympy.Symbol
    atoms : tuple of sympy.Expr
        ``n_k(x)``, scaled so that the smallest ``|M[i, k]|`` is 1 (state
        units per second).
    weights : ndarray, shape (p, n)
        ``w_k`` (the seed's ``lambda``, ``gamma``).
    incidence : ndarray, shape (n, p)
        ``M``.
    A_lin : ndarray, shape (n, n)
        Linear part (1/s).
    B : ndarray, shape (n, m)
    d : ndarray, shape (n,)
        Constant term.
    C : ndarray, shape (q, n)
        Output matrix (the plant's output map must be linear).
    atom_states : tuple of tuple of int
        State indices each atom depends on.
    exact_incidence : sympy.Matrix
        ``M`` with exact entries (for symbolic work).
    exact_A_lin : sympy.Matrix
    input_bounds : tuple of (float, float)
        Actuator range per input (``[-1, 1]`` when the plant gives none).
    """

    states: tuple[sp.Symbol, ...]
    inputs: tuple[sp.Symbol, ...]
    atoms: tuple[sp.Expr, ...]
    weights: np.ndarray
    incidence: np.ndarray
    A_lin: np.ndarray
    B: np.ndarray
    d: np.ndarray
    C: np.ndarray
    atom_states: tuple[tuple[int, ...], ...]
    exact_incidence: sp.Matrix
    exact_A_lin: sp.Matrix
    input_bounds: tuple[tuple[float, float], ...] = ()
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def n(self) -> int:
        """Number of states."""
        return len(self.states)

    @property
    def p(self) -> int:
        """Number of premise variables."""
        return len(self.atoms)

    @property
    def premise_symbols(self) -> tuple[sp.Symbol, ...]:
        """``z1, ..., zp``."""
        return tuple(sp.Symbol(f"z{k + 1}", real=True) for k in range(self.p))

    def premise_expressions(self) -> tuple[sp.Expr, ...]:
        """``z_k(x) = n_k(x) / (w_k . x)`` with exact (rational) weights."""
        out = []
        for k, atom in enumerate(self.atoms):
            den = sum(exact(w) * s for w, s in zip(self.weights[k], self.states))
            out.append(atom / den)
        return tuple(out)

    def A_of(self, z: Sequence[float]) -> np.ndarray:
        """``A(z)`` for one premise vector (1/s)."""
        z = np.asarray(z, dtype=float).reshape(self.p)
        return self.A_lin + np.einsum("k,ik,kj->ij", z, self.incidence, self.weights)

    def A_symbolic(self, symbolic_weights: bool = False) -> sp.Matrix:
        """``A(z)`` in the premise symbols (eq. 10).

        Parameters
        ----------
        symbolic_weights : bool
            Keep the weights as symbols ``w{k}_{j}`` (for rank conditions in
            terms of ``lambda``, ``gamma``) instead of their values.
        """
        z = self.premise_symbols
        A = sp.Matrix(self.exact_A_lin)
        for k in range(self.p):
            if symbolic_weights:
                w = sp.Matrix([[sp.Symbol(f"w{k + 1}_{j + 1}", real=True) for j in range(self.n)]])
            else:
                w = sp.Matrix([[exact(v) for v in self.weights[k]]])
            A += z[k] * self.exact_incidence[:, k] * w
        return A

    def _lambdified(self, name: str, builder: Callable[[], Any]) -> Any:
        if name not in self._cache:
            self._cache[name] = builder()
        return self._cache[name]

    def atom_values(self, X: np.ndarray) -> np.ndarray:
        """``n_k(x)`` at M points: (M, n) -> (M, p)."""
        fn = self._lambdified("atoms", lambda: sp.lambdify(
            [self.states], list(self.atoms), modules=_NUMPY))
        X = np.atleast_2d(np.asarray(X, dtype=float))
        vals = fn(X.T)
        return np.column_stack([np.broadcast_to(np.asarray(v, dtype=float), (X.shape[0],))
                                for v in vals])

    def premise_values(self, X: np.ndarray) -> np.ndarray:
        """``z_k(x)`` at M points: (M, n) -> (M, p)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return self.atom_values(X) / (X @ self.weights.T)

    def with_weights(self, weights: np.ndarray) -> "QuasiLPV":
        """Same decomposition with other weights (cache of atoms kept)."""
        weights = _check_weights(np.asarray(weights, dtype=float), self.p, self.n)
        new = QuasiLPV(self.states, self.inputs, self.atoms, weights, self.incidence, self.A_lin,
                       self.B, self.d, self.C, self.atom_states, self.exact_incidence,
                       self.exact_A_lin, self.input_bounds)
        if "atoms" in self._cache:
            new._cache["atoms"] = self._cache["atoms"]
        return new

    def atoms_as_dict(self) -> list[dict]:
        """JSON-friendly list of premise definitions."""
        names = [str(s) for s in self.states]
        return [{"premise": f"z{k + 1}", "atom": str(self.atoms[k]),
                 "states": [names[j] for j in self.atom_states[k]],
                 "weights": self.weights[k].tolist(),
                 "incidence": self.incidence[:, k].tolist()} for k in range(self.p)]


def _check_weights(W: np.ndarray, p: int, n: int) -> np.ndarray:
    if W.shape != (p, n):
        raise DimensionError(f"weights must have shape ({p}, {n}), got {W.shape}")
    if not np.all(np.isfinite(W)):
        raise SpecError("weights must be finite", key="weights")
    for k in range(p):
        if not np.any(W[k]):
            raise SpecError(f"weights of z{k + 1} are all zero (degenerate case of seed 001)",
                            key=f"weights.z{k + 1}")
    return W


def quasi_lpv(plant: Plant,
              weights: Mapping[str, Sequence[float]] | np.ndarray | None = None) -> QuasiLPV:
    """Split a plant into the quasi-LPV form of seed 001 eq. (9)-(11).

    Parameters
    ----------
    plant : Plant
        Its general ``f`` (with ``sgn``/``abs``) is used, so the rewriting is
        exact for every flow direction.
    weights : mapping or ndarray, optional
        ``{"z1": [...], "z3": [...]}`` (length-n weight vectors by premise
        name) or a ``(p, n)`` array. Premises not given get the default: the
        unit vector of the state when the atom depends on one state,
        otherwise the sum of the states it depends on.

    Returns
    -------
    QuasiLPV

    Raises
    ------
    SpecError
        A term is not of the supported form (the input must enter
        linearly with constant coefficients), or bad weights.
    """
    x, u = plant.x, plant.u
    xs, us = set(x), set(u)
    n, m = plant.n, plant.m
    A_lin = sp.zeros(n, n)
    B = sp.zeros(n, m)
    d = sp.zeros(n, 1)
    found: dict[sp.Expr, dict[int, sp.Expr]] = {}
    for i, fi in enumerate(plant.f_numeric):
        for term in sp.Add.make_args(sp.expand(fi)):
            coeff, rest = term.as_independent(*x, *u, as_Add=False)
            if rest == 1:
                d[i] += coeff
            elif rest in xs:
                A_lin[i, x.index(rest)] += coeff
            elif rest in us:
                B[i, u.index(rest)] += coeff
            elif rest.free_symbols & us:
                raise SpecError(f"term {term} of equation {i + 1} is not linear in the inputs with a "
                                "constant coefficient: the TS rewriting supports f = A(z) x + B u + d",
                                key="plant")
            else:
                found.setdefault(rest, {})
                found[rest][i] = found[rest].get(i, 0) + coeff
    atoms = [a for a, eqs in found.items() if any(c != 0 for c in eqs.values())]

    def states_of(a: sp.Expr) -> tuple[int, ...]:
        return tuple(sorted(x.index(s) for s in a.free_symbols if s in xs))

    atoms.sort(key=lambda a: (min(found[a]), len(states_of(a)), states_of(a), str(a)))
    p = len(atoms)
    M_exact = sp.zeros(n, p)
    scaled = []
    for k, a in enumerate(atoms):
        scale = min((abs(c) for c in found[a].values() if c != 0), key=lambda c: float(c))
        scaled.append(scale * a)
        for i, c in found[a].items():
            M_exact[i, k] = sp.nsimplify(c / scale)
    atom_states = tuple(states_of(a) for a in atoms)
    W = np.zeros((p, n))
    for k, st in enumerate(atom_states):
        W[k, list(st)] = 1.0
    if weights is not None:
        if isinstance(weights, Mapping):
            for key, vec in weights.items():
                if not (isinstance(key, str) and key.startswith("z") and key[1:].isdigit()
                        and 1 <= int(key[1:]) <= p):
                    raise SpecError(f"unknown premise {key!r}; expected one of "
                                    + ", ".join(f"z{k + 1}" for k in range(p)), key=f"weights.{key}")
                arr = np.asarray(vec, dtype=float).reshape(-1) if _numeric_list(vec) else None
                if arr is None or arr.size != n:
                    raise SpecError(f"expected {n} numbers (one weight per state)",
                                    key=f"weights.{key}")
                W[int(key[1:]) - 1] = arr
        else:
            W = np.asarray(weights, dtype=float)
    W = _check_weights(W, p, n)
    C_sym = jacobian(plant.h_numeric, x)
    if any(e.free_symbols for e in C_sym):
        raise SpecError("the output map is not linear in the states: the observer LMI needs y = C x",
                        key="plant.outputs")
    f64 = lambda Mx: np.array(Mx.evalf(), dtype=float)  # noqa: E731
    return QuasiLPV(tuple(x), tuple(u), tuple(scaled), W, f64(M_exact).reshape(n, p),
                    f64(A_lin).reshape(n, n), f64(B).reshape(n, m), f64(d).reshape(n),
                    f64(C_sym).reshape(plant.q, n), atom_states, M_exact, A_lin,
                    _input_box(plant))


def _input_box(plant: Plant) -> tuple[tuple[float, float], ...]:
    """Finite actuator box of a plant (``[-1, 1]`` where a limit is infinite)."""
    lim = np.asarray(plant.input_limits, dtype=float).reshape(plant.m, 2)
    return tuple((float(lo) if np.isfinite(lo) else -1.0, float(hi) if np.isfinite(hi) else 1.0)
                 for lo, hi in lim)


def _numeric_list(vec: Any) -> bool:
    return isinstance(vec, (list, tuple, np.ndarray)) and all(
        isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool) for v in vec)


# ------------------------------------------------------------------ interval tools
def _recip(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    with np.errstate(divide="ignore"):
        rlo = np.where((lo > 0) | (hi < 0), 1.0 / hi, np.where(lo == 0, 1.0 / hi, -np.inf))
        rhi = np.where((lo > 0) | (hi < 0), 1.0 / lo, np.where(hi == 0, 1.0 / lo, np.inf))
    both = (lo == 0) & (hi == 0)
    rlo = np.where(both, -np.inf, rlo)
    rhi = np.where(both, np.inf, rhi)
    zero_lo = (lo == 0) & (hi > 0)
    rhi = np.where(zero_lo, np.inf, rhi)
    zero_hi = (hi == 0) & (lo < 0)
    rlo = np.where(zero_hi, -np.inf, rlo)
    return rlo, rhi


def _mul(alo, ahi, blo, bhi):
    with np.errstate(invalid="ignore"):
        prods = np.stack([alo * blo, alo * bhi, ahi * blo, ahi * bhi])
    prods = np.where(np.isnan(prods), 0.0, prods)   # 0 * inf = 0 on extended reals
    return prods.min(axis=0), prods.max(axis=0)


def interval_evaluate(expr: sp.Expr, variables: Sequence[sp.Symbol], lo: np.ndarray,
                      hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Interval enclosure of an expression over many boxes at once.

    Natural interval extension (no outward rounding; callers widen by a
    relative 1e-12). Supports numbers, symbols, ``+``, ``*``, powers
    (integer and rational), ``Abs``, ``sign``, ``sqrt``; ``DiracDelta``
    (from differentiating ``sign``) encloses to 0, its value almost
    everywhere.

    Parameters
    ----------
    expr : sympy.Expr
    variables : sequence of sympy.Symbol, length n
    lo, hi : ndarray, shape (B, n)
        Box corners.

    Returns
    -------
    lo, hi : ndarray, shape (B,)
        Enclosure of ``expr`` on each box (``-inf``/``inf`` when unbounded).
    """
    index = {v: j for j, v in enumerate(variables)}
    count = lo.shape[0]
    cache: dict = {}

    def rec(e: sp.Expr):
        if e in cache:
            return cache[e]
        if e.is_Symbol:
            if e not in index:
                raise TanksynthError(f"interval evaluation: free symbol {e}")
            out = (lo[:, index[e]], hi[:, index[e]])
        elif e.is_number:
            v = float(e)
            out = (np.full(count, v), np.full(count, v))
        elif e.is_Add:
            parts = [rec(a) for a in e.args]
            out = (sum(p[0] for p in parts), sum(p[1] for p in parts))
        elif e.is_Mul:
            a = rec(e.args[0])
            for arg in e.args[1:]:
                a = _mul(*a, *rec(arg))
            out = a
        elif e.is_Pow:
            base, ex = e.args
            blo, bhi = rec(base)
            if ex.is_Integer:
                k = int(ex)
                if k < 0:
                    blo, bhi = _recip(blo, bhi)
                    k = -k
                if k % 2 == 0:
                    a, b = blo ** k, bhi ** k
                    inside = (blo < 0) & (bhi > 0)
                    out = (np.where(inside, 0.0, np.minimum(a, b)), np.maximum(a, b))
                else:
                    out = (blo ** k, bhi ** k)
            elif ex.is_Rational or ex.is_number:
                r = float(ex)
                blo = np.maximum(blo, 0.0)
                bhi = np.maximum(bhi, 0.0)
                with np.errstate(divide="ignore"):
                    a, b = blo ** r, bhi ** r
                out = (a, b) if r > 0 else (b, a)
            else:
                raise TanksynthError(f"interval evaluation: symbolic exponent in {e}")
        elif isinstance(e, sp.Abs):
            a, b = rec(e.args[0])
            out = (np.where(a >= 0, a, np.where(b <= 0, -b, 0.0)),
                   np.where(a >= 0, b, np.where(b <= 0, -a, np.maximum(-a, b))))
        elif isinstance(e, sp.sign):
            a, b = rec(e.args[0])
            out = (np.sign(a), np.sign(b))
        elif isinstance(e, sp.DiracDelta):
            out = (np.zeros(count), np.zeros(count))
        else:
            raise TanksynthError(f"interval evaluation does not support {type(e).__name__} in {e}")
        cache[e] = out
        return out

    a, b = rec(expr if isinstance(expr, sp.Basic) else sp.Float(float(expr)))
    a = np.where(np.isnan(a), -np.inf, a)
    b = np.where(np.isnan(b), np.inf, b)
    return np.asarray(a, dtype=float) * np.ones(count), np.asarray(b, dtype=float) * np.ones(count)


def _box_feasible(domain: Domain, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    if not domain.G.size:
        return np.ones(lo.shape[0], dtype=bool)
    Gp, Gm = np.maximum(domain.G, 0), np.minimum(domain.G, 0)
    best = lo @ Gm.T + hi @ Gp.T            # max of G x over each box
    return np.all(best >= domain.g - 1e-15, axis=1)


def _split(lo: np.ndarray, hi: np.ndarray, width: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    rel = (hi - lo) / width
    dim = np.argmax(rel, axis=1)
    mid = 0.5 * (lo[np.arange(len(lo)), dim] + hi[np.arange(len(lo)), dim])
    lo2, hi1 = lo.copy(), hi.copy()
    hi1[np.arange(len(lo)), dim] = mid
    lo2[np.arange(len(lo)), dim] = mid
    return np.vstack([lo, lo2]), np.vstack([hi1, hi])


def _branch_and_bound(upper_fn: Callable[[np.ndarray, np.ndarray], np.ndarray],
                      point_fn: Callable[[np.ndarray], np.ndarray], domain: Domain,
                      seeds: np.ndarray, rtol: float, max_boxes: int,
                      max_rounds: int) -> tuple[float, float, int, int]:
    """Maximise over the domain: guaranteed upper bound and best sampled value."""
    width = domain.upper - domain.lower
    lo, hi = domain.lower[None].copy(), domain.upper[None].copy()
    vals = point_fn(seeds) if len(seeds) else np.array([-np.inf])
    inner = float(np.max(vals[np.isfinite(vals)])) if np.any(np.isfinite(vals)) else -np.inf
    total = 0
    for rounds in range(1, max_rounds + 1):
        keep = _box_feasible(domain, lo, hi)
        lo, hi = lo[keep], hi[keep]
        up = upper_fn(lo, hi)
        total += len(lo)
        centre = 0.5 * (lo + hi)
        inside = domain.contains(centre)
        if np.any(inside):
            cv = point_fn(centre[inside])
            cv = cv[np.isfinite(cv)]
            if cv.size:
                inner = max(inner, float(cv.max()))
        outer = float(np.max(up))
        scale = max(abs(outer), abs(inner), 1e-300)
        if np.isfinite(outer) and outer - inner <= rtol * scale:
            return outer, inner, total, rounds
        cand = up >= inner
        lo, hi, up = lo[cand], hi[cand], up[cand]
        if 2 * len(lo) > max_boxes:
            order = np.argsort(-up)
            take = order[: max_boxes // 2]
            rest = order[max_boxes // 2:]
            l2, h2 = _split(lo[take], hi[take], width)
            lo, hi = np.vstack([l2, lo[rest]]), np.vstack([h2, hi[rest]])
        else:
            lo, hi = _split(lo, hi, width)
    up = upper_fn(lo[_box_feasible(domain, lo, hi)], hi[_box_feasible(domain, lo, hi)])
    return float(np.max(up)), inner, total, max_rounds


# ---------------------------------------------------------------------- bounds
@dataclass(frozen=True)
class PremiseBounds:
    """Bounds ``z_k in [lower_k, upper_k]`` of the premise variables (eq. 13).

    Attributes
    ----------
    lower, upper : ndarray, shape (p,)
        ``z_k2 = min`` and ``z_k1 = max`` used to build the TS model.
    method : str
        ``"interval"`` (guaranteed enclosure by interval arithmetic and
        branch-and-bound) or ``"sampling"`` (dense sampling widened by
        ``margin``).
    margin : float
        Relative widening applied (sampling), or 1e-12 (interval round-off).
    sampled_lower, sampled_upper : ndarray, shape (p,)
        Extremes found at sample points (inner estimates).
    detail : dict
        Boxes used, rounds, gaps, denominators' ranges (from LP).
    """

    lower: np.ndarray
    upper: np.ndarray
    method: str
    margin: float
    sampled_lower: np.ndarray
    sampled_upper: np.ndarray
    detail: dict

    def as_dict(self) -> dict:
        """JSON-friendly summary."""
        return {"lower": self.lower.tolist(), "upper": self.upper.tolist(), "method": self.method,
                "method_text": ("interval arithmetic with branch-and-bound (guaranteed enclosure, "
                                "widened by 1e-12 relative for round-off)" if self.method == "interval"
                                else f"dense sampling widened by {self.margin:g} of the sampled "
                                     "range on each side (not guaranteed)"),
                "margin": self.margin, "sampled_lower": self.sampled_lower.tolist(),
                "sampled_upper": self.sampled_upper.tolist(), **self.detail}


def _denominator_ranges(qlpv: QuasiLPV, domain: Domain) -> list[tuple[float, float]]:
    out = []
    for k in range(qlpv.p):
        lo, hi = domain.linear_range(qlpv.weights[k])
        if lo <= 0 <= hi:
            raise SpecError(
                f"premise z{k + 1} is unbounded on the domain: its weighted sum "
                f"{' + '.join(f'{w:g}*{s}' for w, s in zip(qlpv.weights[k], qlpv.states) if w)} "
                f"takes values in [{lo:.4g}, {hi:.4g}], which contains 0 (seed 001 assumes it never "
                "vanishes; choose other weights or a smaller region)", key=f"weights.z{k + 1}")
        out.append((lo, hi))
    return out


def premise_bounds(qlpv: QuasiLPV, domain: Domain, method: str = "interval", samples: int = 20000,
                   margin: float = 0.01, seed: int = 0, rtol: float = 1e-3,
                   max_boxes: int = 4096, max_rounds: int = 30) -> PremiseBounds:
    """Bounds of the premise variables over the domain.

    Parameters
    ----------
    qlpv : QuasiLPV
    domain : Domain
    method : {"interval", "sampling"}
        Guaranteed interval enclosure (branch-and-bound until the gap to
        the best sampled value is below ``rtol``) or dense sampling widened
        by ``margin``.
    samples : int
        Sample points (both methods use them; sampling relies on them).
    margin : float
        Relative widening of the sampled range for ``"sampling"`` (>= 0).
    seed : int
        Seed of the sampler.
    rtol : float
        Relative gap at which branch-and-bound stops.
    max_boxes, max_rounds : int
        Limits of branch-and-bound.

    Returns
    -------
    PremiseBounds

    Raises
    ------
    SpecError
        A weighted sum ``w . x`` vanishes on the domain (premise unbounded)
        or the enclosure stays infinite.
    """
    if method not in ("interval", "sampling"):
        raise SpecError(f"unknown bounds method {method!r}; expected 'interval' or 'sampling'",
                        key="bounds")
    if not (np.isfinite(margin) and margin >= 0):
        raise SpecError(f"bounds margin must be >= 0, got {margin}", key="bounds_margin")
    dens = _denominator_ranges(qlpv, domain)
    pts = np.vstack([domain.sample(samples, seed), domain.corners()])
    Z = qlpv.premise_values(pts)
    smin, smax = Z.min(axis=0), Z.max(axis=0)
    detail: dict = {"samples": int(len(pts)),
                    "weighted_sum_ranges": [list(r) for r in dens]}
    if method == "sampling":
        span = smax - smin
        lower, upper = smin - margin * span, smax + margin * span
        return PremiseBounds(lower, upper, "sampling", float(margin), smin, smax, detail)
    exprs = qlpv.premise_expressions()
    lower, upper = np.empty(qlpv.p), np.empty(qlpv.p)
    info = []
    for k, e in enumerate(exprs):
        fn = sp.lambdify([qlpv.states], e, modules=_NUMPY)

        def point(X, fn=fn, sign=1.0):
            return sign * np.broadcast_to(np.asarray(fn(X.T), dtype=float), (len(X),))

        up = _branch_and_bound(lambda lo, hi, e=e: interval_evaluate(e, qlpv.states, lo, hi)[1],
                               point, domain, pts, rtol, max_boxes, max_rounds)
        dn = _branch_and_bound(lambda lo, hi, e=e: -interval_evaluate(e, qlpv.states, lo, hi)[0],
                               lambda X, fn=fn: point(X, fn, -1.0), domain, pts, rtol, max_boxes,
                               max_rounds)
        if not (np.isfinite(up[0]) and np.isfinite(dn[0])):
            raise SpecError(f"premise z{k + 1} = {e} has no finite interval enclosure on the domain",
                            key=f"weights.z{k + 1}")
        hi_k, lo_k = up[0], -dn[0]
        pad = 1e-12 * max(abs(hi_k), abs(lo_k), 1e-300)
        upper[k], lower[k] = hi_k + pad, lo_k - pad
        info.append({"premise": f"z{k + 1}", "boxes": up[2] + dn[2], "rounds": [up[3], dn[3]],
                     "gap_upper": up[0] - up[1], "gap_lower": dn[0] - dn[1]})
        smin[k] = min(smin[k], -dn[1])
        smax[k] = max(smax[k], up[1])
    detail["branch_and_bound"] = info
    return PremiseBounds(lower, upper, "interval", 1e-12, smin, smax, detail)


# ---------------------------------------------------------------------- TS model
#: Above this many premise variables the 2^p vertices are not enumerated.
MAX_ENUMERATED_PREMISES = 12


@dataclass(frozen=True)
class TSModel:
    """Takagi-Sugeno multiple model (seed 001 eq. 12-16).

    Attributes
    ----------
    qlpv : QuasiLPV
    bounds : PremiseBounds
    domain : Domain
    sigmas : tuple of tuple of int
        ``sigma_i`` of Table I (1 = maximum ``z_k1``, 2 = minimum ``z_k2``);
        empty when the vertices are not enumerated.
    A : ndarray, shape (r, n, n), or None
        Vertex matrices ``A_i`` (1/s); None when ``p`` exceeds
        `MAX_ENUMERATED_PREMISES` (``2^p`` matrices would not fit: tank
        networks).
    B : ndarray, shape (n, m)
        ``B_i`` (all equal here).
    d : ndarray, shape (n,)
    C : ndarray, shape (q, n)
    A0 : ndarray, shape (n, n)
        Mean vertex matrix (eq. 19), 1/s. As ``A(z)`` is affine in ``z``, it
        equals ``A`` at the midpoints of the premise bounds, which is how it
        is computed when the vertices are not enumerated.
    """

    qlpv: QuasiLPV
    bounds: PremiseBounds
    domain: Domain
    sigmas: tuple[tuple[int, ...], ...]
    A: np.ndarray | None
    B: np.ndarray
    d: np.ndarray
    C: np.ndarray
    A0: np.ndarray

    @property
    def r(self) -> int:
        """Number of sub-models ``2^p``."""
        return 2 ** self.qlpv.p

    @property
    def enumerated(self) -> bool:
        """True when the vertex matrices are stored."""
        return self.A is not None

    @property
    def B0(self) -> np.ndarray:
        """Mean input matrix (all ``B_i`` are equal)."""
        return self.B

    def vertex(self, sigma: Sequence[int]) -> np.ndarray:
        """``A_i`` for one ``sigma`` (1 = max, 2 = min per premise), 1/s."""
        sigma = tuple(int(v) for v in sigma)
        if len(sigma) != self.qlpv.p or not set(sigma) <= {1, 2}:
            raise DimensionError(f"sigma must have {self.qlpv.p} entries in {{1, 2}}")
        return self.qlpv.A_of([self.bounds.upper[k] if s == 1 else self.bounds.lower[k]
                               for k, s in enumerate(sigma)])

    def partitions(self, X: np.ndarray) -> np.ndarray:
        """``F_k1(z_k(x))`` at M points: (M, n) -> (M, p) (eq. 12)."""
        Z = self.qlpv.premise_values(X)
        span = self.bounds.upper - self.bounds.lower
        safe = np.where(span > 0, span, 1.0)
        return np.where(span > 0, (Z - self.bounds.lower) / safe, 1.0)

    def memberships(self, X: np.ndarray) -> np.ndarray:
        """``mu_i(x)`` at M points: (M, n) -> (M, r) (eq. 14, Table I order).

        Raises
        ------
        TanksynthError
            When the vertices are not enumerated (``p`` too large).
        """
        if not self.enumerated:
            raise TanksynthError(f"2^{self.qlpv.p} memberships are not enumerated; use partitions()")
        F1 = self.partitions(X)
        F = np.stack([F1, 1.0 - F1], axis=2)           # (M, p, 2)
        mu = np.ones((F1.shape[0], self.r))
        for i, sig in enumerate(self.sigmas):
            for k, s in enumerate(sig):
                mu[:, i] *= F[:, k, s - 1]
        return mu

    def rhs(self, X: np.ndarray, U: np.ndarray) -> np.ndarray:
        """``sum_i mu_i (A_i x + B_i u) + d`` at M points (eq. 16).

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units).
        U : ndarray, shape (M, m)
            Inputs (input units).

        Returns
        -------
        ndarray, shape (M, n)
            State units per second.
        """
        X = np.atleast_2d(np.asarray(X, dtype=float))
        U = np.atleast_2d(np.asarray(U, dtype=float))
        if self.enumerated:
            mu = self.memberships(X)
            return np.einsum("mi,inj,mj->mn", mu, self.A, X) + U @ self.B.T + self.d
        # sum_i mu_i A_i = A_lin + sum_k (F_k1 z_k1 + F_k2 z_k2) M_k w_k' (products of F sum to 1)
        F1 = self.partitions(X)
        zhat = F1 * self.bounds.upper + (1.0 - F1) * self.bounds.lower
        q = self.qlpv
        return (X @ q.A_lin.T + (zhat * (X @ q.weights.T)) @ q.incidence.T + U @ self.B.T + self.d)

    def as_dict(self) -> dict:
        """JSON-friendly description (premises, bounds, vertices)."""
        small = self.enumerated and self.r <= 256
        return {"premises": self.qlpv.atoms_as_dict(), "bounds": self.bounds.as_dict(),
                "domain": self.domain.as_dict(), "r": self.r, "vertices_enumerated": self.enumerated,
                "sigmas": [list(s) for s in self.sigmas] if small else None,
                "A_vertices": self.A.tolist() if small else None, "A0": self.A0.tolist(),
                "B": self.B.tolist(), "d": self.d.tolist(), "C": self.C.tolist()}


def ts_model(qlpv: QuasiLPV, domain: Domain, bounds: PremiseBounds | None = None,
             **bound_options: Any) -> TSModel:
    """Build the ``2^p`` vertex TS model from a quasi-LPV form.

    Parameters
    ----------
    qlpv : QuasiLPV
    domain : Domain
    bounds : PremiseBounds, optional
        Precomputed bounds; default `premise_bounds` with ``bound_options``.
    **bound_options
        Passed to `premise_bounds` (``method``, ``samples``, ``margin``, ...).

    Returns
    -------
    TSModel
    """
    if bounds is None:
        bounds = premise_bounds(qlpv, domain, **bound_options)
    elif bound_options:
        raise TypeError(f"unexpected options with precomputed bounds: {sorted(bound_options)}")
    if qlpv.p <= MAX_ENUMERATED_PREMISES:
        sigmas = tuple(itertools.product((1, 2), repeat=qlpv.p))
        A = np.array([qlpv.A_of([bounds.upper[k] if s == 1 else bounds.lower[k]
                                 for k, s in enumerate(sig)]) for sig in sigmas])
        A0 = A.mean(axis=0)
    else:
        sigmas, A = (), None
        A0 = qlpv.A_of(0.5 * (bounds.upper + bounds.lower))
    return TSModel(qlpv, bounds, domain, sigmas, A, qlpv.B.copy(), qlpv.d, qlpv.C, A0)


# ------------------------------------------------------------------ exactness test
@dataclass(frozen=True)
class ExactnessReport:
    """Exactness of the TS model against the plant at random points.

    Attributes
    ----------
    points : int
    max_relative_error : float
        ``max |f_TS - f|_inf / |terms|_inf`` where ``|terms|`` is the size of
        the individual contributions (so cancellation near equilibria does
        not inflate it).
    max_abs_error : float
        State units/s.
    min_membership : float
    max_sum_deviation : float
        ``max |sum_i mu_i - 1|``.
    rtol : float
    passed : bool
    """

    points: int
    max_relative_error: float
    max_abs_error: float
    min_membership: float
    max_sum_deviation: float
    rtol: float
    passed: bool

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return dict(self.__dict__)


def check_exactness(ts: TSModel, plant: Plant, count: int = 5000, seed: int = 0,
                    rtol: float = 1e-10) -> ExactnessReport:
    """Compare ``sum_i mu_i (A_i x + B_i u) + d`` with ``f(x, u)`` at random points.

    ``f`` is evaluated by the plant's compiled CasADi function, independently
    of the sympy rewriting. Inputs are drawn in the actuator range (or in
    ``[-1, 1]`` when the plant gives none).

    Parameters
    ----------
    ts : TSModel
    plant : Plant
    count : int
        Number of random points of the domain.
    seed : int
    rtol : float
        Relative tolerance.

    Returns
    -------
    ExactnessReport
    """
    rng = np.random.default_rng(seed + 1)
    X = ts.domain.sample(count, seed)
    ub = _input_box(plant)
    U = rng.uniform([b[0] for b in ub], [b[1] for b in ub], size=(count, plant.m))
    f = plant.compiled.rhs(X, U)
    g = ts.rhs(X, U)
    if ts.enumerated:
        mu = ts.memberships(X)
        mmin, dev = float(mu.min()), float(np.max(np.abs(mu.sum(axis=1) - 1.0)))
    else:
        # mu_i are products of partition functions: F in [0, 1] gives mu_i >= 0, and
        # sum_i mu_i = prod_k (F_k1 + F_k2) = 1 up to round-off.
        F1 = ts.partitions(X)
        mmin = float(min(F1.min(), (1.0 - F1).min())) if F1.size else 1.0
        dev = float(np.max(np.abs(np.prod(F1 + (1.0 - F1), axis=1) - 1.0))) if F1.size else 0.0
    q = ts.qlpv
    terms = (np.abs(X @ q.A_lin.T) + np.abs(q.atom_values(X)) @ np.abs(q.incidence).T
             + np.abs(U @ q.B.T) + np.abs(q.d))
    scale = np.maximum(np.max(terms, axis=1), 1e-300)
    err = np.max(np.abs(g - f), axis=1)
    rel = float(np.max(err / scale))
    return ExactnessReport(count, rel, float(err.max()), mmin, dev, rtol,
                           bool(rel <= rtol and mmin >= 0.0 and dev <= 1e-12))


# ------------------------------------------------------------ observability / rules
@dataclass(frozen=True)
class VertexObservability:
    """Observability of every vertex pair ``(A_i, C)`` (seed 001 eq. 17).

    Attributes
    ----------
    ranks : tuple of int
    conditions : tuple of float
        Condition numbers of the observability matrices.
    unobservable : tuple of int
        Indices (1-based, Table I order) of unobservable vertices.
    symbolic : dict or None
        Factored determinant of the symbolic observability matrix of
        ``A(z)`` (n <= 4 only).
    """

    ranks: tuple[int, ...]
    conditions: tuple[float, ...]
    unobservable: tuple[int, ...]
    symbolic: dict | None = None

    @property
    def all_observable(self) -> bool:
        """Every vertex observable."""
        return not self.unobservable

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"ranks": list(self.ranks), "conditions": list(self.conditions),
                "unobservable_vertices": list(self.unobservable),
                "all_observable": self.all_observable, "symbolic": self.symbolic}


def vertex_observability(ts: TSModel, C: np.ndarray | None = None, symbolic: bool = True,
                         sample_vertices: int = 64) -> VertexObservability:
    """Kalman rank of every vertex (uses `tanksynth.analysis.rank`).

    Parameters
    ----------
    ts : TSModel
    C : ndarray, optional
        Output matrix; default the plant's.
    symbolic : bool
        Also factor ``det O(z)`` of ``A(z)`` symbolically (only if n <= 4).
    sample_vertices : int
        When the vertices are not enumerated, how many (seeded, random) are
        checked; ``unobservable`` then indexes that sample.
    """
    C = ts.C if C is None else np.atleast_2d(np.asarray(C, dtype=float))
    ranks, conds, bad = [], [], []
    if ts.enumerated:
        vertices = ts.A
    else:   # 2^p too many: a seeded sample of vertices (reported as such)
        rng = np.random.default_rng(0)
        vertices = np.array([ts.vertex(rng.integers(1, 3, ts.qlpv.p))
                             for _ in range(sample_vertices)])
    for i, Ai in enumerate(vertices):
        res = _rank.observability_rank(Ai, C)
        ranks.append(res.rank)
        conds.append(res.condition_number)
        if not res.full:
            bad.append(i + 1)
    sym = None
    if symbolic and ts.qlpv.n <= 4:
        C_exact = sp.Matrix([[exact(v) for v in row] for row in C])
        res = _rank.symbolic_observability(ts.qlpv.A_symbolic(), C_exact, ts.qlpv.premise_symbols)
        sym = res.as_dict()
    return VertexObservability(tuple(ranks), tuple(conds), tuple(bad), sym)


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
    f = sp.Matrix(qlpv.exact_A_lin) * sp.Matrix(qlpv.states)
    f += qlpv.exact_incidence * sp.Matrix(qlpv.atoms)
    return jacobian(f, qlpv.states)


_NUMPY = [{"DiracDelta": lambda a: 0 * a}, "numpy"]


def _jacobian_function(q: QuasiLPV, J: sp.Matrix) -> Callable[[np.ndarray], np.ndarray]:
    """Vectorised ``df/dx`` at M points: (M, n) -> (M, n, n); inf where singular."""
    fns = {(i, j): sp.lambdify([q.states], J[i, j], modules=_NUMPY)
           for i in range(q.n) for j in range(q.n) if J[i, j].free_symbols}

    def jac_at(P: np.ndarray) -> np.ndarray:
        out = np.empty((len(P), q.n, q.n))
        with np.errstate(divide="ignore", invalid="ignore"):
            for i in range(q.n):
                for j in range(q.n):
                    fn = fns.get((i, j))
                    out[:, i, j] = float(J[i, j]) if fn is None else np.broadcast_to(
                        np.asarray(fn(P.T), dtype=float), (len(P),))
        return out

    return jac_at


def _prod(a: float, b: float) -> float:
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
    jac_at = _jacobian_function(q, J)
    A0 = ts.A0
    with np.errstate(divide="ignore", invalid="ignore"):
        D = jac_at(X) - A0
    finite = np.all(np.isfinite(D), axis=(1, 2))
    sampled = float(np.max(np.linalg.norm(D[finite], 2, axis=(1, 2)))) if finite.any() else np.inf
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
        entries = [(i, j, J[i, j]) for i in range(q.n) for j in range(q.n)]

        def upper(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
            tot = np.zeros(len(lo))
            for i, j, e in entries:
                a, b = interval_evaluate(e, q.states, lo, hi)
                a, b = a - A0[i, j], b - A0[i, j]
                tot = tot + np.maximum(np.abs(a), np.abs(b)) ** 2
            return np.sqrt(tot)

        def point(P: np.ndarray) -> np.ndarray:
            with np.errstate(divide="ignore", invalid="ignore"):
                Dp = jac_at(P) - A0
            v = np.sqrt(np.sum(Dp ** 2, axis=(1, 2)))
            return np.where(np.isfinite(v), v, np.inf)

        outer, inner, boxes, rounds = _branch_and_bound(upper, point, ts.domain, X, rtol, max_boxes,
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
            fn = sp.lambdify([q.states], de, modules=_NUMPY)
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
    terms, printed = 0.0, 0.0
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
        printed += _prod(np.linalg.norm(Abar[i], 2), omega[i]) + _prod(np.linalg.norm(ts.B, 2) * phi,
                                                                        tau[i])
    value = float(terms) if np.isfinite(terms) else np.inf
    return LipschitzBound(value, form, "sampling", sampled,
                          {"tau": tau.tolist(), "omega": omega.tolist(), "phi": phi,
                           "margin": margin, "samples": int(len(X)),
                           "value_with_printed_B_term": float(printed),
                           "text": "seed 001 eq. (27) with tau_i, omega_i from sampled gradient norms "
                                   f"times (1 + {margin:g}); the input term uses Bbar_i = B_i - B0 "
                                   "(sum_i (mu_i(x) - mu_i(xhat)) = 0), the printed form with B_i "
                                   "is in value_with_printed_B_term"})


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
        Observer LMI options (`tanksynth.design.lmi.observer_lmi`).
    bounds_method, samples, bounds_margin, seed
        Premise bounds options (sampling is the fast default here).
    rtol : float
        Relative accuracy of each ``psi_max``.

    Returns
    -------
    WeightSearch
    """
    from tanksynth.design.lmi import ObserverLMIProblem, bisect_feasible

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
    prob = ObserverLMIProblem(qlpv.n, C, variant, kappa, solver=solver)
    Xs = np.vstack([domain.sample(samples, seed), domain.corners()])
    J = None
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
        if J is None:
            J = _jacobian_function(qlpv, _jacobian_exprs(qlpv))(Xs)
        D = J - A0
        lip = (float(np.max(np.linalg.norm(D, 2, axis=(1, 2)))) if np.all(np.isfinite(D))
               else float("inf"))
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
