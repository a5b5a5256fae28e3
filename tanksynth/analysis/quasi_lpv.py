"""Operating domain and quasi-LPV form of a plant (seed 001 eq. 9-11).

The plant's vector field (parameters substituted) is split, term by term,
into::

    f(x, u) = A_lin x + sum_k M[:, k] n_k(x) + B u + d

where the ``n_k`` ("atoms") are the distinct nonlinear functions of the
state (for the three-tank: the three Torricelli flows divided by the tank
section) and ``M`` is their constant incidence matrix. Following seed 001
(eq. 7-8), every atom is divided by a weighted sum of the states,
``z_k(x) = n_k(x) / (w_k . x)``, which gives the quasi-LPV form (eq. 9-11)::

    dx/dt = A(z) x + B u + d,     A(z) = A_lin + sum_k z_k M[:, k] w_k'.

The premise bounds and the multiple model built on this form are
`tanksynth.analysis.premise_bounds` and `tanksynth.analysis.takagi_sugeno`.
"""

from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import numpy.typing as npt
import sympy as sp

from tanksynth.analysis.symbolic import canonical_form, form_symbol, jacobian
from tanksynth.errors import DimensionError, RegionError, SpecError, TanksynthError
from tanksynth.plants.base import Plant, exact

#: ``modules`` of every `sympy.lambdify` of the TS analysis: numpy, with the derivative of
#: abs/sign (DiracDelta) zero away from the kinks.
LAMBDIFY_MODULES = [{"DiracDelta": lambda a: 0 * a}, "numpy"]


#: Results of `Domain.sample`, `Domain.linear_range` and `lambdify_cached`, keyed by the
#: domain's numbers (and the sample size and seed, the weights, the expression): the TS
#: weighting search asks for the same ones over and over (`recall`, `remember`). `clear_cache`
#: empties it; at most `_CACHE_SIZE` entries (then emptied).
_CACHE: dict[tuple, Any] = {}
_CACHE_SIZE = 1024


def recall(key: tuple) -> Any:
    """The analysis cache's value for ``key`` (see `remember`), or None.

    Parameters
    ----------
    key : tuple
        Hashable key: what was computed and from which numbers.
    """
    return _CACHE.get(key)


def remember(key: tuple, value: Any) -> Any:
    """Keep ``value`` in the analysis cache under ``key`` (bounded; `clear_cache` empties it).

    Parameters
    ----------
    key : tuple
        Hashable key: what was computed and from which numbers (a domain's, a plant's).
    value : object
        The result (treated as read-only by everyone who recalls it).

    Returns
    -------
    object
        ``value``.
    """
    if len(_CACHE) >= _CACHE_SIZE:
        _CACHE.clear()
    _CACHE[key] = value
    return value


def clear_cache() -> int:
    """Forget the cached domain samples, LP ranges and lambdified functions.

    Returns
    -------
    int
        Number of entries dropped.
    """
    count = len(_CACHE)
    _CACHE.clear()
    return count


def lambdify_cached(args: Sequence[Any], expr: Any, **kw: Any) -> Callable:
    """`sympy.lambdify` of ``expr`` in ``args`` (modules `LAMBDIFY_MODULES`), compiled once per expression.

    Parameters
    ----------
    args : sequence
        The lambdified function's arguments (as for `sympy.lambdify`).
    expr : sympy expression or sequence of them
    **kw
        Other `sympy.lambdify` options (hashable values).

    Returns
    -------
    callable
    """
    key = ("lambdify", _freeze(args), _freeze(expr), tuple(sorted(kw.items())))
    fn = recall(key)
    if fn is None:
        fn = remember(key, sp.lambdify(args, expr, modules=LAMBDIFY_MODULES, **kw))
    return fn


