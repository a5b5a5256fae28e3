"""Batch closed-loop simulation of a nonlinear plant (M runs at once).

The simulator never designs: it takes a `Plant` (the symbolic model), an
optional estimator and an optional control law, and integrates ``M``
independent runs at once:

* sampled at ``ts`` (s); inputs are held (zero-order hold) over each period
  and saturated to the actuators' range (pump saturation);
* the one integrator of the toolbox (`tanksynth.sim.integrate.Integrator`):
  fixed-step RK4 with ``substeps`` steps per period, vectorised over the
  runs, stage and end states clipped by the plant's one clipping rule
  (`Plant.state_bounds`: levels never below zero, nor above the overflow
  height ``hmax`` where the plant has one), hybrid switching surfaces
  located inside a step (bisection on the step fraction, to
  ``2**-event_iterations`` of the step) so RK4 never straddles one and never
  chatters at ``h0``;
* process noise (added to the state at each sample, state units) and
  measurement noise (added to ``h(x)``, output units) are drawn from one
  ``numpy.random.Generator`` per run, seeded explicitly: run ``r`` with
  seed ``s`` gives the same trajectory bit for bit whatever the other runs
  of the batch are;
* parameter changes (faults: a valve leak or clogging from a given sample)
  and state jumps (water added or removed) at given samples.

The vector field is the plant compiled once: the sampling period as C
compiled with the system compiler (`tanksynth.sim.kernel`, the whole horizon
of every run in one call when the inputs are known in advance) when a
compiler works, else generated numpy code on the row layout and the same
code as one CasADi function per sampling period for small batches
(`tanksynth.sim.tape`); all bit for bit equal (`SimulationResult.backend`
names the route), with the
parameters as inputs (each run may carry its own values, e.g. a +-10 %
uncertainty draw, and faults switch values mid-run).

Sample-time convention, for estimators and control laws: at sample ``k``
(time ``t_k = k ts``) the plant is measured, ``y_k = h(x_k) + v_k``; the
estimator is called with ``(y_k, u_{k-1})`` and returns ``x_hat_k``; the
control law maps ``(x_hat_k, r_k, t_k)`` to ``u_k``, which is saturated and
held over ``[t_k, t_{k+1})``. At ``k = 0``, ``u_{-1}`` is ``u_init``.

Closed loops whose law describes itself as a CasADi Function (``loop_law``)
and feeds back the true state run through one compiled kernel over the whole
horizon (`tanksynth.sim.closed_loop`: law, saturation, plant, process noise;
the same numbers); ``TANKSYNTH_SIM_BACKEND=numpy`` forces the period-by-period
loop.

`simulate_inputs` is the open-loop special case (a given input sequence per
run, no noise): training and test data for estimators.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.errors import DimensionError, SimulationError
from tanksynth.plants.base import Plant
from tanksynth.sim.inputs import (BatchEstimator, ConstantInput, ControlLaw, EstimatorAdapter,
                                  InputSequence, ParameterChange, StateJump)
from tanksynth.sim.affine import affine_horizon
from tanksynth.sim.closed_loop import loop_kernel, run_closed_loop
from tanksynth.sim.integrate import Integrator, input_limits, param_arrays

__all__ = [
    "BatchEstimator",
    "ControlLaw",
    "SimulationError",
    "StateJump",
    "ParameterChange",
    "SimulationResult",
    "ConstantInput",
    "InputSequence",
    "EstimatorAdapter",
    "run_seeds",
    "simulate",
    "simulation_bytes",
    "max_simulation_bytes",
    "simulate_inputs",
]

#: ``(x, y, u, x_hat, modes)`` of M runs, run-major: shapes (M, N + 1, n), (M, N + 1, q),
#: (M, N, m), (M, N + 1, n), (M, N + 1, k).
_Runs = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class SimulationResult:
    """Trajectories of M runs (arrays are read-only).

    Attributes
    ----------
    t : ndarray, shape (N + 1,)
        Sample times ``k ts`` (s).
    x : ndarray, shape (M, N + 1, n)
        True states at the samples (state units).
    y : ndarray, shape (M, N + 1, q)
        Measurements (with noise), output units.
    u : ndarray, shape (M, N, m)
        Inputs held over each period, after saturation (input units).
    x_hat : ndarray, shape (M, N + 1, n)
        Estimates (the true state when no estimator was given).
    reference : ndarray, shape (N + 1, r)
        Reference at the samples (r = 0 when none).
    seeds : ndarray of int, shape (M,)
        Seed of each run's noise generator.
    modes : ndarray of int8, shape (M, N + 1, k)
        Hybrid mode bits at the samples (k = 0 for non-hybrid plants).
    ts : float
        Sampling period (s).
    substeps : int
    events : int
        Switching-surface crossings located inside RK4 steps (all runs).
    clipped_low, clipped_high : int
        RK4 steps (or noise additions) after which some level was clipped at 0
        or at ``hmax``.
    timing : dict
        Wall-clock seconds spent in ``estimator`` and ``controller`` calls,
        ``calls`` (samples) and ``runs`` (M): the batch per-step time is
        ``timing["controller"] / calls``. Through the closed-loop kernel
        (backend ``"loop"``) ``controller`` is the kernel's time: law and plant
        together.
    plant : str
        Plant model name.
    backend : str
        Route that integrated the periods (``"loop"``: the closed loop's compiled
        kernel, law included, `tanksynth.sim.closed_loop`; ``"native"``: the plant's
        compiled C kernel, ``"casadi"``, ``"numpy"``; several joined by ``+``), see
        `tanksynth.sim.integrate.Integrator.backends` and, when it is not
        ``"native"``, `tanksynth.sim.kernel.kernel_status` for why.
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    u: np.ndarray
    x_hat: np.ndarray
    reference: np.ndarray
    seeds: np.ndarray
    modes: np.ndarray
    ts: float
    substeps: int
    events: int
    clipped_low: int
    clipped_high: int
    timing: Mapping[str, float]
    plant: str
    backend: str = ""

    @property
    def runs(self) -> int:
        """Number of runs M."""
        return int(self.x.shape[0])

    @property
    def steps(self) -> int:
        """Number of periods N."""
        return int(self.u.shape[1])

    def mode_switches(self) -> np.ndarray:
        """Number of mode changes between consecutive samples, per run, shape (M,)."""
        if self.modes.shape[2] == 0:
            return np.zeros(self.runs, dtype=int)
        return np.sum(np.any(np.diff(self.modes, axis=1) != 0, axis=2), axis=1)


