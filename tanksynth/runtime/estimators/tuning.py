"""The one validator of estimator tunings (and of the sampled models' options).

Every tuning of `tanksynth.runtime.estimators` (`KalmanTuning`, `UKFTuning`,
the adaptive, consensus, Luenberger and NARX tunings) and `discrete_model`
check their numbers here, so that one rule, with one message, holds for
each kind of value:

=====================  ==================================================
`as_matrix`            finite float matrix of a given shape
`as_vector`            finite float vector of a given size
`as_spd`               symmetric positive (semi)definite matrix
`positive_int`         integer >= a minimum (counts: steps, window, delays)
`positive_float`       number > 0 (or >= 0)
`number_in`            number in a range (``alpha`` in (0, 1], ``kappa``)
`choice`               one of a few words (``form``)
`operating_point`      ``(x0, u0)`` pair of vectors, or None
`noise_covariances`    ``Q`` (or ``Q0``), ``R`` (or sensors' ``R_i``), ``P0``, ``x0``
`noise_input`          ``G``, the n x r matrix the process noise enters by
`agree_on_states`      matrices with one side per state agree with ``x0``
`set_fields`           store validated values in a frozen tuning
`require_tuning`       an estimator is given the tuning class it runs
`fits_plant`           a tuning's ``x0`` and matrices have the plant's sizes
`artefact_gains`       a tuning's arrays for the artefact, operating point included
=====================  ==================================================

Every check raises a `TanksynthError` subclass naming the value, the value
given and what was expected: `DimensionError` for shapes and non-finite
entries, `SpecError` for values out of range (the key is the value's name).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tanksynth.analysis.matrices import symmetrize
from tanksynth.errors import DimensionError, SpecError

__all__ = ["as_matrix", "as_vector", "as_spd", "positive_int", "positive_float", "number_in",
           "choice", "operating_point", "noise_covariances", "noise_input", "agree_on_states",
           "set_fields", "require_tuning", "fits_plant", "artefact_gains"]


def _floats(value: Any, name: str, what: str) -> np.ndarray:
    """``value`` as a float array; a `DimensionError` naming ``name`` when it is not numeric."""
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a numeric {what}, got {value!r}") from None


def _finite(arr: np.ndarray, name: str) -> np.ndarray:
    """``arr``, or a `DimensionError` naming ``name`` when an entry is NaN or infinite."""
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} has non-finite entries")
    return arr


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
    arr = _floats(value, name, "matrix")
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim == 1 and shape is not None and shape[1] == 1 and arr.size == shape[0]:
        arr = arr.reshape(-1, 1)
    if arr.ndim != 2:
        raise DimensionError(f"{name} must be a 2-D matrix, got an array of shape {arr.shape}")
    if shape is not None and arr.shape != tuple(shape):
        raise DimensionError(f"{name} must have shape {tuple(shape)}, got {arr.shape}")
    return _finite(arr, name)


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
    arr = _floats(value, name, "vector")
    if arr.ndim > 1 and sum(d > 1 for d in arr.shape) <= 1:
        arr = arr.reshape(-1)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise DimensionError(f"{name} must be a vector, got an array of shape {arr.shape}")
    if size is not None and arr.size != size:
        raise DimensionError(f"{name} must have {size} entries, got {arr.size}")
    return _finite(arr, name)


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
    arr = _floats(value, name, "matrix")
    if size is not None and arr.ndim == 0:
        arr = float(arr) * np.eye(size)
    elif size is not None and arr.ndim == 1 and arr.size == size and size > 1:
        arr = np.diag(arr)
    arr = as_matrix(arr, name, None if size is None else (size, size))
    if arr.shape[0] != arr.shape[1]:
        raise DimensionError(f"{name} must be square, got shape {arr.shape}")
    scale = float(np.max(np.abs(arr))) if arr.size else 0.0
    asymmetry = float(np.max(np.abs(arr - arr.T), initial=0.0))
    if asymmetry > rtol * max(scale, 1e-300):
        raise SpecError(f"{name} must be symmetric; largest |{name} - {name}'| entry "
                        f"{asymmetry:.3g}", key=name)
    arr = symmetrize(arr)
    eig = np.linalg.eigvalsh(arr)
    if semidefinite:
        ok = not (eig.size and eig[0] < -rtol * max(scale, 1e-300))
    else:
        try:
            np.linalg.cholesky(arr)
            ok = not (eig.size and not eig[0] > 0)
        except np.linalg.LinAlgError:
            ok = False
    if not ok:
        kind = "positive semidefinite" if semidefinite else "positive definite"
        raise SpecError(f"{name} must be {kind}; smallest eigenvalue {eig[0]:.3g}", key=name)
    return arr


def positive_int(value: Any, name: str, minimum: int = 1) -> int:
    """An integer (not a bool) >= ``minimum``: a count (steps, window, delays, runs).

    Parameters
    ----------
    value : int
        The count (dimensionless).
    name : str
        Its name, for the message (and the spec key).
    minimum : int
        Smallest value accepted; default 1.

    Raises
    ------
    SpecError
        Not an integer, or below ``minimum``.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise SpecError(f"{name} must be an integer >= {minimum}, got {value!r}", key=name)
    return int(value)


