"""Performance metrics of simulated runs, named after the plant's own quantities.

Every metric is computed per run (arrays of shape (M,)). A metric exists only
for what ran: tracking metrics for a controller's controlled variables,
estimation RMSE for an estimator's estimate, detection metrics for a
residual and a threshold, prediction errors for a model.

===========================  ======  ===============================================
``ise_<y>``                  y^2 s   integral square error ``sum_k (r_k - y_k)^2 ts`` of
                                     each controlled variable ``y`` (seed 002 section 5's
                                     ISE1, ISE2)
``offset_<y>``               y       steady offset ``mean(y - r)`` over the last 10 %
``tracking_time``            s       from a set-point step until every controlled error
                                     stays within the band
``rejection_time``           s       the same after water is added/removed or a fault
``rmse_<state>``             state   estimation RMSE ``sqrt(mean((x_hat - x)^2))`` after
                                     the warm-up (`ESTIMATION_WARMUP`)
``estimator_time``           s       batch estimator time per sample, divided by M
``controller_time``          s       batch control-law time per sample, divided by M
``detection_delay``          s       first alarm at or after the fault onset, minus the
                                     onset (``inf``: missed)
``false_alarm_rate``         1       fraction of the samples of the fault-free run that
                                     raise an alarm
``first_false_alarm``        s       time of the first alarm of the fault-free run
                                     (``inf``: none)
``prediction_rmse_<state>``  state   RMS error of a model's free-run prediction
``one_step_rmse_<state>``    state   RMS error of a model's one-step prediction
===========================  ======  ===============================================

``<y>`` is the name of the plant output that equals the controlled state
when there is one, else the state's name (a law may control a state that
is not measured: the hybrid three-tank measures only h3 and controls h1,
h2). Units are the plant's. Times that never settle are ``inf``; with
several steps or disturbances the tracking/rejection time is the largest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from tanksynth.plants.base import Plant
from tanksynth.sim.scenarios import ScenarioSetup
from tanksynth.sim.simulate import SimulationResult

__all__ = ["Metric", "ESTIMATION_WARMUP", "warmup_samples", "controlled_names", "ise",
           "settling_time", "steady_offset", "estimation_rmse", "tracking_metrics",
           "estimation_metrics", "timing_metrics", "detection_metrics", "prediction_metrics",
           "compute_metrics", "metric_table"]

#: Fraction of a run's samples an estimator may spend converging before its RMSE counts.
ESTIMATION_WARMUP = 0.1


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


def warmup_samples(steps: int, fraction: float = ESTIMATION_WARMUP) -> int:
    """First sample whose estimate counts in the RMSE.

    Parameters
    ----------
    steps : int
        Periods N of the run (samples 0..N).
    fraction : float
        Warm-up as a fraction of N (default `ESTIMATION_WARMUP`, 10 %).

    Returns
    -------
    int
        ``max(1, round(fraction N))``: sample 0 (the initial guess) never counts.
    """
    return max(1, int(round(float(fraction) * int(steps))))


def controlled_names(plant: Plant, tracked: Sequence[int]) -> list[str]:
    """Names of the controlled variables: the output equal to each state, else the state.

    Parameters
    ----------
    plant : Plant
    tracked : sequence of int
        Controlled state indices.
    """
    names = []
    for i in tracked:
        out = [o.name for o, h in zip(plant.outputs, plant.h) if h == plant.x[i]]
        names.append(out[0] if out else plant.states[i].name)
    return names


def _errors(result: SimulationResult, tracked: Sequence[int]) -> np.ndarray:
    """``r - x`` of the tracked states, shape (M, N + 1, r)."""
    return result.reference[None, :, :] - result.x[:, :, list(tracked)]


def ise(result: SimulationResult, tracked: Sequence[int], start: int = 0) -> np.ndarray:
    """Integral square error of each tracked state, shape (M, r), in (state unit)^2 s.

    ``ISE_i = sum_{k >= start} (r_i(k) - x_i(k))^2 ts`` over the samples.

    Parameters
    ----------
    result : SimulationResult
        The simulated runs.
    tracked : sequence of int
        Indices of the tracked states.
    start : int, optional
        First sample counted.
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

    Parameters
    ----------
    result : SimulationResult
        The simulated runs.
    tracked : sequence of int
        Indices of the tracked states.
    window : int, optional
        Number of final samples averaged.
    """
    count = result.x.shape[1]
    w = max(1, count // 10) if window is None else max(1, int(window))
    return -np.mean(_errors(result, tracked)[:, -w:], axis=1)


def estimation_rmse(result: SimulationResult, start: int = 0) -> np.ndarray:
    """RMSE of the estimate of each state over samples ``k >= start``, shape (M, n) (state units).

    Parameters
    ----------
    result : SimulationResult
        The simulated runs (with estimates).
    start : int, optional
        First sample counted.
    """
    d = result.x_hat[:, start:] - result.x[:, start:]
    return np.sqrt(np.mean(d * d, axis=1))


def tracking_metrics(result: SimulationResult, setup: ScenarioSetup, plant: Plant,
                     band: float | None = None) -> dict[str, Metric]:
    """ISE, offset, tracking and rejection times of the controlled variables.

    Parameters
    ----------
    result : SimulationResult
    setup : ScenarioSetup
        The scenario it ran (tracked states, event samples).
    plant : Plant
    band : float, optional
        Tolerance of the tracking/rejection times (state units). Default:
        5 % of the largest set-point step or level jump of the scenario, or
        1 % of the largest set-point when it has neither.

    Returns
    -------
    dict of str to Metric
        Empty when nothing is tracked (no reference).
    """
    tracked = setup.tracked
    if not tracked or result.reference.shape[1] != len(tracked):
        return {}
    sc = setup.scenario
    units = [plant.states[i].unit for i in tracked]
    names = controlled_names(plant, tracked)
    M = result.runs
    out: dict[str, Metric] = {}
    values = ise(result, tracked)
    for j, nm in enumerate(names):
        out[f"ise_{nm}"] = Metric(f"ise_{nm}", values[:, j], f"{units[j]}^2 s",
                                  f"integral square error of {nm}")
    off = steady_offset(result, tracked)
    for j, nm in enumerate(names):
        out[f"offset_{nm}"] = Metric(f"offset_{nm}", off[:, j], units[j],
                                     f"steady offset of {nm} (mean y - r, last 10 % of samples)")
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
        out[kind] = Metric(kind, worst, "s", f"{what} time (band {tol:.3g} {units[0]})")
    return out


def estimation_metrics(result: SimulationResult, plant: Plant, warmup: int | None = None
                       ) -> dict[str, Metric]:
    """``rmse_<state>`` of the estimate after the warm-up.

    Parameters
    ----------
    result : SimulationResult
        A run with an estimator (``x_hat`` is its estimate).
    plant : Plant
    warmup : int, optional
        First sample that counts; default `warmup_samples` (10 % of the run).
    """
    start = warmup_samples(result.steps) if warmup is None else int(warmup)
    rmse = estimation_rmse(result, start)
    out = {}
    for i, s in enumerate(plant.states):
        out[f"rmse_{s.name}"] = Metric(
            f"rmse_{s.name}", rmse[:, i], s.unit,
            f"estimation RMSE of {s.name} over samples {start}..{result.steps} (warm-up: the first "
            f"{start} samples, {ESTIMATION_WARMUP:.0%} of the run, are not counted)")
    return out


def timing_metrics(result: SimulationResult, *, estimator: bool, controller: bool) -> dict[str, Metric]:
    """Wall-clock time per sample and run of the estimator and/or the control law that ran (s).

    Parameters
    ----------
    result : SimulationResult
        The simulated runs (with their timings).
    estimator, controller : bool
        Whether an estimator and a control law ran.
    """
    M = result.runs
    calls = max(int(result.timing.get("calls", 0)), 1)
    out = {}
    for key, ran in (("estimator", estimator), ("controller", controller)):
        if not ran:
            continue
        per = float(result.timing.get(key, 0.0)) / calls / max(M, 1)
        out[f"{key}_time"] = Metric(f"{key}_time", np.full(M, per), "s",
                                    f"{key} computation time per sample and run (batch time / M)")
    return out


def detection_metrics(t: np.ndarray, residual: np.ndarray, threshold: np.ndarray,
                      healthy_residual: np.ndarray, fault_sample: int | None) -> dict[str, Metric]:
    """Detection delay (faulty run) and false alarms (fault-free run) of a residual test.

    An alarm is raised at sample ``k`` when ``residual[:, k] > threshold[k]``.

    Parameters
    ----------
    t : ndarray, shape (N + 1,)
        Sample times (s).
    residual : ndarray, shape (M, N + 1)
        Residual of the run with the fault (output units).
    threshold : ndarray, shape (N + 1,)
        Threshold at each sample (output units).
    healthy_residual : ndarray, shape (M, N + 1)
        Residual of the same runs without the fault.
    fault_sample : int or None
        Onset of the fault; None: the scenario has no fault (no delay).
    """
    t = np.asarray(t, dtype=float)
    thr = np.asarray(threshold, dtype=float)[None, :]
    healthy = np.asarray(healthy_residual, dtype=float) > thr
    M = healthy.shape[0]
    first = np.array([t[int(np.argmax(row))] if row.any() else math.inf for row in healthy])
    out = {"false_alarm_rate": Metric("false_alarm_rate", healthy.mean(axis=1), "1",
                                      "fraction of the samples of the fault-free run above the "
                                      "threshold"),
           "first_false_alarm": Metric("first_false_alarm", first, "s",
                                       "time of the first alarm of the fault-free run (inf: none)")}
    if fault_sample is not None:
        alarm = np.asarray(residual, dtype=float) > thr
        delay = np.full(M, math.inf)
        for r in range(M):
            idx = np.flatnonzero(alarm[r, fault_sample:])
            if idx.size:
                delay[r] = t[fault_sample + int(idx[0])] - t[fault_sample]
        out["detection_delay"] = Metric("detection_delay", delay, "s",
                                        f"first alarm at or after the fault onset t = "
                                        f"{t[fault_sample]:g} s, minus the onset (inf: missed)")
    return out


def prediction_metrics(plant: Plant, x: np.ndarray, free_run: np.ndarray, one_step: np.ndarray
                       ) -> dict[str, Metric]:
    """RMS prediction errors of a model against the simulated states.

    Parameters
    ----------
    plant : Plant
    x : ndarray, shape (M, N + 1, n)
        Simulated (true) states.
    free_run : ndarray, shape (M, N + 1, n)
        The model's prediction from the initial state and the applied inputs.
    one_step : ndarray, shape (M, N, n)
        The model's prediction of ``x[:, k + 1]`` from ``x[:, k]`` and ``u_k``.
    """
    free = np.sqrt(np.mean((free_run - x) ** 2, axis=1))
    step = np.sqrt(np.mean((one_step - x[:, 1:]) ** 2, axis=1))
    out = {}
    for i, s in enumerate(plant.states):
        out[f"prediction_rmse_{s.name}"] = Metric(
            f"prediction_rmse_{s.name}", free[:, i], s.unit,
            f"RMS error of the model's free-run prediction of {s.name} (from the initial state "
            "and the applied inputs)")
        out[f"one_step_rmse_{s.name}"] = Metric(
            f"one_step_rmse_{s.name}", step[:, i], s.unit,
            f"RMS error of the model's one-step prediction of {s.name}")
    return out


def compute_metrics(result: SimulationResult, setup: ScenarioSetup, plant: Plant,
                    band: float | None = None, *, estimated: bool | None = None,
                    controlled: bool = True) -> dict[str, Metric]:
    """The metrics of a scenario run, by name: tracking, estimation, timing.

    Parameters
    ----------
    result : SimulationResult
    setup : ScenarioSetup
        The scenario it ran (tracked states, event samples).
    plant : Plant
        The simulated plant (names and units of the metrics).
    band : float, optional
        Band of the tracking/rejection times (see `tracking_metrics`).
    estimated : bool, optional
        Whether an estimator ran (its RMSE is reported). Default: whether
        the result records estimator time.
    controlled : bool
        Whether a control law ran (tracking metrics and its time).

    Returns
    -------
    dict of str to Metric
    """
    if estimated is None:
        estimated = float(result.timing.get("estimator", 0.0)) > 0.0
    out: dict[str, Metric] = {}
    if controlled:
        out.update(tracking_metrics(result, setup, plant, band))
    if estimated:
        out.update(estimation_metrics(result, plant))
    out.update(timing_metrics(result, estimator=bool(estimated), controller=controlled))
    return out


def metric_table(metrics: Mapping[str, Metric]) -> dict[str, float]:
    """Mean of each metric over the runs (for summaries).

    Parameters
    ----------
    metrics : mapping of str to Metric
        Metrics over the runs (their own units).
    """
    return {name: float(np.mean(m.values)) for name, m in metrics.items()}
