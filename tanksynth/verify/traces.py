"""Recording the main simulation of a running verdict (see `tanksynth.artefacts.traces`)."""

from __future__ import annotations

import math
from contextvars import ContextVar
from typing import Any, Sequence

import numpy as np

from tanksynth.artefacts.traces import TRACE_MAX_SAMPLES, TRACE_RUNS

__all__ = ["record_trace"]


#: The trace slot of the verdict running in this context (None: nothing is recorded).
_TRACE: ContextVar[dict | None] = ContextVar("tanksynth_verdict_trace", default=None)



def record_trace(result: Any, plant: Any, *, scenario: str, check: str, estimator: bool = False,
                 reference_names: Sequence[str] | None = None, runs: int = TRACE_RUNS) -> None:
    """Keep a compact trace of a verdict simulation (the first one of the verdict only).

    Does nothing unless the verdict runs under `verdict_with_trace`, or when
    that verdict already recorded a trace: the first simulation a verdict
    runs is its main one.

    Parameters
    ----------
    result : SimulationResult
    plant : Plant
        Gives the state, input and output names and units.
    scenario : str
        What the simulation does (plain text, for the figure caption).
    check : str
        Name of the check this simulation decides.
    estimator : bool
        The run has an estimator/observer (``x_hat`` is kept).
    reference_names : sequence of str, optional
        Names of the reference columns (states or outputs); default
        ``r1, r2, ...``.
    runs : int
        First runs of the batch kept.
    """
    slot = _TRACE.get()
    if slot is None or "trace" in slot:
        return
    t = np.asarray(result.t, dtype=float)
    stride = max(1, int(math.ceil(t.size / TRACE_MAX_SAMPLES)))
    keep = slice(None, None, stride)
    r = max(1, min(int(runs), int(result.x.shape[0])))
    ref = np.asarray(result.reference, dtype=float)
    names = [str(v) for v in reference_names] if reference_names is not None else \
        [f"r{i + 1}" for i in range(ref.shape[1])]
    arrays: dict[str, np.ndarray] = {
        "t": t[keep],
        "x": np.asarray(result.x[:r], dtype=float)[:, keep],
        "t_u": t[:-1][keep],
        "u": np.asarray(result.u[:r], dtype=float)[:, keep],
    }
    if estimator:
        arrays["x_hat"] = np.asarray(result.x_hat[:r], dtype=float)[:, keep]
    if ref.ndim == 2 and ref.shape[1] > 0:
        arrays["reference"] = ref[keep]
    header = {
        "schema": "tanksynth.traces/1",
        "scenario": str(scenario),
        "check": str(check),
        "runs": r,
        "stride": stride,
        "ts": float(result.ts),
        "plant": str(getattr(plant, "name", "")),
        "state_names": [q.name for q in plant.states],
        "state_units": [q.unit for q in plant.states],
        "input_names": [q.name for q in plant.inputs],
        "input_units": [q.unit for q in plant.inputs],
        "reference_names": names[:ref.shape[1]] if ref.ndim == 2 else [],
        "seeds": [int(v) for v in np.asarray(result.seeds)[:r]],
    }
    slot["trace"] = {"header": header, "arrays": arrays}
