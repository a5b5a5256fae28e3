"""Reading an artefact's diagnostics tree tolerantly, and what several method families write.

The readers (`entry`, `entries`, `section`, `names`) turn a missing key or a value of the
wrong type into "missing", so that an artefact edited by hand gives a report without the
edited quantity instead of a traceback (`tanksynth.reports.diagnostics`). The shared sections
are the time domain, integral action (`integral_of`), the LMI region a design was asked for
(`lmi_region_of`) and the printed values a design was compared with (`references_of`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, TypeGuard, TypeVar, Union

import numpy as np

__all__ = ["Diagnostics", "JsonNumber", "is_number", "is_json_number", "is_text", "is_flag", "entry", "entries",
           "section", "names", "eigenvalue_pairs", "description", "time_domain_of", "Integral", "integral_of",
           "LmiRegion", "lmi_region_of", "Reference", "references_of"]

#: The type an `entry` is read as.
T = TypeVar("T")

#: An artefact's ``"diagnostics"``: a JSON tree (mappings, lists, numbers, strings).
Diagnostics = Mapping[str, Any]

#: A number as an artefact writes it: a float or int, one of the strings ``"inf"``, ``"-inf"``,
#: ``"nan"`` (strict JSON has no non-finite numbers; `tanksynth.artefacts.io.to_jsonable`), or
#: None where the design had no value. `tanksynth.reports.latex.format_number` prints each.
JsonNumber = Union[float, str, None]

_NON_FINITE = ("inf", "-inf", "nan")


def is_number(value: Any) -> TypeGuard[float]:
    """True for an int or float that is not a bool (JSON ``true`` is no number).

    Parameters
    ----------
    value : object
        A diagnostics value.
    """
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_json_number(value: Any) -> TypeGuard[JsonNumber]:
    """True for a `JsonNumber`: a number, a non-finite number's string, or None.

    Parameters
    ----------
    value : object
        A diagnostics value.
    """
    return value is None or is_number(value) or (isinstance(value, str) and value in _NON_FINITE)


def is_text(value: Any) -> TypeGuard[str]:
    """True for a non-empty string (an empty one says nothing).

    Parameters
    ----------
    value : object
        A diagnostics value.
    """
    return isinstance(value, str) and bool(value)


def is_flag(value: Any) -> TypeGuard[bool]:
    """True for a bool: a yes or no the design wrote.

    Parameters
    ----------
    value : object
        A diagnostics value.
    """
    return isinstance(value, bool)


def entry(node: Any, key: str, accept: Callable[[Any], TypeGuard[T]]) -> T | None:
    """``node[key]`` when ``accept`` takes it, else None: ``node`` is no mapping, has no such
    key, or holds a value of another type there. Numbers stay as written (an int stays an int).

    Parameters
    ----------
    node : object
        A diagnostics mapping (anything else reads as empty).
    key : str
        The entry's key.
    accept : callable
        The entry's type check, ``accept(value) -> bool`` (`is_number`, `is_json_number`,
        `is_text`, `is_flag`).
    """
    value = node.get(key) if isinstance(node, Mapping) else None
    return value if accept(value) else None


def entries(node: Any, key: str, accept: Callable[[Any], TypeGuard[T]]) -> tuple[T, ...] | None:
    """``node[key]`` as a tuple when it is a list whose every element ``accept`` takes (possibly
    empty), else None.

    Parameters
    ----------
    node : object
        A diagnostics mapping (anything else reads as empty).
    key : str
        The list's key.
    accept : callable
        The elements' type check (`is_number`, `is_json_number` ...).
    """
    value = node.get(key) if isinstance(node, Mapping) else None
    return tuple(value) if isinstance(value, list) and all(accept(v) for v in value) else None


def section(node: Any, key: str) -> Mapping[str, Any]:
    """``node[key]`` when both are mappings, else an empty mapping.

    Parameters
    ----------
    node : object
        A diagnostics mapping (anything else reads as empty).
    key : str
        The section's key.
    """
    value = node.get(key) if isinstance(node, Mapping) else None
    return value if isinstance(value, Mapping) else {}


def names(node: Any, key: str) -> tuple[str, ...]:
    """``node[key]`` as a tuple of names (each entry as ``str``); empty unless it is a list.

    Parameters
    ----------
    node : object
        A diagnostics mapping.
    key : str
        The list's key.
    """
    value = node.get(key) if isinstance(node, Mapping) else None
    return tuple(str(v) for v in value) if isinstance(value, list) else ()


def eigenvalue_pairs(node: Any, key: str) -> tuple[tuple[float, float], ...] | None:
    """``node[key]`` as eigenvalues ``(re, im)`` (written as numbers or ``[re, im]`` pairs), or
    None when it is not such a list. Units are the design's (1/s continuous, none discrete).

    Parameters
    ----------
    node : object
        A diagnostics mapping.
    key : str
        The eigenvalue list's key.
    """
    value = node.get(key) if isinstance(node, Mapping) else None
    if not isinstance(value, list):
        return None
    pairs = []
    try:  # the conversions of `tanksynth.reports.latex.format_eigenvalues`, which prints them
        for v in value:
            if isinstance(v, (list, tuple)):
                if len(v) != 2:
                    return None
                pairs.append((float(v[0]), float(v[1])))
            else:
                pairs.append((float(v), 0.0))
    except (TypeError, ValueError):
        return None
    return tuple(pairs)


def description(node: Any, key: str) -> str | None:
    """``node[key]["description"]``: the words of a region or domain the design wrote
    (``|z - 0.9| < 0.08``), or None.

    Parameters
    ----------
    node : object
        A diagnostics mapping.
    key : str
        The key of the region or domain section (``"region"``, ``"domain"``).
    """
    return entry(section(node, key), "description", is_text)


def time_domain_of(diag: Diagnostics) -> str | None:
    """The design's ``time_domain`` (``"continuous"`` or ``"discrete"``), or None.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return entry(diag, "time_domain", is_text)


