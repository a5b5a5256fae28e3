"""Campaign runner of the H2 / H-infinity / multi-objective designs: their observer ``L`` on the
noisy measurements or their state feedback ``K`` in closed loop, run as the placement family
runs its artefacts (`tanksynth.verify.placement.campaign.placement_run`)."""

from __future__ import annotations

from typing import Any, Mapping

from tanksynth.spec import Spec
from tanksynth.verify.estimation import EstimatorRun
from tanksynth.verify.laws.campaign import ClosedLoop
from tanksynth.verify.placement.campaign import placement_run

__all__ = ["synthesis_run"]


def synthesis_run(doc: Mapping[str, Any], spec: Spec) -> EstimatorRun | ClosedLoop:
    """Campaign runner: the observer ``L`` on the noisy measurements, or ``K`` in closed loop.

    The same runs as ``lmi_placement`` artefacts
    (`tanksynth.verify.placement.campaign.placement_run`).

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
        The validated spec.
    """
    return placement_run(doc, spec)
