"""Seed 001 (three-tank quasi-LPV model, eq. 7-10): observability determinant and conditions.

A(z1, z2, z3) of eq. (10) is first checked against the nonlinear three-tank model
(A(z(x)) x == f(x, 0)); then the observability matrix for C = [1 0 0] and for
C = [1 0 0; 0 1 0] is derived with `symbolic_observability` and compared with
the printed determinant and claims. Disagreements are asserted as errata.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from tanksynth.analysis.rank import observability_rank, symbolic_observability
from tanksynth.papers import seed001 as paper
from tanksynth.plants import three_tank

(z1, z2, z3), (l1, l2, l3), (g1, g2, g3) = paper.symbols()
LAM = (l1, l2, l3)
GAM = (g1, g2, g3)
PAPER = {**dict(zip(LAM, map(sp.nsimplify, paper.LAMBDA))),
         **dict(zip(GAM, map(sp.nsimplify, paper.GAMMA)))}
A_eq10 = paper.A_eq10

C1 = sp.Matrix([[1, 0, 0]])
C12 = sp.Matrix([[1, 0, 0], [0, 1, 0]])

PRINTED_DET = paper.det_O1()
DERIVED_DET = z1**2 * ((l2 - l3) * (g3 * l2 - g2 * l3) * z3 + l2 * l3 * z2)


# ------------------------------------------------------ A(z) against the model
@pytest.mark.parametrize("lam,gam", [
    (paper.LAMBDA, paper.GAMMA),                  # the paper's simulation choice
    ((1.3, -0.4, 2.2), (0.9, 1.7, -0.6)),         # arbitrary
])
def test_quasi_lpv_matrix_reproduces_the_model(lam, gam):
    S, Sn, a1, a2, a3, g = 0.0154, 5e-5, 0.46, 0.6, 0.48, paper.G
    plant = three_tank().with_parameters({"A": S, "Phi": Sn, "mu13": a1, "mu32": a3, "mu20": a2,
                                           "g": g})
    rng = np.random.default_rng(1)
    X = rng.uniform(0.05, 0.6, size=(60, 3))        # every flow direction occurs
    lam, gam = np.array(lam), np.array(gam)
    X = X[(np.abs(X @ lam) > 1e-3) & (np.abs(X @ gam) > 1e-3)]
    assert len(X) > 30
    f = plant.compiled.rhs(X, np.zeros((len(X), 2)))
    subs_par = dict(zip(LAM + GAM, [*lam, *gam]))
    An = sp.lambdify((z1, z2, z3), A_eq10().xreplace(subs_par), "numpy")
    orders = set()
    for x, fx in zip(X, f):
        x1, x2, x3 = x
        W13 = a1 * Sn / S * np.sign(x1 - x3)
        W32 = a3 * Sn / S * np.sign(x3 - x2)
        Z1 = W13 * np.sqrt(2 * g * abs(x1 - x3)) / (lam @ x)
        Z2 = a2 * Sn / S * np.sqrt(2 * g) / np.sqrt(x2)
        Z3 = W32 * np.sqrt(2 * g * abs(x3 - x2)) / (gam @ x)
        np.testing.assert_allclose(np.asarray(An(Z1, Z2, Z3), dtype=float) @ x, fx, rtol=1e-10,
                                   atol=1e-14)
        orders.add((x1 > x3, x3 > x2))
    assert len(orders) == 4


# ------------------------------------------------------------ one output: x1
@pytest.fixture(scope="module")
def single():
    return symbolic_observability(A_eq10(), C1, variables=(z1, z2, z3))


def test_observability_matrix_rows_match_print(single):
    """The printed O1 (rows C, CA, CA^2 with (*)1..(*)3) is right; only its det is not."""
    O = single.matrix
    assert (O - paper.O1()).applyfunc(sp.expand) == sp.zeros(3, 3)


def test_determinant_single_output(single):
    assert sp.expand(single.determinant - DERIVED_DET) == 0
    assert sp.expand(single.matrix.det() - DERIVED_DET) == 0
    # factors: z1 and the bracket
    assert z1 in single.factors
    assert len(single.factors) == 2


def test_printed_determinant_erratum(single):
    """Printed det(O1) has the wrong sign on the lambda2 lambda3 z1^2 z2 term."""
    diff = sp.expand(single.determinant - PRINTED_DET)
    assert diff != 0
    assert sp.expand(diff - 2 * l2 * l3 * z1**2 * z2) == 0


def test_degenerate_parameter_sets_single_output(single):
    found = {frozenset(d.items()) for d in single.degenerate_parameters}
    assert found == {
        frozenset({(l2, 0), (l3, 0)}),
        frozenset({(l2, 0), (g2, 0)}),
        frozenset({(l3, 0), (g3, 0)}),
    }
    # each set really kills the determinant identically ...
    for d in single.degenerate_parameters:
        assert sp.expand(DERIVED_DET.xreplace(d)) == 0


def test_paper_claim_rank_iff_lambda2_lambda3_nonzero_is_wrong(single):
    """Paper: rank 3 iff lambda3 != 0 and lambda2 != 0. Counterexample: lambda2 = 0."""
    claimed = {frozenset((sp.Symbol(k), v) for k, v in d.items()) for d in paper.RANK_CLAIM}
    found = {frozenset(d.items()) for d in single.degenerate_parameters}
    assert claimed == {frozenset({(l2, 0)}), frozenset({(l3, 0)})} and not claimed <= found
    values = {l1: 1, l2: 0, l3: 2, g1: 0, g2: 1, g3: -1}
    det = sp.expand(single.determinant.xreplace(values))
    assert det == 4 * z1**2 * z3                       # gamma2 lambda3^2 z1^2 z3: not identically 0
    An = np.array(A_eq10().xreplace(values).xreplace({z1: 0.7, z2: 1.3, z3: 0.4}), dtype=float)
    r = observability_rank(An, np.array([[1.0, 0, 0]]))
    assert r.rank == 3 and r.full
    # whereas with lambda2 = 0 and gamma2 = 0 the rank really drops
    values2 = {l1: 1, l2: 0, l3: 2, g1: 0, g2: 0, g3: -1}
    An2 = np.array(A_eq10().xreplace(values2).xreplace({z1: 0.7, z2: 1.3, z3: 0.4}), dtype=float)
    assert observability_rank(An2, np.array([[1.0, 0, 0]])).rank == 2


def test_paper_example_determinant(single):
    det = sp.expand(single.determinant.xreplace(PAPER))
    assert sp.expand(det - z1**2 * (-552 * z3 + 85 * z2)) == 0
    # the printed formula would give z1^2 (-552 z3 - 85 z2)
    assert sp.expand(PRINTED_DET.xreplace(PAPER) - z1**2 * (-552 * z3 - 85 * z2)) == 0


# ---------------------------------------------------------- two outputs: x1, x2
@pytest.fixture(scope="module")
def double():
    return symbolic_observability(A_eq10(), C12, variables=(z1, z2, z3))


def test_two_outputs_degenerate_set(double):
    """Paper: avoid lambda3 = gamma3 = 0 -- confirmed, and that is the only such set."""
    assert [dict(d) for d in double.degenerate_parameters] == [{l3: 0, g3: 0}]
    assert [{sp.Symbol(k): v for k, v in d.items()} for d in paper.TWO_OUTPUT_CLAIM] == [{l3: 0, g3: 0}]
    O = double.matrix
    assert O.shape == (6, 3)
    assert O.xreplace({l3: 0, g3: 0}).rank() == 2
    # generic parameters: full rank
    assert O.xreplace(PAPER).xreplace({z1: 1, z2: 2, z3: 3}).rank() == 3
    # lambda3 = 0 alone or gamma3 = 0 alone keeps the rank
    assert O.xreplace({**PAPER, l3: 0}).xreplace({z1: 1, z2: 2, z3: 3}).rank() == 3
    assert O.xreplace({**PAPER, g3: 0}).xreplace({z1: 1, z2: 2, z3: 3}).rank() == 3


def test_two_outputs_printed_matrix_errata(double):
    """The printed O_{1,2} has typos in rows 3, 5 and 6 (recorded as errata)."""
    O = double.matrix
    derived_rows = [O[i, :] for i in range(6)]
    printed = paper.O12_entries()
    # row 3 printed as [-l1 z1, -l2 z2, -l3 z1]: the middle entry should be -l2 z1
    assert sp.expand(derived_rows[2][1] + l2 * z1) == 0
    assert sp.expand(derived_rows[2][1] - printed[3, 2]) != 0
    # (5,1) printed l1 z1^2 (l1 - l3) + g1 l3 z1 z3: misses -g1 l2 z1 z3
    assert sp.expand(derived_rows[4][0] - printed[5, 1] + g1 * l2 * z1 * z3) == 0
    # (5,2), (5,3) as printed are right
    assert sp.expand(derived_rows[4][1] - printed[5, 2]) == 0
    assert sp.expand(derived_rows[4][2] - printed[5, 3]) == 0
    # (6,1) printed l1 z1 z3 (g3 - g1) - g1 z3 [z2 - z3 (g3 - g2)]: sign of (g3 - g2) is wrong
    assert sp.expand(derived_rows[5][0] - printed[6, 1]) != 0
    assert sp.expand(derived_rows[5][0] - (l1 * z1 * z3 * (g3 - g1) - g1 * z3 * (z2 - z3 * (g2 - g3)))) == 0
    # (6,2) printed (g2 z3 - z2)^2 - g2 g3 z3^2: misses l2 z1 z3 (g3 - g1)
    assert sp.expand(derived_rows[5][1] - printed[6, 2] - l2 * z1 * z3 * (g3 - g1)) == 0
    # (6,3) as printed is right
    assert sp.expand(derived_rows[5][2] - printed[6, 3]) == 0
