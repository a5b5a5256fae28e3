"""Region sampling of a plant's operating region."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.analysis.region import region_points
from tanksynth.plants import three_tank


@pytest.fixture(scope="module")
def tank():
    return three_tank(outputs="all")


def test_region_points_respect_orderings(tank):
    pts = region_points(tank, per_axis=7, samples=50, seed=1)
    assert np.all(pts[:, 0] > pts[:, 2]) and np.all(pts[:, 2] > pts[:, 1])
    assert np.all(pts >= 0) and np.all(pts <= 0.62)
