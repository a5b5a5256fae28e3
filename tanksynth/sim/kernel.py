"""The plant's simulation kernel: built once with the C compiler, cached on disk, loaded.

`native_kernel` turns a plant's generated numpy code into its period kernel
(C source from `tanksynth.sim.csource.kernel_source`), compiles it once per
plant structure with ``cc -O3 -shared -fPIC -ffp-contract=off
-fno-math-errno`` (plus ``-mavx2`` on an x86-64 CPU with AVX2; without it if
that build fails) and loads it (`ctypes`); `NativeKernel.run` integrates M
runs over N sampling periods in one call (same numbers as the numpy code of
`tanksynth.sim.integrate`, bit for bit, tested).

A run whose hybrid mode changes inside a period is not located by the
kernel: it stops that run at the start of that period (``stop``); the
caller re-integrates the period with the numpy code (bisection on the step
fraction, `tanksynth.sim.integrate.Integrator`) and resumes the kernel from
the next period (``start``).

Choice of route (automatic): the native kernel when a C compiler works;
otherwise the CasADi/numpy routes of `tanksynth.sim.integrate` (no error),
with the reason in `kernel_status` and in the log (logger
``tanksynth.sim``, a warning when a compiler was found but failed).
Environment: ``TANKSYNTH_SIM_BACKEND`` = ``auto`` (default: load a kernel
already built, compile a new one only for a simulation of at least
`BUILD_WORK` state-steps), ``native`` (always compile) or ``numpy`` (never
use a kernel).

Compiler, flags and cache: the one native-compile cache of tanksynth
(`tanksynth.native_cache`: ``$TANKSYNTH_CC``, else ``gcc``/``cc``; ``-O3
-shared -fPIC -ffp-contract=off -fno-math-errno -std=c99``, plus ``-mavx2``
on an x86-64 CPU with AVX2, without it if that build fails; locked, atomic
builds). The kernels are its family ``sim``: ``tk_sim_*.so`` files in
`cache_dir` (``$TANKSYNTH_CACHE_DIR/sim``, else
``$XDG_CACHE_HOME/tanksynth/sim``, else ``~/.cache/tanksynth/sim``), named by
the SHA-256 of the C source, `tanksynth.sim.csource.KERNEL_VERSION`, the
compiler path and its flags, so a library is never used for another kernel.
Loaded kernels are kept in memory; `clear_cache` forgets them (and, on
request, deletes the files); `cache_info` reports the counts, including the
compiler runs of this process (``compiles``).
"""

from __future__ import annotations

import ctypes
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

from tanksynth.native_cache import NativeBuildError, NativeCache, ctypes_loader, find_compiler
from tanksynth.sim.csource import KERNEL_VERSION, kernel_source

__all__ = ["NativeKernel", "PeriodCall", "native_kernel", "kernel_status", "cache_dir", "clear_cache",
           "cache_info", "per_run_table", "BUILD_WORK"]

_LOG = logging.getLogger("tanksynth.sim")

#: Smallest simulation (RK4 run-steps x states) for which ``auto`` compiles a new kernel.
BUILD_WORK = 1e6

def per_run_table(values: Any, count: int) -> np.ndarray:
    """Values (scalars or (M,) arrays) as a (M, len(values)) table for `NativeKernel.run`.

    All scalars: one row broadcast over the runs (run stride 0, no copy per run).

    Parameters
    ----------
    values : sequence
        Floats or arrays of ``count`` values (e.g. parameter values, SI units).
    count : int
        Number of runs M.
    """
    try:
        row = np.array(values, dtype=float)
    except ValueError:                  # scalars mixed with per-run arrays
        row = None
    if row is not None and row.ndim == 1:
        return np.broadcast_to(row[None, :], (count, row.size))
    out = np.empty((count, len(values)))
    for j, v in enumerate(values):
        out[:, j] = v
    return out


# ----------------------------------------------------------------------------- build + cache
#: The simulation kernels' family of the native-compile cache.
_CACHE = NativeCache("sim", "tk_sim_")

#: What the last `native_kernel` request gave (`kernel_status`).
_STATUS = ["no kernel asked for yet"]


def cache_dir() -> Path:
    """Directory of the compiled simulation kernels (not created here).

    Returns
    -------
    pathlib.Path
        ``$TANKSYNTH_CACHE_DIR/sim``, else ``$XDG_CACHE_HOME/tanksynth/sim``,
        else ``~/.cache/tanksynth/sim``.
    """
    return _CACHE.directory()


