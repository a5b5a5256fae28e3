"""The one integrator of the plant: RK4, one clipping rule, explicit hybrid switching.

Every simulation of a plant in the toolbox goes through this module:

* the batch simulator (`tanksynth.sim.simulate`) and any verdict that needs
  one sampling period of the nominal plant use `Integrator` (M runs at
  once, per-run parameters): the plant's compiled C kernel when available
  (`tanksynth.sim.kernel`, driven by `tanksynth.sim.native`), else the
  CasADi period function (small batches) or the generated numpy code
  (`tanksynth.sim.tape`), all bit for bit equal;
* design code that needs the step as a CasADi expression (the ISE tuning of
  the inverse-dynamics gains, laws evaluated at every Runge-Kutta stage)
  builds it with `symbolic_rk4` / `casadi_step` (`tanksynth.sim.symbolic`,
  re-exported here);
* a linear system (the fault-detection residual of plant and observer) is
  advanced by `rk4_matrix`, the same step written as a matrix (likewise).

The scheme, identical in all three: classical RK4 (`tanksynth.plants.compile.rk4_step`,
the one formula, shared with the estimators' prediction models), stage
states clipped to the plant's bounds before the vector field is evaluated,
the end state of every step clipped (`Plant.state_bounds`: levels never
below zero nor above the overflow height ``hmax`` where the plant has one),
inputs saturated to the actuators' range. Hybrid switching is explicit: after
each step the mode bits ``[s_j(x) > 0]`` at its start and end are compared;
the numeric integrator re-integrates a run whose mode changed up to the
crossing (bisection on the step fraction, to ``2**-event_iterations`` of the
step), then from just past the surface to the end of the step, so RK4 never
straddles a switching surface. The symbolic step cannot branch per run: it
returns a ``crossed`` flag instead, and its users hand the flagged runs to
the numeric integrator (so both give the same numbers, tested to rounding).
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np

from tanksynth.errors import DimensionError
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import rk4_step
from tanksynth.sim.csource import MAX_SUBSTEPS
from tanksynth.sim import native
from tanksynth.sim.kernel import NativeKernel, native_kernel
from tanksynth.sim.symbolic import SymbolicStep, casadi_step, rk4_matrix, symbolic_rk4
from tanksynth.sim.tape import CASADI_MAX_RUNS, CASADI_MAX_RUNS_HYBRID, NumpyModel, numpy_model

# numpy's element-wise clip ufunc (one call instead of maximum + minimum; same NaN rule)
_clip = getattr(getattr(getattr(np, "_core", None), "umath", None), "clip", None) or np.clip

__all__ = [
    "Integrator",
    "param_arrays",
    "input_limits",
    "SymbolicStep",
    "symbolic_rk4",
    "casadi_step",
    "rk4_matrix",
]


#: id(plant) -> (plant, (hmax, parameter values), lower, upper): the plant's state bounds.
_BOUNDS: dict[int, tuple] = {}


# ----------------------------------------------------------------------------- parameters
def param_arrays(plant: Plant, overrides: Mapping[str, Any] | None, count: int) -> dict[str, Any]:
    """The plant's parameter values for a batch, with overrides.

    Parameters
    ----------
    plant : Plant
    overrides : mapping, optional
        Parameter name -> a float (all runs) or an array of ``count`` values
        (one per run), in the parameter's unit.
    count : int
        Number of runs M.

    Returns
    -------
    dict
        Every parameter name -> float or ndarray (M,).

    Raises
    ------
    DimensionError
        Unknown parameter name or an array of the wrong shape.
    """
    values: dict[str, Any] = {prm.name: float(prm.value) for prm in plant.parameters}
    for name, v in (overrides or {}).items():
        if name not in values:
            raise DimensionError(f"unknown parameter {name!r} of plant '{plant.name}'")
        arr = np.asarray(v, dtype=float)
        if arr.ndim == 0:
            values[name] = float(arr)
        elif arr.shape == (count,):
            values[name] = arr.copy()
        else:
            raise DimensionError(f"parameter {name} has shape {arr.shape}: expected () or ({count},)")
    return values


def input_limits(plant: Plant, params: Mapping[str, Any], count: int) -> tuple[np.ndarray, np.ndarray]:
    """Actuator range of each run, ``(lower, upper)`` each (M, m), input units.

    Bounds naming a parameter (e.g. ``"Qmax"``) take its value in ``params``
    (per run when it is an array).

    Parameters
    ----------
    plant : Plant
        The plant model (its input bounds).
    params : mapping of str
        Parameter values (scalars or one per run, SI units).
    count : int
        Number of runs M.
    """
    lo = np.full((count, plant.m), -np.inf)
    hi = np.full((count, plant.m), np.inf)
    for j, pair in enumerate(plant.input_bounds):
        for arr, b in ((lo, pair[0]), (hi, pair[1])):
            arr[:, j] = params[b] if isinstance(b, str) else float(b)
    return lo, hi


# ----------------------------------------------------------------------------- numeric
class Integrator:
    """RK4 of a plant over M runs, with clipping and explicit switching-surface location.

    Parameters
    ----------
    model : NumpyModel
        The plant's numpy tapes (`tanksynth.sim.tape.numpy_model`).
    lower, upper : ndarray, shape (n,)
        State bounds (the plant's `Plant.state_bounds`).
    event_iterations : int
        Bisection iterations locating a crossing (0: no location).
    max_splits : int
        Crossings handled inside one step (more are integrated across).
    work : float, optional
        RK4 run-steps the caller expects to integrate (runs x periods x steps):
        decides whether compiling the plant's kernel pays
        (`tanksynth.sim.kernel.native_kernel`); None: use a kernel only if
        one is already built.

    Attributes
    ----------
    events : int
        Crossings located so far (all runs).
    clipped_low, clipped_high : int
        Clipping operations after which some state sat on its lower/upper bound
        because it had passed it.
    backends : set of str
        Routes that integrated periods so far: ``"native"`` (the compiled C
        kernel, `tanksynth.sim.kernel`), ``"casadi"`` (the CasADi period
        function) or ``"numpy"`` (the generated numpy code); runs whose hybrid
        mode changed inside a period are always re-integrated by the numpy
        code (not listed).
    """

    def __init__(self, model: NumpyModel, lower: np.ndarray, upper: np.ndarray,
                 event_iterations: int = 12, max_splits: int = 3, work: float | None = None):
        self.model = model
        self.work = work
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.iterations = int(event_iterations)
        self.max_splits = max(int(max_splits), 1)
        self.events = 0
        self.clipped_low = 0
        self.clipped_high = 0
        self._cache_key: tuple | None = None
        self._cache: tuple = ((), ())
        self._finite_values: tuple = (None, True)        # (_cache it was computed for, finite)
        self._buffers: dict[tuple, Any] = {}
        self._rows: tuple | None = None
        self._kernel: NativeKernel | None | bool = False     # False: not asked for yet
        self._tables: tuple = ((), None, None)
        self.backends: set[str] = set()

    @classmethod
    def for_plant(cls, plant: Plant, params: Mapping[str, Any] | None = None, *,
                  bounds: tuple[np.ndarray, np.ndarray] | None = None, event_iterations: int = 12,
                  max_splits: int = 3, work: float | None = None) -> "Integrator":
        """The integrator of ``plant``: its numpy model and its `Plant.state_bounds`.

        Parameters
        ----------
        plant : Plant
        params : mapping, optional
            Parameter values (only ``hmax`` enters the bounds).
        bounds : (lower, upper), optional
            Other state bounds (state units), instead of the plant's rule.
        event_iterations, max_splits : int
            See the class.
        work : float, optional
            See the class.
        """
        if bounds is not None:
            lower, upper = bounds
        else:
            hmax = (params or {}).get("hmax")
            key = (None if hmax is None or np.ndim(hmax) else float(hmax),
                   tuple(prm.value for prm in plant.parameters))
            held = _BOUNDS.get(id(plant))
            if held is not None and held[0] is plant and held[1] == key:
                lower, upper = held[2], held[3]
            else:
                lower, upper = plant.state_bounds({} if hmax is None else {"hmax": hmax})
                lower.flags.writeable = upper.flags.writeable = False
                if key[0] is not None or hmax is None:
                    _BOUNDS[id(plant)] = (plant, key, lower, upper)
                    while len(_BOUNDS) > 64:
                        del _BOUNDS[next(iter(_BOUNDS))]
        return cls(numpy_model(plant), lower, upper, event_iterations, max_splits, work)

    def clip(self, x: np.ndarray) -> np.ndarray:
        """States clipped to the bounds (the one clipping rule).

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        """
        return np.minimum(np.maximum(x, self.lower), self.upper)

    def rk4(self, x: np.ndarray, u: np.ndarray, p: Mapping[str, Any], h: np.ndarray | float) -> np.ndarray:
        """One RK4 step of ``h`` s (a float, or one per run, shape (M,)), stages clipped.

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        u : ndarray, shape (M, m)
            Inputs held over the step (input units, m^3/s).
        p : mapping of str
            Parameter values (scalars or one per run, SI units).
        h : float or ndarray, shape (M,)
            Step length [s].
        """
        h = h if np.ndim(h) == 0 else np.asarray(h)[:, None]
        return rk4_step(lambda s: self.model.rhs(s, u, p), x, h, self.clip)

    def bits(self, x: np.ndarray, p: Mapping[str, Any]) -> np.ndarray:
        """Mode bits ``s_j(x) > 0``, shape (M, k).

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        p : mapping of str
            Parameter values (scalars or one per run, SI units).
        """
        pv, c = self._values(p)
        return (self.model.switching_rows(np.asarray(x, dtype=float).T, c, pv) > 0).T

    def output(self, x: np.ndarray, p: Mapping[str, Any]) -> np.ndarray:
        """The plant's output ``h(x)`` at M states (M, n) -> (M, q), output units.

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        p : mapping of str
            Parameter values (scalars or one per run, SI units).
        """
        pv, c = self._values(p)
        return self.model.output_rows(np.asarray(x, dtype=float).T, c, pv).T

    def step(self, x: np.ndarray, u: np.ndarray, p: Mapping[str, Any], h: float) -> np.ndarray:
        """Advance every run by ``h`` seconds (one RK4 step, split at crossings), clipped.

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        u : ndarray, shape (M, m)
            Inputs held over the step (input units, m^3/s).
        p : mapping of str
            Parameter values (scalars or one per run, SI units).
        h : float
            Step length [s].
        """
        return self.advance(x, u, p, h, 1)

    def advance(self, x: np.ndarray, u: np.ndarray, p: Mapping[str, Any], ts: float,
                substeps: int) -> np.ndarray:
        """One sampling period ``ts`` (s) under the held input ``u``: ``substeps`` steps.

        ``u`` is used as given (saturate it first, see `input_limits`). The
        period is one call of the plant's compiled C kernel (`native`) when
        a C compiler works; otherwise, up to `CASADI_MAX_RUNS` runs, one call
        of the plant's CasADi period function, and above, the generated numpy
        code on the row layout (n, M). Runs whose mode changed are
        re-integrated by the numpy code, which locates the crossing. All
        routes give the same numbers bit for bit.

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States at the start (state units).
        u : ndarray, shape (M, m)
            Held inputs (input units).
        p : mapping
            Parameter values (floats or (M,) arrays).
        ts : float
            Length of the period (s).
        substeps : int
            RK4 steps in the period.

        Returns
        -------
        ndarray, shape (M, n)
            States at the end of the period, clipped (state units).
        """
        substeps = int(substeps)
        h = float(ts) / substeps
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        limit = CASADI_MAX_RUNS_HYBRID if self.model.k else CASADI_MAX_RUNS
        kernel = self.native(substeps) if x.shape[0] else None
        if kernel is not None:
            x1, low, high = native.period(self, kernel, x, u, p, h, substeps)
            self.backends.add("native")
        elif (0 < x.shape[0] <= limit and self.model.n and self.lower.ndim == 1
              and self.upper.ndim == 1 and self._finite(x, u, p)):
            x1, low, high = self._period_casadi(x, u, p, h, substeps)
            self.backends.add("casadi")
        else:
            x1, low, high = self._period_rows(x, u, p, h, substeps)
            self.backends.add("numpy")
        self.clipped_low += int(np.count_nonzero(low))
        self.clipped_high += int(np.count_nonzero(high))
        return x1

    def native(self, substeps: int) -> NativeKernel | None:
        """The plant's compiled kernel for this integrator, or None (then CasADi/numpy).

        None when the bounds are per run, ``substeps`` exceeds
        `tanksynth.sim.csource.MAX_SUBSTEPS`, or no kernel could be built
        (`tanksynth.sim.kernel.kernel_status` says why).

        Parameters
        ----------
        substeps : int
            RK4 steps per period.
        """
        if not (self.model.n and self.lower.ndim == 1 and self.upper.ndim == 1
                and 1 <= int(substeps) <= MAX_SUBSTEPS):
            return None
        if self._kernel is False:
            self._kernel = native_kernel(self.model, self.work)
        return self._kernel  # type: ignore[return-value]

    def _values(self, p: Mapping[str, Any]) -> tuple[list, tuple]:
        """Parameter values in the model's order and their constants (cached by identity)."""
        pv = self.model.parameter_values(p)
        key = tuple(map(id, pv))
        if self._cache_key != key:
            self._cache_key, self._cache = key, (pv, self.model.constants(pv))
        return self._cache

    def _finite(self, x: np.ndarray, u: np.ndarray, p: Mapping[str, Any]) -> bool:
        """States, inputs and parameter values all finite (the parameters' test cached with them).

        The CasADi period function clips with ``fmin``/``fmax``, which return the other
        operand for a NaN: a NaN state would become a bound, a finite trajectory where the
        numpy code (and the native kernel) propagate it and the loop reports it.
        """
        if not (np.isfinite(x).all() and np.isfinite(u).all()):
            return False
        values = self._values(p)
        if self._finite_values[0] is not values:
            self._finite_values = (values, all(np.isfinite(v).all() for v in (*values[0], *values[1])))
        return self._finite_values[1]

    def _run_matrices(self, pv: list, c: tuple, count: int) -> tuple[np.ndarray, np.ndarray]:
        """Constants and parameter values as (count, width) matrices, one row per run (scalars
        broadcast), the layout of the CasADi period functions' inputs."""
        cm = np.empty((count, self.model.n_constants))
        pm = np.empty((count, len(pv)))
        for j, v in enumerate(c):
            cm[:, j] = v
        for j, v in enumerate(pv):
            pm[:, j] = v
        return cm, pm

    def _row_bounds(self) -> tuple[Callable, Callable, Callable]:
        """Clipping ``clip(src, dst)`` on the row layout and the tests ``below``/``above``.

        Scalar bounds when every state has the same (one numpy call on all
        rows), else one call per row; NaN propagates as in `clip`.
        """
        if self._rows is not None:
            return self._rows
        lo, hi = self.lower, self.upper
        if lo.ndim == 1 and hi.ndim == 1 and lo.size and np.all(lo == lo[0]) and np.all(hi == hi[0]):
            a, b = float(lo[0]), float(hi[0])

            def clip(src: np.ndarray, dst: np.ndarray) -> None:
                _clip(src, a, b, out=dst)

            def below(v: np.ndarray) -> bool:
                return bool(v.min() < a) if v.size else False

            def above(v: np.ndarray) -> bool:
                return bool(v.max() > b) if v.size else False
        else:
            lo_t = lo[:, None] if lo.ndim == 1 else lo.T
            hi_t = hi[:, None] if hi.ndim == 1 else hi.T

            def clip(src: np.ndarray, dst: np.ndarray) -> None:
                np.minimum(np.maximum(src, lo_t, out=dst), hi_t, out=dst)

            def below(v: np.ndarray) -> bool:
                return bool(np.any(v < lo_t))

            def above(v: np.ndarray) -> bool:
                return bool(np.any(v > hi_t))
        self._rows = (clip, below, above)
        return self._rows

    def _period_rows(self, x: np.ndarray, u: np.ndarray, p: Mapping[str, Any], h: float,
                     substeps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The period on the row layout: end states (M, n), clipping flags per step."""
        model = self.model
        pv, c = self._values(p)
        n, count = model.n, x.shape[0]
        clip, below, above = self._row_bounds()
        xt = np.array(x.T, order="C")
        stage = np.empty((n, count))
        k1, k2, k3, k4 = (np.empty((n, count)) for _ in range(4))
        rows = [*stage, *np.array(u.T, order="C")]
        f = model.rhs_rows_unguarded     # under the errstate of the whole period, below
        low = np.zeros(substeps, dtype=bool)
        high = np.zeros(substeps, dtype=bool)
        half = 0.5 * h
        with np.errstate(invalid="ignore", divide="ignore"):
            for i in range(substeps):
                clip(xt, stage)
                f(rows, c, pv, k1)
                for k_in, k_out, w in ((k1, k2, half), (k2, k3, half), (k3, k4, h)):
                    np.multiply(k_in, w, out=stage)
                    stage += xt
                    clip(stage, stage)
                    f(rows, c, pv, k_out)
                # x + h/6 (k1 + 2 k2 + 2 k3 + k4), summed in this order (the one RK4 formula)
                acc = np.multiply(k2, 2.0, out=k2)
                acc += k1
                acc += np.multiply(k3, 2.0, out=k3)
                acc += k4
                acc *= h / 6.0
                x1 = xt + acc
                if model.k:
                    crossed = np.any((model.switching_rows(xt, c, pv) > 0)
                                     != (model.switching_rows(x1, c, pv) > 0), axis=0)
                    if crossed.any():
                        x1 = np.array(self._split(xt.T, np.array(x1.T), u, p, h).T, order="C")
                low[i] = below(x1)
                high[i] = above(x1)
                clip(x1, x1)
                xt = x1
        return np.array(xt.T, order="C"), low, high

    def _period_casadi(self, x: np.ndarray, u: np.ndarray, p: Mapping[str, Any], h: float,
                       substeps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The period through the CasADi period function (in place, `casadi.FunctionBuffer`)."""
        model = self.model
        count = x.shape[0]
        pv, c = self._values(p)
        slot = self._buffers.get((substeps, count))
        if slot is None:
            args = [np.empty((count, model.n)), np.empty((count, model.m)),
                    np.empty((count, model.n_constants)), np.empty((count, len(pv))),
                    np.empty((count, 1)),
                    np.broadcast_to(self.lower, (count, model.n)).copy(),
                    np.broadcast_to(self.upper, (count, model.n)).copy()]
            res = [np.empty((count, model.n)), np.empty((count, 1)), np.empty((count, substeps)),
                   np.empty((count, substeps))]
            buf, run = model.casadi_advance(substeps, count).buffer()
            for j, a in enumerate(args):
                buf.set_arg(j, a.data)
            for j, r in enumerate(res):
                buf.set_res(j, r.data)
            slot = self._buffers[(substeps, count)] = [args, res, buf, run, None]
        args, res, _, run, filled = slot
        args[0][...] = x
        args[1][...] = u
        args[4][...] = h
        if filled is not self._cache_key:
            for j, v in enumerate(c):
                args[2][:, j] = v
            for j, v in enumerate(pv):
                args[3][:, j] = v
            slot[4] = self._cache_key
        run()
        x1, crossed, low, high = res[0].copy(), res[1], res[2], res[3]
        if not crossed.any():                    # flags are exactly 0.0 or 1.0
            return x1, low.max(axis=0) > 0.5, high.max(axis=0) > 0.5
        low, high = low > 0.5, high > 0.5
        hit = np.flatnonzero(crossed[:, 0] > 0.5)
        if hit.size:
            sub = {k: (v[hit] if np.ndim(v) else v) for k, v in p.items()}
            x1[hit], low_hit, high_hit = self._period_rows(x[hit], u[hit], sub, h, substeps)
            self._cache_key = None
            rest = np.ones(count, dtype=bool)
            rest[hit] = False
            low = np.any(low[rest], axis=0) | low_hit
            high = np.any(high[rest], axis=0) | high_hit
        else:
            low, high = low.any(axis=0), high.any(axis=0)
        return x1, low, high

    def horizon(self, x: np.ndarray, U: np.ndarray, p: Mapping[str, Any], ts: float,
                substeps: int, out: np.ndarray | None = None) -> np.ndarray | None:
        """Open loop over a whole input sequence in one call, or None.

        With the compiled kernel (`native`): one call for every run and
        period; a run whose hybrid mode changes in a period stops there, that
        period is re-integrated by the numpy code (crossing located) and the
        kernel resumes from the next one. Without it: the CasADi period
        function accumulated over the ``N`` periods (``mapaccum``) and mapped
        over the runs. Both give the numbers of `advance`, bit for bit.
        Returns None, having changed nothing, when this path does not apply
        (no kernel and too many runs or no CasADi form, or, on the CasADi
        route, non-finite data or a period that changed a hybrid mode) or a
        state became non-finite:
        the caller then steps period by period.

        Parameters
        ----------
        x : ndarray, shape (M, n)
            Clipped states at the start (state units).
        U : ndarray, shape (N, M, m)
            Saturated inputs held over each period (input units).
        p : mapping
            Parameter values (floats or (M,) arrays), constant over the horizon.
        ts : float
            Sampling period (s).
        substeps : int
        out : ndarray, shape (N, M, n), optional
            Buffer for the result (any strides, e.g. ``X[:, 1:].transpose(1, 0,
            2)`` of a run-major ``X``; last axis contiguous); may be written even
            when None is returned.

        Returns
        -------
        ndarray, shape (N, M, n) or None
            States at the end of every period (state units; ``out`` when given).
        """
        model = self.model
        N, count = U.shape[0], x.shape[0]
        substeps = int(substeps)
        kernel = self.native(substeps) if count and N else None
        if kernel is not None:
            return native.horizon(self, kernel, x, U, p, float(ts) / substeps, substeps, out)
        limit = CASADI_MAX_RUNS_HYBRID if model.k else CASADI_MAX_RUNS
        if not (0 < count <= limit and N > 0 and model.n and self.lower.ndim == 1
                and self.upper.ndim == 1 and self._finite(x, U, p)):
            return None
        pv, c = self._values(p)
        key = ("horizon", substeps, N, count)
        fn = model.compiled.get(key)
        if fn is None:
            fn = model.casadi_advance(substeps, 1).mapaccum(N)
            fn = fn if count == 1 else fn.map(count, "serial")
            model.compiled[key] = fn
        rep = lambda a: np.ascontiguousarray(np.broadcast_to(  # noqa: E731
            np.asarray(a, dtype=float)[:, None, :], (count, N, a.shape[-1])))
        cm, pm = self._run_matrices(pv, c, count)
        args = [np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(U.transpose(1, 0, 2)),
                rep(cm), rep(pm), np.full((count, N, 1), float(ts) / substeps),
                rep(np.broadcast_to(self.lower, (count, model.n))),
                rep(np.broadcast_to(self.upper, (count, model.n)))]
        res = [np.empty((count, N, model.n)), np.empty((count, N, 1)),
               np.empty((count, N, substeps)), np.empty((count, N, substeps))]
        buf, run = fn.buffer()
        for j, a in enumerate(args):
            buf.set_arg(j, a.data)
        for j, r in enumerate(res):
            buf.set_res(j, r.data)
        run()
        X, crossed, low, high = res
        if crossed.any() or not np.isfinite(X).all():
            return None
        self.clipped_low += int(np.count_nonzero(low.max(axis=0) > 0.5))
        self.clipped_high += int(np.count_nonzero(high.max(axis=0) > 0.5))
        self.backends.add("casadi")
        if out is not None:
            out[...] = X.transpose(1, 0, 2)
            return out
        return X.transpose(1, 0, 2)

    def clip_counted(self, x: np.ndarray) -> np.ndarray:
        """Clip, counting the clipping events (the step or noise overshot a bound).

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        """
        self.clipped_low += int((x < self.lower).any())
        self.clipped_high += int((x > self.upper).any())
        return self.clip(x)

    def _split(self, x: np.ndarray, x1: np.ndarray, u: np.ndarray, p: Mapping[str, Any],
               h: float) -> np.ndarray:
        crossed = np.any(self.bits(x, p) != self.bits(x1, p), axis=1)
        if not crossed.any():
            return x1
        idx = np.flatnonzero(crossed)
        sub = lambda q, i: {k: (v[i] if np.ndim(v) else v) for k, v in q.items()}  # noqa: E731
        cur, uc, pc = x[idx], u[idx], sub(p, idx)
        left = np.full(idx.size, float(h))
        for split in range(self.max_splits):
            b0 = self.bits(cur, pc)
            lo = np.zeros(idx.size)
            hi = np.ones(idx.size)
            for _ in range(self.iterations):
                mid = 0.5 * (lo + hi)
                changed = np.any(self.bits(self.rk4(cur, uc, pc, mid * left), pc) != b0, axis=1)
                hi = np.where(changed, mid, hi)
                lo = np.where(changed, lo, mid)
            self.events += idx.size
            # Just past the first crossing, then the rest of the step from there.
            cur = self.clip(self.rk4(cur, uc, pc, hi * left))
            left = (1.0 - hi) * left
            end = self.rk4(cur, uc, pc, left)
            again = np.any(self.bits(cur, pc) != self.bits(end, pc), axis=1)
            if split == self.max_splits - 1 or not again.any():
                x1[idx] = end
                break
            done = ~again
            x1[idx[done]] = end[done]
            idx, cur, uc, left = idx[again], cur[again], uc[again], left[again]
            pc = sub(pc, again)
        return x1
