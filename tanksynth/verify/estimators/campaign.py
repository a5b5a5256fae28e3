"""Campaign runners of the estimators: each runs the estimator its artefact ships on the noisy
measurements (`tanksynth.verify.estimation.EstimatorRun`).

Runners (``runner(doc, spec) -> EstimatorRun``):

==========================  =================================================================
`kalman_run`, ...           kalman, ekf, ukf, luenberger, adaptive_kalman,
                            adaptive_scaling_kalman, consensus_filter (`estimator_run` with the
                            method's `tanksynth.verify.estimation.EstimatorRebuild`)
`narx_run`                  NARX network with the stored weights, own estimates fed back
==========================  =================================================================
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

from tanksynth.runtime.estimators.narx import NARXEstimator
from tanksynth.sim.simulate import EstimatorAdapter
from tanksynth.spec import Spec
from tanksynth.verify.common import operating_point, sampling_period
from tanksynth.verify.estimation import (EstimatorRebuild, EstimatorRun, estimation_context,
                                         estimator_run)
from tanksynth.verify.estimators import verdicts as est
from tanksynth.verify.estimators.narx import narx_tuning

__all__ = ["kalman_run", "ekf_run", "ukf_run", "adaptive_kalman_run", "adaptive_scaling_kalman_run",
           "consensus_filter_run", "luenberger_run", "narx_run"]


def _estimator_run_for(rebuild: EstimatorRebuild) -> Callable[[Mapping[str, Any], Spec], EstimatorRun]:
    """The campaign runner of one estimator method: `estimator_run` with its rebuild."""
    def runner(doc: Mapping[str, Any], spec: Spec) -> EstimatorRun:
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


def narx_run(doc: Mapping[str, Any], spec: Spec) -> EstimatorRun:
    """The NARX estimator of a ``narx`` artefact (stored weights, own estimates fed back).

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    tuning = narx_tuning(doc, spec, sampling_period(spec))
    estimator = EstimatorAdapter(NARXEstimator(spec.plant, tuning, backend="vm"))
    x_op, u_op = operating_point(spec)
    return EstimatorRun(estimator, x_op, u_op, tuning.x0,
                        f"NARX estimator ({tuning.W1.shape[0]} tanh neurons, {tuning.delays} output "
                        "delays, the artefact's weights; own estimates fed back), "
                        + estimation_context(spec, tuning.x0))
