"""Riccati route of H2 / H-infinity state feedback (used by `tanksynth.design.synthesis.synthesize`).

For ONE model, no pole region and no extra bounds, the LMIs of
`tanksynth.design.synthesis.lmis` have Riccati solutions with the same optimum
(``R = Dzu' Dzu > 0`` and ``S = Cz' Dzu``, ``Q = Cz' Cz``):

H2
    the LQR: continuous ``A'X + XA - (XB + S) R^-1 (B'X + S') + Q = 0``,
    ``K = R^-1 (B'X + S')``; discrete ``X = A'XA - (A'XB + S)(R + B'XB)^-1
    (B'XA + S') + Q``, ``K = (R + B'XB)^-1 (B'XA + S')``; ``||T_zw||_2^2 =
    trace(Bw' X Bw)``.
H-infinity
    the game Riccati equation of the augmented input ``[u; w]`` with weight
    ``diag(R, -gamma^2 I)``: a stabilising solution ``X >= 0`` exists (and,
    discrete, ``gamma^2 I - Bw'XBw > 0``) iff some static state feedback
    reaches ``||T_zw||_inf < gamma``; the central gain is continuous ``K =
    R^-1 (B'X + S')``, discrete ``K = (R + B' Xb B)^-1 (B' Xb A + S')`` with
    ``Xb = X + X Bw (gamma^2 I - Bw'XBw)^-1 Bw'X`` (de Souza and Xie, 1992).
    The optimum is found by bisection on gamma (as ``hinfsyn`` does); a gamma
    counts as reachable only when the central gain's closed loop passes the
    Hamiltonian test ``||T_zw||_inf < gamma`` (`tanksynth.analysis.statespace.
    hinf_below`), so the upper end of the bracket is always certified by a gain.

Every function works on the (unscaled) `GeneralizedPlant`; scipy's ARE
solvers balance the problem themselves. The callers run them with the BLAS limited
to one thread (`tanksynth.analysis.blas.small_dense`): the matrices are small (a few
hundred rows), and on a loaded machine OpenBLAS's thread pool made the N = 64
bisection 20 to 40 times slower (48 s against 1.2 s measured).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from tanksynth.analysis.statespace import hinf_below, hinf_norm
from tanksynth.design.matrices import symmetrized
from tanksynth.design.synthesis.lmis import GeneralizedPlant

__all__ = ["RiccatiSolution", "riccati_applicable", "riccati_h2", "riccati_hinf", "BISECTION_RTOL"]

#: Relative width of the final gamma bracket of the H-infinity bisection.
BISECTION_RTOL = 1e-8


@dataclass(frozen=True, eq=False)
class RiccatiSolution:
    """A state-feedback gain from a Riccati equation.

    Attributes
    ----------
    K : ndarray, shape (m, n)
        ``u = -K x``.
    X : ndarray, shape (n, n)
        The stabilising solution of the (game) Riccati equation at ``gamma``
        (cost unit per state unit^2).
    h2 : float or None
        ``sqrt(trace(Bw' X Bw))`` of the LQR (H2 route).
    gamma : float or None
        The gamma the gain was computed at (H-infinity route; z unit per w unit).
    gamma_optimum : float or None
        Upper end of the final bisection bracket (smallest certified gamma).
    gamma_lower : float or None
        Lower end of the final bracket (no gain certified below it); z unit per w unit.
    iterations : int
        Riccati solves.
    """

    K: np.ndarray
    X: np.ndarray
    h2: float | None = None
    gamma: float | None = None
    gamma_optimum: float | None = None
    gamma_lower: float | None = None
    iterations: int = 1


def _weights(P: GeneralizedPlant) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    Q = P.Cz.T @ P.Cz
    return symmetrized(Q), P.Dzu.T @ P.Dzu, P.Cz.T @ P.Dzu


def riccati_applicable(P: GeneralizedPlant) -> str | None:
    """None if the Riccati route applies to ``P``, else the reason (``Dzu' Dzu`` singular).

    Parameters
    ----------
    P : GeneralizedPlant

    Returns
    -------
    str or None
    """
    R = P.Dzu.T @ P.Dzu
    w = np.linalg.eigvalsh(symmetrized(R))
    if w.size == 0 or w[0] <= 1e-12 * max(w[-1], 1e-300):
        return "Dzu' Dzu is singular (every input must be weighted in z)"
    return None


def _h2_gain(P: GeneralizedPlant) -> tuple[np.ndarray, np.ndarray]:
    Q, R, S = _weights(P)
    if P.domain == "continuous":
        X = sla.solve_continuous_are(P.A, P.B, Q, R, s=S)
        K = np.linalg.solve(R, P.B.T @ X + S.T)
    else:
        X = sla.solve_discrete_are(P.A, P.B, Q, R, s=S)
        K = np.linalg.solve(R + P.B.T @ X @ P.B, P.B.T @ X @ P.A + S.T)
    return symmetrized(X), K


def riccati_h2(P: GeneralizedPlant) -> RiccatiSolution:
    """The H2-optimal state feedback (LQR for ``Q = Cz'Cz``, ``R = Dzu'Dzu``, ``S = Cz'Dzu``).

    Parameters
    ----------
    P : GeneralizedPlant

    Returns
    -------
    RiccatiSolution

    Raises
    ------
    numpy.linalg.LinAlgError
        No stabilising solution (scipy).
    """
    X, K = _h2_gain(P)
    return RiccatiSolution(K=K, X=X, h2=float(np.sqrt(max(np.trace(P.Bw.T @ X @ P.Bw), 0.0))))


def _hinf_gain(P: GeneralizedPlant, gamma: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Central gain at ``gamma`` if the game Riccati equation's conditions hold and it reaches gamma."""
    Q, R, S = _weights(P)
    n, nw = P.n, P.Bw.shape[1]
    Bt = np.hstack([P.B, P.Bw])
    Rt = sla.block_diag(R, -gamma ** 2 * np.eye(nw))
    St = np.hstack([S, np.zeros((n, nw))])
    try:
        with np.errstate(all="ignore"):
            if P.domain == "continuous":
                X = sla.solve_continuous_are(P.A, Bt, Q, Rt, s=St)
            else:
                X = sla.solve_discrete_are(P.A, Bt, Q, Rt, s=St)
    except (np.linalg.LinAlgError, ValueError):
        return None
    X = symmetrized(X)
    if not np.all(np.isfinite(X)):
        return None
    scale = max(float(np.max(np.abs(X))), 1e-300)
    if np.linalg.eigvalsh(X)[0] < -1e-8 * scale:
        return None
    try:
        if P.domain == "continuous":
            K = np.linalg.solve(R, P.B.T @ X + S.T)
        else:
            G = gamma ** 2 * np.eye(nw) - P.Bw.T @ X @ P.Bw
            if np.linalg.eigvalsh(symmetrized(G))[0] <= 0:
                return None
            XBw = X @ P.Bw
            Xb = X + XBw @ np.linalg.solve(G, XBw.T)
            K = np.linalg.solve(R + P.B.T @ Xb @ P.B, P.B.T @ Xb @ P.A + S.T)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(K)):
        return None
    Acl, Bcl, Ccl = P.closed_loop(K)
    dt = None if P.domain == "continuous" else (P.dt or 1.0)
    if not hinf_below(gamma, Acl, Bcl, Ccl, None, dt):
        return None
    return X, K


def riccati_hinf(P: GeneralizedPlant, backoff: float = 0.0,
                 rtol: float = BISECTION_RTOL) -> RiccatiSolution:
    """H-infinity-optimal static state feedback by gamma bisection on the game Riccati equation.

    Parameters
    ----------
    P : GeneralizedPlant
    backoff : float
        The gain returned is the central gain at ``gamma_optimum (1 + backoff)``
        (>= 0, dimensionless; a moderate gain instead of the one at the edge of the
        bracket).
    rtol : float
        Relative width of the final bracket.

    Returns
    -------
    RiccatiSolution

    Raises
    ------
    numpy.linalg.LinAlgError
        No gain found at any gamma (not stabilisable, or the LQR fails).
    """
    X2, K2 = _h2_gain(P)            # the LQR closed loop has a finite norm: a first upper bound
    Acl, Bcl, Ccl = P.closed_loop(K2)
    dt = None if P.domain == "continuous" else (P.dt or 1.0)
    g_lqr = hinf_norm(Acl, Bcl, Ccl, None, dt)
    if not np.isfinite(g_lqr):
        raise np.linalg.LinAlgError("the LQR closed loop is unstable")
    calls = 0
    hi, best = g_lqr * (1 + 1e-6), None
    for _ in range(60):
        calls += 1
        best = _hinf_gain(P, hi)
        if best is not None:
            break
        hi *= 1.5
    if best is None:
        raise np.linalg.LinAlgError("no central H-infinity gain reaches the LQR closed loop's norm")
    lo = hi * 1e-3
    while True:                     # a gamma no gain reaches
        calls += 1
        if _hinf_gain(P, lo) is None:
            break
        lo *= 1e-3
        if lo < 1e-300:
            raise np.linalg.LinAlgError("gamma bisection found no lower bound")
    while hi - lo > rtol * hi:
        mid = np.sqrt(lo * hi) if hi > 10 * lo else 0.5 * (lo + hi)
        calls += 1
        sol = _hinf_gain(P, mid)
        if sol is None:
            lo = mid
        else:
            hi, best = mid, sol
    gamma = hi
    if backoff > 0:
        calls += 1
        sol = _hinf_gain(P, hi * (1 + backoff))
        if sol is not None:
            gamma, best = hi * (1 + backoff), sol
    return RiccatiSolution(K=best[1], X=best[0], gamma=float(gamma), gamma_optimum=float(hi),
                           gamma_lower=float(lo), iterations=calls)