def simulation_bytes(plant: Plant, runs: int, steps: int) -> int:
    """Memory a simulation's trajectories and noise take, about (bytes).

    States, estimates, outputs, inputs and hybrid modes of every run and sample, the
    process and measurement noise, and one copy of each for the result's layout.

    Parameters
    ----------
    plant : Plant
    runs : int
        Number of runs M.
    steps : int
        Number of sampling periods N.

    Returns
    -------
    int
        Bytes.
    """
    per_sample = 8 * (3 * plant.n + 2 * plant.q + plant.m) + plant.n   # (modes: < n bytes)
    return int(2 * runs * (steps + 1) * per_sample)


def max_simulation_bytes() -> int:
    """Largest `simulation_bytes` `simulate` accepts (bytes).

    ``TANKSYNTH_SIM_MAX_BYTES`` if set, else half the machine's physical memory (16 GiB
    when it cannot be read).

    Returns
    -------
    int
        Bytes.
    """
    text = os.environ.get("TANKSYNTH_SIM_MAX_BYTES", "").strip()
    if text:
        try:
            return max(int(float(text)), 1)
        except ValueError:
            raise DimensionError(f"TANKSYNTH_SIM_MAX_BYTES must be a number of bytes, got {text!r}") from None
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")) // 2
    except (ValueError, OSError, AttributeError):
        return 16 * 2**30


def run_seeds(base_seed: int, runs: int | Sequence[int]) -> np.ndarray:
    """Seeds of runs derived from one base seed (independent streams).

    Parameters
    ----------
    base_seed : int
        Campaign seed (>= 0).
    runs : int or sequence of int
        Number of runs (indices ``0..runs-1``) or the run indices.

    Returns
    -------
    ndarray of uint64
        ``SeedSequence([base_seed, r]).generate_state(1, uint64)[0]`` for each
        run index ``r``: run ``r`` of a campaign has the same seed however
        the runs are split into batches.
    """
    indices = range(runs) if isinstance(runs, (int, np.integer)) else runs
    return np.array([np.random.SeedSequence([int(base_seed), int(r)]).generate_state(1, np.uint64)[0]
                     for r in indices], dtype=np.uint64)


