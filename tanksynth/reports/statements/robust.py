"""The ``robust`` family's problem statements: one gain for every vertex of a parameter box,
stated alike (``_robust``): the LMI region condition at every vertex, the polytope and its corner
models, the H-infinity bound and its channel, then what differs between the controller
(integral action or offsets, saturation) and the observer (its bias).
"""

from __future__ import annotations

from functools import partial
from typing import Callable

from tanksynth.reports.diagnostics.common import Diagnostics, integral_of, time_domain_of
from tanksynth.reports.diagnostics.robust import HinfChannel, Robustness, robustness_of
from tanksynth.reports.latex import escape_latex, format_number, symbol_latex
from tanksynth.reports.statements.common import domain_phrase, problem_statement, region_lmi_problem

__all__ = ["robust_state_feedback_statement", "robust_observer_statement"]


def _polytope(robust: Robustness) -> str:
    """The models the certificate covers."""
    if not robust.uncertain:
        return " for the nominal model (no uncertain parameter)"
    box = ", ".join(rf"{symbol_latex(u.name)} \in [{format_number(u.low)}, {format_number(u.high)}]"
                    for u in robust.uncertain)
    text = (rf" for every model of the polytope spanned by the $2^{{{len(robust.uncertain)}}}$ corners of "
            rf"the parameter box ${box}$ and the nominal model (linearised at the operating levels, "
            r"each with its own equilibrium input), with one common Lyapunov matrix")
    off = sum(1 for b in robust.balanced if b is False)
    if off:
        text += (rf"; at {off} of the {len(robust.balanced)} corner models the operating levels are not "
                 r"an equilibrium for any input (with fewer pumps than levels, the usual case once a "
                 r"parameter moves): they are linearised at the levels with the least-squares input, "
                 r"which leaves the level rates $f(x_0, u_0) \neq 0$")
    return text


def _box_source(diag: Diagnostics) -> str:
    """Where the box came from when it is a fit's intervals (``uncertain = "fit"``)."""
    source = diag.get("uncertain_source") if hasattr(diag, "get") else None
    if not isinstance(source, dict):
        return ""
    level = source.get("level")
    pct = (rf"{format_number(100 * float(level), 3)}\,\%" if isinstance(level, (int, float))
           else "the")
    sha = str(source.get("sha256", ""))[:12]
    return (rf" (the box is the {pct} confidence intervals of the parameters fitted to logged data, "
            rf"read from \texttt{{{escape_latex(source.get('file', ''), breakable=True)}}}, sha256 "
            rf"\texttt{{{escape_latex(sha)}}}\ldots)")


def _channel(channel: HinfChannel | None) -> str:
    """`` (w: ...; z = ...)``: the H-infinity channel, the spec's matrices or the defaults."""
    if channel is None:
        return ""
    if "Bw" in channel.given:
        w = r"$w$ enters through the given $B_w$, $\dot x = f(x, u) + B_w w$"
    elif channel.observer:
        w = (r"$w$ a level-rate disturbance on every state, $B_w = s I$ with $s$ 10\,\% of the pumps' "
             r"largest authority $\max_k |B_{ik}|\,\mathrm{range}_k$ (default)")
    else:
        w = r"$w$ enters like each pump with 10\,\% of its range, $B_w = B\,\mathrm{diag}(0.1\,\mathrm{range})$ (default)"
    z = r"$z = C_z x" + ("" if channel.observer else r" + D_{zu} u") + "$"
    z += r" with the given $C_z$" if "Cz" in channel.given else r", $C_z = I$ (every state, default)"
    if not channel.observer and "Dzu" not in channel.given:
        z += r", $D_{zu} = 0$"
    return f" ({w}; {z})"


def _certificate(robust: Robustness, diag: Diagnostics) -> str:
    """Which models, which region, which H-infinity bound: what the vertex LMIs certify."""
    text = _polytope(robust) + _box_source(diag)
    if robust.region:
        text += r"; here $D$: " + escape_latex(robust.region)
    text += domain_phrase(robust.domain or time_domain_of(diag))
    hinf = robust.hinf
    if hinf is not None:
        text += (rf". At every vertex the bounded real lemma certifies $\|T_{{zw}}\|_\infty < "
                 rf"{format_number(hinf.gamma)}$")
        text += _channel(robust.channel)
        if hinf.imposed is False:  # the design without the bound already met it
            scale = hinf.lyapunov_scale
            text += (" with the design's own Lyapunov matrix"
                     + (rf" times ${format_number(scale)}$" if scale is not None and abs(scale - 1) > 1e-9
                        else "")
                     + ": the bound does not bind, so it was not imposed in the LMIs")
    if robust.margin is not None:
        text += rf". Strict inequalities carry the margin ${format_number(robust.margin)}$ after scaling"
    return text + "."


def _controller(robust: Robustness, diag: Diagnostics) -> str:
    """Integral action (or the offsets without it) and the saturation-aware ellipsoid."""
    text = ""
    if integral_of(diag) is not None:
        text += r" The plant is augmented with integral action, $K = [K_1\;K_2]$ (no offset on the tracked outputs)."
    elif robust.offset is not None:
        text += (rf" Without integral action the law applies the nominal $u_0$: a plant at a vertex "
                 rf"settles up to ${format_number(robust.offset)}$ (state units) away from $x_0$.")
    if robust.saturation:
        text += (r" Saturation: the ellipsoid $\{x : x^\top P x \le 1\}$, $P = X^{-1}$, is invariant at "
                 r"every vertex and $\begin{bmatrix} u_{\max,j}^2 & Y_j \\ Y_j^\top & X\end{bmatrix} "
                 r"\succeq 0$ gives $|u_j - u_{0,j}| \le u_{\max,j}$ on it")
        if robust.ellipsoid_axes:
            text += "; semi-axes $" + ", ".join(format_number(a) for a in robust.ellipsoid_axes) + "$ (state units)"
        text += "."
    return text


def _observer(robust: Robustness, diag: Diagnostics) -> str:
    """What the certificate does not say about an observer on the nominal model."""
    return (r" An observer running on the nominal model keeps a bias when the plant's parameters "
            r"differ; the certificate is about the error dynamics.")


def _robust(problem: str, particular: Callable[[Robustness, Diagnostics], str], diag: Diagnostics) -> str:
    """The family's template: the vertex LMI ``problem``, what it certifies, then the sentences
    ``particular`` to the design."""
    robust = robustness_of(diag)
    return problem + _certificate(robust, diag) + particular(robust, diag)


robust_state_feedback_statement = problem_statement(
    "robust_state_feedback", __name__,
    partial(_robust, region_lmi_problem("A_i X - B_i Y", r"K = Y X^{-1}", "A_i - B_i K"), _controller))
robust_observer_statement = problem_statement(
    "robust_observer", __name__,
    partial(_robust, region_lmi_problem(r"A_i^\top X - C_i^\top Y", r"L = (Y X^{-1})^\top", "A_i - L C_i",
                                        dual=" (dual pairs)"), _observer))
