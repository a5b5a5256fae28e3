"""NARX estimator (seed 002 section 3.3, Table 3): the shipped kernel and its tuning.

Training (data through the simulator, Levenberg-Marquardt) is tested in tests/design/test_narx.py.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from tanksynth.errors import DimensionError
from tanksynth.plants.hybrid_three_tank import LPH
from tanksynth.runtime.estimators import NARXEstimator, NARXTuning, discrete_model


@pytest.fixture(scope="module")
def tuning():
    """Table 3 structure with random weights and a realistic standardisation."""
    rng = np.random.default_rng(11)
    return NARXTuning(W1=rng.normal(0, 0.3, (5, 10)), b1=rng.normal(0, 0.1, 5),
                      W2=rng.normal(0, 0.3, (3, 5)), b2=rng.normal(0, 0.1, 3),
                      in_mean=np.r_[[0.3] * 3, 0.0, [0.3] * 6], in_scale=np.r_[[0.05] * 3, 1e-3, [0.05] * 6],
                      out_mean=[0.3] * 3, out_scale=[0.05] * 3, x0=[0.3] * 3, ts=1.0)


def test_kernel_step_is_the_network(tuning, hybrid_plant):
    """One kernel step = prediction, innovation, standardised tanh network (eq. 42-45)."""
    tun = tuning
    narx = NARXEstimator(hybrid_plant, tun, backend="vm")
    past = np.array([[0.32, 0.31, 0.305], [0.321, 0.309, 0.306]])
    narx._states[narx._cur][:] = past.reshape(1, -1)
    u = np.array([100 * LPH, 90 * LPH])
    y = np.array([0.307])
    out = narx.step(y, u)
    model = discrete_model(hybrid_plant, 1.0)
    xs, us = ca.SX.sym("x", 3), ca.SX.sym("u", 2)
    F = ca.Function("F", [xs, us], [model.predict_sx(xs, us)])
    xp = np.asarray(F(past[0], u)).ravel()
    inp = np.concatenate([xp, y - xp[2:3], past[0], past[1]])
    z = (inp - tun.in_mean) / tun.in_scale
    expected = tun.out_mean + tun.out_scale * (tun.W2 @ np.tanh(tun.W1 @ z + tun.b1) + tun.b2)
    np.testing.assert_allclose(out, expected, rtol=1e-13)
    np.testing.assert_allclose(narx.state[0, 3:], past[0])           # delayed output shifts


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
