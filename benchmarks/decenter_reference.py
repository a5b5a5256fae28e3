"""DECENTER's published finite-horizon decentralised Kalman algorithm, in plain numpy.

Issue 15: the second contender of ``benchmarks/decentralized_numpy.py``. Seed 003
designs its window gains with the DECENTER toolbox (``kalmanFiniteHorizonLTV(system,
E, FH_w, P0_pred, opts)`` with ``opts.epsl = 1e-6``, ``opts.maxOLIt = 100``; Pedroso,
Batista, Oliveira & Silvestre, Int. J. Systems Science 2021, Section 4) and solves the
masked gain equation with ``sparseEqSolver`` (Pedroso & Batista, Mathematics 9(13)
1497, 2021, Section 3). This module follows the published MATLAB source of those
three functions (``kalmanOneStepLTV``, ``sparseEqSolver``, ``kalmanFiniteHorizonLTV``,
github.com/decenter2021/decenter), written anew here, step for step:

1. start: the one-step gains along the window,
   ``K(i) = sparseEqSolver(I, C P(i|i-1) C' + R, P(i|i-1) C', E)``, Joseph form;
2. outer iteration k = 1..maxOLIt, backward over i = T..1:
   ``P_ = A(i-1) P(i-1|i-1) A(i-1)' + Q(i-1)`` (``P(1|0)`` at i = 1) from the last
   forward pass; ``Lambda = I + sum_{m=i+1}^{T} Gamma_m' Gamma_m`` with
   ``Gamma_m = prod_{t=m}^{i+1} (I - K(t) C(t)) A(t-1)``, each product rebuilt from
   the identity for every m (as printed: O(T^2) products per step, O(T^3) per sweep;
   the later gains are the ones already updated in this sweep);
   ``K(i) = sparseEqSolver(Lambda, C(i) P_ C(i)' + R(i), Lambda P_ C(i)', E)``;
3. forward pass: ``P(i|i) = K R K' + (I - K C) P_ (I - K C)'``;
4. stop when ``max_i |tr P(i|i) - tr P_prev(i|i)| / tr P_prev(i|i) < epsl``, checked
   from the second outer iteration on (the first is compared with nothing).

``sparseEqSolver`` builds ``S[p, q] = A[i_p, i_q] B[j_q, j_p]`` and ``r[p] =
C[i_p, j_p]`` over the free entries (i, j) of E in row-major order and solves
``S x = r``. The printed version fills S in four nested loops (a MATLAB JIT loop);
here the same products are taken by fancy indexing (the same floating-point
operations, entry for entry: checked against the literal loops below), because a
Python quadruple loop would time the interpreter, not the algorithm. MATLAB's ``\\``
becomes ``np.linalg.solve`` (LU; S is not exactly symmetric in floating point).

Typos in the print, and what is used instead: the header of
``kalmanFiniteHorizonLTV`` lists ``system{i,2} = B(i)`` (it is ``C(i)``: it
multiplies the gain and gives ``n`` from its columns); ``kalmanOneStepLTV``'s
header lists ``system{2,2}, system{3,3}, system{4,4}`` (read ``system{1,2..4}``, as
its code does) and calls ``P(k|k)`` "predicted"; the documentation page calls
``epsl`` a relative improvement of the objective, the code compares every step's
trace (the code is followed).

Run as a script (``make bench`` does): a self-check on a random 6-state window with
a pattern of 10 free entries: the vectorised ``sparse_eq_solver`` against the literal
quadruple loop and against the Kronecker form ``[B' kron A]_EE vec_E(X) =
vec_E(C)``; the printed ``Lambda`` sum against the recursion ``Lambda_i = I + M'
Lambda_{i+1} M``; the finite-horizon cost never above the one-step cost. Exit 1 on
a mismatch.
"""

from __future__ import annotations

import sys

import numpy as np

__all__ = ["finite_horizon", "lambda_printed", "one_step", "sparse_eq_solver",
           "sparse_eq_solver_loops"]


