"""Estimator and observer artefacts in Monte-Carlo campaigns.

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

Runners (``runner(doc, spec) -> EstimatorRun``):

==========================  =================================================================
`kalman_run`, ...           kalman, ekf, ukf, luenberger, adaptive_kalman,
                            adaptive_scaling_kalman, consensus_filter (`estimator_run` with the
                            method's `tanksynth.verify.estimators.verdicts.EstimatorRebuild`)
`placement_run`             pole_placement, lmi_placement: the observer gain ``L`` (predictor
                            form when designed in discrete time, continuous form otherwise), or
                            the state feedback in closed loop (`state_feedback_loop`)
`canonical_observer_run`    continuous Luenberger observer with the stored ``L``
`ts_observer_run`           Takagi-Sugeno multiple observer (seed 001 eq. 20) with the stored
                            ``L`` on the multiple model rebuilt from the recorded premises
`narx_run`                  NARX network with the stored weights, own estimates fed back
`decentralized_kalman_run`  decentralised filter with the stored window gains ``K_0..K_{T-1}``
                            (open-loop prediction after the window)
==========================  =================================================================
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant
from tanksynth.sim.metrics import Metric, estimation_metrics, timing_metrics
from tanksynth.sim.scenarios import Scenario, run_scenario
from tanksynth.sim.simulate import BatchEstimator, EstimatorAdapter
from tanksynth.verify.laws.campaign import (ClosedLoop, sampling_period, spec_operating_point,
                                           state_feedback_loop)
from tanksynth.verify.common import artefact_gain, design_options

from tanksynth.verify.estimators import verdicts as est

__all__ = ["EstimatorRun", "estimator_run", "kalman_run", "ekf_run", "ukf_run", "adaptive_kalman_run", "adaptive_scaling_kalman_run", "consensus_filter_run", "luenberger_run", "placement_run", "canonical_observer_run",
           "ts_observer_run", "narx_run", "decentralized_kalman_run"]


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


def _nothing_to_estimate(sc: Scenario, setup: Any) -> bool:
    """A noise-free, undisturbed, exactly modelled scenario whose estimate starts at the true state."""
    exact_start = np.array_equal(np.asarray(setup.x0, dtype=float), np.asarray(setup.x_hat0, dtype=float))
    return (sc.process_std == 0 and sc.measurement_std == 0 and not sc.jumps and not sc.faults
            and sc.parameter_factor == 1.0 and sc.input_schedule is None and exact_start)


def _measured(spec: Any) -> str:
    return ", ".join(o.name for o in spec.plant.outputs)


def _context(spec: Any, x_hat0: np.ndarray | None) -> str:
    start = ("the artefact's initial estimate x_hat0 = [" + ", ".join(f"{v:.4g}" for v in x_hat0) + "]"
             if x_hat0 is not None else "the plant's initial state")
    sampled = "" if spec.ts else (f" every {sampling_period(spec):g} s (the spec has no sampling "
                                  "period)")
    return (f"fed the noisy measurements of {_measured(spec)}{sampled}; estimate from {start} unless "
            "the scenario sets it; plant driven by the scenario's input schedule or the operating "
            "input held")


def _initial_estimate(doc: Mapping[str, Any], n: int) -> np.ndarray | None:
    x0 = doc["gains"].get("x_hat0")
    if x0 is None:
        return None
    x0 = np.asarray(x0, dtype=float).reshape(-1)
    return x0 if x0.size == n else None


def estimator_run(doc: Mapping[str, Any], spec: Any, rebuild: Any) -> EstimatorRun:
    """The estimator an artefact ships, rebuilt by its method's `EstimatorRebuild`.

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
    rebuild : tanksynth.verify.estimators.verdicts.EstimatorRebuild
        ``rebuild.build(doc, spec) -> (BatchEstimator, x0_hat, description)``.
    """
    est, _, what = rebuild.build(doc, spec)
    x_op, u_op = spec_operating_point(spec)
    x_hat0 = _initial_estimate(doc, spec.plant.n)
    return EstimatorRun(est, x_op, u_op, x_hat0, f"{what} (the artefact's gains), "
                                                 + _context(spec, x_hat0))


def _estimator_run_for(rebuild: Any) -> Callable[[Mapping[str, Any], Any], EstimatorRun]:
    """The campaign runner of one estimator method: `estimator_run` with its rebuild."""
    def runner(doc: Mapping[str, Any], spec: Any) -> EstimatorRun:
        return estimator_run(doc, spec, rebuild)

    runner.__name__ = runner.__qualname__ = f"{rebuild.method}_run"
    runner.__doc__ = (f"Campaign runner of ``{rebuild.method}`` artefacts (see `estimator_run`).\n\n"
                      "Parameters\n----------\ndoc, spec : mapping, Spec\n"
                      "    The artefact and the validated spec.\n")
    return runner


kalman_run = _estimator_run_for(est.KALMAN)
ekf_run = _estimator_run_for(est.EKF)
ukf_run = _estimator_run_for(est.UKF)
adaptive_kalman_run = _estimator_run_for(est.ADAPTIVE_KALMAN)
adaptive_scaling_kalman_run = _estimator_run_for(est.ADAPTIVE_SCALING_KALMAN)
consensus_filter_run = _estimator_run_for(est.CONSENSUS_FILTER)
luenberger_run = _estimator_run_for(est.LUENBERGER)


def _time_domain(doc: Mapping[str, Any], spec: Any) -> str:
    diag = doc.get("diagnostics") or {}
    value = diag.get("time_domain") if isinstance(diag, Mapping) else None
    if value not in ("continuous", "discrete"):
        value = design_options(doc, spec).get("time_domain")
    if value in ("continuous", "discrete"):
        return str(value)
    return "discrete" if spec.ts is not None else "continuous"


def _observer_gain(doc: Mapping[str, Any], spec: Any) -> np.ndarray:
    L = artefact_gain(doc, "L")
    n, q = spec.plant.n, spec.plant.q
    if L.size != n * q:
        raise ArtefactError(f"artefact '{doc['name']}': gain L has {L.size} entries, expected "
                            f"{n} x {q}")
    return L.reshape(n, q)


def _luenberger_run(doc: Mapping[str, Any], spec: Any, form: str, what: str) -> EstimatorRun:
    from tanksynth.verify.simulations import luenberger_estimator

    x_op, u_op = spec_operating_point(spec)
    est = luenberger_estimator(spec.plant, _observer_gain(doc, spec), x_op, u_op, sampling_period(spec),
                               form)
    return EstimatorRun(est, x_op, u_op, None,
                        f"{what}: Luenberger observer, {form} form, with the artefact's L on the "
                        f"plant linearised at the operating point, " + _context(spec, None))


def placement_run(doc: Mapping[str, Any], spec: Any) -> EstimatorRun | ClosedLoop:
    """A ``pole_placement``/``lmi_placement`` artefact: its observer, or its state feedback.

    An observer gain ``L`` runs as a Luenberger observer on the noisy
    measurements (predictor form ``x+ = Ad x + Bd u + L (y - C x)`` for a
    discrete design, the continuous form integrated exactly over each
    period otherwise); ``K1``/``K2`` or ``K`` run in closed loop
    (`tanksynth.verify.laws.campaign.state_feedback_loop`).

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    if "L" in doc["gains"]:
        domain = _time_domain(doc, spec)
        form = "predictor" if domain == "discrete" else "continuous"
        return _luenberger_run(doc, spec, form, f"{doc['method']} observer ({domain} design)")
    return state_feedback_loop(doc, spec)


