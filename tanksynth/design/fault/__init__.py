"""The ``fault`` family (design): observer-based fault detection (``fault_detection``).
"""

__all__: list[str] = []
