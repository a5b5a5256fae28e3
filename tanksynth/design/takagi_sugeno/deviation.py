"""The deviation Takagi-Sugeno model of the PDC designs (`tanksynth.design.takagi_sugeno.pdc`).

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
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike

from tanksynth.analysis.quasi_lpv import LAMBDIFY_MODULES, Domain, QuasiLPV, lambdify_cached
from tanksynth.analysis.takagi_sugeno import vertex_memberships
from tanksynth.errors import SpecError

__all__ = ["DeviationTSModel", "deviation_ts_model", "linear_argument"]


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
    fn = sp.lambdify([states], atom, modules=LAMBDIFY_MODULES)
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
        return vertex_memberships(F1, self.sigmas)

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



def deviation_ts_model(qlpv: QuasiLPV, domain: Domain, x0: ArrayLike, u0: ArrayLike,
                       samples: int = 20001, margin: float = 1e-3) -> DeviationTSModel:
    """Exact TS model of the deviations from ``(x0, u0)`` on ``domain``.

    Parameters
    ----------
    qlpv : QuasiLPV
        Atoms and incidence of the plant (its weights are not used).
    domain : Domain
        Where the model must be exact (must contain ``x0``).
    x0 : array_like, shape (n,)
        Operating point (state units).
    u0 : array_like, shape (m,)
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
    x_op = np.asarray(x0, dtype=float).reshape(qlpv.n)
    u_op = np.asarray(u0, dtype=float).reshape(qlpv.B.shape[1])
    if not bool(domain.contains(x_op)[0]):
        raise SpecError(f"operating point {x_op.tolist()} is outside the TS domain "
                        f"({domain.description})", key="domain")
    if qlpv.p > 12:
        raise SpecError(f"{qlpv.p} premises: 2^{qlpv.p} vertices are too many for the PDC LMIs",
                        key="plant")
    forms = np.array([linear_argument(a, qlpv.states) for a in qlpv.atoms]).reshape(qlpv.p, qlpv.n)
    model = DeviationTSModel(x_op, u_op, forms, np.zeros(qlpv.p), np.zeros(qlpv.p), np.zeros(qlpv.p),
                             np.zeros(qlpv.p), np.zeros((1, qlpv.n, qlpv.n)), qlpv.B, qlpv.C, (),
                             domain, qlpv, "")
    slope0 = model._tangent()
    lo, hi, slo, shi = [], [], [], []
    for k in range(qlpv.p):
        a = forms[k]
        tmin, tmax = domain.linear_range(a)
        t0 = float(a @ x_op)
        grid = np.unique(np.concatenate([np.linspace(tmin, tmax, samples), [tmin, tmax]]))
        # the line x_op + s a covers the exact range of a . x but may leave the domain (h2 < 0 on
        # the line of h3 - h2): atom k depends on a . x only, so it alone is evaluated there
        X = x_op + np.outer(grid - t0, a / (a @ a))
        vals = _atom_on_points(qlpv, k, X)
        at0 = float(_atom_on_points(qlpv, k, x_op[None, :])[0])
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
    return DeviationTSModel(x_op, u_op, forms, lower, upper, np.array(slo), np.array(shi), A, qlpv.B,
                            qlpv.C, sigmas, domain, qlpv, method)
