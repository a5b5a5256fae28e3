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
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from tanksynth.artefacts.traces import TRACE_EXTRAS, TRACE_MAX_SAMPLES, TRACE_MAX_VALUES, TRACE_RUNS

if TYPE_CHECKING:  # annotations only: this module stays free of the plant (sympy) stack
    from tanksynth.plants.base import Plant

__all__ = ["Signal", "TraceRecorder", "trace_of"]


@dataclass(frozen=True, eq=False)
class Signal:
    """A further named signal of a simulation, recorded beside the states (see `trace_of`).

    Attributes
    ----------
    name : str
        Legend entry (e.g. ``|epsilon|``).
    unit : str
        Its unit (as the verdict defines it).
    values : ndarray, shape (M, N + 1)
        One value per run of the batch and sample time ``result.t``, in ``unit``.
    style : str
        Line style of the figure: ``"-"`` solid, ``"--"`` dashed, ``":"`` dotted.
    """

    name: str
    unit: str
    values: Any
    style: str = "-"


def trace_of(result: Any, plant: Plant, *, scenario: str, check: str, estimator: bool = False,
             reference_names: Sequence[str] | None = None, runs: int = TRACE_RUNS,
             disturbances: Sequence[str] = (), rows: Sequence[int] | None = None,
             signals: Sequence[Signal] = (), signal_title: str = "",
             events: Sequence[tuple[float, str]] = ()) -> dict:
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
    rows : sequence of int, optional
        The runs of the batch kept, in this order (at most ``runs`` of them); default the
        first ``runs`` runs. Fewer are kept when the widest array would hold more than
        `TRACE_MAX_VALUES` values (the limit of a trace file).
    signals : sequence of Signal
        Further named signals on the sample times ``result.t``, one value per run of the batch
        (e.g. a residual and its threshold): array ``signals`` (runs kept, samples, k) and header
        ``signal_names``, ``signal_units``, ``signal_styles``, ``signal_title``; nothing of
        them when empty (the trace is then the one written before signals existed).
    signal_title : str
        Title of the signals' panel (header ``signal_title``).
    events : sequence of (float, str)
        Instants (s) worth marking in the signals' panel with their labels, e.g. the fault onset
        (header ``events``, ``[[t, label], ...]``; only with signals).

    Returns
    -------
    dict
        Arrays ``t`` (s), ``x`` (state units), ``t_u`` (s), ``u`` (input
        units), ``x_hat``, ``reference`` and ``signals`` (signal units) when present, and ``y``
        (runs kept, samples, q; output units, header ``output_names``, ``output_units``) when a
        reference names an output that is not a state; decimated to
        at most `TRACE_MAX_SAMPLES` samples; the header names them.

    Raises
    ------
    ValueError
        A kept run index outside the batch, or a signal not one value per run and sample.
    """
    t = np.asarray(result.t, dtype=float)
    stride = max(1, int(math.ceil(t.size / TRACE_MAX_SAMPLES)))
    keep = slice(None, None, stride)
    M = int(result.x.shape[0])
    if rows is None:
        idx = np.arange(max(1, min(int(runs), M)))
    else:
        idx = np.asarray([int(i) for i in rows][:max(1, int(runs))], dtype=int)
        if idx.size == 0 or np.any((idx < 0) | (idx >= M)):
            raise ValueError(f"trace_of: runs {list(rows)} to keep of a batch of {M}")
    # a trace file stays within what every reader accepts (TRACE_MAX_VALUES per array): the
    # widest array's runs are cut (a Monte-Carlo batch of thousands keeps its first ones)
    widest = max([int(np.asarray(result.x).shape[-1]), int(np.asarray(result.u).shape[-1]), len(signals), 1])
    idx = idx[:max(1, TRACE_MAX_VALUES // (min(t.size, TRACE_MAX_SAMPLES) * widest))]
    r = int(idx.size)
    ref = np.asarray(result.reference, dtype=float)
    names = [str(v) for v in reference_names] if reference_names is not None else \
        [f"r{i + 1}" for i in range(ref.shape[1] if ref.ndim == 2 else 0)]
    arrays: dict[str, np.ndarray] = {
        "t": t[keep],
        "x": np.asarray(result.x, dtype=float)[idx][:, keep],
        "t_u": t[:-1][keep],
        "u": np.asarray(result.u, dtype=float)[idx][:, keep],
    }
    if estimator:
        arrays["x_hat"] = np.asarray(result.x_hat, dtype=float)[idx][:, keep]
    if ref.ndim == 2 and ref.shape[1] > 0:
        arrays["reference"] = ref[keep]
    states = [q.name for q in plant.states]
    y = np.asarray(getattr(result, "y", np.zeros((0, 0, 0))), dtype=float)
    # references of outputs that are not states (y = kc h1 in V): the outputs are kept, so that the
    # figure draws them and their references in output units, not beside the states
    outputs_kept = bool("reference" in arrays and any(v not in states for v in names[:ref.shape[1]])
                        and y.ndim == 3 and y.shape[:2] == tuple(np.shape(result.x))[:2])
    if outputs_kept:
        arrays["y"] = y[idx][:, keep]
    header = {
        "schema": "tanksynth.traces/1",
        "scenario": str(scenario),
        "check": str(check),
        "runs": r,
        "stride": stride,
        "ts": float(result.ts),
        "plant": str(getattr(plant, "name", "")),
        "state_names": states,
        "state_units": [q.unit for q in plant.states],
        "input_names": [q.name for q in plant.inputs],
        "input_units": [q.unit for q in plant.inputs],
        "reference_names": names[:ref.shape[1]] if ref.ndim == 2 else [],
        "seeds": [int(v) for v in np.asarray(result.seeds)[idx]],
    }
    if outputs_kept:
        header["output_names"] = [q.name for q in plant.outputs]
        header["output_units"] = [q.unit for q in plant.outputs]
    if disturbances:
        header["disturbance_names"] = [str(v) for v in disturbances]
    if signals:
        values = []
        for sig in signals:
            v = np.asarray(sig.values, dtype=float)
            if v.shape != (M, t.size):
                raise ValueError(f"trace_of: signal {sig.name!r} has shape {v.shape}, expected "
                                 f"{(M, t.size)} (runs, samples)")
            values.append(v[idx][:, keep])
        arrays["signals"] = np.stack(values, axis=-1)
        header["signal_names"] = [str(sig.name) for sig in signals]
        header["signal_units"] = [str(sig.unit) for sig in signals]
        header["signal_styles"] = [str(sig.style) for sig in signals]
        header["signal_title"] = str(signal_title)
        header["events"] = [[float(te), str(label)] for te, label in events]
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

    def record(self, result: Any, plant: Plant, *, scenario: str, check: str, estimator: bool = False,
               reference_names: Sequence[str] | None = None, runs: int = TRACE_RUNS,
               disturbances: Sequence[str] = (), **more: Any) -> None:
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
        **more
            ``rows``, ``signals``, ``signal_title``, ``events`` of `trace_of`.
        """
        if self.trace is not None:
            kept = {str(tr["header"]["check"]) for tr in [self.trace, *self.extras]}
            if str(check) in kept or len(self.extras) >= TRACE_EXTRAS:
                return
        tr = trace_of(result, plant, scenario=scenario, check=check, estimator=estimator,
                      reference_names=reference_names, runs=runs, disturbances=disturbances, **more)
        if self.trace is None:
            self.trace = tr
        else:
            self.extras.append(tr)
