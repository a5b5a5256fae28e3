"""Metrics on hand-made trajectories, and on a closed loop."""

import numpy as np
import pytest

from tanksynth.plants import hybrid_three_tank
from tanksynth.verify.campaign import InverseDynamicsLaw
from tanksynth.sim.metrics import compute_metrics, estimation_rmse, ise, settling_time
from tanksynth.sim.scenarios import run_scenario, scenario
from tanksynth.sim.simulate import SimulationResult

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
    assert np.all(m["rmse_h1"].values == 0)            # perfect estimator
    assert m["controller_time"].values[0] > 0
