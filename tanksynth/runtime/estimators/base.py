"""Common machinery of the state estimators: one interface, single and batch runs.

Every estimator is built from a plant and a frozen *tuning* (the artefact:
gains, ``Q``, ``R``, ``P0``, window, weights) and runs through the same
interface:

* ``est.step(y, u) -> x_hat`` for one run (``y`` shape (q,), ``u`` shape
  (m,), result shape (n,)), or, for an estimator made with ``runs=M``, for
  ``M`` independent runs at once (``y`` (M, q), ``u`` (M, m) or (m,),
  result (M, n)). ``est.batch(M)`` makes the batch twin of a single-run
  estimator; a batch run equals ``M`` single runs bit for bit.
* ``u`` is the input held over the sampling interval that ends at the
  measurement ``y`` (seed 000 eq. 30 and seed 002 eq. 13 both predict
  ``x(k|k-1) = F(x(k-1), u(k))``): a simulator that applies ``u[k-1]`` on
  ``[t_{k-1}, t_k)`` and then measures ``y[k]`` calls ``step(y[k], u[k-1])``.

Two implementations share that interface:

* `KernelEstimator`: the whole step (prediction, update, Joseph-form
  covariance, positive-definiteness pivots) is one CasADi SX function built
  once from the plant's compiled functions and evaluated on numpy buffers
  (``casadi.Function.buffer``) with no per-step conversion; ``M`` runs go
  through ``Function.map``. With a C compiler on the machine the kernel is
  compiled to native code once and cached (``backend="native"``; the cache's
  location and `clear_cache` are in `tanksynth.runtime.estimators.kernels`),
  otherwise CasADi's virtual machine evaluates it (``backend="vm"``).
* `ArrayEstimator`: vectorised numpy over the run axis, for the linear-model
  filters (adaptive Kalman, adaptive scaling, consensus, Luenberger).

Covariances are updated in Joseph form and symmetrised; a covariance that
stops being positive definite (or a state that stops being finite) raises
`CovarianceError` naming the step, the run and the matrix, never a silent
NaN. The estimator keeps its last valid state when that happens.

The pieces live in sibling modules and are re-exported here: the tuning
validator (`tanksynth.runtime.estimators.tuning`), the sampled model
(`tanksynth.runtime.estimators.model`), SX helpers and native kernels
(`tanksynth.runtime.estimators.kernels`).
"""

from __future__ import annotations

import abc
import math
from typing import Any, Callable

import casadi as ca
import numpy as np

from tanksynth.analysis.matrices import symmetrize
from tanksynth.errors import CovarianceError, DimensionError, SpecError, TanksynthError
from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.horizon import (BUILD_STEPS, CHUNK, Horizon, horizon_backend,
                                                  horizon_function, observed_step)
from tanksynth.runtime.estimators.kernels import (native_function, sx_cholesky, sx_spd_inverse,
                                                  sx_symmetrize)
from tanksynth.runtime.estimators.model import (DiscreteModel, PlantDimensions, discrete_model,
                                                regularized_jacobian)
from tanksynth.runtime.estimators.tuning import as_matrix, as_spd, as_vector, positive_int

__all__ = [
    "CovarianceError",
    "DiscreteModel",
    "discrete_model",
    "regularized_jacobian",
    "Estimator",
    "KernelEstimator",
    "CovarianceKernelEstimator",
    "ArrayEstimator",
    "as_matrix",
    "as_vector",
    "as_spd",
    "sx_cholesky",
    "sx_spd_inverse",
    "sx_symmetrize",
    "joseph_update",
    "mv",
    "per_run",
    "column_major",
    "BACKENDS",
]

#: Kernel evaluation back ends (``"auto"`` = native when a C compiler works).
BACKENDS = ("auto", "native", "vm")


