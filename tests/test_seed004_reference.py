"""Seed 004 (linear hydraulic model with a tank-2 leak): Q_O, Q_C, transfer functions, PBH.

The plant is `hydraulic_fault` (psi = (2, 1, 2), delta = (1, 1.5, 1)). The
printed Q_C(H), Q_O(H), their faulty versions and both transfer functions
are derived here from the model and checked entry by entry.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from tanksynth.analysis.linearize import linearize, symbolic_jacobians
from tanksynth.plants import hydraulic_fault
from tanksynth.analysis.rank import (controllability_matrix, controllability_rank,
                                   observability_matrix, observability_rank, pbh_test,
                                   symbolic_observability)

DELTA_BAR = 0.3

PRINTED_QC_H = np.array([[1, -0.5, 0.25], [0, 0.5, -1.00], [0, 0.0, 0.75]])
PRINTED_QO_H = np.array([[0.000, 0.000, 0.500], [0.000, 0.750, -0.250], [0.375, -1.500, 0.125]])


def printed_QC_v(d: float) -> np.ndarray:
    return np.array([[1, -0.5, 0.25], [0, 0.5, -1 - 0.5 * d], [0, 0.0, 0.75]])


def printed_QO_v(d: float) -> np.ndarray:
    return np.array([[0.000, 0.000, 0.500], [0.000, 0.750, -0.250], [0.375, -1.5 - 0.75 * d, 0.125]])


def _lin(plant):
    # linear plant: any operating point gives the same matrices
    return linearize(plant, [1.0, 1.0, 1.0], [0.0])


@pytest.fixture(scope="module")
def healthy():
    return _lin(hydraulic_fault())


@pytest.fixture(scope="module")
def faulty():
    return _lin(hydraulic_fault().with_parameters({"delta_bar": DELTA_BAR}))


def test_state_space_matches_print(healthy, faulty):
    np.testing.assert_allclose(healthy.F, [[-0.5, 0, 0], [0.5, -1.5, 0], [0, 1.5, -0.5]], atol=1e-15)
    np.testing.assert_allclose(healthy.B, [[1], [0], [0]], atol=1e-15)
    np.testing.assert_allclose(healthy.C, [[0, 0, 0.5]], atol=1e-15)
    np.testing.assert_allclose(faulty.F[1, 1], -1.5 - DELTA_BAR, atol=1e-15)
    # linear: the Jacobian does not depend on the point
    other = linearize(hydraulic_fault(), [0.3, 7.0, 2.0], [1.5])
    np.testing.assert_array_equal(other.F, healthy.F)


def test_controllability_matrix_healthy(healthy):
    Q = controllability_matrix(healthy.F, healthy.B)
    np.testing.assert_allclose(Q, PRINTED_QC_H, rtol=0, atol=1e-12)
    assert controllability_rank(healthy.F, healthy.B).rank == 3


def test_observability_matrix_healthy(healthy):
    Q = observability_matrix(healthy.F, healthy.C)
    np.testing.assert_allclose(Q, PRINTED_QO_H, rtol=0, atol=1e-12)
    assert observability_rank(healthy.F, healthy.C).rank == 3


def test_faulty_matrices(faulty):
    np.testing.assert_allclose(controllability_matrix(faulty.F, faulty.B), printed_QC_v(DELTA_BAR),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(observability_matrix(faulty.F, faulty.C), printed_QO_v(DELTA_BAR),
                               rtol=0, atol=1e-12)
    assert controllability_rank(faulty.F, faulty.B).full
    assert observability_rank(faulty.F, faulty.C).full


def test_faulty_formulas_symbolically():
    """Q_C(v), Q_O(v) and Phi_v(s) hold for every delta_bar, not only 0.3."""
    plant = hydraulic_fault()
    F, B, C = symbolic_jacobians(plant)
    db = plant.p["delta_bar"]
    values = {k: v for k, v in plant.parameter_values.items() if k != db}
    F, B, C = (M.xreplace(values) for M in (F, B, C))
    QC = sp.Matrix.hstack(B, F * B, F * F * B)
    QO = sp.Matrix.vstack(C, C * F, C * F * F)
    h = sp.Rational(1, 2)
    assert (QC - sp.Matrix([[1, -h, h / 2], [0, h, -1 - h * db], [0, 0, sp.Rational(3, 4)]])).applyfunc(sp.expand) == sp.zeros(3, 3)
    assert (QO - sp.Matrix([[0, 0, h], [0, sp.Rational(3, 4), -h / 2],
                            [sp.Rational(3, 8), -sp.Rational(3, 2) - sp.Rational(3, 4) * db, h / 4]])
            ).applyfunc(sp.expand) == sp.zeros(3, 3)
    s = sp.Symbol("s")
    M = s * sp.eye(3) - F
    den = sp.expand(M.det())
    num = sp.expand((C * M.adjugate() * B)[0])
    assert num == sp.Rational(3, 8)
    assert sp.expand(den - (s**3 + (sp.Rational(5, 2) + db) * s**2 + (sp.Rational(7, 4) + db) * s
                            + sp.Rational(3, 8) + db / 4)) == 0
    assert sp.expand(den - (s + h)**2 * (s + sp.Rational(3, 2) + db)) == 0


def test_transfer_function_healthy():
    plant = hydraulic_fault()
    F, B, C = (M.xreplace(plant.parameter_values) for M in symbolic_jacobians(plant))
    s = sp.Symbol("s")
    M = s * sp.eye(3) - F
    G = sp.cancel((C * M.adjugate() * B)[0] / M.det())
    assert sp.simplify(G - sp.Rational(3, 8) / (s**3 + sp.Rational(5, 2) * s**2 + sp.Rational(7, 4) * s
                                                 + sp.Rational(3, 8))) == 0


def test_transfer_function_numeric(healthy, faulty):
    """Same via numpy: denominator poly(A), numerator from C adj(sI - A) B at 4 points."""
    for lin, d in ((healthy, 0.0), (faulty, DELTA_BAR)):
        den = np.poly(lin.F)
        np.testing.assert_allclose(den, [1, 2.5 + d, 1.75 + d, 0.375 + 0.25 * d], atol=1e-12)
        # numerator of a strictly proper 3rd-order system: C adj(sI-A) B = G(s) den(s)
        ss = np.array([0.7, 1.3, 2.9, -4.1])
        nums = [(lin.C @ np.linalg.solve(s * np.eye(3) - lin.F, lin.B))[0, 0] * np.polyval(den, s)
                for s in ss]
        np.testing.assert_allclose(np.polyfit(ss, nums, 3), [0, 0, 0, 0.375], atol=1e-10)


def test_pbh_healthy_and_degenerate_sensor(healthy):
    names = ["x1", "x2", "x3"]
    res = pbh_test(healthy.F, C=healthy.C, state_names=names)
    assert res.passed and res.modes == ()
    assert pbh_test(healthy.F, B=healthy.B, state_names=names).passed
    # measuring tank 1 only: tanks 2 and 3 are downstream and invisible
    bad = pbh_test(healthy.F, C=np.array([[0.5, 0, 0]]), state_names=names)
    assert not bad.passed
    eigs = sorted(round(m.eigenvalue.real, 9) for m in bad.modes)
    assert eigs == [-1.5, -0.5]
    by_eig = {round(m.eigenvalue.real, 9): m for m in bad.modes}
    # the -1.5 mode lives in x2 and x3 (eigenvector (0, 1, -1.5)); the repeated -0.5 has
    # an unobservable direction in x3 alone (x1's -0.5 direction is seen)
    assert set(by_eig[-1.5].states) == {"x2", "x3"}
    assert by_eig[-0.5].states == ("x3",)
    assert all(m.smallest_singular_value < 1e-9 for m in bad.modes)
    assert observability_rank(healthy.F, np.array([[0.5, 0, 0]])).rank == 1


def test_symbolic_observability_conditions():
    plant = hydraulic_fault()
    F, _, C = symbolic_jacobians(plant)
    res = symbolic_observability(F, C, variables=plant.x)
    p = plant.p
    expected = -p["delta1"] * p["delta2"]**2 / (p["psi1"] * p["psi2"]**2 * p["psi3"]**3)
    assert sp.simplify(res.determinant - expected) == 0
    # the rank drops exactly where delta1 or delta2 vanishes (delta_bar, delta3 play no role)
    assert set(res.factors) == {p["delta1"], p["delta2"]}
    # delta1, delta2 are declared > 0: no admissible parameter set makes the plant
    # unobservable, so nothing is reported as degenerate ...
    assert res.degenerate_parameters == ()
    # ... whereas with the positivity dropped, exactly {delta1 = 0} and {delta2 = 0} are
    free = {s: sp.Symbol(s.name, real=True) for s in (p["delta1"], p["delta2"])}
    res2 = symbolic_observability(F.xreplace(free), C, variables=plant.x)
    found = {frozenset((str(k), v) for k, v in d.items()) for d in res2.degenerate_parameters}
    assert found == {frozenset({("delta1", 0)}), frozenset({("delta2", 0)})}
