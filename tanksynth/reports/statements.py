"""One problem statement per design method: what was solved, in mathematics, for the report.

Each ``<method>_statement(diag) -> Tex`` reads the artefact's diagnostics only.
The method table (`tanksynth.methods`) holds which statement belongs to which method.
"""

from __future__ import annotations

from typing import Any, Mapping

from tanksynth.reports.latex import Tex, escape_latex, format_eigenvalues, format_number
from tanksynth.reports.prose import prose_latex


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


__all__ = ["linearize_statement", "pole_placement_statement", "lmi_placement_statement",
           "ts_observer_statement", "canonical_observer_statement",
           "feedback_linearization_statement", "integral_tracking_statement", "inverse_dynamics_statement", "decentralized_kalman_statement", "kalman_statement", "ekf_statement", "ukf_statement", "adaptive_kalman_statement", "adaptive_scaling_kalman_statement", "consensus_filter_statement", "luenberger_statement", "narx_statement", "fault_detection_statement",
           "robust_state_feedback_statement", "robust_observer_statement",
           "ts_state_feedback_statement", "ts_output_feedback_statement"]


def linearize_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``linearize`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"First-order Taylor expansion of the smooth model at the operating point, "
               r"$F = \partial f/\partial x$, $B = \partial f/\partial u$, $C = \partial h/\partial x$ "
               r"at $(x_0, u_0)$ with the equilibrium input $u_0$ computed from the model; "
               r"exact zero-order-hold discretisation $A_d = e^{F t_s}$, "
               r"$B_d = \int_0^{t_s} e^{F\tau}B\,d\tau$.")


def pole_placement_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``pole_placement`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    pl = diag.get("placement") or {}
    kind = pl.get("kind", "state_feedback")
    if str(kind).startswith("observer"):
        what = r"the eigenvalues of the error dynamics $A - LC$"
    else:
        what = r"the closed-loop eigenvalues of $A - BK$ (control law $u = -Kx$)"
    text = rf"Place {what} exactly"
    if "requested" in pl:
        try:
            text += r" at $" + format_eigenvalues(pl["requested"], 4) + "$"
        except (TypeError, ValueError):
            pass
    method = pl.get("method")
    if method:
        text += r" with \texttt{" + escape_latex(method) + "}"
    text += "."
    integ = diag.get("integral")
    if isinstance(integ, Mapping):
        tracked = ", ".join(str(t) for t in integ.get("tracked", []))
        text += (r" Integral action: the model is augmented with $z(k+1) = z(k) + t_s(y_r - C_1 x)$"
                 r" for the tracked outputs " + prose_latex(tracked)
                 + r", and $K = [K_1\;K_2]$ acts on $(x, z)$.")
    return Tex(text)


