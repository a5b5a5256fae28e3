"""The ``observer_lmi`` family's problem statement (``ts_observer``: the LMI (28) of seed 001)."""

from __future__ import annotations

from tanksynth.reports.diagnostics.common import Diagnostics
from tanksynth.reports.diagnostics.observer_lmi import ts_observer_of
from tanksynth.reports.latex import format_number
from tanksynth.reports.prose import prose_latex
from tanksynth.reports.statements.common import problem_statement

__all__ = ["ts_observer_statement"]


def _ts_observer(diag: Diagnostics) -> str:
    observer = ts_observer_of(diag)
    text = (r"Observer $\dot{\hat x} = A_0\hat x + \Delta(\hat x, u) + L(y - C\hat x)$ for the "
            r"Takagi--Sugeno model of the plant; the error obeys $\dot e = (A_0 - LC)e + \Delta$ "
            r"with $\|\Delta\| \le \psi\|e\|$. Find $P \succ 0$, $Q \succ 0$, $K$ with "
            r"\[\begin{bmatrix} A_0^\top P + P A_0 - C^\top K^\top - K C + \psi^2 Q & P \\ "
            r"P & -Q \end{bmatrix} \prec 0, \qquad L = P^{-1}K\]"
            r"(the Lipschitz observer LMI of seed 001).")
    if observer.psi is not None:
        text += rf" Here $\psi = {format_number(observer.psi)}$"
        if observer.psi_source:
            text += " (" + prose_latex(observer.psi_source) + ")"
        text += "."
    if observer.q_form:
        text += " " + prose_latex(observer.q_form) + "."
    model = observer.ts_model
    if model.vertices is not None:
        text += f" The TS model has {model.vertices} vertices"
        if model.domain.description:
            text += " on the domain " + prose_latex(model.domain.description)
        text += "."
    return text


ts_observer_statement = problem_statement("ts_observer", __name__, _ts_observer)