def _bounds(above: float | None, at_least: float | None, at_most: float | None) -> str:
    """``> 0``, ``>= 0``, ``in (0, 1]``: the range of `number_in` in words."""
    low = above if above is not None else at_least
    if at_most is None:
        return f"{'>' if above is not None else '>='} {low:g}"
    if low is None:
        return f"<= {at_most:g}"
    return f"in {'(' if above is not None else '['}{low:g}, {at_most:g}]"


def number_in(value: Any, name: str, *, above: float | None = None, at_least: float | None = None,
              at_most: float | None = None, expected: str | None = None) -> float:
    """A finite real number (not a bool) in a range.

    Parameters
    ----------
    value : float
        The number (in its own units).
    name : str
        Its name, for the message (and the spec key).
    above, at_least : float, optional
        Strict and inclusive lower bounds (same units).
    at_most : float, optional
        Inclusive upper bound (same units).
    expected : str, optional
        The range in words for the message, when the bounds alone do not say why
        (``"finite with n + kappa > 0"``); default from the bounds (``"> 0"``, ``"in (0, 1]"``).

    Raises
    ------
    SpecError
        Not a number, not finite, or out of the range.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SpecError(f"{name} must be a number, got {value!r}", key=name)
    v = float(value)
    inside = (np.isfinite(v) and (above is None or v > above) and (at_least is None or v >= at_least)
              and (at_most is None or v <= at_most))
    if not inside:
        raise SpecError(f"{name} must be {expected or _bounds(above, at_least, at_most)}, "
                        f"got {value!r}", key=name)
    return v


def positive_float(value: Any, name: str, allow_zero: bool = False) -> float:
    """A finite number > 0 (>= 0 with ``allow_zero``): a period, a tolerance, a weight.

    Parameters
    ----------
    value : float
        The number (in its own units).
    name : str
        Its name, for the message (and the spec key).
    allow_zero : bool
        Accept 0.

    Raises
    ------
    SpecError
        Not a number, not finite, or out of range.
    """
    return number_in(value, name, at_least=0.0) if allow_zero else number_in(value, name, above=0.0)


def choice(value: Any, name: str, choices: tuple[str, ...]) -> str:
    """One of ``choices`` (a form, a variant).

    Parameters
    ----------
    value : str
        The word given.
    name : str
        Its name, for the message (and the spec key).
    choices : tuple of str
        The words accepted.

    Raises
    ------
    SpecError
        Not one of ``choices``.
    """
    if value not in choices:
        raise SpecError(f"{name} must be one of {choices}, got {value!r}", key=name)
    return value


def operating_point(value: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """The ``(x0, u0)`` a tuning linearises about, as finite float vectors (None stays None).

    Parameters
    ----------
    value : tuple of array_like, or None
        ``(x0, u0)``: state (state units) and input (input units).

    Raises
    ------
    DimensionError
        Not vectors, or non-finite entries.
    """
    if value is None:
        return None
    x_op, u_op = value
    return as_vector(x_op, "operating_point x0"), as_vector(u_op, "operating_point u0")


def noise_covariances(tuning: Any, process: str = "Q", sensors: bool = False) -> dict[str, Any]:
    """The noise model of a Kalman-type tuning, validated: process and measurement
    covariances, initial covariance and initial estimate.

    Parameters
    ----------
    tuning : object
        A tuning with the fields ``process``, ``R``, ``P0`` and ``x0``.
    process : str
        Name of the process-noise covariance field (``"Q"``, ``"Q0"``): symmetric positive
        semidefinite (squared units of the noise).
    sensors : bool
        ``R`` is a non-empty list of one covariance per sensor (``R[0]``, ``R[1]``, ...).

    Returns
    -------
    dict
        ``{process: Q, "R": R (or a tuple of R_i), "P0": P0, "x0": x0}``: ``R`` positive
        definite (squared output units), ``P0`` positive definite (squared state units),
        ``x0`` a finite vector (state units), ``P0`` n x n for the n entries of ``x0``.

    Raises
    ------
    DimensionError
        Shapes, non-finite entries, or ``P0`` and ``x0`` of different sizes.
    SpecError
        A covariance not symmetric, or not positive (semi)definite; ``R`` not a list of
        sensor covariances.
    """
    Q = as_spd(getattr(tuning, process), process, semidefinite=True)
    R = tuning.R
    if sensors:
        if isinstance(R, np.ndarray) or not isinstance(R, (tuple, list)) or not R:
            raise SpecError("R must be a non-empty list of sensor covariances R_i", key="R")
        R = tuple(as_spd(Ri, f"R[{i}]") for i, Ri in enumerate(R))
    else:
        R = as_spd(R, "R")
    out = {process: Q, "R": R, "P0": as_spd(tuning.P0, "P0"), "x0": as_vector(tuning.x0, "x0")}
    agree_on_states(out["x0"], P0=out["P0"])
    return out


def noise_input(G: Any, states: int, size: int) -> np.ndarray:
    """The matrix through which process noise enters the states (default the identity).

    Parameters
    ----------
    G : array_like, shape (n, r), or None
        Noise input matrix (state units per noise unit); None: ``I`` (r = n).
    states : int
        Number of states n.
    size : int
        Size r of the process-noise covariance.

    Raises
    ------
    DimensionError
        ``G`` is not n x r, or has non-finite entries.
    """
    G = np.eye(states) if G is None else as_matrix(G, "G")
    if G.shape != (states, size):
        raise DimensionError(f"G must be {states} x {size} (n x size of Q), got {G.shape}")
    return G


def agree_on_states(x0: np.ndarray, **square: np.ndarray) -> None:
    """Check that n x n matrices (``P0``, ``Q``) have the n states of the estimate ``x0``.

    Parameters
    ----------
    x0 : ndarray, shape (n,)
        The initial estimate (state units).
    **square : ndarray
        Matrices by name, each to be n x n.

    Raises
    ------
    DimensionError
        A matrix is not n x n; the message gives every shape.
    """
    n = x0.size
    if any(M.shape != (n, n) for M in square.values()):
        shapes = ", ".join(f"{name} {M.shape}" for name, M in square.items())
        raise DimensionError(f"{shapes} and x0 ({n},) must agree on the number of states")


def set_fields(tuning: Any, **values: Any) -> None:
    """Store validated values in a frozen dataclass (from its ``__post_init__``).

    Parameters
    ----------
    tuning : object
        The frozen tuning being built.
    **values
        Field name -> validated value.
    """
    for name, value in values.items():
        object.__setattr__(tuning, name, value)


def require_tuning(estimator: Any, tuning: Any, expected: type) -> None:
    """Check that an estimator is given the tuning class it runs.

    Parameters
    ----------
    estimator : object
        The estimator being built (its class names the message).
    tuning : object
        The tuning given.
    expected : type
        The tuning class it needs.

    Raises
    ------
    SpecError
        ``tuning`` is not an ``expected``; the key is ``tuning``.
    """
    if not isinstance(tuning, expected):
        name = expected.__name__
        article = "an" if name[0] in "AEIOU" else "a"
        raise SpecError(f"{type(estimator).__name__} needs {article} {name}, got "
                        f"{type(tuning).__name__}", key="tuning")


def fits_plant(tuning: Any, plant: Any, **shapes: tuple[int, int]) -> None:
    """Check a tuning's sizes against the plant: ``x0`` has n entries, each named matrix its shape.

    Parameters
    ----------
    tuning : object
        A tuning with ``x0`` (and the named matrices; one that is None is not checked).
    plant : Plant
        The plant (``n`` states, ``q`` outputs, ``name``).
    **shapes : (int, int)
        Field name -> required shape, e.g. ``R=(q, q)``, ``L=(n, q)``.

    Raises
    ------
    DimensionError
        A matrix or ``x0`` of the wrong size; the message names the plant and its n and q.
    """
    n, q = plant.n, plant.q
    for name, shape in shapes.items():
        value = getattr(tuning, name, None)
        if value is not None and value.shape != tuple(shape):
            raise DimensionError(f"{name} must be {shape[0]} x {shape[1]} for plant "
                                 f"'{plant.name}' (n = {n}, q = {q}), got {value.shape}")
    if tuning.x0.size != n:
        raise DimensionError(f"x0 must have {n} entries for plant '{plant.name}', got "
                             f"{tuning.x0.size}")


def artefact_gains(tuning: Any, **gains: np.ndarray) -> dict[str, np.ndarray]:
    """A tuning's arrays for the artefact, in order, then its operating point (``x_op``, ``u_op``).

    Parameters
    ----------
    tuning : object
        The tuning (its ``operating_point``, if it has one and it is set, is appended).
    **gains : ndarray
        Artefact name -> array, in the order they are written (the initial estimate as
        ``x_hat0``).

    Returns
    -------
    dict of str to ndarray
    """
    op = getattr(tuning, "operating_point", None)
    if op is not None:
        gains["x_op"], gains["u_op"] = op
    return gains
