"""What Monte-Carlo campaigns run for the ``fit`` family: ``fit``.

Scaffolded by scripts/add_method.py.
"""

from __future__ import annotations

from typing import Any, Mapping

from tanksynth.errors import ArtefactError
from tanksynth.verify.model.campaign import ModelRun

__all__ = ["fit_run"]


def fit_run(doc: Mapping[str, Any], spec: Any) -> ModelRun:
    """What a Monte-Carlo campaign runs for a ``fit`` artefact: not written yet, refused.

    TODO(fit): build from the artefact what it ships and the campaign runs on each
    scenario (the kinds of run are listed in `tanksynth.verify.campaign`).

    Parameters
    ----------
    doc : mapping
        The artefact (gains as arrays).
    spec : Spec
        The validated spec.

    Returns
    -------
    ModelRun
        Once written, what the campaign runs.

    Raises
    ------
    ArtefactError
        Always, until the runner is written: nothing runs in its place.
    """
    raise ArtefactError(f"artefact '{doc['name']}': the campaign runner of method "
                        "'fit' is not written yet: "
                        "fit_run in tanksynth.verify.fit.campaign")
