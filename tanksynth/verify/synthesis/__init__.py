"""The ``synthesis`` family (verdicts and campaign runners): H2 / H-infinity synthesis (``h2_*``,
``hinf_*``, ``multiobjective``).
"""

__all__: list[str] = []
