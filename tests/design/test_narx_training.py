"""NARX training (seed 002 section 3.3, Table 3): EKF data through the simulator, LM fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from tanksynth.design.estimators.narx_training import generate_ekf_data, levenberg_marquardt, train_narx
from tanksynth.plants import hybrid_three_tank
from tanksynth.plants.hybrid_three_tank import LPH
from tanksynth.runtime.estimators import KalmanTuning
from tanksynth.sim.simulate import simulate_inputs

EKF = dict(Q=1e-7 * np.eye(3), R=[[1e-6]], P0=1e-2 * np.eye(3), x0=[0.2, 0.2, 0.2], ts=1.0)


@pytest.fixture(scope="module")
def hybrid_plant():
    return hybrid_three_tank()


@pytest.fixture(scope="module")
def trained(hybrid_plant):
    return train_narx(hybrid_plant, KalmanTuning(**EKF), runs=3, validation_runs=1, steps=400,
                      seed=0, input_range=[[30 * LPH, 130 * LPH]] * 2, restarts=2, max_iter=120)


@pytest.mark.slow
def test_structure_is_table_3(trained):
    tun = trained.tuning
    d = trained.diagnostics["structure"]
    assert tun.hidden == 5 and tun.delays == 2 and tun.n_outputs == 1
    assert d["exogenous_inputs"] == 4 and d["outputs"] == 3 and d["input_delays"] == 0
    assert d["hidden_activation"] == "tanh" and d["output_activation"] == "linear"
    assert tun.W1.shape == (5, 10) and tun.W2.shape == (3, 5) and d["parameters"] == 73


@pytest.mark.slow
def test_training_data_seed_and_fit_error_are_recorded(trained, hybrid_plant):
    diag = trained.diagnostics
    assert diag["training"]["seed"] == 0 and diag["training"]["samples"] == 3 * 400
    assert trained.inputs.shape == (1200, 10) and trained.targets.shape == (1200, 3)
    assert all(np.isfinite(diag["fit"]["mse_train"])) and diag["fit"]["mse_standardised"] < 0.05
    cl = diag["closed_loop_validation"]
    # closed loop on held-out data stays in the ballpark of the EKF it imitates
    assert max(cl["rmse_vs_true"]) < 0.1
    assert max(cl["rmse_vs_true"]) < 5 * max(cl["ekf_rmse_vs_true"])
    # determinism: same seed, same weights, bit for bit
    again = train_narx(hybrid_plant, KalmanTuning(**EKF), runs=3, validation_runs=1, steps=400,
                       seed=0, input_range=[[30 * LPH, 130 * LPH]] * 2, restarts=2, max_iter=120)
    np.testing.assert_array_equal(again.tuning.parameters(), trained.tuning.parameters())


def test_levenberg_marquardt_matches_minpack_on_a_curve_fit():
    t = np.linspace(0, 3, 60)
    truth = np.array([2.0, -1.3, 0.5])
    data = truth[0] * np.exp(truth[1] * t) + truth[2]

    def res(p):
        return p[0] * np.exp(p[1] * t) + p[2] - data

    def jac(p):
        e = np.exp(p[1] * t)
        return np.stack([e, p[0] * t * e, np.ones_like(t)], axis=1)

    ours = levenberg_marquardt(res, jac, np.array([1.0, -0.5, 0.0]), max_iter=200)
    ref = least_squares(res, np.array([1.0, -0.5, 0.0]), jac=jac, method="lm")
    np.testing.assert_allclose(ours.x, ref.x, rtol=1e-7)
    np.testing.assert_allclose(ours.x, truth, rtol=1e-7)
    assert ours.success


@pytest.mark.slow
def test_training_data_come_from_the_simulator(hybrid_plant):
    """The plant runs through the toolbox's one simulator: same states, saturated inputs."""
    data = generate_ekf_data(hybrid_plant, KalmanTuning(**EKF), runs=2, steps=120, seed=3,
                             input_range=[[0.0, 300 * LPH]] * 2, hold=(20, 40))
    assert data["u"].max() <= 240 * LPH                     # asked up to 300 lph: pumps saturate
    X0 = data["x"][0]
    again = simulate_inputs(hybrid_plant, X0, data["u"], 1.0, substeps=10)
    np.testing.assert_array_equal(again.x.transpose(1, 0, 2), data["x"])
    lo, hi = hybrid_plant.state_bounds()
    assert np.all(data["x"] >= lo) and np.all(data["x"] <= hi)
    assert np.all(np.isfinite(data["x_ekf"])) and data["y"].shape == (120, 2, 1)
