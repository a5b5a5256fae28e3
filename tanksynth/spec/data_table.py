"""The ``[data]`` table of a spec: how logged data files map onto the plant's signals.

Example::

    [data]
    time = "t"                               # time column (s); default "t"
    # ts = 1.0                               # or a fixed period (s): the files have no time column
    columns = {q1 = "pump1", h1 = "level1"}  # plant input/output name -> column (default: same name)
    scale = {h1 = 0.01}                      # plant value = column value * scale (cm -> m)
    limits = {h1 = [0.0, 0.60]}              # sensor range of an output (samples there: censored)
    states = {h2 = "h2_ref"}                 # logged reference states (state name -> column)

The table is validated with the spec (`tanksynth.spec.Spec.data`); the files themselves are read
by `tanksynth.measurements.read_experiments`. This module sits in the spec layer so that a spec
is checked before any data file is opened.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Mapping

from tanksynth.errors import SpecError
from tanksynth.spec.options import parse_box, parse_number, short_repr, unknown_word_hint

if TYPE_CHECKING:
    from tanksynth.plants.base import Plant

__all__ = ["DataTable", "parse_data_table", "DATA_KEYS", "MAX_COLUMN_NAME"]

#: The keys of a ``[data]`` table and what each one means.
DATA_KEYS = {
    "time": "time column name (s), default \"t\"",
    "ts": "fixed sampling period (s) when the files have no time column",
    "columns": "plant input/output name -> column name",
    "scale": "plant value = column value * scale, per signal",
    "limits": "sensor range [min, max] per output (samples at a limit are censored)",
    "states": "state name -> column of a logged reference state",
}
#: Longest column name accepted (characters).
MAX_COLUMN_NAME = 128
#: Largest sampling period ``ts`` accepted (s), as for ``[sampling] ts``.
MAX_DATA_TS = 1e6


def _frozen(mapping: Mapping[str, Any]) -> Mapping[str, Any]:
    return MappingProxyType(dict(mapping))


@dataclass(frozen=True)
class DataTable:
    """The validated ``[data]`` table (every name checked against the plant).

    Attributes
    ----------
    time : str or None
        Name of the time column (s); None when ``ts`` is given.
    ts : float or None
        Fixed sampling period (s) of files without a time column; None when ``time`` is used.
    columns : mapping of str to str
        Plant input or output name -> its column name (only the renamed ones; any other
        signal is read from the column of its own name).
    scale : mapping of str to float
        Input, output or state name -> factor: plant value = column value * factor.
    limits : mapping of str to (float, float)
        Output name -> sensor range (output unit), overriding a range declared by the plant.
    states : mapping of str to str
        State name -> column of a logged reference state (state unit after ``scale``).
    """

    time: str | None = "t"
    ts: float | None = None
    columns: Mapping[str, str] = field(default_factory=lambda: _frozen({}))
    scale: Mapping[str, float] = field(default_factory=lambda: _frozen({}))
    limits: Mapping[str, tuple[float, float]] = field(default_factory=lambda: _frozen({}))
    states: Mapping[str, str] = field(default_factory=lambda: _frozen({}))

    def column(self, name: str) -> str:
        """The column that holds the plant input or output ``name`` (its own name by default).

        Parameters
        ----------
        name : str
            A plant input or output name.
        """
        return self.columns.get(name, name)

    def factor(self, name: str) -> float:
        """The scale of signal ``name`` (1.0 when none is given).

        Parameters
        ----------
        name : str
            A plant input, output or state name.
        """
        return float(self.scale.get(name, 1.0))


def _column_name(value: Any, key: str) -> str:
    if not isinstance(value, str) or not value.strip() or len(value) > MAX_COLUMN_NAME:
        raise SpecError(f"expected a column name (a non-empty string of at most {MAX_COLUMN_NAME} "
                        f"characters), got {short_repr(value)}", key=key)
    return value


def _names_table(value: Any, key: str, known: list[str], what: str) -> dict[str, Any]:
    if not isinstance(value, Mapping):
        raise SpecError(f"expected a table {{{what} name = ...}}, got {type(value).__name__} "
                        f"{short_repr(value)}", key=key)
    for nm in value:
        if nm not in known:
            raise SpecError(f"unknown {what} {nm!r} of the plant" + unknown_word_hint(nm, known),
                            key=f"{key}.{nm}")
    return dict(value)


def parse_data_table(raw: Any, plant: Plant, key: str = "data") -> DataTable:
    """Validate a ``[data]`` table against the plant's signal names.

    Parameters
    ----------
    raw : mapping
        The table as written in the spec (keys `DATA_KEYS`).
    plant : Plant
        The spec's plant (its input, output and state names).
    key : str, optional
        Where the table is in the spec, for the errors.

    Returns
    -------
    DataTable

    Raises
    ------
    SpecError
        Unknown key or plant name (with "did you mean"), a column named twice, both ``time`` and
        ``ts``, a scale that is zero or not finite, a sensor range with ``min >= max``.
    """
    if not isinstance(raw, Mapping):
        raise SpecError(f"expected a table [{key}], got {type(raw).__name__}", key=key)
    for k in raw:
        if k not in DATA_KEYS:
            raise SpecError(f"unknown key {k!r}" + unknown_word_hint(k, list(DATA_KEYS)),
                            key=f"{key}.{k}")
    inputs = [s.name for s in plant.inputs]
    outputs = [s.name for s in plant.outputs]
    states = [s.name for s in plant.states]
    signals = list(dict.fromkeys(inputs + outputs))
    if "time" in raw and "ts" in raw:
        raise SpecError("give either a time column (time) or a fixed period (ts), not both",
                        key=f"{key}.ts")
    ts = (parse_number(raw["ts"], f"{key}.ts", above=0.0, at_most=MAX_DATA_TS)
          if "ts" in raw else None)
    time = None if ts is not None else _column_name(raw.get("time", "t"), f"{key}.time")

    columns = {nm: _column_name(col, f"{key}.columns.{nm}") for nm, col in
               _names_table(raw.get("columns", {}), f"{key}.columns", signals, "input or output").items()}
    scale_names = list(dict.fromkeys(signals + states))
    scale = {nm: parse_number(v, f"{key}.scale.{nm}") for nm, v in
             _names_table(raw.get("scale", {}), f"{key}.scale", scale_names, "input, output or state").items()}
    for nm, v in scale.items():
        if v == 0.0:
            raise SpecError("a scale of 0 erases the signal; expected a nonzero factor "
                            "(plant value = column value * scale)", key=f"{key}.scale.{nm}")
    limits = parse_box(raw.get("limits", {}), f"{key}.limits", outputs, what="output")
    refs = {nm: _column_name(col, f"{key}.states.{nm}") for nm, col in
            _names_table(raw.get("states", {}), f"{key}.states", states, "state").items()}

    # every column feeds one signal: the time, each input and output (renamed or by its own
    # name), each reference state
    owner: dict[str, str] = {}
    uses = ([(time, "the time", f"{key}.time")] if time is not None else [])
    uses += [(columns.get(nm, nm), f"{'input' if nm in inputs else 'output'} {nm}",
              f"{key}.columns.{nm}") for nm in signals]
    uses += [(col, f"reference state {nm}", f"{key}.states.{nm}") for nm, col in refs.items()]
    for col, what, k in uses:
        if col in owner:
            raise SpecError(f"column {col!r} would feed both {owner[col]} and {what}: map one of "
                            f"them to another column in [{key}] columns", key=k)
        owner[col] = what
    return DataTable(time=time, ts=ts, columns=_frozen(columns), scale=_frozen(scale),
                     limits=_frozen(limits), states=_frozen(refs))