def _per_run(value: Any, count: int, width: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return np.full((count, width), float(arr))
    if arr.shape == (width,):
        out = np.empty((count, width))
        out[...] = arr
        return out
    if arr.shape == (count, width):
        return arr.copy()
    raise DimensionError(f"{name} has shape {arr.shape}: expected ({width},) or ({count}, {width})")


def simulate(plant: Plant, *, ts: float, steps: int, x0: Sequence[float] | np.ndarray,
             seeds: Sequence[int] | np.ndarray, controller: Callable | None = None,
             estimator: BatchEstimator | None = None,
             reference: np.ndarray | None = None, x_hat0: np.ndarray | None = None,
             u_init: np.ndarray | None = None,
             process_std: float | Sequence[float] = 0.0,
             measurement_std: float | Sequence[float] = 0.0,
             parameters: Mapping[str, Any] | None = None,
             changes: Sequence[ParameterChange] = (), jumps: Sequence[StateJump] = (),
             substeps: int = 4, event_iterations: int = 12, max_splits: int = 3,
             bounds: tuple[np.ndarray, np.ndarray] | None = None) -> SimulationResult:
    """Simulate M runs of a plant in closed loop (or open loop), in one batch.

    Parameters
    ----------
    plant : Plant
    ts : float
        Sampling period (s).
    steps : int
        Number of periods N (the runs last ``N ts`` seconds).
    x0 : array, shape (n,) or (M, n)
        Initial true states (state units); a single state is used for every run.
    seeds : sequence of int, length M
        Seed of each run's noise generator (see `run_seeds`); M is its length.
    controller : ControlLaw, optional
        ``(x_hat (M, n), reference (M, r), t) -> u (M, m)``. Default: hold
        ``u_init`` (open loop).
    estimator : BatchEstimator, optional
        Default: the true state is fed back (a perfect estimator).
    reference : array, shape (N + 1, r), optional
        Reference at each sample (e.g. level set-points in m).
    x_hat0 : array, shape (n,) or (M, n), optional
        Initial estimate (state units; default ``x0``).
    u_init : array, shape (m,) or (M, m), optional
        Input held before ``t = 0`` (given to the estimator at ``k = 0``) and
        the open-loop input when there is no controller; default zeros.
    process_std : float or sequence of n floats
        Standard deviation of the process noise added to the state at each
        sample (state units).
    measurement_std : float or sequence of q floats
        Standard deviation of the measurement noise (output units).
    parameters : mapping, optional
        Plant parameter values for this simulation: a float (all runs) or an
        array (M,) per parameter name.
    changes : sequence of ParameterChange
        Parameter values that change from a sample on (faults).
    jumps : sequence of StateJump
        Instantaneous level changes (water added/removed).
    substeps : int
        RK4 steps per sampling period.
    event_iterations : int
        Bisection iterations locating a switching-surface crossing.
    max_splits : int
        Crossings handled inside one RK4 step (more are integrated across).
    bounds : (lower, upper), optional
        State bounds (default: the plant's clipping rule, `Plant.state_bounds`).

    Returns
    -------
    SimulationResult

    Raises
    ------
    DimensionError
        Inconsistent shapes or unknown parameter names, or trajectories larger than
        `max_simulation_bytes` (checked before anything is allocated).
    SimulationError
        A state became non-finite (the run and sample are named).
    """
    n, m, q = plant.n, plant.m, plant.q
    seeds = np.asarray(seeds, dtype=np.uint64).reshape(-1)
    M = int(seeds.size)
    N = int(steps)
    if M < 1 or N < 1:
        raise DimensionError(f"need at least one run and one step, got M = {M}, N = {N}")
    need = simulation_bytes(plant, M, N)
    if need > max_simulation_bytes():
        raise DimensionError(
            f"{M} runs x {N} samples need about {need / 2**30:.1f} GiB for the trajectories "
            f"(limit {max_simulation_bytes() / 2**30:.1f} GiB, TANKSYNTH_SIM_MAX_BYTES): simulate "
            "the runs in blocks")
    if not (np.isfinite(ts) and ts > 0) or int(substeps) < 1:
        raise DimensionError(f"ts must be > 0 s and substeps >= 1, got {ts!r}, {substeps!r}")
    x = _per_run(x0, M, n, "x0")
    xh0 = x.copy() if x_hat0 is None else _per_run(x_hat0, M, n, "x_hat0")
    u_prev = np.zeros((M, m)) if u_init is None else _per_run(u_init, M, m, "u_init")
    if reference is None:
        ref = np.zeros((N + 1, 0))
    else:
        ref = np.asarray(reference, dtype=float)
        if ref.ndim == 1:
            ref = ref[:, None]
        if ref.shape[0] != N + 1:
            raise DimensionError(f"reference has {ref.shape[0]} samples, expected N + 1 = {N + 1}")
    wstd = _per_run(process_std, 1, n, "process_std")[0]
    vstd = _per_run(measurement_std, 1, q, "measurement_std")[0]
    params = param_arrays(plant, parameters, M)
    schedule: dict[int, list[Mapping[str, float | np.ndarray]]] = {}
    for ch in changes:
        param_arrays(plant, ch.values, M)  # validates names and shapes
        schedule.setdefault(int(ch.sample), []).append(ch.values)
    jump_at: dict[int, np.ndarray] = {}
    for j in jumps:
        delta = np.asarray(j.delta, dtype=float).reshape(-1)
        if delta.size != n:
            raise DimensionError(f"state jump at sample {j.sample} has {delta.size} entries, expected {n}")
        jump_at[int(j.sample)] = jump_at.get(int(j.sample), np.zeros(n)) + delta
    integ = Integrator.for_plant(plant, params, bounds=bounds, event_iterations=event_iterations,
                                 max_splits=max_splits, work=float(M) * N * int(substeps))
    model = integ.model

    # Noise: one generator per run, drawn in a fixed order (process, then measurement).
    # Without noise nothing is drawn (the draws would be multiplied by zero).
    noisy = bool((wstd != 0).any() or (vstd != 0).any())
    w: np.ndarray | None = None   # process noise, (M, N, n) when noisy
    v: np.ndarray | None = None   # measurement noise, (M, N + 1, q) when noisy
    if noisy:
        w, v = _draw_noise(seeds, N, n, q, wstd, vstd)

    timing = {"estimator": 0.0, "controller": 0.0, "calls": 0, "runs": M}
    if estimator is not None:
        estimator.reset(xh0.copy())
    if controller is not None and hasattr(controller, "reset"):
        controller.reset(M)
    x = integ.clip(x)
    # Input limits depend on the parameters only: rebuilt when a change applies.
    lo, hi = input_limits(plant, params, M)
    sequence = (controller.inputs if isinstance(controller, InputSequence)
                and controller.inputs.shape[0] >= N else None)
    if (controller is None or sequence is not None) and not noisy and not jump_at:
        # The inputs are known in advance (held, or a given sequence), whatever the estimate: the
        # plant does not depend on the estimator. The whole horizon in one call per stretch
        # between parameter changes (same numbers), then the estimator over its measurements.
        seq = sequence[:N] if sequence is not None else np.broadcast_to(u_prev, (N, M, m))
        done = (_open_loop_changes(integ, plant, x, seq, params, schedule, ts, int(substeps))
                if schedule else _open_loop(integ, x, seq, params, lo, hi, ts, int(substeps)))
        if done is not None:
            timing["calls"] = N
            if estimator is not None:
                done = _estimate(estimator, done, u_prev, timing)
            return _pack(*done, ref, seeds, ts, substeps, integ, timing, plant)
    compiled = _kernel_loop(plant, integ, controller, x, ref, w, v, params, schedule, jump_at, M,
                            ts, int(substeps), timing, (lo, hi)) if estimator is None else None
    if compiled is not None:
        return _pack(*compiled, ref, seeds, ts, substeps, integ, timing, plant)
    affine = getattr(controller, "affine", None)
    if affine is not None and estimator is None and not noisy and not schedule and not jump_at:
        # u_k = b_k - K (x_k - x_ref): law and plant in one CasADi call over the horizon
        b, K, x_ref = affine(N, float(ts))
        loop = affine_horizon(integ, x, np.asarray(b, dtype=float).reshape(N, m), K, x_ref, params,
                              lo, hi, ts, int(substeps))
        if loop is not None:
            timing["calls"] = N
            return _pack(*_with_outputs(integ, *loop, params), ref, seeds, ts, substeps, integ,
                         timing, plant)
    # Time-major buffers (contiguous writes per sample), returned run-major.
    X = np.empty((N + 1, M, n))
    Y = np.empty((N + 1, M, q))
    U = np.empty((N, M, m))
    XH = np.empty((N + 1, M, n))
    modes = np.zeros((N + 1, M, model.k), dtype=np.int8)
    refs = np.broadcast_to(ref[:, None, :], (N + 1, M, ref.shape[1]))
    # Inputs that do not depend on the estimate (none, a given sequence, a law whose class says
    # ``open_loop = True``: a constant input, a scenario's schedule): the estimator runs after the
    # loop over the measurements (`_estimate`: the same calls, through its horizon kernel)
    later = estimator is not None and (controller is None or sequence is not None
                                       or getattr(type(controller), "open_loop", False) is True)
    u_first = u_prev
    for k in range(N + 1):
        t_k = k * ts
        for values in schedule.get(k, ()):
            params.update({name: param_arrays(plant, values, M)[name] for name in values})
            lo, hi = input_limits(plant, params, M)
        if k in jump_at:
            x = integ.clip(x + jump_at[k])
        if not np.isfinite(x).all():
            bad = int(np.flatnonzero(~np.all(np.isfinite(x), axis=1))[0])
            raise SimulationError(f"run {bad} (seed {int(seeds[bad])}): non-finite state at sample {k}")
        X[k] = x
        if model.k:
            modes[k] = integ.bits(x, params)
        y = integ.output(x, params)
        if v is not None:   # noisy
            y = y + v[:, k]
        Y[k] = y
        if estimator is not None and not later:
            t0 = time.perf_counter()
            xh = np.asarray(estimator.step(y, u_prev), dtype=float)
            timing["estimator"] += time.perf_counter() - t0
            if xh.shape != (M, n):
                raise DimensionError(f"estimator returned shape {xh.shape}, expected ({M}, {n})")
        else:
            xh = x
        XH[k] = xh
        if k == N:
            break
        if controller is not None:
            t0 = time.perf_counter()
            u = np.asarray(controller(xh.copy(), refs[k], t_k), dtype=float)
            timing["controller"] += time.perf_counter() - t0
            if u.shape != (M, m):
                raise DimensionError(f"controller returned shape {u.shape}, expected ({M}, {m})")
        else:
            u = u_prev
        timing["calls"] += 1
        if not np.isfinite(u).all():   # (CasADi's fmin/fmax would saturate NaN to a bound)
            bad = int(np.flatnonzero(~np.all(np.isfinite(u), axis=1))[0])
            raise SimulationError(f"run {bad} (seed {int(seeds[bad])}): non-finite input at sample {k}")
        u = np.minimum(np.maximum(u, lo), hi)
        U[k] = u
        x = integ.advance(x, u, params, ts, int(substeps))
        if w is not None:   # noisy (without noise the advanced state is already clipped)
            x = integ.clip_counted(x + w[:, k])
        u_prev = u
    if later and estimator is not None:
        run_major = lambda a: np.ascontiguousarray(a.transpose(1, 0, 2))  # noqa: E731
        done = _estimate(estimator, (run_major(X), run_major(Y), run_major(U), XH, run_major(modes)),
                         u_first, timing)
        return _pack(*done, ref, seeds, ts, substeps, integ, timing, plant)
    return _result(X, Y, U, XH, ref, seeds, modes, ts, substeps, integ, timing, plant)


#: Runs of noise drawn per thread task (`_draw_noise`); fewer runs are drawn in one thread.
_NOISE_BLOCK = 512


def _draw_noise(seeds: np.ndarray, N: int, n: int, q: int, wstd: np.ndarray,
                vstd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Process (M, N, n) and measurement (M, N + 1, q) noise: one generator per run, process
    draws first. Blocks of runs drawn in threads (numpy's generators release the GIL while
    they fill): the same numbers, each run's from its own seed."""
    M = seeds.size
    w, v = np.empty((M, N, n)), np.empty((M, N + 1, q))

    def block(a: int, b: int) -> None:
        for r in range(a, b):
            rng = np.random.default_rng(int(seeds[r]))
            rng.standard_normal(out=w[r])
            rng.standard_normal(out=v[r])
        w[a:b] *= wstd
        v[a:b] *= vstd

    cuts = list(range(0, M, _NOISE_BLOCK)) + [M]
    if len(cuts) <= 2:
        block(0, M)
    else:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=max(1, min(len(cuts) - 1, os.cpu_count() or 1))) as pool:
            for job in [pool.submit(block, a, b) for a, b in zip(cuts[:-1], cuts[1:])]:
                job.result()
    return w, v


def _kernel_loop(plant: Plant, integ: Integrator, controller: Any, x: np.ndarray, ref: np.ndarray,
                 w: np.ndarray | None, v: np.ndarray | None, params: dict[str, Any],
                 schedule: Mapping[int, list], jump_at: Mapping[int, np.ndarray], M: int, ts: float,
                 substeps: int, timing: dict,
                 limits: tuple[np.ndarray, np.ndarray] | None = None) -> _Runs | None:
    """The closed loop through its compiled kernel (`tanksynth.sim.closed_loop`), or None.

    For a controller offering ``loop_law(runs)`` with the true state fed back; None (nothing
    changed, the controller's state included) when there is no kernel or a run stopped in it.
    """
    offer = getattr(controller, "loop_law", None)
    if offer is None or os.environ.get("TANKSYNTH_SIM_BACKEND", "").strip().lower() == "numpy":
        return None
    law = offer(M)
    if law is None:
        return None
    N = ref.shape[0] - 1
    kernel = loop_kernel(integ.model, law, ref.shape[1], work=float(M) * N * substeps)
    if kernel is None:
        return None

    def update(p: dict[str, Any], values: Mapping[str, Any]) -> None:
        p.update({name: param_arrays(plant, values, M)[name] for name in values})

    done = run_closed_loop(integ, kernel, law, x, ref, w, params,
                           lambda p: input_limits(plant, p, M), schedule, update, jump_at, ts,
                           substeps, first_limits=limits)
    if done is None:
        return None
    X, Y, U, modes, seconds = done
    if v is not None:   # noisy
        Y += v
    timing["controller"] += seconds
    timing["calls"] = N
    return X, Y, U, X.view(), modes      # the true state fed back: x_hat is x (read-only view)


def _open_loop(integ: Integrator, x: np.ndarray, seq: np.ndarray, params: dict[str, Any],
               lo: np.ndarray, hi: np.ndarray, ts: float, substeps: int) -> _Runs | None:
    """Open loop over a known input sequence in one `Integrator.horizon` call, or None.

    Works on run-major buffers (the result's layout: no transposed copies);
    returns ``(x, y, u, x_hat, modes)`` run-major, ``x_hat`` a read-only view
    of ``x``.
    """
    N, M = seq.shape[0], x.shape[0]
    model = integ.model
    seq = seq[:, None, :] if seq.ndim == 2 else seq
    if seq.shape[1] not in (1, M) or not np.isfinite(x).all() or not np.isfinite(seq).all():
        return None                      # (non-finite start or input: the loop names run and sample)
    Ur = np.empty((M, N, model.m))
    src = np.broadcast_to(seq, (N, M, model.m)).transpose(1, 0, 2)
    np.minimum(np.maximum(src, lo[:, None, :]), hi[:, None, :], out=Ur)
    loop = None
    if integ.native(substeps) is None and model.m and (M == 1 or np.all(seq == seq[:, :1])):
        # no compiled kernel: CasADi in chunks built once per plant (`affine_horizon` with K = 0,
        # u = sat(b) exactly) rather than `Integrator.horizon`'s mapaccum built per length N
        loop = affine_horizon(integ, x, seq[:, 0, :], np.zeros((model.m, model.n)),
                              np.zeros(model.n), params, lo, hi, ts, substeps)
    if loop is not None:
        Xr = loop[0]
    else:
        Xr = np.empty((M, N + 1, model.n))
        Xr[:, 0] = x
        if integ.horizon(x, Ur.transpose(1, 0, 2), params, ts, substeps,
                         out=Xr[:, 1:].transpose(1, 0, 2)) is None:
            return None
    Xr.flags.writeable = False
    flat = Xr.reshape(-1, model.n)
    rows = params
    if (model.output_index is None or model.k) and any(np.ndim(v) for v in params.values()):
        rows = {k: (np.repeat(v, N + 1) if np.ndim(v) else v) for k, v in params.items()}
    if model.output_index == tuple(range(model.n)):
        Y = Xr.view()                                   # y = x: the same (read-only) numbers
    elif model.output_index is not None:
        Y = Xr[:, :, list(model.output_index)]
    else:
        Y = integ.output(flat, rows).reshape(M, N + 1, model.q)
    modes = np.zeros((M, N + 1, model.k), dtype=np.int8)
    if model.k:
        modes[:] = integ.bits(flat, rows).reshape(M, N + 1, model.k)
    return Xr, Y, Ur, Xr.view(), modes


def _open_loop_changes(integ: Integrator, plant: Plant, x: np.ndarray, seq: np.ndarray,
                       params: dict[str, Any], schedule: Mapping[int, list], ts: float,
                       substeps: int) -> _Runs | None:
    """`_open_loop` over the stretches between parameter changes, or None (integrator untouched).

    As in the loop: the values changing at sample ``k`` hold from the measurement at ``k`` on
    (and the input limits naming them from the input of period ``k``).
    """
    N, M = seq.shape[0], x.shape[0]
    seq = seq[:, None, :] if seq.ndim == 2 else seq
    saved = (integ.events, integ.clipped_low, integ.clipped_high, set(integ.backends))
    p = dict(params)
    cuts = sorted(k for k in schedule if 0 < k <= N)
    parts = []
    for a, b in zip([0] + cuts, cuts + [N + 1]):
        for values in schedule.get(a, ()) if a <= N else ():
            p.update({name: param_arrays(plant, values, M)[name] for name in values})
        if b > N:                                  # the last stretch ends with sample N
            b = N
        lo, hi = input_limits(plant, p, M)
        if b > a:
            part = _open_loop(integ, x, seq[a:b], p, lo, hi, ts, substeps)
        else:                                      # a change at the last sample: its output only
            part = _with_outputs(integ, x[:, None, :], np.empty((M, 0, seq.shape[-1])), p)
        if part is None:
            integ.events, integ.clipped_low, integ.clipped_high = saved[:3]
            integ.backends = saved[3]
            return None
        parts.append(part)
        x = np.array(part[0][:, -1])
    last = len(parts) - 1
    cut = lambda arr, i: arr if i == last else arr[:, :-1]  # noqa: E731 - drop the shared sample
    X = np.concatenate([cut(q[0], i) for i, q in enumerate(parts)], axis=1)
    Y = np.concatenate([cut(q[1], i) for i, q in enumerate(parts)], axis=1)
    U = np.concatenate([q[2] for q in parts], axis=1)
    modes = np.concatenate([cut(q[4], i) for i, q in enumerate(parts)], axis=1)
    return X, Y, U, X.copy(), modes


def _with_outputs(integ: Integrator, X: np.ndarray, U: np.ndarray, params: dict[str, Any]) -> _Runs:
    """``(x, y, u, x_hat, modes)`` run-major from the states (M, N + 1, n) and inputs of a loop."""
    model = integ.model
    M, N1, n = X.shape
    flat = X.reshape(-1, n)
    rows = params
    if any(np.ndim(v) for v in params.values()):
        rows = {k: (np.repeat(v, N1) if np.ndim(v) else v) for k, v in params.items()}
    Y = integ.output(flat, rows).reshape(M, N1, model.q)
    modes = np.zeros((M, N1, model.k), dtype=np.int8)
    if model.k:
        modes[:] = integ.bits(flat, rows).reshape(M, N1, model.k)
    return X, Y, U, X.copy(), modes


def _estimate(estimator: BatchEstimator, done: _Runs, u_init: np.ndarray, timing: dict) -> _Runs:
    """The estimator over the measurements of an open-loop run: ``done`` with ``x_hat`` filled.

    The same calls as the closed loop: at sample ``k`` the estimator gets ``(y_k, u_{k-1})``
    with ``u_{-1} = u_init`` (as given) and then the saturated inputs held.
    """
    X, Y, U, _, modes = done
    M, N1, n = X.shape
    t0 = time.perf_counter()
    run = getattr(estimator, "run", None)
    if run is not None:              # the whole sequence in one call (the same steps)
        Us = np.empty((N1, M, U.shape[2]))
        Us[0] = u_init
        Us[1:] = U.transpose(1, 0, 2)
        XH = run(np.ascontiguousarray(Y.transpose(1, 0, 2)), Us)
        if XH is not None:
            XH = np.asarray(XH, dtype=float)
            if XH.shape != (N1, M, n):
                raise DimensionError(f"estimator returned shape {XH.shape[1:]}, expected ({M}, {n})")
            timing["estimator"] += time.perf_counter() - t0
            return X, Y, U, np.ascontiguousarray(XH.transpose(1, 0, 2)), modes
    XH = np.empty((N1, M, n))
    u_prev = u_init
    for k in range(N1):
        xh = np.asarray(estimator.step(np.array(Y[:, k]), u_prev), dtype=float)
        if xh.shape != (M, n):
            raise DimensionError(f"estimator returned shape {xh.shape}, expected ({M}, {n})")
        XH[k] = xh
        if k < N1 - 1:
            u_prev = np.array(U[:, k])
    timing["estimator"] += time.perf_counter() - t0
    return X, Y, U, np.ascontiguousarray(XH.transpose(1, 0, 2)), modes


def _result(X: np.ndarray, Y: np.ndarray, U: np.ndarray, XH: np.ndarray, ref: np.ndarray,
            seeds: np.ndarray, modes: np.ndarray, ts: float, substeps: int, integ: Integrator,
            timing: dict, plant: Plant) -> SimulationResult:
    """The read-only, run-major result from the time-major buffers."""
    run_major = lambda a: np.ascontiguousarray(a.transpose(1, 0, 2))  # noqa: E731
    return _pack(run_major(X), run_major(Y), run_major(U), run_major(XH), run_major(modes), ref,
                 seeds, ts, substeps, integ, timing, plant)


def _pack(x: np.ndarray, y: np.ndarray, u: np.ndarray, x_hat: np.ndarray, modes: np.ndarray,
          ref: np.ndarray, seeds: np.ndarray, ts: float, substeps: int, integ: Integrator,
          timing: dict, plant: Plant) -> SimulationResult:
    """The read-only result from run-major arrays."""
    arrays = dict(t=np.arange(x.shape[1]) * float(ts), x=x, y=y, u=u, x_hat=x_hat, reference=ref,
                  seeds=seeds.copy(), modes=modes)
    for arr in arrays.values():
        arr.flags.writeable = False
    return SimulationResult(**arrays, ts=float(ts), substeps=int(substeps), events=integ.events,
                            clipped_low=integ.clipped_low, clipped_high=integ.clipped_high,
                            timing=timing, plant=plant.name,
                            backend="+".join(sorted(integ.backends)))


def simulate_inputs(plant: Plant, x0: Any, inputs: Any, ts: float, *, substeps: int = 10,
                    parameters: Mapping[str, Any] | None = None) -> SimulationResult:
    """Open-loop runs of the plant under given input sequences, without noise.

    `simulate` with an `InputSequence`: the data behind estimator tests and
    the NARX training data (one integrator, one clipping rule).

    Parameters
    ----------
    plant : Plant
    x0 : array_like, shape (n,) or (M, n)
        Initial states (state units).
    inputs : array_like, shape (N, m) or (N, M, m)
        Input held over each period (input units; saturated to the
        actuators' range like every simulated input).
    ts : float
        Sampling period (s).
    substeps : int
        RK4 steps per period.
    parameters : mapping, optional
        Plant parameter values (see `simulate`).

    Returns
    -------
    SimulationResult
        ``x`` has shape (M, N + 1, n): the states at ``t_0 .. t_N``.
    """
    U = np.asarray(inputs, dtype=float)
    if U.ndim not in (2, 3) or U.shape[-1] != plant.m:
        raise DimensionError(f"inputs must have shape (N, {plant.m}) or (N, M, {plant.m}), got "
                             f"{U.shape}")
    X0 = np.asarray(x0, dtype=float)
    runs = U.shape[1] if U.ndim == 3 else (X0.shape[0] if X0.ndim == 2 else 1)
    return simulate(plant, ts=ts, steps=U.shape[0], x0=X0, seeds=np.zeros(runs, dtype=np.uint64),
                    controller=InputSequence(U), u_init=U[0], parameters=parameters,
                    substeps=substeps)