class FormEvaluator:
    """Many expressions of the states evaluated at M points, one compiled function per form.

    Expressions that differ only by which states they use (one tank type,
    another instance: ``c sqrt(h1)`` and ``c sqrt(h3)``) share one renamed
    form (`tanksynth.analysis.symbolic.canonical_form`); each form is compiled
    once (`lambdify_cached`) and evaluated on the columns of all its
    instances at once. A network of n tanks of a few types compiles a few
    small functions instead of one function of n expressions.

    Parameters
    ----------
    exprs : sequence of sympy.Expr
        Functions of ``states`` only (other free symbols: `TanksynthError`).
    states : sequence of sympy.Symbol
    """

    def __init__(self, exprs: Sequence[sp.Expr], states: Sequence[sp.Symbol]) -> None:
        index = {s: j for j, s in enumerate(states)}
        groups: dict[sp.Expr, list[tuple[int, tuple[int, ...]]]] = {}
        arity: dict[sp.Expr, tuple[sp.Symbol, ...]] = {}
        for k, e in enumerate(exprs):
            e = sp.sympify(e, strict=True)  # sympy expressions (numbers at most), never text
            if e.free_symbols - set(index):
                raise TanksynthError(f"expression {e} depends on symbols other than the states")
            form, _, own = canonical_form(e, index)
            groups.setdefault(form, []).append((k, tuple(index[s] for s in own)))
            arity[form] = tuple(form_symbol(i, s) for i, s in enumerate(own))
        self.count = len(exprs)
        self._groups = []
        for form, members in groups.items():
            fn = lambdify_cached([list(arity[form])], form)
            rows = np.array([k for k, _ in members], dtype=int)
            cols = np.array([c for _, c in members], dtype=int).reshape(len(members), len(arity[form]))
            # (M, n) -> (arity, M, members): the column indices transposed once here, so that a
            # call takes the arguments with one fancy index (`X[:, cols.T]` is `X[:, cols]`
            # transposed, the same numbers)
            self._groups.append((fn, rows, np.ascontiguousarray(cols.T)))

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """Values at the points ``X`` (M, n): (M, count); NaN/inf where undefined (no warning)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        M = X.shape[0]
        out = np.empty((M, self.count))
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            for fn, rows, cols_t in self._groups:
                values = np.asarray(fn(X[:, cols_t].transpose(1, 0, 2)), dtype=float)  # (arity, M, members)
                out[:, rows] = values if values.shape == (M, len(rows)) else np.broadcast_to(
                    values, (M, len(rows)))
        return out


def _freeze(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v) for v in value)
    if isinstance(value, sp.MatrixBase):
        return ("matrix", value.shape, tuple(value))
    return value

__all__ = ["Domain", "domain_from_plant", "QuasiLPV", "quasi_lpv", "clear_cache", "recall", "remember",
           "input_box", "LAMBDIFY_MODULES", "lambdify_cached",
           "FormEvaluator"]


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
        """Boolean mask of the rows of ``X`` (M, n) inside the domain.

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units, m).
        """
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
        key = ("sample", self.cache_key(), int(count), int(seed))
        hit = recall(key)
        if hit is not None:
            return hit.copy()
        rng = np.random.default_rng(seed)
        out = np.empty((0, self.n))
        for _ in range(200):
            cand = rng.uniform(self.lower, self.upper, size=(max(4 * count, 256), self.n))
            out = np.vstack([out, cand[self.contains(cand)]])
            if len(out) >= count:
                remember(key, out[:count].copy())
                return out[:count]
        raise RegionError("the TS domain is empty or too thin to sample", key="region")

    def cache_key(self) -> tuple:
        """The domain's numbers (bounds and constraints, as bytes), a hashable key of the
        analysis cache (`recall`, `remember`)."""
        return (self.lower.tobytes(), self.upper.tobytes(), self.G.shape, self.G.tobytes(),
                self.g.tobytes())

    def corners(self, limit: int = 4096, seed: int = 0) -> np.ndarray:
        """Corners of the box that satisfy the inequalities.

        All ``2^n`` corners when ``2^n <= limit``, otherwise ``limit`` seeded
        random corners.

        Parameters
        ----------
        limit : int, optional
            Largest number of corners returned.
        seed : int, optional
            Seed of the random corners.
        """
        if self.n <= int(np.log2(max(limit, 1))):
            pts = np.array(list(itertools.product(*zip(self.lower, self.upper))), dtype=float)
        else:
            bits = np.random.default_rng(seed).integers(0, 2, size=(limit, self.n)).astype(bool)
            pts = np.where(bits, self.upper, self.lower)
        return pts[self.contains(pts)]

    def linear_range(self, w: np.ndarray) -> tuple[float, float]:
        """Exact ``(min, max)`` of ``w . x`` over the (closed) domain, by LP (closed form for a box).

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
        import scipy.optimize as sopt  # deferred: scipy.optimize imports in ~0.15 s
        w = np.asarray(w, dtype=float)
        key = ("linear_range", self.cache_key(), w.tobytes())
        hit = recall(key)
        if hit is not None:
            return hit
        if not self.G.size:     # a box: the extremes are at its corners, no LP needed
            lo = float(np.sum(np.where(w > 0, w * self.lower, w * self.upper)))
            hi = float(np.sum(np.where(w > 0, w * self.upper, w * self.lower)))
            return remember(key, (lo, hi))
        bounds = list(zip(self.lower, self.upper))
        kw = dict(A_ub=-self.G, b_ub=-self.g)
        vals = []
        for sgn in (1.0, -1.0):
            res = sopt.linprog(sgn * w, bounds=bounds, method="highs", **kw)
            if res.status != 0:
                raise RegionError(f"the TS domain is empty ({res.message})", key="region")
            vals.append(sgn * res.fun)
        return remember(key, (float(vals[0]), float(vals[1])))

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
        """``z_k(x) = n_k(x) / (w_k . x)`` with exact (rational) weights (built once)."""
        if "premise_expressions" not in self._cache:
            out = []
            for k, atom in enumerate(self.atoms):
                den = sum(exact(w) * s for w, s in zip(self.weights[k], self.states) if w != 0)
                out.append(atom / den)
            self._cache["premise_expressions"] = tuple(out)
        return self._cache["premise_expressions"]

    def A_of(self, z: npt.ArrayLike) -> np.ndarray:
        """``A(z)`` for one premise vector (1/s).

        Parameters
        ----------
        z : array_like, shape (p,)
            Premise values, one per atom (their own units).
        """
        premises = np.asarray(z, dtype=float).reshape(self.p)
        return self.A_lin + np.einsum("k,ik,kj->ij", premises, self.incidence, self.weights)

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

    def atom_evaluator(self) -> "FormEvaluator":
        """The atoms ``n_k(x)`` compiled once (`FormEvaluator`): (M, n) -> (M, p), no warning
        where they are undefined (NaN), unlike `atom_values`."""
        if "atoms" not in self._cache:
            self._cache["atoms"] = FormEvaluator(self.atoms, self.states)
        return self._cache["atoms"]

    def atom_values(self, X: np.ndarray) -> np.ndarray:
        """``n_k(x)`` at M points: (M, n) -> (M, p).

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units, m).
        """
        fn = self.atom_evaluator()
        X = np.atleast_2d(np.asarray(X, dtype=float))
        out = fn(X)
        if np.isfinite(out).all():        # the common case: nothing to warn about
            return out
        bad = ~np.all(np.isfinite(out), axis=1) & np.all(np.isfinite(X), axis=1)
        if bad.any():
            from tanksynth.errors import TanksynthWarning

            k = int(np.flatnonzero(bad)[0])
            point = ", ".join(f"{s} = {v:.4g}" for s, v in zip(self.states, X[k]))
            warnings.warn(TanksynthWarning(
                f"Takagi-Sugeno premises undefined (NaN) at {int(bad.sum())} of {X.shape[0]} "
                f"point(s), first at {point}: the state left the domain where the premises are "
                "defined (e.g. a negative level under a square root)"), stacklevel=2)
        return out

    def premise_values(self, X: np.ndarray) -> np.ndarray:
        """``z_k(x)`` at M points: (M, n) -> (M, p).

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units, m).
        """
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return self.atom_values(X) / (X @ self.weights.T)

    def with_weights(self, weights: np.ndarray) -> "QuasiLPV":
        """Same decomposition with other weights (cache of atoms kept).

        Parameters
        ----------
        weights : ndarray
            The new weights of the decomposition (dimensionless).
        """
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
    index = {s: j for j, s in enumerate((*x, *u))}
    split: dict[sp.Expr, list[tuple[sp.Expr, sp.Expr]]] = {}   # per row form (one per tank type)
    for i, fi in enumerate(plant.f_numeric):
        form, back, own = canonical_form(fi, index)
        if form not in split:
            names = [form_symbol(k, s) for k, s in enumerate(own)]
            split[form] = [term.as_independent(*names, as_Add=False)
                           for term in sp.Add.make_args(sp.expand(form))]
        for coeff, rest in split[form]:
            coeff, rest = coeff.xreplace(back), rest.xreplace(back)
            if rest == 1:
                d[i] += coeff
            elif rest in xs:
                A_lin[i, x.index(rest)] += coeff
            elif rest in us:
                B[i, u.index(rest)] += coeff
            elif rest.free_symbols & us:
                term = coeff * rest
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
    if any(e.free_symbols for e in C_sym.todok().values()):
        raise SpecError("the output map is not linear in the states: the observer LMI needs y = C x",
                        key="plant.outputs")
    f64 = _float_matrix
    return QuasiLPV(tuple(x), tuple(u), tuple(scaled), W, f64(M_exact).reshape(n, p),
                    f64(A_lin).reshape(n, n), f64(B).reshape(n, m), f64(d).reshape(n),
                    f64(C_sym).reshape(plant.q, n), atom_states, M_exact, A_lin,
                    input_box(plant))


def _float_matrix(Mx: sp.Matrix) -> np.ndarray:
    """``np.array(Mx.evalf(), dtype=float)``, evaluating the nonzero entries only."""
    out = np.zeros(Mx.shape)
    for (i, j), v in Mx.todok().items():
        out[i, j] = float(v.evalf())
    return out


def input_box(plant: Plant) -> tuple[tuple[float, float], ...]:
    """Finite actuator box of a plant: its input limits, ``-1`` or ``1`` where a limit is infinite.

    Parameters
    ----------
    plant : Plant
        The plant (its ``input_limits``, input units).

    Returns
    -------
    tuple of (float, float)
        ``(low, high)`` of each input (input units).
    """
    lim = np.asarray(plant.input_limits, dtype=float).reshape(plant.m, 2)
    return tuple((float(lo) if np.isfinite(lo) else -1.0, float(hi) if np.isfinite(hi) else 1.0)
                 for lo, hi in lim)


def _numeric_list(vec: Any) -> bool:
    return isinstance(vec, (list, tuple, np.ndarray)) and all(
        isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool) for v in vec)