def lmi_placement_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``lmi_placement`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    lmi = diag.get("lmi") or {}
    region = (lmi.get("region") or {}).get("description")
    kind = lmi.get("kind", "state_feedback")
    if str(kind).startswith("observer"):
        body = (r"Find $X \succ 0$ and $Y$ with $L_D \otimes X + M_D \otimes (A^\top X - C^\top Y) "
                r"+ M_D^\top \otimes (A^\top X - C^\top Y)^\top \prec 0$ (dual pair), "
                r"$L = (Y X^{-1})^\top$: every eigenvalue of $A - LC$ lies in the LMI region $D$")
    else:
        body = (r"Find $X \succ 0$ and $Y$ with $L_D \otimes X + M_D \otimes (AX - BY) "
                r"+ M_D^\top \otimes (AX - BY)^\top \prec 0$, $K = Y X^{-1}$: every eigenvalue of "
                r"$A - BK$ lies in the LMI region $D = \{z : L_D + M_D z + M_D^\top \bar z \prec 0\}$")
    text = body + (r" (Chilali--Gahinet)")
    if region:
        text += r"; here $D$: " + prose_latex(region)
    dom = lmi.get("domain") or diag.get("time_domain")
    if dom:
        text += f" ({escape_latex(dom)} time)"
    margin = lmi.get("margin")
    if _is_number(margin):
        text += rf". The strict inequality is imposed with margin ${format_number(margin)}$ after scaling"
    text += "."
    if isinstance(diag.get("integral"), Mapping):
        text += r" The plant is augmented with integral action, $K = [K_1\;K_2]$."
    return Tex(text)


def ts_observer_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``ts_observer`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    lmi = diag.get("lmi") or {}
    text = (r"Observer $\dot{\hat x} = A_0\hat x + \Delta(\hat x, u) + L(y - C\hat x)$ for the "
            r"Takagi--Sugeno model of the plant; the error obeys $\dot e = (A_0 - LC)e + \Delta$ "
            r"with $\|\Delta\| \le \psi\|e\|$. Find $P \succ 0$, $Q \succ 0$, $K$ with "
            r"\[\begin{bmatrix} A_0^\top P + P A_0 - C^\top K^\top - K C + \psi^2 Q & P \\ "
            r"P & -Q \end{bmatrix} \prec 0, \qquad L = P^{-1}K\]"
            r"(seed 001 LMI (28)).")
    psi = lmi.get("psi")
    if _is_number(psi):
        text += rf" Here $\psi = {format_number(psi)}$"
        src = diag.get("psi_source")
        if src:
            text += " (" + prose_latex(src) + ")"
        text += "."
    if lmi.get("Q_form"):
        text += " " + prose_latex(lmi["Q_form"]) + "."
    ts = diag.get("ts_model") or {}
    if isinstance(ts.get("r"), int):
        text += f" The TS model has {ts['r']} vertices"
        dom = (ts.get("domain") or {}).get("description")
        if dom:
            text += " on the domain " + prose_latex(dom)
        text += "."
    return Tex(text)


def canonical_observer_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``canonical_observer`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Observer through the observer canonical form (seed 004 eqs.~(25)--(29)): "
               r"$\Delta = \mathcal{Q}_O^{-1}\bar{\mathcal{Q}}_O$, the canonical gain $\Psi_o$ "
               r"matches $\det(sI - \Gamma)$ with the desired polynomial, $L = \Delta\Psi_o$, in "
               r"exact arithmetic; cross-checked against \texttt{place}.")




def feedback_linearization_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``feedback_linearization`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Exact input-output linearisation of $\dot x = f(x) + g(x)u$, $y = h(x)$: with relative "
               r"degrees $r_i$ and decoupling matrix $D(x) = [L_g L_f^{r_i-1} h_i]$ invertible on the "
               r"region, $u = D(x)^{-1}\big(v - [L_f^{r_i} h_i(x)]\big)$ gives $y_i^{(r_i)} = v_i$; the "
               r"outer loop $v$ places the poles of each chain, and the zero dynamics are checked stable.")


def integral_tracking_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``integral_tracking`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Sampled tracking with integral action about $(x_0, u_0)$: $u(k) = \mathrm{sat}\big(u_0 - "
               r"K_1 (x(k) - x_0) - K_2 z(k)\big)$, $z(k+1) = z(k) + t_s (y_r(k) - C_1 x(k))$ plus "
               r"anti-windup, with $[K_1\ K_2]$ placing the eigenvalues of the augmented pair "
               r"$\left(\begin{smallmatrix} A_d & 0 \\ -t_s C_1 & I\end{smallmatrix}\right)$, "
               r"$\left(\begin{smallmatrix} B_d \\ 0\end{smallmatrix}\right)$.")


def inverse_dynamics_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``inverse_dynamics`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Inverse dynamics of the pump-fed states $x_c$: impose $\dot x_{c,i} = C_i (x_{c,i}^{sp} - "
               r"x_{c,i})$, i.e. $u = G_c(\hat x)^{-1}\big(\mathrm{diag}(C)(x_c^{sp} - \hat x_c) - "
               r"f_{0,c}(\hat x)\big)$ saturated to the pump range, with the rates $C_i \ge 0$ minimising "
               r"the integral of squared errors of a servo scenario.")


