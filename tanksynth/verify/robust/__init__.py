"""The ``robust`` family (verdicts and campaign runners): polytopic robust state feedback and
observers (``robust_state_feedback``, ``robust_observer``).
"""

__all__: list[str] = []