@dataclass(frozen=True)
class Integral:
    """Integral action a design added (``diagnostics["integral"]``).

    Attributes
    ----------
    tracked : tuple of str
        The outputs integrated (and so tracked without offset).
    """

    tracked: tuple[str, ...]


def integral_of(diag: Diagnostics) -> Integral | None:
    """The design's integral action, or None without one.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    integral = diag.get("integral") if isinstance(diag, Mapping) else None
    if not isinstance(integral, Mapping):
        return None
    return Integral(names(integral, "tracked"))


@dataclass(frozen=True)
class LmiRegion:
    """An LMI region ``D = {z : L + M z + M' conj(z) < 0}`` a design placed its poles in.

    Attributes
    ----------
    L, M : ndarray, shape (k, k)
        The region's matrices (``L`` in the units of z: 1/s in continuous time, dimensionless in
        discrete time; ``M`` dimensionless).
    description : str
        The region in words (empty when not written).
    domain : str or None
        The plane: ``"continuous"`` (s-plane) or ``"discrete"`` (z-plane), when the design says.
    """

    L: np.ndarray
    M: np.ndarray
    description: str
    domain: str | None


def lmi_region_of(diag: Diagnostics) -> LmiRegion | None:
    """The LMI region of the design: the first ``region`` section with square matrices ``L``
    and ``M`` of one shape, searched breadth first (``lmi.region``, ``robust.region``,
    ``synthesis.region`` ...), or None.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    frontier: list[Any] = [diag]
    while frontier:
        node = frontier.pop(0)
        if not isinstance(node, Mapping):
            continue
        region = node.get("region")
        if isinstance(region, Mapping) and "L" in region and "M" in region:
            try:
                L, M = np.asarray(region["L"], dtype=float), np.asarray(region["M"], dtype=float)
            except (TypeError, ValueError):
                return None
            if L.ndim == 2 and L.shape == M.shape and L.shape[0] == L.shape[1]:
                domain = time_domain_of(diag) or entry(section(diag, "lmi"), "domain", is_text)
                return LmiRegion(L, M, entry(region, "description", is_text) or "", domain)
        frontier.extend(v for v in node.values() if isinstance(v, Mapping))
    return None


@dataclass(frozen=True)
class Reference:
    """A printed value the spec gave a design to compare with (``diagnostics["reference_*"]``).

    Attributes
    ----------
    label : str
        What was compared (``gain``, ``L``, ``closed_loop``; ``value`` when unnamed).
    reference : ndarray
        The printed value (its own units).
    derived : ndarray
        The design's value, same units.
    eigenvalues : tuple
        The eigenvalues the printed value gives, ``(re, im)`` pairs per set recorded (1/s, or
        dimensionless in discrete time).
    max_pole_error : float or None
        How far those eigenvalues are from the design's, at most (same units).
    note : str or None
        The design's remark on the comparison.
    """

    label: str
    reference: np.ndarray
    derived: np.ndarray
    eigenvalues: tuple[tuple[tuple[float, float], ...], ...] = ()
    max_pole_error: float | None = None
    note: str | None = None


def _reference(key: str, ref: Mapping[str, Any]) -> Reference | None:
    try:
        reference = np.asarray(ref["reference"], dtype=float)
        derived = np.asarray(ref["derived"], dtype=float)
    except (TypeError, ValueError):
        return None
    eigenvalues = (eigenvalue_pairs(ref, k) for k in ("reference_closed_loop_eigenvalues", "reference_eigenvalues"))
    error = entry(ref, "reference_max_pole_error", is_number)
    note = ref.get("note")
    return Reference(key[len("reference_"):] or "value", reference, derived,
                     eigenvalues=tuple(e for e in eigenvalues if e is not None),
                     max_pole_error=error if error is not None and math.isfinite(error) else None,
                     note=note if isinstance(note, str) else None)


def references_of(diag: Diagnostics) -> tuple[Reference, ...]:
    """Every ``reference_*`` comparison the design stored (by key) whose values are numbers.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    found = (_reference(str(key), diag[key]) for key in sorted(k for k in diag if str(k).startswith("reference"))
             if isinstance(diag[key], Mapping) and "reference" in diag[key] and "derived" in diag[key])
    return tuple(r for r in found if r is not None)
