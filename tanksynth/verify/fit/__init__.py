"""The ``fit`` family in ``tanksynth.verify``: grey-box fit of free plant parameters and initial
states to logged data (CasADi + IPOPT, multiple shooting) (``fit``).
"""

__all__: list[str] = []
