"""Campaign runners of ``robust_state_feedback`` and ``robust_observer``: each Monte-Carlo run
draws its own parameter values from the uncertain box (from its seed) and runs the nonlinear
plant with them (`tanksynth.verify.campaign`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.plants.base import Plant
from tanksynth.sim.metrics import Metric, compute_metrics, estimation_metrics, timing_metrics
from tanksynth.sim.scenarios import Scenario, ScenarioSetup, run_scenario
from tanksynth.spec import Spec
from tanksynth.verify.common import (artefact_matrix, operating_point, option, output_at, sampling_period,
                                     time_domain)
from tanksynth.verify.estimation import EstimatorRun
from tanksynth.verify.laws.campaign import ClosedLoop, output_setpoint_law
from tanksynth.verify.robust.models import uncertain_box
from tanksynth.verify.robust.verdicts import robust_feedback_law
from tanksynth.verify.simulations import luenberger_estimator

__all__ = ["RobustClosedLoop", "RobustObserverRun", "robust_state_feedback_run", "robust_observer_run"]


def _draws(box: Sequence[tuple[str, float, float]], seeds: Sequence[int]) -> np.ndarray:
    """Run ``r``'s parameters: uniform in the box from ``default_rng([seed_r, 1])`` (shape (M, k))."""
    out = np.zeros((len(seeds), len(box)))
    for r, s in enumerate(seeds):
        u = np.random.default_rng([int(s), 1]).random(len(box))
        out[r] = [lo + u[j] * (hi - lo) for j, (_, lo, hi) in enumerate(box)]
    return out



def _sampled_setup(sc: Scenario, setup: ScenarioSetup, box: Sequence[tuple[str, float, float]],
                   seeds: Sequence[int]) -> tuple[Any, np.ndarray]:
    draws = _draws(box, seeds)
    params: dict[str, Any] = {**dict(setup.parameters), **{b[0]: draws[:, j] for j, b in enumerate(box)}}
    return replace(setup, parameters=params), draws



def _param_metrics(plant: Plant, box: Sequence[tuple[str, float, float]], draws: np.ndarray
                   ) -> dict[str, Metric]:
    units = {p.name: p.unit for p in plant.parameters}
    return {f"param_{name}": Metric(f"param_{name}", draws[:, j], units[name],
                                    f"sampled value of {name} in this run")
            for j, (name, _, _) in enumerate(box)}



@dataclass(frozen=True)
class RobustClosedLoop(ClosedLoop):
    """A robust state feedback in closed loop, each run on a plant with sampled parameters.

    The parameters of run ``r`` are drawn uniformly in the design's box from
    ``default_rng([seed_r, 1])`` (reproducible from the row's seed) and
    override the scenario's values of the same names; the law applies the
    nominal ``u0`` (the parameters are unknown to it).

    Attributes
    ----------
    box : tuple of (str, float, float)
        Uncertain parameters and their intervals (parameter units).
    controller : callable
        The control law (input units, m^3/s).
    estimator_factory : callable or None
        Builds the estimator fed back; None: the true state.
    x_op, u_op : ndarray
        Operating point (state units) and nominal input (input units).
    tracked : tuple of int
        Rows of the tracked outputs.
    description : str
        One line for the report.
    """

    box: tuple[tuple[str, float, float], ...] = ()

    def evaluate(self, sc: Scenario, plant: Plant, *, ts: float, seeds: Sequence[int],
                 substeps: int = 4) -> dict[str, Metric]:
        """The closed-loop metrics of `ClosedLoop.evaluate` and ``param_<name>`` per run.

        Parameters
        ----------
        sc : Scenario
            The scenario.
        plant : Plant
            The plant model.
        ts : float
            Sampling period [s].
        seeds : sequence of int
            One seed per run.
        substeps : int, optional
            RK4 steps per period.
        """
        setup, draws = _sampled_setup(sc, sc.setup(plant, self.x_op, self.u_op, self.tracked, ts=ts),
                                      self.box, seeds)
        result = run_scenario(setup, plant, ts=ts, seeds=list(seeds), controller=self.controller,
                              substeps=substeps)
        return {**compute_metrics(result, setup, plant, estimated=False, controlled=True),
                **_param_metrics(plant, self.box, draws)}



