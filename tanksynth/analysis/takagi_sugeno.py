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

from tanksynth.analysis import rank as _rank
from tanksynth.analysis.interval import _branch_and_bound, interval_evaluate
from tanksynth.analysis.symbolic import jacobian
from tanksynth.errors import DimensionError, RegionError, SpecError, TanksynthError
from tanksynth.plants.base import Plant, exact

#: lambdify modules: the derivative of abs/sign (DiracDelta) is zero away from the kinks.
_NUMPY = [{"DiracDelta": lambda a: 0 * a}, "numpy"]

__all__ = ["Domain", "domain_from_plant", "QuasiLPV", "quasi_lpv", "PremiseBounds", "premise_bounds",
           "MAX_ENUMERATED_PREMISES", "TSModel", "ts_model", "ExactnessReport", "check_exactness",
           "VertexObservability", "vertex_observability"]


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
