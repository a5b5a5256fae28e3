"""The option toolkit: every spec value (number, vector, matrix, covariance, poles, region) is read here.

Each reader takes the raw TOML value and the spec key it came from, and
raises `SpecError` naming that key and what was expected.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.errors import SpecError

__all__ = ["parse_number", "parse_matrix", "parse_poles", "parse_region", "parse_covariance"]

_NUM = (int, float)


def parse_number(value: Any, key: str) -> float:
    """A finite real number (booleans refused); ``key`` names it in the error."""
    if isinstance(value, bool) or not isinstance(value, _NUM):
        raise SpecError(f"expected a number, got {type(value).__name__} {value!r}", key=key)
    value = float(value)
    if not np.isfinite(value):
        raise SpecError(f"expected a finite number, got {value}", key=key)
    return value



def parse_matrix(value: Any, key: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A real matrix given as a list of rows, optionally of a given shape."""
    if not isinstance(value, list) or not value or not all(isinstance(r, list) for r in value):
        raise SpecError("expected a matrix as a list of rows (lists of numbers)", key=key)
    rows = [[parse_number(v, f"{key}[{i}][{j}]") for j, v in enumerate(r)] for i, r in enumerate(value)]
    if len({len(r) for r in rows}) != 1:
        raise SpecError("rows of the matrix have different lengths", key=key)
    arr = np.array(rows, dtype=float)
    if shape is not None and arr.shape != shape:
        raise SpecError(f"expected a {shape[0]} x {shape[1]} matrix, got {arr.shape[0]} x "
                        f"{arr.shape[1]}", key=key)
    return arr



def parse_poles(value: Any, key: str) -> list[complex]:
    """Poles from a spec list: numbers, or ``[re, im]`` pairs for complex poles.

    Parameters
    ----------
    value : list
    key : str
        Spec key for error messages.

    Returns
    -------
    list of complex
    """
    if not isinstance(value, list) or not value:
        raise SpecError("expected a non-empty list of poles (numbers or [re, im] pairs)", key=key)
    out = []
    for i, v in enumerate(value):
        if isinstance(v, list):
            if len(v) != 2:
                raise SpecError("expected [re, im]", key=f"{key}[{i}]")
            out.append(complex(parse_number(v[0], f"{key}[{i}][0]"), parse_number(v[1], f"{key}[{i}][1]")))
        else:
            out.append(complex(parse_number(v, f"{key}[{i}]")))
    return out



def parse_region(value: Any, key: str) -> tuple[tuple, ...]:
    """An LMI region from a spec list of tables (their intersection).

    Each table has a ``type``: ``"half_plane"`` with ``alpha`` (``Re z <
    -alpha``), ``"disk"`` with ``center`` and ``radius``, ``"sector"`` with
    ``angle_deg`` (half-angle about the negative real axis).

    Parameters
    ----------
    value : list of dict
    key : str

    Returns
    -------
    tuple of tuple
        ``("half_plane", alpha)``, ``("disk", center, radius)``, ``("sector", theta)`` (theta in
        radians); `tanksynth.analysis.lmi_region.region_from_parts` builds the region.
    """
    if isinstance(value, Mapping):
        value = [value]
    if not isinstance(value, list) or not value:
        raise SpecError("expected a list of region tables, e.g. [{type = \"disk\", center = 0.0, "
                        "radius = 0.9}]", key=key)
    parts = []
    fields = {"half_plane": ("alpha",), "disk": ("center", "radius"), "sector": ("angle_deg",)}
    for i, item in enumerate(value):
        k = f"{key}[{i}]"
        if not isinstance(item, Mapping):
            raise SpecError("expected a table with a 'type'", key=k)
        kind = item.get("type")
        if kind not in fields:
            raise SpecError(f"unknown region type {kind!r}; expected one of {list(fields)}",
                            key=f"{k}.type")
        extra = [f for f in item if f not in ("type", *fields[kind])]
        missing = [f for f in fields[kind] if f not in item]
        if extra or missing:
            raise SpecError(f"region '{kind}' takes {list(fields[kind])}"
                            + (f"; unknown {extra}" if extra else "")
                            + (f"; missing {missing}" if missing else ""), key=k)
        args = [parse_number(item[f], f"{k}.{f}") for f in fields[kind]]
        if kind == "disk" and not args[1] > 0:
            raise SpecError(f"disk radius must be > 0, got {args[1]:g}", key=f"{k}.radius")
        if kind == "sector" and not 0 < args[0] < 90:
            raise SpecError(f"sector half-angle must be in (0, 90) degrees, got {args[0]:g}",
                            key=f"{k}.angle_deg")
        parts.append((kind, *args) if kind != "sector" else (kind, float(np.radians(args[0]))))
    return tuple(parts)


def parse_covariance(value: Any, key: str, size: int, semidefinite: bool = False) -> np.ndarray:
    """A symmetric positive (semi)definite ``size x size`` matrix: a number (``s I``), a list
    (diagonal) or a list of rows (squared units of the state or output)."""
    try:
        if isinstance(value, bool):
            raise TypeError
        if isinstance(value, _NUM):
            M = float(value) * np.eye(size)
        elif isinstance(value, list) and value and all(isinstance(v, _NUM) and not isinstance(v, bool)
                                                       for v in value):
            if len(value) != size:
                raise SpecError(f"expected {size} diagonal entries, got {len(value)}", key=key)
            M = np.diag(np.array(value, dtype=float))
        elif isinstance(value, list) and value and all(isinstance(r, list) for r in value):
            M = np.array(value, dtype=float)
        else:
            raise TypeError
    except (TypeError, ValueError):
        raise SpecError("expected a number (s I), a list (diagonal) or a list of rows",
                        key=key) from None
    if M.shape != (size, size):
        raise SpecError(f"expected a {size} x {size} matrix, got shape {M.shape}", key=key)
    if not np.all(np.isfinite(M)):
        raise SpecError("entries must be finite", key=key)
    if np.max(np.abs(M - M.T), initial=0.0) > 1e-12 * max(np.max(np.abs(M)), 1e-300):
        raise SpecError("matrix must be symmetric", key=key)
    w = np.linalg.eigvalsh(0.5 * (M + M.T))
    if (w[0] < 0) if semidefinite else (w[0] <= 0):
        kind = "positive semidefinite" if semidefinite else "positive definite"
        raise SpecError(f"matrix must be {kind}; smallest eigenvalue {w[0]:.3g}", key=key)
    return 0.5 * (M + M.T)