def decentralized_kalman_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``decentralized_kalman`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Kalman gains $K(k)$ constrained to a sparsity pattern $E$ (each tank uses its own "
               r"measurements): minimise $\mathrm{tr}\,P(k|k)$ step by step (one-step) or "
               r"$\sum_k \mathrm{tr}\,P(k|k)$ over a window (finite horizon), with the covariance "
               r"recursion $P(k|k) = (I - KC)P(k|k-1)(I - KC)^\top + K R K^\top$ of the linearised network.")


def _filter_statement(what: str) -> Tex:
    return Tex(what + r" State $x(k+1) = F(x(k), u(k)) + w(k)$, $y(k) = h(x(k)) + v(k)$ with "
               r"$w \sim \mathcal{N}(0, Q)$, $v \sim \mathcal{N}(0, R)$, $x(0) \sim \mathcal{N}(\hat x_0, P_0)$; "
               r"covariance updates in Joseph form, symmetrised.")


def kalman_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``kalman`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _filter_statement(r"Kalman filter on the exact ZOH linearisation $(A_d, B_d, C)$ at the "
                             r"operating point: the minimum-variance linear estimator.")


def ekf_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``ekf`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _filter_statement(r"Extended Kalman filter: the nonlinear model is propagated and its "
                             r"Jacobians at the current estimate give the gain.")


def ukf_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``ukf`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _filter_statement(r"Unscented Kalman filter: $2n+1$ sigma points (weights from "
                             r"$\alpha, \beta, \kappa$) propagated through the nonlinear model.")


def adaptive_kalman_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``adaptive_kalman`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _filter_statement(r"Adaptive Kalman filter: $Q$ re-estimated from the innovations "
                             r"$\nu_k$ over a sliding window of length $\Psi$.")


def adaptive_scaling_kalman_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``adaptive_scaling_kalman`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _filter_statement(r"Adaptive-scaling Kalman filter: the process noise is scaled by "
                             r"$\varphi_k$ solved from $\nu_k^\top \nu_k = \mathrm{tr}(\beta) + \varphi_k "
                             r"\mathrm{tr}(C G Q G^\top C^\top)$.")


def consensus_filter_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``consensus_filter`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _filter_statement(r"Information-form consensus filter: $N$ redundant sensors fuse "
                             r"$\sum_i C^\top R_i^{-1} C$ and $\sum_i C^\top R_i^{-1} y_i$.")


def luenberger_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``luenberger`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Luenberger observer $\hat x(k+1) = A_d \hat x(k) + B_d u(k) + L\big(y(k) - C\hat x(k)\big)$ "
               r"(or its continuous form), $L$ given or placing the eigenvalues of $A - LC$.")


