"""Linear models of the tank network for the decentralised gains: pattern, Van Loan noise, models."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.integrate import quad_vec

from tanksynth.design.decentralized.models import (DiscreteModel, discretize_noise,
                                                   equicorrelated_intensity, linear_model,
                                                   lower_tank_equilibrium, own_tank_pattern,
                                                   window_models)
from tanksynth.errors import DimensionError, RegionError, SpecError
from tanksynth.plants import tank_network, three_tank


# ------------------------------------------------------------ sparsity patterns
def test_own_tank_pattern():
    np.testing.assert_array_equal(own_tank_pattern(tank_network(6)), np.eye(6))
    with pytest.raises(DimensionError, match="h3, h4"):
        own_tank_pattern(tank_network(4, parameter_set="johansson_min_phase"))


# ------------------------------------------------------------ noise and models
def test_van_loan_matches_quadrature_and_scalar_formula():
    rng = np.random.default_rng(3)
    F = rng.standard_normal((4, 4)) * 0.3 - np.eye(4) * 0.5
    G = rng.standard_normal((4, 2))
    Qc = G @ G.T
    Ad, Qd = discretize_noise(F, Qc, 0.7)
    np.testing.assert_allclose(Ad, sla.expm(0.7 * F), rtol=1e-12)
    ref, _ = quad_vec(lambda s: sla.expm(F * s) @ Qc @ sla.expm(F * s).T, 0.0, 0.7, epsabs=1e-13)
    np.testing.assert_allclose(Qd, ref, rtol=1e-9, atol=1e-12)
    assert np.array_equal(Qd, Qd.T)
    a, q, ts = -0.02, 0.3, 1.0
    _, qd = discretize_noise([[a]], [[q]], ts)
    assert qd[0, 0] == pytest.approx(q * (np.exp(2 * a * ts) - 1) / (2 * a), rel=1e-12)
    with pytest.raises(SpecError):
        discretize_noise(F, -Qc, 0.7)
    with pytest.raises(SpecError):
        discretize_noise(F, Qc, 0.0)


def test_equicorrelated_intensity():
    Q = equicorrelated_intensity(4, 0.5, 0.25)
    assert Q[0, 0] == 0.5 and Q[0, 1] == pytest.approx(0.125)
    assert np.linalg.eigvalsh(Q)[0] > 0
    with pytest.raises(SpecError):
        equicorrelated_intensity(4, 0.5, 1.0)
    with pytest.raises(SpecError):
        equicorrelated_intensity(4, -1.0)


@pytest.mark.parametrize("N", [4, 8, 40])
def test_lower_tank_equilibrium_balances_the_model(N):
    plant = tank_network(N)
    rng = np.random.default_rng(N)
    lower = rng.uniform(8.0, 30.0, N // 2)
    x, u = lower_tank_equilibrium(plant, lower)
    np.testing.assert_array_equal(x[: N // 2], lower)
    assert np.all(x > 0) and np.all(u > 0)
    assert np.max(np.abs(plant.compiled.rhs(x[None], u[None]))) < 1e-12


def test_lower_tank_equilibrium_errors():
    with pytest.raises(SpecError, match="tank_network"):
        lower_tank_equilibrium(three_tank(), [10.0])
    with pytest.raises(RegionError, match="positive"):
        lower_tank_equilibrium(tank_network(4), [10.0, -1.0])
    with pytest.raises(DimensionError):
        lower_tank_equilibrium(tank_network(4), [10.0, 1.0, 3.0])


def test_linear_models():
    plant = tank_network(8)
    x = np.array([20, 18, 22, 19, 9, 4, 6, 5], dtype=float)
    u = np.full(4, 5.0)
    Qc = equicorrelated_intensity(8, 0.01, 0.5)
    eq = linear_model(plant, x, u, 1.0, Qc, np.eye(8))
    assert isinstance(eq, DiscreteModel) and eq.scheme == "lower_tank_equilibrium"
    x_lin, u_lin = lower_tank_equilibrium(plant, x[:4])
    np.testing.assert_allclose(eq.x_lin, x_lin)
    np.testing.assert_array_equal(eq.d, np.zeros(8))
    np.testing.assert_allclose(eq.predict(x_lin, u_lin), x_lin, atol=1e-12)   # equilibrium stays
    np.testing.assert_array_equal(eq.C, np.eye(8))
    F, _ = plant.compiled.jacobians(x_lin[None], u_lin[None])
    np.testing.assert_allclose(eq.A, sla.expm(F[0]), rtol=1e-12)
    np.testing.assert_allclose(eq.Q, discretize_noise(F[0], Qc, 1.0)[1], rtol=1e-12)
    # "jacobian" scheme: one step of the nonlinear model to second order in ts
    jac = linear_model(plant, x, u, 0.1, Qc, np.eye(8), scheme="jacobian")
    from scipy.integrate import solve_ivp
    sol = solve_ivp(lambda t, z: plant.compiled.rhs(z[None], u[None])[0], (0, 0.1), x,
                    rtol=1e-11, atol=1e-12)
    assert np.max(np.abs(jac.predict(x, u) - sol.y[:, -1])) < 1e-5
    assert linear_model(three_tank(), [0.4, 0.2, 0.3], [1e-4, 1e-4], 1.0, 1e-6 * np.eye(3),
                        np.eye(3)).scheme == "jacobian"


def test_window_models_relinearise_on_schedule():
    plant = tank_network(4)
    models, xp = window_models(plant, np.full(4, 20.0), np.full((25, 2), 6.0), 1.0,
                               0.01 * np.eye(4), np.eye(4), relinearize_every=10)
    assert len(models) == 25 and xp.shape == (26, 4)
    for k in range(1, 25):
        assert (models[k] is models[k - 1]) == (k % 10 != 0)
    for k in range(25):
        np.testing.assert_allclose(xp[k + 1], models[k].predict(xp[k], [6.0, 6.0]))
    with pytest.raises(SpecError):
        window_models(plant, np.full(4, 20.0), np.full((5, 2), 6.0), 1.0, np.eye(4), np.eye(4),
                      relinearize_every=0)
