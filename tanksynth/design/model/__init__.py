"""The ``model`` family (design): linear models of the plant (``linearize``).
"""

__all__: list[str] = []
