"""The ``placement`` family's problem statements: exact pole placement, pole placement in an LMI
region, and the observer by the observable canonical form.
"""

from __future__ import annotations

from tanksynth.reports.diagnostics.common import Diagnostics, integral_of, time_domain_of
from tanksynth.reports.diagnostics.placement import exact_placement_of, region_placement_of
from tanksynth.reports.latex import escape_latex, format_eigenvalues, format_number
from tanksynth.reports.prose import prose_latex
from tanksynth.reports.statements.common import domain_phrase, problem_statement, region_lmi_problem

__all__ = ["pole_placement_statement", "lmi_placement_statement", "canonical_observer_statement"]


def _exact(diag: Diagnostics) -> str:
    placement = exact_placement_of(diag)
    if placement.observer:
        what = r"the eigenvalues of the error dynamics $A - LC$"
    else:
        what = r"the closed-loop eigenvalues of $A - BK$ (control law $u = -Kx$)"
    text = rf"Place {what} exactly"
    if placement.requested is not None:
        text += r" at $" + format_eigenvalues([list(p) for p in placement.requested], 4) + "$"
    if placement.method:
        text += r" with \texttt{" + escape_latex(placement.method) + "}"
    text += "."
    integral = integral_of(diag)
    if integral is not None:
        text += (r" Integral action: the model is augmented with $z(k+1) = z(k) + t_s(y_r - y_0 - "
                 r"C_1 (x - x_0))$ (the measured outputs' error, $y_0 = h(x_0)$) for the tracked outputs " + prose_latex(", ".join(integral.tracked))
                 + r", and $K = [K_1\;K_2]$ acts on $(x, z)$.")
    return text


def _region(diag: Diagnostics) -> str:
    placement = region_placement_of(diag)
    if placement.observer:
        text = region_lmi_problem(r"A^\top X - C^\top Y", r"L = (Y X^{-1})^\top", "A - LC", dual=" (dual pair)")
    else:
        text = region_lmi_problem("AX - BY", r"K = Y X^{-1}", "A - BK",
                                  region=r"D = \{z : L_D + M_D z + M_D^\top \bar z \prec 0\}")
    text += r" (Chilali--Gahinet)"
    if placement.region:
        text += r"; here $D$: " + prose_latex(placement.region)
    text += domain_phrase(placement.domain or time_domain_of(diag))
    if placement.margin is not None:
        text += rf". The strict inequality is imposed with margin ${format_number(placement.margin)}$ after scaling"
    text += "."
    if integral_of(diag) is not None:
        text += r" The plant is augmented with integral action, $K = [K_1\;K_2]$."
    return text


pole_placement_statement = problem_statement("pole_placement", __name__, _exact)
lmi_placement_statement = problem_statement("lmi_placement", __name__, _region)
canonical_observer_statement = problem_statement(
    "canonical_observer", __name__,
    r"Observer through the observer canonical form (as in seed 004): "
    r"$\Delta = \mathcal{Q}_O^{-1}\bar{\mathcal{Q}}_O$, the canonical gain $\Psi_o$ "
    r"matches $\det(sI - \Gamma)$ with the desired polynomial, $L = \Delta\Psi_o$, in "
    r"exact arithmetic; cross-checked against \texttt{place}.")
