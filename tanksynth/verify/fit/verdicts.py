"""Verdicts of the ``fit`` family: ``fit``.

Scaffolded by scripts/add_method.py.
"""

from __future__ import annotations

from typing import Any, Mapping

from tanksynth.analysis.checks import Check

__all__ = ["fit_verdict"]


def fit_verdict(doc: Mapping[str, Any], spec: Any) -> list[Check]:
    """Verdict of ``fit``: not written yet, so it fails (a scaffolded method never passes
    verification silently).

    TODO(fit): re-derive what the design claims from the artefact (``doc["gains"]``,
    ``doc["diagnostics"]``) with this stage's own numerics and simulate it on the nonlinear
    plant; never import the design code.

    Parameters
    ----------
    doc : mapping
        The artefact (gains as arrays).
    spec : Spec
        The validated spec.

    Returns
    -------
    list of Check
        One failing check, ``verdict_not_written``.
    """
    return [Check("verdict_not_written", False,
                  f"verdict not written yet: the artefact '{doc['name']}' of method "
                  "'fit' is not verified: "
                  "write fit_verdict in tanksynth.verify.fit.verdicts")]
