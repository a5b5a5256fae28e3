"""Closed-loop performance metrics of simulated runs (seed 002 section 5).

Every metric is computed per run (arrays of shape (M,)) from a
`SimulationResult` and the `ScenarioSetup` it ran:

=====================  ======  ==================================================
``ise_<state>``        m^2 s   integral square error ``sum_k (r_k - x_k)^2 ts`` of
                               each tracked state (the paper's ISE1, ISE2)
``tracking_time``      s       set-point tracking time: from a set-point step
                               until every tracked error stays within the band
``rejection_time``     s       disturbance rejection time: the same after water is
                               added/removed or a fault appears
``offset_<state>``     m       steady offset ``mean(x - r)`` over the last window
``rmse_<state>``       m       estimation RMSE ``sqrt(mean((x_hat - x)^2))``
``estimator_time``     s       batch estimator time per sample, divided by M
``controller_time``    s       batch control-law time per sample, divided by M
=====================  ======  ==================================================

Units are those of the plant's states (m for the tanks). Times that never
settle are ``inf``. When several steps or disturbances occur, the
tracking/rejection time is the largest over them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from tanksynth.plants.base import Plant
from tanksynth.sim.scenarios import ScenarioSetup
from tanksynth.sim.simulate import SimulationResult

__all__ = ["Metric", "ise", "settling_time", "steady_offset", "estimation_rmse", "compute_metrics",
           "metric_table"]


@dataclass(frozen=True)
class Metric:
    """One metric over the runs.

    Attributes
    ----------
    name : str
    values : ndarray, shape (M,)
    unit : str
    description : str
    """

    name: str
    values: np.ndarray
    unit: str
    description: str


def _errors(result: SimulationResult, tracked: Sequence[int]) -> np.ndarray:
    """``r - x`` of the tracked states, shape (M, N + 1, r)."""
    return result.reference[None, :, :] - result.x[:, :, list(tracked)]


def ise(result: SimulationResult, tracked: Sequence[int], start: int = 0) -> np.ndarray:
    """Integral square error of each tracked state, shape (M, r), in (state unit)^2 s.

    ``ISE_i = sum_{k >= start} (r_i(k) - x_i(k))^2 ts`` over the samples.
    """
    e = _errors(result, tracked)[:, start:]
    return np.sum(e * e, axis=1) * result.ts


def settling_time(error: np.ndarray, start: int, stop: int, band: float, ts: float) -> np.ndarray:
    """Time after sample ``start`` until ``|error|`` stays within ``band``.

    Parameters
    ----------
    error : ndarray, shape (M, N + 1, r)
        Errors (state units).
    start, stop : int
        Sample window ``[start, stop)`` (the next event or the end).
    band : float
        Tolerance (state units).
    ts : float
        Sampling period (s).

    Returns
    -------
    ndarray, shape (M,)
        Seconds; 0 if the error never leaves the band, ``inf`` if it is still
        outside it at the end of the window.
    """
    window = np.abs(error[:, start:stop]) > band
    outside = np.any(window, axis=2)                    # (M, W)
    count = outside.shape[1]
    out = np.zeros(outside.shape[0])
    for r in range(outside.shape[0]):
        idx = np.flatnonzero(outside[r])
        if idx.size == 0:
            continue
        last = int(idx[-1])
        out[r] = np.inf if last == count - 1 else (last + 1) * ts
    return out


def steady_offset(result: SimulationResult, tracked: Sequence[int], window: int | None = None) -> np.ndarray:
    """Mean of ``x - r`` over the last ``window`` samples, shape (M, r) (state units).

    The default window is the last 10 % of the samples (at least one).
    """
    count = result.x.shape[1]
    w = max(1, count // 10) if window is None else max(1, int(window))
    return -np.mean(_errors(result, tracked)[:, -w:], axis=1)


def estimation_rmse(result: SimulationResult, start: int = 0) -> np.ndarray:
    """RMSE of the estimate of each state, shape (M, n) (state units)."""
    d = result.x_hat[:, start:] - result.x[:, start:]
    return np.sqrt(np.mean(d * d, axis=1))


def compute_metrics(result: SimulationResult, setup: ScenarioSetup, plant: Plant,
                    band: float | None = None) -> dict[str, Metric]:
    """Every metric of a scenario run, by name.

    Parameters
    ----------
    result : SimulationResult
    setup : ScenarioSetup
        The scenario it ran (tracked states, event samples).
    plant : Plant
        The simulated plant (state names and units for the metric names).
    band : float, optional
        Tolerance of the tracking/rejection times (state units). Default:
        5 % of the largest set-point step or level jump of the scenario, or
        1 % of the largest set-point when it has neither.

    Returns
    -------
    dict of str to Metric
    """
    tracked = setup.tracked
    sc = setup.scenario
    state_names = [s.name for s in plant.states]
    units = [s.unit for s in plant.states]
    names = [state_names[i] for i in tracked]
    M = result.runs
    out: dict[str, Metric] = {}
    if tracked and result.reference.shape[1] == len(tracked):
        values = ise(result, tracked)
        for j, nm in enumerate(names):
            out[f"ise_{nm}"] = Metric(f"ise_{nm}", values[:, j], f"{units[tracked[j]]}^2 s",
                                      f"integral square error of {nm}")
        off = steady_offset(result, tracked)
        for j, nm in enumerate(names):
            out[f"offset_{nm}"] = Metric(f"offset_{nm}", off[:, j], units[tracked[j]],
                                         f"steady offset of {nm} (mean x - r, last 10 % of samples)")
        sizes = [abs(s) for _, s in sc.setpoint_steps] + [abs(s) for _, _, s in sc.reference_steps]
        sizes += [abs(d) for _, d in sc.jumps]
        tol = band if band is not None else (0.05 * max(sizes) if sizes
                                             else 0.01 * float(np.max(np.abs(result.reference))))
        events = sorted(set(setup.setpoint_samples) | set(setup.disturbance_samples))
        err = _errors(result, tracked)
        for kind, samples in (("tracking_time", setup.setpoint_samples),
                              ("rejection_time", setup.disturbance_samples)):
            if not samples:
                continue
            worst = np.zeros(M)
            for s in samples:
                later = [e for e in events if e > s]
                stop = later[0] if later else err.shape[1]
                worst = np.maximum(worst, settling_time(err, s, stop, tol, result.ts))
            what = "set-point tracking" if kind == "tracking_time" else "disturbance rejection"
            out[kind] = Metric(kind, worst, "s", f"{what} time (band {tol:.3g} {units[tracked[0]]})")
    rmse = estimation_rmse(result)
    for i, nm in enumerate(state_names):
        out[f"rmse_{nm}"] = Metric(f"rmse_{nm}", rmse[:, i], units[i], f"estimation RMSE of {nm}")
    calls = max(int(result.timing.get("calls", 0)), 1)
    for key in ("estimator", "controller"):
        per = float(result.timing.get(key, 0.0)) / calls / max(M, 1)
        out[f"{key}_time"] = Metric(f"{key}_time", np.full(M, per), "s",
                                    f"{key} computation time per sample and run (batch time / M)")
    return out


def metric_table(metrics: Mapping[str, Metric]) -> dict[str, float]:
    """Mean of each metric over the runs (for summaries)."""
    return {name: float(np.mean(m.values)) for name, m in metrics.items()}

