"""Pole placement: LMI regions (Chilali-Gahinet), exact placement, canonical form.

Three routes to a state-feedback gain ``K`` (``u = -K x``) or an observer gain
``L`` (error dynamics ``A - L C``):

LMI regions
    ``D = {z : L_D + M_D z + M_D' conj(z) < 0}``: half-plane ``Re z < -alpha``,
    disk (centre, radius; the natural region in discrete time), conic sector,
    and intersections of these. ``A - B K`` has all its eigenvalues in ``D``
    iff there is ``X > 0`` with ``L_D (x) X + M_D (x) (A X - B Y) + M_D' (x)
    (A X - B Y)' < 0``, ``K = Y X^-1``. Observers use the dual ``(A', C')``.
    Solved with cvxpy + Clarabel after scaling (diagonal balancing of ``A``,
    input normalisation, time scaling in continuous time), with an explicit
    margin, and re-checked in numpy (LMI eigenvalues, closed-loop
    eigenvalues inside the region).
Exact placement
    python-control ``place`` (Tits-Yang, MIMO) or ``acker`` (SISO) with an
    accuracy report: achieved poles, largest pole error, condition number of
    the closed-loop eigenvector matrix.
Observer canonical form (seed 004 eq. 27-29)
    ``Delta = Q_O^-1 Qbar_O``, ``Psi = Delta Psi_o``, in exact arithmetic.

Integral action for tracking (seed 000 eq. 13-16) augments ``(A_d, B_d)``
with ``z(k+1) = z(k) + ts (y_r - C1 x)``; the gain is ``K = [K1 K2]``.

The LMI-region route is `tanksynth.design.placement.regions`, exact placement
`tanksynth.design.placement.exact`; every route is importable from here.
"""

from __future__ import annotations

import warnings

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import sympy as sp

from tanksynth.design.matrices import matrix_pair, real_matrix
from tanksynth.design.placement.exact import (PlacementResult, checked_poles, place_observer,
                                              place_state_feedback, pole_errors)
from tanksynth.design.placement.regions import LMIPlacementResult, lmi_observer, lmi_state_feedback
from tanksynth.errors import DimensionError, SpecError, UnobservableError
from tanksynth.plants.base import exact

__all__ = [
    "LMIPlacementResult",
    "lmi_state_feedback",
    "lmi_observer",
    "PlacementResult",
    "place_state_feedback",
    "place_observer",
    "AugmentedSystem",
    "integral_augmentation",
    "CanonicalObserver",
    "canonical_observer",
    "pole_errors",
]


# ------------------------------------------------------------- integral action
@dataclass(frozen=True)
class AugmentedSystem:
    """Discrete plant augmented with tracking integrators (seed 000 eq. 14-15).

    ``x_e = [x; z]``, ``x_e(k+1) = A x_e + B u + Br y_r``.

    Attributes
    ----------
    A : ndarray, shape (n+p, n+p)
        ``[[A_d, 0], [-ts C1, I]]``.
    B : ndarray, shape (n+p, m)
        ``[[B_d], [0]]``.
    Br : ndarray, shape (n+p, p)
        ``[[0], [ts I]]``.
    C1 : ndarray, shape (p, n)
        Tracked outputs.
    ts : float
        Sampling period (s).
    """

    A: np.ndarray
    B: np.ndarray
    Br: np.ndarray
    C1: np.ndarray
    ts: float

    @property
    def n(self) -> int:
        """Plant states."""
        return self.C1.shape[1]

    @property
    def p(self) -> int:
        """Integrators."""
        return self.C1.shape[0]


