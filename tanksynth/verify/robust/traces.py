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
