"""The ``takagi_sugeno`` family (verdicts and campaign runners): Takagi-Sugeno PDC controllers
(``ts_state_feedback``, ``ts_output_feedback``).
"""

__all__: list[str] = []