def integral_augmentation(Ad: Any, Bd: Any, C1: Any, ts: float) -> AugmentedSystem:
    """Augment ``(A_d, B_d)`` with ``z(k+1) = z(k) + ts (y_r - C1 x)`` (seed 000 eq. 13-15).

    Parameters
    ----------
    Ad : array_like, shape (n, n)
    Bd : array_like, shape (n, m)
        State unit per input unit.
    C1 : array_like, shape (p, n)
        Tracked outputs, ``p <= m``.
    ts : float
        Sampling period (s, > 0).

    Returns
    -------
    AugmentedSystem
    """
    Ad, Bd = matrix_pair(Ad, Bd, "Bd")
    C1 = real_matrix(C1, "C1")
    n, m = Bd.shape
    p = C1.shape[0]
    if C1.shape[1] != n:
        raise DimensionError(f"C1 has {C1.shape[1]} columns, expected n = {n}")
    if p > m:
        raise DimensionError(f"{p} tracked outputs but only {m} inputs (seed 000 needs p <= m)")
    if not (isinstance(ts, (int, float)) and np.isfinite(ts) and ts > 0):
        raise SpecError(f"sampling period must be > 0 s, got {ts!r}", key="sampling.ts")
    A = np.block([[Ad, np.zeros((n, p))], [-ts * C1, np.eye(p)]])
    B = np.vstack([Bd, np.zeros((p, m))])
    Br = np.vstack([np.zeros((n, p)), ts * np.eye(p)])
    return AugmentedSystem(A, B, Br, C1, float(ts))


# ------------------------------------------------------------ canonical form
@dataclass(frozen=True)
class CanonicalObserver:
    """Observer gain through the observer canonical form (seed 004 eq. 27-29).

    All matrices are exact sympy matrices.

    Attributes
    ----------
    A, C : sympy.Matrix
    Q_O : sympy.Matrix
        Observability matrix ``[C; CA; ...]``.
    char_coefficients : tuple
        ``(a_0, ..., a_{n-1})`` of ``det(sI - A) = s^n + a_{n-1} s^{n-1} + ... + a_0``.
    A_o, C_o : sympy.Matrix
        Observer canonical form (companion matrix, ``C_o = [0 ... 0 1]``).
    Q_O_bar : sympy.Matrix
        Observability matrix of ``(A_o, C_o)``.
    Delta : sympy.Matrix
        ``Q_O^-1 Qbar_O`` (eq. 27).
    desired_coefficients : tuple
        ``(alpha_0, ..., alpha_{n-1})`` of ``prod (s - p_i)``.
    Psi_o : sympy.Matrix
        ``alpha - a`` (eq. 28).
    Psi : sympy.Matrix
        ``Delta Psi_o`` (eq. 29), the observer gain ``L``.
    Gamma_d : sympy.Matrix
        ``A - Psi C``.
    exact : bool
        ``det(sI - Gamma_d)`` equals the desired polynomial exactly.
    """

    A: sp.Matrix
    C: sp.Matrix
    Q_O: sp.Matrix
    char_coefficients: tuple
    A_o: sp.Matrix
    C_o: sp.Matrix
    Q_O_bar: sp.Matrix
    Delta: sp.Matrix
    desired_coefficients: tuple
    Psi_o: sp.Matrix
    Psi: sp.Matrix
    Gamma_d: sp.Matrix
    exact: bool

    @property
    def L(self) -> np.ndarray:
        """The observer gain ``Psi`` as a float array, shape (n, 1) (`FeedbackGain`'s name)."""
        return np.array(self.Psi.evalf(17), dtype=float).reshape(-1, 1)

    @property
    def gain(self) -> np.ndarray:
        """Deprecated: `L`."""
        warnings.warn("CanonicalObserver.gain is deprecated: use .L", DeprecationWarning, stacklevel=2)
        return self.L

    def as_dict(self) -> dict:
        """JSON-friendly form (exact values as strings)."""
        s = lambda M: [[str(v) for v in M.row(i)] for i in range(M.rows)]  # noqa: E731
        return {"Q_O": s(self.Q_O), "A_o": s(self.A_o), "C_o": s(self.C_o), "Q_O_bar": s(self.Q_O_bar),
                "Delta": s(self.Delta), "char_coefficients": [str(v) for v in self.char_coefficients],
                "desired_coefficients": [str(v) for v in self.desired_coefficients],
                "Psi_o": [str(v) for v in self.Psi_o], "Psi": [str(v) for v in self.Psi],
                "Gamma_d": s(self.Gamma_d), "characteristic_polynomial_exact": self.exact}


