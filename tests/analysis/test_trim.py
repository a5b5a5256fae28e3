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
