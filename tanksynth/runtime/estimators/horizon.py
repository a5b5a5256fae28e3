"""Horizon kernels: an estimator's step over a whole measurement sequence in native calls.

A `KernelEstimator` steps one sample per call from Python (a few microseconds of
overhead per step). When the measurements and inputs are known in advance (an
open-loop simulation, a replayed log, a verdict's scenario) the same step runs
over the sequence inside one compiled function instead:

* `horizon_function`: the step accumulated over `CHUNK` samples (CasADi
  ``mapaccum``: the state, covariance included, carried from step to step; the
  measurements and inputs, ``q x CHUNK`` and ``m x CHUNK``, one column per
  step; the parameters shared), returning the state after every step and the
  checks of every step. One chunk length for every sequence: a sequence of
  ``N`` samples takes ``ceil(N / CHUNK)`` calls (the last chunk padded with its
  last sample, whose results are dropped), so one library serves every ``N``.
* `observed_step`: the step with a mask of the outputs measured at that
  sample, the same numbers as `KernelEstimator.step_observed` (a single run)
  for the replay of logs with missing or censored values.
* `Horizon`: a compiled horizon kernel mapped over ``M`` runs (``Function.map``
  of the loaded library, no new compile per ``M``), with its numpy buffers.

Compilation: the MX function is generated to C and compiled with the
estimator kernels' cache (`tanksynth.runtime.estimators.kernels.native_function`,
family ``kernels``; the key is the generated source, so the step's structure
and the chunk length). The same C code of the step as the one-step kernel, the
same flags (no fused multiply-add): the same numbers, bit for bit on this
machine. A library not yet on disk is built only for sequences of at least
`BUILD_STEPS` run-steps (shorter ones step until it is built; one on disk is always loaded).

Environment (`horizon_backend`): ``TANKSYNTH_ESTIMATOR_BACKEND`` = ``auto``
(default; as above), ``horizon`` (build whatever the length) or ``step`` (never:
one call per sample, the path before horizon kernels); ``TANKSYNTH_SIM_BACKEND=numpy``
also means ``step``. Without a C compiler (an estimator on CasADi's virtual
machine) the estimator steps.
"""

from __future__ import annotations

import os
from typing import Any

import casadi as ca
import numpy as np

__all__ = ["CHUNK", "BUILD_STEPS", "HORIZON_BACKENDS", "horizon_backend", "horizon_function",
           "observed_step", "Horizon"]

#: Samples per call of a horizon kernel (the kernel's length; a sequence takes ceil(N / CHUNK)).
CHUNK = 256

#: Run-steps (samples x runs) from which ``auto`` compiles a horizon library not yet on disk (the
#: compiler takes 0.3-2 s once per machine, stepping about 5 us per sample): shorter sequences
#: step unless the library is already built (loaded, then, whatever the length).
BUILD_STEPS = 20_000

#: Values of ``TANKSYNTH_ESTIMATOR_BACKEND``.
HORIZON_BACKENDS = ("auto", "horizon", "step")


def horizon_backend() -> str:
    """The horizon-kernel policy asked by the environment (see the module notes).

    Returns
    -------
    str
        ``"step"`` when ``TANKSYNTH_SIM_BACKEND=numpy`` or ``TANKSYNTH_ESTIMATOR_BACKEND=step``,
        ``"horizon"`` when ``TANKSYNTH_ESTIMATOR_BACKEND=horizon``, else ``"auto"`` (an unknown
        value counts as ``auto``).
    """
    if (os.environ.get("TANKSYNTH_SIM_BACKEND") or "").strip().lower() == "numpy":
        return "step"
    value = (os.environ.get("TANKSYNTH_ESTIMATOR_BACKEND") or "auto").strip().lower()
    return value if value in HORIZON_BACKENDS else "auto"


def observed_step(step: ca.Function, model: Any, n: int, q: int,
                  unobserved_variance: float) -> ca.Function:
    """The step with a fifth input ``observed`` (q flags): `KernelEstimator.step_observed` in SX.

    An unobserved output ``i`` (flag 0) gets ``R_ii = unobserved_variance * scale`` with
    ``scale = max(1, max|R|, max|state[n:]|)`` and its correlations zeroed, and its measurement
    replaced by the one-step prediction ``h(F(x, u))`` of the step's model (what the replay
    feeds); with every flag 1 the step is the plain step (the same numbers).

    Parameters
    ----------
    step : casadi.Function
        The SX step ``(state, y, u, params) -> (state_new, checks, extra)`` whose ``params``
        end with ``R`` (q x q, column-major).
    model : DiscreteModel
        The sampled model of the step (``predict_sx``, ``output_sx``).
    n, q : int
        States and outputs.
    unobserved_variance : float
        Relative variance of an unobserved output (dimensionless,
        `KernelEstimator.UNOBSERVED_VARIANCE`).

    Returns
    -------
    casadi.Function
        ``(state, y, u, params, observed) -> (state_new, checks, extra)`` (SX).
    """
    S, y, u, p = step.sx_in()
    o = ca.SX.sym("observed", q)
    x = S[:n]
    yp = model.output_sx(model.predict_sx(x, u))
    y_eff = ca.vertcat(*[ca.if_else(o[i] > 0, y[i], yp[i]) for i in range(q)])
    R = ca.reshape(p[p.numel() - q * q:], q, q)
    scale = ca.SX(1.0)
    for i in range(q * q):
        scale = ca.fmax(scale, ca.fabs(p[p.numel() - q * q + i]))
    for i in range(n, S.numel()):
        scale = ca.fmax(scale, ca.fabs(S[i]))
    entries = []
    for j in range(q):          # column-major, as the parameters hold R
        for i in range(q):
            if i == j:
                entries.append(ca.if_else(o[i] > 0, R[i, i], unobserved_variance * scale))
            else:
                entries.append(ca.if_else(ca.logic_and(o[i] > 0, o[j] > 0), R[i, j], 0.0))
    p_eff = ca.vertcat(p[:p.numel() - q * q], *entries)
    out = step.call([S, y_eff, u, p_eff])
    return ca.Function(f"{step.name()}_observed", [S, y, u, p, o], out,
                       [*step.name_in(), "observed"], step.name_out())