def _exact_matrix(M: Any, name: str) -> sp.Matrix:
    if isinstance(M, sp.MatrixBase):
        out = sp.Matrix(M)
    else:
        arr = np.atleast_2d(np.asarray(M, dtype=float))
        if not np.all(np.isfinite(arr)):
            raise DimensionError(f"{name} has non-finite entries")
        out = sp.Matrix([[exact(v) for v in row] for row in arr])
    if out.free_symbols:
        names = sorted(map(str, out.free_symbols))
        raise DimensionError(f"{name} must be numeric, has symbols {names}")
    return out


def _exact_pole(p: Any) -> sp.Expr:
    if isinstance(p, sp.Expr):
        return p
    c = complex(p)
    return exact(c.real) + (sp.I * exact(c.imag) if c.imag else 0)


def canonical_observer(A: Any, C: Any, poles: Sequence[Any]) -> CanonicalObserver:
    """Observer gain by the observer canonical form, in exact arithmetic (seed 004).

    Parameters
    ----------
    A : array_like or sympy.Matrix, shape (n, n)
        Floats are converted to exact rationals of their decimal form.
    C : array_like or sympy.Matrix, shape (1, n)
        Single output.
    poles : sequence
        Desired observer poles (numbers or sympy numbers; complex ones in
        conjugate pairs).

    Returns
    -------
    CanonicalObserver

    Raises
    ------
    DimensionError
        Not square, not single-output, wrong number of poles.
    UnobservableError
        ``Q_O`` singular.
    """
    A = _exact_matrix(A, "A")
    C = _exact_matrix(C, "C")
    n = A.rows
    if A.shape != (n, n):
        raise DimensionError(f"A must be square, got shape {A.shape}")
    if C.shape != (1, n):
        raise DimensionError(f"the canonical-form route needs a single output: C must be (1, {n}), "
                             f"got {C.shape}")
    if len(poles) != n:
        raise DimensionError(f"{len(poles)} poles given, expected n = {n}")
    checked_poles([complex(sp.N(_exact_pole(p))) for p in poles], n)
    s = sp.Symbol("s")
    Q_O = sp.Matrix.vstack(*[C * A ** k for k in range(n)])
    if Q_O.det() == 0:
        raise UnobservableError(f"(A, C) is not observable: Q_O is singular (rank {Q_O.rank()} < {n})")
    a = A.charpoly(s).all_coeffs()[::-1][:n]            # a_0 .. a_{n-1}
    A_o = sp.zeros(n, n)
    for i in range(1, n):
        A_o[i, i - 1] = 1
    for i in range(n):
        A_o[i, n - 1] = -a[i]
    C_o = sp.zeros(1, n)
    C_o[0, n - 1] = 1
    Q_bar = sp.Matrix.vstack(*[C_o * A_o ** k for k in range(n)])
    Delta = Q_O.inv() * Q_bar
    desired = sp.Poly(sp.expand(sp.prod([s - _exact_pole(p) for p in poles])), s)
    alpha = [sp.nsimplify(sp.expand(c)) for c in desired.all_coeffs()[::-1][:n]]
    if any(sp.im(c) != 0 for c in alpha):
        raise SpecError("complex poles must come in conjugate pairs", key="poles")
    Psi_o = sp.Matrix([alpha[i] - a[i] for i in range(n)])
    Psi = (Delta * Psi_o).applyfunc(sp.nsimplify)
    Gamma = (A - Psi * C).applyfunc(sp.nsimplify)
    ok = sp.expand(Gamma.charpoly(s).as_expr() - desired.as_expr()) == 0
    return CanonicalObserver(A, C, Q_O, tuple(a), A_o, C_o, Q_bar, Delta, tuple(alpha), Psi_o, Psi,
                             Gamma, bool(ok))
