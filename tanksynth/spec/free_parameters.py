"""Free plant parameters: ``{value, min, max, fit = true}`` in ``[plant.parameters]``.

A parameter written as a table with ``fit = true`` is estimated from measured data
(``tanksynth fit``, the ``fit`` method): ``value`` is the starting point, ``[min, max]`` the
closed search box, which must lie inside the parameter's admissible range. Without ``fit`` (or
with ``fit = false``) the table is just a value (its ``min``/``max``, if any, are still
checked, so that a fit can be switched off and on again without editing them)::

    [plant.parameters]
    mu13 = {value = 0.5, min = 0.2, max = 0.9, fit = true}   # free
    mu20 = 0.675                                              # fixed

Built-in families take the table here (`split_parameters`); custom plants take ``fit`` beside
their ``{value, unit, min, max}`` (`tanksynth.plants.custom`), read back by
`custom_free_parameters`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping

from tanksynth.errors import SpecError
from tanksynth.plants.base import check_search_box
from tanksynth.spec.options import parse_bool, short_repr, unknown_word_hint

if TYPE_CHECKING:
    from tanksynth.plants.base import Plant

__all__ = ["FreeParameter", "split_parameters", "custom_free_parameters", "PARAMETER_FIELDS"]

#: Fields of a built-in plant's parameter table.
PARAMETER_FIELDS = ("value", "min", "max", "fit")


@dataclass(frozen=True)
class FreeParameter:
    """A plant parameter estimated from data.

    Attributes
    ----------
    name : str
        The plant's parameter name.
    start : float
        Starting value (the spec's ``value``; the parameter's unit).
    lower, upper : float
        Search box ``[lower, upper]`` (closed; the parameter's unit), ``lower < upper``,
        inside the parameter's admissible range.
    unit : str
        The parameter's unit.
    """

    name: str
    start: float
    lower: float
    upper: float
    unit: str


def split_parameters(raw: Any, plant: Plant, key: str = "plant.parameters"
                     ) -> tuple[dict[str, Any], tuple[FreeParameter, ...]]:
    """Values and free parameters of a built-in plant's ``[plant.parameters]`` table.

    Parameters
    ----------
    raw : mapping
        The table as written: ``name = number`` or ``name = {value, min, max, fit}``.
    plant : Plant
        The family's plant with its default parameters (names, units, admissible ranges).
    key : str, optional
        Where the table is in the spec.

    Returns
    -------
    values : dict of str to Any
        ``name -> value`` for `tanksynth.plants.Plant.with_parameters` (which checks them).
    free : tuple of FreeParameter
        The parameters with ``fit = true``, in the table's order.

    Raises
    ------
    SpecError
        An unknown parameter (with "did you mean"), an unknown field, ``value`` missing,
        ``fit`` not a boolean, ``min``/``max`` not numbers or outside the admissible range,
        ``min >= max``, ``value`` outside ``[min, max]``, ``fit = true`` without both bounds.
    """
    if not isinstance(raw, Mapping):
        raise SpecError("expected a table of parameter values", key=key)
    known = {prm.name: prm for prm in plant.parameters}
    values: dict[str, Any] = {}
    free: list[FreeParameter] = []
    for name, entry in raw.items():
        pkey = f"{key}.{name}"
        if name not in known:
            what = ("a free parameter (fit = true) must be one of the plant's"
                    if isinstance(entry, Mapping) and entry.get("fit") is True else "unknown parameter")
            raise SpecError(f"{what}: {name!r} is not a parameter of plant '{plant.name}'"
                            + unknown_word_hint(name, list(known)), key=pkey)
        if not isinstance(entry, Mapping):
            values[name] = entry
            continue
        prm = known[name]
        extra = [f for f in entry if f not in PARAMETER_FIELDS]
        if extra:
            raise SpecError(f"unknown field {extra[0]!r}" + unknown_word_hint(extra[0], PARAMETER_FIELDS)
                            + f" (a built-in parameter's unit is {prm.unit})", key=f"{pkey}.{extra[0]}")
        if "value" not in entry:
            raise SpecError("expected a number or a table {value, min, max, fit}: give value "
                            "(the starting point of a fit)", key=pkey)
        value = prm.check(entry["value"], f"{pkey}.value")
        fit = parse_bool(entry["fit"], f"{pkey}.fit") if "fit" in entry else False
        lower = prm.check(entry["min"], f"{pkey}.min") if "min" in entry else None
        upper = prm.check(entry["max"], f"{pkey}.max") if "max" in entry else None
        check_search_box(name, value, lower, upper, fit, pkey)
        values[name] = value
        if fit and lower is not None and upper is not None:   # (check_search_box: fit has both)
            free.append(FreeParameter(name, value, lower, upper, prm.unit))
    return values, tuple(free)


def custom_free_parameters(raw: Any, plant: Plant, key: str = "plant.parameters"
                           ) -> tuple[FreeParameter, ...]:
    """The free parameters of a custom plant (its table validated by `tanksynth.plants.custom`).

    Parameters
    ----------
    raw : mapping
        The custom plant's ``[plant.parameters]`` table as written.
    plant : Plant
        The custom plant built from it (values, units, ``min``/``max`` as the search box).
    key : str, optional
        Where the table is in the spec.

    Returns
    -------
    tuple of FreeParameter
        The parameters with ``fit = true``, in the table's order.
    """
    if not isinstance(raw, Mapping):
        return ()
    free = []
    for name, entry in raw.items():
        if isinstance(entry, Mapping) and entry.get("fit") is True:
            prm = plant.parameter(name)
            if prm.lower is None or prm.upper is None:  # custom_plant refuses this first
                raise SpecError(f"a free parameter (fit = true) needs min and max, got {short_repr(entry)}",
                                key=f"{key}.{name}")
            free.append(FreeParameter(name, prm.value, prm.lower, prm.upper, prm.unit))
    return tuple(free)
