"""The lean kernels of the iterative finite-horizon route (issue 15).

Every product mode of `_Kernels` ("diag", "select" through a slice or a
gather, "dense", all entries free) must give the gains and cost of the plain
algorithm, written here independently in numpy (dense products, LU solves).
"""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.design.decentralized.gains import finite_horizon_gains
from tanksynth.design.decentralized.recursion import (GainPattern, _Kernels, _spd_solve,
                                                      require_positive_definite)
from tanksynth.errors import InfeasibleDesign


def plain_fh(A, C, Q, R, E, P0, tol=1e-6, max_iter=100):
    """Pedroso & Batista's iteration, dense numpy (the reference)."""
    T, n = len(A), A[0].shape[0]
    rows, cols = np.nonzero(E)
    eye = np.eye(n)

    def masked(L, S, rhs):
        K = np.zeros(E.shape)
        K[rows, cols] = np.linalg.solve(L[np.ix_(rows, rows)] * S[np.ix_(cols, cols)],
                                        rhs[rows, cols])
        return K

    def forward(K):
        Pp, pred, tr = P0, [], []
        for k in range(T):
            pred.append(Pp)
            IKC = eye - K[k] @ C[k]
            Pf = IKC @ Pp @ IKC.T + K[k] @ R[k] @ K[k].T
            tr.append(np.trace(Pf))
            Pp = A[k] @ Pf @ A[k].T + Q[k]
        return pred, np.array(tr)

    K, Pp = [], P0
    for k in range(T):
        K.append(masked(eye, C[k] @ Pp @ C[k].T + R[k], Pp @ C[k].T))
        IKC = eye - K[k] @ C[k]
        Pp = A[k] @ (IKC @ Pp @ IKC.T + K[k] @ R[k] @ K[k].T) @ A[k].T + Q[k]
    pred, traces = forward(K)
    for _ in range(max_iter):
        L = eye
        for k in range(T - 1, -1, -1):
            if k < T - 1:
                M = (eye - K[k + 1] @ C[k + 1]) @ A[k]
                L = eye + M.T @ L @ M
            K[k] = masked(L, C[k] @ pred[k] @ C[k].T + R[k], L @ pred[k] @ C[k].T)
        pred, new = forward(K)
        done = np.max(np.abs(new - traces) / traces) < tol
        traces = new
        if done:
            break
    return K, float(traces.sum())


def system(n, C_of, E, T=12, seed=0):
    """A stable drifting LTV system with the given output matrix and pattern."""
    rng = np.random.default_rng(seed)
    A0 = 0.9 * np.eye(n) + 0.05 * rng.standard_normal((n, n))
    A, C, Q, R = [], [], [], []
    for _ in range(T):
        A0 = A0 + 0.01 * rng.standard_normal((n, n))
        A.append(A0.copy())
        C.append(C_of(rng))
        q = rng.standard_normal((n, n))
        Q.append(0.01 * q @ q.T + 0.01 * np.eye(n))
        o = C[-1].shape[0]
        r = rng.standard_normal((o, o))
        R.append(0.1 * r @ r.T + np.eye(o))
    p = rng.standard_normal((n, n))
    return A, C, Q, R, E, p @ p.T + 5 * np.eye(n)


def lower_pattern(n):
    h = n // 2
    low = np.arange(h)
    E = np.zeros((n, h))
    E[low, low] = 1
    E[h + low, low] = 1
    E[h + low, (low - 1) % h] = 1
    return E


def scaled_permutation(n, o, seed=3):
    rng = np.random.default_rng(seed)
    sel = rng.permutation(n)[:o]
    C = np.zeros((o, n))
    C[np.arange(o), sel] = rng.uniform(0.5, 2.0, o)
    return C, sel


