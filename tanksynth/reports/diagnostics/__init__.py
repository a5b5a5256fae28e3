"""What the report reads of an artefact's diagnostics, by name, one module per method family.

The design writes its diagnostics as a JSON tree (``"diagnostics"`` of the artefact); the
report reads that tree only through the accessors of these modules (``robustness_of(diag)``,
``certified_region_of(diag)`` ...), never by raw keys, so that each key the report depends on
is spelled once, next to the type it is read as.

Artefacts may be edited by hand between ``design`` and ``report``, so every accessor is
tolerant: a missing key, a section that is not a mapping, or a value of another type than
the design writes reads as *missing* (None, an empty tuple, False), never as an exception.
Numbers are kept as written (an ``int`` stays an ``int``: the report prints it so).

``common`` holds what several families read (the time domain, integral action, LMI region
descriptions); ``model``, ``placement``, ``observer_lmi``, ``takagi_sugeno``, ``robust``,
``synthesis`` and ``fault`` what their methods write. The remaining families' statements
read no diagnostics.
"""

__all__: list[str] = []
