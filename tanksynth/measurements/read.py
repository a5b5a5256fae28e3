"""`read_experiments`: data files -> checked `Experiment` objects in the plant's names and units.

Each file is one experiment (named by its stem). Its columns are mapped onto the plant by the
spec's ``[data]`` table (`tanksynth.spec.data_table.DataTable`): every plant input is required,
each output is optional (at least one is needed), the time comes from a time column or a fixed
period. Values are scaled (``plant value = column value * scale``), checked for a unit that
cannot be right, and the outputs' samples at a sensor limit are flagged censored and clipped
to the limit. Every problem is a `DataError` (exit code 2) naming the file, the column and the
row.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from tanksynth.errors import DataError
from tanksynth.measurements.experiment import Experiment
from tanksynth.measurements.files import read_data_bytes
from tanksynth.measurements.formats import FORMATS, ColumnFile
from tanksynth.spec.data_table import DataTable, parse_data_table
from tanksynth.spec.options import did_you_mean

if TYPE_CHECKING:
    from tanksynth.plants.base import Plant

__all__ = ["read_experiments", "read_experiment", "output_ranges", "censor", "check_fit_data",
           "MAX_EXPERIMENTS", "LIMIT_RTOL", "OUTPUT_UNIT_FACTOR", "INPUT_UNIT_FACTOR",
           "MIN_TIME_STEP", "MAX_TIME_STEP", "MAX_GAP_RATIO"]

#: Most data files read at once.
MAX_EXPERIMENTS = 256
#: A sample within ``LIMIT_RTOL * (max - min)`` of a sensor limit (or beyond it) is at the limit.
LIMIT_RTOL = 1e-6
#: An output or reference-state column whose magnitude exceeds this many times the plant's
#: range on its operating region is in another unit (cm for m, mm for m).
OUTPUT_UNIT_FACTOR = 10.0
#: An input column whose magnitude exceeds this many times the plant's actuator bound is in
#: another unit (l/s, l/min or ml/s for m^3/s: a pump logged at 10x its capacity is no pump).
INPUT_UNIT_FACTOR = 10.0
#: Shortest time step accepted (s): a shorter one means a time column not in seconds.
MIN_TIME_STEP = 1e-9
#: Longest time step accepted (s), the bound of ``[data] ts`` and ``[sampling] ts``.
MAX_TIME_STEP = 1e6
#: A time step longer than this many times the log's median step is a gap (the logger was
#: paused): the model, held input and fixed substeps per interval, cannot bridge it.
MAX_GAP_RATIO = 1000.0


def _table(table: DataTable | Mapping[str, Any] | None, plant: Plant, key: str) -> DataTable:
    if table is None:
        return DataTable()
    if isinstance(table, DataTable):
        return table
    return parse_data_table(table, plant, key)


def read_experiments(paths: Sequence[str | Path], plant: Plant,
                     table: DataTable | Mapping[str, Any] | None = None, *,
                     key: str = "data") -> tuple[Experiment, ...]:
    """Read logged experiments (one per file) in the plant's signal names and units.

    Parameters
    ----------
    paths : sequence of str or Path
        Data files: ``.csv`` (a header row of column names, comma-separated, an empty cell or
        NaN for a missing sample), ``.npz`` (one array per column name) or ``.mat`` (one
        variable per column; MATLAB v4 to v7).
    plant : Plant
        The plant the data were logged on (its input, output and state names, units, region,
        actuator ranges and declared sensor ranges).
    table : DataTable or mapping, optional
        The spec's ``[data]`` table (`tanksynth.spec.Spec.data`), or the raw table (validated
        here); None: every column named as its plant signal, time column ``t``.
    key : str, optional
        Where a raw ``table`` is in the spec, for its errors.

    Returns
    -------
    tuple of Experiment
        In the order of ``paths``; each named by its file's stem.

    Raises
    ------
    DataError
        No file, too many files, two files with the same stem, an unknown extension, a file
        that is not a regular file or too large, or any bad data in a file (see
        `read_experiment`). One line naming the file, column and row.
    """
    paths = list(paths)
    if not paths:
        raise DataError("no data files given; expected one or more .csv, .npz or .mat files")
    if len(paths) > MAX_EXPERIMENTS:
        raise DataError(f"{len(paths)} data files, more than the {MAX_EXPERIMENTS} read at once")
    data_table = _table(table, plant, key)
    seen: dict[str, str] = {}
    for p in paths:
        stem = Path(p).stem
        if stem in seen:
            raise DataError(f"experiment name {stem!r} (the file's stem) is also the name of "
                            f"{seen[stem]}; rename one file (experiment names must be unique)",
                            source=str(p))
        seen[stem] = str(p)
    ranges = output_ranges(plant)
    return tuple(read_experiment(p, plant, data_table, ranges=ranges) for p in paths)


def read_experiment(path: str | Path, plant: Plant, table: DataTable | None = None, *,
                    ranges: np.ndarray | None = None) -> Experiment:
    """Read one data file as an `Experiment` (see `read_experiments`).

    Parameters
    ----------
    path : str or Path
        A ``.csv``, ``.npz`` or ``.mat`` file.
    plant : Plant
        The plant.
    table : DataTable, optional
        The ``[data]`` mapping (default: names as in the plant, time column ``t``).
    ranges : ndarray, shape (q,), optional
        `output_ranges` of the plant (computed when not given).

    Returns
    -------
    Experiment

    Raises
    ------
    DataError
        Columns of different lengths, time missing, not finite or not strictly increasing,
        an input column missing ("did you mean") or with a missing sample, no output column,
        a used column all NaN, a cell that is not a number or not finite, a unit that cannot
        be right (values far beyond the plant's range: the unit the plant expects is named),
        fewer than 2 samples.
    """
    source = str(path)
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise DataError(f"unknown data file type {suffix or '(no extension)'!r}; expected "
                        + ", ".join(FORMATS), source=source)
    table = table or DataTable()
    cols = FORMATS[suffix](read_data_bytes(path), source)
    return _assemble(cols, plant, table, output_ranges(plant) if ranges is None else ranges)


def _missing(cols: ColumnFile, column: str, what: str, hint: str = "", *, time: bool = False
             ) -> DataError:
    listed = ", ".join(repr(c) for c in cols.names[:12]) + (", ..." if len(cols.names) > 12 else "")
    close = did_you_mean(column, cols.names)
    if not close and time:  # "t" is too short for a close match: a column that says time
        named = [c for c in cols.names if "time" in c.lower()]
        close = f"; did you mean {named[0]!r}?" if named else ""
    return DataError(f"missing column {column!r} ({what}){close}{hint}; the file has {listed}",
                     source=cols.source)


def _finite_or_missing(cols: ColumnFile, column: str, values: np.ndarray) -> None:
    bad = np.flatnonzero(np.isinf(values))
    if bad.size:
        raise DataError(f"column {column!r}, {cols.where(int(bad[0]))}: {values[bad[0]]} is not a "
                        "finite number (an empty cell or NaN marks a missing sample)",
                        source=cols.source)


def _same_length(cols: ColumnFile, used: dict[str, np.ndarray]) -> int:
    lengths = {c: v.shape[0] for c, v in used.items()}
    first = next(iter(lengths))
    for c, n in lengths.items():
        if n != lengths[first]:
            raise DataError(f"column {c!r} has {n} rows, column {first!r} has {lengths[first]}: "
                            "every column needs one value per sample", source=cols.source)
    return lengths[first]


def _unit_check(cols: ColumnFile, column: str, values: np.ndarray, bound: float, factor: float,
                what: str, unit: str) -> None:
    """Refuse a column whose magnitude exceeds ``factor * bound`` (another unit)."""
    if not np.isfinite(bound) or bound <= 0:
        return
    mag = np.abs(values)
    if not np.any(mag > factor * bound):
        return
    row = int(np.nanargmax(mag))
    raise DataError(f"column {column!r} ({what}): |value| {mag[row]:.4g} at {cols.where(row)} is more "
                    f"than {factor:g}x the plant's range (|{what.split()[-1]}| <= {bound:.4g} {unit}): "
                    f"the plant expects {unit}; convert the column or set a factor in [data] scale",
                    source=cols.source)


def _assemble(cols: ColumnFile, plant: Plant, table: DataTable, ranges: np.ndarray) -> Experiment:
    source = cols.source
    names = set(cols.names)
    ts_hint = "; or set [data] ts (a fixed period) for a file without a time column"
    used: dict[str, np.ndarray] = {}
    if table.time is not None:
        if table.time not in names:
            raise _missing(cols, table.time, "time, s", ts_hint, time=True)
        used[table.time] = cols.column(table.time)
    for s in plant.inputs:
        column = table.column(s.name)
        if column not in names:
            raise _missing(cols, column, f"plant input {s.name}, {s.unit}; every input is required")
        used[column] = cols.column(column)
    out_index = []
    for j, s in enumerate(plant.outputs):
        column = table.column(s.name)
        if column in names:
            out_index.append(j)
            used[column] = cols.column(column)
        elif s.name in table.columns:  # mapped explicitly: required
            raise _missing(cols, column, f"plant output {s.name}, {s.unit}, [data] columns.{s.name}")
    if not out_index:
        wanted = [table.column(s.name) for s in plant.outputs]
        hints = next((h for h in (did_you_mean(w, cols.names) for w in wanted) if h), "")
        raise DataError("no output column: none of " + ", ".join(repr(w) for w in wanted)
                        + f" is in the file{hints}; at least one plant output must be logged "
                        "(or map it in [data] columns)", source=source)
    state_names = [s.name for s in plant.states]
    for nm, column in table.states.items():
        if column not in names:
            raise _missing(cols, column, f"reference state {nm}, [data] states.{nm}")
        used[column] = cols.column(column)

    count = _same_length(cols, used)
    if count < 2:
        raise DataError(f"{count} sample(s); an experiment needs at least 2", source=source)
    for column, values in used.items():
        _finite_or_missing(cols, column, values)

    if table.time is not None:
        t = used[table.time]
        nan = np.flatnonzero(np.isnan(t))
        if nan.size:
            raise DataError(f"time column {table.time!r}, {cols.where(int(nan[0]))}: missing (the "
                            "time must be given on every row)", source=source)
        step = np.diff(t)
        bad = np.flatnonzero(~(step > 0))
        if bad.size:
            k = int(bad[0]) + 1
            raise DataError(f"time column {table.time!r} is not strictly increasing at "
                            f"{cols.where(k)} (t = {t[k]:.6g} s after {t[k - 1]:.6g} s)", source=source)
        _check_steps(cols, table.time, t, step)
    elif table.ts is not None:
        t = table.ts * np.arange(count, dtype=float)
    else:
        raise DataError("the [data] table gives neither a time column nor a period ts", source=source)

    u = np.empty((count, plant.m))
    limits_in = np.asarray(plant.input_limits, dtype=float).reshape(plant.m, 2)
    for i, s in enumerate(plant.inputs):
        column = table.column(s.name)
        raw = used[column]
        nan = np.flatnonzero(np.isnan(raw))
        if nan.size:
            raise DataError(f"column {column!r} (input {s.name}), {cols.where(int(nan[0]))}: missing "
                            "sample; an input must be logged on every row (the model holds it "
                            "between samples)", source=source)
        u[:, i] = raw * table.factor(s.name)
        finite = limits_in[i][np.isfinite(limits_in[i])]
        _unit_check(cols, column, u[:, i], float(np.max(np.abs(finite))) if finite.size else np.inf,
                    INPUT_UNIT_FACTOR, f"input {s.name}", s.unit)

    y = np.empty((count, len(out_index)))
    limits: list[tuple[float, float]] = []
    for c, j in enumerate(out_index):
        s = plant.outputs[j]
        column = table.column(s.name)
        raw = used[column]
        if np.all(np.isnan(raw)):
            raise DataError(f"column {column!r} (output {s.name}) is empty: every sample is "
                            "missing (NaN); remove the column or log the output", source=source)
        y[:, c] = raw * table.factor(s.name)
        _unit_check(cols, column, y[:, c], float(ranges[j]), OUTPUT_UNIT_FACTOR,
                    f"output {s.name}", s.unit)
        lim = table.limits.get(s.name, s.limits)
        limits.append((-np.inf, np.inf) if lim is None else (float(lim[0]), float(lim[1])))
    y, low, high = censor(y, limits)

    x_ref = None
    if table.states:
        x_ref = np.full((count, plant.n), np.nan)
        for nm, column in table.states.items():
            i = state_names.index(nm)
            raw = used[column]
            if np.all(np.isnan(raw)):
                raise DataError(f"column {column!r} (reference state {nm}) is empty: every sample "
                                "is missing (NaN)", source=source)
            x_ref[:, i] = raw * table.factor(nm)
            lo, hi = plant.region.bounds[i]
            _unit_check(cols, column, x_ref[:, i], max(abs(lo), abs(hi)), OUTPUT_UNIT_FACTOR,
                        f"state {nm}", plant.states[i].unit)

    return Experiment(name=Path(source).stem, source=source, t=np.asarray(t, dtype=float), u=u, y=y,
                      input_names=tuple(s.name for s in plant.inputs),
                      output_names=tuple(plant.outputs[j].name for j in out_index),
                      censored_low=low, censored_high=high, limits=tuple(limits), x_ref=x_ref)


def _check_steps(cols: ColumnFile, column: str, t: np.ndarray, step: np.ndarray) -> None:
    """Refuse a time step not in seconds (below `MIN_TIME_STEP` or above `MAX_TIME_STEP`) or
    a gap (more than `MAX_GAP_RATIO` times the median step)."""
    median = float(np.median(step))
    checks = ((step < MIN_TIME_STEP, f"shorter than {MIN_TIME_STEP:g} s: the time column must be in "
               "seconds"),
              (step > MAX_TIME_STEP, f"longer than {MAX_TIME_STEP:g} s: the time column must be in "
               "seconds"),
              (step > MAX_GAP_RATIO * median, f"more than {MAX_GAP_RATIO:g}x the median step "
               f"{median:.6g} s: a gap in the log; split the file at the gap"))
    for bad, why in checks:
        rows = np.flatnonzero(bad)
        if rows.size:
            k = int(rows[0]) + 1
            raise DataError(f"time column {column!r}, {cols.where(k)}: step {step[k - 1]:.6g} s "
                            f"(t = {t[k]:.6g} s after {t[k - 1]:.6g} s) is {why}", source=cols.source)


def check_fit_data(experiments: Sequence[Experiment], parameters: int, states: int) -> None:
    """Refuse data a fit cannot learn from, before it runs.

    Every experiment needs at least one observed output value (present and not censored at a
    sensor limit), and all of them together at least as many observed values as unknowns: the
    ``parameters`` free parameters plus ``states`` initial states per experiment.

    Parameters
    ----------
    experiments : sequence of Experiment
        The estimation experiments.
    parameters : int
        Number of free parameters.
    states : int
        Number of initial states fitted per experiment (the plant's state count ``n``).

    Raises
    ------
    DataError
        An experiment whose every output sample is missing or censored (naming its file), or
        fewer observed values than unknowns (both counted).
    """
    total = 0
    for e in experiments:
        observed = int(np.count_nonzero(e.observed))
        if observed == 0:
            censored = int(np.count_nonzero(e.censored_low | e.censored_high))
            raise DataError(f"no output sample to fit: every one is missing or at a sensor limit "
                            f"({censored} censored of {e.y.size}); a censored sample only says the "
                            "output is beyond the limit", source=e.source)
        total += observed
    unknowns = parameters + len(experiments) * states
    if total <= unknowns:
        files = ", ".join(e.source for e in experiments[:3]) + (", ..." if len(experiments) > 3 else "")
        raise DataError(f"{total} observed output value(s) for {unknowns} unknowns ({parameters} "
                        f"free parameter(s) + {len(experiments)} x {states} initial states): the fit "
                        f"needs more observed values than unknowns; log longer experiments ({files})")


def censor(y: np.ndarray, limits: Sequence[tuple[float, float]]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flag and clip the samples at or beyond each output's sensor limits.

    A sample ``y <= min + tol`` is censored low and set to ``min``; ``y >= max - tol`` censored
    high and set to ``max``, with ``tol = LIMIT_RTOL * (max - min)`` when both limits are finite,
    else ``LIMIT_RTOL * max(1, |limit|)``. Missing samples (NaN) are never censored.

    Parameters
    ----------
    y : ndarray, shape (N, p)
        Outputs (output units), NaN where missing.
    limits : sequence of (float, float)
        Sensor range per column (``-inf``/``inf`` where none).

    Returns
    -------
    y : ndarray, shape (N, p)
        A copy, censored samples clipped to their limit.
    low, high : ndarray of bool, shape (N, p)
        The censored samples.
    """
    y = np.array(y, dtype=float)
    low = np.zeros(y.shape, dtype=bool)
    high = np.zeros(y.shape, dtype=bool)
    for c, (lo, hi) in enumerate(limits):
        span = hi - lo
        for value, mask, sign in ((lo, low, 1.0), (hi, high, -1.0)):
            if not np.isfinite(value):
                continue
            tol = LIMIT_RTOL * (span if np.isfinite(span) else max(1.0, abs(value)))
            with np.errstate(invalid="ignore"):
                hit = (y[:, c] <= value + tol) if sign > 0 else (y[:, c] >= value - tol)
            mask[:, c] = hit
            y[hit, c] = value
    return y, low, high


def output_ranges(plant: Plant) -> np.ndarray:
    """Largest magnitude of each output over the plant's operating box (output units).

    Evaluated on the box's grid of corners, edge midpoints and centre (``3^n`` points up to
    ``n = 6``, else the corners and centre of 64 seeded random points); ``inf`` where the box is
    unbounded or an output is not finite there (no unit check is made then).

    Parameters
    ----------
    plant : Plant
        The plant.

    Returns
    -------
    ndarray, shape (q,)
    """
    bounds = np.asarray(plant.region.bounds, dtype=float).reshape(plant.n, 2)
    if not np.all(np.isfinite(bounds)):
        return np.full(plant.q, np.inf)
    lo, hi = bounds[:, 0], bounds[:, 1]
    if plant.n <= 6:
        grid = np.array(list(itertools.product((0.0, 0.5, 1.0), repeat=plant.n)))
    else:
        grid = np.random.default_rng(0).uniform(size=(64, plant.n))
        grid = np.vstack([grid, np.full((1, plant.n), 0.5), np.zeros((1, plant.n)),
                          np.ones((1, plant.n))])
    points = lo + grid * (hi - lo)
    with np.errstate(all="ignore"):
        values = np.asarray(plant.compiled.output(points), dtype=float).reshape(len(points), plant.q)
    out = np.max(np.abs(values), axis=0)
    out[~np.all(np.isfinite(values), axis=0)] = np.inf
    return out
