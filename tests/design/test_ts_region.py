"""Switch level and composite decay of the TS PDC certificates (tanksynth.design.takagi_sugeno.region)."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.design.takagi_sugeno.region import composite_decay, switch_level


def _min_level_on_boundary(P1, P2, c2, d, points=200_000):
    """min z' P1 z over the boundary of {(z - d)' P2 (z - d) <= c2} (2-D, dense parametrisation)."""
    lam, V = np.linalg.eigh(P2)
    t = np.linspace(0, 2 * np.pi, points)
    Z = d + (np.stack([np.cos(t), np.sin(t)], axis=1) * np.sqrt(c2 / lam)) @ V.T
    return float(np.min(np.einsum("mi,ij,mj->m", Z, P1, Z)))


def test_switch_level_of_circles_in_closed_form():
    # the unit ball about d = (0.5, 0) contains the ball of radius 0.5 about 0: gamma = 0.25
    assert switch_level(np.eye(2), 1.0, np.eye(2), 1.0, np.array([0.5, 0.0])) == pytest.approx(0.25, rel=1e-3)
    # concentric, the second larger: the whole first set fits
    assert switch_level(4 * np.eye(3), 1.0, np.eye(3), 1.0, np.zeros(3)) == 1.0
    # first centre outside the second ellipsoid: nothing is certified
    assert switch_level(np.eye(2), 1.0, np.eye(2), 1.0, np.array([1.2, 0.0])) == 0.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_switch_level_against_the_boundary_minimum(seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(2, 2))
    B = rng.normal(size=(2, 2))
    P1, P2 = A @ A.T + 0.5 * np.eye(2), B @ B.T + 0.5 * np.eye(2)
    c1, c2 = 1.3, 0.9
    d = rng.normal(size=2) * 0.2 * np.sqrt(c2 / np.linalg.eigvalsh(P2)[-1])
    assert d @ P2 @ d < c2
    expected = min(1.0, _min_level_on_boundary(P1, P2, c2, d) / c1)
    assert switch_level(P1, c1, P2, c2, d) == pytest.approx(expected, rel=2e-3)


def test_composite_decay_scalar_closed_form():
    """n = 1: W - 2 a D >= 0 <=> (ac - a)(ao - a) >= k^2 / (4 beta) with a below both rates."""
    ac, ao, k, beta = 0.3, 0.5, 0.4, 2.0
    a = composite_decay(np.eye(1), np.eye(1), np.array([[[k]]]), ac, np.eye(1), ao, beta)
    exact = ((ac + ao) - np.sqrt((ac - ao) ** 2 + k ** 2 / beta)) / 2
    assert a == pytest.approx(exact, rel=1e-10)
    # the smallest over the vertex gains
    a2 = composite_decay(np.eye(1), np.eye(1), np.array([[[k]], [[2 * k]]]), ac, np.eye(1), ao, beta)
    assert a2 == pytest.approx(((ac + ao) - np.sqrt((ac - ao) ** 2 + 4 * k ** 2 / beta)) / 2, rel=1e-10)
