"""Interval arithmetic on sympy expressions."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from tanksynth.analysis.interval import interval_evaluate
from tanksynth.errors import TanksynthError


def test_interval_evaluate_rules():
    x, y = sp.symbols("x y", real=True)
    lo = np.array([[-1.0, 1.0], [0.0, 2.0], [1.0, 4.0]])
    hi = np.array([[2.0, 2.0], [4.0, 3.0], [4.0, 9.0]])
    a, b = interval_evaluate(sp.Abs(x) * y, (x, y), lo, hi)
    np.testing.assert_allclose(a, [0, 0, 4])
    np.testing.assert_allclose(b, [4, 12, 36])
    a, b = interval_evaluate(1 / x, (x, y), lo, hi)
    assert a[0] == -np.inf and b[0] == np.inf and b[1] == np.inf and a[2] == 0.25
    a, b = interval_evaluate(sp.sqrt(y) - x ** 2 + sp.sign(x), (x, y), lo, hi)
    assert np.all(a <= b)
    np.testing.assert_allclose([a[2], b[2]], [2 - 16 + 1, 3 - 1 + 1])
    with pytest.raises(TanksynthError, match="does not support"):
        interval_evaluate(sp.sin(x), (x, y), lo, hi)
