"""Report statements of the ``fit`` family: ``fit``.

Scaffolded by scripts/add_method.py.
"""

from __future__ import annotations

from typing import Any, Mapping

from tanksynth.reports.latex import Tex

__all__ = ["fit_statement"]


def fit_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``fit`` solves, in mathematics, from the artefact's diagnostics.

    TODO(fit): state the problem solved from ``diag`` (tolerate missing or edited entries).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Problem statement of \texttt{fit} not written yet.")