@dataclass(frozen=True)
class RobustObserverRun(EstimatorRun):
    """A robust observer on the NOMINAL model (as deployed), plants with sampled parameters.

    Its RMSE includes the bias the parameter mismatch causes (the
    certificate is about the error dynamics ``A(p) - L C``).

    Attributes
    ----------
    box : tuple of (str, float, float)
    estimator : BatchEstimator
        The observer (nominal model).
    x_op, u_op : ndarray
        Operating point (state units) and nominal input (input units).
    x_hat0 : ndarray or None
        Initial estimate (state units); None: the operating point.
    description : str
        One line for the report.
    """

    box: tuple[tuple[str, float, float], ...] = ()

    def evaluate(self, sc: Scenario, plant: Plant, *, ts: float, seeds: Sequence[int],
                 substeps: int = 4) -> dict[str, Metric]:
        """The estimation metrics and ``param_<name>`` per run.

        Parameters
        ----------
        sc : Scenario
            The scenario.
        plant : Plant
            The plant model.
        ts : float
            Sampling period [s].
        seeds : sequence of int
            One seed per run.
        substeps : int, optional
            RK4 steps per period.
        """
        setup, draws = _sampled_setup(sc, sc.setup(plant, self.x_op, self.u_op, ts=ts), self.box, seeds)
        result = run_scenario(setup, plant, ts=ts, seeds=list(seeds), estimator=self.estimator,
                              substeps=substeps)
        return {**estimation_metrics(result, plant),
                **timing_metrics(result, estimator=True, controller=False),
                **_param_metrics(plant, self.box, draws)}



def robust_state_feedback_run(doc: Mapping[str, Any], spec: Spec) -> ClosedLoop:
    """Campaign runner of ``robust_state_feedback``: a `RobustClosedLoop` (true state fed back).

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
        The validated spec.
    """
    plant = spec.plant
    gains = doc["gains"]
    x0, u0 = operating_point(spec)
    C = np.asarray(gains["C"], dtype=float).reshape(plant.q, plant.n)
    rows = None
    y0 = None
    if "K1" in gains and "K2" in gains:
        outputs = [s.name for s in plant.outputs]
        integ = (doc.get("diagnostics") or {}).get("integral") or {}
        tracked = list(option(doc, spec, "tracked") or integ.get("tracked") or outputs[:plant.m])
        rows = [outputs.index(t) for t in tracked]
        y0 = output_at(plant, x0)[rows]   # the integrators integrate y_r - h(x0) - C1 (x - x0)
    K = np.asarray(gains["K"], dtype=float).reshape(plant.m, plant.n + (len(rows) if rows else 0))
    states = tuple(int(np.argmax(np.abs(C[r]))) for r in rows) if rows is not None \
        else tuple(range(min(plant.m, plant.n)))
    law: Callable = robust_feedback_law(K, C, rows, x0, u0, sampling_period(spec), y0)
    if rows is not None and y0 is not None:   # the scenario moves state set-points: as outputs
        law = output_setpoint_law(law, C[rows], y0, x0, states)
    return RobustClosedLoop(law, None,
                            x0, u0, states,
                            "robust state feedback u = u0 - K (x - x0)"
                            + (" - K2 z" if rows is not None else "")
                            + ", true state fed back, plants with parameters sampled in the box",
                            box=tuple(uncertain_box(doc, spec)))



def robust_observer_run(doc: Mapping[str, Any], spec: Spec) -> EstimatorRun:
    """Campaign runner of ``robust_observer``: a `RobustObserverRun` on the nominal model.

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
        The validated spec.
    """
    plant = spec.plant
    x0, u0 = operating_point(spec)
    form = "predictor" if time_domain(doc, spec) == "discrete" else "continuous"
    L = artefact_matrix(doc, "L", (plant.n, plant.q))
    est = luenberger_estimator(plant, L, x0, u0, sampling_period(spec), form)
    return RobustObserverRun(est, x0, u0, None,
                             f"robust observer L ({form} form) on the nominal model, plants with "
                             "parameters sampled in the box", box=tuple(uncertain_box(doc, spec)))
