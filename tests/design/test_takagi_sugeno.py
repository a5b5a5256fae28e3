"""Takagi-Sugeno multiple model by exact sector rewriting (seed 001 eq. 7-17)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import sympy as sp

from tanksynth.design import takagi_sugeno as tsmod
from tanksynth.analysis.interval import interval_evaluate
from tanksynth.analysis.takagi_sugeno import (MAX_ENUMERATED_PREMISES, check_exactness,
                                              domain_from_plant, premise_bounds, quasi_lpv,
                                              ts_model, vertex_observability)
from tanksynth.design.takagi_sugeno import (candidate_weights, lipschitz_bound, search_weightings,
                                            selection_rules)
from tanksynth.errors import DimensionError, RegionError, SpecError, TanksynthError
from tanksynth.plants import tank_network, three_tank

PAPER = {"z1": [-0.7, 5.0, 17.0], "z3": [0.0, -3.0, -1.0]}
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


# --------------------------------------------------------------- decomposition
def test_atoms_come_out_in_the_paper_order(qlpv):
    assert qlpv.p == 3
    assert qlpv.atom_states == ((0, 2), (1,), (1, 2))          # z1: T1-T3, z2: T2 out, z3: T3-T2
    np.testing.assert_array_equal(qlpv.incidence, [[-1, 0, 0], [0, -1, 1], [1, 0, -1]])
    np.testing.assert_array_equal(qlpv.A_lin, np.zeros((3, 3)))
    np.testing.assert_allclose(qlpv.B, [[1 / 0.0154, 0], [0, 1 / 0.0154], [0, 0]])
    np.testing.assert_array_equal(qlpv.C, [[1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(qlpv.weights[1], [0, 1, 0])  # default for a one-state atom


def test_symbolic_A_is_eq10(qlpv):
    """A(z) of the rewriting equals seed 001 eq. (10) with lambda, gamma as symbols."""
    A = qlpv.A_symbolic(symbolic_weights=True)
    z1, z2, z3 = qlpv.premise_symbols
    lam = [sp.Symbol(f"w1_{j}", real=True) for j in (1, 2, 3)]
    gam = [sp.Symbol(f"w3_{j}", real=True) for j in (1, 2, 3)]
    w2 = [sp.Symbol(f"w2_{j}", real=True) for j in (1, 2, 3)]
    eq10 = sp.Matrix([
        [-lam[0] * z1, -lam[1] * z1, -lam[2] * z1],
        [gam[0] * z3, gam[1] * z3 - z2, gam[2] * z3],
        [lam[0] * z1 - gam[0] * z3, lam[1] * z1 - gam[1] * z3, lam[2] * z1 - gam[2] * z3],
    ])
    A = A.xreplace({w2[0]: 0, w2[1]: 1, w2[2]: 0})
    assert sp.simplify(A - eq10) == sp.zeros(3, 3)


def test_premises_are_eq8(plant, qlpv):
    """z1 = W13 sqrt(2g|x1-x3|)/(lambda.x) etc. with the declared DTS200 values."""
    S, Sn, a1, a2, a3, g = 0.0154, 5e-5, 0.5, 0.675, 0.5, 9.82
    rng = np.random.default_rng(3)
    X = rng.uniform(0.05, 0.62, size=(200, 3))
    lam, gam = np.array(PAPER["z1"]), np.array(PAPER["z3"])
    x1, x2, x3 = X.T
    z1 = a1 * Sn / S * np.sign(x1 - x3) * np.sqrt(2 * g * abs(x1 - x3)) / (X @ lam)
    z2 = a2 * Sn / S * np.sqrt(2 * g) / np.sqrt(x2)
    z3 = a3 * Sn / S * np.sign(x3 - x2) * np.sqrt(2 * g * abs(x3 - x2)) / (X @ gam)
    np.testing.assert_allclose(qlpv.premise_values(X), np.column_stack([z1, z2, z3]), rtol=1e-12)


def test_weights_validation(plant):
    with pytest.raises(SpecError, match="unknown premise"):
        quasi_lpv(plant, {"z9": [1, 0, 0]})
    with pytest.raises(SpecError, match="expected 3 numbers"):
        quasi_lpv(plant, {"z1": [1, 0]})
    with pytest.raises(SpecError, match="all zero"):
        quasi_lpv(plant, {"z1": [0, 0, 0]})
    with pytest.raises(DimensionError):
        quasi_lpv(plant, np.ones((2, 3)))


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
    from tanksynth.design.takagi_sugeno import _jacobian_exprs, _jacobian_function
    J = _jacobian_function(qlpv, _jacobian_exprs(qlpv))(X)
    assert np.max(np.linalg.norm(J - ts.A0, 2, axis=(1, 2))) <= guaranteed.value


def test_lipschitz_options(ts_all):
    with pytest.raises(SpecError):
        lipschitz_bound(ts_all, "euclid")
    with pytest.raises(SpecError):
        lipschitz_bound(ts_all, "jacobian", "guess")


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


def test_domain_validation(plant):
    with pytest.raises(SpecError):
        domain_from_plant(plant, [(0.5, 0.1)] * 3)
    with pytest.raises(DimensionError):
        domain_from_plant(plant, [(0.0, 1.0)] * 2)
    with pytest.raises(SpecError):
        domain_from_plant(plant, BOX, gap=-1.0)
    dom = domain_from_plant(plant, [(0.0, 0.1)] * 3, gap=0.2)     # h1 - h3 >= 0.2: empty
    with pytest.raises(RegionError):
        dom.sample(10)


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
    with pytest.raises(SpecError, match="eq. \\(27\\)"):
        lipschitz_bound(ts, "eq27")


def test_module_exports():
    for name in tsmod.__all__:
        assert hasattr(tsmod, name)
