"""The ``fault`` family's problem statement (``fault_detection``)."""

from __future__ import annotations

from tanksynth.reports.statements.common import problem_statement

__all__ = ["fault_detection_statement"]

fault_detection_statement = problem_statement(
    "fault_detection", __name__,
    r"Observer-based fault detection: the residual $r(t) = y(t) - C\hat x(t)$ of a Luenberger "
    r"observer with poles placed by the canonical form is compared with a threshold "
    r"$J_{th}(t)$ derived from the bounds of the healthy error dynamics; a fault is declared "
    r"when $|r(t)| > J_{th}(t)$.")
