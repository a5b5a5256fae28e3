"""Interval arithmetic on sympy expressions (`interval_evaluate`) and a branch-and-bound
enclosure of a function's maximum over a domain (`branch_and_bound`).

Used for guaranteed bounds of Takagi-Sugeno premise variables and Lipschitz
constants over an operating domain.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np
import sympy as sp

from tanksynth.errors import TanksynthError

if TYPE_CHECKING:
    from tanksynth.analysis.takagi_sugeno import Domain

__all__ = ["interval_evaluate", "branch_and_bound"]


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



def branch_and_bound(upper_fn: Callable[[np.ndarray, np.ndarray], np.ndarray],
                     point_fn: Callable[[np.ndarray], np.ndarray], domain: Domain,
                     seeds: np.ndarray, rtol: float, max_boxes: int,
                     max_rounds: int, seed_values: np.ndarray | None = None
                     ) -> tuple[float, float, int, int]:
    """Maximise a function over the domain: a guaranteed upper bound and the best sampled value.

    Boxes of the domain's bounding box that can hold the maximum are halved
    along their relatively widest side (the most promising `max_boxes` / 2 when
    there are too many) until the enclosure and the best value found agree to
    ``rtol``, or for `max_rounds` rounds.

    Parameters
    ----------
    upper_fn : callable
        ``upper_fn(lo, hi) -> (B,)``: an upper bound of the function over each box
        ``[lo, hi]`` (``lo``, ``hi`` of shape (B, n), state units), e.g. from
        `interval_evaluate`.
    point_fn : callable
        ``point_fn(X) -> (P,)``: the function's values at points ``X`` (P, n) of the
        domain (non-finite values are ignored).
    domain : Domain
        The box and the linear constraints ``G x <= g`` to maximise over.
    seeds : ndarray, shape (S, n)
        Sample points of the domain giving the first lower bound of the maximum.
    rtol : float
        Relative gap between the upper bound and the best value at which to stop
        (dimensionless).
    max_boxes : int
        Largest number of boxes kept per round.
    max_rounds : int
        Largest number of halving rounds.
    seed_values : ndarray, shape (S,), optional
        ``point_fn(seeds)`` when the caller already has it.

    Returns
    -------
    upper : float
        Guaranteed upper bound of the maximum (the function's units; inf when unbounded).
    best : float
        Best value found at a sample point (a lower bound of the maximum).
    boxes : int
        Boxes bounded in all.
    rounds : int
        Rounds run.
    """
    width = domain.upper - domain.lower
    lo, hi = domain.lower[None].copy(), domain.upper[None].copy()
    if seed_values is not None and len(seeds):
        vals = np.asarray(seed_values, dtype=float)
    else:
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
