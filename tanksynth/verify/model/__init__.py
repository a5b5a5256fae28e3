"""The ``model`` family (verdicts and campaign runners): linear models of the plant
(``linearize``).
"""

__all__: list[str] = []
