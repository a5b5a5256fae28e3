"""Affine matrix expressions solved straight in Clarabel's conic form (robust LMIs)."""

from __future__ import annotations

import cvxpy as cp
import numpy as np
import pytest

from tanksynth.design import conic as rc
from tanksynth.design.robust.polytopic import robust_state_feedback
from tanksynth.analysis.lmi_region import region_from_parts


def test_expressions_evaluate_like_numpy():
    m = rc.Model()
    X = m.variable((3, 3), symmetric=True)
    Y = m.variable((2, 3))
    t = m.variable()
    rng = np.random.default_rng(0)
    A, B, L = rng.standard_normal((3, 3)), rng.standard_normal((3, 2)), rng.standard_normal((2, 2))
    Xv = rng.standard_normal((3, 3))
    Xv = Xv + Xv.T
    Yv, tv = rng.standard_normal((2, 3)), 0.7
    m.freeze()
    # variables in order: X's upper triangle column by column, Y row-major, t
    m.values = np.concatenate([[Xv[i, j] for j in range(3) for i in range(j + 1)], Yv.ravel(), [tv]])
    np.testing.assert_allclose(X.value, Xv)
    np.testing.assert_allclose(Y.value, Yv)
    assert t.value == tv
    AX = A @ X - B @ Y
    np.testing.assert_allclose(AX.value, A @ Xv - B @ Yv, rtol=1e-14)
    np.testing.assert_allclose(rc.kron(L, AX).value, np.kron(L, A @ Xv - B @ Yv), rtol=1e-14)
    blk = rc.bmat([[X, AX.T], [AX, -t * np.eye(3)]])
    np.testing.assert_allclose(blk.value, np.block([[Xv, (A @ Xv - B @ Yv).T],
                                                    [A @ Xv - B @ Yv, -tv * np.eye(3)]]), rtol=1e-14)
    np.testing.assert_allclose((0.5 * (AX + AX.T) / 2.0 + 1.0).value,
                               0.25 * (A @ Xv - B @ Yv + (A @ Xv - B @ Yv).T) + 1.0, rtol=1e-14)
    np.testing.assert_allclose(rc.reshape(t, (1, 1)).value, [[tv]])
    np.testing.assert_allclose(Y[1:2, :].value, Yv[1:2, :])
    with pytest.raises(TypeError):
        X @ X


def _lyapunov_margin_cvxpy(A, kappa):
    X, t = cp.Variable((len(A), len(A)), symmetric=True), cp.Variable()
    prob = cp.Problem(cp.Maximize(t), [A @ X + X @ A.T << -t * np.eye(len(A)), X >> np.eye(len(A)),
                                       X << kappa * np.eye(len(A)), t <= 10.0])
    prob.solve(solver="CLARABEL")
    return float(t.value)


def test_lmi_optimum_equals_a_hand_written_cvxpy_problem():
    rng = np.random.default_rng(3)
    for _ in range(5):
        A = rng.standard_normal((4, 4)) - 3.0 * np.eye(4)
        m = rc.Model()
        X, t = m.variable((4, 4), symmetric=True), m.variable()
        I = np.eye(4)
        prob = rc.Problem(rc.Maximize(t), [A @ X + X @ A.T << -t * I, X >> I, X << 50.0 * I,
                                            t <= 10.0])
        assert rc.solve_status(prob, "CLARABEL") == "optimal"
        ref = _lyapunov_margin_cvxpy(A, 50.0)
        assert abs(t.value - ref) <= 1e-6 * max(1.0, abs(ref))
        Xv = X.value
        assert np.max(np.linalg.eigvalsh(A @ Xv + Xv @ A.T)) <= -t.value * (1 - 1e-6)


def test_frobenius_norm_and_nonnegative_variable():
    m = rc.Model()
    Y, tau, r = m.variable((2, 2)), m.variable(nonneg=True), m.variable()
    C = np.array([[1.0, -2.0], [0.5, 3.0]])
    prob = rc.Problem(rc.Minimize(rc.norm(Y - C, "fro", epigraph=r)), [Y[0:1, 0:1] >= 2.0])
    assert rc.solve_status(prob, "CLARABEL") == "optimal"
    np.testing.assert_allclose(Y.value, [[2.0, -2.0], [0.5, 3.0]], atol=1e-6)
    prob = rc.Problem(rc.Minimize(tau), [tau >= -5.0])          # tau >= 0 binds, not -5
    assert rc.solve_status(prob, "CLARABEL") == "optimal" and abs(tau.value) <= 1e-7
    m2 = rc.Model()
    z = m2.variable()
    bad = rc.Problem(rc.Maximize(z), [z <= 1.0, z >= 2.0])
    assert rc.solve_status(bad, "CLARABEL").startswith("infeasible") and z.value is None


def test_robust_state_feedback_conic_route_meets_the_cvxpy_route():
    """Same problem through cvxpy (SCS) and straight into Clarabel: same optimal margin."""
    rng = np.random.default_rng(5)
    A = np.stack([np.array([[-1.0, 0.5], [0.0, -2.0]]) + 0.1 * rng.standard_normal((2, 2))
                  for _ in range(3)])
    B = np.stack([np.array([[0.0], [1.0]])] * 3)
    region = region_from_parts([("half_plane", 0.5)])
    a = robust_state_feedback(A, B, region, solver="CLARABEL")
    b = robust_state_feedback(A, B, region, solver="SCS")
    ta, tb = a.largest_margin, b.largest_margin
    assert abs(ta - tb) <= 1e-3 * abs(tb)                        # SCS: first-order accuracy
    for i in range(3):
        assert np.max(np.linalg.eigvals(A[i] - B[i] @ a.gain_matrix).real) < -0.5


def test_trace_and_a_feasibility_problem():
    """``trace`` (the H2 objective) and a constant objective (``Minimize(0)``: feasibility)."""
    m = rc.Model()
    W = m.variable((2, 2), symmetric=True)
    X = m.variable((2, 2), symmetric=True)
    m.freeze()
    Wv = np.array([[2.0, 0.5], [0.5, -1.0]])
    m.values = np.concatenate([[Wv[0, 0], Wv[0, 1], Wv[1, 1]], np.zeros(3)])
    assert rc.trace(W).value == pytest.approx(1.0, abs=1e-15)
    with pytest.raises(ValueError):
        rc.trace(W[0:1, :])
    # min trace W s.t. [[W, C], [C', I]] >= 0  <=>  W >= C C': optimum trace C C'
    C = np.array([[1.0, 2.0], [0.0, 3.0]])
    blk = rc.bmat([[W, C], [C.T, np.eye(2)]])
    prob = rc.Problem(rc.Minimize(rc.trace(W)), [blk >> 0])
    assert prob.solve() == pytest.approx(np.trace(C @ C.T), rel=1e-7)
    np.testing.assert_allclose(W.value, C @ C.T, atol=1e-6)
    # feasibility: X >= I and X <= 2 I is feasible, X >= 3 I and X <= 2 I is not
    assert rc.solve_status(rc.Problem(rc.Minimize(0), [X >> np.eye(2), X << 2 * np.eye(2)]),
                           "CLARABEL") == "optimal"
    assert np.all(np.linalg.eigvalsh(X.value) >= 1 - 1e-7)
    assert rc.solve_status(rc.Problem(rc.Minimize(0), [X >> 3 * np.eye(2), X << 2 * np.eye(2)]),
                           "CLARABEL") == "infeasible"
