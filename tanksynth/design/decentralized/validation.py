"""The checks of the matrices given to the decentralised gain routines (seed 003).

Every routine of `tanksynth.design.decentralized.gains` and
`tanksynth.design.decentralized.models` checks its inputs once, at entry: a matrix of numbers of
the expected shape, finite; a covariance symmetric (a relative asymmetry up to 1e-8 is rounding
and is symmetrised away) and positive definite (``R``, ``P``) or semidefinite (``Q``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tanksynth.design.matrices import symmetrized
from tanksynth.errors import DimensionError, SpecError

__all__ = ["checked_matrix", "checked_symmetric", "positive_definite", "positive_semidefinite"]

_SYM_RTOL = 1e-8          # relative asymmetry accepted (then symmetrised) in inputs
_PSD_RTOL = 1e-10         # relative negative eigenvalue accepted in Q (rounding)


def checked_matrix(value: Any, name: str,
                   shape: tuple[int | None, int | None] | None = None) -> np.ndarray:
    """``value`` as a finite float matrix of the expected shape (a number is 1 x 1).

    Parameters
    ----------
    value : array_like
        The matrix (any units: returned as floats, unchanged).
    name : str
        Its name, for the error message.
    shape : tuple of (int or None), optional
        Expected ``(rows, columns)``; None in either place accepts any size.

    Returns
    -------
    ndarray, shape (r, c)

    Raises
    ------
    DimensionError
        Not numbers, not 2-D, another shape, or non-finite entries.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a matrix of numbers, got {type(value).__name__}") from None
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim != 2:
        raise DimensionError(f"{name} must be a 2-D matrix, got an array of shape {arr.shape}")
    if shape is not None:
        for got, want in zip(arr.shape, shape):
            if want is not None and got != want:
                raise DimensionError(f"{name} has shape {arr.shape}, expected "
                                     f"({shape[0] if shape[0] is not None else '*'}, "
                                     f"{shape[1] if shape[1] is not None else '*'})")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} has non-finite entries")
    return arr


def checked_symmetric(M: np.ndarray, name: str) -> np.ndarray:
    """``M`` symmetrised, refused when its asymmetry is more than rounding (1e-8 relative).

    Parameters
    ----------
    M : ndarray, shape (k, k)
        A covariance (squared state or output units).
    name : str
        Its name: the error's key.

    Returns
    -------
    ndarray, shape (k, k)
        ``(M + M') / 2``.

    Raises
    ------
    SpecError
        Not symmetric.
    """
    scale = max(1.0, float(np.max(np.abs(M))))
    if float(np.max(np.abs(M - M.T))) > _SYM_RTOL * scale:
        raise SpecError(f"{name} is not symmetric (max |M - M'| = {np.max(np.abs(M - M.T)):.3g})",
                        key=name)
    return symmetrized(M)


def positive_definite(M: np.ndarray, name: str) -> np.ndarray:
    """``M`` symmetrised, refused unless positive definite (Cholesky).

    Parameters
    ----------
    M : ndarray, shape (k, k)
        A covariance (squared state or output units).
    name : str
        Its name: the error's key.

    Returns
    -------
    ndarray, shape (k, k)

    Raises
    ------
    SpecError
        Not symmetric, or not positive definite (naming its smallest eigenvalue).
    """
    M = checked_symmetric(M, name)
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        low = float(np.linalg.eigvalsh(M)[0])
        raise SpecError(f"{name} is not positive definite (smallest eigenvalue {low:.3g})",
                        key=name) from None
    return M


def positive_semidefinite(M: np.ndarray, name: str) -> np.ndarray:
    """``M`` symmetrised, refused unless positive semidefinite (to a 1e-10 relative rounding).

    Parameters
    ----------
    M : ndarray, shape (k, k)
        A process-noise covariance or intensity (squared state units, per s for an intensity).
    name : str
        Its name: the error's key.

    Returns
    -------
    ndarray, shape (k, k)

    Raises
    ------
    SpecError
        Not symmetric, or with an eigenvalue below the rounding slack.
    """
    M = checked_symmetric(M, name)
    slack = _PSD_RTOL * max(1.0, float(np.max(np.abs(M))))
    try:
        np.linalg.cholesky(M + slack * np.eye(M.shape[0]))
        return M
    except np.linalg.LinAlgError:
        low = float(np.linalg.eigvalsh(M)[0])
    if low < -slack:
        raise SpecError(f"{name} is not positive semidefinite (smallest eigenvalue {low:.3g})",
                        key=name)
    return M
