"""The ``laws`` family's diagnostics: the outputs a decoupling law controls."""

from __future__ import annotations

from tanksynth.reports.diagnostics.common import Diagnostics

__all__ = ["controlled_outputs_of"]


def controlled_outputs_of(diag: Diagnostics) -> tuple[str, ...] | None:
    """The outputs ``feedback_linearization`` decouples (``diagnostics["outputs"]``), None when it
    does not say (an entry that is no list reads as no output).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    outputs = diag.get("outputs")
    if outputs is None:
        return None
    return tuple(str(o) for o in outputs) if isinstance(outputs, list) else ()
