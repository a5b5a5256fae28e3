"""A mapped CasADi function called many times on fixed-shape numpy batches, without per-call setup.

`tanksynth.plants.compile.evaluate_map` checks the shapes and binds the arrays at every call (about
0.1 ms); the per-sample estimators of the verdicts call one period function thousands of times with
the same shapes, so `BatchCall` binds preallocated input and output arrays to the function's buffer
once and only copies the values in and out.

`CasadiControlLaw` and `CasadiIntegralLaw` are control laws serialised as CasADi Functions,
evaluated that way on the M runs of a simulation at once.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tanksynth.sim.closed_loop import LoopLaw

__all__ = ["BatchCall", "mapped_call", "CasadiControlLaw", "CasadiIntegralLaw"]


class BatchCall:
    """``fn`` mapped over M points, evaluated through one bound buffer.

    Parameters
    ----------
    fn : casadi.Function
        Dense vector arguments (k_i,) and dense vector results (r_j,) (`fits`); ``call``
        returns the first, `all` every one.
    count : int
        Number of points M of every call.

    Notes
    -----
    ``call(a_0, a_1, ...)`` takes arrays broadcastable to (M, k_i) and returns a NEW (M, r) array.
    """

    def __init__(self, fn: Any, count: int) -> None:
        self.count = int(count)
        self.mapped = fn.map(self.count, "serial")
        self._args = [np.zeros((self.count, fn.size1_in(i))) for i in range(fn.n_in())]
        self._outs = [np.zeros((self.count, fn.size1_out(j))) for j in range(fn.n_out())]
        self._out = self._outs[0]
        self._buf, self._run = self.mapped.buffer()
        for i, a in enumerate(self._args):
            self._buf.set_arg(i, a.data)
        for j, r in enumerate(self._outs):
            self._buf.set_res(j, r.data)

    @staticmethod
    def fits(fn: Any) -> bool:
        """True when every argument and result of ``fn`` is a dense, non-empty column vector.

        Parameters
        ----------
        fn : casadi.Function
        """
        ins = [fn.sparsity_in(i) for i in range(fn.n_in())]
        outs = [fn.sparsity_out(j) for j in range(fn.n_out())]
        return bool(outs) and all(sp.is_dense() and sp.size2() == 1 and sp.size1() > 0
                                  for sp in ins + outs)

    def all(self, *arrays: np.ndarray) -> list[np.ndarray]:
        """Every result at the M points: (M, k_i) arrays in, NEW (M, r_j) arrays out.

        Parameters
        ----------
        *arrays : ndarray, shape (M, k_i) (or broadcastable)
            Argument i at every point (its units).
        """
        for dst, src in zip(self._args, arrays):
            np.copyto(dst, src)
        self._run()
        return [r.copy() for r in self._outs]

    def __call__(self, *arrays: np.ndarray) -> np.ndarray:
        """Evaluate at the M points: (M, k_i) arrays in, (M, r) array out.

        Parameters
        ----------
        *arrays : ndarray, shape (M, k_i) (or broadcastable)
            Argument i at every point (its units).

        Returns
        -------
        ndarray, shape (M, r)
        """
        for dst, src in zip(self._args, arrays):
            np.copyto(dst, src)
        self._run()
        return self._out.copy()


def mapped_call(fn: Any, count: int, nargs: int) -> tuple[BatchCall | None, Any]:
    """How to evaluate ``fn`` at ``count`` points: a bound buffer, or the mapped Function.

    Parameters
    ----------
    fn : casadi.Function
        The function (its results: the same numbers either way).
    count : int
        Number of points M of every call.
    nargs : int
        Number of arguments the caller passes.

    Returns
    -------
    (BatchCall, None) or (None, casadi.Function)
        A `BatchCall` when ``fn`` `fits` and takes ``nargs`` arguments; else ``fn`` mapped
        over ``count`` points (itself for one point).
    """
    if BatchCall.fits(fn) and nargs == fn.n_in():
        return BatchCall(fn, count), None
    return None, (fn.map(int(count), "serial") if count > 1 else fn)


class CasadiControlLaw:
    """A `ControlLaw` from a CasADi Function ``(x_hat, reference) -> u`` (batch over runs).

    The Function is evaluated on the M runs at once (``Function.map``);
    only its first output is used (feedback-linearisation laws also return
    ``zeta``).

    Parameters
    ----------
    function : casadi.Function
        Inputs ``x_hat`` (n) and the reference (r), first output ``u`` (m).
    """

    def __init__(self, function: Any):
        self.function = function
        self._mapped: dict[int, Any] = {}

    def evaluate(self, *args: np.ndarray) -> list[np.ndarray]:
        """Every output of the Function at M points: inputs (M, k_i) -> outputs (M, k_j).

        Parameters
        ----------
        *args : ndarray
            One array per input of the Function, shape (M, k_i) (its units).
        """
        count = int(args[0].shape[0])
        if count not in self._mapped:     # one bound buffer per batch size when the Function allows
            self._mapped[count] = mapped_call(self.function, count, len(args))
        buffered, fn = self._mapped[count]
        if buffered is not None:
            return buffered.all(*[np.asarray(a, dtype=float) for a in args])
        outs = fn(*[np.asarray(a, dtype=float).T for a in args])
        outs = outs if isinstance(outs, (list, tuple)) else [outs]
        return [np.asarray(o, dtype=float).reshape(-1, count).T for o in outs]

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m) for the estimate (M, n) and the reference (M, r)."""
        return self.evaluate(x_hat, reference)[0]

    def loop_law(self, runs: int) -> LoopLaw | None:
        """The law for the closed-loop kernel (`tanksynth.sim.closed_loop`): no state of its own.

        Parameters
        ----------
        runs : int
            Number of runs M.

        Returns
        -------
        LoopLaw or None
            None when the Function does not take ``(x_hat, reference)``.
        """
        fn = self.function
        if fn.n_in() != 2:
            return None
        wrapped = getattr(self, "_loop_fn", None)
        if wrapped is None:
            import casadi as ca

            x = ca.SX.sym("x", fn.nnz_in(0))
            z = ca.SX.sym("z", 0)
            r = ca.SX.sym("r", fn.nnz_in(1))
            try:
                u = fn(x, r)
            except (RuntimeError, NotImplementedError):
                return None
            u = u[0] if isinstance(u, (list, tuple)) else u
            wrapped = self._loop_fn = ca.Function("law", [x, z, r], [ca.vec(u), z])
        return LoopLaw(wrapped, np.zeros((int(runs), 0)))


