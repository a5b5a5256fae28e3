"""Takagi-Sugeno multiple model by exact sector rewriting (seed 001 eq. 12-17)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from tanksynth.papers import seed001
from tanksynth.analysis import takagi_sugeno as tsmod
from tanksynth.analysis.takagi_sugeno import (MAX_ENUMERATED_PREMISES, check_exactness,
                                              domain_from_plant, quasi_lpv, ts_model,
                                              vertex_observability)
from tanksynth.errors import TanksynthError
from tanksynth.plants import tank_network, three_tank

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


@pytest.fixture(scope="module")
def ts_all(qlpv, all_directions):
    return ts_model(qlpv, all_directions)


# ------------------------------------------------------------------ exactness
@pytest.mark.parametrize("orderings", [False, True])
@pytest.mark.parametrize("method", ["interval", "sampling"])
def test_exact_at_thousands_of_points(plant, qlpv, orderings, method):
    dom = domain_from_plant(plant, BOX, use_orderings=orderings, gap=0.01)
    ts = ts_model(qlpv, dom, method=method, samples=4000)
    rep = check_exactness(ts, plant, count=5000, seed=7)
    assert rep.points == 5000
    assert rep.max_relative_error <= 1e-10
    assert rep.min_membership >= 0.0
    assert rep.max_sum_deviation <= 1e-12
    assert rep.passed


def test_memberships_follow_table_I(ts_all):
    assert ts_all.sigmas == tuple(itertools.product((1, 2), repeat=3))
    assert ts_all.r == 8 and ts_all.A.shape == (8, 3, 3)
    np.testing.assert_allclose(ts_all.A0, ts_all.A.mean(axis=0))
    X = ts_all.domain.sample(50, 1)
    mu = ts_all.memberships(X)
    F1 = ts_all.partitions(X)
    np.testing.assert_allclose(mu[:, 0], F1[:, 0] * F1[:, 1] * F1[:, 2])
    np.testing.assert_allclose(mu[:, 7], (1 - F1[:, 0]) * (1 - F1[:, 1]) * (1 - F1[:, 2]))
    # vertex 1 uses the maxima of every premise, vertex 8 the minima
    np.testing.assert_allclose(ts_all.A[0], ts_all.qlpv.A_of(ts_all.bounds.upper))
    np.testing.assert_allclose(ts_all.A[7], ts_all.qlpv.A_of(ts_all.bounds.lower))


# -------------------------------------------------------------- observability
def test_paper_vertices_are_observable(ts_all):
    obs = vertex_observability(ts_all)
    assert obs.all_observable and obs.ranks == (3,) * 8
    assert obs.as_dict()["symbolic"] is not None


def test_single_output_needs_lambda2_and_lambda3(plant, all_directions):
    """Seed 001 II-C: with y = x1, the vertices are observable iff lambda2, lambda3 != 0."""
    p1 = three_tank("h1").with_parameters({"g": 9.82})
    good = ts_model(quasi_lpv(p1, PAPER), all_directions)
    assert vertex_observability(good).all_observable
    bad = ts_model(quasi_lpv(p1, {"z1": [1.0, 0.0, 0.0], "z3": [0.0, -3.0, -1.0]}), all_directions)
    obs = vertex_observability(bad)
    assert obs.unobservable == tuple(range(1, 9))
    assert obs.symbolic["determinant"] == "0"


# ------------------------------------------------------------- tank networks
def test_large_networks_are_not_enumerated():
    p = tank_network(N=16)
    q = quasi_lpv(p)
    assert q.p == 16 > MAX_ENUMERATED_PREMISES
    dom = domain_from_plant(p, [(1.0, 40.0)] * 16)
    ts = ts_model(q, dom, method="sampling", samples=2000)
    assert not ts.enumerated and ts.A is None and ts.r == 2 ** 16
    rep = check_exactness(ts, p, count=2000)
    assert rep.passed, rep
    np.testing.assert_allclose(ts.A0, q.A_of(0.5 * (ts.bounds.lower + ts.bounds.upper)))
    assert vertex_observability(ts, sample_vertices=8).all_observable
    with pytest.raises(TanksynthError):
        ts.memberships(dom.sample(3))


def test_module_exports():
    """The quasi-LPV form and the premise bounds stay importable from this module."""
    for name in tsmod.__all__:
        assert hasattr(tsmod, name)



def test_full_column_rank_C_skips_the_kalman_ranks_with_a_reason(ts_all):
    obs = vertex_observability(ts_all, C=np.eye(3))
    assert obs.all_observable and obs.reason and "full column rank" in obs.reason
    assert obs.ranks == (3,) * 8 and obs.conditions == ()
    assert obs.as_dict()["reason"] == obs.reason
    # a rank-deficient C still gets the Kalman test, checked with numpy's matrix_rank here
    C = np.array([[1.0, 0.0, 0.0]])
    obs2 = vertex_observability(ts_all, C=C, symbolic=False)
    assert obs2.reason is None and len(obs2.conditions) == 8
    for Ai, r in zip(ts_all.A, obs2.ranks):
        O = np.vstack([C @ np.linalg.matrix_power(Ai, k) for k in range(3)])
        assert r == np.linalg.matrix_rank(O)
