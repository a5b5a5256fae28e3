"""The ``laws`` family's problem statements: nonlinear control laws (``feedback_linearization``,
``integral_tracking``, ``inverse_dynamics``). Each states its law; none reads the diagnostics.
"""

from __future__ import annotations

from tanksynth.reports.statements.common import problem_statement

__all__ = ["feedback_linearization_statement", "integral_tracking_statement", "inverse_dynamics_statement"]

feedback_linearization_statement = problem_statement(
    "feedback_linearization", __name__,
    r"Exact input-output linearisation of $\dot x = f(x) + g(x)u$, $y = h(x)$: with relative "
    r"degrees $r_i$ and decoupling matrix $D(x) = [L_g L_f^{r_i-1} h_i]$ invertible on the "
    r"region, $u = D(x)^{-1}\big(v - [L_f^{r_i} h_i(x)]\big)$ gives $y_i^{(r_i)} = v_i$; the "
    r"outer loop $v$ places the poles of each chain, and the zero dynamics are checked stable.")

integral_tracking_statement = problem_statement(
    "integral_tracking", __name__,
    r"Sampled tracking with integral action about $(x_0, u_0)$: $u(k) = \mathrm{sat}\big(u_0 - "
    r"K_1 (x(k) - x_0) - K_2 z(k)\big)$, $z(k+1) = z(k) + t_s \big(y_r(k) - y_0 - C_1 (x(k) - "
    r"x_0)\big)$ (the measured outputs' error, $y_0 = h(x_0)$ with the sensors' offsets and "
    r"gains) plus anti-windup, with $[K_1\ K_2]$ placing the eigenvalues of the augmented pair "
    r"$\left(\begin{smallmatrix} A_d & 0 \\ -t_s C_1 & I\end{smallmatrix}\right)$, "
    r"$\left(\begin{smallmatrix} B_d \\ 0\end{smallmatrix}\right)$.")

inverse_dynamics_statement = problem_statement(
    "inverse_dynamics", __name__,
    r"Inverse dynamics of the pump-fed states $x_c$: impose $\dot x_{c,i} = C_i (x_{c,i}^{sp} - "
    r"x_{c,i})$, i.e. $u = G_c(\hat x)^{-1}\big(\mathrm{diag}(C)(x_c^{sp} - \hat x_c) - "
    r"f_{0,c}(\hat x)\big)$ saturated to the pump range, with the rates $C_i \ge 0$ minimising "
    r"the integral of squared errors of a servo scenario.")
