"""Reading an artefact's diagnostics tree tolerantly, and what several method families write.

The readers (`entry`, `entries`, `section`, `names`) turn a missing key or a value of the
wrong type into "missing", so that an artefact edited by hand gives a report without the
edited quantity instead of a traceback (`tanksynth.reports.diagnostics`). The shared sections
are the time domain, integral action (`integral_of`) and the description of an LMI region.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, TypeGuard, TypeVar, Union

__all__ = ["Diagnostics", "JsonNumber", "is_number", "is_json_number", "is_text", "is_flag", "entry", "entries",
           "section", "names", "eigenvalue_pairs", "description", "time_domain_of", "Integral", "integral_of"]

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
