"""Kalman, extended and unscented Kalman filters: linear-plant identities and the hybrid EKF."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import sympy as sp
from estimator_helpers import linear_data

from tanksynth.runtime.estimators import (ExtendedKalmanFilter, KalmanFilter, KalmanTuning,
                                         UKFTuning, UnscentedKalmanFilter, discrete_model,
                                         regularized_jacobian, steady_state_gain, ukf_weights)
from tanksynth.errors import SpecError
from tanksynth.plants.hybrid_three_tank import LPH, mode_vector_field

Q = np.diag([1e-3, 2e-3, 1e-3])
R = np.array([[1e-2]])
P0 = np.eye(3)


@pytest.fixture(scope="module")
def linear_run(fault_plant):
    tk = KalmanTuning(Q=Q, R=R, P0=P0, x0=[1.0, 1.0, 1.0], ts=0.1)
    kf = KalmanFilter(fault_plant, tk, backend="vm")
    U = np.where(np.arange(400) < 100, 2.0, 1.0)[:, None]
    X, Y, U = linear_data(kf.model, 400, Q, R, [4.0, 4 / 3, 4.0], seed=3, u=U)
    return tk, kf, X, Y, U


def test_linear_plant_gets_the_exact_zoh_model(fault_plant):
    model = discrete_model(fault_plant, 0.1)
    assert model.kind == "linear" and model.exact
    F = np.array([[-0.5, 0, 0], [0.5, -1.5, 0], [0, 1.5, -0.5]])
    np.testing.assert_allclose(model.Ad, sla.expm(F * 0.1), rtol=0, atol=1e-15)
    np.testing.assert_allclose(model.C, [[0, 0, 0.5]])


def test_kf_converges_to_the_dare_gain(linear_run):
    tk, kf, X, Y, U = linear_run
    K_ss, P_ss = steady_state_gain(kf.model, Q, R)
    # the DARE solution from scipy directly
    P = sla.solve_discrete_are(kf.model.Ad.T, kf.model.C.T, Q, R)
    np.testing.assert_allclose(P_ss, P)
    kf.reset()
    kf.run(Y, U)
    np.testing.assert_allclose(kf.gain, K_ss, rtol=0, atol=1e-8)
    # the predicted covariance converges to the DARE solution too
    Pp = kf.model.Ad @ kf.covariance @ kf.model.Ad.T + Q
    np.testing.assert_allclose(Pp, P_ss, rtol=0, atol=1e-8)


def test_ekf_and_ukf_equal_the_kf_on_a_linear_plant(fault_plant, linear_run):
    tk, kf, X, Y, U = linear_run
    kf.reset()
    x_kf = kf.run(Y, U)
    ekf = ExtendedKalmanFilter(fault_plant, tk, backend="vm")
    np.testing.assert_allclose(ekf.run(Y, U), x_kf, rtol=0, atol=1e-8)
    for alpha in (1.0, 1e-3):
        ukf = UnscentedKalmanFilter(fault_plant, UKFTuning(Q=Q, R=R, P0=P0, x0=tk.x0, ts=0.1,
                                                           alpha=alpha), backend="vm")
        np.testing.assert_allclose(ukf.run(Y, U), x_kf, rtol=0, atol=1e-8)
        np.testing.assert_allclose(ukf.covariance, kf.covariance, rtol=0, atol=1e-8)


def test_ukf_without_redraw_is_not_the_kf(fault_plant, linear_run):
    # seed 002 eq. 27 read literally (propagated sigma points): Q is missing from Pyy
    tk, kf, X, Y, U = linear_run
    kf.reset()
    x_kf = kf.run(Y[:50], U[:50])
    ukf = UnscentedKalmanFilter(fault_plant, UKFTuning(Q=Q, R=R, P0=P0, x0=tk.x0, ts=0.1,
                                                       alpha=1.0, redraw=False), backend="vm")
    assert np.max(np.abs(ukf.run(Y[:50], U[:50]) - x_kf)) > 1e-4


def test_ukf_weights_follow_seed_002():
    Wm, Wc, gamma = ukf_weights(3, 1e-3, 2.0, 0.0)
    lam = 1e-6 * 3 - 3
    assert Wm[0] == pytest.approx(lam / (3 + lam)) and Wc[0] == pytest.approx(lam / (3 + lam) + 3 - 1e-6)
    assert np.sum(Wm) == pytest.approx(1.0)
    assert gamma == pytest.approx(np.sqrt(3 + lam))


def test_kalman_filter_refuses_a_nonlinear_plant_without_operating_point(tank_plant):
    tk = KalmanTuning(Q=1e-8 * np.eye(3), R=1e-4 * np.eye(3), P0=np.eye(3), x0=[0.4, 0.2, 0.3],
                      ts=1.0)
    with pytest.raises(SpecError, match="operating_point"):
        KalmanFilter(tank_plant, tk)


def test_kf_at_an_operating_point_works_in_absolute_levels(tank_plant):
    from tanksynth.analysis.linearize import equilibrium_input

    x_op = np.array([0.40, 0.20, 0.30])
    u_op = equilibrium_input(tank_plant, x_op).u0
    tk = KalmanTuning(Q=1e-10 * np.eye(3), R=1e-6 * np.eye(3), P0=np.eye(3), x0=x_op, ts=1.0,
                      operating_point=(x_op, u_op))
    kf = KalmanFilter(tank_plant, tk)
    for _ in range(5):
        x = kf.step(x_op, u_op)
    np.testing.assert_allclose(x, x_op, atol=1e-12)       # the equilibrium is a fixed point


# ------------------------------------------------------------------ hybrid three-tank EKF
def test_regularised_jacobian_is_finite_at_zero_heads(hybrid_plant):
    model = discrete_model(hybrid_plant, 1.0)
    J = model._funcs()["J"]
    for x in ([0.3, 0.3, 0.3], [0.2, 0.2, 0.2], [0.0, 0.0, 0.0], [0.4, 0.3, 0.4]):
        value = np.asarray(J(x, [3e-5, 3e-5]))
        assert np.all(np.isfinite(value)), x
    # plain automatic differentiation is not finite there (the reason for the regularisation)
    raw = np.asarray(hybrid_plant.compiled.jac_x([0.3, 0.2, 0.2], [3e-5, 3e-5]))
    assert not np.all(np.isfinite(raw))


def test_regularised_derivative_matches_notes(hybrid_plant):
    J = regularized_jacobian(hybrid_plant, 1e-6)
    h1, h2, h3 = hybrid_plant.x
    pv = {s: float(v) for s, v in hybrid_plant.parameter_values.items()}
    A = np.pi * 0.15 ** 2 / 4
    k1 = 2.6363e-5
    point = {h1: 0.25, h2: 0.1, h3: 0.25}            # h1 = h3: zero head on link 1, below h0
    dQ1 = k1 * np.sqrt(2 * 9.81) / (2 * np.sqrt(1e-6))
    assert float(J[0, 0].subs(point).subs(pv)) == pytest.approx(-dQ1 / A, rel=1e-9)


def test_regularised_derivative_at_equal_heads_of_a_signed_link():
    """The three-tank link h2 - h3 is written sgn(h3 - h2) sqrt(2 g |h3 - h2|): its derivative is
    sign(-b) sign(b) / sqrt(|b|) = -1 / sqrt(|b|), not 0, at equal heads (the regularised value,
    continuous with the entries next to the surface)."""
    from tanksynth.plants import three_tank

    plant = three_tank()
    J = regularized_jacobian(plant, 1e-6)
    h1, h2, h3 = plant.x
    on = np.array(J.subs({h1: 0.4, h2: 0.3, h3: 0.3}), dtype=float)
    near = np.array(J.subs({h1: 0.4, h2: 0.3, h3: 0.3 + 1e-13}), dtype=float)
    assert abs(on[1, 2]) > 1.0                       # 3.6 1/s with eps = 1e-6 m
    np.testing.assert_allclose(on, near, rtol=1e-6)


@pytest.mark.parametrize("mode", [(0, 0, 0), (1, 1, 1), (1, 0, 1), (0, 1, 0), (1, 1, 0)])
def test_ekf_jacobian_is_the_mode_jacobian(hybrid_plant, mode):
    """Away from the surfaces the regularised Jacobian equals d f_mode/dx (seed 002 section 3)."""
    model = discrete_model(hybrid_plant, 1.0)
    J = model._funcs()["J"]
    fm = mode_vector_field(hybrid_plant, mode).xreplace(hybrid_plant.parameter_values)
    Jm = fm.jacobian(sp.Matrix(hybrid_plant.x)).replace(lambda e: isinstance(e, sp.DiracDelta),
                                                        lambda e: sp.Integer(0))
    Jm = sp.lambdify([list(hybrid_plant.x) + list(hybrid_plant.u)], Jm, "numpy")
    above, below = (0.45, 0.38, 0.34), (0.22, 0.12, 0.17)
    for shift in (0.0, 0.01, -0.015):
        x = np.array([(above if b else below)[i] + shift for i, b in enumerate(mode)])
        u = [3e-5, 3e-5]
        # regularisation eps = 1e-6 m against heads >= 0.04 m: relative effect < 2e-5
        np.testing.assert_allclose(np.asarray(J(x, u)), Jm([*x, *u]), rtol=1e-4, atol=0)


def test_ekf_keeps_the_previous_jacobian_on_a_switching_surface(hybrid_plant):
    tk = KalmanTuning(Q=1e-8 * np.eye(3), R=[[1e-6]], P0=1e-3 * np.eye(3), x0=[0.35, 0.32, 0.31],
                      ts=1.0)
    ekf = ExtendedKalmanFilter(hybrid_plant, tk, backend="vm")
    u = np.array([100 * LPH, 100 * LPH])
    ekf.step([0.31], u)
    assert not ekf.kept_jacobian
    # put the estimate exactly on h2 = h0 and step: the previous Phi must be reused
    state = ekf.state
    state[0, 1] = 0.3
    ekf._states[ekf._cur][:] = state
    P_before = ekf.covariance
    Phi_prev = ekf.state[0, 12:21].reshape(3, 3).T
    ekf.step([0.31], u)
    assert ekf.kept_jacobian
    Phi_used = ekf.state[0, 12:21].reshape(3, 3).T
    np.testing.assert_array_equal(Phi_used, Phi_prev)
    # the covariance prediction used exactly that Phi
    K = ekf.gain
    H = np.array([[0.0, 0.0, 1.0]])
    Pp = Phi_prev @ P_before @ Phi_prev.T + tk.Q
    Pp = 0.5 * (Pp + Pp.T)
    IKH = np.eye(3) - K @ H
    P_expected = IKH @ Pp @ IKH.T + K @ tk.R @ K.T
    np.testing.assert_allclose(ekf.covariance, 0.5 * (P_expected + P_expected.T), rtol=1e-10)
    # a tolerance widens the surface
    ekf2 = ExtendedKalmanFilter(hybrid_plant, KalmanTuning(Q=tk.Q, R=tk.R, P0=tk.P0, x0=tk.x0,
                                                           ts=1.0, switch_tol=0.05), backend="vm")
    ekf2.step([0.31], u)
    ekf2.step([0.31], u)
    assert ekf2.kept_jacobian
