"""Matrix helpers every design family uses: checked inputs, the symmetric part, eigenvalue lists.

==================  ===========================================================
`real_matrix`       an argument as a finite real 2-D array (`DimensionError`
                    naming it otherwise)
`matrix_pair`       ``(A, B)`` checked together: ``A`` square, ``B`` with as
                    many rows
`symmetrized`       ``(M + M') / 2``: the symmetric part of a matrix (numpy
                    array or an affine LMI expression)
`complex_pairs`     eigenvalues as sorted ``[re, im]`` pairs (JSON diagnostics)
==================  ===========================================================
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tanksynth.errors import DimensionError

__all__ = ["real_matrix", "matrix_pair", "symmetrized", "complex_pairs"]


def real_matrix(value: Any, name: str) -> np.ndarray:
    """``value`` as a finite real 2-D float array (a scalar or a vector becomes one row).

    Parameters
    ----------
    value : array_like
        The matrix (any units: returned unchanged, as floats).
    name : str
        Its name, for the error message.

    Returns
    -------
    ndarray, shape (r, c)

    Raises
    ------
    DimensionError
        Not convertible to real numbers, more than two dimensions, or non-finite entries.
    """
    try:
        arr = np.atleast_2d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a real 2-D array") from None
    if arr.ndim != 2:
        raise DimensionError(f"{name} must be 2-D, got {arr.ndim} dimensions")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} has non-finite entries")
    return arr


def matrix_pair(A: Any, B: Any, name_b: str = "B") -> tuple[np.ndarray, np.ndarray]:
    """A square ``A`` and a ``B`` with as many rows (a state-space pair), checked.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (1/s in continuous time, dimensionless in discrete time).
    B : array_like, shape (n, m)
        Input (or, for the dual problem, transposed output) matrix.
    name_b : str
        The name of ``B`` in error messages (``"C'"`` for an observer's dual pair).

    Returns
    -------
    A, B : ndarray
        As finite float arrays.

    Raises
    ------
    DimensionError
        ``A`` not square, ``B`` with another number of rows, or non-finite entries.
    """
    A = real_matrix(A, "A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise DimensionError(f"A must be square, got shape {A.shape}")
    B = real_matrix(B, name_b)
    if B.shape[0] != n:
        raise DimensionError(f"{name_b} has {B.shape[0]} rows, expected n = {n}")
    return A, B


def symmetrized(M: Any) -> Any:
    """The symmetric part ``(M + M') / 2`` of a square matrix.

    Removes the round-off asymmetry of a computed covariance or Lyapunov matrix before
    eigenvalues or a Cholesky factorisation, and states the symmetric part of an LMI block
    (works on numpy arrays and on the affine expressions of `tanksynth.design.conic` or cvxpy
    alike: only ``+``, ``*`` and ``.T`` are used).

    Parameters
    ----------
    M : ndarray or expression, shape (k, k)
        Any units (kept).

    Returns
    -------
    ndarray or expression, shape (k, k)
    """
    return 0.5 * (M + M.T)


def complex_pairs(values: Any) -> list[list[float]]:
    """Complex numbers (eigenvalues, poles) as ``[re, im]`` pairs, sorted (real part first).

    Parameters
    ----------
    values : array_like of complex
        1/s in continuous time, dimensionless in discrete time (kept).

    Returns
    -------
    list of [float, float]
        Sorted by ``numpy.sort_complex``: JSON-friendly and independent of the eigensolver's order.
    """
    return [[float(v.real), float(v.imag)] for v in np.sort_complex(np.asarray(values, dtype=complex))]