class Estimator(PlantDimensions, abc.ABC):
    """Interface of every estimator (single run or ``runs`` parallel runs).

    Subclasses implement `_advance` (one step on the run-stacked state) and
    the state bookkeeping; this class validates ``y`` and ``u`` and counts
    steps.

    Attributes
    ----------
    plant : Plant
    tuning : frozen dataclass
        The design (the artefact).
    runs : int or None
        None for a single run, else the number of parallel runs ``M``.
    k : int
        Steps taken since the last reset.
    """

    #: Method name used in artefacts.
    method: str = "estimator"

    def __init__(self, plant: Plant, tuning: Any, runs: int | None):
        if runs is not None:
            runs = positive_int(runs, "runs")
        self.plant = plant
        self.tuning = tuning
        self.runs = runs
        self.k = 0
        self._n, self._m, self._q = plant.n, plant.m, plant.q
        self._no_input = np.zeros((1 if runs is None else runs, 0))

    # -- dimensions (n, m, q: from PlantDimensions) ----------------------------------
    @property
    def _M(self) -> int:
        return 1 if self.runs is None else self.runs

    # -- input checks -----------------------------------------------------------------
    def _inputs(self, y: Any, u: Any) -> tuple[np.ndarray, np.ndarray]:
        """Validate ``y`` and ``u`` and return them as (M, q), (M, m) arrays."""
        M, q, m = self._M, self._q, self._m
        Y = np.asarray(y, dtype=float)
        if self.runs is None:
            if Y.shape != (q,) and not (q == 1 and Y.shape == ()):
                raise DimensionError(f"y must have shape ({q},) for a single run, got {Y.shape}")
            Y = Y.reshape(1, q)
        elif Y.shape != (M, q):
            raise DimensionError(f"y must have shape ({M}, {q}) for {M} runs, got {Y.shape}")
        if u is None:
            if m:
                raise DimensionError(f"u is required: the plant has {m} inputs")
            U = self._no_input
        else:
            U = np.asarray(u, dtype=float)
            if self.runs is None:
                if U.shape != (m,) and not (m == 1 and U.shape == ()):
                    raise DimensionError(f"u must have shape ({m},) for a single run, got {U.shape}")
                U = U.reshape(1, m)
            elif U.shape == (m,):
                U = np.broadcast_to(U, (M, m))
            elif U.shape != (M, m):
                raise DimensionError(f"u must have shape ({M}, {m}) or ({m},) for {M} runs, "
                                     f"got {U.shape}")
        if self.runs is None:
            finite = all(map(math.isfinite, Y[0].tolist())) and all(map(math.isfinite, U[0].tolist()))
        else:
            finite = bool(np.isfinite(Y).all() and np.isfinite(U).all())
        if not finite:
            raise DimensionError(f"step {self.k + 1}: y and u must be finite")
        return Y, U

    # -- public API -------------------------------------------------------------------
    def step(self, y: Any, u: Any = None) -> np.ndarray:
        """Take one measurement and return the state estimate.

        Parameters
        ----------
        y : array_like, shape (q,) or (M, q)
            Measurement at ``t_k`` (output units).
        u : array_like, shape (m,) or (M, m) (or (m,) for all runs)
            Input held over ``[t_{k-1}, t_k)`` (input units).

        Returns
        -------
        ndarray, shape (n,) or (M, n)
            ``x_hat(k)`` in state units (a copy).

        Raises
        ------
        DimensionError
            Wrong shapes or non-finite ``y``/``u``.
        CovarianceError
            A covariance stopped being positive definite at this step.
        """
        Y, U = self._inputs(y, u)
        X = self._advance(Y, U)
        self.k += 1
        return X[0].copy() if self.runs is None else X.copy()

    def run(self, Y: Any, U: Any) -> np.ndarray:
        """Filter a whole sequence.

        Parameters
        ----------
        Y : array_like, shape (N, q) (single) or (N, M, q) (batch)
        U : array_like, shape (N, m) (single) or (N, M, m) / (N, m) (batch)

        Returns
        -------
        ndarray, shape (N, n) or (N, M, n)
        """
        Y = np.asarray(Y, dtype=float)
        U = np.asarray(U, dtype=float)
        if Y.ndim < 1 or U.ndim < 1 or len(Y) != len(U):
            raise DimensionError(f"Y and U must have the same number of steps, got {Y.shape} and "
                                 f"{U.shape}")
        out = np.empty((len(Y), *(((self.n,)) if self.runs is None else (self.runs, self.n))))
        M, q, m = self._M, self._q, self._m
        if (self.runs is not None and m and Y.shape == (len(Y), M, q) and U.shape == (len(Y), M, m)
                and np.isfinite(Y).all() and np.isfinite(U).all()):
            # batch arrays checked once for the whole sequence: `step`'s checks pass at every
            # step, so its work is `_advance` alone (same numbers)
            for i in range(len(Y)):
                out[i] = self._advance(Y[i], U[i])
                self.k += 1
            return out
        for i in range(len(Y)):
            out[i] = self.step(Y[i], U[i])
        return out

    @property
    @abc.abstractmethod
    def x_hat(self) -> np.ndarray:
        """Current estimate, shape (n,) or (M, n) (a copy)."""

    @abc.abstractmethod
    def reset(self, x0: Any = None) -> None:
        """Back to the initial state (``x0`` overrides the tuning's initial estimate).

        Parameters
        ----------
        x0 : array_like, optional
            Initial estimate, (n,) or (M, n) (state units); default the tuning's.
        """

    @abc.abstractmethod
    def batch(self, runs: int) -> "Estimator":
        """A fresh estimator of the same design for ``runs`` parallel runs.

        Parameters
        ----------
        runs : int
            Number of parallel runs (>= 1).
        """

    @abc.abstractmethod
    def _advance(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        """One step on run-stacked arrays; returns the (M, n) estimates (may be a view)."""

    def _x0_rows(self, x0: Any, default: np.ndarray) -> np.ndarray:
        M, n = self._M, self.n
        if x0 is None:
            return np.tile(default, (M, 1))
        arr = np.asarray(x0, dtype=float)
        if arr.shape == (n,):
            return np.tile(arr, (M, 1))
        if self.runs is not None and arr.shape == (M, n):
            if not np.all(np.isfinite(arr)):
                raise DimensionError("x0 has non-finite entries")
            return arr.copy()
        raise DimensionError(f"x0 must have shape ({n},)" +
                             (f" or ({M}, {n})" if self.runs is not None else "") +
                             f", got {arr.shape}")

    def _raise(self, run: int, matrix: str, value: float) -> None:
        where = "" if self.runs is None else f" (run {run})"
        raise CovarianceError(
            f"{type(self).__name__}: {matrix} is not positive definite at step {self.k + 1}"
            f"{where}: smallest Cholesky pivot {value:.3g}. Check Q, R and P0 (scaling, "
            "definiteness) and the model; the estimator keeps its state of step "
            f"{self.k}.", self.k + 1, None if self.runs is None else run, matrix, float(value))


class KernelEstimator(Estimator):
    """An estimator whose step is one compiled CasADi function (see module notes).

    Subclasses implement `_build` returning the SX kernel
    ``(state, y, u, params) -> (state_new, checks, extra)`` with
    ``checks = [pivots..., sum(x_new)]`` (all pivots must be > 0 and all
    finite), `_params` (the numeric tuning vector) and `_initial_state`.

    Parameters
    ----------
    plant : Plant
        The plant.
    tuning : object
        The estimator's tuning (its artefact).
    model : DiscreteModel
        The sampled model the kernel predicts with.
    runs : int or None
        Number of parallel runs (None: a single run).
    backend : {"auto", "native", "vm"}
        Compiled C kernel, CasADi's virtual machine, or native when a compiler works.
    _shared : dict, optional
        Internal: the kernel of another instance (`batch`).
    """

    #: Names of the matrices whose minimum Cholesky pivot is in ``checks``.
    check_names: tuple[str, ...] = ()

    def __init__(self, plant: Plant, tuning: Any, model: DiscreteModel, runs: int | None,
                 backend: str, _shared: dict | None = None):
        super().__init__(plant, tuning, runs)
        if backend not in BACKENDS:
            raise SpecError(f"backend must be one of {BACKENDS}, got {backend!r}", key="backend")
        self.model = model
        if _shared is None:
            kernel = self._build()
            fn = kernel
            used = "vm"
            if backend in ("auto", "native"):
                native = native_function(kernel)
                if native is not None:
                    fn, used = native, "native"
                elif backend == "native":
                    raise TanksynthError("backend 'native' needs a working C compiler (gcc/cc)")
            _shared = {"fn": fn, "backend": used, "sx": kernel, "maps": {}, "horizon_fns": {}}
        self._shared = _shared
        self.backend = _shared["backend"]
        fn = _shared["fn"]
        M = self._M
        if self.runs is None:
            run_fn = fn
        else:
            maps = _shared["maps"]
            if M not in maps:
                maps[M] = fn.map(f"{fn.name()}_map{M}", "serial", M, [3], [])
            run_fn = maps[M]
        self._s = fn.size1_in(0)
        self._c = fn.size1_out(1)
        self._e = fn.size1_out(2)
        self._states = [np.zeros((M, self._s)), np.zeros((M, self._s))]
        self._Y = np.zeros((M, self.q))
        self._U = np.zeros((M, self.m))
        self._P = np.ascontiguousarray(self._params(), dtype=float).reshape(-1)
        self._checks = np.zeros((M, self._c))
        self._extra = np.zeros((M, self._e))
        self._buffers = []
        for a, b in ((0, 1), (1, 0)):
            fb, ev = run_fn.buffer()
            fb.set_arg(0, self._states[a].reshape(-1).data)
            fb.set_arg(1, self._Y.reshape(-1).data)
            fb.set_arg(2, self._U.reshape(-1).data)
            fb.set_arg(3, self._P.data)
            fb.set_res(0, self._states[b].reshape(-1).data)
            fb.set_res(1, self._checks.reshape(-1).data)
            fb.set_res(2, self._extra.reshape(-1).data)
            self._buffers.append((fb, ev, b))
        self._cur = 0
        self._horizons: dict[bool, Horizon] = {}
        self._backend_request = backend
        self.reset()

    # -- to implement -------------------------------------------------------------------
    @abc.abstractmethod
    def _build(self) -> ca.Function:
        """The SX kernel ``(state, y, u, params) -> (state_new, checks, extra)``."""

    @abc.abstractmethod
    def _params(self) -> np.ndarray:
        """Numeric tuning vector fed to the kernel's ``params`` input."""

    @abc.abstractmethod
    def _initial_state(self, X0: np.ndarray) -> np.ndarray:
        """(M, s) kernel state for initial estimates ``X0`` (M, n)."""

    # -- machinery ------------------------------------------------------------------------
    @property
    def state(self) -> np.ndarray:
        """Raw kernel state, shape (M, s) (a copy; layout per subclass)."""
        return self._states[self._cur].copy()

    @property
    def x_hat(self) -> np.ndarray:
        """Current estimate, shape (n,) or (M, n) (a copy)."""
        X = self._states[self._cur][:, :self.n]
        return X[0].copy() if self.runs is None else X.copy()

    @property
    def extra(self) -> np.ndarray:
        """Kernel's extra outputs of the last step (innovation, ...), (M, e) (a copy)."""
        return self._extra.copy()

    def reset(self, x0: Any = None) -> None:
        """Back to the initial state.

        Parameters
        ----------
        x0 : array_like, shape (n,) or (M, n), optional
            Initial estimate overriding the tuning's ``x0`` (state units).
        """
        X0 = self._x0_rows(x0, self.tuning.x0)
        self._states[self._cur][:] = self._initial_state(X0)
        self.k = 0

    def _advance(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        self._Y[:] = Y
        if self.m:
            self._U[:] = U
        fb, ev, nxt = self._buffers[self._cur]
        ev()
        chk = self._checks
        if self.runs is None:
            vals = chk[0].tolist()
            ok = all(0.0 < v < math.inf for v in vals[:-1]) and math.isfinite(vals[-1])
        else:
            npiv = self._c - 1
            ok = bool(np.isfinite(chk).all() and (chk[:, :npiv] > 0).all())
        if not ok:
            self._failure(chk)
        self._cur = nxt
        return self._states[nxt][:, :self._n]

    def _failure(self, chk: np.ndarray) -> None:
        npiv = self._c - 1
        for run in range(chk.shape[0]):
            for j in range(npiv):
                v = chk[run, j]
                if not (np.isfinite(v) and v > 0):
                    self._raise(run, self.check_names[j], v)
            if not np.isfinite(chk[run, npiv]):
                where = "" if self.runs is None else f" (run {run})"
                raise CovarianceError(
                    f"{type(self).__name__}: the state estimate is not finite at step {self.k + 1}"
                    f"{where}; the estimator keeps its state of step {self.k}.", self.k + 1,
                    None if self.runs is None else run, "state estimate", float(chk[run, npiv]))

    def batch(self, runs: int) -> "KernelEstimator":
        """A fresh estimator of the same design for ``runs`` parallel runs (shares the kernel).

        Parameters
        ----------
        runs : int
            Number of parallel runs (>= 1).
        """
        clone = object.__new__(type(self))
        clone._clone_from(self, runs)
        return clone

    def _clone_from(self, other: "KernelEstimator", runs: int | None) -> None:
        KernelEstimator.__init__(self, other.plant, other.tuning, other.model, runs,
                                 other._backend_request, _shared=other._shared)

    @property
    def step_kernel(self) -> ca.Function:
        """The SX step ``(state, y, u, params) -> (state_new, checks, extra)`` (see `_build`),
        before any compilation: what an exported law is built from."""
        return self._shared["sx"]

    @property
    def kernel_parameters(self) -> np.ndarray:
        """The numeric tuning vector the kernel's ``params`` input is fed (a copy; units of
        the tuning's entries)."""
        return self._P.copy()

    @property
    def instructions(self) -> int:
        """Number of elementary operations of the step kernel (per run)."""
        return int(self.step_kernel.n_instructions())

    # -- whole sequences: horizon kernels ---------------------------------------------------
    def run(self, Y: Any, U: Any) -> np.ndarray:
        """Filter a whole sequence (the same numbers as `step` at each sample in turn).

        Through the compiled horizon kernel (`tanksynth.runtime.estimators.horizon`) when
        one is available, else one `step` per sample.

        Parameters
        ----------
        Y : array_like, shape (N, q) (single) or (N, M, q) (batch)
            Measurements (output units).
        U : array_like, shape (N, m) (single) or (N, M, m) / (N, m) (batch)
            Inputs held before each measurement (input units).

        Returns
        -------
        ndarray, shape (N, n) or (N, M, n)
            Estimates after each sample (state units).
        """
        X = self._run_horizon(Y, U, None, self.n)
        if X is None:
            return super().run(Y, U)
        return X[:, 0] if self.runs is None else X

    def run_states(self, Y: Any, U: Any, observed: Any = None) -> np.ndarray:
        """Filter a whole sequence and return the raw kernel state after every sample.

        The same numbers as `step` (or `step_observed` where ``observed`` has a False) at
        each sample in turn, through the horizon kernel when one is available (with
        ``observed``: single runs only, estimators whose parameters hold ``R``).

        Parameters
        ----------
        Y : array_like, shape (N, q) (single) or (N, M, q) (batch)
            Measurements (output units; any finite value where not observed).
        U : array_like, shape (N, m) (single) or (N, M, m) / (N, m) (batch)
            Inputs held before each measurement (input units).
        observed : array_like of bool, shape (N, q), optional
            Outputs measured at each sample (default all).

        Returns
        -------
        ndarray, shape (N, s) or (N, M, s)
            Kernel states (state units, then per estimator e.g. the covariance in squared state
            units).

        Raises
        ------
        DimensionError
            Shapes that do not fit, non-finite values.
        CovarianceError
            A covariance stopped being positive definite (at the step that `step` names).
        """
        O = None
        if observed is not None:
            O = np.asarray(observed, dtype=bool)
            if O.shape != (len(np.asarray(Y)), self.q):
                raise DimensionError(f"observed must have shape ({len(np.asarray(Y))}, {self.q}), "
                                     f"got {O.shape}")
            if O.all():
                O = None
        states = self._run_horizon(Y, U, O, self._s)
        if states is not None:
            return states[:, 0].copy() if self.runs is None else states
        Y = np.asarray(Y, dtype=float)
        U = np.asarray(U, dtype=float)
        if Y.ndim < 1 or U.ndim < 1 or len(Y) != len(U):
            raise DimensionError(f"Y and U must have the same number of steps, got {Y.shape} and "
                                 f"{U.shape}")
        out = np.empty((len(Y), *((self._s,) if self.runs is None else (self._M, self._s))))
        for i in range(len(Y)):
            if O is None:
                self.step(Y[i], U[i])
            else:
                self.step_observed(Y[i], U[i], O[i])
            st = self._states[self._cur]
            out[i] = st[0] if self.runs is None else st
        return out

    def _horizon(self, masked: bool, work: int) -> Horizon | None:
        """The loaded horizon kernel for this estimator's runs, or None (then step)."""
        policy = horizon_backend()
        if policy == "step" or self.backend != "native":
            return None
        known = self._shared["horizon_fns"]
        fn = known.get(masked)             # the library, False (failed) or "absent" (not built)
        if fn is False:
            return None
        if fn is None or isinstance(fn, str):
            build = policy == "horizon" or work >= BUILD_STEPS
            if isinstance(fn, str) and not build:
                return None
            step = self.step_kernel
            if masked:
                step = observed_step(step, self.model, self.n, self.q, self.UNOBSERVED_VARIANCE)
            fn = native_function(horizon_function(step, CHUNK), build=build)
            if fn is None:                     # failed (remembered: the estimator steps) or absent
                known[masked] = False if build else "absent"
                return None
            known[masked] = fn
        hz = self._horizons.get(masked)
        if hz is None:                         # buffers of this instance (its runs, its params)
            hz = self._horizons[masked] = Horizon(fn, self._M, self._P)
        return hz

    def _run_horizon(self, Y: Any, U: Any, O: np.ndarray | None, keep: int) -> np.ndarray | None:
        """The first ``keep`` kernel-state entries after every sample (N, M, keep) through the
        horizon kernel, or None when it does not apply."""
        M, q, m = self._M, self._q, self._m
        Y = np.asarray(Y, dtype=float)
        U = np.asarray(U, dtype=float)
        N = len(Y) if Y.ndim else 0
        if N < 2 or not m or len(U) != N:
            return None
        if self.runs is None:
            if Y.shape != (N, q) or U.shape != (N, m):
                return None
            Y, U = Y[:, None, :], U[:, None, :]
        else:
            if Y.shape != (N, M, q) or U.shape not in ((N, M, m), (N, m)):
                return None
            if U.ndim == 2:
                U = np.broadcast_to(U[:, None, :], (N, M, m))
        if O is not None and (M != 1 or not self.noise_in_parameters):
            return None
        if not (np.isfinite(Y).all() and np.isfinite(U).all()):
            return None                         # (the steps name the sample)
        # A batch gives the kernel whole chunks only: a padded chunk of M runs costs its full
        # length (50 samples of 1,000 runs through a 256-sample chunk: 12-30x the steps, which
        # already run every run in one C call); one run pads (a step costs ~10 kernel samples).
        span = N - 1 if M == 1 else (N - 1) // CHUNK * CHUNK
        if span < 1:
            return None
        hz = self._horizon(O is not None, N * M)
        if hz is None:
            return None
        out = np.empty((N, M, keep))
        done = hz.run(self._states[self._cur], Y[:span], U[:span], out,
                      None if O is None else O[:span].astype(float))
        if done:
            self._states[self._cur][:] = hz.state
        self.k += done
        # the rest (the last sample, or from the chunk that failed on) through the steps: the
        # same numbers, the extra outputs of the last step, the error naming its step
        for i in range(done, N):
            y, u = (Y[i, 0], U[i, 0]) if self.runs is None else (Y[i], U[i])
            if O is not None and not O[i].all():
                self.step_observed(y, u, O[i])
            else:
                self.step(y, u)
            out[i] = self._states[self._cur][:, :keep]
        return out

    #: The kernel's parameter vector ends with the measurement-noise covariance ``R`` (q x q,
    #: column-major): `step_observed` can leave outputs out of the correction.
    noise_in_parameters: bool = False

    #: ``R`` of the outputs left out by `step_observed`, relative to the largest entry of ``R``
    #: and of the covariance (at least 1): their gain is that much smaller than any other's.
    UNOBSERVED_VARIANCE = 1e12

    def _predicted_where_unobserved(self, y: Any, u: Any, mask: np.ndarray) -> Any:
        """``y`` with its unobserved outputs replaced by the one-step prediction
        ``h(F(x_hat, u))`` of the step's model, as the masked horizon kernel feeds them
        (`tanksynth.runtime.estimators.horizon.observed_step`); ``y`` unchanged when its shape
        or values do not fit (`step` then says why)."""
        n, q, m, M = self.n, self.q, self.m, self._M
        Y = np.array(y, dtype=float)
        if Y.shape not in ((q,), (M, q)) or not np.isfinite(Y).all():
            return y
        try:
            Ur = np.broadcast_to(np.asarray(0.0 if u is None else u, dtype=float).reshape(-1, m)
                                 if m else np.zeros((M, 0)), (M, m))
        except ValueError:
            return y
        fn = self._shared.get("prediction")
        if fn is None:
            x, uu = ca.SX.sym("x", n), ca.SX.sym("u", m)
            fn = self._shared["prediction"] = ca.Function(
                "prediction", [x, uu], [self.model.output_sx(self.model.predict_sx(x, uu))])
        X = self._states[self._cur][:, :n]
        yp = np.asarray((fn if M == 1 else fn.map(M))(X.T, Ur.T), dtype=float).reshape(q, M).T
        if Y.ndim == 1:
            Y[~mask] = yp[0, ~mask]
        else:
            Y[:, ~mask] = yp[:, ~mask]
        return Y

    def step_observed(self, y: Any, u: Any, observed: Any) -> np.ndarray:
        """One step whose correction uses only the outputs marked observed (missing samples).

        The same kernel as `step`, run with the variance of each unobserved output raised to
        `UNOBSERVED_VARIANCE` times the largest entry of ``R`` and of the covariance (its
        correlations zeroed): its gain vanishes (relative size 1e-12), so the correction is the
        one of the observed outputs alone and, with none observed, the step is the prediction
        ``x(k|k-1)``, ``P(k|k-1)``. The values of ``y`` at unobserved outputs do not matter
        (they must be finite): the one-step prediction ``h(F(x_hat, u))`` of the step's model
        is fed there, as the masked horizon kernel does (`run_states`), so that both give the
        same numbers whatever ``y`` holds there (a 1e-12 gain times ``y - h(F(x_hat, u))``
        otherwise: 3e-10 measured on an UKF, issue 29).

        Parameters
        ----------
        y : array_like, shape (q,) or (M, q)
            Measurement at ``t_k`` (output units).
        u : array_like, shape (m,) or (M, m)
            Input held over ``[t_{k-1}, t_k)`` (input units).
        observed : array_like of bool, shape (q,)
            Which outputs were measured (the same for every run of a batch).

        Returns
        -------
        ndarray, shape (n,) or (M, n)
            ``x_hat(k)`` (state units).

        Raises
        ------
        TanksynthError
            The estimator's kernel does not take ``R`` as parameters.
        DimensionError
            ``observed`` is not q booleans.
        """
        if not self.noise_in_parameters:
            raise TanksynthError(f"{type(self).__name__} cannot leave outputs out of a step")
        mask = np.asarray(observed, dtype=bool).reshape(-1)
        if mask.shape != (self.q,):
            raise DimensionError(f"observed must be {self.q} booleans, got shape {mask.shape}")
        if mask.all():
            return self.step(y, u)
        y = self._predicted_where_unobserved(y, u, mask)
        q = self.q
        nominal = self._P.copy()
        R = nominal[-q * q:].reshape(q, q, order="F").copy()
        scale = max(1.0, float(np.abs(R).max()), float(np.abs(self.state[:, self.n:]).max()))
        R[~mask, :] = 0.0
        R[:, ~mask] = 0.0
        R[~mask, ~mask] = self.UNOBSERVED_VARIANCE * scale
        self._P[-q * q:] = column_major(R)
        try:
            return self.step(y, u)
        finally:
            self._P[:] = nominal


class CovarianceKernelEstimator(KernelEstimator):
    """A `KernelEstimator` whose state is the estimate then its covariance ``P`` (column-major).

    The Kalman-type kernels (extended Kalman, unscented): ``state = [x (n), vec(P) (n n), ...]``.

    Parameters
    ----------
    plant : Plant
        The plant.
    tuning : object
        The estimator's tuning (its artefact).
    model : DiscreteModel
        The sampled model the kernel predicts with.
    runs : int or None
        Number of parallel runs (None: a single run).
    backend : {"auto", "native", "vm"}
        Compiled C kernel, CasADi's virtual machine, or native when a compiler works.
    """

    @property
    def covariance(self) -> np.ndarray:
        """``P(k|k)``, shape (n, n) or (M, n, n) (state units^2, a copy)."""
        raw = self.covariance_of(self._states[self._cur])
        return raw[0].copy() if self.runs is None else raw.copy()

    def covariance_of(self, states: np.ndarray) -> np.ndarray:
        """``P`` held in raw kernel states (`state`, `run_states`).

        Parameters
        ----------
        states : ndarray, shape (..., s)
            Kernel states (state units, then squared state units).

        Returns
        -------
        ndarray, shape (..., n, n)
            The covariances (squared state units; a view where numpy can).
        """
        n = self.n
        raw = np.asarray(states)[..., n:n + n * n]
        return raw.reshape(*raw.shape[:-1], n, n).swapaxes(-1, -2)


class ArrayEstimator(Estimator):
    """An estimator written in vectorised numpy over the run axis.

    Subclasses keep their state in arrays with a leading run axis and
    implement `_advance`, `_reset_arrays` and `_clone_args`.

    Parameters
    ----------
    plant : Plant
        The plant.
    tuning : object
        The estimator's tuning (its artefact).
    runs : int or None
        Number of parallel runs (None: a single run).
    """

    def __init__(self, plant: Plant, tuning: Any, runs: int | None):
        super().__init__(plant, tuning, runs)

    @property
    def x_hat(self) -> np.ndarray:
        """Current estimate, shape (n,) or (M, n) (a copy)."""
        return self._x[0].copy() if self.runs is None else self._x.copy()

    def reset(self, x0: Any = None) -> None:
        """Back to the initial state (``x0``: (n,) or (M, n) overrides the tuning's).

        Parameters
        ----------
        x0 : array_like, optional
            Initial estimate, (n,) or (M, n) (state units); default the tuning's.
        """
        self._x = self._x0_rows(x0, self.tuning.x0)
        self._reset_arrays()
        self.k = 0

    @abc.abstractmethod
    def _reset_arrays(self) -> None:
        """Re-initialise the arrays other than ``_x``."""

    @abc.abstractmethod
    def _clone_args(self) -> tuple[tuple, dict]:
        """Positional and keyword arguments rebuilding this estimator (without ``runs``)."""

    def batch(self, runs: int) -> "ArrayEstimator":
        """A fresh estimator of the same design for ``runs`` parallel runs.

        Parameters
        ----------
        runs : int
            Number of parallel runs (>= 1).
        """
        args, kwargs = self._clone_args()
        # each subclass has its own constructor (``_clone_args`` gives its arguments)
        build: Callable[..., ArrayEstimator] = type(self)
        return build(*args, runs=runs, **kwargs)

    def _check_spd(self, P: np.ndarray, matrix: str) -> None:
        """Raise `CovarianceError` if any (M, n, n) slice is not positive definite."""
        try:
            L = np.linalg.cholesky(P)
            ok = bool(np.isfinite(L).all())
        except np.linalg.LinAlgError:
            ok = False
        if not ok:
            for run in range(P.shape[0]):
                Pi = P[run]
                if not np.isfinite(Pi).all():
                    self._raise(run, matrix, float("nan"))
                try:
                    np.linalg.cholesky(Pi)
                except np.linalg.LinAlgError:
                    self._raise(run, matrix, float(np.linalg.eigvalsh(Pi)[0]))

    def _check_state(self, X: np.ndarray) -> None:
        if not np.isfinite(X).all():
            run = int(np.argwhere(~np.isfinite(X))[0, 0])
            where = "" if self.runs is None else f" (run {run})"
            raise CovarianceError(
                f"{type(self).__name__}: the state estimate is not finite at step {self.k + 1}"
                f"{where}", self.k + 1, None if self.runs is None else run, "state estimate",
                float("nan"))


def mv(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``A x`` for every row ``x`` of ``X`` (M, k) -> (M, n).

    An ``einsum`` loop rather than ``X @ A.T``: a 2-D matrix product goes to
    BLAS, whose blocking depends on ``M``, so a batch would not equal its
    single runs bit for bit.

    Parameters
    ----------
    A : ndarray, shape (n, k)
        The matrix.
    X : ndarray, shape (M, k)
        One vector per row.
    """
    return np.einsum("ij,mj->mi", A, X)


def per_run(A: np.ndarray, runs: int) -> np.ndarray:
    """A writable copy of ``A`` for each of ``runs`` runs, shape ``(runs,) + A.shape``.

    Parameters
    ----------
    A : ndarray
        The per-run initial value (a covariance, squared state units).
    runs : int
        Number of runs M.
    """
    return np.broadcast_to(A, (runs, *A.shape)).copy()


def column_major(A: np.ndarray) -> np.ndarray:
    """The entries of ``A`` column by column, as a kernel's parameter vector reads a matrix.

    Parameters
    ----------
    A : array_like, shape (r, c)
        A matrix (any units).

    Returns
    -------
    ndarray, shape (r c,)
    """
    return np.asarray(A, dtype=float).ravel(order="F")


def joseph_update(P: np.ndarray, K: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Joseph-form covariance update, symmetrised, on stacked arrays.

    ``(I - K H) P (I - K H)' + K R K'`` for ``P`` (M, n, n), ``K`` (M, n, q),
    ``H`` (q, n) or (M, q, n), ``R`` (q, q).

    Parameters
    ----------
    P : ndarray, shape (M, n, n)
        Predicted covariances (squared state units).
    K : ndarray, shape (M, n, q)
        Gains (state per output units).
    H : ndarray, shape (q, n) or (M, q, n)
        Output Jacobians (output per state units).
    R : ndarray, shape (q, q)
        Measurement-noise covariance (squared output units).
    """
    n = P.shape[-1]
    IKH = np.eye(n) - K @ H
    return symmetrize(IKH @ P @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2))
