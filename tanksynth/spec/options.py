"""The option toolkit: every spec value is read here.

Each reader takes the raw TOML value and the spec key it came from, and
raises `SpecError` naming that key and what was expected:

=====================  =====================================================
`parse_number`         finite real, optionally bounded (``above``,
                       ``at_least``, ``below``, ``at_most``)
`parse_integer`        integer, optionally bounded
`parse_choice`         one of a few values ("did you mean" for strings)
`parse_bool`           true or false
`parse_vector`         numbers of a given length (a list, a table keyed by
                       names, or one number for all)
`parse_matrix`         list of rows, optionally of a given shape
`parse_covariance`     symmetric positive (semi)definite matrix
`parse_poles`          numbers or ``[re, im]`` pairs
`parse_region`         LMI region: list of half-plane/disk/sector tables
`parse_names`          names among known ones (states, outputs)
`parse_box`            ``{name = [min, max]}`` bounds of named signals
=====================  =====================================================

Every reader also accepts the value it returns (a reader applied to its own
result gives it back), so code holding validated options (`MethodOptions`)
can pass them through the same reader.
"""

from __future__ import annotations

import difflib
import math
import numbers
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.errors import SpecError

__all__ = ["parse_number", "parse_integer", "parse_choice", "parse_bool", "parse_vector",
           "parse_matrix", "parse_covariance", "parse_poles", "parse_region", "region_is_stable",
           "region_real_interval", "region_emptiness",
           "parse_names", "parse_box", "did_you_mean", "unknown_word_hint", "short_repr"]

#: Largest integer any option accepts (a 64-bit signed integer: seeds, counts).
MAX_INTEGER = 2 ** 63 - 1
#: Largest magnitude of a covariance entry (squared SI units): beyond it products overflow.
MAX_COVARIANCE = 1e100

#: Fields of each elementary LMI region, in the order of its parts tuple.
_REGION_FIELDS = {"half_plane": ("alpha",), "disk": ("center", "radius"), "sector": ("angle_deg",)}


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _type(value: Any) -> str:
    return f"{type(value).__name__} {short_repr(value)}"


