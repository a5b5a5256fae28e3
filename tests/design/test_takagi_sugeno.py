"""Takagi-Sugeno design support: selection rules, Lipschitz bounds, weighting search (seed 001)."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.papers import seed001
from tanksynth.design.observer_lmi import weighting as tsmod
from tanksynth.analysis.takagi_sugeno import domain_from_plant, quasi_lpv, ts_model
from tanksynth.design.observer_lmi.weighting import (candidate_weights, lipschitz_bound, search_weightings,
                                            selection_rules)
from tanksynth.errors import SpecError
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
def ordered(plant):
    return domain_from_plant(plant, BOX, use_orderings=True, gap=0.1)


@pytest.fixture(scope="module")
def ts_all(qlpv, all_directions):
    return ts_model(qlpv, all_directions)


# ---------------------------------------------------------------------- rules
def test_selection_rules(plant):
    rules = selection_rules(quasi_lpv(plant, PAPER))
    assert rules.rule1_passed and rules.premise_count == 3
    assert rules.null_rows_B == (3,)          # tank 3 has no pump: structural, reported only
    assert rules.shared_premises == ("z1", "z3")
    assert rules.premise_states == 3 and rules.states_per_premise == (3, 1, 2)
    degenerate = selection_rules(quasi_lpv(plant, {"z1": [1.0, 0, 0], "z3": [0, 1.0, 0]}))
    assert degenerate.null_cols_A == (3,) and not degenerate.rule1_passed


# ------------------------------------------------------------------ Lipschitz
def test_not_lipschitz_when_levels_may_be_equal(ts_all):
    lb = lipschitz_bound(ts_all, "jacobian", "interval")
    assert lb.value == np.inf and "not Lipschitz" in lb.detail["text"]


@pytest.mark.slow
def test_lipschitz_bounds_on_an_ordered_region(qlpv, ordered):
    ts = ts_model(qlpv, ordered)
    sampled = lipschitz_bound(ts, "jacobian", "sampling", margin=0.0)
    guaranteed = lipschitz_bound(ts, "jacobian", "interval")
    eq27 = lipschitz_bound(ts, "eq27", samples=3000)
    assert 0 < sampled.value <= guaranteed.value < 1.5 * sampled.value
    assert eq27.value > guaranteed.value       # the paper's bound is the conservative one
    assert len(eq27.detail["tau"]) == 8 and eq27.detail["phi"] == pytest.approx(np.hypot(1.2e-4, 1.2e-4))
    # dense independent sampling never exceeds the guaranteed bound
    X = ordered.sample(20000, seed=5)
    from tanksynth.design.observer_lmi.weighting import _jacobian_exprs, _jacobian_function
    J = _jacobian_function(qlpv, _jacobian_exprs(qlpv))(X)
    assert np.max(np.linalg.norm(J - ts.A0, 2, axis=(1, 2))) <= guaranteed.value


def test_lipschitz_options(ts_all):
    with pytest.raises(SpecError):
        lipschitz_bound(ts_all, "euclid")
    with pytest.raises(SpecError):
        lipschitz_bound(ts_all, "jacobian", "guess")


def test_eq27_bound_needs_the_enumerated_vertices():
    """A 16-tank network (2^16 vertices, not enumerated) has no eq. (27) bound."""
    p = tank_network(N=16)
    q = quasi_lpv(p)
    dom = domain_from_plant(p, [(1.0, 40.0)] * 16)
    ts = ts_model(q, dom, method="sampling", samples=2000)
    with pytest.raises(SpecError, match="eq. \\(27\\)"):
        lipschitz_bound(ts, "eq27")


# ----------------------------------------------------------------------- search
def test_candidate_weights_up_to_scale():
    W = candidate_weights(3)
    assert W.shape == (13, 3)                  # (3^3 - 1) / 2 directions
    assert candidate_weights(2, (-1, 1)).shape == (2, 2)


def test_search_reports_what_it_searched(qlpv, ordered):
    natural = np.array([[-1.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, -1.0, 1.0]])   # h3-h1, h3-h2
    found = search_weightings(qlpv, ordered, values=(-1.0, 1.0), include=[qlpv.weights, natural],
                              samples=2000)
    d = found.as_dict()
    assert d["searched"]["premises_varied"] == ["z1", "z3"]
    assert d["searched"]["combinations"] == 4 * 4 + 2
    assert sum(d["outcomes"].values()) == 18
    assert {"unbounded", "ok"} <= set(d["outcomes"])
    assert found.best is not None and found.best["psi_max"] > 0
    assert all(c["psi_max"] <= found.best["psi_max"] for c in found.candidates if "psi_max" in c)
    # a certified weighting exists on this region: psi_max covers its Lipschitz constant
    assert found.best_certified is not None and found.best_certified["ratio"] >= 1.0


def test_module_exports():
    for name in tsmod.__all__:
        assert hasattr(tsmod, name)


# ------------------------------------------------------------- sampled norms (issue 15)
def test_blockwise_spectral_norms_equal_the_dense_norm():
    """`_spectral_norms` splits df/dx - A0 into the components of its pattern; the dense
    2-norm (numpy SVD of the whole n x n matrix) is the reference, on the tank network (2 x 2
    blocks) and on the three-tank (one coupled block)."""
    from tanksynth.design.observer_lmi.weighting import (_jacobian_exprs, _jacobian_parts,
                                                _spectral_norms)
    for plant, box in ((tank_network(N=12), [(1.0, 40.0)] * 12),
                       (three_tank("h1h2"), [(0.05, 0.62), (0.05, 0.62), (0.05, 0.62)])):
        q = quasi_lpv(plant)
        dom = domain_from_plant(plant, box)
        ts = ts_model(q, dom, method="sampling", samples=500)
        parts = _jacobian_parts(q, _jacobian_exprs(q))
        X = dom.sample(300, seed=3)
        norms = _spectral_norms(parts, ts.A0, parts.values(X))
        D = parts.dense(X) - ts.A0
        ok = np.all(np.isfinite(D), axis=(1, 2))
        assert ok.any()
        np.testing.assert_allclose(norms[ok], np.linalg.norm(D[ok], 2, axis=(1, 2)), rtol=1e-12)
        assert np.all(np.isnan(norms[~ok]))
    # a random pattern with 1 x k, 2 x k and 3 x 3 blocks, A0 with entries off the pattern
    rng = np.random.default_rng(0)
    n = 9
    base = np.zeros((n, n))
    rows, cols = np.array([0, 0, 1, 2, 3, 4, 5, 5, 6, 7, 8]), np.array([0, 1, 1, 3, 4, 2, 5, 6, 7, 8, 6])
    parts = tsmod._JacobianParts(base, rows, cols, None)
    A0 = np.zeros((n, n))
    A0[2, 2] = 0.5
    values = rng.normal(size=(50, len(rows)))
    dense = np.zeros((50, n, n))
    dense[:, rows, cols] = values
    np.testing.assert_allclose(_spectral_norms(parts, A0, values),
                               np.linalg.norm(dense - A0, 2, axis=(1, 2)), rtol=1e-12)