def sparse_eq_solver(A: np.ndarray, B: np.ndarray, C: np.ndarray, E: np.ndarray) -> np.ndarray:
    """X with ``[A X B - C]_ij = 0`` where ``E_ij != 0`` and ``X_ij = 0`` elsewhere.

    Parameters
    ----------
    A : ndarray (n, n)
    B : ndarray (o, o)
    C : ndarray (n, o)
    E : ndarray (n, o), sparsity pattern (nonzero = free entry)

    Returns
    -------
    ndarray (n, o)
        The solution (units of C / (A B)).
    """
    rows, cols = np.nonzero(E)                       # row-major: the printed (i, j) loop order
    S = A[np.ix_(rows, rows)] * B[np.ix_(cols, cols)].T   # S[p, q] = A[i_p, i_q] B[j_q, j_p]
    X = np.zeros(E.shape)
    X[rows, cols] = np.linalg.solve(S, C[rows, cols])
    return X


def sparse_eq_solver_loops(A: np.ndarray, B: np.ndarray, C: np.ndarray, E: np.ndarray
                           ) -> np.ndarray:
    """``sparse_eq_solver`` with S filled by the printed quadruple loop (self-check only)."""
    n, o = E.shape
    free = [(i, j) for i in range(n) for j in range(o) if E[i, j] != 0]
    S = np.zeros((len(free), len(free)))
    r = np.zeros(len(free))
    for p, (i, j) in enumerate(free):
        r[p] = C[i, j]
        for q, (k, l) in enumerate(free):
            S[p, q] = A[i, k] * B[l, j]
    x = np.linalg.solve(S, r)
    X = np.zeros((n, o))
    for p, (i, j) in enumerate(free):
        X[i, j] = x[p]
    return X


def one_step(A, C, Q, R, E, P_prev):
    """``kalmanOneStepLTV``: (K(k), P(k+1|k), P(k|k)) from ``P_prev = P(k|k-1)``."""
    n = A.shape[0]
    K = sparse_eq_solver(np.eye(n), C @ P_prev @ C.T + R, P_prev @ C.T, E)
    IKC = np.eye(n) - K @ C
    P_filt = K @ R @ K.T + IKC @ P_prev @ IKC.T
    return K, A @ P_filt @ A.T + Q, P_filt


def lambda_printed(A, C, K, i: int) -> np.ndarray:
    """``Lambda`` of step ``i`` (0-based) as printed: ``I + sum_m Gamma_m' Gamma_m``."""
    T, n = len(A), A[0].shape[0]
    eye = np.eye(n)
    Lam = eye
    for m in range(i + 1, T):
        G = eye
        for t in range(m, i, -1):                    # t = m, m-1, ..., i+1
            G = G @ (eye - K[t] @ C[t]) @ A[t - 1]
        Lam = Lam + G.T @ G
    return Lam


def finite_horizon(A, C, Q, R, E, P0, epsl: float = 1e-5, max_it: int = 100):
    """``kalmanFiniteHorizonLTV``: masked finite-horizon gains minimising ``sum tr P(k|k)``.

    Parameters
    ----------
    A, C, Q, R : sequences of ndarray, length T
        ``A(k)`` (n, n), ``C(k)`` (o, n), ``Q(k)`` (n, n) (squared state units),
        ``R(k)`` (o, o) (squared output units).
    E : ndarray (n, o)
        Sparsity pattern.
    P0 : ndarray (n, n)
        ``P(1|0)`` (squared state units).
    epsl : float
        Relative change of every ``tr P(k|k)`` below which the iteration stops
        (DECENTER's default 1e-5; seed 003 uses 1e-6).
    max_it : int
        Outer iterations at most.

    Returns
    -------
    K : list of ndarray (n, o)
    P : list of ndarray (n, n)
        ``P(k|k)``.
    cost : float
        ``sum_k tr P(k|k)`` (squared state units).
    iterations : int
        Outer iterations run.
    """
    T, n = len(A), C[0].shape[1]
    eye = np.eye(n)
    K, P = [None] * T, [None] * T
    P_pred = P0
    for i in range(T):
        K[i], P_pred, P[i] = one_step(A[i], C[i], Q[i], R[i], E, P_pred)
    P_prev_it = None
    for k in range(1, max_it + 1):
        for i in range(T - 1, -1, -1):
            P_ = A[i - 1] @ P[i - 1] @ A[i - 1].T + Q[i - 1] if i > 0 else P0
            Lam = lambda_printed(A, C, K, i)
            K[i] = sparse_eq_solver(Lam, C[i] @ P_ @ C[i].T + R[i], Lam @ P_ @ C[i].T, E)
        for i in range(T):
            P_ = A[i - 1] @ P[i - 1] @ A[i - 1].T + Q[i - 1] if i > 0 else P0
            IKC = eye - K[i] @ C[i]
            P[i] = K[i] @ R[i] @ K[i].T + IKC @ P_ @ IKC.T
        if k != 1:
            rel = max(abs(np.trace(P[j]) - np.trace(P_prev_it[j])) / np.trace(P_prev_it[j])
                      for j in range(T))
            if rel < epsl:
                break
        P_prev_it = list(P)
    return K, P, float(sum(np.trace(Pk) for Pk in P)), k


