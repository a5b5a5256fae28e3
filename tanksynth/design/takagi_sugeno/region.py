"""Certified region and output-feedback coupling of the Takagi-Sugeno PDC designs.

The largest Lyapunov level set inside the TS domain box on which the pump
limits hold (`certified_region`), the observer LMI with a decay rate used by
``ts_output_feedback`` and the weight that ties the controller and observer
Lyapunov functions into one composite certificate.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from tanksynth.design.conic import modelling
from tanksynth.design.matrices import symmetrized
from tanksynth.errors import InfeasibleDesign

__all__ = ["Region", "certified_region", "coupling_weight", "lyapunov_decay", "observer_decay_lmi",
           "switch_level", "composite_decay", "initial_error_allowance"]


@dataclass(frozen=True)
class Region:
    """Certified level set ``{x : (x - x0)' P (x - x0) <= c}``.

    Attributes
    ----------
    c : float
    limits : dict
        ``c`` allowed by each constraint (domain faces, pump margins).
    binding : str
        The constraint that fixes ``c``.
    semi_axes : ndarray, shape (n,)
        Semi-axes of the ellipsoid (state units, ascending).
    axes : ndarray, shape (n, n)
        Their directions (columns).
    extents : ndarray, shape (n,)
        Largest deviation of each state on the region (state units).
    """

    c: float
    limits: dict
    binding: str
    semi_axes: np.ndarray
    axes: np.ndarray
    extents: np.ndarray

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"c": self.c, "limits": self.limits, "binding": self.binding,
                "semi_axes": self.semi_axes.tolist(), "axes": self.axes.tolist(),
                "extents": self.extents.tolist()}



def certified_region(P: np.ndarray, K: np.ndarray, faces: tuple[np.ndarray, np.ndarray],
                     input_margins: Sequence[float] | None, names: Sequence[str] = (),
                     extra_inverse: np.ndarray | None = None) -> Region:
    """Largest ``c`` with ``{e' P e <= c}`` inside the faces and the pumps unsaturated.

    ``c = min(min_l g_l^2 / (G_l P^-1 G_l'), min_ij margin_j^2 / (k_ij P^-1 k_ij'))``.
    ``extra_inverse`` (output feedback) adds ``P_o^-1 / beta`` to the inverse
    seen by the controller (the estimate ``x_hat = x - eps``).

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Lyapunov matrix (per squared state unit).
    K : ndarray, shape (r, m, n)
        Vertex gains (input units per state unit).
    faces : (ndarray, ndarray)
        ``(G, g)``: faces ``G e <= g`` of the domain in deviation coordinates (state units).
    input_margins : sequence of float or None
        Distance of each input's operating value to its nearest bound (input units); None: unbounded.
    names : sequence of str, optional
        Names of the faces (default ``face0``, ``face1``, ...).
    extra_inverse : ndarray, shape (n, n), optional
        Added to ``P^-1`` for the input limits (output feedback: ``P_o^-1 / beta``).
    """
    P = symmetrized(P)
    Pi = np.linalg.inv(P)
    G, g = faces
    limits: dict[str, float] = {}
    names = list(names) or [f"face{l}" for l in range(len(g))]
    for l in range(len(g)):
        limits[f"face {names[l] if l < len(names) else l}"] = float(g[l] ** 2 / (G[l] @ Pi @ G[l]))
    if input_margins is not None:
        Pk = Pi if extra_inverse is None else Pi + extra_inverse
        for i in range(K.shape[0]):
            for j, um in enumerate(input_margins):
                k = K[i, j]
                den = float(k @ Pk @ k)
                limits[f"pump {j + 1} at vertex {i + 1}"] = float(um ** 2 / den) if den > 0 else np.inf
    binding = min(limits, key=lambda face: limits[face])
    c = float(limits[binding])
    lam, V = np.linalg.eigh(P)
    return Region(c, limits, binding, np.sqrt(c / lam)[::-1], V[:, ::-1],
                  np.sqrt(c * np.diag(Pi)))



def lyapunov_decay(P: np.ndarray, W: np.ndarray) -> float:
    """Largest ``a`` with ``W >= 2 a P`` (``dV/dt <= -e' W e`` gives ``dV/dt <= -2 a V``), 1/s.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Lyapunov matrix (positive definite).
    W : ndarray, shape (n, n)
        Decrease matrix: ``dV/dt <= -e' W e``.
    """
    Lc = np.linalg.cholesky(symmetrized(P))
    Li = np.linalg.inv(Lc)
    return float(np.linalg.eigvalsh(Li @ symmetrized(W) @ Li.T)[0] / 2.0)



def coupling_weight(Pc: np.ndarray, K: np.ndarray, B: np.ndarray, alpha_c: float, Po: np.ndarray,
                    alpha_o: float, factor: float = 2.0) -> float:
    """Weight ``beta`` of the composite ``V = e' Pc e + beta eps' Po eps`` (separation by cascade).

    With ``dV_c/dt <= -2 alpha_c V_c + 2 e' Pc B K(.) eps`` and ``dV_o/dt <=
    -2 alpha_o V_o``, ``dV/dt < 0`` for every convex ``K(.)`` when ``beta >
    max_j lambda_max(Po^-1/2 K_j' B' Pc B K_j Po^-1/2) / (4 alpha_c alpha_o)``
    (Schur complement of the 2x2 block condition); ``factor`` times that.

    Parameters
    ----------
    Pc : ndarray, shape (n, n)
        Controller Lyapunov matrix.
    K : ndarray, shape (r, m, n)
        Vertex gains (input units per state unit).
    B : ndarray, shape (n, m)
        Input matrix (state units per input unit and s).
    alpha_c : float
        Controller decay rate [1/s].
    Po : ndarray, shape (n, n)
        Observer Lyapunov matrix.
    alpha_o : float
        Observer decay rate [1/s].
    factor : float, optional
        Safety factor on the smallest admissible weight (dimensionless).
    """
    if not (alpha_c > 0 and alpha_o > 0):
        raise InfeasibleDesign(f"composite certificate needs positive decay rates (controller "
                               f"{alpha_c:.3g} 1/s, observer {alpha_o:.3g} 1/s)")
    lam, V = np.linalg.eigh(symmetrized(Po))
    R = V @ np.diag(lam ** -0.5) @ V.T
    worst = max(float(np.linalg.eigvalsh(R @ Kj.T @ B.T @ Pc @ B @ Kj @ R)[-1]) for Kj in K)
    return factor * worst / (4.0 * alpha_c * alpha_o)



def initial_error_allowance(Pc: np.ndarray, Po: np.ndarray, beta: float, c: float) -> dict:
    """What initial estimation error the composite certificate ``V = e' Pc e + beta eps' Po eps <= c``
    allows (``e = x - x0`` the plant's deviation, ``eps = x - x_hat`` the estimation error).

    The certified region ``{e' Pc e <= c}`` holds for the plant only with ``eps(0) = 0``; otherwise
    ``(e(0), eps(0))`` must lie in ``{V <= c}``.

    Parameters
    ----------
    Pc, Po : ndarray, shape (n, n)
        Controller and observer Lyapunov matrices (1/state unit^2).
    beta : float
        Weight of the observer's term (dimensionless).
    c : float
        Level of the certified sublevel set (dimensionless).

    Returns
    -------
    dict
        ``error_ball_at_x_op``: radius of the largest ball of ``eps(0)`` allowed with the plant
        starting at the operating point, ``sqrt(c / (beta lambda_max(Po)))``;
        ``error_semi_axes``: semi-axes of the ellipsoid of allowed ``eps(0)`` then, ascending
        (the largest error allowed along the most favourable direction is the last);
        ``plant_ball_estimate_at_x_op``: radius of the largest ball of ``x(0)`` around the
        operating point when the estimate starts there (``eps(0) = e(0)``),
        ``sqrt(c / lambda_max(Pc + beta Po))``; all in state units.
    """
    Po = symmetrized(np.asarray(Po, dtype=float))
    Pc = symmetrized(np.asarray(Pc, dtype=float))
    lam = np.linalg.eigvalsh(beta * Po)
    both = float(np.linalg.eigvalsh(Pc + beta * Po)[-1])
    return {"error_ball_at_x_op": float(np.sqrt(c / lam[-1])),
            "error_semi_axes": np.sort(np.sqrt(c / lam)).tolist(),
            "plant_ball_estimate_at_x_op": float(np.sqrt(c / both)),
            "rule": "(e(0), eps(0)) in {e' P e + beta eps' Po eps <= c}: eps(0) = 0 for the certified "
                    "region of the plant alone"}


def observer_decay_lmi(A0: Any, C: Any, psi: float, alpha: float, *, margin: float = 1e-6,
                       kappa: float = 1e4, solver: str = "CLARABEL") -> tuple[np.ndarray, ...]:
    """Seed 001 LMI (28) with ``Q = q I`` and a decay rate (1/s), re-checked in numpy.

    ``[[He(P A0 - N C) + 2 alpha P + psi^2 q I, P], [P, -q I]] < 0``, ``L = P^-1 N``:
    ``d(eps' P eps)/dt <= -2 alpha eps' P eps`` for ``|Delta| <= psi |eps|``.
    Scaled by ``omega = |A0|_2``; ``I <= P``, ``trace P <= kappa n``.

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        State matrix of the observer's linear part [1/s].
    C : array_like, shape (q, n)
        Output matrix.
    psi : float
        Lipschitz bound of the remainder [1/s].
    alpha : float
        Decay rate [1/s].
    margin : float, optional
        Strictness margin of the LMIs (dimensionless, scaled problem).
    kappa : float, optional
        Bound on ``trace P / n`` (dimensionless).
    solver : str, optional
        cvxpy solver name.

    Returns
    -------
    (L, P, Q)
        Gain (state units per output unit / s), Lyapunov matrix and ``Q = q I``.

    Raises
    ------
    InfeasibleDesign
        Infeasible, or the re-check fails.
    """
    A0 = np.asarray(A0, dtype=float)
    C = np.atleast_2d(np.asarray(C, dtype=float))
    n, q = A0.shape[0], C.shape[0]
    om = max(float(np.linalg.norm(A0, 2)), psi, alpha, 1e-12)
    As, ps, al = A0 / om, psi / om, alpha / om
    # Clarabel: the LMI written straight in its conic form (design.conic); others through cvxpy
    lib = modelling(solver)
    P = lib.variable((n, n), symmetric=True)
    N = lib.variable((n, q))
    qv = lib.variable()
    H = P @ As - N @ C
    blk = lib.bmat([[H + H.T + 2 * al * P + ps ** 2 * qv * np.eye(n), P], [P, -qv * np.eye(n)]])
    cons = [symmetrized(blk) << -margin * np.eye(2 * n), P >> np.eye(n),
            lib.trace(P) <= kappa * n, qv >= margin]
    prob = lib.Problem(lib.Minimize(0), cons)
    status = lib.solve_status(prob, solver)
    if status.startswith("solver_error"):
        raise InfeasibleDesign("observer LMI (28) with decay: solver failed: "
                               f"{status.removeprefix('solver_error ')}")
    if prob.status not in ("optimal", "optimal_inaccurate") or P.value is None:
        raise InfeasibleDesign(f"observer LMI (28) with decay {alpha:g} 1/s and psi = {psi:.4g} 1/s: "
                               f"solver status {prob.status}")
    Pv = 0.5 * (P.value + P.value.T)
    L = np.linalg.solve(Pv, N.value) * om
    Q = float(qv.value) * np.eye(n) / om      # Q in original time units: psi^2 Q = (psi/om)^2 q om
    G = Pv @ (A0 - L @ C)
    full = np.block([[G + G.T + 2 * alpha * Pv + psi ** 2 * Q, Pv], [Pv, -Q]])
    if not (np.linalg.eigvalsh(symmetrized(full))[-1] < 0 and np.linalg.eigvalsh(Pv)[0] > 0):
        raise InfeasibleDesign(f"observer LMI (28) with decay {alpha:g} 1/s: the re-check fails")
    return L, Pv, Q


def _contained(P1: np.ndarray, level1: float, P2: np.ndarray, c2: float, d: np.ndarray) -> bool:
    """S-lemma: ``{z' P1 z <= level1}`` inside ``{(z - d)' P2 (z - d) <= c2}``."""
    from scipy.optimize import minimize_scalar  # deferred: scipy.optimize imports in ~0.3 s

    Lc = np.linalg.cholesky(symmetrized(P1))
    Li = np.linalg.inv(Lc)
    Q = Li @ symmetrized(P2) @ Li.T / c2        # w = Lc' z: {w' w <= level1}
    b = Q @ (Lc.T @ d)
    corner = float((Lc.T @ d) @ b) - 1.0
    lo = float(np.linalg.eigvalsh(Q)[-1])
    hi = -corner / level1 if level1 > 0 else np.inf
    if not hi >= lo:
        return False
    n = P1.shape[0]

    def lam(tau: float) -> float:
        M = np.block([[Q - tau * np.eye(n), -b[:, None]], [-b[None, :],
                                                            np.array([[corner + tau * level1]])]])
        return float(np.linalg.eigvalsh(M)[-1])

    if not np.isfinite(hi):
        return lam(lo) <= 0.0
    best = minimize_scalar(lam, bounds=(lo, hi), method="bounded",
                           options={"xatol": 1e-12 * max(hi, 1.0), "maxiter": 500})
    return min(float(best.fun), lam(lo), lam(hi)) <= -1e-12


def switch_level(P1: np.ndarray, c1: float, P2: np.ndarray, c2: float, d: np.ndarray,
                 rtol: float = 1e-4) -> float:
    """Largest ``gamma`` in [0, 1] with ``{z' P1 z <= gamma c1}`` inside ``{(z - d)' P2 (z - d) <= c2}``.

    Containment of one ellipsoid in another is decided exactly by the
    S-lemma (one quadratic constraint, lossless): there is ``tau >= 0`` with
    ``[[P2 - tau P1, -P2 d], [-d' P2, d' P2 d - c2 + tau gamma c1]] <= 0``;
    ``lambda_max`` of that matrix is convex in ``tau`` (minimised on the
    interval where it can be feasible), ``gamma`` is bisected. Used for a
    set-point change: ``z`` is the deviation from the first operating point,
    ``d`` the step to the second one.

    Parameters
    ----------
    P1 : ndarray, shape (k, k)
        Lyapunov matrix of the first design (per squared state unit).
    c1 : float
        Its certified level (dimensionless: the units of ``e' P e``).
    P2 : ndarray, shape (k, k)
        Lyapunov matrix of the second design.
    c2 : float
        Its certified level (dimensionless: the units of ``e' P e``).
    d : ndarray, shape (k,)
        Centre of the second ellipsoid in the first one's coordinates (state units, m).
    rtol : float, optional
        Relative accuracy of the bisection on ``gamma`` (dimensionless).

    Returns
    -------
    float
        ``gamma`` (0 when the first centre is not strictly inside the second ellipsoid).
    """
    P1, P2, d = np.asarray(P1, float), np.asarray(P2, float), np.asarray(d, float).ravel()
    if not float(d @ P2 @ d) < c2:
        return 0.0
    if _contained(P1, c1, P2, c2, d):
        return 1.0
    lo, hi = 0.0, 1.0
    while hi - lo > rtol * max(lo, 1e-12) and hi > 1e-12:
        mid = 0.5 * (lo + hi)
        if _contained(P1, mid * c1, P2, c2, d):
            lo = mid
        else:
            hi = mid
    return lo



def composite_decay(Pc: np.ndarray, B: np.ndarray, K: np.ndarray, alpha_c: float, Po: np.ndarray,
                    alpha_o: float, beta: float) -> float:
    """Decay rate (1/s) of ``V = e' Pc e + beta eps' Po eps`` for the controller-observer cascade.

    ``dV/dt <= -[e; eps]' W_j [e; eps]`` with ``W_j = [[2 alpha_c Pc, -Pc B
    K_j], [-K_j' B' Pc, 2 beta alpha_o Po]]`` at every vertex gain (the law
    is a convex combination of them); the rate is ``min_j`` of the largest
    ``a`` with ``W_j >= 2 a diag(Pc, beta Po)`` (`lyapunov_decay`).

    Parameters
    ----------
    Pc : ndarray, shape (n, n)
        Controller Lyapunov matrix (1 / (state units)^2).
    B : ndarray, shape (n, m)
        Input matrix (state units per s per input unit).
    K : ndarray, shape (r, m, n)
        Vertex gains (input units per state unit).
    alpha_c, alpha_o : float
        Controller and observer decay rates [1/s].
    Po : ndarray, shape (n, n)
        Observer Lyapunov matrix.
    beta : float
        Weight of the observer term (dimensionless).
    """
    n = Pc.shape[0]
    D = np.block([[Pc, np.zeros((n, n))], [np.zeros((n, n)), beta * Po]])
    rates = []
    for Kj in K:
        X = -Pc @ B @ Kj
        W = np.block([[2 * alpha_c * Pc, X], [X.T, 2 * beta * alpha_o * Po]])
        rates.append(lyapunov_decay(D, W))
    return float(min(rates))
