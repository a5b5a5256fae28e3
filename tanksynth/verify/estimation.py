"""Estimators and observers in Monte-Carlo campaigns: what every estimating family runs.

An estimator or observer artefact runs on the simulated noisy measurements:
the plant follows the scenario (its input schedule, or the operating input
held; its disturbances, mismatch, faults and noise) and the estimator,
rebuilt from the artefact, is fed ``(y_k, u_{k-1})`` at every sample. The
metrics are the RMSE of ITS estimate against the true state after the
warm-up (`tanksynth.sim.metrics.ESTIMATION_WARMUP`) and its computation time.
Set-point changes of a scenario act on nothing here (there is no loop to
follow them).

The estimate starts at the scenario's initial estimate when it prescribes
one (``mismatch``), else at the artefact's designed initial estimate (gain
``x_hat0``) when it ships one, else at the plant's initial state.

Shared by the families whose artefacts estimate (``estimators``,
``placement``, ``observer_lmi``, ``decentralized``, ``robust``,
``synthesis``): `EstimatorRun` (what runs), `EstimatorRebuild` (how an
estimator method's artefact is rebuilt, for its verdict and its run),
`estimator_run` (the run of such a method), `observer_gain` and
`estimation_context` (the description's common part). Each family's runners
are in its ``campaign`` module.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant
from tanksynth.sim.metrics import Metric, estimation_metrics, timing_metrics
from tanksynth.sim.scenarios import Scenario, ScenarioSetup, run_scenario
from tanksynth.sim.simulate import BatchEstimator
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, operating_point, sampling_period

__all__ = ["EstimatorRebuild", "EstimatorRun", "estimator_run", "estimation_context", "observer_gain"]


@dataclass(frozen=True)
class EstimatorRebuild:
    """How the verify stage rebuilds one estimator method's artefact, and the horizon of its run.

    Attributes
    ----------
    method : str
        The design method.
    build : callable
        ``build(doc, spec) -> (BatchEstimator, x0_hat, description)``: the estimator the
        artefact ships (through `tanksynth.runtime`, wrapped for the batch simulator), the
        initial estimate it ships (state units, shape (n,)) and a one-line description.
    error : callable
        ``error(doc, spec) -> (E, how)``: the discrete error matrix whose eigenvalues set the
        convergence horizon (steady-state gain at the operating point, or the observer's).
    covariance : bool
        The filter's covariance is checked symmetric positive definite after the run.
    """

    method: str
    build: Callable[[Mapping[str, Any], Spec], tuple[BatchEstimator, np.ndarray, str]]
    error: Callable[[Mapping[str, Any], Spec], tuple[np.ndarray, str]]
    covariance: bool = False


@dataclass(frozen=True)
class EstimatorRun:
    """An estimator or observer on the noisy measurements (a campaign run of kind ``"estimator"``).

    Attributes
    ----------
    estimator : BatchEstimator
        Rebuilt from the artefact; `reset` starts it afresh for each simulation.
    x_op, u_op : ndarray
        Operating point (initial plant state, held input), in state and input units.
    x_hat0 : ndarray or None
        The artefact's designed initial estimate (state units); None: the plant's
        initial state.
    description : str
    kind : str
        ``"estimator"``.
    """

    estimator: BatchEstimator
    x_op: np.ndarray
    u_op: np.ndarray
    x_hat0: np.ndarray | None
    description: str
    kind: str = field(default="estimator", init=False)

    def evaluate(self, sc: Scenario, plant: Plant, *, ts: float, seeds: Sequence[int],
                 substeps: int = 4) -> dict[str, Metric]:
        """Simulate the scenario with the estimator on the measurements.

        Parameters
        ----------
        sc : Scenario
        plant : Plant
        ts : float
            Sampling period (s).
        seeds : sequence of int
            One per run (process and measurement noise).
        substeps : int
            RK4 steps per period.

        Returns
        -------
        dict of str to Metric
            ``rmse_<state>`` (after the warm-up) and ``estimator_time``.
        """
        setup = sc.setup(plant, self.x_op, self.u_op, ts=ts)
        if sc.x_hat0 is None and self.x_hat0 is not None:
            setup = replace(setup, x_hat0=np.asarray(self.x_hat0, dtype=float).copy())
        if _nothing_to_estimate(sc, setup):
            return {"not_applicable": Metric(
                "not_applicable", np.ones(len(seeds)), "1",
                f"scenario {sc.name!r} has no noise, no disturbance, no model mismatch and the "
                "estimate starts at the true state: an estimator's error would be zero by "
                "construction, so no RMSE is reported")}
        result = run_scenario(setup, plant, ts=ts, seeds=list(seeds), estimator=self.estimator,
                              substeps=substeps)
        return {**estimation_metrics(result, plant),
                **timing_metrics(result, estimator=True, controller=False)}


def _nothing_to_estimate(sc: Scenario, setup: ScenarioSetup) -> bool:
    """A noise-free, undisturbed, exactly modelled scenario whose estimate starts at the true state."""
    exact_start = np.array_equal(np.asarray(setup.x0, dtype=float), np.asarray(setup.x_hat0, dtype=float))
    return (sc.process_std == 0 and sc.measurement_std == 0 and not sc.jumps and not sc.faults
            and sc.parameter_factor == 1.0 and sc.input_schedule is None and exact_start)


def estimation_context(spec: Spec, x_hat0: np.ndarray | None) -> str:
    """What every estimator run is fed and where its estimate starts, for its description.

    Parameters
    ----------
    spec : Spec
        The validated spec.
    x_hat0 : ndarray or None
        The artefact's initial estimate (state units); None: the plant's initial state.
    """
    start = ("the artefact's initial estimate x_hat0 = [" + ", ".join(f"{v:.4g}" for v in x_hat0) + "]"
             if x_hat0 is not None else "the plant's initial state")
    sampled = "" if spec.ts else (f" every {sampling_period(spec):g} s (the spec has no sampling "
                                  "period)")
    measured = ", ".join(o.name for o in spec.plant.outputs)
    return (f"fed the noisy measurements of {measured}{sampled}; estimate from {start} unless "
            "the scenario sets it; plant driven by the scenario's input schedule or the operating "
            "input held")


def _initial_estimate(doc: Mapping[str, Any], n: int) -> np.ndarray | None:
    x0 = doc["gains"].get("x_hat0")
    if x0 is None:
        return None
    x0 = np.asarray(x0, dtype=float).reshape(-1)
    return x0 if x0.size == n else None


def estimator_run(doc: Mapping[str, Any], spec: Spec, rebuild: EstimatorRebuild) -> EstimatorRun:
    """The estimator an artefact ships, rebuilt by its method's `EstimatorRebuild`.

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
        The validated spec.
    rebuild : EstimatorRebuild
        ``rebuild.build(doc, spec) -> (BatchEstimator, x0_hat, description)``.
    """
    est, _, what = rebuild.build(doc, spec)
    x_op, u_op = operating_point(spec)
    x_hat0 = _initial_estimate(doc, spec.plant.n)
    return EstimatorRun(est, x_op, u_op, x_hat0, f"{what} (the artefact's gains), "
                                                 + estimation_context(spec, x_hat0))


def observer_gain(doc: Mapping[str, Any], spec: Spec) -> np.ndarray:
    """The observer gain ``L`` of an artefact, shape (n, q) (state units per output unit).

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
        The validated spec.

    Raises
    ------
    ArtefactError
        ``L`` missing or of another size than n x q.
    """
    L = artefact_gain(doc, "L")
    n, q = spec.plant.n, spec.plant.q
    if L.size != n * q:
        raise ArtefactError(f"artefact '{doc['name']}': gain L has {L.size} entries, expected "
                            f"{n} x {q}")
    return L.reshape(n, q)
