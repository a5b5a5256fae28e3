"""The ``laws`` family (verdicts and campaign runners): nonlinear and sampled control laws
(``feedback_linearization``, ``integral_tracking``, ``inverse_dynamics``).
"""

__all__: list[str] = []
