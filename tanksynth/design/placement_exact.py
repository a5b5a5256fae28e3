"""Exact pole placement with an accuracy report, and the checks shared by the placement routes.

python-control ``place`` (Tits-Yang, MIMO) or ``acker`` (SISO): achieved
poles, largest pole error, condition number of the closed-loop eigenvector
matrix. Uncontrollable (unobservable) pairs are refused before placing,
naming the modes (PBH). The routes are collected in
`tanksynth.design.placement`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import control
import numpy as np
from scipy.optimize import linear_sum_assignment

from tanksynth.errors import (DimensionError, InfeasibleDesign, SpecError, UncontrollableError,
                      UnobservableError)
# Module import (not names), so that a test may replace the rank functions.
from tanksynth.analysis import rank as _rank

__all__ = [
    "PlacementResult",
    "place_state_feedback",
    "place_observer",
    "pole_errors",
]


# -------------------------------------------------------------------- helpers
def _matrix(value: Any, name: str) -> np.ndarray:
    try:
        arr = np.atleast_2d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a real 2-D array") from None
    if arr.ndim != 2 or not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be a finite 2-D array")
    return arr


def _pair(A: Any, B: Any, nameB: str = "B") -> tuple[np.ndarray, np.ndarray]:
    A = _matrix(A, "A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise DimensionError(f"A must be square, got shape {A.shape}")
    B = _matrix(B, nameB)
    if B.shape[0] != n:
        raise DimensionError(f"{nameB} has {B.shape[0]} rows, expected n = {n}")
    return A, B


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


def _poles(poles: Any, n: int) -> np.ndarray:
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
    r = np.asarray(requested, dtype=complex).reshape(-1)
    a = np.asarray(achieved, dtype=complex).reshape(-1)
    cost = np.abs(r[:, None] - a[None, :])
    rows, cols = linear_sum_assignment(cost)
    err = cost[rows, cols]
    return err, float(err.max()) if err.size else 0.0


def _complex_list(values: np.ndarray) -> list[list[float]]:
    return [[float(v.real), float(v.imag)] for v in np.sort_complex(np.asarray(values, dtype=complex))]


# -------------------------------------------------------------- exact placement
@dataclass(frozen=True)
class PlacementResult:
    """Exact pole placement with its accuracy report.

    Attributes
    ----------
    gain : ndarray
        ``K`` (m, n) or ``L`` (n, q).
    kind : str
        ``"state_feedback"`` or ``"observer"``.
    method : str
        ``"place"`` (python-control, Tits-Yang) or ``"acker"``.
    requested, achieved : ndarray of complex
        Requested poles and eigenvalues of the closed loop.
    errors : ndarray
        Matched ``|achieved - requested|``.
    max_pole_error : float
    eigenvector_condition : float
        2-norm condition number of the closed-loop eigenvector matrix
        (large: poles sensitive to perturbations of the gain).
    closed_loop : ndarray, shape (n, n)
        ``A - B K`` or ``A - L C``.
    """

    gain: np.ndarray
    kind: str
    method: str
    requested: np.ndarray
    achieved: np.ndarray
    errors: np.ndarray
    max_pole_error: float
    eigenvector_condition: float
    closed_loop: np.ndarray

    def as_dict(self) -> dict:
        """JSON-friendly accuracy report."""
        return {"kind": self.kind, "method": self.method,
                "requested": _complex_list(self.requested), "achieved": _complex_list(self.achieved),
                "max_pole_error": self.max_pole_error,
                "eigenvector_condition": self.eigenvector_condition,
                "gain_norm": float(np.linalg.norm(self.gain, 2))}


def place_state_feedback(A: Any, B: Any, poles: Any, method: str = "auto", tol: float = 1e-6,
                         state_names: Sequence[str] | None = None,
                         _dual: bool = False) -> PlacementResult:
    """Exact pole placement ``eig(A - B K) = poles`` with python-control.

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, m)
    poles : array_like of complex, length n
        Complex poles in conjugate pairs (1/s in continuous time).
    method : {"auto", "place", "acker"}
        ``auto``: ``acker`` for one input, ``place`` (Tits-Yang) otherwise.
    tol : float
        Largest accepted pole error relative to ``max(1, |pole|)``.
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
    A, B = _pair(A, B, "C'" if _dual else "B")
    n, m = B.shape
    p = _poles(poles, n)
    if method not in ("auto", "place", "acker"):
        raise SpecError(f"unknown placement method {method!r}; expected auto, place or acker",
                        key="method")
    if method == "auto":
        method = "acker" if m == 1 else "place"
    if method == "acker" and m != 1:
        raise DimensionError(f"acker needs a single input (column), got {m}")
    _refuse_uncontrollable(A, B, state_names, _dual)
    try:
        K = np.asarray(control.acker(A, B, p) if method == "acker" else control.place(A, B, p),
                       dtype=float)
    except ValueError as exc:
        raise SpecError(f"{method} cannot place these poles: {exc}", key="poles") from None
    K = K.reshape(m, n)
    Acl = A - B @ K
    ach, V = np.linalg.eig(Acl)
    err, emax = pole_errors(p, ach)
    rel = float(np.max(err / np.maximum(1.0, np.abs(p))))
    if rel > tol:
        raise InfeasibleDesign(f"pole placement inaccurate: largest pole error {emax:.3g} "
                               f"(relative {rel:.3g} > {tol:g}); eigenvector condition "
                               f"{np.linalg.cond(V):.3g}")
    kind = "observer" if _dual else "state_feedback"
    gain = K.T if _dual else K
    cl = Acl.T if _dual else Acl
    return PlacementResult(gain, kind, method, p, np.linalg.eigvals(cl), err, emax,
                           float(np.linalg.cond(V)), cl)


def place_observer(A: Any, C: Any, poles: Any, method: str = "auto", tol: float = 1e-6,
                   state_names: Sequence[str] | None = None) -> PlacementResult:
    """Exact observer placement ``eig(A - L C) = poles`` (dual of state feedback).

    Parameters
    ----------
    A : array_like, shape (n, n)
    C : array_like, shape (q, n)
    poles : array_like of complex, length n
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
    A = _matrix(A, "A")
    C = _matrix(C, "C")
    if C.shape[1] != A.shape[0]:
        raise DimensionError(f"C has {C.shape[1]} columns, expected n = {A.shape[0]}")
    return place_state_feedback(A.T, C.T, poles, method, tol, state_names, _dual=True)


