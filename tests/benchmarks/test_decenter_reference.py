"""The DECENTER port used as a benchmark contender (benchmarks/decenter_reference.py).

Each piece is checked against an independent formulation: the sparse gain equation
against its Kronecker (vec) form, the printed ``Lambda`` sum against the backward
recursion, the finite-horizon result against tanksynth's iterative route and
against the covariance recursion recomputed here from its gains.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import decenter_reference as dec

from tanksynth.design.decentralized.gains import finite_horizon_gains


def _window(seed: int, n: int = 5, o: int = 3, T: int = 10):
    rng = np.random.default_rng(seed)
    A = [0.9 * np.eye(n) + 0.15 * rng.standard_normal((n, n)) for _ in range(T)]
    C = [rng.standard_normal((o, n)) for _ in range(T)]
    Q = []
    for _ in range(T):
        M = 0.3 * rng.standard_normal((n, n))
        Q.append(M @ M.T)
    R = []
    for _ in range(T):
        M = 0.3 * rng.standard_normal((o, o))
        R.append(M @ M.T + np.eye(o))
    M = rng.standard_normal((n, n))
    P0 = M @ M.T + np.eye(n)
    E = np.zeros((n, o))
    E.flat[rng.permutation(n * o)[: n + 2]] = 1
    return A, C, Q, R, E, P0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sparse_eq_solver_solves_the_masked_equation(seed):
    rng = np.random.default_rng(seed)
    n, o = 6, 4
    E = (rng.random((n, o)) < 0.5).astype(float)
    E[0, 0] = 1
    A, C = rng.standard_normal((n, n)), rng.standard_normal((n, o))
    M = rng.standard_normal((o, o))
    B = M @ M.T + np.eye(o)
    X = dec.sparse_eq_solver(A, B, C, E)
    assert np.all(X[E == 0] == 0)
    # [A X B - C]_E = 0, and the same as the Kronecker form vec(A X B) = (B' kron A) vec(X)
    assert np.abs((A @ X @ B - C)[E != 0]).max() < 1e-9 * np.abs(C).max()
    free = np.flatnonzero(E.T.ravel())
    x = np.linalg.solve(np.kron(B.T, A)[np.ix_(free, free)], C.T.ravel()[free])
    np.testing.assert_allclose(X.T.ravel()[free], x, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(X, dec.sparse_eq_solver_loops(A, B, C, E))


def test_printed_lambda_is_the_backward_recursion():
    A, C, _, _, E, _ = _window(4)
    rng = np.random.default_rng(5)
    K = [rng.standard_normal(E.shape) * E for _ in A]
    n, T = A[0].shape[0], len(A)
    L = np.eye(n)
    for i in range(T - 1, -1, -1):
        if i < T - 1:
            M = (np.eye(n) - K[i + 1] @ C[i + 1]) @ A[i]
            L = np.eye(n) + M.T @ L @ M
        np.testing.assert_allclose(dec.lambda_printed(A, C, K, i), L, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("seed", [0, 3, 7])
def test_finite_horizon_matches_tanksynth_and_its_own_recursion(seed):
    A, C, Q, R, E, P0 = _window(seed)
    K, P, cost, iters = dec.finite_horizon(A, C, Q, R, E, P0, epsl=1e-8, max_it=200)
    ours = finite_horizon_gains(A, C, Q, R, E, P0, tol=1e-8, max_iter=200)
    assert abs(cost - ours.cost) <= 1e-9 * ours.cost
    scale = max(np.abs(k).max() for k in ours.K)
    assert max(np.abs(a - b).max() for a, b in zip(K, ours.K)) <= 1e-6 * scale
    # the cost is the Joseph-form recursion of the returned gains, recomputed here
    Pp, total = P0, 0.0
    for k in range(len(A)):
        IKC = np.eye(len(P0)) - K[k] @ C[k]
        Pf = IKC @ Pp @ IKC.T + K[k] @ R[k] @ K[k].T
        np.testing.assert_allclose(P[k], Pf, rtol=1e-12, atol=1e-12)
        total += np.trace(Pf)
        Pp = A[k] @ Pf @ A[k].T + Q[k]
    assert abs(total - cost) <= 1e-12 * cost
    assert all(np.all(k[E == 0] == 0) for k in K)
    assert iters >= 2


def test_stop_is_checked_from_the_second_iteration():
    """As printed: iteration 1 is never compared, so even a huge epsl runs two sweeps."""
    A, C, Q, R, E, P0 = _window(11)
    assert dec.finite_horizon(A, C, Q, R, E, P0, epsl=1e6, max_it=50)[3] == 2
    assert dec.finite_horizon(A, C, Q, R, E, P0, epsl=1e6, max_it=1)[3] == 1
    one = dec.finite_horizon(A, C, Q, R, E, P0, max_it=1)[2]
    two = dec.finite_horizon(A, C, Q, R, E, P0, max_it=2)[2]
    assert two < one   # each sweep is an exact block-coordinate minimisation