def canonical_observer_run(doc: Mapping[str, Any], spec: Any) -> EstimatorRun:
    """The continuous Luenberger observer of a ``canonical_observer`` artefact.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    return _luenberger_run(doc, spec, "continuous", "canonical-form observer")


def _ts_model(doc: Mapping[str, Any], spec: Any) -> Any:
    """The TS multiple model rebuilt from the plant and the recorded premises, bounds and domain."""
    from tanksynth.analysis.takagi_sugeno import Domain, PremiseBounds, quasi_lpv, ts_model

    plant = spec.plant
    diag = doc.get("diagnostics") or {}
    rec = diag.get("ts_model") if isinstance(diag, Mapping) else None
    try:
        W = np.array([p["weights"] for p in rec["premises"]], dtype=float)
        dom, bounds = rec["domain"], rec["bounds"]
        ineq = dom.get("inequalities") or []
        G = np.array([r["G"] for r in ineq], dtype=float).reshape(len(ineq), plant.n)
        g = np.array([r["g"] for r in ineq], dtype=float)
        domain = Domain(np.array(dom["lower"], float), np.array(dom["upper"], float), G, g,
                        tuple(s.name for s in plant.states), str(dom.get("description", "")))
        lower, upper = np.array(bounds["lower"], float), np.array(bounds["upper"], float)
    except (TypeError, KeyError, ValueError) as exc:
        raise ArtefactError(f"artefact '{doc['name']}': diagnostics.ts_model does not record the "
                            f"premises, bounds and domain of the TS model ({exc})") from None
    pb = PremiseBounds(lower, upper, str(bounds.get("method", "recorded")),
                       float(bounds.get("margin", 0.0)), lower, upper, {})
    return ts_model(quasi_lpv(plant, W), domain, bounds=pb)


def ts_observer_run(doc: Mapping[str, Any], spec: Any) -> EstimatorRun:
    """The Takagi-Sugeno multiple observer (seed 001 eq. 20) of a ``ts_observer`` artefact.

    `tanksynth.verify.common.TSObserver` (exponential rule, exact on the
    stiff linear part) with the stored ``L`` on the TS model rebuilt from
    the plant and the recorded premises, premise bounds and domain.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    from tanksynth.verify.observer_lmi.verdicts import TSObserver

    model = _ts_model(doc, spec)
    x_op, u_op = spec_operating_point(spec)
    est = TSObserver(model, _observer_gain(doc, spec), sampling_period(spec))
    return EstimatorRun(est, x_op, u_op, None,
                        f"Takagi-Sugeno multiple observer (eq. 20) with the artefact's L on the "
                        f"{model.r}-vertex model rebuilt from the recorded premises, "
                        + _context(spec, None))


