"""The ``takagi_sugeno`` family's problem statements: parallel distributed compensation on the
exact TS model of the deviations, by state feedback or on a TS observer (``_pdc_statement``).

Both state the PDC LMIs of the relaxation used, then the certified region and any set-point
change; the output feedback states its observer in between.
"""

from __future__ import annotations

from functools import partial
from typing import Callable

from tanksynth.reports.diagnostics.common import Diagnostics
from tanksynth.reports.diagnostics.takagi_sugeno import (PdcDesign, certified_region_of, pdc_design_of,
                                                          setpoint_change_of)
from tanksynth.reports.latex import escape_latex, format_number
from tanksynth.reports.prose import prose_latex
from tanksynth.reports.statements.common import problem_statement

__all__ = ["ts_state_feedback_statement", "ts_output_feedback_statement"]

#: The vertex conditions of each relaxation (``vertex`` for any other name).
_CONDITIONS = {
    "tuan": (r"$\Upsilon_{ii} \prec 0$, $\tfrac{2}{r-1}\Upsilon_{ii} + \Upsilon_{ij} + \Upsilon_{ji} "
             r"\prec 0$ ($i \ne j$; Tuan et al.\ 2001)"),
    "all_pairs": r"$\Upsilon_{ij} \prec 0$ for every $(i, j)$ (premises of the controller estimated)",
}
_VERTEX_CONDITIONS = (r"$\Upsilon_{ii} \prec 0$, $\Upsilon_{ij} + \Upsilon_{ji} \prec 0$ ($i < j$; basic "
                      r"vertex conditions)")


def _pdc(design: PdcDesign) -> str:
    """The PDC law and the LMIs of its relaxation."""
    text = (r"Parallel distributed compensation $u = u_0 - \sum_j \mu_j(x) K_j (x - x_0)$ on the exact "
            r"Takagi--Sugeno model of the deviations, $\dot e = \sum_i \mu_i(x)(A_i e + B v)$, with "
            r"premises $z_k = (n_k(x) - n_k(x_0))/(a_k^\top (x - x_0))$ (sector rewriting of the "
            r"increments). With $X = P^{-1}$, $M_j = K_j X$ and "
            r"$\Upsilon_{ij} = A_i X + X A_i^\top - B M_j - M_j^\top B^\top + 2\alpha X$: ")
    text += _CONDITIONS.get(design.relaxation or "", _VERTEX_CONDITIONS)
    text += (r"; the ellipsoid $e^\top P e \le 1$ inside the domain ($a_l^\top X a_l \le b_l^2$) and "
             r"within the pump margins ($\left[\begin{smallmatrix} \bar u_j^2 & m_{ij} \\ m_{ij}^\top & "
             r"X\end{smallmatrix}\right] \succeq 0$), enlarged. Continuous time.")
    if design.decay_rate is not None and design.decay_at_least is not None:
        text += (rf" Relaxation used: {escape_latex(design.relaxation)}; certified decay rate "
                 rf"$\alpha \ge {format_number(design.decay_at_least)}$ 1/s (the conditions strict there: "
                 rf"margin ${format_number(design.decay_margin, 3)}$, minus their largest eigenvalue); "
                 r"these matrices certify "
                 rf"at most $\alpha = {format_number(design.decay_rate)}$ 1/s, where the conditions hold "
                 r"with equality.")
    elif design.decay_rate is not None:
        text += (rf" Relaxation used: {escape_latex(design.relaxation)}; decay rate at most "
                 rf"${format_number(design.decay_rate)}$ 1/s (the supremum these matrices certify, where "
                 r"the conditions hold with equality).")
    return text


def _region(diag: Diagnostics) -> str:
    """The certified region, its binding constraint and its size."""
    region = certified_region_of(diag)
    if region.c is None:
        return ""
    text = (rf" Certified region $\{{x : (x - x_0)^\top P (x - x_0) \le {format_number(region.c)}\}}$"
            r" (inside the TS domain, pumps unsaturated)")
    if region.binding:
        text += ", bound by " + prose_latex(region.binding.replace("+ -", "- "))
    if region.extents is not None and len(region.extents) == len(region.states):
        text += "; largest deviations " + ", ".join(
            f"${escape_latex(s)}$: {format_number(v)} m" for s, v in zip(region.states, region.extents))
    if region.semi_axes:
        text += "; semi-axes " + ", ".join(format_number(v) for v in region.semi_axes) + " m"
    return text + "."


