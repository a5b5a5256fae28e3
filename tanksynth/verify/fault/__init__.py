"""The ``fault`` family (verdicts and campaign runners): observer-based fault detection
(``fault_detection``).
"""

__all__: list[str] = []
