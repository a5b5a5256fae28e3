"""Trim: the operating point a plant holds still at, from what the user knows of it.

Two questions, both ``f(x, u) = 0`` solved on the model (`scipy.optimize`, with the model's
Jacobians, from several starting points of the operating region; the solution inside the
region with the smallest residual is kept):

* `trim`: the pumps run at these inputs ``u``; where do the levels ``x`` settle?
* `trim_outputs`: the outputs must read ``y``; which inputs ``u`` and levels ``x`` hold them
  (``h(x) = y``)?

The spec's ``[operating_point] trim = "states"`` / ``"inputs"`` calls them
(`tanksynth.spec`); `tanksynth.analysis.trim` re-exports them beside the hints printed for an
operating point that is not an equilibrium.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from tanksynth.errors import DimensionError
from tanksynth.plants.base import Plant

__all__ = ["Trim", "trim", "trim_outputs"]


@dataclass(frozen=True)
class Trim:
    """Levels that balance given inputs, with the evidence.

    Attributes
    ----------
    x : ndarray, shape (n,)
        Levels (state units) with ``f(x, u) = 0``.
    u : ndarray, shape (m,)
        The given inputs (input units).
    residual : ndarray, shape (n,)
        ``f(x, u)`` (state units per s) at the solution.
    converged : bool
        ``max |residual| <= tolerance`` and ``x`` inside the operating region.
    tolerance : float
        Absolute tolerance on ``max |f|`` (state units/s).
    in_region : bool
        ``x`` satisfies the region's bounds and orderings.
    violations : tuple of str
        Region conditions ``x`` violates (empty when inside).
    starts : int
        Starting points tried.
    """

    x: np.ndarray
    u: np.ndarray
    residual: np.ndarray
    converged: bool
    tolerance: float
    in_region: bool
    violations: tuple[str, ...]
    starts: int

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"x": self.x.tolist(), "u": self.u.tolist(), "residual": self.residual.tolist(),
                "max_abs_residual": float(np.max(np.abs(self.residual))),
                "converged": self.converged, "tolerance": self.tolerance,
                "in_region": self.in_region, "violations": list(self.violations),
                "starts": self.starts}


def trim(plant: Plant, u: npt.ArrayLike, x_guess: npt.ArrayLike | None = None,
         starts: int = 20, seed: int = 0, tolerance: float | None = None) -> Trim:
    """Levels ``x`` with ``f(x, u) = 0`` for given inputs ``u`` (root finding on the model).

    Parameters
    ----------
    plant : Plant
    u : array_like, shape (m,)
        Inputs (pump flows) in the input units.
    x_guess : array_like, shape (n,), optional
        First starting point (state units); then the region's centre and
        ``starts`` seeded samples of the region.
    starts : int
        Sampled starting points (>= 0).
    seed : int
        Seed of the sampling.
    tolerance : float, optional
        Absolute tolerance on ``max |f(x, u)|`` (state units/s); default
        ``1e-9`` times the largest input term ``max |df/du u|`` (at least 1e-15).

    Returns
    -------
    Trim
        The best solution found (``converged`` False when no start reached
        the tolerance inside the region: the inputs cannot hold the plant in
        its region, e.g. more inflow than the outlets can drain).
    """
    from scipy.optimize import root  # deferred: scipy.optimize imports in ~0.15 s
    u_vec = np.asarray(u, dtype=float).reshape(-1)
    if u_vec.size != plant.m or not np.all(np.isfinite(u_vec)):
        raise DimensionError(f"u must have {plant.m} finite entries, got {u_vec.tolist()}")
    comp = plant.compiled
    points = _start_points(plant, x_guess, starts, seed)
    G = comp.jacobians(points[-1][None], u_vec[None])[1][0]
    scale = float(np.max(np.abs(G @ u_vec))) if u_vec.size else 0.0
    tol = float(tolerance) if tolerance is not None else max(1e-9 * scale, 1e-15)

    def fun(x):
        return comp.rhs(x[None], u_vec[None])[0]

    def jac(x):
        return comp.jacobians(x[None], u_vec[None])[0][0]

    best = None
    for x0 in points:
        with np.errstate(all="ignore"):
            sol = root(fun, x0, jac=jac, method="hybr", options={"xtol": 1e-14})
        x = np.asarray(sol.x, dtype=float)
        if not np.all(np.isfinite(x)):
            continue
        r = fun(x)
        if not np.all(np.isfinite(r)):
            continue
        bad = tuple(plant.region.violations(x, plant.x))
        key = (len(bad) > 0, float(np.max(np.abs(r))))
        if best is None or key < best[0]:
            best = (key, x, r, bad)
        if not bad and key[1] <= tol:
            break
    if best is None:
        x = points[-1]
        return Trim(x, u_vec, fun(x), False, tol, False, ("no start converged",), len(points))
    (_, worst), x, r, bad = best
    return Trim(x, u_vec, r, bool(not bad and worst <= tol), tol, not bad, bad, len(points))


def _start_points(plant: Plant, x_guess: npt.ArrayLike | None, starts: int, seed: int) -> list[np.ndarray]:
    """``x_guess`` (if any), ``starts`` seeded samples of the region, then the box centre."""
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    points = []
    if x_guess is not None:
        g = np.asarray(x_guess, dtype=float).reshape(-1)
        if g.size != plant.n:
            raise DimensionError(f"x_guess has {g.size} entries, expected {plant.n}")
        points.append(g)
    try:
        points += list(plant.region.sample(max(int(starts), 1), plant.x, seed=seed, margin=0.01))
    except Exception:  # a region too thin to sample: the box centre only
        pass
    points.append(0.5 * (lo + hi))
    return points


def trim_outputs(plant: Plant, y: npt.ArrayLike, x_guess: npt.ArrayLike | None = None,
                 starts: int = 20, seed: int = 0, tolerance: float | None = None) -> Trim:
    """Inputs ``u`` and levels ``x`` with ``f(x, u) = 0`` and ``h(x) = y`` for given outputs.

    Bounded least squares on ``(x, u)`` (``x`` in the region's box, ``u`` in the
    actuator range) from the starting points of `trim`. With as many outputs as
    inputs the solution is generically unique; with more outputs, ``y`` must be
    consistent (the residual says whether it is).

    Parameters
    ----------
    plant : Plant
        Needs at least as many outputs as inputs (``q >= m``).
    y : array_like, shape (q,)
        Outputs in the output units.
    x_guess : array_like, shape (n,), optional
        First starting point (state units).
    starts : int
        Sampled starting points (>= 0).
    seed : int
        Seed of the sampling.
    tolerance : float, optional
        Absolute tolerance on ``max |f(x, u)|`` (state units/s); default ``1e-9``
        times the largest input term ``max |df/du u|`` at the solution (at least
        1e-15). The outputs must match to ``1e-9 max(1, |y|)`` (output units).

    Returns
    -------
    Trim
        ``u`` the solved inputs; ``residual`` is ``f(x, u)``; ``converged`` also
        requires ``|h(x) - y|`` within its tolerance (``violations`` says by how much
        the outputs miss when they do not).

    Raises
    ------
    DimensionError
        ``y`` of the wrong size, or fewer outputs than inputs (the inputs would not
        be determined).
    """
    from scipy.optimize import least_squares  # deferred: scipy.optimize imports in ~0.15 s

    y_vec = np.asarray(y, dtype=float).reshape(-1)
    if y_vec.size != plant.q or not np.all(np.isfinite(y_vec)):
        raise DimensionError(f"y must have {plant.q} finite entries, got {y_vec.tolist()}")
    if plant.q < plant.m:
        raise DimensionError(f"{plant.q} outputs cannot determine {plant.m} inputs: give the "
                             "inputs and solve for the levels instead")
    comp = plant.compiled
    n, m = plant.n, plant.m
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    ulim = np.asarray(plant.input_limits, dtype=float).reshape(m, 2)
    y_tol = 1e-9 * max(1.0, float(np.max(np.abs(y_vec))) if y_vec.size else 1.0)

    def fun(z):
        x, u = z[:n], z[n:]
        return np.concatenate([comp.rhs(x[None], u[None])[0], comp.output(x[None])[0] - y_vec])

    def jac(z):
        x, u = z[:n], z[n:]
        A, B = (J[0] for J in comp.jacobians(x[None], u[None]))
        H = np.asarray(comp.jac_h(x), dtype=float).reshape(plant.q, n)
        return np.block([[A, B], [H, np.zeros((plant.q, m))]])

    u_start = np.where(np.isfinite(ulim).all(axis=1), ulim.mean(axis=1), 0.0)
    points = _start_points(plant, x_guess, starts, seed)
    best = None
    for x0 in points:
        z0 = np.concatenate([np.clip(x0, lo, hi), u_start])
        with np.errstate(all="ignore"):
            try:
                sol = least_squares(fun, z0, jac=jac, bounds=(np.r_[lo, ulim[:, 0]], np.r_[hi, ulim[:, 1]]),
                                    xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=400)
            except ValueError:
                continue
        z = np.asarray(sol.x, dtype=float)
        r = fun(z)
        if not np.all(np.isfinite(r)):
            continue
        x, u = z[:n], z[n:]
        G = comp.jacobians(x[None], u[None])[1][0]
        tol = float(tolerance) if tolerance is not None else max(1e-9 * float(np.max(np.abs(G @ u))), 1e-15)
        bad = tuple(plant.region.violations(x, plant.x))
        ok = not bad and float(np.max(np.abs(r[:n]))) <= tol and float(np.max(np.abs(r[n:]))) <= y_tol
        key = (not ok, len(bad) > 0, float(np.max(np.abs(r[:n]))) + float(np.max(np.abs(r[n:]))))
        if best is None or key < best[0]:
            best = (key, x, u, r[:n], bad, tol, ok)
        if ok:
            break
    if best is None:
        x = points[-1]
        return Trim(x, u_start, comp.rhs(x[None], u_start[None])[0], False,
                    float(tolerance or 0.0), False, ("no start converged",), len(points))
    (_, _, _), x, u, r, bad, tol, ok = best
    miss = float(np.max(np.abs(comp.output(x[None])[0] - y_vec)))
    reasons = bad + ((f"the outputs miss y by up to {miss:.3g} output units (tolerance {y_tol:.3g}) at the "
                      "closest point of the region's box and actuator range",) if miss > y_tol else ())
    return Trim(x, u, r, ok, tol, not bad, reasons, len(points))
