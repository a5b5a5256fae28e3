"""Campaign runner of ``ts_observer``: the Takagi-Sugeno multiple observer (seed 001 eq. 20)
with the stored ``L`` on the noisy measurements (`tanksynth.verify.estimation.EstimatorRun`)."""

from __future__ import annotations

from typing import Any, Mapping

from tanksynth.analysis.takagi_sugeno import TSModel, quasi_lpv, ts_model
from tanksynth.errors import ArtefactError
from tanksynth.spec import Spec
from tanksynth.verify.common import operating_point, sampling_period
from tanksynth.verify.estimation import EstimatorRun, estimation_context, observer_gain
from tanksynth.verify.observer_lmi.verdicts import TSObserver, recorded_ts_parts

__all__ = ["ts_observer_run"]


def _ts_model(doc: Mapping[str, Any], spec: Spec) -> TSModel:
    """The TS multiple model rebuilt from the plant and the recorded premises, bounds and domain."""
    plant = spec.plant
    diag = doc.get("diagnostics") or {}
    record = diag.get("ts_model") if isinstance(diag, Mapping) else None
    try:
        W, domain, bounds = recorded_ts_parts(plant, record if isinstance(record, Mapping) else {})
    except (TypeError, KeyError, ValueError) as exc:
        raise ArtefactError(f"artefact '{doc['name']}': diagnostics.ts_model does not record the "
                            f"premises, bounds and domain of the TS model ({exc})") from None
    return ts_model(quasi_lpv(plant, W), domain, bounds=bounds)


def ts_observer_run(doc: Mapping[str, Any], spec: Spec) -> EstimatorRun:
    """The Takagi-Sugeno multiple observer (seed 001 eq. 20) of a ``ts_observer`` artefact.

    `tanksynth.verify.observer_lmi.verdicts.TSObserver` (exponential rule, exact on the
    stiff linear part) with the stored ``L`` on the TS model rebuilt from
    the plant and the recorded premises, premise bounds and domain.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    model = _ts_model(doc, spec)
    x_op, u_op = operating_point(spec)
    estimator = TSObserver(model, observer_gain(doc, spec), sampling_period(spec))
    return EstimatorRun(estimator, x_op, u_op, None,
                        f"Takagi-Sugeno multiple observer (eq. 20) with the artefact's L on the "
                        f"{model.r}-vertex model rebuilt from the recorded premises, "
                        + estimation_context(spec, None))
