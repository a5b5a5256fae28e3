"""Campaign runner of ``decentralized_kalman``: the decentralised filter with the stored window
gains on the noisy measurements (`tanksynth.verify.estimation.EstimatorRun`)."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, operating_point, sampling_period
from tanksynth.verify.decentralized.verdicts import DecentralizedFilter
from tanksynth.verify.estimation import EstimatorRun, estimation_context

__all__ = ["decentralized_kalman_run"]


def decentralized_kalman_run(doc: Mapping[str, Any], spec: Spec) -> EstimatorRun:
    """The decentralised filter of a ``decentralized_kalman`` artefact.

    `tanksynth.verify.decentralized.verdicts.DecentralizedFilter` with the stored
    gains ``K_0 .. K_{T-1}`` of the design window: after the window it
    predicts in open loop (the artefact ships no gain beyond it).

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    plant = spec.plant
    gains = doc["gains"]
    T = 0
    while f"K_{T}" in gains:
        T += 1
    if T == 0:
        raise ArtefactError(f"artefact '{doc['name']}' has no gain K_0")
    Ks = [np.atleast_2d(artefact_gain(doc, f"K_{j}")).reshape(plant.n, plant.q) for j in range(T)]
    x_op, u_op = operating_point(spec)
    return EstimatorRun(DecentralizedFilter(plant, Ks, sampling_period(spec)), x_op, u_op, None,
                        f"decentralised filter with the artefact's {T} window gains K_0..K_{T - 1} "
                        f"(open-loop prediction after sample {T}), " + estimation_context(spec, None))
