"""Bounds of the Takagi-Sugeno premise variables over the operating domain (seed 001 eq. 13).

Premise bounds are computed either by interval arithmetic with
branch-and-bound (a guaranteed enclosure) or by dense sampling plus an
explicit relative margin; the method is recorded in the diagnostics.

The quasi-LPV form is `tanksynth.analysis.quasi_lpv`; the TS model built on
these bounds is `tanksynth.analysis.takagi_sugeno`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tanksynth.analysis.interval import branch_and_bound, interval_evaluate
from tanksynth.analysis.quasi_lpv import Domain, QuasiLPV, recall, remember
from tanksynth.errors import SpecError

__all__ = ["PremiseBounds", "premise_bounds"]


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
    # the weighting search asks for the same bounds over and over (cached with the domain's
    # samples and LP ranges, `tanksynth.analysis.quasi_lpv.clear_cache`)
    key = ("premise_bounds", tuple(qlpv.premise_expressions()), qlpv.weights.tobytes(),
           tuple(qlpv.states), domain.cache_key(),
           method, int(samples), float(margin), int(seed), float(rtol), int(max_boxes),
           int(max_rounds))
    hit = recall(key)
    if hit is not None:
        return hit
    return remember(key, _premise_bounds(qlpv, domain, dens, method, samples, margin, seed, rtol,
                                          max_boxes, max_rounds))


def _premise_bounds(qlpv: QuasiLPV, domain: Domain, dens: list, method: str, samples: int,
                    margin: float, seed: int, rtol: float, max_boxes: int,
                    max_rounds: int) -> PremiseBounds:
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
    # the atoms' compiled functions (one per form, `FormEvaluator`), not one `lambdify` per
    # premise; the sample points' values are Z, computed above
    atoms = qlpv.atom_evaluator()
    for k, e in enumerate(exprs):
        def point(X, k=k, sign=1.0):
            with np.errstate(invalid="ignore", divide="ignore"):
                return sign * (atoms(X)[:, k] / (X @ qlpv.weights[k]))

        def upper_bound(lo: np.ndarray, hi: np.ndarray, e=e) -> np.ndarray:
            return interval_evaluate(e, qlpv.states, lo, hi)[1]

        def negated_lower_bound(lo: np.ndarray, hi: np.ndarray, e=e) -> np.ndarray:
            return -interval_evaluate(e, qlpv.states, lo, hi)[0]

        def negated_point(X: np.ndarray, k: int = k) -> np.ndarray:
            return point(X, k, -1.0)

        up = branch_and_bound(upper_bound, point, domain, pts, rtol, max_boxes, max_rounds,
                              seed_values=Z[:, k])
        dn = branch_and_bound(negated_lower_bound, negated_point, domain, pts, rtol, max_boxes,
                              max_rounds, seed_values=-Z[:, k])
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

