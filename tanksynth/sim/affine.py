"""Closed loops under an affine state feedback: the horizon in a few CasADi calls.

A control law that can describe itself as ``u_k = b_k - K (x_k - x_ref)`` (``b_k`` known in
advance for every period, e.g. ``u0`` plus a scheduled disturbance) offers
``affine(steps, ts) -> (b (N, m), K (m, n), x_ref (n,))``. With the true state fed back
(no estimator), no noise, faults or jumps, `tanksynth.sim.simulate.simulate` then integrates
the loop here: the law, the actuator saturation and the plant's sampling period
(`tanksynth.sim.tape.NumpyModel.casadi_advance`, the integrator's period as CasADi) are
one CasADi function per period, accumulated over `CHUNK` periods (``mapaccum``, built once
per plant) and mapped over the runs, instead of one Python round trip per period.

The numbers are those of the period-by-period loop up to rounding: the plant's period is
the same function; the law's matrix-vector product ``K (x - x_ref)`` is summed in column
order here, while numpy's ``@`` may use BLAS (other order, fused multiply-adds), so the
inputs can differ in the last bit (measured on the examples' verdicts: every check value
equal, the recorded inputs within 4e-16 relative). A run that changes hybrid mode inside a period (the
switching surface must be located) or a non-finite state sends the caller back to the
period-by-period loop.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.sim.tape import CASADI_MAX_RUNS, CASADI_MAX_RUNS_HYBRID

__all__ = ["affine_horizon", "CHUNK", "MAX_RUNS"]

#: Most runs integrated here when the plant's compiled C kernel would serve the loop (above,
#: the kernel's loop is faster than CasADi's virtual machine: 0.7 against 2-3 us a run-period).
MAX_RUNS = 8


#: Periods per call of the accumulated function: built once per plant (its build time grows
#: with the length: 30 ms for 2,000 periods), called ceil(N / CHUNK) times.
CHUNK = 64


def _function(model: Any, substeps: int, runs: int) -> Any:
    """``mapaccum`` over `CHUNK` periods of law + saturation + period, mapped over ``runs``."""
    key = ("affine", substeps, runs)
    fn = model.compiled.get(key)
    if fn is not None:
        return fn
    import casadi as ca

    n, m = model.n, model.m
    period = model.casadi_advance(substeps, 1)
    x = ca.SX.sym("x", n)
    b = ca.SX.sym("b", m)
    K = ca.SX.sym("K", m * n)
    xr = ca.SX.sym("x_ref", n)
    ulo = ca.SX.sym("u_lower", m)
    uhi = ca.SX.sym("u_upper", m)
    c = ca.SX.sym("c", model.n_constants)
    p = ca.SX.sym("p", len(model.parameter_names))
    h = ca.SX.sym("h")
    lo = ca.SX.sym("lower", n)
    hi = ca.SX.sym("upper", n)
    d = [x[j] - xr[j] for j in range(n)]
    inputs = []
    for i in range(m):
        acc = K[i * n] * d[0]
        for j in range(1, n):
            acc = acc + K[i * n + j] * d[j]
        inputs.append(ca.fmin(ca.fmax(b[i] - acc, ulo[i]), uhi[i]))
    u = ca.vertcat(*inputs)
    x1, crossed, low, high = period(x, u, c, p, h, lo, hi)
    step = ca.Function("affine_period", [x, b, K, xr, ulo, uhi, c, p, h, lo, hi],
                       [x1, u, crossed, low, high])
    fn = step.mapaccum(CHUNK)
    fn = fn if runs == 1 else fn.map(runs, "serial")
    model.compiled[key] = fn
    return fn


def affine_horizon(integ: Any, x: np.ndarray, b: np.ndarray, K: np.ndarray, x_ref: np.ndarray,
                   p: Mapping[str, Any], lo: np.ndarray, hi: np.ndarray, ts: float,
                   substeps: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The closed loop ``u_k = sat(b_k - K (x_k - x_ref))`` over the horizon, or None.

    Parameters
    ----------
    integ : tanksynth.sim.integrate.Integrator
        The plant's integrator (its model, state bounds and counters).
    x : ndarray, shape (M, n)
        Clipped initial states (state units).
    b : ndarray, shape (N, m)
        The law's value at ``x_ref`` in each period (input units).
    K : ndarray, shape (m, n)
        Feedback gain (input units per state unit).
    x_ref : ndarray, shape (n,)
        Reference state (state units).
    p : mapping
        Parameter values (floats or (M,) arrays), constant over the horizon.
    lo, hi : ndarray, shape (M, m)
        Actuator range of each run (input units).
    ts : float
        Sampling period (s).
    substeps : int
        RK4 steps per period.

    Returns
    -------
    (X, U) or None
        ``X`` (M, N + 1, n) the states at the samples, ``U`` (M, N, m) the saturated inputs
        held over each period; None (nothing counted) when a run changed hybrid mode
        inside a period, a state, input, gain or parameter is not finite (NaN limits),
        or the loop does not fit this route
        (per-run bounds, more than `MAX_RUNS` runs when the plant's compiled kernel
        serves the loop, more than the CasADi route takes): the caller then steps
        period by period.
    """
    model = integ.model
    count, n, m = x.shape[0], model.n, model.m
    N = int(b.shape[0])
    substeps = int(substeps)
    limit = CASADI_MAX_RUNS_HYBRID if model.k else CASADI_MAX_RUNS
    if not (0 < count <= limit and N > 0 and n and m and integ.lower.ndim == 1
            and integ.upper.ndim == 1):
        return None
    if count > MAX_RUNS and integ.native(substeps) is not None:
        return None
    pv, c = integ._values(p)
    # NaN never reaches the states here (CasADi's fmin/fmax, as C's, return the other operand:
    # the saturation and the clipping would turn it into a bound): non-finite data goes to the
    # loop, which reports it (`SimulationError`) as before.
    finite = (np.isfinite(x).all() and np.isfinite(b).all() and np.isfinite(K).all()
              and np.isfinite(x_ref).all() and not np.isnan(lo).any() and not np.isnan(hi).any()
              and all(np.isfinite(v).all() for v in (*pv, *c)))
    if not finite:
        return None
    fn = _function(model, substeps, count)
    per_run = lambda a, w: np.broadcast_to(  # noqa: E731
        np.asarray(a, dtype=float).reshape(-1, w) if np.ndim(a) else a, (count, w))
    cm, pm = integ._run_matrices(pv, c, count)
    rep = lambda a: np.ascontiguousarray(np.broadcast_to(  # noqa: E731
        np.asarray(a, dtype=float)[:, None, :], (count, CHUNK, a.shape[-1])))
    xk = np.array(x, dtype=float, order="C")      # a copy: the caller's x stays the start
    bk = np.empty((count, CHUNK, m))
    args = [xk, bk, rep(per_run(np.asarray(K, dtype=float).reshape(-1), m * n)),
            rep(per_run(x_ref, n)), rep(lo), rep(hi), rep(cm), rep(pm),
            np.full((count, CHUNK, 1), float(ts) / substeps),
            rep(per_run(integ.lower, n)), rep(per_run(integ.upper, n))]
    res = [np.empty((count, CHUNK, n)), np.empty((count, CHUNK, m)), np.empty((count, CHUNK, 1)),
           np.empty((count, CHUNK, substeps)), np.empty((count, CHUNK, substeps))]
    buf, run = fn.buffer()
    for j, a in enumerate(args):
        buf.set_arg(j, a.data)
    for j, r in enumerate(res):
        buf.set_res(j, r.data)
    b = np.asarray(b, dtype=float)
    X = np.empty((count, N + 1, n))
    U = np.empty((count, N, m))
    X[:, 0] = x
    low = np.zeros((N, substeps), dtype=bool)
    high = np.zeros((N, substeps), dtype=bool)
    for k0 in range(0, N, CHUNK):
        k1 = min(k0 + CHUNK, N)
        bk[:, : k1 - k0] = b[k0:k1]
        bk[:, k1 - k0:] = b[k1 - 1]               # past the horizon: computed, not used
        run()
        Xc, Uc, crossed, lowc, highc = res
        if crossed[:, : k1 - k0].any() or not np.isfinite(Xc[:, : k1 - k0]).all():
            return None
        X[:, k0 + 1:k1 + 1] = Xc[:, : k1 - k0]
        U[:, k0:k1] = Uc[:, : k1 - k0]
        low[k0:k1] = lowc[:, : k1 - k0].max(axis=0) > 0.5
        high[k0:k1] = highc[:, : k1 - k0].max(axis=0) > 0.5
        xk[...] = Xc[:, k1 - k0 - 1]
    integ.clipped_low += int(np.count_nonzero(low))
    integ.clipped_high += int(np.count_nonzero(high))
    integ.backends.add("casadi")
    return X, U