def narx_run(doc: Mapping[str, Any], spec: Any) -> EstimatorRun:
    """The NARX estimator of a ``narx`` artefact (stored weights, own estimates fed back).

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    from tanksynth.runtime.estimators.narx import NARXEstimator, NARXTuning

    plant = spec.plant
    n = plant.n
    g = lambda k: np.asarray(artefact_gain(doc, k), dtype=float)  # noqa: E731
    W1 = np.atleast_2d(g("W1"))
    H = W1.shape[0]
    opts = design_options(doc, spec)
    tuning = NARXTuning(W1, g("b1").reshape(H), np.atleast_2d(g("W2")).reshape(n, H),
                        g("b2").reshape(n), g("in_mean").reshape(-1), g("in_scale").reshape(-1),
                        g("out_mean").reshape(n), g("out_scale").reshape(n), x0=g("x_hat0").reshape(n),
                        ts=sampling_period(spec), delays=int(round(float(np.ravel(g("delays"))[0]))),
                        substeps=int(opts.get("substeps", 1)), clip=bool(opts.get("clip", False)))
    est = EstimatorAdapter(NARXEstimator(plant, tuning, backend="vm"))
    x_op, u_op = spec_operating_point(spec)
    return EstimatorRun(est, x_op, u_op, tuning.x0,
                        f"NARX estimator ({H} tanh neurons, {tuning.delays} output delays, the "
                        "artefact's weights; own estimates fed back), " + _context(spec, tuning.x0))


def decentralized_kalman_run(doc: Mapping[str, Any], spec: Any) -> EstimatorRun:
    """The decentralised filter of a ``decentralized_kalman`` artefact.

    `tanksynth.verify.decentralized.verdicts.DecentralizedFilter` with the stored
    gains ``K_0 .. K_{T-1}`` of the design window: after the window it
    predicts in open loop (the artefact ships no gain beyond it).

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    from tanksynth.verify.decentralized.verdicts import DecentralizedFilter

    plant = spec.plant
    gains = doc["gains"]
    T = 0
    while f"K_{T}" in gains:
        T += 1
    if T == 0:
        raise ArtefactError(f"artefact '{doc['name']}' has no gain K_0")
    Ks = [np.atleast_2d(artefact_gain(doc, f"K_{j}")).reshape(plant.n, plant.q) for j in range(T)]
    x_op, u_op = spec_operating_point(spec)
    return EstimatorRun(DecentralizedFilter(plant, Ks, sampling_period(spec)), x_op, u_op, None,
                        f"decentralised filter with the artefact's {T} window gains K_0..K_{T - 1} "
                        f"(open-loop prediction after sample {T}), " + _context(spec, None))
