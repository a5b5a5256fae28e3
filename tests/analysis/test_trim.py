"""Trim: levels for given pump flows (issue 12 item 10)."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.analysis import equilibrium_input, trim
from tanksynth.errors import DimensionError
from tanksynth.plants import three_tank


def test_trim_inverts_equilibrium_input():
    p = three_tank()
    u0 = equilibrium_input(p, [0.40, 0.20, 0.30]).u0
    t = trim(p, u0)
    assert t.converged and t.in_region
    assert np.allclose(t.x, [0.40, 0.20, 0.30], atol=1e-9)


def test_trim_against_torricelli_by_hand():
    """q1 = q2 = 4e-5 m^3/s: at steady state q13 = q1, q20 = q1 + q2, q32 = q13 (independent)."""
    p = three_tank()
    q1 = q2 = 4e-5
    k = 5e-5 * np.sqrt(2 * 9.81)
    h2 = ((q1 + q2) / (0.675 * k)) ** 2
    h3 = h2 + (q1 / (0.5 * k)) ** 2
    h1 = h3 + (q1 / (0.5 * k)) ** 2
    t = trim(p, [q1, q2])
    assert t.converged
    assert np.allclose(t.x, [h1, h2, h3], rtol=1e-9)


def test_trim_outside_the_region_is_not_converged():
    t = trim(three_tank(), [1.1e-4, 1.1e-4])       # the tanks would overflow
    assert not t.converged and not t.in_region and t.violations
    with pytest.raises(DimensionError):
        trim(three_tank(), [1e-5])


def test_balancing_levels_against_torricelli_by_hand():
    """x_op = (0.5, 0.15, 0.35) m is not an equilibrium (q13 != q32 into tank 3). Holding two levels,
    tank 3 balances when q13 = q32, i.e. (mu13 = mu32) h1 - h3 = h3 - h2: h3 = 0.325, h1 = 0.55 or
    h2 = 0.2 m; the pumps then are q1 = q13 and q2 = q20 - q32 (independent of the tool)."""
    from tanksynth.analysis.trim import balancing_hint, balancing_levels

    p = three_tank()
    x = np.array([0.50, 0.15, 0.35])
    fixes = {f.state: f for f in balancing_levels(p, x, tolerance=1e-12)}
    assert set(fixes) == {"h1", "h2", "h3"}
    expected = {"h3": 0.325, "h1": 0.55, "h2": 0.20}
    k = 5e-5 * np.sqrt(2 * 9.81)
    for name, value in expected.items():
        assert fixes[name].value == pytest.approx(value, abs=1e-9)
        h = x.copy()
        h["h1 h2 h3".split().index(name)] = value
        q13, q32, q20 = 0.5 * k * np.sqrt(h[0] - h[2]), 0.5 * k * np.sqrt(h[2] - h[1]), \
            0.675 * k * np.sqrt(h[1])
        assert np.allclose(fixes[name].u, [q13, q20 - q32], rtol=1e-7, atol=1e-12)
    # the smallest change relative to the range first
    assert balancing_hint(p, x, 1e-12).startswith("the plant balances with h3 = 0.325 m")


def test_balancing_levels_empty_when_no_single_level_can_balance():
    """x = (0.05, 0.6, 0.3) m with the orderings h1 > h3 > h2: tank 3 balances only with
    h1 - h3 = h3 - h2, which needs h1 > h2 (h3 alone cannot), h1 = 2 h3 - h2 = 0 (below h3) or
    h2 = 2 h3 - h1 = 0.55 (above h3): no single change is an equilibrium inside the region."""
    from tanksynth.analysis.trim import balancing_hint, balancing_levels

    p = three_tank()
    assert p.region.orderings and balancing_levels(p, [0.05, 0.60, 0.30], 1e-12) == []
    assert balancing_hint(p, [0.05, 0.60, 0.30], 1e-12) == ""
    with pytest.raises(DimensionError):
        balancing_levels(p, [0.1, 0.2], 1e-12)
