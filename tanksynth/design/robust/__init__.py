"""The ``robust`` family (design): polytopic robust state feedback and observers
(``robust_state_feedback``, ``robust_observer``).
"""

__all__: list[str] = []
