"""Exact pole placement with an accuracy report, and the checks shared by the placement routes.

Tits-Yang (``place``, MIMO: ``scipy.signal.place_poles(method="YT")``, the
routine python-control's ``place`` wraps) or Ackermann's formula (``acker``,
SISO: `ackermann`, python-control's ``acker`` formula in numpy); both are
called directly, without importing python-control (about 0.9 s of imports
for one call; the tests cross-check both against python-control). Achieved
poles, largest pole error, condition number of the closed-loop eigenvector
matrix. Uncontrollable (unobservable) pairs are refused before placing,
naming the modes (PBH). The routes are collected in
`tanksynth.design.placement.canonical`.

Accuracy (`placement_accuracy`)
    The eigenvalues of a k-fold pole are only computable to about
    ``eps^(1/k)`` (a Jordan block), so a fixed pole-error test refuses
    correct gains. Requested poles are grouped in clusters (poles closer than
    ``CLUSTER_RADIUS max(1, |p|)``); a simple pole must be met to ``tol
    max(1, |p|)``, a pole of a k-cluster to ``tol^(1/k) max(1, |p|)``, and
    then the characteristic polynomial of the closed loop (well conditioned
    for repeated roots) must match ``prod (s - p_i)`` coefficient by
    coefficient to ``tol`` relative to the coefficients of ``prod (s + r_i)``,
    ``r_i = max(|p_i|, 0.01 max(1, |p|))``. The measure used and its value
    are reported.
Robustness (`robustness_report`)
    The complex stability radius of the closed loop, ``min over the stability
    boundary of sigma_min(z I - A_cl)``, relative to ``||A||_2``: the
    smallest relative (unstructured) perturbation of ``A`` that puts a
    closed-loop pole on the stability boundary. Below
    `FRAGILITY_THRESHOLD` the design adapters refuse the gain unless the
    spec says ``allow_fragile = true``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

# Module import (not names), so that a test may replace the rank functions.
from tanksynth.analysis import blas as _blas
from tanksynth.analysis import rank as _rank
from tanksynth.design.result import FeedbackGain
from tanksynth.design.matrices import complex_pairs, matrix_pair, real_matrix
from tanksynth.errors import (DimensionError, InfeasibleDesign, SpecError, UncontrollableError,
                              UnobservableError)

__all__ = [
    "PlacementResult",
    "place_state_feedback",
    "place_observer",
    "ackermann",
    "checked_poles",
    "pole_errors",
    "pole_clusters",
    "placement_accuracy",
    "stability_radius",
    "robustness_report",
    "refuse_fragile",
    "CLUSTER_RADIUS",
    "FRAGILITY_THRESHOLD",
]

#: Requested poles closer than this (relative to ``max(1, |p|)``) form one cluster.
CLUSTER_RADIUS = 1e-3
#: Smallest accepted relative stability radius ``r / ||A||_2`` of a closed loop
#: (dimensionless): a loop that a relative change of ``A`` smaller than this
#: destabilises is refused unless ``allow_fragile = true``.
FRAGILITY_THRESHOLD = 1e-6


# -------------------------------------------------------------------- helpers
def _refuse_uncontrollable(A: np.ndarray, B: np.ndarray, names: Sequence[str] | None,
                           dual: bool) -> None:
    rank = _rank.controllability_rank(A, B)
    if rank.full:
        return
    pbh = _rank.pbh_test(A, B=B, state_names=names)
    modes = "; ".join(f"eigenvalue {m.eigenvalue:.4g} in states {list(m.states)}" for m in pbh.modes)
    if dual:
        raise UnobservableError(f"(A, C) is not observable (rank {rank.rank} < {rank.n}); "
                                f"unobservable modes: {modes or 'not isolated by PBH'}")
    raise UncontrollableError(f"(A, B) is not controllable (rank {rank.rank} < {rank.n}); "
                              f"uncontrollable modes: {modes or 'not isolated by PBH'}")


def checked_poles(poles: Any, n: int) -> np.ndarray:
    """The requested poles as ``n`` finite complex numbers, complex ones in conjugate pairs.

    Parameters
    ----------
    poles : array_like of complex
        Requested poles (1/s in continuous time, dimensionless in discrete time).
    n : int
        Number of states: how many poles are needed.

    Returns
    -------
    ndarray of complex, shape (n,)

    Raises
    ------
    SpecError
        Not numbers, not finite, or complex poles without their conjugates (key ``poles``).
    DimensionError
        Another number of poles than ``n``.
    """
    try:
        p = np.asarray(poles, dtype=complex).reshape(-1)
    except (TypeError, ValueError):
        raise SpecError(f"poles must be numbers, got {poles!r}", key="poles") from None
    if p.size != n:
        raise DimensionError(f"{p.size} poles given, expected n = {n}")
    if not np.all(np.isfinite(p)):
        raise SpecError("poles must be finite", key="poles")
    a = np.sort_complex(p)
    b = np.sort_complex(np.conj(p))
    if not np.allclose(a, b, rtol=0, atol=1e-12 * max(1.0, float(np.max(np.abs(p))))):
        raise SpecError("complex poles must come in conjugate pairs", key="poles")
    return p


def pole_errors(requested: Any, achieved: Any) -> tuple[np.ndarray, float]:
    """Match achieved to requested poles (assignment) and return the errors.

    Parameters
    ----------
    requested, achieved : array_like of complex, same length

    Returns
    -------
    errors : ndarray
        ``|achieved - requested|`` after the best one-to-one matching.
    max_error : float
    """
    from scipy.optimize import linear_sum_assignment  # deferred: scipy.optimize imports in ~0.15 s
    r = np.asarray(requested, dtype=complex).reshape(-1)
    a = np.asarray(achieved, dtype=complex).reshape(-1)
    cost = np.abs(r[:, None] - a[None, :])
    rows, cols = linear_sum_assignment(cost)
    err = cost[rows, cols]
    return err, float(err.max()) if err.size else 0.0


def pole_clusters(poles: Any, radius: float = CLUSTER_RADIUS) -> np.ndarray:
    """Multiplicity of each pole: the size of its cluster of (nearly) repeated poles.

    Parameters
    ----------
    poles : array_like of complex
        The poles (1/s in continuous time, dimensionless in discrete time).
    radius : float
        Poles closer than ``radius max(1, |p|)`` are linked (single linkage);
        dimensionless (relative).

    Returns
    -------
    ndarray of int
        ``k_i`` for each pole, in the order given (1 for a simple pole); a
        count (dimensionless).
    """
    p = np.asarray(poles, dtype=complex).reshape(-1)
    label = np.arange(p.size)
    scale = np.maximum(1.0, np.abs(p))
    for i in range(p.size):
        for j in range(i + 1, p.size):
            if abs(p[i] - p[j]) <= radius * max(scale[i], scale[j]):
                old, new = label[j], label[i]
                label[label == old] = new
    return np.array([int(np.sum(label == lab)) for lab in label])


def placement_accuracy(requested: Any, closed_loop: Any, tol: float = 1e-6) -> dict:
    """How well ``eig(closed_loop)`` meets the requested poles, judged by what is well conditioned.

    Simple poles: matched pole error ``<= tol max(1, |p|)``. Poles of a
    k-cluster (repeated or nearly repeated): pole error ``<= tol^(1/k)
    max(1, |p|)`` (a k-fold eigenvalue is only computable to ``eps^(1/k)``)
    *and* the characteristic polynomial of the closed loop within ``tol`` of
    ``prod (s - p_i)``, coefficient by coefficient, relative to the
    coefficients of ``prod (s + r_i)``, ``r_i = max(|p_i|, 0.01 max(1,
    max |p|))``.

    Parameters
    ----------
    requested : array_like of complex, length n
        Poles (1/s or dimensionless).
    closed_loop : array_like, shape (n, n)
    tol : float
        Relative tolerance (dimensionless).

    Returns
    -------
    dict
        ``passed``, ``measure`` (which test decided), ``max_pole_error``,
        ``max_relative_pole_error``, ``pole_tolerances`` (per pole),
        ``multiplicity`` (per pole), ``characteristic_polynomial_relative_error``,
        ``tolerance``.
    """
    from scipy.optimize import linear_sum_assignment  # deferred: scipy.optimize imports in ~0.15 s
    p = np.asarray(requested, dtype=complex).reshape(-1)
    Acl = np.asarray(closed_loop, dtype=float)
    ach = np.linalg.eigvals(Acl)
    r = p.copy()
    a = np.asarray(ach, dtype=complex)
    cost = np.abs(r[:, None] - a[None, :])
    rows, cols = linear_sum_assignment(cost)
    err = np.empty(p.size)
    err[rows] = cost[rows, cols]
    mult = pole_clusters(p)
    scale = np.maximum(1.0, np.abs(p))
    allowed = scale * tol ** (1.0 / mult)
    rel = err / scale
    floor = 0.01 * max(1.0, float(np.max(np.abs(p)))) if p.size else 1.0
    weights = np.abs(np.poly(np.maximum(np.abs(p), floor)))[1:]
    want = np.real_if_close(np.poly(p))[1:]
    got = np.poly(Acl)[1:]
    coef = float(np.max(np.abs(got - want) / weights)) if p.size else 0.0
    repeated = bool(np.any(mult > 1))
    poles_ok = bool(np.all(err <= allowed))
    passed = poles_ok and (coef <= tol if repeated else True)
    measure = ("characteristic polynomial coefficients (relative) and multiplicity-scaled pole error "
               "tol^(1/k)" if repeated else "pole error relative to max(1, |p|)")
    return {"passed": passed, "measure": measure, "tolerance": float(tol),
            "max_pole_error": float(err.max()) if err.size else 0.0,
            "max_relative_pole_error": float(rel.max()) if rel.size else 0.0,
            "pole_tolerances": (allowed / scale).tolist(), "multiplicity": mult.tolist(),
            "characteristic_polynomial_relative_error": coef,
            "value": coef if repeated else (float(rel.max()) if rel.size else 0.0)}


def _diagonal_blocks(Acl: np.ndarray) -> list[np.ndarray] | None:
    """The diagonal blocks of ``Acl`` after a symmetric permutation, stacked by size.

    The connected components of the sparsity graph of ``Acl`` (exact zeros;
    ``z I - Acl`` has the same components): a list of (g, b, b) stacks, or
    None when there is one component (a dense matrix).
    """
    n = Acl.shape[0]
    r, c = np.nonzero(Acl)
    count, label = connected_components(coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n)),
                                        directed=False)
    if count <= 1:
        return None
    by_size: dict[int, list[np.ndarray]] = {}
    for comp in range(count):
        idx = np.flatnonzero(label == comp)
        by_size.setdefault(idx.size, []).append(idx)
    return [Acl[np.array(group)[:, :, None], np.array(group)[:, None, :]]
            for group in by_size.values()]


def stability_radius(closed_loop: Any, domain: str) -> tuple[float, complex]:
    """Complex stability radius ``min_{z on the stability boundary} sigma_min(z I - A_cl)``.

    The smallest 2-norm of a complex perturbation ``E`` such that ``A_cl + E``
    has an eigenvalue on the boundary (imaginary axis, or unit circle in
    discrete time). Computed on a grid of the boundary (dense near the
    eigenvalues' frequencies) refined by bounded scalar minimisation, so the
    value is an upper estimate of the exact radius. When ``A_cl`` is block
    diagonal up to a permutation (exact zeros), each ``sigma_min`` is the
    smallest of its blocks' (the same value, without an n x n SVD per point).

    Parameters
    ----------
    closed_loop : array_like, shape (n, n)
        1/s (continuous) or dimensionless (discrete).
    domain : {"continuous", "discrete"}

    Returns
    -------
    radius : float
        In the units of ``closed_loop`` (1/s in continuous time); 0 when a
        pole is already outside.
    where : complex
        The boundary point of the minimum.
    """
    from scipy.optimize import minimize_scalar  # deferred: scipy.optimize imports in ~0.15 s
    Acl = np.asarray(closed_loop, dtype=float)
    n = Acl.shape[0]
    lam = np.linalg.eigvals(Acl)
    unstable = (np.abs(lam) >= 1.0) if domain == "discrete" else (lam.real >= 0.0)
    if np.any(unstable):
        return 0.0, complex(lam[np.argmax(np.abs(lam) if domain == "discrete" else lam.real)])
    eye = np.eye(n)
    if domain == "discrete":
        point = lambda w: np.exp(1j * w)  # noqa: E731
        grid = np.concatenate([np.linspace(0.0, np.pi, 721), np.abs(np.angle(lam))])
        lo_b, hi_b = 0.0, np.pi
    else:
        point = lambda w: 1j * w  # noqa: E731
        size = max(float(np.max(np.abs(lam))), float(np.linalg.norm(Acl, 2)), 1e-300)
        grid = np.concatenate([[0.0], np.logspace(np.log10(size) - 4, np.log10(size) + 3, 561),
                               np.abs(lam.imag)])
        lo_b, hi_b = 0.0, 1e3 * size
    grid = np.unique(grid)
    blocks = _diagonal_blocks(Acl)

    def smin(w: float) -> float:
        z = point(w)
        if blocks is None:
            return float(np.linalg.svd(z * eye - Acl, compute_uv=False)[-1])
        # z I - A_cl is block diagonal up to one permutation: the union of the blocks' values
        return float(min(np.min(np.linalg.svd(z * np.eye(b.shape[1]) - b, compute_uv=False)[:, -1])
                         for b in blocks))

    with _blas.small_dense():
        vals = np.array([smin(w) for w in grid])
    best_w, best = float(grid[np.argmin(vals)]), float(vals.min())
    for i in np.argsort(vals)[:3]:
        a = grid[max(i - 1, 0)]
        b = grid[min(i + 1, grid.size - 1)]
        if b > a:
            with _blas.small_dense():
                res = minimize_scalar(smin, bounds=(max(a, lo_b), min(b, hi_b)), method="bounded",
                                      options={"xatol": 1e-12 * max(1.0, abs(b))})
            if res.fun < best:
                best, best_w = float(res.fun), float(res.x)
    return best, complex(point(best_w))


def robustness_report(A: Any, closed_loop: Any, gain: Any, domain: str,
                      threshold: float = FRAGILITY_THRESHOLD) -> dict:
    """Robustness figures of a closed loop (or observer error matrix) and the fragility verdict.

    Parameters
    ----------
    A : array_like, shape (n, n)
        The open-loop matrix a model error would perturb.
    closed_loop : array_like, shape (n, n)
        ``A - B K`` or ``A - L C``.
    gain : array_like
        ``K`` or ``L``.
    domain : {"continuous", "discrete"}
    threshold : float
        Smallest accepted relative stability radius (dimensionless).

    Returns
    -------
    dict
        ``relative_stability_radius`` (``r / ||A||_2``; the smallest relative
        change of ``A`` that destabilises the loop), ``stability_radius``,
        ``boundary_point``, ``eigenvector_condition``, ``gain_norm``,
        ``condition_times_gain`` (eigenvector condition times ``||gain||_2``),
        ``threshold`` and ``fragile``.
    """
    A = np.asarray(A, dtype=float)
    Acl = np.asarray(closed_loop, dtype=float)
    r, z = stability_radius(Acl, domain)
    with _blas.small_dense():
        normA = float(np.linalg.norm(A, 2)) or 1.0
        _, V = np.linalg.eig(Acl)
        with np.errstate(all="ignore"):
            cond = float(np.linalg.cond(V))
        gnorm = float(np.linalg.norm(np.asarray(gain, dtype=float), 2))
    cond = cond if np.isfinite(cond) else float("inf")
    rel = r / normA
    return {"relative_stability_radius": rel, "stability_radius": r,
            "boundary_point": [z.real, z.imag], "norm_A": normA,
            "eigenvector_condition": cond, "gain_norm": gnorm,
            "condition_times_gain": cond * gnorm, "threshold": threshold,
            "fragile": bool(rel < threshold),
            "measure": "smallest relative complex perturbation ||E||/||A|| putting a pole of the "
                       "closed loop on the stability boundary (stability radius)"}


def refuse_fragile(report: dict, what: str, option: str = "allow_fragile") -> None:
    """Raise `InfeasibleDesign` for a fragile loop (``report["fragile"]``), naming the option.

    Parameters
    ----------
    report : dict
        From `robustness_report`.
    what : str
        The loop, for the message (``"A - B K"``).
    option : str
        The spec option that accepts a fragile design.
    """
    if not report["fragile"]:
        return
    raise InfeasibleDesign(
        f"fragile design: a relative change of A of {report['relative_stability_radius']:.3g} "
        f"(smaller than the threshold {report['threshold']:g}) puts a pole of {what} on the "
        f"stability boundary; gain norm {report['gain_norm']:.3g}, eigenvector condition "
        f"{report['eigenvector_condition']:.3g} (nearly uncontrollable/unobservable modes?); set "
        f"{option} = true to accept it")


# -------------------------------------------------------------- exact placement
@dataclass(frozen=True)
class PlacementResult(FeedbackGain):
    """Exact pole placement with its accuracy report.

    Attributes
    ----------
    gain_matrix : ndarray
        Read as ``K`` / ``L`` (`FeedbackGain`; ``gain`` is deprecated): ``K`` (m, n) or ``L`` (n, q).
    kind : str
        ``"state_feedback"`` or ``"observer"``.
    method : str
        ``"place"`` (Tits-Yang, scipy's ``place_poles`` as python-control's ``place``) or
        ``"acker"`` (Ackermann).
    requested, achieved : ndarray of complex
        Requested poles and eigenvalues of the closed loop (1/s in continuous
        time, dimensionless in discrete time).
    errors : ndarray
        Matched ``|achieved - requested|``.
    max_pole_error : float
    eigenvector_condition : float
        2-norm condition number of the closed-loop eigenvector matrix
        (dimensionless; large: poles sensitive to perturbations of the gain).
    closed_loop : ndarray, shape (n, n)
        ``A - B K`` or ``A - L C``.
    accuracy : dict
        `placement_accuracy` of the closed loop: the measure that decided
        (pole error, or characteristic polynomial with multiplicity-scaled
        pole tolerances for repeated poles) and its value.
    """

    gain_matrix: np.ndarray
    kind: str
    method: str
    requested: np.ndarray
    achieved: np.ndarray
    errors: np.ndarray
    max_pole_error: float
    eigenvector_condition: float
    closed_loop: np.ndarray
    accuracy: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """JSON-friendly accuracy report."""
        return {"kind": self.kind, "method": self.method,
                "requested": complex_pairs(self.requested), "achieved": complex_pairs(self.achieved),
                "max_pole_error": self.max_pole_error,
                "eigenvector_condition": self.eigenvector_condition,
                "gain_norm": float(np.linalg.norm(self.gain_matrix, 2)),
                "accuracy": self.accuracy}


def ackermann(A: Any, B: Any, poles: Any) -> np.ndarray:
    """Single-input pole placement by Ackermann's formula, ``K = e_n' W^-1 phi(A)``.

    ``W = [b, A b, ..., A^(n-1) b]`` is the controllability matrix and
    ``phi(s) = prod (s - p_i)`` the requested characteristic polynomial,
    evaluated at ``A`` by Horner's scheme. The same formula as python-control's
    ``acker`` (which sums matrix powers instead of Horner's scheme: the gains
    agree to rounding, checked on random systems in the tests), without
    importing python-control (~0.9 s: scipy.signal, scipy.stats, pyplot).
    Only as accurate as ``W`` is conditioned: callers judge the poles.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (1/s in continuous time, dimensionless in discrete time).
    B : array_like, shape (n, 1)
        Input column (state units per input unit, per second in continuous time).
    poles : array_like of complex, length n
        Requested poles, complex ones in conjugate pairs (units of ``A``).

    Returns
    -------
    ndarray, shape (1, n)
        ``K`` with ``eig(A - B K) = poles`` (input units per state unit).

    Raises
    ------
    ValueError
        ``B`` is not one column, or the controllability matrix is rank deficient
        (numpy ``matrix_rank``).
    """
    A = np.asarray(A, dtype=float)
    b = np.asarray(B, dtype=float)
    n = A.shape[0]
    if b.ndim != 2 or b.shape != (n, 1):
        raise ValueError(f"Ackermann's formula needs one input column of {n} rows, got shape "
                         f"{b.shape}")
    W = np.empty((n, n))
    W[:, 0] = b[:, 0]
    for k in range(1, n):
        W[:, k] = A @ W[:, k - 1]
    rank = int(np.linalg.matrix_rank(W))
    if rank < n:
        raise ValueError(f"(A, b) is not controllable: controllability matrix of rank {rank} < {n}")
    phi = np.eye(n)
    for c in np.real(np.poly(np.asarray(poles, dtype=complex).reshape(-1)))[1:]:
        phi = phi @ A + c * np.eye(n)
    return np.linalg.solve(W, phi)[-1].reshape(1, n)


def _tits_yang(A: np.ndarray, B: np.ndarray, poles: np.ndarray) -> np.ndarray:
    """``scipy.signal.place_poles(A, B, poles, method="YT").gain_matrix``: what python-control's
    ``place`` returns (it converts the arrays and calls exactly this), without python-control's
    own import (~0.45 s more: pyplot and its modules)."""
    from scipy.signal import place_poles  # here, not at import: scipy.signal ~0.4 s

    return place_poles(A, B, np.atleast_1d(np.squeeze(poles)), method="YT").gain_matrix


def place_state_feedback(A: Any, B: Any, poles: Any, method: str = "auto", tol: float = 1e-6,
                         state_names: Sequence[str] | None = None,
                         _dual: bool = False) -> PlacementResult:
    """Exact pole placement ``eig(A - B K) = poles`` (python-control's ``place`` / ``acker`` routines).

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, m)
    poles : array_like of complex, length n
        Complex poles in conjugate pairs (1/s in continuous time).
    method : {"auto", "place", "acker"}
        ``auto``: ``acker`` for one input, ``place`` otherwise. ``place``:
        Tits-Yang, ``scipy.signal.place_poles(method="YT")`` (what
        python-control's ``place`` calls: the same gain); ``acker``:
        `ackermann` (python-control's ``acker`` formula, Horner's scheme).
    tol : float
        Largest accepted pole error relative to ``max(1, |pole|)`` for a
        simple pole; repeated poles are judged by `placement_accuracy`
        (characteristic polynomial to ``tol``, pole error to ``tol^(1/k)``);
        dimensionless.
    state_names : sequence of str, optional

    Returns
    -------
    PlacementResult

    Raises
    ------
    UncontrollableError
        Before placing, naming the modes.
    SpecError
        Poles not in conjugate pairs, or a pole repeated more than
        ``rank(B)`` times for ``place``.
    InfeasibleDesign
        The achieved poles miss the requested ones by more than ``tol``.
    """
    A, B = matrix_pair(A, B, "C'" if _dual else "B")
    n, m = B.shape
    p = checked_poles(poles, n)
    if method not in ("auto", "place", "acker"):
        raise SpecError(f"unknown placement method {method!r}; expected auto, place or acker",
                        key="method")
    if method == "auto":
        method = "acker" if m == 1 else "place"
    if method == "acker" and m != 1:
        raise DimensionError(f"acker needs a single input (column), got {m}")
    _refuse_uncontrollable(A, B, state_names, _dual)
    try:
        K = ackermann(A, B, p) if method == "acker" else _tits_yang(A, B, p)
    except ValueError as exc:
        raise SpecError(f"{method} cannot place these poles: {exc}", key="poles") from None
    K = K.reshape(m, n)
    Acl = A - B @ K
    ach, V = np.linalg.eig(Acl)
    err, emax = pole_errors(p, ach)
    acc = placement_accuracy(p, Acl, tol)
    if not acc["passed"]:
        raise InfeasibleDesign(
            f"pole placement inaccurate: largest pole error {emax:.3g} (relative "
            f"{acc['max_relative_pole_error']:.3g}, allowed {min(acc['pole_tolerances']):.3g} and "
            f"up, multiplicities {acc['multiplicity']}); characteristic polynomial relative error "
            f"{acc['characteristic_polynomial_relative_error']:.3g} (tolerance {tol:g}); "
            f"eigenvector condition {np.linalg.cond(V):.3g}")
    kind = "observer" if _dual else "state_feedback"
    gain = K.T if _dual else K
    cl = Acl.T if _dual else Acl
    return PlacementResult(gain, kind, method, p, np.linalg.eigvals(cl), err, emax,
                           float(np.linalg.cond(V)), cl, acc)


def place_observer(A: Any, C: Any, poles: Any, method: str = "auto", tol: float = 1e-6,
                   state_names: Sequence[str] | None = None) -> PlacementResult:
    """Exact observer placement ``eig(A - L C) = poles`` (dual of state feedback).

    Parameters
    ----------
    A : array_like, shape (n, n)
    C : array_like, shape (q, n)
    poles : array_like of complex, length n
        Observer poles (1/s in continuous time, dimensionless in discrete time).
    method : {"auto", "place", "acker"}
    tol : float
    state_names : sequence of str, optional

    Returns
    -------
    PlacementResult
        ``gain`` is ``L`` (n, q).

    Raises
    ------
    UnobservableError
        Before placing, naming the modes.
    """
    A = real_matrix(A, "A")
    C = real_matrix(C, "C")
    if C.shape[1] != A.shape[0]:
        raise DimensionError(f"C has {C.shape[1]} columns, expected n = {A.shape[0]}")
    return place_state_feedback(A.T, C.T, poles, method, tol, state_names, _dual=True)