def _setpoint(diag: Diagnostics, design: PdcDesign) -> str:
    """The certified switch to a second operating point."""
    change = setpoint_change_of(diag)
    if change is None:
        return ""
    text = (r" Set-point change to $x_0' = (" + r",\; ".join(format_number(v) for v in change.x_op2)
            + r")$ m: the TS model of the deviations is exact about any point of the domain but its "
            r"premises (secants from that point) and vertices are not, so a second PDC is designed on the "
            r"exact model about $x_0'$ ($u_0'$ balancing it), with its own region $V_2 = (x - x_0')^\top "
            r"P_2 (x - x_0') \le c_2$")
    if change.region_c is not None:
        text += rf" ($c_2 = {format_number(change.region_c)}$)"
    text += (r"; the switch is certified from $\{V_1 \le \gamma c_1\} \subset \{V_2 \le c_2\}$ "
             r"(S-lemma), $\gamma = " + format_number(change.switch_level) + "$")
    if change.dwell_time is not None:
        text += (r", reached from anywhere in the first region after the dwell time "
                 rf"$\ln(1/\gamma)/(2\alpha_1) = {format_number(change.dwell_time)}$ s ($\alpha_1$ the "
                 r"certified decay rate of $V_1$)")
    return text + (", the observer kept (its error does not depend on the set-point)."
                   if design.composite else ".")


def _observer(design: PdcDesign) -> str:
    """The TS observer the output feedback runs on, and the composite certificate."""
    if design.premises == "measured":
        text = (r" Measured premises: PDC observer $\dot{\hat x} = \sum_i \mu_i(y)(A_i \hat e + B v) + "
                r"\sum_j \mu_j(y) L_j (y - C\hat x)$ designed separately (separation holds: "
                r"$\dot\varepsilon = \sum_{ij}\mu_i\mu_j (A_i - L_j C)\varepsilon$).")
    else:
        text = (r" Estimated premises: observer of seed 001 (premises at the estimate) with the observer LMI "
                r"$\begin{bmatrix} A_0^\top P_o + P_o A_0 - C^\top K^\top - K C + \psi^2 Q & P_o \\ P_o & -Q \end{bmatrix} \prec 0$, $L = P_o^{-1} K$, "
                r"for $\psi$ the Lipschitz bound of the remainder; the controller uses the all-pairs "
                r"conditions (two-step design).")
        if design.observer_psi is not None:
            text += rf" Here $\psi = {format_number(design.observer_psi)}$ 1/s."
    if design.composite_beta is not None:
        text += (r" Composite certificate $V = e^\top P e + \beta \varepsilon^\top P_o \varepsilon$ with "
                 rf"$\beta = {format_number(design.composite_beta)}$.")
    return text


def _initial_error(design: PdcDesign) -> str:
    """What initial estimation error the composite certificate allows (output feedback)."""
    if design.error_ball is None or design.plant_ball_estimate_at_x_op is None:
        return ""
    text = (r" The region holds for the plant with the estimate starting exact ($\varepsilon(0) = 0$); "
            r"otherwise the certificate needs $(e(0), \varepsilon(0))$ in $\{V \le c\}$: with the plant "
            rf"starting at $x_0$, an initial estimation error within the ball of radius "
            rf"${format_number(design.error_ball, 3)}$ m")
    if design.error_semi_axes:
        text += (r" (the ellipsoid $\beta\, \varepsilon^\top P_o \varepsilon \le c$, semi-axes up to "
                 rf"${format_number(design.error_semi_axes[-1], 3)}$ m)")
    return text + (r"; with the estimate started at the operating point ($\hat x(0) = x_0$, "
                   r"$\varepsilon(0) = e(0)$), plant states within "
                   rf"${format_number(design.plant_ball_estimate_at_x_op, 3)}$ m of $x_0$.")


def _pdc_statement(observer: Callable[[PdcDesign], str] | None, diag: Diagnostics) -> str:
    """The family's template: the PDC LMIs, the ``observer`` (output feedback), the certified
    region and the set-point change."""
    design = pdc_design_of(diag)
    return (_pdc(design) + (observer(design) if observer else "") + _region(diag) + _initial_error(design)
            + _setpoint(diag, design))


ts_state_feedback_statement = problem_statement("ts_state_feedback", __name__, partial(_pdc_statement, None))
ts_output_feedback_statement = problem_statement("ts_output_feedback", __name__,
                                                 partial(_pdc_statement, _observer))