def horizon_function(step: ca.Function, chunk: int = CHUNK) -> ca.Function:
    """The step accumulated over ``chunk`` samples, one MX function (see the module notes).

    Parameters
    ----------
    step : casadi.Function
        ``(state, y, u, params[, observed]) -> (state_new, checks, extra)`` (SX).
    chunk : int
        Samples per call.

    Returns
    -------
    casadi.Function
        ``(state (s), y (q x chunk), u (m x chunk), params (p)[, observed (q x chunk)]) ->
        (states (s x chunk), checks (c x chunk))``: column ``k`` is the state after, and the
        checks of, the step fed column ``k`` (the ``extra`` outputs are left out).
    """
    ins = step.sx_in()
    outs = step.call(ins)
    core = ca.Function(f"{step.name()}_sc", ins, outs[:2], step.name_in(), step.name_out()[:2])
    acc = core.mapaccum(f"{step.name()}_acc", chunk)
    S = ca.MX.sym("state", step.size1_in(0))
    seq = [ca.MX.sym(step.name_in(i), step.size1_in(i), chunk) for i in (1, 2)]
    P = ca.MX.sym("params", step.size1_in(3))
    args = [S, *seq, ca.repmat(P, 1, chunk)]
    inputs = [S, *seq, P]
    if step.n_in() == 5:
        O = ca.MX.sym("observed", step.size1_in(4), chunk)
        args.append(O)
        inputs.append(O)
    states, checks = acc(*args)
    return ca.Function(f"{step.name()}_horizon{chunk}", inputs, [states, checks],
                       [step.name_in(i) for i in range(len(inputs))], ["states", "checks"])


class Horizon:
    """A loaded horizon kernel over ``runs`` runs, with its buffers.

    Parameters
    ----------
    fn : casadi.Function
        The loaded library of a `horizon_function` (``chunk`` from its inputs).
    runs : int
        Number of runs ``M`` (the kernel is mapped over them, the parameters shared).
    params : ndarray, shape (p,)
        The parameter vector (kept by reference: its current values are used at each call).
    """

    def __init__(self, fn: ca.Function, runs: int, params: np.ndarray):
        self.chunk = int(fn.size2_in(1))
        self.runs = int(runs)
        self.masked = fn.n_in() == 5
        run_fn: Any = fn if runs == 1 else fn.map(f"{fn.name()}_map{runs}", "serial", runs, [3], [])
        M, L = self.runs, self.chunk
        s, q, m, c = fn.size1_in(0), fn.size1_in(1), fn.size1_in(2), fn.size1_out(1)
        self.state = np.zeros((M, s))
        self.Y = np.zeros((M, L, q))
        self.U = np.zeros((M, L, m))
        self.O = np.ones((M, L, q))
        self.states = np.zeros((M, L, s))
        self.checks = np.zeros((M, L, c))
        self.params = params
        self._fb, self._ev = run_fn.buffer()
        self._fb.set_arg(0, self.state.reshape(-1).data)
        self._fb.set_arg(1, self.Y.reshape(-1).data)
        self._fb.set_arg(2, self.U.reshape(-1).data)
        self._fb.set_arg(3, params.data)
        if self.masked:
            self._fb.set_arg(4, self.O.reshape(-1).data)
        self._fb.set_res(0, self.states.reshape(-1).data)
        self._fb.set_res(1, self.checks.reshape(-1).data)
        self.function = fn

    def run(self, state0: np.ndarray, Y: np.ndarray, U: np.ndarray, out: np.ndarray,
            observed: np.ndarray | None = None) -> int:
        """The states after every sample of a sequence, and where its checks first failed.

        Parameters
        ----------
        state0 : ndarray, shape (M, s)
            Kernel state before the first sample.
        Y : ndarray, shape (N, M, q)
            Measurements (output units).
        U : ndarray, shape (N, M, m)
            Inputs held before each measurement (input units).
        out : ndarray, shape (N, M, r)
            Filled with the first ``r`` entries of the state after each sample (``r <= s``).
        observed : ndarray, shape (N, q), optional
            Masked kernels: 1 where the output was measured, 0 where not.

        Returns
        -------
        int
            Samples done: ``N`` when every check passed, else the first sample of the chunk
            whose checks failed (``out`` is filled before it); the last state done is in
            `state`.
        """
        N, L = Y.shape[0], self.chunk
        r = out.shape[2]
        self.state[:] = state0
        npiv = self.checks.shape[2] - 1
        for a in range(0, N, L):
            b = min(a + L, N)
            k = b - a
            self.Y[:, :k] = Y[a:b].transpose(1, 0, 2)
            self.U[:, :k] = U[a:b].transpose(1, 0, 2)
            if observed is not None:
                self.O[:, :k] = observed[a:b]
            if k < L:               # pad with the last sample (results dropped)
                self.Y[:, k:] = self.Y[:, k - 1:k]
                self.U[:, k:] = self.U[:, k - 1:k]
                self.O[:, k:] = self.O[:, k - 1:k]
            self._ev()
            chk = self.checks[:, :k]
            if not (np.isfinite(chk).all() and (chk[:, :, :npiv] > 0).all()):
                return a
            out[a:b] = self.states[:, :k, :r].transpose(1, 0, 2)
            self.state[:] = self.states[:, k - 1]
        return N
