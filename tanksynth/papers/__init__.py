"""Every value printed in a seed paper, and nothing else.

One module per seed paper (`seed000` .. `seed004`): matrices, tables, printed gains
and poles, printed formulas (as functions that evaluate them exactly as printed),
printed detection times, and notes of what the paper printed wrong. The comparison
with what tanksynth derives lives in `tanksynth.reports` (the paper-vs-tool section).

Imported only by `tanksynth.reports`, the tests, the notebooks and the benchmarks
(an import-linter contract checks it): general code never branches on a paper.
"""

from __future__ import annotations

from tanksynth.papers import seed000, seed001, seed002, seed003, seed004

__all__ = ["seed000", "seed001", "seed002", "seed003", "seed004"]
