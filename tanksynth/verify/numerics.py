"""The verdicts' own numerics: pole matching, LMI residuals, integral augmentation.

Written for the verify stage from the equations the designs claim to
satisfy, never by calling the design code they judge: a bug in a design's
block builder cannot hide behind the same builder in its verdict.

``match_poles``
    optimal one-to-one matching of achieved eigenvalues to requested poles
    (assignment problem on the relative distances ``|q_j - p_i| / max(1,
    |p_i|)``).
``pole_agreement``
    multiplicity-aware: a pole of a k-cluster (repeated or nearly repeated
    poles) is met to ``tol^(1/k)`` (a k-fold eigenvalue is computable only to
    ``eps^(1/k)``) and the characteristic polynomial of the matrix must match
    ``prod (s - p_i)`` to ``tol`` relative to the coefficient sizes.
``region_lmi_matrix``
    the Chilali-Gahinet matrix ``L (x) X + M (x) (A X) + M' (x) (A X)'`` of
    an LMI region ``{z : L + M z + M' conj(z) < 0}``; negative definite
    with ``X > 0`` iff every eigenvalue of ``A`` lies in the region.
``observer_lmi_recheck``
    the observer LMI (28) of the Takagi-Sugeno observer (seed 001)
    evaluated from the stored ``P``, ``Q``, ``L`` and ``psi``.
``integral_augmentation``
    the plant augmented with the integral of the tracking error
    (continuous ``z' = r - C1 x`` or discrete ``z+ = z + ts (r - C1 x)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment

from tanksynth.errors import DimensionError

__all__ = ["PoleMatch", "match_poles", "PoleAgreement", "pole_agreement", "symmetric", "region_lmi_matrix", "LMIItem",
           "ObserverLMIRecheck", "observer_lmi_recheck", "integral_augmentation"]


@dataclass(frozen=True, eq=False)
class PoleMatch:
    """Achieved eigenvalues matched one to one with requested poles.

    Attributes
    ----------
    requested : ndarray of complex, shape (k,)
        In the order given.
    achieved : ndarray of complex, shape (k,)
        ``achieved[i]`` is the eigenvalue matched with ``requested[i]`` (units of
        the poles: 1/s in continuous time, dimensionless in discrete time).
    errors : ndarray, shape (k,)
        ``|achieved[i] - requested[i]|`` (units of the poles).
    relative_errors : ndarray, shape (k,)
        ``errors[i] / max(1, |requested[i]|)``.
    """

    requested: np.ndarray
    achieved: np.ndarray
    errors: np.ndarray
    relative_errors: np.ndarray

    @property
    def max_error(self) -> float:
        """Largest matched error (0 for no pole)."""
        return float(np.max(self.errors)) if self.errors.size else 0.0

    @property
    def max_relative_error(self) -> float:
        """Largest matched error relative to ``max(1, |p|)`` (0 for no pole)."""
        return float(np.max(self.relative_errors)) if self.relative_errors.size else 0.0


def match_poles(requested: ArrayLike, achieved: ArrayLike) -> PoleMatch:
    """Match achieved eigenvalues to requested poles, one to one.

    The matching minimises the sum of the relative distances ``|q_j - p_i|
    / max(1, |p_i|)`` over all one-to-one assignments (Hungarian algorithm,
    `scipy.optimize.linear_sum_assignment`), so a repeated or clustered
    pole cannot be matched twice.

    Parameters
    ----------
    requested, achieved : sequence of complex, same length
        Poles (1/s in continuous time, dimensionless in discrete time).

    Returns
    -------
    PoleMatch

    Raises
    ------
    DimensionError
        The two lists have different lengths.
    """
    p = np.asarray(requested, dtype=complex).reshape(-1)
    q = np.asarray(achieved, dtype=complex).reshape(-1)
    if p.size != q.size:
        raise DimensionError(f"{p.size} requested poles but {q.size} achieved eigenvalues")
    scale = np.maximum(1.0, np.abs(p))
    cost = np.abs(p[:, None] - q[None, :]) / scale[:, None]
    rows, cols = linear_sum_assignment(cost)
    matched = np.empty_like(p)
    matched[rows] = q[cols]
    errors = np.abs(matched - p)
    return PoleMatch(p, matched, errors, errors / scale)


@dataclass(frozen=True, eq=False)
class PoleAgreement:
    """Requested poles against the eigenvalues of a matrix, repeated poles judged fairly.

    Attributes
    ----------
    match : PoleMatch
        One-to-one matching of the eigenvalues to the poles.
    multiplicity : ndarray of int
        Size of each pole's cluster (1 for a simple pole); a count, dimensionless.
    allowed : ndarray
        Accepted relative error of each pole: ``tol^(1/k)`` (dimensionless).
    polynomial_error : float
        Largest ``|c_k(matrix) - c_k(poles)| / w_k`` over the coefficients of
        the characteristic polynomial, ``w_k`` the coefficients of ``prod (s
        + r_i)`` with ``r_i = max(|p_i|, 0.01 max(1, max |p|))`` (relative, dimensionless).
    tolerance : float
    passed : bool
    measure : str
        Which test decided.
    """

    match: PoleMatch
    multiplicity: np.ndarray
    allowed: np.ndarray
    polynomial_error: float
    tolerance: float
    passed: bool
    measure: str


def pole_agreement(requested: ArrayLike, matrix: ArrayLike, tol: float = 1e-6,
                   cluster: float = 1e-3) -> PoleAgreement:
    """Do the eigenvalues of ``matrix`` meet the requested poles, with multiplicity in mind?

    Simple poles: relative error (to ``max(1, |p|)``) at most ``tol``.
    Poles in a cluster of ``k`` (closer than ``cluster max(1, |p|)``):
    relative error at most ``tol^(1/k)`` and the characteristic polynomial of
    ``matrix`` within ``tol`` of ``prod (s - p_i)`` (relative to the
    coefficient sizes), which is well conditioned where the eigenvalues of a
    Jordan block are not.

    Parameters
    ----------
    requested : sequence of complex
        Poles (1/s or dimensionless).
    matrix : array_like, shape (n, n)
    tol : float
        Relative tolerance (dimensionless).
    cluster : float
        Relative radius grouping nearly repeated poles (dimensionless).

    Returns
    -------
    PoleAgreement
    """
    p = np.asarray(requested, dtype=complex).reshape(-1)
    M = np.atleast_2d(np.asarray(matrix, dtype=float))
    match = match_poles(p, np.linalg.eigvals(M))
    scale = np.maximum(1.0, np.abs(p))
    near = np.abs(p[:, None] - p[None, :]) <= cluster * np.maximum(scale[:, None], scale[None, :])
    # transitive closure of "near" (single linkage)
    reach = near.copy()
    for _ in range(p.size):
        nxt = (reach.astype(int) @ near.astype(int)) > 0
        if np.array_equal(nxt, reach):
            break
        reach = nxt
    mult = reach.sum(axis=1).astype(int)
    allowed = tol ** (1.0 / mult)
    floor = 0.01 * max(1.0, float(np.abs(p).max())) if p.size else 1.0
    r = np.maximum(np.abs(p), floor)
    weights = np.ones(1)
    for ri in r:  # coefficients of prod (s + r_i)
        weights = np.convolve(weights, [1.0, ri])
    target = np.ones(1, dtype=complex)
    for pi in p:
        target = np.convolve(target, [1.0, -pi])
    actual = np.poly(M)
    poly_err = float(np.max(np.abs(actual[1:] - target[1:].real) / weights[1:])) if p.size else 0.0
    repeated = bool(np.any(mult > 1))
    ok = bool(np.all(match.relative_errors <= allowed)) and (poly_err <= tol or not repeated)
    measure = ("characteristic polynomial (relative coefficient error) and pole errors within "
               "tol^(1/k) for k-fold poles" if repeated else "pole error relative to max(1, |p|)")
    return PoleAgreement(match, mult, allowed, poly_err, float(tol), ok, measure)


def symmetric(M: Any) -> np.ndarray:
    """``(M + M') / 2`` as a float array.

    Parameters
    ----------
    M : array_like, shape (n, n)
        A square matrix.
    """
    M = np.asarray(M, dtype=float)
    return 0.5 * (M + M.T)


def region_lmi_matrix(L: Any, M: Any, A: Any, X: Any) -> np.ndarray:
    """Chilali-Gahinet matrix ``L (x) X + M (x) (A X) + M' (x) (A X)'`` (symmetrised).

    For the LMI region ``D = {z : L + M z + M' conj(z) < 0}`` the
    eigenvalues of ``A`` all lie in ``D`` iff some ``X > 0`` makes this
    matrix negative definite.

    Parameters
    ----------
    L : array_like, shape (d, d)
        Symmetric (units of the eigenvalues).
    M : array_like, shape (d, d)
    A : array_like, shape (n, n)
        The closed-loop or error matrix (1/s or dimensionless).
    X : array_like, shape (n, n)
        The Lyapunov matrix (symmetric positive definite).

    Returns
    -------
    ndarray, shape (d n, d n)
    """
    L, M, A, X = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (L, M, A, X))
    n = A.shape[0]
    if A.shape != (n, n) or X.shape != (n, n) or L.shape != M.shape or L.shape[0] != L.shape[1]:
        raise DimensionError(f"region LMI: L {L.shape}, M {M.shape}, A {A.shape}, X {X.shape} "
                             "do not fit")
    d = L.shape[0]
    AX = A @ X
    out = np.zeros((d * n, d * n))
    for i in range(d):
        for j in range(d):
            out[i * n:(i + 1) * n, j * n:(j + 1) * n] = L[i, j] * X + M[i, j] * AX + M[j, i] * AX.T
    return symmetric(out)


@dataclass(frozen=True)
class LMIItem:
    """One condition of an LMI re-check: ``value`` compared with ``limit``.

    Attributes
    ----------
    name : str
    value, limit : float
    passed : bool
    unit : str
    """

    name: str
    value: float
    limit: float
    passed: bool
    unit: str = ""

    def as_dict(self) -> dict:
        """JSON-friendly record."""
        return {"name": self.name, "value": self.value, "limit": self.limit, "passed": self.passed,
                "unit": self.unit}


@dataclass(frozen=True, eq=False)
class ObserverLMIRecheck:
    """The observer LMI (28) evaluated from a stored solution.

    Attributes
    ----------
    items : tuple of LMIItem
        Block matrix (normalised, original units), ``P > 0``, ``Q > 0`` and
        the decay of ``A0 - L C`` the LMI implies.
    lmi_eigenvalues : ndarray, shape (2 n,)
        Of the normalised block matrix.
    error_eigenvalues : ndarray of complex, shape (n,)
        Of ``A0 - L C`` (1/s).
    """

    items: tuple[LMIItem, ...]
    lmi_eigenvalues: np.ndarray
    error_eigenvalues: np.ndarray

    @property
    def passed(self) -> bool:
        """Every item holds."""
        return all(item.passed for item in self.items)


def observer_lmi_recheck(A0: Any, C: Any, L: Any, P: Any, Q: Any, psi: float, *, margin: float,
                         omega: float, tolerance: float = 0.5) -> ObserverLMIRecheck:
    """Evaluate the observer LMI (28) of seed 001 at a stored solution.

    With the error matrix ``G = A0 - L C`` (so ``P L = K`` of the LMI) the
    condition reads::

        W = [[G' P + P G + psi^2 Q,  P],
             [P,                    -Q]]  < 0,   P > 0,   Q > 0

    (its Schur complement ``G' P + P G + psi^2 Q + P Q^-1 P < 0`` bounds
    the Lipschitz remainder and puts every eigenvalue of ``G`` left of
    ``-psi``, checked as well). The normalised matrix is ``W`` in the time
    unit ``1 / omega``: ``[[(G' P + P G + psi^2 Q) / omega, P], [P, -omega
    Q]]``; its largest eigenvalue must be ``<= -(1 - tolerance) margin``.

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        1/s.
    C : array_like, shape (q, n)
    L : array_like, shape (n, q)
        Observer gain (1/s per output unit).
    P, Q : array_like, shape (n, n)
        Stored LMI variables (``Q`` in s).
    psi : float
        Decay rate / Lipschitz weight (1/s).
    margin : float
        Margin of the normalised LMI the design required.
    omega : float
        Time scale (1/s) of the normalisation.
    tolerance : float
        Fraction of ``margin`` granted to solver round-off.

    Returns
    -------
    ObserverLMIRecheck
    """
    A0, C, L, P, Q = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (A0, C, L, P, Q))
    n = A0.shape[0]
    if A0.shape != (n, n) or P.shape != (n, n) or Q.shape != (n, n) or C.shape[1] != n \
            or L.shape != (n, C.shape[0]):
        raise DimensionError(f"observer LMI: A0 {A0.shape}, C {C.shape}, L {L.shape}, P {P.shape}, "
                             f"Q {Q.shape} do not fit")
    if not (math.isfinite(omega) and omega > 0):
        raise DimensionError(f"observer LMI: the time scale omega must be > 0, got {omega}")
    G = A0 - L @ C
    lyap = G.T @ P + P @ G + psi ** 2 * Q
    W = symmetric(np.block([[lyap, P], [P.T, -Q]]))
    Wn = symmetric(np.block([[lyap / omega, P], [P.T, -omega * Q]]))
    eig_n = np.linalg.eigvalsh(Wn)
    eig_w = float(np.max(np.linalg.eigvalsh(W)))
    err = np.linalg.eigvals(G)
    pmin = float(np.min(np.linalg.eigvalsh(symmetric(P))))
    qmin = float(np.min(np.linalg.eigvalsh(symmetric(Q))))
    need = -(1.0 - tolerance) * margin
    decay = float(np.max(err.real))
    items = (
        LMIItem("observer LMI block matrix, normalised (max eigenvalue <= -(1-tol) margin)",
                float(eig_n.max()), need, bool(eig_n.max() <= need), "normalised"),
        LMIItem("observer LMI block matrix, original units (max eigenvalue < 0)", eig_w, 0.0,
                bool(eig_w < 0)),
        LMIItem("P > 0 (min eigenvalue)", pmin, 0.0, bool(pmin > 0)),
        LMIItem("Q > 0 (min eigenvalue)", qmin, 0.0, bool(qmin > 0), "s"),
        LMIItem("A0 - L C decays faster than psi (max real part < -psi)", decay, -psi,
                bool(decay < -psi), "1/s"),
    )
    return ObserverLMIRecheck(items, eig_n, err)


def integral_augmentation(A: Any, B: Any, C1: Any, ts: float | None = None
                          ) -> tuple[np.ndarray, np.ndarray]:
    """The plant augmented with the integral of the tracking error.

    Continuous time (``ts`` None): ``z' = r - C1 x``, so ``Aa = [[A, 0],
    [-C1, 0]]``. Discrete time: ``z(k+1) = z(k) + ts (r(k) - C1 x(k))``, so
    ``Aa = [[A, 0], [-ts C1, I]]``. In both ``Ba = [B; 0]`` and the state
    feedback ``u = -K [x; z]`` closes the loop ``Aa - Ba K``.

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, m)
    C1 : array_like, shape (p, n)
        Rows of the tracked outputs.
    ts : float, optional
        Sampling period (s) of a discrete model.

    Returns
    -------
    Aa : ndarray, shape (n + p, n + p)
    Ba : ndarray, shape (n + p, m)
    """
    A, B, C1 = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (A, B, C1))
    n, m, p = A.shape[0], B.shape[1], C1.shape[0]
    if A.shape != (n, n) or B.shape[0] != n or C1.shape[1] != n:
        raise DimensionError(f"integral augmentation: A {A.shape}, B {B.shape}, C1 {C1.shape} "
                             "do not fit")
    if ts is None:
        lower = np.hstack([-C1, np.zeros((p, p))])
    else:
        lower = np.hstack([-float(ts) * C1, np.eye(p)])
    Aa = np.vstack([np.hstack([A, np.zeros((n, p))]), lower])
    Ba = np.vstack([B, np.zeros((p, m))])
    return Aa, Ba
