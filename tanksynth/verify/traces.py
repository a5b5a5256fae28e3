"""Recording the main simulation of a verdict, and a few others (see `tanksynth.artefacts.traces`).

Recording is explicit: the runner hands a `TraceRecorder` to the verdict
(keyword ``trace``), the verdict hands it to the simulations it runs, and each
simulation calls `TraceRecorder.record` with its result. The recorder keeps the
first simulation (the main trace) and the first simulation of each other check,
at most `TRACE_EXTRAS` of them. A verdict called without a recorder
(``trace=None``, the default) records nothing.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from tanksynth.artefacts.traces import TRACE_EXTRAS, TRACE_MAX_SAMPLES, TRACE_RUNS

__all__ = ["TraceRecorder", "trace_of"]


def trace_of(result: Any, plant: Any, *, scenario: str, check: str, estimator: bool = False,
             reference_names: Sequence[str] | None = None, runs: int = TRACE_RUNS,
             disturbances: Sequence[str] = ()) -> dict:
    """A compact trace of a simulation: ``{"header": dict, "arrays": dict of ndarray}``.

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
    disturbances : sequence of str
        Names of the plant inputs that are disturbances, not the controller's (header
        ``disturbance_names`` when any: the report draws them apart).

    Returns
    -------
    dict
        Arrays ``t`` (s), ``x`` (state units), ``t_u`` (s), ``u`` (input
        units), ``x_hat`` and ``reference`` when present, decimated to at most
        `TRACE_MAX_SAMPLES` samples; the header names them.
    """
    t = np.asarray(result.t, dtype=float)
    stride = max(1, int(math.ceil(t.size / TRACE_MAX_SAMPLES)))
    keep = slice(None, None, stride)
    r = max(1, min(int(runs), int(result.x.shape[0])))
    ref = np.asarray(result.reference, dtype=float)
    names = [str(v) for v in reference_names] if reference_names is not None else \
        [f"r{i + 1}" for i in range(ref.shape[1] if ref.ndim == 2 else 0)]
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
    if disturbances:
        header["disturbance_names"] = [str(v) for v in disturbances]
    return {"header": header, "arrays": arrays}


class TraceRecorder:
    """Keeps the trace of the first simulation a verdict records (its main one) and of the first
    simulation of each other check, at most `TRACE_EXTRAS` (2) of those.

    A simulation of a check already kept (main or extra) and any check after the limit are not
    kept: the traces stay small and the report draws one figure per kept trace.

    Attributes
    ----------
    trace : dict or None
        `trace_of` the first recorded simulation; None while nothing was
        recorded.
    extras : list of dict
        `trace_of` the first simulation of each further check, in the order recorded.
    """

    def __init__(self) -> None:
        self.trace: dict | None = None
        self.extras: list[dict] = []

    def record(self, result: Any, plant: Any, *, scenario: str, check: str, estimator: bool = False,
               reference_names: Sequence[str] | None = None, runs: int = TRACE_RUNS,
               disturbances: Sequence[str] = ()) -> None:
        """Keep the trace of ``result`` (see `trace_of`): as the main trace when none is kept, as
        an extra one when its check has none yet and fewer than `TRACE_EXTRAS` are kept.

        Parameters
        ----------
        result, plant : SimulationResult, Plant
            The simulated runs and the plant model.
        scenario, check : str
            Names of the scenario and the check the runs belong to.
        estimator, reference_names, runs : bool, sequence of str or None, int
            Whether estimates are kept, names of the references, number of runs kept.
        disturbances : sequence of str
            Names of the inputs that are disturbances (see `trace_of`).
        """
        if self.trace is not None:
            kept = {str(tr["header"]["check"]) for tr in [self.trace, *self.extras]}
            if str(check) in kept or len(self.extras) >= TRACE_EXTRAS:
                return
        tr = trace_of(result, plant, scenario=scenario, check=check, estimator=estimator,
                      reference_names=reference_names, runs=runs, disturbances=disturbances)
        if self.trace is None:
            self.trace = tr
        else:
            self.extras.append(tr)
