"""BatchCall (verify/batch_call.py): repeated mapped calls through one bound buffer."""

from __future__ import annotations

import casadi as ca
import numpy as np

from tanksynth.verify.batch_call import BatchCall


def _fn(m: int = 2):
    x, u = ca.SX.sym("x", 3), ca.SX.sym("u", m)
    out = ca.vertcat(x[0] * x[1] + (ca.sum1(u) if m else 0), ca.sin(x[2]), x[0] - 2 * x[2])
    return ca.Function("g", [x, u], [out])


def _by_hand(X, U):
    s = U.sum(axis=1) if U.shape[1] else 0.0
    return np.column_stack([X[:, 0] * X[:, 1] + s, np.sin(X[:, 2]), X[:, 0] - 2 * X[:, 2]])


def test_repeated_calls_give_fresh_results_per_point():
    rng = np.random.default_rng(0)
    call = BatchCall(_fn(), 5)
    first = None
    for _ in range(4):
        X, U = rng.standard_normal((5, 3)), rng.standard_normal((5, 2))
        got = call(X, U)
        np.testing.assert_allclose(got, _by_hand(X, U), rtol=1e-14, atol=1e-15)
        if first is None:
            first, X0, U0 = got, X, U
    np.testing.assert_allclose(first, _by_hand(X0, U0), rtol=1e-14, atol=1e-15)  # not overwritten


def test_broadcast_arguments_and_empty_inputs():
    X = np.arange(12.0).reshape(4, 3)
    call = BatchCall(_fn(2), 4)
    np.testing.assert_allclose(call(X, np.array([1.0, 2.0])), _by_hand(X, np.tile([1.0, 2.0], (4, 1))))
    call0 = BatchCall(_fn(0), 4)
    np.testing.assert_allclose(call0(X, np.zeros((4, 0))), _by_hand(X, np.zeros((4, 0))))