def narx_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``narx`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"NARX estimator: a one-hidden-layer network maps delayed measurements and inputs to the "
               r"state, trained by Levenberg-Marquardt on EKF-labelled data to minimise "
               r"$\sum_k \|\hat x_k - x_k^{\mathrm{EKF}}\|^2$.")


def fault_detection_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``fault_detection`` solves.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Observer-based fault detection: the residual $r(t) = y(t) - C\hat x(t)$ of a Luenberger "
               r"observer with poles placed by the canonical form is compared with a threshold "
               r"$J_{th}(t)$ derived from the bounds of the healthy error dynamics; a fault is declared "
               r"when $|r(t)| > J_{th}(t)$.")


def _robust_common(diag: Mapping[str, Any]) -> str:
    rob = diag.get("robust") or {}
    region = (rob.get("region") or {}).get("description")
    unc = diag.get("uncertain") or []
    if unc:
        box = ", ".join(rf"{escape_latex(str(u[0]))} \in [{format_number(u[1])}, {format_number(u[2])}]"
                        for u in unc if len(u) == 3)
        text = (rf" for every model of the polytope spanned by the $2^{{{len(unc)}}}$ corners of the "
                rf"parameter box ${box}$ and the nominal model (linearised at the operating levels, "
                r"each with its own equilibrium input), with one common Lyapunov matrix")
        balanced = (diag.get("vertex_models") or {}).get("balanced") or []
        off = sum(1 for b in balanced if b is False)
        if off:
            text += (rf"; {off} of the {len(balanced)} corner models cannot hold the operating levels "
                     r"with any input (no equilibrium there): they are linearised at the levels with "
                     r"the least-squares input, which leaves the level rates $f(x_0, u_0) \neq 0$")
    else:
        text = " for the nominal model (no uncertain parameter)"
    if region:
        text += r"; here $D$: " + escape_latex(region)
    dom = rob.get("domain") or diag.get("time_domain")
    if dom:
        text += f" ({escape_latex(dom)} time)"
    hinf = rob.get("hinf")
    if isinstance(hinf, Mapping) and _is_number(hinf.get("gamma")):
        text += (rf". At every vertex the bounded real lemma certifies $\|T_{{zw}}\|_\infty < "
                 rf"{format_number(hinf['gamma'])}$")
        text += _hinf_channel(diag.get("hinf_channel"))
        if hinf.get("imposed") is False:  # the design without the bound already met it
            scale = hinf.get("lyapunov_scale")
            text += (" with the design's own Lyapunov matrix"
                     + (rf" times ${format_number(scale)}$" if _is_number(scale) and abs(scale - 1) > 1e-9
                        else "")
                     + ": the bound does not bind, so it was not imposed in the LMIs")
    margin = rob.get("margin")
    if _is_number(margin):
        text += rf". Strict inequalities carry the margin ${format_number(margin)}$ after scaling"
    return text + "."


def _hinf_channel(channel: Any) -> str:
    """`` (w: ...; z = ...)``: the robust designs' H-infinity channel (``hinf_channel``)."""
    if not isinstance(channel, Mapping) or "observer" not in channel:
        return ""
    given = set(channel.get("given") or ())
    observer = bool(channel["observer"])
    if "Bw" in given:
        w = r"$w$ enters through the given $B_w$, $\dot x = f(x, u) + B_w w$"
    elif observer:
        w = (r"$w$ a level-rate disturbance on every state, $B_w = s I$ with $s$ 10\,\% of the pumps' "
             r"largest authority $\max_k |B_{ik}|\,\mathrm{range}_k$ (default)")
    else:
        w = r"$w$ enters like each pump with 10\,\% of its range, $B_w = B\,\mathrm{diag}(0.1\,\mathrm{range})$ (default)"
    z = r"$z = C_z x" + ("" if observer else r" + D_{zu} u") + "$"
    z += r" with the given $C_z$" if "Cz" in given else r", $C_z = I$ (every state, default)"
    if not observer and "Dzu" not in given:
        z += r", $D_{zu} = 0$"
    return f" ({w}; {z})"


def robust_state_feedback_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``robust_state_feedback`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    text = (r"Find $X \succ 0$ and $Y$ with $L_D \otimes X + M_D \otimes (A_i X - B_i Y) + M_D^\top "
            r"\otimes (A_i X - B_i Y)^\top \prec 0$, $K = Y X^{-1}$: every eigenvalue of $A_i - B_i K$ "
            r"lies in the LMI region $D$" + _robust_common(diag))
    if isinstance(diag.get("integral"), Mapping):
        text += r" The plant is augmented with integral action, $K = [K_1\;K_2]$ (no offset on the tracked outputs)."
    elif diag.get("offsets"):
        off = diag["offsets"].get("max_abs_deviation")
        if _is_number(off):
            text += (rf" Without integral action the law applies the nominal $u_0$: a plant at a vertex "
                     rf"settles up to ${format_number(off)}$ (state units) away from $x_0$.")
    sat = diag.get("saturation")
    if isinstance(sat, Mapping):
        text += (r" Saturation: the ellipsoid $\{x : x^\top P x \le 1\}$, $P = X^{-1}$, is invariant at "
                 r"every vertex and $\begin{bmatrix} u_{\max,j}^2 & Y_j \\ Y_j^\top & X\end{bmatrix} "
                 r"\succeq 0$ gives $|u_j - u_{0,j}| \le u_{\max,j}$ on it")
        axes = (sat.get("ellipsoid_axes") or {}).get("lengths")
        if isinstance(axes, list) and axes:
            text += "; semi-axes $" + ", ".join(format_number(a) for a in axes) + "$ (state units)"
        text += "."
    return Tex(text)


