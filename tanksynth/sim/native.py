"""The compiled kernel inside the integrator: one period, and a whole horizon, of M runs.

Used by `tanksynth.sim.integrate.Integrator` (``advance`` and ``horizon``)
when the plant's native kernel is available (`tanksynth.sim.kernel`). Runs
whose hybrid mode changes inside a period are re-integrated by the
integrator's numpy code, which locates the crossing (``_period_rows``); on
the horizon, the kernel then resumes those runs from the next period. The
numbers are those of the numpy code, bit for bit.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.sim.kernel import NativeKernel, per_run_table

__all__ = ["tables", "period", "horizon"]

#: Tables of scalar parameter values kept per model (the newest).
_TABLES_KEPT = 16


def tables(integ: Any, p: Mapping[str, Any], count: int) -> tuple[np.ndarray, np.ndarray]:
    """Constants and parameter tables (M, .) of the kernel (cached while ``p`` holds).

    Parameters
    ----------
    integ : tanksynth.sim.integrate.Integrator
    p : mapping of str
        Parameter values (scalars or (M,) arrays, SI units).
    count : int
        Number of runs M.
    """
    model = integ.model
    pv = model.parameter_values(p)
    if all(type(v) is float for v in pv):   # scalar values: tables kept on the model by value
        key = ("tables", tuple(pv), int(count))
        hit = model.compiled.get(key)
        if hit is None:
            c = model.constants(pv)
            hit = model.compiled[key] = (per_run_table(c, count), per_run_table(pv, count))
            for old in [k for k in model.compiled if k[0] == "tables"][:-_TABLES_KEPT]:
                del model.compiled[old]
        return hit
    pv, c = integ._values(p)
    held, C, P = integ._tables
    if (C is None or C.shape[0] != count or len(held) != len(pv)
            or any(a is not b for a, b in zip(held, pv))):
        C, P = per_run_table(c, count), per_run_table(pv, count)
        integ._tables = (list(pv), C, P)
    return C, P

def period(integ: Any, kernel: NativeKernel, x: np.ndarray, u: np.ndarray,
           p: Mapping[str, Any], h: float, substeps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One period through the compiled kernel; crossed runs by the numpy code.

    Parameters
    ----------
    integ : tanksynth.sim.integrate.Integrator
    kernel : NativeKernel
    x : ndarray, shape (M, n)
        Clipped states at the start (state units).
    u : ndarray, shape (M, m)
        Saturated inputs held over the period (input units).
    p : mapping of str
        Parameter values (scalars or (M,) arrays, SI units).
    h : float
        RK4 step (s).
    substeps : int
        RK4 steps in the period.

    Returns
    -------
    x1 : ndarray, shape (M, n)
        End states, clipped.
    low, high : ndarray of bool, shape (substeps,)
        Steps after which some run passed a bound.
    """
    count = x.shape[0]
    C, P = tables(integ, p, count)
    call = integ._buffers.get(("native", substeps, count))
    if call is None:
        call = integ._buffers[("native", substeps, count)] = kernel.period(count, substeps)
    call.bind(C, P, integ.lower, integ.upper, h)
    x1, stop, low, high = call(x, u)
    if stop.max() >= 0:
        hit = np.flatnonzero(stop >= 0)
        sub = {k: (v[hit] if np.ndim(v) else v) for k, v in p.items()}
        x1[hit], low_hit, high_hit = integ._period_rows(x[hit], u[hit], sub, h, substeps)
        integ._cache_key = None
        low, high = low | low_hit, high | high_hit
    return x1, low, high

def horizon(integ: Any, kernel: NativeKernel, x: np.ndarray, U: np.ndarray,
            p: Mapping[str, Any], h: float, substeps: int,
            out: np.ndarray | None = None) -> np.ndarray | None:
    """`Integrator.horizon` through the compiled kernel (crossed periods by the numpy code).

    Parameters
    ----------
    integ : tanksynth.sim.integrate.Integrator
    kernel : NativeKernel
    x : ndarray, shape (M, n)
        Clipped states at the start (state units).
    U : ndarray, shape (N, M, m)
        Saturated inputs held over each period (input units).
    p : mapping of str
        Parameter values (scalars or (M,) arrays, SI units), constant.
    h : float
        RK4 step (s).
    substeps : int
        RK4 steps per period.
    out : ndarray, shape (N, M, n), optional
        Buffer for the result (any strides, last axis contiguous).

    Returns
    -------
    ndarray, shape (N, M, n) or None
        End states of every period (state units); None (counters unchanged) when
        a state became non-finite.
    """
    N, count, n = U.shape[0], x.shape[0], integ.model.n
    C, P = tables(integ, p, count)
    x0 = np.ascontiguousarray(x, dtype=float)
    if U.shape[2] > 1 and U.strides[2] != U.itemsize or U.dtype != np.float64:
        U = np.ascontiguousarray(U, dtype=float)
    X = np.empty((N, count, n)) if out is None else out
    saved = (integ.events, integ.clipped_low, integ.clipped_high)
    stop, low, high = kernel.run(x0, U, C, P, integ.lower, integ.upper, h, substeps, X)
    periods = np.arange(N)[:, None]
    while True:
        idx = np.flatnonzero(stop >= 0)
        if not idx.size:
            break
        ks = stop[idx]
        for k in np.unique(ks):
            g = idx[ks == k]
            sub = {name: (v[g] if np.ndim(v) else v) for name, v in p.items()}
            start = x0[g] if k == 0 else X[k - 1, g]
            X[k, g], low_k, high_k = integ._period_rows(start, U[k, g], sub, h, substeps)
            low[k] |= low_k
            high[k] |= high_k
        integ._cache_key = None
        part = np.empty((N, idx.size, n))
        stop_r, low_r, high_r = kernel.run(np.ascontiguousarray(X[ks, idx]),
                                           np.ascontiguousarray(U[:, idx]), C[idx], P[idx],
                                           integ.lower, integ.upper, h, substeps, part,
                                           start=ks + 1)
        end = np.where(stop_r >= 0, stop_r, N)
        mask = (periods > ks) & (periods < end)
        block = X[:, idx]
        block[mask] = part[mask]
        X[:, idx] = block
        low |= low_r
        high |= high_r
        stop = np.full(count, -1, dtype=np.int64)
        stop[idx] = stop_r
    if not np.isfinite(X).all():
        integ.events, integ.clipped_low, integ.clipped_high = saved
        return None
    integ.clipped_low += int(np.count_nonzero(low))
    integ.clipped_high += int(np.count_nonzero(high))
    integ.backends.add("native")
    return X
