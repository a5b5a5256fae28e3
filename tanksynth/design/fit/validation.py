"""Fitted models against data: predicted outputs with `tanksynth.sim`, validation runs.

`simulate_outputs` simulates an experiment's inputs with the toolbox's simulator (the same
RK4, clipping and saturation as the fit's model; uniform sampling through
`tanksynth.sim.simulate_inputs`, non-uniform sampling one interval at a time with the
simulator's `Integrator`). `validate_experiment` estimates the initial state of a
validation run from its first samples only, then simulates the rest, as the identification
benchmarks do, and scores every output by RMSE and NRMSE fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import casadi as ca
import numpy as np

from tanksynth.design.fit.estimation import SUBSTEPS
from tanksynth.design.fit.model import direct_states, fit_model, quiet_solve
from tanksynth.design.fit.problem import Intervals, fit_data, noise_guess
from tanksynth.measurements.scores import fit_percent, rmse
from tanksynth.errors import SpecError
from tanksynth.measurements.experiment import Experiment
from tanksynth.plants.base import Plant
from tanksynth.sim.integrate import Integrator, input_limits, param_arrays
from tanksynth.sim.simulate import simulate_inputs

__all__ = ["ValidationResult", "simulate_outputs", "estimate_initial_state", "validate_experiment"]


@dataclass(frozen=True)
class ValidationResult:
    """A fitted model simulated on one validation experiment.

    Attributes
    ----------
    name : str
        The experiment's name.
    x0 : ndarray, shape (n,)
        Initial state estimated on the first ``init_samples`` samples (state units).
    init_samples : int
        Samples used for ``x0`` (left out of the scores).
    rmse : dict of str to float
        RMSE per output over the exact samples after the first ``init_samples`` (output units).
    fit_percent : dict of str to float
        NRMSE fit ``100 (1 - ||y - yhat|| / ||y - mean y||)`` per output, same samples (%).
    predicted : ndarray, shape (N, p)
        Simulated outputs of the experiment's output columns (output units).
    """

    name: str
    x0: np.ndarray
    init_samples: int
    rmse: dict[str, float]
    fit_percent: dict[str, float]
    predicted: np.ndarray = field(repr=False)


def simulate_outputs(plant: Plant, values: Mapping[str, float], experiment: Experiment,
                     x0: Any, *, substeps: int = SUBSTEPS) -> np.ndarray:
    """The plant's outputs under an experiment's inputs, simulated with `tanksynth.sim`.

    Parameters
    ----------
    plant : Plant
        The plant.
    values : mapping of str to float
        Parameter values to use (e.g. `FitResult.parameters`; parameter units).
    experiment : Experiment
        The experiment (its inputs held between samples, its sample times).
    x0 : array_like, shape (n,)
        State at the first sample (state units).
    substeps : int
        RK4 steps per sampling interval (`FitResult.substeps`).

    Returns
    -------
    ndarray, shape (N, p)
        Outputs at the sample times, the experiment's output columns (output units).

    Raises
    ------
    SpecError
        The experiment does not match the plant.
    """
    d = fit_data(plant, experiment)
    x0 = np.asarray(x0, dtype=float).reshape(plant.n)
    period = experiment.uniform_period
    if period is not None:
        run = simulate_inputs(plant, x0, d.u[:-1], period, substeps=int(substeps),
                              parameters=dict(values))
        return np.array(run.y[0][:, list(d.columns)])
    params = param_arrays(plant, dict(values), 1)
    integ = Integrator.for_plant(plant, params)
    lo, hi = input_limits(plant, params, 1)
    X = np.empty((d.samples, plant.n))
    x = integ.clip(x0[None, :])
    X[0] = x[0]
    for i, dt in enumerate(d.dt):
        u = np.minimum(np.maximum(d.u[i][None, :], lo), hi)
        x = integ.advance(x, u, params, float(dt), int(substeps))
        X[i + 1] = x[0]
    return np.asarray(integ.output(X, params))[:, list(d.columns)]


def estimate_initial_state(plant: Plant, values: Mapping[str, float], experiment: Experiment,
                           *, init_samples: int = 10, substeps: int = SUBSTEPS) -> np.ndarray:
    """Least-squares initial state on the first ``init_samples`` samples (parameters fixed).

    Parameters
    ----------
    plant : Plant
        The plant.
    values : mapping of str to float
        Parameter values (parameter units).
    experiment : Experiment
        The experiment.
    init_samples : int
        Samples used (>= 1; all of them when the experiment is shorter).
    substeps : int
        RK4 steps per sampling interval.

    Returns
    -------
    ndarray, shape (n,)
        The initial state (state units), inside the plant's state bounds.
    """
    if isinstance(init_samples, bool) or int(init_samples) < 1:
        raise SpecError(f"init_samples must be an integer >= 1, got {init_samples!r}",
                        key="design.init_samples")
    fixed = plant.with_parameters(dict(values))
    model = fit_model(fixed, (), substeps, allow_empty=True)
    full = fit_data(fixed, experiment)
    count = max(2, min(int(init_samples), full.samples))
    head = Experiment(experiment.name, experiment.source, experiment.t[:count],
                      np.asarray(experiment.u)[:count], np.asarray(experiment.y)[:count],
                      experiment.input_names, experiment.output_names,
                      np.asarray(experiment.censored_low)[:count],
                      np.asarray(experiment.censored_high)[:count], experiment.limits)
    d = fit_data(fixed, head)
    res = Intervals(model, [d], count)
    x0 = ca.MX.sym("x0", plant.n)
    w = np.ones(model.q)
    w[list(d.columns)] = 1.0 / noise_guess([d], d.output_names)
    r, _ = res.single(0, x0, ca.MX(0, 1), ca.DM(w))
    problem: dict[str, Any] = {"x": x0, "f": 0.5 * ca.sumsqr(r)}
    opts: dict[str, Any] = {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
                            "ipopt.tol": 1e-12, "show_eval_warnings": False}
    solver = ca.nlpsol("x0fit", "ipopt", problem, opts)
    lo = np.where(np.isfinite(model.state_lower), model.state_lower, -np.inf)
    hi = np.where(np.isfinite(model.state_upper), model.state_upper, np.inf)
    start = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), np.where(np.isfinite(lo), lo, 0.0))
    direct = direct_states(model, np.zeros(0))
    for j, col in enumerate(d.columns):       # a measured state starts at its first sample
        ok = np.flatnonzero(d.exact[:, j])
        if ok.size and col in direct:
            i, a, b = direct[col]
            start[i] = (d.y[ok[0], j] - b) / a
    sol = quiet_solve(solver, x0=np.clip(start, lo, hi), lbx=lo, ubx=hi)
    return np.clip(np.asarray(sol["x"]).ravel(), lo, hi)


def validate_experiment(plant: Plant, values: Mapping[str, float], experiment: Experiment, *,
                        init_samples: int = 10, substeps: int = SUBSTEPS) -> ValidationResult:
    """Score fitted parameter values on a validation experiment (pure simulation).

    The initial state is estimated on the first ``init_samples`` samples only
    (`estimate_initial_state`), then the whole experiment is simulated with `tanksynth.sim`
    (`simulate_outputs`); RMSE and fit % per output count the exact samples from
    ``init_samples`` on.

    Parameters
    ----------
    plant : Plant
        The plant.
    values : mapping of str to float
        Parameter values (e.g. `FitResult.parameters`; parameter units).
    experiment : Experiment
        The validation experiment.
    init_samples : int
        Samples for the initial state (>= 1).
    substeps : int
        RK4 steps per sampling interval (`FitResult.substeps`).

    Returns
    -------
    ValidationResult
    """
    x0 = estimate_initial_state(plant, values, experiment, init_samples=init_samples,
                                substeps=substeps)
    Yh = simulate_outputs(plant, values, experiment, x0, substeps=substeps)
    d = fit_data(plant, experiment)
    skip = min(int(init_samples), d.samples - 1)
    r = rmse(d.y[skip:], Yh[skip:], d.exact[skip:])   # the scores the verdict recomputes
    f = fit_percent(d.y[skip:], Yh[skip:], d.exact[skip:])
    rm = {nm: float(r[j]) for j, nm in enumerate(d.output_names)}
    fp = {nm: float(f[j]) for j, nm in enumerate(d.output_names)}
    return ValidationResult(experiment.name, x0, skip, rm, fp, Yh)
