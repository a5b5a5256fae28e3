"""Every value printed in a seed paper, and nothing else.

Imported only by `tanksynth.reports`, the tests, the notebooks and the benchmarks
(an import-linter contract checks it): general code never branches on a paper.
"""

from __future__ import annotations

__all__: list[str] = []
