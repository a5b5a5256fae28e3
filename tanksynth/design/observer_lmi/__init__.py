"""The ``observer_lmi`` family (design): the Takagi-Sugeno observer LMI of seed 001
(``ts_observer``).
"""

__all__: list[str] = []