def robust_observer_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``robust_observer`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Find $X \succ 0$ and $Y$ with $L_D \otimes X + M_D \otimes (A_i^\top X - C_i^\top Y) + "
               r"M_D^\top \otimes (A_i^\top X - C_i^\top Y)^\top \prec 0$ (dual pairs), $L = (Y X^{-1})^\top$: "
               r"every eigenvalue of $A_i - L C_i$ lies in the LMI region $D$" + _robust_common(diag)
               + r" An observer running on the nominal model keeps a bias when the plant's parameters "
                 r"differ; the certificate is about the error dynamics.")
def _ts_region_text(diag: Mapping[str, Any]) -> str:
    reg = diag.get("region") or {}
    text = ""
    c = reg.get("c")
    if _is_number(c):
        text += (rf" Certified region $\{{x : (x - x_0)^\top P (x - x_0) \le {format_number(c)}\}}$"
                 r" (inside the TS domain, pumps unsaturated)")
        binding = reg.get("binding")
        if binding:
            text += ", bound by " + escape_latex(str(binding))
        ext = reg.get("extents")
        states = reg.get("states") or []
        if isinstance(ext, list) and len(ext) == len(states):
            text += "; largest deviations " + ", ".join(
                f"${escape_latex(str(s))}$: {format_number(v)} m" for s, v in zip(states, ext))
        axes = reg.get("semi_axes")
        if isinstance(axes, list) and axes:
            text += "; semi-axes " + ", ".join(format_number(v) for v in axes) + " m"
        text += "."
    return text


def _ts_setpoint_text(diag: Mapping[str, Any]) -> str:
    sp = diag.get("setpoint") or {}
    x2, gamma = sp.get("x_op2"), sp.get("switch_level")
    if not (isinstance(x2, list) and _is_number(gamma)):
        return ""
    reg = sp.get("region") or {}
    text = (r" Set-point change to $x_0' = (" + r",\; ".join(format_number(v) for v in x2) + r")$ m: the "
            r"TS model of the deviations is exact about any point of the domain but its premises "
            r"(secants from that point) and vertices are not, so a second PDC is designed on the "
            r"exact model about $x_0'$ ($u_0'$ balancing it), with its own region $V_2 = (x - x_0')^\top "
            r"P_2 (x - x_0') \le c_2$")
    if _is_number(reg.get("c")):
        text += rf" ($c_2 = {format_number(reg['c'])}$)"
    text += (r"; the switch is certified from $\{V_1 \le \gamma c_1\} \subset \{V_2 \le c_2\}$ "
             r"(S-lemma), $\gamma = " + format_number(gamma) + "$")
    if _is_number(sp.get("dwell_time")):
        text += (r", reached from anywhere in the first region after the dwell time "
                 rf"$\ln(1/\gamma)/(2\alpha_1) = {format_number(sp['dwell_time'])}$ s ($\alpha_1$ the "
                 r"certified decay rate of $V_1$)")
    return text + (", the observer kept (its error does not depend on the set-point)."
                   if diag.get("composite") else ".")


def ts_state_feedback_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``ts_state_feedback`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    rel = diag.get("relaxation", "")
    text = (r"Parallel distributed compensation $u = u_0 - \sum_j \mu_j(x) K_j (x - x_0)$ on the exact "
            r"Takagi--Sugeno model of the deviations, $\dot e = \sum_i \mu_i(x)(A_i e + B v)$, with "
            r"premises $z_k = (n_k(x) - n_k(x_0))/(a_k^\top (x - x_0))$ (sector rewriting of the "
            r"increments). With $X = P^{-1}$, $M_j = K_j X$ and "
            r"$\Upsilon_{ij} = A_i X + X A_i^\top - B M_j - M_j^\top B^\top + 2\alpha X$: ")
    if rel == "tuan":
        text += (r"$\Upsilon_{ii} \prec 0$, $\tfrac{2}{r-1}\Upsilon_{ii} + \Upsilon_{ij} + \Upsilon_{ji} "
                 r"\prec 0$ ($i \ne j$; Tuan et al.\ 2001)")
    elif rel == "all_pairs":
        text += r"$\Upsilon_{ij} \prec 0$ for every $(i, j)$ (premises of the controller estimated)"
    else:
        text += r"$\Upsilon_{ii} \prec 0$, $\Upsilon_{ij} + \Upsilon_{ji} \prec 0$ ($i < j$; basic vertex conditions)"
    text += (r"; the ellipsoid $e^\top P e \le 1$ inside the domain ($a_l^\top X a_l \le b_l^2$) and "
             r"within the pump margins ($\left[\begin{smallmatrix} \bar u_j^2 & m_{ij} \\ m_{ij}^\top & "
             r"X\end{smallmatrix}\right] \succeq 0$), enlarged. Continuous time.")
    dec = diag.get("decay_rate")
    if _is_number(dec):
        text += rf" Relaxation used: {escape_latex(str(rel))}; certified decay rate ${format_number(dec)}$ 1/s."
    return Tex(text + _ts_region_text(diag) + _ts_setpoint_text(diag))


