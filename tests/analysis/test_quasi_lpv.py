"""Quasi-LPV form and operating domain of the Takagi-Sugeno rewriting (seed 001 eq. 7-11)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from tanksynth.papers import seed001
from tanksynth.analysis.quasi_lpv import domain_from_plant, quasi_lpv
from tanksynth.errors import DimensionError, RegionError, SpecError
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


# ---------------------------------------------------------------------- domain
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


def test_domain_samples_and_lp_ranges_are_cached_and_clearable():
    import numpy as np

    from tanksynth.analysis import quasi_lpv as ql

    dom = ql.Domain(np.array([0.0, 1.0]), np.array([1.0, 3.0]), np.array([[1.0, -1.0]]),
                    np.array([-2.5]), ("a", "b"))
    ql.clear_cache()
    first = dom.sample(500, seed=3)
    first[:] = -1.0                                   # the caller's copy, not the cache
    again = dom.sample(500, seed=3)
    assert np.all(dom.contains(again)) and not np.any(again == -1.0)
    assert again.shape == (500, 2)
    lo, hi = dom.linear_range([1.0, 1.0])
    # a - b >= -2.5 on [0, 1] x [1, 3]: a + b spans [1, 4] (the LP answer, checked by hand)
    assert abs(lo - 1.0) < 1e-9 and abs(hi - 4.0) < 1e-9
    assert dom.linear_range(np.array([1.0, 1.0])) == (lo, hi)
    assert ql.clear_cache() >= 2
    assert np.array_equal(dom.sample(500, seed=3), again)   # recomputed: same seeded draw


def test_atom_values_warn_when_a_state_leaves_the_premises_domain(qlpv):
    """A real state with a negative level (the square root undefined) is reported, once per call
    with the count; inside the domain nothing is said."""
    import warnings

    from tanksynth.errors import TanksynthWarning

    with warnings.catch_warnings():
        warnings.simplefilter("error", TanksynthWarning)
        vals = qlpv.atom_values(np.array([[0.4, 0.2, 0.3], [0.1, 0.6, 0.05]]))
    assert np.all(np.isfinite(vals))
    with pytest.warns(TanksynthWarning, match=r"undefined \(NaN\) at 1 of 2 point\(s\), first at "
                                              r"h1 = 0.4, h2 = -0.01"):
        vals = qlpv.atom_values(np.array([[0.4, 0.2, 0.3], [0.4, -0.01, 0.3]]))
    assert np.all(np.isfinite(vals[0])) and not np.all(np.isfinite(vals[1]))


# ------------------------------------------------------------------ issue 15
def test_form_evaluator_matches_one_lambdify_per_expression():
    """Expressions sharing a form (one tank type) are compiled once; each value equals the
    expression's own lambdified value."""
    from tanksynth.analysis.quasi_lpv import FormEvaluator
    h = sp.symbols("h1:7", positive=True)
    exprs = [3 * sp.sqrt(h[0]), 3 * sp.sqrt(h[2]), sp.sqrt(sp.Abs(h[1] - h[3])) / h[1],
             sp.sqrt(sp.Abs(h[4] - h[5])) / h[4], 2 * h[5] ** 2 + h[0], sp.Integer(2) * h[3]]
    ev = FormEvaluator(exprs, h)
    assert len(ev._groups) == 4
    X = np.random.default_rng(1).uniform(0.1, 2.0, size=(40, 6))
    got = ev(X)
    for k, e in enumerate(exprs):
        ref = sp.lambdify([h], e, "numpy")(X.T)
        np.testing.assert_allclose(got[:, k], np.broadcast_to(ref, (40,)), rtol=1e-15)
    # constant expressions (a form without arguments) broadcast to every point
    const = FormEvaluator([sp.Integer(5), 3 * sp.sqrt(h[0]), sp.Rational(1, 3)], h)(X)
    np.testing.assert_array_equal(const[:, [0, 2]], np.tile([5.0, 1.0 / 3.0], (40, 1)))
    np.testing.assert_allclose(const[:, 1], 3 * np.sqrt(X[:, 0]), rtol=1e-15)
    with pytest.raises(Exception, match="other than the states"):
        FormEvaluator([h[0] * sp.Symbol("k")], h)


def test_box_linear_range_matches_linprog():
    """On a box (no orderings) the range of w . x is in closed form; scipy's LP agrees."""
    import scipy.optimize as sopt

    from tanksynth.analysis.quasi_lpv import Domain
    lo, hi = np.array([0.1, -2.0, 0.0]), np.array([0.7, 3.0, 5.0])
    dom = Domain(lo, hi, np.zeros((0, 3)), np.zeros(0), ("a", "b", "c"))
    for w in (np.array([1.0, -2.0, 0.5]), np.array([0.0, 0.0, -1.0])):
        bounds = list(zip(lo, hi))
        ref = (sopt.linprog(w, bounds=bounds).fun, -sopt.linprog(-w, bounds=bounds).fun)
        assert dom.linear_range(w) == pytest.approx(ref, rel=1e-12, abs=1e-12)
