"""Points of a plant's operating region and batch evaluation of CasADi functions on them."""

from __future__ import annotations

import casadi as ca
import numpy as np
import sympy as sp

from tanksynth.plants.base import Plant

__all__ = ['batch_eval', 'batch_eval2', 'region_points']


def batch_eval(fn: ca.Function, points: np.ndarray) -> list[np.ndarray]:
    """Evaluate a one-argument CasADi Function at M points -> per output (M, rows, cols).

    Parameters
    ----------
    fn : casadi.Function
        A one-argument Function.
    points : ndarray, shape (M, k)
        The argument at M points (its units).
    """
    points = np.atleast_2d(np.asarray(points, dtype=float))
    count = points.shape[0]
    outs = fn.map(count, "serial")(points.T)
    outs = outs if isinstance(outs, (list, tuple)) else [outs]
    res = []
    for k, out in enumerate(outs):
        rows, cols = fn.size1_out(k), fn.size2_out(k)
        res.append(np.asarray(out, dtype=float).reshape(rows, count, cols).transpose(1, 0, 2))
    return res



def batch_eval2(fn: ca.Function, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Evaluate a two-argument, vector-valued CasADi Function at M points -> (M, rows).

    Parameters
    ----------
    fn : casadi.Function
        A two-argument, vector-valued Function.
    a, b : ndarray, shape (M, k_a), (M, k_b)
        The two arguments at M points (their units).
    """
    count = a.shape[0]
    out = fn.map(count, "serial")(np.asarray(a, float).T, np.asarray(b, float).T)
    out = out[0] if isinstance(out, (list, tuple)) else out
    return np.asarray(out, dtype=float).T



def region_points(plant: Plant, per_axis: int = 11, samples: int = 400, seed: int = 0,
                  margin: float = 0.02) -> np.ndarray:
    """Points of the operating region: a grid (when small enough) plus random samples.

    The grid spans each box interval shrunk by ``margin`` (relative) and
    keeps the points satisfying the strict orderings; the random points come
    from `Region.sample` (seeded).

    Parameters
    ----------
    plant : Plant
    per_axis : int
        Grid points per state (the grid is skipped when ``per_axis ** n >
        20000``).
    samples : int
        Additional random points.
    seed : int
        Seed of the random points.
    margin : float
        Relative margin from the box faces (keeps ``sqrt`` heads away from 0).

    Returns
    -------
    numpy.ndarray, shape (M, n)
        In the state units.
    """
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    span = hi - lo
    parts = []
    if per_axis >= 2 and per_axis ** plant.n <= 20000:
        axes = [np.linspace(a + margin * s, b - margin * s, per_axis) for a, b, s in zip(lo, hi, span)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, plant.n)
        keep = np.ones(len(grid), dtype=bool)
        for a, b in plant.region.orderings:
            diff = sp.expand(a - b).xreplace(plant.parameter_values)
            fn = sp.lambdify([list(plant.x)], diff, "numpy")
            keep &= np.asarray(fn(grid.T), dtype=float) * np.ones(len(grid)) > 0
        parts.append(grid[keep])
    if samples > 0:
        parts.append(plant.region.sample(samples, plant.x, seed=seed, margin=margin))
    return np.vstack(parts) if parts else np.empty((0, plant.n))
