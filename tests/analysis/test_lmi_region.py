"""LMI regions (Chilali-Gahinet): membership, stability domains, validation."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.analysis.lmi_region import LMIRegion, disk, half_plane, intersect, sector
from tanksynth.errors import SpecError


def test_region_membership():
    hp, dk, sc = half_plane(1.0), disk(-2.0, 1.5), sector(np.pi / 4)
    assert hp.contains(-1.5) and not hp.contains(-0.5) and not hp.contains(-1.0)
    assert dk.contains(-3.0 + 1.0j) and not dk.contains(0.0)
    assert sc.contains(-1.0 + 0.9j) and not sc.contains(-1.0 + 1.1j)
    both = hp & sc
    assert isinstance(both, LMIRegion) and both.order == 3
    assert both.contains(-2.0 + 1.0j) and not both.contains(-0.5) and not both.contains(-2 + 3j)
    assert intersect(hp, dk, sc).order == 5
    assert "Re z < -1" in both.describe()


def test_region_stability_domains():
    assert half_plane(0.0).stable_in("continuous") and not half_plane(-1.0).stable_in("continuous")
    assert disk(0.0, 0.9).stable_in("discrete") and not disk(0.5, 0.6).stable_in("discrete")
    assert not half_plane(1.0).stable_in("discrete")
    assert (half_plane(0.1) & disk(0.0, 0.95)).stable_in("discrete")


@pytest.mark.parametrize("make", [lambda: disk(0.0, -1.0), lambda: sector(2.0),
                                  lambda: half_plane(float("nan")), lambda: disk("a", 1.0),
                                  lambda: intersect()])
def test_bad_regions(make):
    with pytest.raises(SpecError):
        make()


def test_disk_descriptions_read_as_written_by_hand():
    assert disk(0.9, 0.08).describe() == "|z - 0.9| < 0.08"
    assert disk(0.0, 0.97).describe() == "|z| < 0.97"
    assert disk(-2.0, 1.5).describe() == "|z + 2| < 1.5"
