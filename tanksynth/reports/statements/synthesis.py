"""The ``synthesis`` family's problem statements: optimal convex synthesis of a state feedback or
an observer (H2, H-infinity, multiobjective), stated alike (``_synthesis``).

Each states the plant and gain, what is minimised by which route, and the bounds certified and
norms recomputed.
"""

from __future__ import annotations

from functools import partial
from typing import Callable

from tanksynth.reports.diagnostics.common import Diagnostics, time_domain_of
from tanksynth.reports.diagnostics.synthesis import Synthesis, synthesis_of
from tanksynth.reports.latex import escape_latex, format_number
from tanksynth.reports.statements.common import domain_phrase, problem_statement, region_inequality

__all__ = ["h2_state_feedback_statement", "h2_observer_statement",
           "hinf_state_feedback_statement", "hinf_observer_statement", "multiobjective_statement"]

#: An observer's LMIs are those of the dual pair.
_DUAL = r" of the dual pair $(A^\top, C^\top)$"


def _plant(synthesis: Synthesis, diag: Diagnostics, observer: bool) -> str:
    """The plant, its channel ``w -> z`` and the gain."""
    discrete = (time_domain_of(diag) or synthesis.domain or "continuous") == "discrete"
    lhs = r"x(k+1)" if discrete else r"\dot x"
    if observer:
        return (rf"For ${lhs} = A x + B u + B_w w$, $y = C x + D_v v$ and the observer error "
                r"$e = x - \hat x$ with gain $L$ (error matrix $A - LC$, performance $z = C_z e$)")
    return (rf"For ${lhs} = A x + B_w w + B u$, $z = C_z x + D_{{zu}} u$ and the state feedback "
            r"$u = -Kx$")


def _numbers(synthesis: Synthesis, diag: Diagnostics, observer: bool) -> str:
    """The time domain, the bounds certified and the norms recomputed from the closed loop."""
    parts = [rf"${label} {format_number(v)}$"
             for v, label in ((synthesis.h2_bound, r"\|T_{zw}\|_2 \le"),
                              (synthesis.gamma, r"\|T_{zw}\|_\infty \le")) if v is not None]
    parts += [rf"recomputed ${label} = {format_number(v)}$"
              for v, label in ((synthesis.achieved_h2, r"\|T_{zw}\|_2"),
                               (synthesis.achieved_hinf, r"\|T_{zw}\|_\infty")) if v is not None]
    return (domain_phrase(time_domain_of(diag)) + (": " + ", ".join(parts) if parts else "") + "."
            + (_norm_units(observer) if parts else ""))


def _norm_units(observer: bool) -> str:
    """What the norms measure and in which units (issue 30: norms were printed without one)."""
    noises = r"$w$ and $v$ are" if observer else r"$w$ is"
    weights = (r"$C_z = Q^{1/2}$, $Q$ in 1/state unit$^2$" if observer else
               r"$C_z$, $D_{zu}$ from $Q^{1/2}$ and $R^{1/2}$, $Q$ in 1/state unit$^2$, $R$ in 1/input unit$^2$")
    return (rf" The disturbance {noises} normalised to unit intensity and $z$ is weighted, so the norms are "
            rf"in the units of $z$ per unit of $w$: dimensionless with the default weights ({weights}); "
            r"$\|T_{zw}\|_2$ is the RMS value of $z$ under unit-intensity white noise, "
            r"$\|T_{zw}\|_\infty$ the largest ratio of the RMS values of $z$ and of the disturbances.")


def _h2(synthesis: Synthesis, observer: bool) -> str:
    """Minimise the H2 norm: by the Riccati equation, or over the H2 LMIs."""
    optimum = "steady Kalman filter" if observer else "LQR"
    if synthesis.route == "riccati":
        weights = (r"the noise covariances $B_w B_w^\top$ (process) and $D_v D_v^\top$ (measurement)"
                   if observer else r"the weights $C_z^\top C_z$, $D_{zu}^\top D_{zu}$")
        return (rf", minimise $\|T_{{zw}}\|_2$: the {optimum} gain from the algebraic Riccati equation "
                rf"with {weights} (the H2 LMI has the same optimum; "
                r"the gain is re-checked by the Gramian)")
    gain = "L^\\top" if observer else "K"
    return (rf", minimise $\operatorname{{tr}} W$ over $X \succ 0$, $Y = {gain} X$, $W$ with the H2 LMIs "
            r"(Gramian bound $X$, $\|T_{zw}\|_2^2 < \operatorname{tr} W$)"
            + (_DUAL if observer else "")
            + r"; the optimum equals the " + optimum + r" Riccati solution for the same weights")