_ARGTYPES = (ctypes.c_long, ctypes.c_long, ctypes.c_int, ctypes.c_double, ctypes.c_void_p,
             ctypes.c_void_p, ctypes.c_long, ctypes.c_long, ctypes.c_void_p, ctypes.c_long,
             ctypes.c_void_p, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
             ctypes.c_void_p, ctypes.c_long, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p,
             ctypes.c_void_p)


class NativeKernel:
    """A loaded period kernel (`native_kernel`): M runs over N periods per call.

    Parameters
    ----------
    lib : ctypes.CDLL
        The loaded shared library (defines ``tk_run``).
    path : pathlib.Path
        Its file.
    n, m : int
        States and inputs of the plant.
    compile_seconds : float
        Compiler wall time in this process (s; 0 when loaded from the disk cache).

    Attributes
    ----------
    n, m : int
        States and inputs of the plant.
    path : pathlib.Path
        The shared library.
    compile_seconds : float
        Wall time of the compiler run that built it in this process (s; 0 when
        loaded from the disk cache).
    """

    def __init__(self, lib: ctypes.CDLL, path: Path, n: int, m: int, compile_seconds: float):
        self._fn = lib.tk_run
        self._fn.argtypes = _ARGTYPES
        self._fn.restype = ctypes.c_int
        self._lib = lib
        self.path = path
        self.n, self.m = n, m
        self.compile_seconds = compile_seconds

    def period(self, count: int, substeps: int) -> "PeriodCall":
        """A reusable one-period call for ``count`` runs (buffers and arguments bound once).

        Parameters
        ----------
        count : int
            Number of runs M.
        substeps : int
            RK4 steps per period.
        """
        return PeriodCall(self, int(count), int(substeps))

    def run(self, x0: np.ndarray, U: np.ndarray, C: np.ndarray, P: np.ndarray, lower: np.ndarray,
            upper: np.ndarray, h: float, substeps: int, X: np.ndarray,
            start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Integrate M runs over N periods (arrays must be C-contiguous float64 where noted).

        Parameters
        ----------
        x0 : ndarray, shape (M, n)
            Clipped states at the start (state units), C-contiguous.
        U : ndarray, shape (N, M, m)
            Saturated inputs held over each period (input units); strides of the
            first two axes may be 0 (broadcast), the last axis contiguous.
        C : ndarray, shape (M, nc)
            The model's parameter-only constants per run (run stride may be 0).
        P : ndarray, shape (M, np)
            Parameter values per run (run stride may be 0).
        lower, upper : ndarray, shape (n,)
            State bounds (state units).
        h : float
            RK4 step (s).
        substeps : int
            RK4 steps per period (1 ... `MAX_SUBSTEPS`).
        X : ndarray, shape (N, M, n)
            Written: end state of every period (state units; last axis contiguous, any strides
            of the first two, e.g. a transposed run-major buffer; periods at or
            after a run's ``stop`` are left untouched).
        start : ndarray of int64, shape (M,), optional
            First period of each run (an index, dimensionless; default 0); states in
            ``x0`` are at its start.

        Returns
        -------
        stop : ndarray of int64, shape (M,)
            First period whose hybrid mode changed (an index, dimensionless; -1: none); the run's state at
            its start is ``X[stop - 1]`` (``x0`` when it is ``start``).
        low, high : ndarray of bool, shape (N, substeps)
            RK4 steps after which a completed run passed a bound (before clipping).
        """
        M, N = x0.shape[0], U.shape[0]
        S = int(substeps)
        stop = np.full(M, -1, dtype=np.int64)
        low = np.zeros((N, S), dtype=bool)
        high = np.zeros((N, S), dtype=bool)
        if M == 0 or N == 0:
            return stop, low, high
        item = 8
        lo = np.ascontiguousarray(lower, dtype=float)
        hi = np.ascontiguousarray(upper, dtype=float)
        st = None if start is None else np.ascontiguousarray(start, dtype=np.int64)
        if not (x0.flags.c_contiguous and x0.shape == (M, self.n) and X.shape == (N, M, self.n)
                and U.shape == (N, M, self.m) and C.shape[0] == M and P.shape[0] == M
                and x0.dtype == U.dtype == C.dtype == P.dtype == X.dtype == np.float64
                and lo.shape == hi.shape == (self.n,) and (st is None or st.shape == (M,))):
            raise ValueError("native kernel: unsupported array shapes or types")
        for a in (U, C, P, X):
            if (a.shape[-1] > 1 and a.strides[-1] != item) or any(s % item for s in a.strides):
                raise ValueError("native kernel: unsupported array layout")
        status = self._fn(M, N, S, float(h), x0.ctypes.data, U.ctypes.data, U.strides[0] // item,
                          U.strides[1] // item, C.ctypes.data, C.strides[0] // item,
                          P.ctypes.data, P.strides[0] // item, lo.ctypes.data, hi.ctypes.data,
                          None if st is None else st.ctypes.data, X.ctypes.data,
                          X.strides[0] // item, X.strides[1] // item, stop.ctypes.data,
                          low.ctypes.data, high.ctypes.data)
        if status:
            raise ValueError(f"native kernel refused substeps = {S}")
        return stop, low, high


class PeriodCall:
    """One sampling period of M runs through the kernel, with persistent buffers.

    The period-by-period loop of the simulator (closed loop, noise) calls the
    kernel once per sample: its arguments are converted once here
    (`bind`), each call only copies the state and the input in.

    Parameters
    ----------
    kernel : NativeKernel
    count : int
        Number of runs M.
    substeps : int
        RK4 steps per period (1 ... `tanksynth.sim.csource.MAX_SUBSTEPS`).
    """

    def __init__(self, kernel: NativeKernel, count: int, substeps: int):
        n, m = kernel.n, kernel.m
        self.kernel = kernel
        self.x = np.empty((count, n))
        self.u = np.empty((1, count, m))
        self.out = np.empty((1, count, n))
        self.stop = np.empty(count, dtype=np.int64)
        self.low = np.zeros((1, substeps), dtype=bool)
        self.high = np.zeros((1, substeps), dtype=bool)
        self.count, self.substeps = count, substeps
        self._args: tuple | None = None
        self._held: tuple = ()

    def bind(self, C: np.ndarray, P: np.ndarray, lower: np.ndarray, upper: np.ndarray,
             h: float) -> None:
        """Constants and parameters (M, .) per run, state bounds (n,), step ``h`` (s).

        Parameters
        ----------
        C, P : ndarray, shape (M, nc) and (M, np)
            See `NativeKernel.run` (kept alive while bound).
        lower, upper : ndarray, shape (n,)
            State bounds (state units).
        h : float
            RK4 step (s).
        """
        held = (C, P, lower, upper, float(h))
        if self._args is not None and all(a is b for a, b in zip(held[:4], self._held[:4])) \
                and held[4] == self._held[4]:
            return
        # validates shapes and layout once (zero periods: nothing integrated)
        self.kernel.run(self.x, self.u[:0], C, P, lower, upper, h, self.substeps,
                        self.out[:0])
        lo = np.ascontiguousarray(lower, dtype=float)
        hi = np.ascontiguousarray(upper, dtype=float)
        item = 8
        vp, lg = ctypes.c_void_p, ctypes.c_long
        self._args = (lg(self.count), lg(1), ctypes.c_int(self.substeps), ctypes.c_double(h),
                      vp(self.x.ctypes.data), vp(self.u.ctypes.data), lg(0),
                      lg(self.u.strides[1] // item), vp(C.ctypes.data), lg(C.strides[0] // item),
                      vp(P.ctypes.data), lg(P.strides[0] // item), vp(lo.ctypes.data),
                      vp(hi.ctypes.data), None, vp(self.out.ctypes.data), lg(0),
                      lg(self.out.strides[1] // item), vp(self.stop.ctypes.data),
                      vp(self.low.ctypes.data), vp(self.high.ctypes.data))
        self._held = (C, P, lower, upper, float(h), lo, hi)

    def __call__(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                              np.ndarray, np.ndarray]:
        """End states (M, n) (a new array), ``stop`` (M,), ``low``/``high`` (substeps,).

        Parameters
        ----------
        x : ndarray, shape (M, n)
            Clipped states at the start of the period (state units).
        u : ndarray, shape (M, m)
            Held inputs (input units).
        """
        if self._args is None:
            raise ValueError("PeriodCall.bind must be called first")
        self.x[...] = x
        self.u[0] = u
        self.stop.fill(-1)
        self.low.fill(False)
        self.high.fill(False)
        if self.kernel._fn(*self._args):
            raise ValueError(f"native kernel refused substeps = {self.substeps}")
        return self.out[0].copy(), self.stop, self.low[0], self.high[0]


def native_kernel(model: Any, work: float | None = None) -> NativeKernel | None:
    """The compiled period kernel of a plant's numpy model, or None (then use the numpy code).

    Built once per plant structure and compiler (cached in memory and on
    disk, see the module notes), when it pays: with
    ``TANKSYNTH_SIM_BACKEND=auto`` (default) a kernel already on disk is
    always loaded, and a new one is compiled only for a simulation of at
    least `BUILD_WORK` state-steps (``work`` times the number of states; the
    compiler takes 0.6-3 s, the CasADi/numpy code a few microseconds per
    step), so short one-off simulations of many different plants never wait
    for a compiler; ``native`` always compiles, ``numpy`` never uses a
    kernel. None, with the reason in `kernel_status` and the log, also when
    no C compiler is found, the plant's code cannot be translated, or the
    build or load fails.

    Parameters
    ----------
    model : tanksynth.sim.tape.NumpyModel
    work : float, optional
        RK4 run-steps of the simulation asking (runs x periods x steps per
        period); None: unknown (load a built kernel, never compile).

    Returns
    -------
    NativeKernel or None
    """
    env = tuple(os.environ.get(v) for v in ("TANKSYNTH_SIM_BACKEND", "TANKSYNTH_CC", "PATH",
                                             "TANKSYNTH_CACHE_DIR", "XDG_CACHE_HOME", "HOME"))
    cached = model.compiled.get(("native", env))
    if cached is not None:
        _STATUS[0] = cached[1]
        return cached[0]
    backend = (env[0] or "auto").strip().lower()
    cc = None if backend == "numpy" else find_compiler()
    key = ("native", backend, cc, str(cache_dir()))
    cached = model.compiled.get(key)
    if cached is not None:
        _STATUS[0] = cached[1]
        return cached[0]
    build = backend == "native" or (work is not None and work * model.n >= BUILD_WORK)
    kernel = _native_kernel(model, backend, cc, build)
    if kernel is not None or build:      # a skipped build is asked again by a larger simulation
        model.compiled[key] = model.compiled[("native", env)] = (kernel, _STATUS[0])
    return kernel


def _native_kernel(model: Any, backend: str, cc: str | None, build: bool) -> NativeKernel | None:
    """`native_kernel` once the backend and the compiler are known; sets `kernel_status`."""
    if backend == "numpy":
        _STATUS[0] = "numpy backend requested (TANKSYNTH_SIM_BACKEND=numpy)"
        return None
    if cc is None:
        _STATUS[0] = ("no C compiler found (TANKSYNTH_CC or gcc/cc on PATH): simulating with "
                      "the CasADi/numpy code")
        _LOG.info(_STATUS[0])
        return None
    source = model.compiled.get("kernel_source")   # the C of a model never changes: translated once
    if source is None:
        try:
            source = kernel_source(model)
        except ValueError as exc:
            source = exc
        model.compiled["kernel_source"] = source
    if isinstance(source, ValueError):
        _STATUS[0] = str(source)
        _LOG.info(_STATUS[0])
        return None
    try:
        lib = _CACHE.library([source, KERNEL_VERSION], lambda name: source,
                             ctypes_loader("tk_run"), cc, build)
    except NativeBuildError as exc:
        _STATUS[0] = (f"native simulation kernel unavailable ({exc}); simulating with the "
                      f"CasADi/numpy code")
        if not exc.repeated:
            _LOG.warning(_STATUS[0])
        return None
    if lib is None:
        _STATUS[0] = (f"native kernel not built: a small simulation (below {BUILD_WORK:.0e} "
                      f"state-steps; TANKSYNTH_SIM_BACKEND=native to build anyway)")
        return None
    _STATUS[0] = (f"native kernel {lib.path.name} ({' '.join(lib.flags[:1] + lib.flags[6:])})"
                  + (f", compiled in {lib.compile_seconds:.2f} s" if lib.compile_seconds else ""))
    return NativeKernel(lib.handle, lib.path, model.n, model.m, lib.compile_seconds)


def kernel_status() -> str:
    """What the last `native_kernel` request gave: the library used, or why none was."""
    return _STATUS[0]


def clear_cache(disk: bool = False) -> dict[str, int]:
    """Forget the loaded kernels (and failures); with ``disk``, delete the libraries too.

    Parameters
    ----------
    disk : bool
        Also delete the ``tk_sim_*.so`` files of `cache_dir`.

    Returns
    -------
    dict
        ``loaded`` (kernels forgotten) and ``files`` (libraries deleted).
    """
    return _CACHE.clear(disk)


def cache_info() -> dict[str, object]:
    """Kernels loaded, failed builds, compiler runs of this process, libraries on disk, the directory."""
    return _CACHE.info()