def _self_check(seed: int = 3) -> list[str]:
    """Independent checks of the port on a random window; the list of failures."""
    rng = np.random.default_rng(seed)
    n, o, T = 6, 4, 12
    E = np.zeros((n, o))
    E.flat[rng.permutation(n * o)[:10]] = 1
    A = [np.eye(n) * 0.9 + 0.1 * rng.standard_normal((n, n)) for _ in range(T)]
    C = [rng.standard_normal((o, n)) for _ in range(T)]
    Gq = 0.3 * rng.standard_normal((T, n, n))
    Gr = 0.3 * rng.standard_normal((T, o, o))
    Q = [G @ G.T for G in Gq]
    R = [G @ G.T + np.eye(o) for G in Gr]
    G0 = rng.standard_normal((n, n))
    P0 = G0 @ G0.T + np.eye(n)
    fails = []
    Am, Bm, Cm = rng.standard_normal((n, n)), R[0], rng.standard_normal((n, o))
    X = sparse_eq_solver(Am, Bm, Cm, E)
    if not np.array_equal(X, sparse_eq_solver_loops(Am, Bm, Cm, E)):
        fails.append("vectorised S differs from the printed loops")
    free = np.flatnonzero(E.T.ravel())                       # column-major vec, as kron needs
    xk = np.linalg.solve(np.kron(Bm.T, Am)[np.ix_(free, free)], Cm.T.ravel()[free])
    if not np.allclose(X.T.ravel()[free], xk, rtol=1e-10, atol=1e-12) or np.any(X[E == 0]):
        fails.append("sparse_eq_solver disagrees with the Kronecker form")
    Ks = [rng.standard_normal((n, o)) * E for _ in range(T)]
    Lam = np.eye(n)
    for i in range(T - 1, -1, -1):
        if i < T - 1:
            M = (np.eye(n) - Ks[i + 1] @ C[i + 1]) @ A[i]
            Lam = np.eye(n) + M.T @ Lam @ M
        if not np.allclose(lambda_printed(A, C, Ks, i), Lam, rtol=1e-10, atol=1e-10):
            fails.append(f"printed Lambda sum differs from the recursion at step {i}")
            break
    _, _, c1, _ = finite_horizon(A, C, Q, R, E, P0, max_it=1)
    Pp, c0 = P0, 0.0
    for i in range(T):
        _, Pp, Pf = one_step(A[i], C[i], Q[i], R[i], E, Pp)
        c0 += np.trace(Pf)
    Kf, _, cf, _ = finite_horizon(A, C, Q, R, E, P0, epsl=1e-10)
    if not (cf <= c1 * (1 + 1e-12) and c1 <= c0 * (1 + 1e-12) and cf < c0):
        fails.append(f"costs not decreasing: one-step {c0}, 1 sweep {c1}, converged {cf}")
    if any(np.any(k_[E == 0]) for k_ in Kf):
        fails.append("a gain leaves the pattern")
    return fails


if __name__ == "__main__":
    failures = _self_check()
    for f in failures:
        print("FAIL", f)
    print("decenter_reference self-check:", "FAILED" if failures else "ok")
    sys.exit(1 if failures else 0)
