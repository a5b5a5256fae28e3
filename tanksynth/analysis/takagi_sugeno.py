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

The operating domain and the quasi-LPV form are `tanksynth.analysis.quasi_lpv`,
the premise bounds `tanksynth.analysis.premise_bounds`; their names are
importable from here.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt
import sympy as sp

from tanksynth.analysis import blas as _blas
from tanksynth.analysis import rank as _rank
from tanksynth.analysis.premise_bounds import PremiseBounds, premise_bounds
from tanksynth.analysis.quasi_lpv import Domain, QuasiLPV, domain_from_plant, input_box, quasi_lpv
from tanksynth.errors import DimensionError, TanksynthError
from tanksynth.plants.base import Plant, exact

__all__ = ["Domain", "domain_from_plant", "QuasiLPV", "quasi_lpv", "PremiseBounds", "premise_bounds",
           "MAX_ENUMERATED_PREMISES", "TSModel", "ts_model", "ExactnessReport", "check_exactness",
           "VertexObservability", "vertex_observability", "vertex_memberships"]


def vertex_memberships(F1: np.ndarray, sigmas: Sequence[Sequence[int]]) -> np.ndarray:
    """The vertex weights ``mu_i = prod_k F_k^(sigma_ik)`` from the first partitions.

    Parameters
    ----------
    F1 : ndarray, shape (M, p)
        First partition ``F_k^1`` of every premise at M points (dimensionless, in [0, 1]);
        the second is ``1 - F_k^1``.
    sigmas : sequence of sequence of int
        Per vertex, which partition (1 or 2) of each premise it takes (Table I order).

    Returns
    -------
    ndarray, shape (M, r)
        The memberships (dimensionless, summing to 1 over the vertices).
    """
    F = np.stack([F1, 1.0 - F1], axis=2)           # (M, p, 2)
    mu = np.ones((F1.shape[0], len(sigmas)))
    for i, sig in enumerate(sigmas):
        for k, s in enumerate(sig):
            mu[:, i] *= F[:, k, s - 1]
    return mu


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

    def vertex(self, sigma: Sequence[int] | npt.NDArray[np.integer]) -> np.ndarray:
        """``A_i`` for one ``sigma`` (1 = max, 2 = min per premise), 1/s.

        Parameters
        ----------
        sigma : sequence of int or ndarray of int, shape (p,)
            One index per premise: 1 for its maximum, 2 for its minimum.
        """
        sigma = tuple(int(v) for v in sigma)
        if len(sigma) != self.qlpv.p or not set(sigma) <= {1, 2}:
            raise DimensionError(f"sigma must have {self.qlpv.p} entries in {{1, 2}}")
        return self.qlpv.A_of([self.bounds.upper[k] if s == 1 else self.bounds.lower[k]
                               for k, s in enumerate(sigma)])

    def partitions(self, X: np.ndarray) -> np.ndarray:
        """``F_k1(z_k(x))`` at M points: (M, n) -> (M, p) (eq. 12).

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units, m).
        """
        Z = self.qlpv.premise_values(X)
        span = self.bounds.upper - self.bounds.lower
        safe = np.where(span > 0, span, 1.0)
        return np.where(span > 0, (Z - self.bounds.lower) / safe, 1.0)

    def memberships(self, X: np.ndarray) -> np.ndarray:
        """``mu_i(x)`` at M points: (M, n) -> (M, r) (eq. 14, Table I order).

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units, m).

        Raises
        ------
        TanksynthError
            When the vertices are not enumerated (``p`` too large).
        """
        if not self.enumerated:
            raise TanksynthError(f"2^{self.qlpv.p} memberships are not enumerated; use partitions()")
        return vertex_memberships(self.partitions(X), self.sigmas)

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
        if self.A is not None:   # the vertices are enumerated
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
                "A_vertices": self.A.tolist() if small and self.A is not None else None,
                "A0": self.A0.tolist(),
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
    ub = input_box(plant)
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
        Condition numbers of the leading Kalman blocks that decide each rank (see
        `tanksynth.analysis.rank.RankResult`; dimensionless).
    unobservable : tuple of int
        Indices (1-based, Table I order) of unobservable vertices.
    symbolic : dict or None
        Factored determinant of the symbolic observability matrix of
        ``A(z)`` (n <= 4 only).
    reason : str or None
        Why the Kalman ranks were not computed, when the answer is known
        without them (``C`` of full column rank: observable whatever ``A``);
        ``conditions`` is then empty.
    """

    ranks: tuple[int, ...]
    conditions: tuple[float, ...]
    unobservable: tuple[int, ...]
    symbolic: dict | None = None
    reason: str | None = None

    @property
    def all_observable(self) -> bool:
        """Every vertex observable."""
        return not self.unobservable

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"ranks": list(self.ranks), "conditions": list(self.conditions),
                "unobservable_vertices": list(self.unobservable),
                "all_observable": self.all_observable, "symbolic": self.symbolic,
                "reason": self.reason}


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
    n = ts.qlpv.n
    count = len(ts.A) if ts.A is not None else int(sample_vertices)
    sv = np.linalg.svd(C, compute_uv=False) if C.size else np.zeros(0)
    tol = max(C.shape) * np.finfo(float).eps * (sv[0] if sv.size else 0.0)
    if C.shape[1] == n and int(np.sum(sv > tol)) == n:
        # C x = 0 only for x = 0: the first block of the Kalman matrix already has rank n.
        return VertexObservability((n,) * count, (), (), None,
                                   f"C has full column rank {n}: (A_i, C) is observable whatever "
                                   f"A_i is; the Kalman ranks of the {count} vertices were not "
                                   f"computed")
    ranks, conds, bad = [], [], []
    if ts.A is not None:   # the vertices are enumerated
        vertices = ts.A
    else:   # 2^p too many: a seeded sample of vertices (reported as such)
        rng = np.random.default_rng(0)
        vertices = np.array([ts.vertex(rng.integers(1, 3, ts.qlpv.p))
                             for _ in range(sample_vertices)])
    with _blas.small_dense():
        for i, Ai in enumerate(vertices):
            res = _rank.observability_rank(Ai, C)
            ranks.append(res.rank)
            conds.append(res.condition_number)
            if not res.full:
                bad.append(i + 1)
    sym = None
    if symbolic and ts.qlpv.n <= 4:
        C_exact = sp.Matrix([[exact(v) for v in row] for row in C])
        symbolic_rank = _rank.symbolic_observability(ts.qlpv.A_symbolic(), C_exact,
                                                     ts.qlpv.premise_symbols)
        sym = symbolic_rank.as_dict()
    return VertexObservability(tuple(ranks), tuple(conds), tuple(bad), sym)
