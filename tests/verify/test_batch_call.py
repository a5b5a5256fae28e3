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


def _two_outputs():
    x, r = ca.SX.sym("x", 3), ca.SX.sym("r", 2)
    u = ca.vertcat(ca.sqrt(x[0]) * r[0] - x[1], r[1] / (1 + x[2] ** 2))
    return ca.Function("law", [x, r], [u, ca.vertcat(r[0] - x[0], r[1] - x[1], x[2])])


def test_every_result_and_the_fit_test():
    rng = np.random.default_rng(1)
    X, R = rng.uniform(0.1, 1.0, (6, 3)), rng.standard_normal((6, 2))
    fn = _two_outputs()
    assert BatchCall.fits(fn)
    u, z = BatchCall(fn, 6).all(X, R)
    ref = fn.map(6, "serial")(X.T, R.T)
    assert np.array_equal(u, np.asarray(ref[0]).T) and np.array_equal(z, np.asarray(ref[1]).T)
    x = ca.SX.sym("x", 3)
    sparse = ca.Function("s", [x], [ca.vertcat(x[0], ca.SX(1, 1), x[2])])   # a structural zero
    assert not BatchCall.fits(sparse)
    assert not BatchCall.fits(ca.Function("m", [x], [ca.reshape(ca.vertcat(x, x), 3, 2)]))


def test_casadi_control_law_buffered_equals_the_mapped_call():
    """`CasadiControlLaw.evaluate` through one bound buffer: the numbers of Function.map."""
    from tanksynth.verify.batch_call import CasadiControlLaw

    rng = np.random.default_rng(2)
    fn = _two_outputs()
    law = CasadiControlLaw(fn)
    for count in (1, 4):
        for _ in range(3):
            X, R = rng.uniform(0.1, 1.0, (count, 3)), rng.standard_normal((count, 2))
            got = law.evaluate(X, R)
            ref = fn.map(count, "serial")(X.T, R.T)
            for g, r in zip(got, ref):
                assert np.array_equal(g, np.asarray(r).reshape(-1, count).T)
            assert np.array_equal(law(X, R, 0.0), got[0])