def did_you_mean(word: Any, candidates: Sequence[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest candidate of a string, else ``""``.

    Parameters
    ----------
    word : Any
        What the spec said; only a string gets a suggestion.
    candidates : sequence of str
        The valid values (compared case-insensitively, `difflib` cutoff 0.6).
    """
    if not isinstance(word, str):
        return ""
    by_lower = {str(c).lower(): str(c) for c in candidates}
    close = difflib.get_close_matches(word.lower(), list(by_lower), n=1, cutoff=0.6)
    return f"; did you mean {by_lower[close[0]]!r}?" if close else ""


def unknown_word_hint(word: Any, candidates: Sequence[str]) -> str:
    """``"; did you mean 'x'?"`` when a candidate is close, else the list of valid values.

    Parameters
    ----------
    word : Any
        What the spec said (an unknown method, option, key or family).
    candidates : sequence of str
        The valid values.
    """
    hint = did_you_mean(word, candidates)
    if hint:
        return hint
    return "; expected one of: " + (", ".join(str(c) for c in candidates) or "(none)")


def short_repr(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (an echoed value stays one short line).

    Parameters
    ----------
    value : object
        The value to echo in a message.
    limit : int, optional
        Largest length of the text (characters; default 60).
    """
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 10 ** 30:
        return f"an integer of {len(str(abs(value)))} digits"
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - a repr that fails is still echoed as its type
        text = f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _bounds_text(above: float | None, at_least: float | None, below: float | None,
                 at_most: float | None) -> str:
    lo = (f"({above:g}" if above is not None else f"[{at_least:g}" if at_least is not None else None)
    hi = (f"{below:g})" if below is not None else f"{at_most:g}]" if at_most is not None else None)
    if lo and hi:
        return f" in {lo}, {hi}"
    if lo:
        return f" > {above:g}" if above is not None else f" >= {at_least:g}"
    if hi:
        return f" < {below:g}" if below is not None else f" <= {at_most:g}"
    return ""


def _check_bounds(value: float, key: str, what: str, above: float | None, at_least: float | None,
                  below: float | None, at_most: float | None) -> None:
    if ((above is not None and not value > above) or (at_least is not None and not value >= at_least)
            or (below is not None and not value < below) or (at_most is not None and not value <= at_most)):
        raise SpecError(f"expected {what}{_bounds_text(above, at_least, below, at_most)}, got {value:g}",
                        key=key)


def parse_number(value: Any, key: str, *, above: float | None = None, at_least: float | None = None,
                 below: float | None = None, at_most: float | None = None) -> float:
    """A finite real number (booleans refused), optionally bounded.

    Parameters
    ----------
    value : Any
        The raw value.
    key : str
        Spec key, for the error.
    above, at_least, below, at_most : float, optional
        Strict (``above``, ``below``) and inclusive bounds.

    Returns
    -------
    float
    """
    if not _is_number(value):
        raise SpecError(f"expected a number{_bounds_text(above, at_least, below, at_most)}, got "
                        f"{_type(value)}", key=key)
    try:
        out = float(value)
    except OverflowError:  # an int beyond float range (TOML ints are unbounded)
        out = math.inf if value > 0 else -math.inf
    if not math.isfinite(out):
        raise SpecError(f"expected a finite number, got {out}", key=key)
    _check_bounds(out, key, "a number", above, at_least, below, at_most)
    return out


def parse_integer(value: Any, key: str, *, at_least: int | None = None,
                  at_most: int | None = None) -> int:
    """An integer (booleans and floats refused), optionally bounded (inclusive).

    Parameters
    ----------
    value : Any
        The raw value.
    key : str
        Spec key, for the error.
    at_least, at_most : int, optional
        Inclusive bounds (the value is a count or a seed: dimensionless).

    Returns
    -------
    int
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise SpecError(f"expected an integer{_bounds_text(None, at_least, None, at_most)}, got "
                        f"{_type(value)}", key=key)
    out = int(value)
    if (at_least is not None and out < at_least) or (at_most is not None and out > at_most):
        raise SpecError(f"expected an integer{_bounds_text(None, at_least, None, at_most)}, got "
                        f"{short_repr(out)}", key=key)
    if out > MAX_INTEGER or out < -MAX_INTEGER:
        raise SpecError(f"expected an integer of at most 64 bits (|n| <= 2**63 - 1), got "
                        f"{short_repr(out)}", key=key)
    return out


def parse_choice(value: Any, key: str, allowed: Sequence[Any]) -> Any:
    """One of ``allowed``; for a misspelt string the error suggests the closest choice.

    Parameters
    ----------
    value : Any
        The raw value.
    key : str
        Spec key, for the error.
    allowed : sequence
        The accepted values (a value matches only one of the same type).
    """
    for choice in allowed:
        if type(choice) is type(value) and choice == value:
            return choice
    raise SpecError(f"expected one of {list(allowed)}, got {short_repr(value)}"
                    + did_you_mean(value, [str(a) for a in allowed]), key=key)


def parse_bool(value: Any, key: str) -> bool:
    """``true`` or ``false``.

    Parameters
    ----------
    value : Any
        The raw value (a TOML boolean).
    key : str
        Spec key, for the error.
    """
    if not isinstance(value, (bool, np.bool_)):
        raise SpecError(f"expected true or false, got {_type(value)}", key=key)
    return bool(value)


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr.flags.writeable = False
    return arr


def parse_vector(value: Any, key: str, size: int | None = None, *,
                 names: Sequence[str] | None = None, broadcast: bool = False,
                 above: float | None = None, at_least: float | None = None,
                 below: float | None = None, at_most: float | None = None) -> np.ndarray:
    """Numbers of a given length, as a read-only float array.

    Parameters
    ----------
    value : list, mapping or number
        A list of numbers; with ``names``, also a table keyed by them; with
        ``broadcast``, also one number for every entry.
    key : str
    size : int, optional
        Required length (``len(names)`` when names are given).
    names : sequence of str, optional
        Entry names (signals), for a table and for the errors.
    broadcast : bool
        Accept one number for all ``size`` entries.
    above, at_least, below, at_most : float, optional
        Bounds of every entry (see `parse_number`).

    Returns
    -------
    ndarray, shape (size,)
    """
    bounds = dict(above=above, at_least=at_least, below=below, at_most=at_most)
    if names is not None:
        size = len(names)
    what = f" ({', '.join(names)})" if names is not None else ""
    if isinstance(value, Mapping) and names is not None:
        unknown = [k for k in value if k not in names]
        missing = [k for k in names if k not in value]
        if unknown or missing:
            raise SpecError(f"expected values for {list(names)}"
                            + (f"; unknown: {unknown}" if unknown else "")
                            + (f"; missing: {missing}" if missing else ""), key=key)
        return _frozen(np.array([parse_number(value[k], f"{key}.{k}", **bounds) for k in names]))
    if broadcast and _is_number(value):
        return _frozen(np.full(size if size is not None else 1, parse_number(value, key, **bounds)))
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)) or (size is None and not value):
        table = f" or a table {{{', '.join(names)}}}" if isinstance(names, Sequence) and names else ""
        one = " (or one number for all)" if broadcast else ""
        count = f"{size} " if size is not None else ""
        raise SpecError(f"expected a list of {count}numbers{what}{one}{table}, got {_type(value)}",
                        key=key)
    if size is not None and len(value) != size:
        if names is not None:
            raise SpecError(f"expected {size} values{what}, got {len(value)}", key=key)
        raise SpecError(f"expected a list of {size} numbers, got {len(value)}", key=key)
    return _frozen(np.array([parse_number(v, f"{key}[{i}]", **bounds) for i, v in enumerate(value)],
                            dtype=float))


def parse_matrix(value: Any, key: str, shape: tuple[int | None, int | None] | None = None
                 ) -> np.ndarray:
    """A real matrix given as a list of rows (read-only float array).

    Parameters
    ----------
    value : list of list of float
        The rows (an array is accepted too); entries in the units the option
        states.
    key : str
        Spec key, for the error.
    shape : (int or None, int or None), optional
        The required rows and/or columns (None: any count).

    Returns
    -------
    ndarray, shape (rows, columns)
    """
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)) or not value or \
            not all(isinstance(r, (list, tuple)) for r in value):
        want = "" if shape is None else f"a {shape[0] or 'r'} x {shape[1] or 'c'} matrix: "
        raise SpecError(f"expected {want}a matrix as a list of rows (lists of numbers), got "
                        f"{_type(value)}", key=key)
    rows = [[parse_number(v, f"{key}[{i}][{j}]") for j, v in enumerate(r)] for i, r in enumerate(value)]
    if len({len(r) for r in rows}) != 1 or not rows[0]:
        raise SpecError("rows of the matrix have different lengths (or none)", key=key)
    arr = np.array(rows, dtype=float)
    if shape is not None and any(want is not None and got != want for want, got in zip(shape, arr.shape)):
        raise SpecError(f"expected a {shape[0] or 'r'} x {shape[1] or 'c'} matrix, got "
                        f"{arr.shape[0]} x {arr.shape[1]}", key=key)
    return _frozen(arr)


def parse_covariance(value: Any, key: str, size: int, semidefinite: bool = False) -> np.ndarray:
    """A symmetric positive (semi)definite ``size x size`` matrix.

    Given as a number (``s I``), a list (the diagonal) or a list of rows, in
    the squared units of the state or output.

    Parameters
    ----------
    value : float, list of float or list of list of float
        The raw value (squared units of the state or output).
    key : str
        Spec key, for the error.
    size : int
        The matrix's order (n or q).
    semidefinite : bool, optional
        Accept a singular matrix (positive semidefinite); default False
        (positive definite).

    Returns
    -------
    ndarray, shape (size, size)
        Symmetric, read-only, in the squared units of the value.
    """
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if _is_number(value):
        M = parse_number(value, key) * np.eye(size)
    elif isinstance(value, (list, tuple)) and value and all(_is_number(v) for v in value):
        if len(value) != size:
            raise SpecError(f"expected {size} diagonal entries, got {len(value)}", key=key)
        M = np.diag([parse_number(v, f"{key}[{i}]") for i, v in enumerate(value)])
    elif isinstance(value, (list, tuple)) and value and all(isinstance(r, (list, tuple)) for r in value):
        M = np.array(parse_matrix(value, key))
    else:
        raise SpecError("expected a number (s I), a list (diagonal) or a list of rows, got "
                        f"{_type(value)}", key=key)
    if M.shape != (size, size):
        raise SpecError(f"expected a {size} x {size} matrix, got {M.shape[0]} x {M.shape[1]}", key=key)
    if np.max(np.abs(M), initial=0.0) > MAX_COVARIANCE:
        raise SpecError(f"entries must be at most {MAX_COVARIANCE:g} in magnitude (squared units), "
                        f"got {np.max(np.abs(M)):.3g}", key=key)
    if np.max(np.abs(M - M.T), initial=0.0) > 1e-12 * max(np.max(np.abs(M)), 1e-300):
        raise SpecError("matrix must be symmetric", key=key)
    w = np.linalg.eigvalsh(0.5 * (M + M.T))
    if (w[0] < 0) if semidefinite else (w[0] <= 0):
        kind = "positive semidefinite" if semidefinite else "positive definite"
        raise SpecError(f"matrix must be {kind}; smallest eigenvalue {w[0]:.3g}", key=key)
    return _frozen(0.5 * (M + M.T))


def parse_poles(value: Any, key: str, *, count: int | None = None, conjugate: bool = True,
                real: bool = False, distinct: bool = False, negative_real: bool = False,
                stable_in: str | None = None, count_note: str = "") -> tuple[complex, ...]:
    """Poles from a spec list: numbers, or ``[re, im]`` pairs for complex poles.

    Parameters
    ----------
    value : list
    key : str
        Spec key for error messages.
    count : int, optional
        Required number of poles.
    conjugate : bool
        Complex poles must come in conjugate pairs (a real gain).
    real, distinct : bool
        Every pole real; no pole repeated.
    negative_real : bool
        Every pole with negative real part (continuous-time stable, 1/s).
    stable_in : {"continuous", "discrete"}, optional
        Every pole stable in that domain (``Re p < 0``, or ``|p| < 1``); the
        error says when the poles look written for the other domain.
    count_note : str
        Why ``count`` poles are expected (added to the error).

    Returns
    -------
    tuple of complex
    """
    if not isinstance(value, (list, tuple)) or not value:
        raise SpecError(f"expected a non-empty list of poles (numbers or [re, im] pairs), got "
                        f"{_type(value)}", key=key)
    out = []
    for i, v in enumerate(value):
        if isinstance(v, (list, tuple)):
            if len(v) != 2:
                raise SpecError(f"expected [re, im], got {v!r}", key=f"{key}[{i}]")
            out.append(complex(parse_number(v[0], f"{key}[{i}][0]"), parse_number(v[1], f"{key}[{i}][1]")))
        elif isinstance(v, complex):
            out.append(complex(parse_number(v.real, f"{key}[{i}]"), parse_number(v.imag, f"{key}[{i}]")))
        else:
            out.append(complex(parse_number(v, f"{key}[{i}]")))
    if count is not None and len(out) != count:
        raise SpecError(f"{len(out)} poles given, expected {count}" + (f" ({count_note})" if count_note
                                                                      else ""), key=key)
    scale = max(1.0, max(abs(p) for p in out))
    if real and any(p.imag != 0 for p in out):
        raise SpecError(f"expected real poles, got {[_pole_text(p) for p in out]}", key=key)
    if conjugate:
        a, b = np.sort_complex(np.array(out)), np.sort_complex(np.conj(np.array(out)))
        if not np.allclose(a, b, rtol=0, atol=1e-12 * scale):
            raise SpecError("complex poles must come in conjugate pairs, got "
                            f"{[_pole_text(p) for p in out]}", key=key)
    if distinct and len(set(out)) != len(out):
        raise SpecError(f"expected distinct{' real' if real else ''} poles, got "
                        f"{[_pole_text(p) for p in out]}", key=key)
    if negative_real and not all(p.real < 0 for p in out):
        raise SpecError(f"expected poles with negative real part (1/s), got "
                        f"{[_pole_text(p) for p in out]}", key=key)
    if stable_in == "continuous" and not all(p.real < 0 for p in out):
        hint = ("; these look like z-plane poles: set time_domain = \"discrete\" (with [sampling] ts)"
                if all(abs(p) < 1 for p in out) else "")
        raise SpecError(f"continuous-time poles must have negative real part (1/s), got "
                        f"{[_pole_text(p) for p in out]}{hint}", key=key)
    if stable_in == "discrete" and not all(abs(p) < 1 for p in out):
        hint = ("; these look like s-plane poles (1/s): a discrete design needs |p| < 1, e.g. "
                "exp(p ts), or set time_domain = \"continuous\""
                if all(p.real < 0 for p in out) else "")
        raise SpecError(f"discrete-time poles must lie inside the unit circle, got "
                        f"{[_pole_text(p) for p in out]}{hint}", key=key)
    return tuple(out)


def _pole_text(p: complex) -> str:
    return f"{p.real:g}" if p.imag == 0 else f"{p.real:g}{p.imag:+g}j"


def parse_region(value: Any, key: str) -> tuple[tuple, ...]:
    """An LMI region from a spec list of tables (their intersection).

    Each table has a ``type``: ``"half_plane"`` with ``alpha`` (``Re z <
    -alpha``), ``"disk"`` with ``center`` and ``radius``, ``"sector"`` with
    ``angle_deg`` (half-angle about the negative real axis).

    Parameters
    ----------
    value : list of dict
        One table alone is also accepted; so are the parts this function
        returns.
    key : str

    Returns
    -------
    tuple of tuple
        ``("half_plane", alpha)``, ``("disk", center, radius)``, ``("sector", theta)`` (theta in
        radians); `tanksynth.analysis.lmi_region.region_from_parts` builds the region.
    """
    if isinstance(value, Mapping):
        value = [value]
    if not isinstance(value, (list, tuple)) or not value:
        raise SpecError("expected a list of region tables, e.g. [{type = \"disk\", center = 0.0, "
                        "radius = 0.9}]", key=key)
    parts = []
    for i, item in enumerate(value):
        k = f"{key}[{i}]"
        if isinstance(item, tuple) and item and item[0] in _REGION_FIELDS:  # already parsed
            fields = _REGION_FIELDS[item[0]]
            if len(item) != 1 + len(fields):
                raise SpecError(f"region part {item!r} takes {list(fields)}", key=k)
            args = [parse_number(a, f"{k}.{f}") for a, f in zip(item[1:], fields)]
            if item[0] == "sector":
                args = [float(np.degrees(args[0]))]
            item = {"type": item[0], **dict(zip(fields, args))}
        if not isinstance(item, Mapping):
            raise SpecError(f"expected a table such as {{type = \"disk\", center = 0.9, radius = 0.08}} "
                            f"(types: half_plane {{alpha}}, disk {{center, radius}}, sector {{angle_deg}}), "
                            f"got {short_repr(item)}", key=k)
        kind = item.get("type")
        if not isinstance(kind, str) or kind not in _REGION_FIELDS:
            raise SpecError(f"unknown region type {kind!r}; expected one of {list(_REGION_FIELDS)}"
                            + did_you_mean(kind, list(_REGION_FIELDS)), key=f"{k}.type")
        fields = _REGION_FIELDS[kind]
        extra = [f for f in item if f not in ("type", *fields)]
        missing = [f for f in fields if f not in item]
        if extra or missing:
            raise SpecError(f"region '{kind}' takes {list(fields)}"
                            + (f"; unknown {extra}" if extra else "")
                            + (f"; missing {missing}" if missing else ""), key=k)
        args = [parse_number(item[f], f"{k}.{f}") for f in fields]
        if kind == "disk" and not args[1] > 0:
            raise SpecError(f"disk radius must be > 0, got {args[1]:g}", key=f"{k}.radius")
        if kind == "sector" and not 0 < args[0] < 90:
            raise SpecError(f"sector half-angle must be in (0, 90) degrees, got {args[0]:g}",
                            key=f"{k}.angle_deg")
        parts.append((kind, *args) if kind != "sector" else (kind, float(np.radians(args[0]))))
    empty = region_emptiness(parts)
    if empty:
        raise SpecError(f"the region is empty: {empty}; no closed loop can have its eigenvalues "
                        "there, whatever the plant: widen or remove a part", key=key)
    return tuple(parts)


def _part_interval(part: tuple) -> tuple[float, float]:
    """The open interval of the real axis inside one region part (`parse_region` form)."""
    if part[0] == "half_plane":
        return -np.inf, -float(part[1])
    if part[0] == "disk":
        return float(part[1]) - float(part[2]), float(part[1]) + float(part[2])
    return -np.inf, 0.0  # a sector about the negative real axis (apex 0 excluded)


def region_real_interval(parts: Sequence[tuple]) -> tuple[float, float]:
    """The real points of a region: the open interval ``(lo, hi)`` (empty when ``lo >= hi``).

    Every part (half-plane ``Re z < -alpha``, disk with a real centre, sector about the
    negative real axis) is convex and symmetric about the real axis, so their intersection
    is too: it is empty exactly when it has no real point (the midpoint of ``z`` and its
    conjugate is real and inside). This interval therefore decides emptiness.

    Parameters
    ----------
    parts : sequence of tuple
        The region's parts (`parse_region`).

    Returns
    -------
    (float, float)
        ``lo``, ``hi`` (units of the eigenvalues; ``-inf`` when unbounded on the left).
    """
    lo, hi = -np.inf, np.inf
    for part in parts:
        a, b = _part_interval(part)
        lo, hi = max(lo, a), min(hi, b)
    return float(lo), float(hi)


def region_emptiness(parts: Sequence[tuple]) -> str:
    """Why a region (`parse_region` parts) is empty, ``""`` when it is not (`region_real_interval`).

    Parameters
    ----------
    parts : sequence of tuple
        The region's parts.

    Returns
    -------
    str
        E.g. ``"part 0 (half_plane) allows real parts below -0.5 only, part 1 (disk) real
        parts in (0.2, 0.4) only: they do not intersect"``.
    """
    lo, hi = region_real_interval(parts)
    if lo < hi:
        return ""
    intervals = [_part_interval(p) for p in parts]
    i_lo = max(range(len(parts)), key=lambda i: intervals[i][0])   # the part that sets lo
    i_hi = min(range(len(parts)), key=lambda i: intervals[i][1])   # the part that sets hi

    def allows(i: int) -> str:
        a, b = intervals[i]
        span = f"below {b:.10g}" if a == -np.inf else f"in ({a:.10g}, {b:.10g})"
        return f"part {i} ({parts[i][0]}) allows real parts {span} only"

    return (f"{allows(i_hi)}, {allows(i_lo)}: they do not intersect (each part is symmetric about "
            "the real axis and convex, so the intersection would contain a real point)")


def region_is_stable(parts: Sequence[tuple], domain: str) -> bool:
    """True if one part of a region (as `parse_region` returns it) lies in the stability domain.

    Continuous time: a half-plane with ``alpha >= 0``, a disk with ``center +
    radius <= 0`` or a sector; discrete time: a disk with ``|center| + radius
    <= 1``. The intersection lies inside each of its parts.

    Parameters
    ----------
    parts : sequence of tuple
        The region's parts (`parse_region`): ``alpha``, ``center`` and
        ``radius`` in 1/s in continuous time (dimensionless in discrete
        time), sector angles in radians.
    domain : {"continuous", "discrete"}
        The time domain of the design.
    """
    if domain == "discrete":
        return any(p[0] == "disk" and abs(p[1]) + p[2] <= 1 for p in parts)
    return any((p[0] == "half_plane" and p[1] >= 0) or (p[0] == "disk" and p[1] + p[2] <= 0)
               or (p[0] == "sector" and p[1] < np.pi / 2) for p in parts)


def parse_names(value: Any, key: str, known: Sequence[str], *, what: str = "name",
                at_least: int = 1, at_most: int | None = None, count: int | None = None,
                unique: bool = True) -> tuple[str, ...]:
    """A list of names, each one of ``known`` (e.g. the plant's outputs or states).

    Parameters
    ----------
    value : list of str
    key : str
    known : sequence of str
        The accepted names.
    what : str
        What a name is, for the errors (``"output"``, ``"state"``).
    at_least, at_most, count : int, optional
        How many names.
    unique : bool
        Refuse a name listed twice.

    Returns
    -------
    tuple of str
    """
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        raise SpecError(f"expected a list of {what} names (some of {list(known)}), got "
                        f"{_type(value)}", key=key)
    for v in value:
        if v not in known:
            raise SpecError(f"unknown {what} {v!r}; expected some of {list(known)}"
                            + did_you_mean(v, known), key=key)
    if unique and len(set(value)) != len(value):
        raise SpecError(f"{what}s listed twice: {list(value)}", key=key)
    n = len(value)
    if count is not None and n != count:
        raise SpecError(f"expected {count} {what} name(s), got {n}: {list(value)}", key=key)
    if n < at_least or (at_most is not None and n > at_most):
        most = f" and at most {at_most}" if at_most is not None else ""
        raise SpecError(f"expected at least {at_least}{most} {what} name(s), got {n}", key=key)
    return tuple(value)


def parse_box(value: Any, key: str, names: Sequence[str], *, what: str = "state"
              ) -> dict[str, tuple[float, float]]:
    """Bounds ``{name = [min, max]}`` of some named signals (``min < max``).

    Parameters
    ----------
    value : mapping of str to [float, float]
        The raw table; bounds in each signal's own unit (e.g. m for a level).
    key : str
        Spec key, for the error.
    names : sequence of str
        The signals that may be bounded.
    what : str, optional
        What a name is, for the errors (default ``"state"``).

    Returns
    -------
    dict of str to (float, float)
        ``name -> (min, max)`` in the signal's unit.
    """
    if not isinstance(value, Mapping):
        raise SpecError(f"expected a table {{{what} = [min, max]}}, got {_type(value)}", key=key)
    out = {}
    for nm, b in value.items():
        k = f"{key}.{nm}"
        if nm not in names:
            raise SpecError(f"unknown {what} {nm!r}; expected one of {list(names)}"
                            + did_you_mean(nm, names), key=k)
        if not isinstance(b, (list, tuple)) or len(b) != 2:
            raise SpecError(f"expected [min, max], got {_type(b)}", key=k)
        lo, hi = parse_number(b[0], k + "[0]"), parse_number(b[1], k + "[1]")
        if not lo < hi:
            raise SpecError(f"min ({lo:g}) must be smaller than max ({hi:g})", key=k)
        out[str(nm)] = (lo, hi)
    return out
