"""TSObserver (verify/observer_lmi/verdicts.py): the compiled period equals the exponential-Euler rule by hand."""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from tanksynth.methods import load_spec
from tanksynth.verify.takagi_sugeno.loops import PlantObserverModel
from tanksynth.verify.observer_lmi.verdicts import TSObserver


def test_compiled_period_is_the_exponential_euler_rule():
    spec = load_spec("examples/three_tank_ts_control.toml")
    plant = spec.plant
    n, m, q = plant.n, plant.m, plant.q
    x_op = np.asarray(spec.x0, dtype=float)
    rng = np.random.default_rng(4)
    A0 = -0.02 * np.eye(n) + 0.002 * rng.standard_normal((n, n))
    C = np.eye(q, n)
    L = 0.05 * rng.random((n, q))
    ts, sub, M = 2.0, 8, 4
    model = PlantObserverModel(plant, A0, C)
    obs = TSObserver(model, L, ts, sub)
    assert obs._period is not None          # the compiled route is the one under test
    # exact ZOH of the stiff linear part over ts / sub, by one expm of the augmented matrix
    aug = np.zeros((2 * n, 2 * n))
    aug[:n, :n], aug[:n, n:] = A0 - L @ C, np.eye(n)
    E = expm(aug * ts / sub)
    phi, gam = E[:n, :n], E[:n, n:]
    f = lambda X, U: np.asarray(plant.compiled.rhs(X, U))  # noqa: E731
    x = x_op[None] * (1 + 0.05 * rng.random((M, n)))
    obs.reset(x)
    y_prev = None
    for _ in range(15):
        y = (x_op[None] * (1 + 0.05 * rng.random((M, n))))[:, :q]
        u = 1e-4 * (1 + rng.random((M, m)))
        got = obs.step(y, u).copy()
        if y_prev is not None:
            for _ in range(sub):
                g = f(x, u) - x @ A0.T + y_prev @ L.T
                x = x @ phi.T + g @ gam.T
        np.testing.assert_allclose(got, x, rtol=1e-12, atol=0)
        y_prev = y