def _cases():
    C40, sel40 = scaled_permutation(40, 20)
    E40 = np.zeros((40, 20))
    E40[sel40, np.arange(20)] = 1                     # each measured state: its own output
    E40[np.setdiff1d(np.arange(40), sel40), np.arange(20)] = 1   # the others: one output each
    E_some = np.eye(6)
    E_some[2, 2] = 0                                  # one state without a gain
    return {
        "diag, C = I, E = I": (8, lambda r: np.eye(8), np.eye(8), "diag"),
        "diag, C = 2 I, a row without gain": (6, lambda r: 2.0 * np.eye(6), E_some, "diag"),
        "select through a slice (lower tanks measured)":
            (8, lambda r: np.eye(8)[:4], lower_pattern(8), "select"),
        "select through a gather, scaled (n = 40)": (40, lambda r: C40, E40, "select"),
        "dense C": (5, lambda r: r.standard_normal((3, 5)), np.eye(5)[:, :3] + np.eye(5)[:, [1, 2, 0]],
                    "dense"),
        "every entry free": (5, lambda r: r.standard_normal((3, 5)), np.ones((5, 3)), "dense"),
    }


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if "n = 40" in n else n for n in _cases()])
def test_every_kernel_mode_gives_the_plain_iteration(name):
    n, C_of, E, mode = _cases()[name]
    A, C, Q, R, E, P0 = system(n, C_of, E)
    kern = _Kernels(C, GainPattern(E != 0))
    assert {step[0] for step in kern.step} == {mode}
    res = finite_horizon_gains(A, C, Q, R, E, P0, tol=1e-9, max_iter=500)
    K_ref, cost_ref = plain_fh(A, C, Q, R, E, P0, tol=1e-9, max_iter=500)
    assert res.converged
    assert res.cost == pytest.approx(cost_ref, rel=1e-10)
    for K, Kr in zip(res.K, K_ref):
        np.testing.assert_allclose(K, Kr, rtol=0, atol=1e-8 * max(1.0, np.abs(Kr).max()))
        assert np.all(K[E == 0] == 0.0)
    for P in res.P:                                    # returned covariances: symmetric
        assert np.array_equal(P, P.T)


def test_spd_solve_falls_back_to_lu_and_refuses_a_singular_system():
    M = np.array([[1.0, 2.0], [2.0, 1.0]])             # symmetric, indefinite, invertible
    b = np.array([1.0, -1.0])
    np.testing.assert_allclose(_spd_solve(M.copy(), b.copy()), np.linalg.solve(M, b), rtol=1e-14)
    S = np.array([[4.0, 2.0], [2.0, 5.0]])
    np.testing.assert_allclose(_spd_solve(S, b), np.linalg.solve(S, b), rtol=1e-14)
    with pytest.raises(InfeasibleDesign, match="singular"):
        _spd_solve(np.zeros((2, 2)), b)


def test_require_positive_definite_names_the_step():
    require_positive_definite(np.eye(3), "P(1|1)")
    with pytest.raises(InfeasibleDesign, match=r"P\(4\|4\).*smallest eigenvalue -1"):
        require_positive_definite(np.diag([1.0, -1.0, 2.0]), "P(4|4)")
    with pytest.raises(InfeasibleDesign, match="not positive definite"):
        require_positive_definite(np.full((2, 2), np.nan), "P(2|2)")


def test_one_state_full_pattern_is_the_scalar_kalman_filter():
    """n = o = 1: the pattern is full and the "diag" mode applies at once (both code paths)."""
    A = [np.array([[0.9 + 0.01 * k]]) for k in range(6)]
    C, Q, R = [np.array([[2.0]])] * 6, [np.array([[0.1]])] * 6, [np.array([[1.0]])] * 6
    assert _Kernels(C, GainPattern(np.ones((1, 1), dtype=bool))).step[0][0] == "diag"
    res = finite_horizon_gains(A, C, Q, R, np.ones((1, 1)), np.array([[3.0]]))
    P, cost = 3.0, 0.0
    for k in range(6):                                 # the scalar Kalman filter by hand
        K = 2.0 * P / (4.0 * P + 1.0)
        Pf = (1 - 2 * K) ** 2 * P + K * K
        assert res.K[k][0, 0] == pytest.approx(K, rel=1e-13)
        cost += Pf
        P = A[k][0, 0] ** 2 * Pf + 0.1
    assert res.cost == pytest.approx(cost, rel=1e-13)


class _RecordsBlasThreads:
    """An array-like ``P(1|0)`` that records the BLAS libraries' thread counts when the design
    converts it to an array (inside its input checks)."""

    def __init__(self, P):
        self.P = P
        self.seen = []

    def __array__(self, dtype=None, copy=None):
        from threadpoolctl import threadpool_info

        self.seen.append([i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"])
        return np.array(self.P, dtype=dtype)


def test_finite_horizon_input_checks_run_on_one_blas_thread():
    """Issue 29: the window's checks (eigenvalues, Cholesky factors of every n x n matrix) ran
    outside `small_dense`, with OpenBLAS's threads: one call in five 3-20x slower at N >= 128 on
    the loaded 2-core machine. They run on one thread now, and the result is unchanged."""
    A, C, Q, R, E, P0 = system(6, lambda r: np.eye(6)[:3], lower_pattern(6))
    probe = _RecordsBlasThreads(P0)
    res = finite_horizon_gains(A, C, Q, R, E, probe, tol=1e-9, max_iter=500)
    assert probe.seen and all(counts and set(counts) == {1} for counts in probe.seen), probe.seen
    K_ref, cost_ref = plain_fh(A, C, Q, R, E, P0, tol=1e-9, max_iter=500)
    assert res.cost == pytest.approx(cost_ref, rel=1e-10)
