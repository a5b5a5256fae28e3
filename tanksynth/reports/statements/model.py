"""The ``model`` family's problem statement (``linearize``)."""

from __future__ import annotations

from tanksynth.reports.statements.common import problem_statement

__all__ = ["linearize_statement"]

linearize_statement = problem_statement(
    "linearize", __name__,
    r"First-order Taylor expansion of the smooth model at the operating point, "
    r"$F = \partial f/\partial x$, $B = \partial f/\partial u$, $C = \partial h/\partial x$ "
    r"at $(x_0, u_0)$ with the equilibrium input $u_0$ computed from the model; "
    r"exact zero-order-hold discretisation $A_d = e^{F t_s}$, "
    r"$B_d = \int_0^{t_s} e^{F\tau}B\,d\tau$.")
