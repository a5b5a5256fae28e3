"""The ``placement`` family (design): pole placement: exact, in LMI regions, by the canonical form
(``pole_placement``, ``lmi_placement``, ``canonical_observer``).
"""

__all__: list[str] = []