def _hinf(synthesis: Synthesis, observer: bool) -> str:
    """Minimise the H-infinity norm: by bisection over the game Riccati equation, or over the
    bounded-real-lemma LMI; then the back-off from the optimum."""
    backoff = synthesis.backoff if synthesis.backoff is not None and synthesis.backoff > 0 else None
    if synthesis.route == "riccati":
        text = (r", minimise $\gamma = \|T_{zw}\|_\infty$ (the $L_2$ gain from the disturbances to $z$) "
                r"by bisection on $\gamma$ over the game algebraic Riccati equation"
                + (_DUAL if observer else "")
                + r"; a $\gamma$ counts as reached only when its gain passes the Hamiltonian norm test")
        if backoff is not None:
            text += rf"; the gain is the one at $\gamma = (1 + {format_number(backoff)})\gamma^\star$"
        return text
    gain = "L^\\top" if observer else "K"
    text = (rf", minimise $\gamma$ over $X \succ 0$, $Y = {gain} X$ with the bounded-real-lemma LMI "
            r"($\|T_{zw}\|_\infty < \gamma$: the $L_2$ gain from the disturbances to $z$)"
            + (_DUAL if observer else ""))
    if backoff is not None:
        text += rf", then keep $\gamma \le (1 + {format_number(backoff)})\gamma^\star$ and maximise the LMI margin"
    return text


def _multiobjective(synthesis: Synthesis, observer: bool) -> str:
    """Minimise one objective under the H2 / H-infinity / region LMIs with one Lyapunov matrix."""
    goal = r"\gamma" if synthesis.objective == "hinf" else r"\operatorname{tr} W"
    text = (rf", minimise ${goal}$ subject to the H2 and/or bounded-real-lemma LMIs and the "
            rf"Chilali--Gahinet region LMI ${region_inequality('AX - BY')}$, all with ONE Lyapunov "
            r"matrix $X$ (msfsyn-style)")
    if synthesis.region:
        text += r"; region $D$: " + escape_latex(synthesis.region)
    return text


#: What `multiobjective` adds after its numbers.
_CONSERVATISM = (r" Conservatism: the common $X$ makes the bounds guaranteed but possibly pessimistic "
                 r"(each objective alone may need another matrix); the achieved norms are recomputed "
                 r"from the closed loop.")


def _synthesis(objective: Callable[[Synthesis, bool], str], observer: bool | None, closing: str,
               diag: Diagnostics) -> str:
    """The family's template: the plant and gain, the ``objective`` (what is minimised and how),
    the numbers, then ``closing``. ``observer`` None: as the design's ``target`` says."""
    synthesis = synthesis_of(diag)
    is_observer = synthesis.observer if observer is None else observer
    return (_plant(synthesis, diag, is_observer) + objective(synthesis, is_observer)
            + _numbers(synthesis, diag, is_observer) + closing)


h2_state_feedback_statement = problem_statement("h2_state_feedback", __name__,
                                                partial(_synthesis, _h2, False, ""))
h2_observer_statement = problem_statement("h2_observer", __name__, partial(_synthesis, _h2, True, ""))
hinf_state_feedback_statement = problem_statement("hinf_state_feedback", __name__,
                                                  partial(_synthesis, _hinf, False, ""))
hinf_observer_statement = problem_statement("hinf_observer", __name__, partial(_synthesis, _hinf, True, ""))
multiobjective_statement = problem_statement("multiobjective", __name__,
                                             partial(_synthesis, _multiobjective, None, _CONSERVATISM))
