"""Units of the gains printed in a report, derived from the plant record's signal units.

A state feedback ``u = u_op - K (x - x_op)`` has ``K`` in input units per state unit; an
observer ``x_hat' = ... + L (y - C x_hat)`` has ``L`` in state units per output unit, per
sample in discrete time and per second in continuous time. A unit is given only when it is
one unit for the whole matrix: every state in the same unit, every input (output) in the same
unit; a plant with mixed units gets no unit line rather than a wrong one.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

__all__ = ["unit_ratio", "gain_unit", "design_is_continuous"]

#: Gain names whose unit this module knows: name -> (numerator signals, denominator signals).
_GAIN_SIGNALS = {"K": ("inputs", "states"), "L": ("states", "outputs")}
_DIMENSIONLESS = ("", "1", "-")


def _common_unit(signals: Sequence[Any]) -> str | None:
    """The unit shared by every signal, ``None`` when they differ or there are none."""
    units = {str(s.get("unit", "")).strip() for s in signals if isinstance(s, Mapping)}
    if len(units) != 1 or len(signals) == 0:
        return None
    return units.pop()


def _grouped(unit: str) -> str:
    """``unit`` ready to stand in a quotient: compound units in parentheses."""
    return f"({unit})" if any(ch in unit for ch in "/* ") else unit


def unit_ratio(numerator: str, denominator: str) -> str:
    """The unit ``numerator / denominator`` as a string ``format_unit`` typesets.

    Parameters
    ----------
    numerator, denominator : str
        Units such as ``m^3/s`` or ``m``; ``"1"`` (or empty) is dimensionless.

    Returns
    -------
    str
        ``(m^3/s)/m`` for ``m^3/s`` over ``m``; ``"1"`` when both are dimensionless.
    """
    num, den = numerator.strip(), denominator.strip()
    if den in _DIMENSIONLESS:
        return num if num not in _DIMENSIONLESS else "1"
    return f"{_grouped(num) if num not in _DIMENSIONLESS else '1'}/{_grouped(den)}"


def gain_unit(name: str, plant: Mapping[str, Any] | None, continuous: bool | None,
              columns: int | None = None) -> str | None:
    """The unit of gain ``name`` from the plant record, ``None`` when it cannot be given.

    Parameters
    ----------
    name : str
        Gain name: ``K`` (state feedback) or ``L`` (observer); others give ``None``.
    plant : mapping or None
        The plant record's ``plant`` table (``states``, ``inputs``, ``outputs`` with ``unit``).
    continuous : bool or None
        Time domain of the design: True continuous (``L`` per second), False discrete (``L``
        per sample), None unknown (no unit for ``L``).
    columns : int, optional
        Columns of the gain: a ``K`` with more columns than states carries integral action
        (``[K1 K2]``, ``K2`` on the integrated output error, another unit): no single unit.

    Returns
    -------
    str or None
        E.g. ``(m^3/s)/m`` for ``K`` of the three-tank plant, ``m/m`` for its discrete ``L``,
        ``m/(m s)`` for a continuous ``L``; ``"1"`` for a dimensionless gain.
    """
    signals = _GAIN_SIGNALS.get(name)
    if signals is None or not isinstance(plant, Mapping):
        return None
    if name == "L" and continuous is None:
        return None
    if name == "K" and columns is not None and columns != len(plant.get("states") or []):
        return None
    num = _common_unit(plant.get(signals[0]) or [])
    den = _common_unit(plant.get(signals[1]) or [])
    if num is None or den is None:
        return None
    if name == "L" and continuous:
        den = "s" if den in _DIMENSIONLESS else f"{den} s"
    return unit_ratio(num, den)


def design_is_continuous(diagnostics: Mapping[str, Any]) -> bool | None:
    """The design's time domain from its diagnostics (``time_domain`` or ``form``), None if unsaid.

    Parameters
    ----------
    diagnostics : mapping
        The artefact's ``diagnostics``.
    """
    for key in ("time_domain", "form"):
        value = diagnostics.get(key)
        if value in ("continuous", "discrete"):
            return value == "continuous"
    return None
