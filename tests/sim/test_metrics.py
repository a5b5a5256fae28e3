"""Metrics on hand-made trajectories, and on a closed loop."""

import numpy as np
import pytest

from pathlib import Path

from tanksynth.methods import load_spec
from tanksynth.plants import hybrid_three_tank, three_tank
from tanksynth.verify.laws.campaign import InverseDynamicsLaw
from tanksynth.sim.metrics import (ESTIMATION_WARMUP, compute_metrics, controlled_names,
                                   detection_metrics, estimation_metrics, estimation_rmse, ise,
                                   settling_time, warmup_samples)
from tanksynth.sim.scenarios import run_scenario, scenario
from tanksynth.sim.simulate import SimulationResult

ROOT = Path(__file__).resolve().parents[2]
HYBRID = hybrid_three_tank()
X_OP = [0.31918677, 0.3209075, 0.30968861]


def _result(x, ref, ts=1.0, x_hat=None):
    M, N1, n = x.shape
    return SimulationResult(t=np.arange(N1) * ts, x=x, y=x[:, :, :1], u=np.zeros((M, N1 - 1, 2)),
                            x_hat=x if x_hat is None else x_hat, reference=ref,
                            seeds=np.zeros(M, dtype=np.uint64), modes=np.zeros((M, N1, 0), np.int8),
                            ts=ts, substeps=1, events=0, clipped_low=0, clipped_high=0,
                            timing={"estimator": 0.0, "controller": 1.0, "calls": N1 - 1, "runs": M},
                            plant="test")


def test_ise_and_settling_time_by_hand():
    x = np.zeros((1, 11, 1))
    x[0, 5:, 0] = [0.5, 0.9, 1.02, 0.99, 1.0, 1.0]
    ref = np.zeros((11, 1))
    ref[5:] = 1.0
    r = _result(x, ref, ts=2.0)
    assert ise(r, (0,))[0, 0] == pytest.approx(2.0 * (0.25 + 0.01 + 0.0004 + 0.0001))
    err = r.reference[None] - r.x
    assert settling_time(err, 5, 11, 0.05, 2.0)[0] == pytest.approx(4.0)   # in the band from sample 7
    assert settling_time(err, 5, 11, 0.005, 2.0)[0] == pytest.approx(8.0)
    assert settling_time(err, 5, 8, 0.001, 2.0)[0] == np.inf
    xh = x + 0.1
    assert estimation_rmse(_result(x, ref, x_hat=xh))[0, 0] == pytest.approx(0.1)


def test_closed_loop_metrics_have_units_and_sense():
    setup = scenario("servo").setup(HYBRID, X_OP, tracked=(0, 1))
    law = InverseDynamicsLaw(HYBRID, (0, 1), (0.05, 0.05))
    res = run_scenario(setup, HYBRID, ts=1.0, seeds=[0, 1], controller=law, substeps=2)
    m = compute_metrics(res, setup, HYBRID)
    assert m["ise_h1"].unit == "m^2 s" and m["tracking_time"].unit == "s"
    # first-order closed loop with c = 0.05 1/s: 5 % band reached after about 3/c = 60 s
    assert 40 < m["tracking_time"].values.mean() < 80
    assert np.all(np.abs(m["offset_h1"].values) < 1e-3)
    assert m["controller_time"].values[0] > 0
    # the true state was fed back: no estimation RMSE, no estimator time (nothing to measure)
    assert not [k for k in m if k.startswith("rmse_") or k == "estimator_time"]
    # only h3 is measured (output y); the controlled h1, h2 keep their state names
    assert {k for k in m if k.startswith(("ise_", "offset_"))} == {"ise_h1", "ise_h2", "offset_h1",
                                                                   "offset_h2"}


def test_controlled_variables_take_the_output_name():
    plant = load_spec(ROOT / "examples" / "custom_two_tank.toml").plant   # output y = h2
    assert controlled_names(plant, (1, 0)) == ["y", "h1"]
    assert controlled_names(three_tank(), (0, 1)) == ["h1", "h2"]
    assert controlled_names(HYBRID, (0, 1)) == ["h1", "h2"]                # y = h3 only


def test_estimation_rmse_skips_the_warm_up():
    assert ESTIMATION_WARMUP == 0.1 and warmup_samples(300) == 30 and warmup_samples(3) == 1
    x = np.zeros((1, 11, 3))
    xh = x.copy()
    xh[0, 0] = 5.0                      # the initial guess: not counted (warm-up = 1 sample here)
    xh[0, 1:] = [0.1, -0.2, 0.0]
    m = estimation_metrics(_result(x, np.zeros((11, 0)), x_hat=xh), three_tank())
    assert sorted(m) == ["rmse_h1", "rmse_h2", "rmse_h3"]
    assert m["rmse_h1"].values[0] == pytest.approx(0.1) and m["rmse_h2"].values[0] == pytest.approx(0.2)
    assert m["rmse_h3"].values[0] == 0.0 and "warm-up" in m["rmse_h1"].description


def test_detection_metrics_by_hand():
    t = np.arange(6) * 0.5
    thr = np.array([10.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    healthy = np.array([[5.0, 0.0, 0.0, 2.0, 0.0, 0.0], [0.0] * 6])
    faulty = np.array([[0.0, 0.0, 0.0, 0.0, 3.0, 3.0], [0.0, 2.0, 0.0, 0.0, 0.0, 0.0]])
    m = detection_metrics(t, faulty, thr, healthy, fault_sample=2)
    assert m["false_alarm_rate"].values.tolist() == [1 / 6, 0.0]
    assert m["first_false_alarm"].values.tolist() == [1.5, np.inf]
    assert m["detection_delay"].values.tolist() == [1.0, np.inf]      # the alarm before t_f is not one
    assert "detection_delay" not in detection_metrics(t, faulty, thr, healthy, None)
