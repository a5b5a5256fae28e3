"""Premise bounds of the Takagi-Sugeno model: interval enclosure or sampling (seed 001 eq. 13)."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.papers import seed001
from tanksynth.analysis.premise_bounds import premise_bounds
from tanksynth.analysis.quasi_lpv import domain_from_plant, quasi_lpv
from tanksynth.errors import SpecError
from tanksynth.plants import three_tank

PAPER = {"z1": list(seed001.LAMBDA), "z3": list(seed001.GAMMA)}
BOX = [(0.05, 0.62)] * 3


@pytest.fixture(scope="module")
def plant():
    # seed 001: g = 9.82 as printed; S, Sn, alpha_i (not printed) = DTS200 / CRAN values
    return three_tank("h1h2").with_parameters({"g": 9.82})


@pytest.fixture(scope="module")
def qlpv(plant):
    return quasi_lpv(plant, PAPER)


@pytest.fixture(scope="module")
def all_directions(plant):
    return domain_from_plant(plant, BOX, use_orderings=False)


# --------------------------------------------------------------------- bounds
def test_interval_bounds_enclose_dense_samples(qlpv, all_directions):
    b = premise_bounds(qlpv, all_directions, "interval")
    Z = qlpv.premise_values(all_directions.sample(100_000, seed=11))
    assert np.all(Z.min(axis=0) >= b.lower) and np.all(Z.max(axis=0) <= b.upper)
    # ... and are tight: within 1% of the range of the best inner values (samples, box
    # corners and branch-and-bound centres)
    span = b.upper - b.lower
    assert np.all(b.upper - b.sampled_upper <= 0.01 * span)
    assert np.all(b.sampled_lower - b.lower <= 0.01 * span)
    # plain random sampling misses the extreme of z1 (a corner, where lambda.x is smallest):
    # the reason to use interval arithmetic or an explicit margin
    assert b.upper[0] - Z[:, 0].max() > 0.05 * span[0]
    d = b.as_dict()
    assert d["method"] == "interval" and "guaranteed" in d["method_text"]
    assert d["weighted_sum_ranges"][0][0] > 0 > d["weighted_sum_ranges"][2][1]


def test_sampling_bounds_state_their_margin(qlpv, all_directions):
    b = premise_bounds(qlpv, all_directions, "sampling", margin=0.05, samples=3000)
    span = b.sampled_upper - b.sampled_lower
    np.testing.assert_allclose(b.upper, b.sampled_upper + 0.05 * span)
    assert "not guaranteed" in b.as_dict()["method_text"]


def test_vanishing_weighted_sum_is_refused(plant, all_directions):
    q = quasi_lpv(plant, {"z1": [1.0, -1.0, 0.0]})
    with pytest.raises(SpecError, match=r"z1 is unbounded.*contains 0"):
        premise_bounds(q, all_directions)
    # the paper's lambda vanishes inside R^3_+ when tank 3 is nearly empty (0.7 h1 = 5 h2 + 17 h3)
    low = domain_from_plant(plant, [(0.0, 0.62)] * 3, use_orderings=False)
    with pytest.raises(SpecError, match="z1 is unbounded"):
        premise_bounds(quasi_lpv(plant, PAPER), low)


def test_bad_bound_options(qlpv, all_directions):
    with pytest.raises(SpecError):
        premise_bounds(qlpv, all_directions, "guess")
    with pytest.raises(SpecError):
        premise_bounds(qlpv, all_directions, "sampling", margin=-1)
