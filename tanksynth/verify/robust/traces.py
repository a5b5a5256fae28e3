"""Traces of the robust verdicts: the Monte-Carlo runs recorded for the report's figure.

``robust_state_feedback`` / ``robust_observer`` verdicts simulate the
nonlinear plant with parameters drawn in the uncertain box
(`tanksynth.verify.robust.verdicts`); `record_monte_carlo` hands those runs to the
verdict's `tanksynth.verify.traces.TraceRecorder` (every run, so the
time-domain figure shows the spread over the box). `PeakRecordingLaw` is the
law wrapper of the saturation check.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from tanksynth.plants.base import Plant
from tanksynth.sim.closed_loop import LoopLaw
from tanksynth.sim.simulate import SimulationResult
from tanksynth.verify.traces import TraceRecorder

__all__ = ["PeakRecordingLaw", "record_monte_carlo"]


class PeakRecordingLaw:
    """A control law that remembers its largest unclipped ``|u - u0| / umax`` per run.

    Parameters
    ----------
    law : callable
        ``law(x, reference, t) -> u`` (batch, input units).
    u0, umax : ndarray, shape (m,)
        Operating input and the allowed excursion (input units).
    """

    def __init__(self, law: Any, u0: np.ndarray, umax: np.ndarray):
        self.law, self.u0, self.umax = law, u0, umax
        self.peak: np.ndarray | None = None

    def reset(self, runs: int) -> None:
        """Start a batch of ``runs`` runs.

        Parameters
        ----------
        runs : int
            Batch size.
        """
        if hasattr(self.law, "reset"):
            self.law.reset(runs)
        self.peak = np.zeros(runs)

    def __call__(self, x: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m), the peak ratio updated."""
        u = self.law(x, reference, t)
        ratio = np.max(np.abs(u - self.u0) / self.umax, axis=1)
        self.peak = ratio if self.peak is None else np.maximum(self.peak, ratio)
        return u

    def loop_law(self, runs: int) -> LoopLaw | None:
        """The wrapped law's `LoopLaw` with the peak as one more state per run (the last).

        ``peak_next = fmax(peak, max_j |u_j - u0_j| / umax_j)`` on the unclipped input,
        the operations of `__call__` (a maximum is exact whatever the order).

        Parameters
        ----------
        runs : int
            Number of runs M.

        Returns
        -------
        LoopLaw or None
            None when the wrapped law offers none, `reset` was not called for ``runs``
            runs, or ``umax`` is not positive everywhere.
        """
        import casadi as ca

        offer = getattr(self.law, "loop_law", None)
        u0 = np.asarray(self.u0, dtype=float).reshape(-1)
        umax = np.asarray(self.umax, dtype=float).reshape(-1)
        if (offer is None or self.peak is None or self.peak.shape != (int(runs),)
                or not np.all(umax > 0) or umax.shape != u0.shape):
            return None
        inner = offer(runs)
        if inner is None:
            return None
        fn = inner.function
        n, p, nr = int(fn.nnz_in(0)), int(fn.nnz_in(1)), int(fn.nnz_in(2))
        if int(fn.nnz_out(0)) != u0.size:
            return None
        key = (id(fn), u0.tobytes(), umax.tobytes())
        held = self.__dict__.get("_loop_fn")
        if held is None or held[0] != key or held[1] is not fn:
            x, z, r = ca.SX.sym("x", n), ca.SX.sym("z", p + 1), ca.SX.sym("r", nr)
            u, zn = fn(x, z[:p], r)[:2]
            ratio = ca.fabs(u[0] - u0[0]) / umax[0]
            for j in range(1, u0.size):
                ratio = ca.fmax(ratio, ca.fabs(u[j] - u0[j]) / umax[j])
            wrapped = ca.Function("peak_recording", [x, z, r],
                                  [u, ca.vertcat(zn, ca.fmax(z[p], ratio))])
            held = self.__dict__["_loop_fn"] = (key, fn, wrapped)
        state = np.concatenate([np.asarray(inner.state, dtype=float).reshape(int(runs), p),
                                np.asarray(self.peak, dtype=float).reshape(-1, 1)], axis=1)

        def commit(zf: np.ndarray) -> None:
            if inner.commit is not None:
                inner.commit(np.array(zf[:, :p]))
            self.peak = np.array(zf[:, p], dtype=float)

        return LoopLaw(held[2], state, commit)


def record_monte_carlo(trace: TraceRecorder | None, result: SimulationResult, plant: Plant, *, observer: bool,
                       reference_names: Sequence[str] | None = None) -> None:
    """Record the Monte-Carlo runs of a robust verdict (no-op without a recorder).

    Parameters
    ----------
    trace : TraceRecorder or None
        The verdict's recorder.
    result : SimulationResult
        The batch of runs (one plant per run).
    plant : Plant
        Names and units of the signals.
    observer : bool
        The runs have estimates (``robust_observer``).
    reference_names : sequence of str, optional
        Names of the reference columns (integral action).
    """
    if trace is None:
        return
    what = ("the observer (one gain L) on" if observer else "the robust state feedback on")
    trace.record(result, plant, scenario=f"Monte-Carlo: {what} nonlinear plants with parameters "
                                         "drawn in the uncertain box, from a perturbed start",
                 check="monte_carlo", estimator=observer, reference_names=reference_names,
                 runs=int(np.asarray(result.x).shape[0]))
