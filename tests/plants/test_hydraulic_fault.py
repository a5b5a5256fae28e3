"""Linear hydraulic fault model (seed 004): matrices and transfer functions."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from tanksynth.plants.hydraulic_fault import hydraulic_fault

A_PRINTED = np.array([[-0.5, 0.0, 0.0], [0.5, -1.5, 0.0], [0.0, 1.5, -0.5]])
B_PRINTED = np.array([[1.0], [0.0], [0.0]])
C_PRINTED = np.array([[0.0, 0.0, 0.5]])


def matrices(plant):
    x = np.array([[1.0, 2.0, 3.0]])
    u = np.array([[0.7]])
    jx, ju = plant.compiled.jacobians(x, u)
    C = np.asarray(plant.compiled.jac_h(x[0]))
    assert ju.shape == (1, 3, 1)
    return jx[0], ju[0], C


def transfer_function(A, B, C):
    """Denominator det(sI - A) and numerator C adj(sI - A) B, as coefficient arrays."""
    den = np.poly(A)
    # C adj(sI - A) B = det(sI - A) * C (sI - A)^{-1} B: fit the polynomial from samples
    s = np.array([0.3, 1.1, 2.0, 3.7])
    vals = [den_s * (C @ np.linalg.solve(si * np.eye(3) - A, B)).item()
            for si, den_s in zip(s, np.polyval(den, s))]
    num = np.polyfit(s, vals, 3)
    return num, den


def test_structure_and_units():
    plant = hydraulic_fault()
    assert (plant.n, plant.m, plant.q) == (3, 1, 1)
    assert [s.unit for s in plant.states] == ["1"] * 3
    assert [s.unit for s in plant.inputs] == ["1"]
    assert [s.unit for s in plant.outputs] == ["1"]
    v = {p.name: p.value for p in plant.parameters}
    assert v == {"psi1": 2.0, "psi2": 1.0, "psi3": 2.0, "delta1": 1.0, "delta2": 1.5,
                 "delta3": 1.0, "delta_bar": 0.0}
    assert all(p.unit == "1" for p in plant.parameters)
    assert plant.region.bounds == ((0.0, 10.0),) * 3
    assert any(a.kind == "reconstructed" and "x3/psi3" in a.text for a in plant.assumptions)
    # linear in x and u
    for row in plant.f_numeric:
        assert sp.Poly(row, *plant.x, *plant.u).total_degree() == 1


def test_healthy_matrices_match_seed():
    A, B, C = matrices(hydraulic_fault())
    np.testing.assert_allclose(A, A_PRINTED, atol=1e-15)
    np.testing.assert_allclose(B, B_PRINTED, atol=1e-15)
    np.testing.assert_allclose(C, C_PRINTED, atol=1e-15)


def test_rhs_matches_matrices_on_batch():
    plant = hydraulic_fault()
    rng = np.random.default_rng(0)
    x = rng.uniform(0, 10, size=(50, 3))
    u = rng.uniform(-1, 3, size=(50, 1))
    np.testing.assert_allclose(plant.compiled.rhs(x, u), x @ A_PRINTED.T + u @ B_PRINTED.T,
                               rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(plant.compiled.output(x), x @ C_PRINTED.T, rtol=1e-14)


def test_healthy_transfer_function():
    num, den = transfer_function(*matrices(hydraulic_fault()))
    np.testing.assert_allclose(den, [1.0, 2.5, 1.75, 0.375], atol=1e-12)
    np.testing.assert_allclose(num, [0.0, 0.0, 0.0, 0.375], atol=1e-9)
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(matrices(hydraulic_fault())[0]).real),
                               [-1.5, -0.5, -0.5], atol=1e-7)


@pytest.mark.parametrize("dbar", [0.2, 1.0, 3.5])
def test_faulty_system(dbar):
    plant = hydraulic_fault().with_parameters({"delta_bar": dbar})
    A, B, C = matrices(plant)
    expected = A_PRINTED.copy()
    expected[1, 1] -= dbar
    np.testing.assert_allclose(A, expected, atol=1e-14)
    num, den = transfer_function(A, B, C)
    np.testing.assert_allclose(den, [1.0, 2.5 + dbar, 1.75 + dbar, 0.375 + 0.25 * dbar],
                               atol=1e-12)
    np.testing.assert_allclose(num, [0.0, 0.0, 0.0, 0.375], atol=1e-9)
    # controllability / observability matrices of seed 004 eqs. (21b), (23b)
    Qc = np.hstack([B, A @ B, A @ A @ B])
    np.testing.assert_allclose(Qc, [[1, -0.5, 0.25], [0, 0.5, -1 - 0.5 * dbar], [0, 0, 0.75]],
                               atol=1e-14)
    Qo = np.vstack([C, C @ A, C @ A @ A])
    np.testing.assert_allclose(Qo, [[0, 0, 0.5], [0, 0.75, -0.25],
                                    [0.375, -1.5 - 0.75 * dbar, 0.125]], atol=1e-14)


def test_steady_state():
    """u = 2 gives x = (4, 4/3, 4), inside the region."""
    plant = hydraulic_fault()
    x = np.array([4.0, 4.0 / 3.0, 4.0])
    np.testing.assert_allclose(plant.compiled.rhs(x[None], np.array([[2.0]])), 0.0, atol=1e-14)
    plant.check_point(x)