class CasadiIntegralLaw(CasadiControlLaw):
    """A stateful `ControlLaw` from ``(x, z, y_r) -> (u, z_next)`` (integral tracking).

    Parameters
    ----------
    function : casadi.Function
        `tanksynth.runtime.laws.integral_tracking_law` signature.
    """

    def __init__(self, function: Any):
        super().__init__(function)
        self.z = np.zeros((0, int(function.nnz_in(1))))

    def reset(self, runs: int) -> None:
        """Zero the integrators of ``runs`` runs.

        Parameters
        ----------
        runs : int
            Number of runs M.
        """
        self.z = np.zeros((int(runs), int(self.function.nnz_in(1))))

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m); advances the integrator state."""
        u, z_next = self.evaluate(x_hat, self.z, reference)[:2]
        self.z = z_next
        return u

    def loop_law(self, runs: int) -> LoopLaw | None:
        """The law for the closed-loop kernel, from the integrators' current state (after `reset`).

        Parameters
        ----------
        runs : int
            Number of runs M.

        Returns
        -------
        LoopLaw or None
            None when the state does not have one row per run.
        """
        if self.z.shape[0] != int(runs) or self.function.n_in() != 3:
            return None

        def commit(z: np.ndarray) -> None:
            self.z = np.array(z, dtype=float)

        return LoopLaw(self.function, np.array(self.z, dtype=float), commit)
