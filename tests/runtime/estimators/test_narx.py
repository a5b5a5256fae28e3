"""NARX estimator (seed 002 section 3.3, Table 3): kernel, Levenberg-Marquardt, training."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from tanksynth.design.narx import levenberg_marquardt, train_narx
from tanksynth.runtime.estimators import KalmanTuning, NARXEstimator, NARXTuning, discrete_model
from tanksynth.errors import DimensionError
from tanksynth.plants.hybrid_three_tank import LPH

EKF = dict(Q=1e-7 * np.eye(3), R=[[1e-6]], P0=1e-2 * np.eye(3), x0=[0.2, 0.2, 0.2], ts=1.0)


@pytest.fixture(scope="module")
def trained(hybrid_plant):
    return train_narx(hybrid_plant, KalmanTuning(**EKF), runs=3, validation_runs=1, steps=400,
                      seed=0, input_range=[[30 * LPH, 130 * LPH]] * 2, restarts=2, max_iter=120)


def test_structure_is_table_3(trained):
    tun = trained.tuning
    d = trained.diagnostics["structure"]
    assert tun.hidden == 5 and tun.delays == 2 and tun.n_outputs == 1
    assert d["exogenous_inputs"] == 4 and d["outputs"] == 3 and d["input_delays"] == 0
    assert d["hidden_activation"] == "tanh" and d["output_activation"] == "linear"
    assert tun.W1.shape == (5, 10) and tun.W2.shape == (3, 5) and d["parameters"] == 73


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


def test_kernel_step_is_the_network(trained, hybrid_plant):
    """One kernel step = prediction, innovation, standardised tanh network (eq. 42-45)."""
    tun = trained.tuning
    narx = NARXEstimator(hybrid_plant, tun, backend="vm")
    past = np.array([[0.32, 0.31, 0.305], [0.321, 0.309, 0.306]])
    narx._states[narx._cur][:] = past.reshape(1, -1)
    u = np.array([100 * LPH, 90 * LPH])
    y = np.array([0.307])
    out = narx.step(y, u)
    model = discrete_model(hybrid_plant, 1.0)
    import casadi as ca

    xs, us = ca.SX.sym("x", 3), ca.SX.sym("u", 2)
    F = ca.Function("F", [xs, us], [model.predict_sx(xs, us)])
    xp = np.asarray(F(past[0], u)).ravel()
    inp = np.concatenate([xp, y - xp[2:3], past[0], past[1]])
    z = (inp - tun.in_mean) / tun.in_scale
    expected = tun.out_mean + tun.out_scale * (tun.W2 @ np.tanh(tun.W1 @ z + tun.b1) + tun.b2)
    np.testing.assert_allclose(out, expected, rtol=1e-13)
    np.testing.assert_allclose(narx.state[0, 3:], past[0])           # delayed output shifts


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


def test_tuning_shape_errors(hybrid_plant):
    rng = np.random.default_rng(0)
    good = dict(W1=rng.standard_normal((5, 10)), b1=np.zeros(5), W2=rng.standard_normal((3, 5)),
                b2=np.zeros(3), in_mean=np.zeros(10), in_scale=np.ones(10), out_mean=np.zeros(3),
                out_scale=np.ones(3), x0=[0.3, 0.3, 0.3], ts=1.0)
    NARXTuning(**good)
    with pytest.raises(DimensionError, match="b1"):
        NARXTuning(**{**good, "b1": np.zeros(4)})
    with pytest.raises(DimensionError, match="n \\+ q \\+ d n"):
        NARXTuning(**{**good, "W1": rng.standard_normal((5, 9)), "in_mean": np.zeros(9),
                      "in_scale": np.ones(9)})
    bad_plant_tuning = NARXTuning(**{**good, "W1": rng.standard_normal((5, 11)),
                                     "in_mean": np.zeros(11), "in_scale": np.ones(11)})
    with pytest.raises(DimensionError, match="takes 2 measurements"):
        NARXEstimator(hybrid_plant, bad_plant_tuning)
