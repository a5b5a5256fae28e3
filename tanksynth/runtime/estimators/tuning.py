"""Validation of the numbers an estimator is built from (tunings, models, options).

Every check raises a `TanksynthError` subclass naming the value and what was
expected: `DimensionError` for shapes and non-finite entries, `SpecError`
for values out of range (the key is the value's name).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tanksynth.errors import DimensionError, SpecError

__all__ = ["as_matrix", "as_vector", "as_spd"]


def as_matrix(value: Any, name: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A finite float matrix of a given shape (scalars become 1 x 1).

    Parameters
    ----------
    value : array_like
    name : str
        Name for error messages (``"Q"``, ``"L"``).
    shape : (int, int), optional
        Required shape.

    Raises
    ------
    DimensionError
        Wrong shape or non-finite entries.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a numeric matrix, got {value!r}") from None
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim == 1 and shape is not None and shape[1] == 1 and arr.size == shape[0]:
        arr = arr.reshape(-1, 1)
    if arr.ndim != 2:
        raise DimensionError(f"{name} must be a 2-D matrix, got an array of shape {arr.shape}")
    if shape is not None and arr.shape != tuple(shape):
        raise DimensionError(f"{name} must have shape {tuple(shape)}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} has non-finite entries")
    return arr


def as_vector(value: Any, name: str, size: int | None = None) -> np.ndarray:
    """A finite float vector (any 1-D-compatible input; scalars allowed when size is 1).

    Parameters
    ----------
    value : array_like or float
        The values (any 1-D-compatible input).
    name : str
        Its name, for messages.
    size : int, optional
        Expected length.

    Raises
    ------
    DimensionError
        Wrong size or non-finite entries.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a numeric vector, got {value!r}") from None
    if arr.ndim > 1 and sum(d > 1 for d in arr.shape) <= 1:
        arr = arr.reshape(-1)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise DimensionError(f"{name} must be a vector, got an array of shape {arr.shape}")
    if size is not None and arr.size != size:
        raise DimensionError(f"{name} must have {size} entries, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} has non-finite entries")
    return arr


def as_spd(value: Any, name: str, size: int | None = None, semidefinite: bool = False,
           rtol: float = 1e-10) -> np.ndarray:
    """A symmetric positive definite (or semidefinite) matrix.

    A scalar ``s`` with ``size`` given is accepted as ``s I``; a vector of
    length ``size`` as a diagonal matrix. Asymmetry up to ``rtol`` (relative
    to the largest entry) is symmetrised away; more is an error.

    Parameters
    ----------
    value : array_like or float
        The matrix, a diagonal (vector) or a scalar ``s`` (``s I``), in squared units.
    name : str
        Its name, for messages (and the spec key).
    size : int, optional
        Expected size n (n x n); needed for a scalar or a vector.
    semidefinite : bool
        Accept positive semidefinite (default: definite).
    rtol : float
        Asymmetry symmetrised away, relative to the largest entry (dimensionless).

    Raises
    ------
    DimensionError
        Wrong shape or non-finite entries.
    SpecError
        Not symmetric, or not positive (semi)definite; the key is ``name``.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a numeric matrix, got {value!r}") from None
    if size is not None and arr.ndim == 0:
        arr = float(arr) * np.eye(size)
    elif size is not None and arr.ndim == 1 and arr.size == size and size > 1:
        arr = np.diag(arr)
    arr = as_matrix(arr, name, None if size is None else (size, size))
    if arr.shape[0] != arr.shape[1]:
        raise DimensionError(f"{name} must be square, got shape {arr.shape}")
    scale = float(np.max(np.abs(arr))) if arr.size else 0.0
    if np.max(np.abs(arr - arr.T), initial=0.0) > rtol * max(scale, 1e-300):
        raise SpecError(f"{name} must be symmetric", key=name)
    arr = 0.5 * (arr + arr.T)
    eig = np.linalg.eigvalsh(arr)
    if semidefinite:
        if eig.size and eig[0] < -rtol * max(scale, 1e-300):
            raise SpecError(f"{name} must be positive semidefinite; smallest eigenvalue {eig[0]:.3g}",
                            key=name)
    else:
        try:
            np.linalg.cholesky(arr)
        except np.linalg.LinAlgError:
            raise SpecError(f"{name} must be positive definite; smallest eigenvalue "
                            f"{eig[0]:.3g}", key=name) from None
        if eig.size and not eig[0] > 0:
            raise SpecError(f"{name} must be positive definite; smallest eigenvalue {eig[0]:.3g}",
                            key=name)
    return arr


def _positive_int(value: Any, name: str, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise SpecError(f"{name} must be an integer >= {minimum}, got {value!r}", key=name)
    return int(value)


def _positive_float(value: Any, name: str, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SpecError(f"{name} must be a number, got {value!r}", key=name)
    v = float(value)
    if not np.isfinite(v) or (v < 0 if allow_zero else v <= 0):
        raise SpecError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {value!r}", key=name)
    return v