def ts_output_feedback_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``ts_output_feedback`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    base = str(ts_state_feedback_statement({k: v for k, v in diag.items()
                                            if k not in ("region", "setpoint")}))
    obs = diag.get("observer") or {}
    if diag.get("premises") == "measured":
        text = (r" Measured premises: PDC observer $\dot{\hat x} = \sum_i \mu_i(y)(A_i \hat e + B v) + "
                r"\sum_j \mu_j(y) L_j (y - C\hat x)$ designed separately (separation holds: "
                r"$\dot\varepsilon = \sum_{ij}\mu_i\mu_j (A_i - L_j C)\varepsilon$).")
    else:
        text = (r" Estimated premises: observer of seed 001 (premises at the estimate) with LMI (28) "
                r"for $\psi$ the Lipschitz bound of the remainder; the controller uses the all-pairs "
                r"conditions (two-step design).")
        if _is_number(obs.get("psi")):
            text += rf" Here $\psi = {format_number(obs['psi'])}$ 1/s."
    comp = diag.get("composite") or {}
    if _is_number(comp.get("beta")):
        text += (r" Composite certificate $V = e^\top P e + \beta \varepsilon^\top P_o \varepsilon$ with "
                 rf"$\beta = {format_number(comp['beta'])}$.")
    return Tex(base + text + _ts_region_text(diag) + _ts_setpoint_text(diag))
# ------------------------------------------------------------ optimal convex synthesis
def _synthesis_plant(diag: Mapping[str, Any], observer: bool) -> str:
    dom = diag.get("time_domain") or (diag.get("synthesis") or {}).get("domain") or "continuous"
    lhs = r"x(k+1)" if dom == "discrete" else r"\dot x"
    if observer:
        return (rf"For ${lhs} = A x + B u + B_w w$, $y = C x + D_v v$ and the observer error "
                r"$e = x - \hat x$ with gain $L$ (error matrix $A - LC$, performance $z = C_z e$)")
    return (rf"For ${lhs} = A x + B_w w + B u$, $z = C_z x + D_{{zu}} u$ and the state feedback "
            r"$u = -Kx$")


def _synthesis_numbers(diag: Mapping[str, Any]) -> str:
    syn = diag.get("synthesis") or {}
    parts = []
    for key, label in (("h2_bound", r"\|T_{zw}\|_2 \le"), ("gamma", r"\|T_{zw}\|_\infty \le")):
        v = syn.get(key)
        if _is_number(v):
            parts.append(rf"${label} {format_number(v)}$")
    for key, label in (("achieved_h2", r"\|T_{zw}\|_2"), ("achieved_hinf", r"\|T_{zw}\|_\infty")):
        v = syn.get(key)
        if isinstance(v, list) and v and _is_number(v[0]):
            parts.append(rf"recomputed ${label} = {format_number(v[0])}$")
    dom = diag.get("time_domain")
    text = (" (" + escape_latex(str(dom)) + " time)") if dom else ""
    return text + (": " + ", ".join(parts) if parts else "") + "."


def _h2_statement(diag: Mapping[str, Any], observer: bool) -> Tex:
    g = "L^\\top" if observer else "K"
    if diag.get("route") == "riccati":
        what = "steady Kalman filter" if observer else "LQR"
        weights = (r"the noise covariances $B_w B_w^\top$ (process) and $D_v D_v^\top$ (measurement)"
                   if observer else r"the weights $C_z^\top C_z$, $D_{zu}^\top D_{zu}$")
        return Tex(_synthesis_plant(diag, observer)
                   + rf", minimise $\|T_{{zw}}\|_2$: the {what} gain from the algebraic Riccati equation "
                   rf"with {weights} (the H2 LMI has the same optimum; "
                   r"the gain is re-checked by the Gramian)" + _synthesis_numbers(diag))
    text = (_synthesis_plant(diag, observer)
            + rf", minimise $\operatorname{{tr}} W$ over $X \succ 0$, $Y = {g} X$, $W$ with the H2 LMIs "
            r"(Gramian bound $X$, $\|T_{zw}\|_2^2 < \operatorname{tr} W$)"
            + (r" of the dual pair $(A^\top, C^\top)$" if observer else "")
            + r"; the optimum equals the " + ("steady Kalman filter" if observer else "LQR")
            + r" Riccati solution for the same weights" + _synthesis_numbers(diag))
    return Tex(text)


def _hinf_statement(diag: Mapping[str, Any], observer: bool) -> Tex:
    g = "L^\\top" if observer else "K"
    if diag.get("route") == "riccati":
        text = (_synthesis_plant(diag, observer)
                + r", minimise $\gamma = \|T_{zw}\|_\infty$ (the $L_2$ gain from the disturbances to $z$) "
                r"by bisection on $\gamma$ over the game algebraic Riccati equation"
                + (r" of the dual pair $(A^\top, C^\top)$" if observer else "")
                + r"; a $\gamma$ counts as reached only when its gain passes the Hamiltonian norm test")
        backoff = (diag.get("synthesis") or {}).get("scaling", {}).get("backoff")
        if _is_number(backoff) and backoff > 0:
            text += rf"; the gain is the one at $\gamma = (1 + {format_number(backoff)})\gamma^\star$"
        return Tex(text + _synthesis_numbers(diag))
    text = (_synthesis_plant(diag, observer)
            + rf", minimise $\gamma$ over $X \succ 0$, $Y = {g} X$ with the bounded-real-lemma LMI "
            r"($\|T_{zw}\|_\infty < \gamma$: the $L_2$ gain from the disturbances to $z$)"
            + (r" of the dual pair $(A^\top, C^\top)$" if observer else ""))
    backoff = (diag.get("synthesis") or {}).get("scaling", {}).get("backoff")
    if _is_number(backoff) and backoff > 0:
        text += rf", then keep $\gamma \le (1 + {format_number(backoff)})\gamma^\star$ and maximise the LMI margin"
    return Tex(text + _synthesis_numbers(diag))


def h2_state_feedback_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``h2_state_feedback`` solves, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _h2_statement(diag, observer=False)


def h2_observer_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``h2_observer`` solves, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _h2_statement(diag, observer=True)


def hinf_state_feedback_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``hinf_state_feedback`` solves, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _hinf_statement(diag, observer=False)


def hinf_observer_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``hinf_observer`` solves, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return _hinf_statement(diag, observer=True)


def multiobjective_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``multiobjective`` solves, with its declared conservatism.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    observer = diag.get("target") == "observer"
    syn = diag.get("synthesis") or {}
    objective = syn.get("objective", "hinf")
    goal = r"\gamma" if objective == "hinf" else r"\operatorname{tr} W"
    text = (_synthesis_plant(diag, observer)
            + rf", minimise ${goal}$ subject to the H2 and/or bounded-real-lemma LMIs and the "
            r"Chilali--Gahinet region LMI $L_D \otimes X + M_D \otimes (AX - BY) + M_D^\top \otimes "
            r"(AX - BY)^\top \prec 0$, all with ONE Lyapunov matrix $X$ (msfsyn-style)")
    region = (syn.get("region") or {}).get("description")
    if region:
        text += r"; region $D$: " + escape_latex(region)
    text += _synthesis_numbers(diag)
    text += (r" Conservatism: the common $X$ makes the bounds guaranteed but possibly pessimistic "
             r"(each objective alone may need another matrix); the achieved norms are recomputed "
             r"from the closed loop.")
    return Tex(text)


__all__ += ["h2_state_feedback_statement", "h2_observer_statement", "hinf_state_feedback_statement",
            "hinf_observer_statement", "multiobjective_statement"]
