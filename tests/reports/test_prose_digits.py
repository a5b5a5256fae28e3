"""Lists of numbers in typeset details keep the digits that tell their entries apart (issue 30:
a bisection bracket [0.0200002085, 0.02000020852] printed as [0.02, 0.02])."""

from __future__ import annotations

import re

from tanksynth.reports.prose import distinct_digits, prose_latex


def _numbers(tex: str) -> list[float]:
    inner = re.search(r"\$\[(.*?)\]\$", tex).group(1)
    return [float(x) for x in re.split(r",\\allowbreak\\ ", inner)]


def test_a_bracket_prints_its_two_ends_apart():
    lo, hi = 0.0200002085, 0.02000020852
    tex = prose_latex(f"recomputed (Hamiltonian bisection, bracket [{lo:.10g}, {hi:.10g}]): 0.020000209")
    a, b = _numbers(tex)
    assert a != b and a <= lo * (1 + 1e-9) and b >= hi * (1 - 1e-9)


def test_lists_whose_entries_differ_early_keep_four_digits():
    assert _numbers(prose_latex("poles [0.8, 0.82, 0.84, 0.86]")) == [0.8, 0.82, 0.84, 0.86]
    assert distinct_digits([0.123456, 0.9]) == 4
    assert distinct_digits([1.0, 1.0]) == 4               # equal values: nothing to tell apart
    assert distinct_digits([0.066572611, 0.066572617]) == 7   # 0.06657261, 0.06657262
