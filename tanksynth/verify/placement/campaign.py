"""Campaign runners of the placement family (``pole_placement``, ``lmi_placement``,
``canonical_observer``): an observer gain ``L`` runs as a Luenberger observer on the noisy
measurements (`tanksynth.verify.estimation.EstimatorRun`), a state feedback in closed loop
(`tanksynth.verify.laws.campaign.state_feedback_loop`).
"""

from __future__ import annotations

from typing import Any, Mapping

from tanksynth.spec import Spec
from tanksynth.verify.common import design_options, operating_point, sampling_period
from tanksynth.verify.estimation import EstimatorRun, estimation_context, observer_gain
from tanksynth.verify.laws.campaign import ClosedLoop, state_feedback_loop
from tanksynth.verify.simulations import luenberger_estimator

__all__ = ["placement_run", "canonical_observer_run"]


def _time_domain(doc: Mapping[str, Any], spec: Spec) -> str:
    """The design's time domain: recorded in the diagnostics, else the spec's option, else
    discrete iff the spec has a sampling period."""
    diag = doc.get("diagnostics") or {}
    value = diag.get("time_domain") if isinstance(diag, Mapping) else None
    if value not in ("continuous", "discrete"):
        value = design_options(doc, spec).get("time_domain")
    if value in ("continuous", "discrete"):
        return str(value)
    return "discrete" if spec.ts is not None else "continuous"


def _luenberger_run(doc: Mapping[str, Any], spec: Spec, form: str, what: str) -> EstimatorRun:
    x_op, u_op = operating_point(spec)
    estimator = luenberger_estimator(spec.plant, observer_gain(doc, spec), x_op, u_op,
                                     sampling_period(spec), form)
    return EstimatorRun(estimator, x_op, u_op, None,
                        f"{what}: Luenberger observer, {form} form, with the artefact's L on the "
                        f"plant linearised at the operating point, " + estimation_context(spec, None))


def placement_run(doc: Mapping[str, Any], spec: Spec) -> EstimatorRun | ClosedLoop:
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


def canonical_observer_run(doc: Mapping[str, Any], spec: Spec) -> EstimatorRun:
    """The continuous Luenberger observer of a ``canonical_observer`` artefact.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    return _luenberger_run(doc, spec, "continuous", "canonical-form observer")
