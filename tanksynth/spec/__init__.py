"""TOML spec -> validated `Spec` (no eval anywhere).

A spec has one ``[plant]`` table (a built-in ``model`` with parameter
overrides and family options, or ``model = "custom"`` with equations), an
``[operating_point]``, a ``[sampling]`` table and one ``[[design]]`` table
per gain to synthesise. Every error is a `SpecError` naming the file, the
key and what was expected.
"""

from __future__ import annotations

import hashlib
import inspect
import re
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Protocol

import numpy as np

from tanksynth.errors import SpecError, TanksynthError
from tanksynth.plants import BUILTIN_PLANTS, Plant, custom_plant
from tanksynth.plants.trim import Trim, trim, trim_outputs
from tanksynth.spec.data_table import DataTable, parse_data_table
from tanksynth.spec.free_parameters import FreeParameter, custom_free_parameters, split_parameters
from tanksynth.spec.memory import memory_budget
from tanksynth.spec.options import (parse_box, parse_number, parse_vector,
                                    unknown_word_hint)

if TYPE_CHECKING:  # the Options classes load with the method table, not with the spec
    from tanksynth.spec.method_options.base import MethodOptions

__all__ = ["Spec", "DesignSpec", "OptionsValidator", "FreeParameter", "DataTable", "load_spec",
           "parse_spec", "parse_spec_text", "MIN_TS", "MAX_TS", "MAX_MODEL_MAGNITUDE"]

#: Sampling periods accepted (s): below MIN_TS a discrete model equals the identity in
#: floating point; above MAX_TS no tank model is meaningful.
MIN_TS, MAX_TS = 1e-6, 1e6
#: Largest magnitude of f, h and their Jacobians at the operating point (SI units); beyond it
#: the parameters are out of any physical range (e.g. an area of 1e-300 m^2) and the rank tests
#: would overflow.
MAX_MODEL_MAGNITUDE = 1e100

_TOP_KEYS = {"title", "description", "plant", "operating_point", "sampling", "design", "data"}
_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}\Z")
#: Design names whose files would overwrite the tool's own files in a result directory.
RESERVED_NAMES = {"plant": "plant.json (the plant record)", "checks": "checks.json (the rank verdicts)",
                  "campaign": "campaign.json/.csv (the campaign table)",
                  "report": "report.tex/.pdf/.log (the design report)",
                  "refused": "refused.json (the designs refused as infeasible)",
                  "replay": "replay.json and replay/ (the replay on measured data)"}
#: Name endings that collide with files written beside another design's artefact.
RESERVED_SUFFIXES = {".traces": "<name>.traces.npz (a verdict trace)",
                     "_law": "<name>_law.c/.h/.casadi (an exported control law)"}


class OptionsValidator(Protocol):
    """What a ``[[design]]`` table's options are validated by: a row of the method table
    (`tanksynth.methods.Method`) or a design adapter (`tanksynth.design.result.DesignMethod`)."""

    def validate(self, options: Mapping[str, Any], key: str, plant: Plant,
                 ts: float | None) -> MethodOptions:
        """The method's validated Options of ``options`` (see `tanksynth.methods.Method.validate`).

        Parameters
        ----------
        options : mapping
            The raw options (without ``name`` and ``method``).
        key : str
            Where the table is in the spec (``design[i]``).
        plant : Plant
            The spec's plant.
        ts : float or None
            Sampling period (s).
        """
        ...


@dataclass(frozen=True)
class DesignSpec:
    """One ``[[design]]`` entry: a name, a method and its options.

    Attributes
    ----------
    name, method : str
    options : mapping
        The options as written in the spec.
    key : str
        Where the entry is in the spec (``design[i]``), for error messages.
    config : MethodOptions or None
        The validated options with their defaults: the method's Options
        dataclass (`tanksynth.spec.method_options`), as its adapter's
        ``validate`` returned it; None when parsed without the methods.
    alias : str or None
        The name the spec wrote when it is an alias (`tanksynth.methods.ALIASES`, e.g.
        ``"lqr"``): then ``method`` is the method it runs and ``options`` hold the options
        the alias fixes; None otherwise (and when parsed without the methods).
    """

    name: str
    method: str
    options: Mapping[str, Any]
    key: str
    config: MethodOptions | None = None
    alias: str | None = None


@dataclass(frozen=True)
class Spec:
    """A validated spec.

    Attributes
    ----------
    plant : Plant
    x0 : ndarray, shape (n,)
        Operating levels (state units), inside the plant's region.
    given_u0 : ndarray or None
        Operating input as written in the spec (checked, not trusted).
    ts : float or None
        Sampling period in s.
    designs : tuple of DesignSpec
    title : str
    source : str or None
        File the spec was read from.
    sha256 : str
        Hash of the spec text (provenance of every artefact).
    raw : mapping
        The parsed TOML tables as written (values in the spec's units).
    text : str
        The spec text itself (copied beside the artefacts).
    trim : Trim or None
        The solution when ``[operating_point] trim`` asked for one (``x0`` is its
        levels; with ``trim = "inputs"``, ``given_u0`` its inputs), else None.
    free_parameters : tuple of FreeParameter
        The plant parameters marked ``fit = true`` (estimated from data), in spec order;
        empty when none. `plant` holds their starting values.
    data : DataTable or None
        The ``[data]`` table (how data files map onto the plant's signals), None when absent.
    """

    plant: Plant
    x0: np.ndarray
    given_u0: np.ndarray | None
    ts: float | None
    designs: tuple[DesignSpec, ...]
    title: str = ""
    source: str | None = None
    sha256: str = ""
    raw: Mapping[str, Any] = field(default_factory=dict, repr=False)
    text: str = field(default="", repr=False)
    trim: Trim | None = field(default=None, repr=False)
    free_parameters: tuple[FreeParameter, ...] = ()
    data: DataTable | None = None


def load_spec(path: str | Path, *, methods: Mapping[str, OptionsValidator] | None = None) -> Spec:
    """Read and validate a TOML spec file.

    Parameters
    ----------
    path : str or Path
    methods : mapping of method name to row, optional
        What the ``[[design]]`` options are validated against (the method table
        `tanksynth.methods.METHODS`, or its design adapters; `tanksynth.load_spec`
        passes the table): ``row.validate(options, key, plant, ts)`` returns the method's
        Options (stored as `DesignSpec.config`). Every design's options are
        validated here, before any design runs. Without it the method names
        and options are not checked: only the plant, operating point,
        sampling and design names are.

    Raises
    ------
    SpecError
        Unreadable file, invalid TOML or any invalid entry.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SpecError(f"cannot read spec: {exc.strerror}", source=str(path)) from None
    from tanksynth.spec.context import reading_spec_file

    with reading_spec_file(path):  # files the options name are relative to the spec file
        return parse_spec_text(data, source=str(path), methods=methods)


def parse_spec_text(data: bytes | str, source: str | None = None, *,
                    methods: Mapping[str, OptionsValidator] | None = None) -> Spec:
    """Validate spec text (TOML) and build the `Spec` (``methods`` as in `load_spec`).

    Parameters
    ----------
    data : bytes or str
        The spec text (UTF-8 bytes, or text).
    source : str, optional
        The file it came from, named in errors and kept as `Spec.source`.
    methods : mapping of method name to row, optional
        As in `load_spec`.

    Raises
    ------
    SpecError
        Invalid UTF-8, invalid TOML or any invalid entry.
    """
    raw = data.encode("utf-8") if isinstance(data, str) else data
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise SpecError("spec is not valid UTF-8 text", source=source) from None
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"invalid TOML: {exc}", source=source) from None
    except RecursionError:
        raise SpecError("invalid TOML: arrays or tables nested too deeply", source=source) from None
    spec = parse_spec(table, source=source, sha256=hashlib.sha256(raw).hexdigest(), methods=methods)
    return replace(spec, text=text)


def _table(table: Mapping[str, Any], name: str, required: bool = True) -> Mapping[str, Any]:
    value = table.get(name)
    if value is None:
        if required:
            raise SpecError(f"missing table [{name}]", key=name)
        return {}
    if not isinstance(value, Mapping):
        raise SpecError(f"expected a table [{name}], got {type(value).__name__}", key=name)
    return value


def _build_plant(table: Mapping[str, Any]) -> tuple[Plant, tuple[FreeParameter, ...]]:
    """The plant of a ``[plant]`` table and its free parameters (``fit = true``)."""
    model = table.get("model")
    if not isinstance(model, str):
        raise SpecError("expected a model name (string): one of "
                        + ", ".join([*BUILTIN_PLANTS, "custom"]), key="plant.model")
    if model == "custom":
        plant = custom_plant(table)
        return plant, custom_free_parameters(table.get("parameters", {}), plant)
    if model not in BUILTIN_PLANTS:
        raise SpecError(f"unknown plant model {model!r}"
                        + unknown_word_hint(model, [*BUILTIN_PLANTS, "custom"]), key="plant.model")
    builder = BUILTIN_PLANTS[model]
    signature = inspect.signature(builder)
    options = {}
    for key, value in table.items():
        if key in ("model", "parameters", "region"):
            continue
        if key not in signature.parameters:
            allowed = ["parameters", "region", *signature.parameters]
            raise SpecError(f"unknown key {key!r} for plant '{model}'"
                            + unknown_word_hint(key, allowed), key=f"plant.{key}")
        default = signature.parameters[key].default
        if isinstance(default, bool) or type(value) is not type(default):
            raise SpecError(f"expected a {type(default).__name__} (default {default!r}), "
                            f"got {type(value).__name__} {value!r}", key=f"plant.{key}")
        options[key] = value
    try:
        plant = builder(**options)
    except SpecError:
        raise
    except (TanksynthError, ValueError, TypeError) as exc:
        raise SpecError(f"cannot build plant '{model}': {exc}", key="plant") from None
    overrides, free = split_parameters(table.get("parameters", {}), plant)
    plant = plant.with_parameters(overrides)
    region = table.get("region")
    if region is not None:
        names = [s.name for s in plant.states]
        bounds = list(plant.region.bounds)
        for nm, b in parse_box(region, "plant.region", names).items():
            bounds[names.index(nm)] = b
        plant = plant.with_region(bounds)
    return plant, free


def parse_spec(table: Mapping[str, Any], source: str | None = None, sha256: str = "", *,
               methods: Mapping[str, OptionsValidator] | None = None) -> Spec:
    """Validate a parsed TOML table and build the `Spec`.

    Parameters
    ----------
    table : mapping
        The TOML document as a dict.
    source : str, optional
        File name for error messages.
    sha256 : str
        Hash of the spec text.
    methods : mapping of method name to row, optional
        See `load_spec`.

    Raises
    ------
    SpecError
        The first error of the plant, operating point or sampling tables; past them, every
        ``[[design]]`` table is validated and all the invalid ones are reported: one table's
        error as it is, several in one `SpecError` (``N invalid designs (design[0] 'a',
        design[2] 'c'): design[0] 'a': key ...: ...; design[2] 'c': ...``) whose ``errors``
        attribute holds each table's error; first of all, a bad ``TANKSYNTH_MEMORY_BUDGET_MB``
        (`tanksynth.spec.memory.memory_budget`: it names the variable, not the file).
    """
    memory_budget()  # the environment's budget, read once for every design (a bad one: refused)
    try:
        return _parse(table, source, sha256, methods)
    except SpecError as exc:
        if exc.source is None and source is not None:
            sourced = type(exc)(exc.detail, key=exc.key, source=source)
            sourced.errors = exc.errors  # several invalid [[design]] tables: each one's error
            raise sourced from None
        raise


def _parse(table: Mapping[str, Any], source: str | None, sha256: str,
           methods: Mapping[str, OptionsValidator] | None) -> Spec:
    if not isinstance(table, Mapping):
        raise SpecError("expected a TOML document (table)")
    unknown = [k for k in table if k not in _TOP_KEYS]
    if unknown:
        raise SpecError(f"unknown top-level key {unknown[0]!r}"
                        + unknown_word_hint(unknown[0], sorted(_TOP_KEYS)), key=str(unknown[0]))
    title = table.get("title", "")
    if not isinstance(title, str):
        raise SpecError("expected a string", key="title")
    plant, free = _build_plant(_table(table, "plant"))

    x0, given_u0, trimmed = _operating_point(plant, _table(table, "operating_point"))

    sampling = _table(table, "sampling", required=False)
    extra = [k for k in sampling if k != "ts"]
    if extra:
        raise SpecError(f"unknown key(s) {extra}; expected ts (sampling period, s)",
                        key=f"sampling.{extra[0]}")
    ts = (parse_number(sampling["ts"], "sampling.ts", at_least=MIN_TS, at_most=MAX_TS)
          if "ts" in sampling else None)

    data = parse_data_table(table["data"], plant) if "data" in table else None

    raw_designs = table.get("design", [])
    if not isinstance(raw_designs, list):
        raise SpecError("expected an array of tables [[design]]", key="design")
    designs: list[DesignSpec] = []
    seen: dict[str, str] = {}
    errors: list[tuple[int, SpecError]] = []
    from tanksynth.spec.context import free_parameter_scope

    with free_parameter_scope(f.name for f in free):  # the fit's options refuse a plant without
        for i, entry in enumerate(raw_designs):
            try:
                designs.append(_design(i, entry, seen, plant, ts, methods))
            except SpecError as exc:  # every design table is checked: all bad ones are reported
                errors.append((i, exc))
    if errors:
        raise _designs_error(raw_designs, errors)
    return Spec(plant, x0, given_u0, ts, tuple(designs), title, source, sha256, table, trim=trimmed,
                free_parameters=free, data=data)


#: Bad ``[[design]]`` tables named one by one (index and name) in the summary of
#: `_designs_error`; beyond, the indices are given as ranges.
MAX_LISTED_DESIGNS = 8
#: Characters of each table's own error in the summary of several (a long list of
#: valid values in one does not hide the others).
MAX_DESIGN_DETAIL = 160


def _designs_error(raw_designs: list, errors: list[tuple[int, SpecError]]) -> SpecError:
    """One error for the invalid ``[[design]]`` tables (``(index, error)`` pairs): the error
    itself when there is one, else a `SpecError` naming every bad table first (so a message cut
    at the CLI's line limit still names them all; as index ranges when there are more than
    `MAX_LISTED_DESIGNS`), then each distinct error with its key and the tables it concerns
    (each cut to `MAX_DESIGN_DETAIL` characters); its ``errors`` attribute holds the single
    errors, in table order."""
    if len(errors) == 1:
        return errors[0][1]

    def label(i: int) -> str:
        name = raw_designs[i].get("name") if isinstance(raw_designs[i], Mapping) else None
        return f"design[{i}]" + (f" {name!r}" if isinstance(name, str) and _NAME_RE.match(name) else "")

    def labels(indices: list[int]) -> str:
        if len(indices) <= MAX_LISTED_DESIGNS:
            return ", ".join(label(i) for i in indices)
        runs: list[list[int]] = []
        for i in indices:
            if runs and i == runs[-1][-1] + 1:
                runs[-1].append(i)
            else:
                runs.append([i])
        return "design[" + ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs) + "]"

    groups: dict[tuple[str, str], list[int]] = {}
    keys: dict[int, str] = {}
    for i, exc in errors:
        keys[i] = "" if exc.key in (None, f"design[{i}]") else exc.key
        key = keys[i][len(f"design[{i}]"):] if keys[i].startswith(f"design[{i}].") else keys[i]
        detail = " ".join(exc.detail.split())
        if len(detail) > MAX_DESIGN_DETAIL:
            detail = detail[:MAX_DESIGN_DETAIL - 4] + " ..."
        groups.setdefault((key, detail), []).append(i)
    # one table: its full key (design[i].poles); several: the key inside each (design[*].poles)
    parts = [f"{labels(ix)}: " + (f"key '{keys[ix[0]] if len(ix) == 1 else 'design[*]' + key}': "
                                  if key else "") + detail
             for (key, detail), ix in groups.items()]
    out = SpecError(f"{len(errors)} invalid designs ({labels([i for i, _ in errors])}): "
                    + "; ".join(parts))
    out.errors = tuple(exc for _, exc in errors)
    return out


def _design(i: int, entry: Any, seen: dict[str, str], plant: Plant, ts: float | None,
            methods: Mapping[str, OptionsValidator] | None) -> DesignSpec:
    """Validate the ``[[design]]`` table number ``i`` (``seen``: the file-name forms of the
    names before it, updated here)."""
    key = f"design[{i}]"
    if not isinstance(entry, Mapping):
        raise SpecError("expected a table", key=key)
    name = entry.get("name")
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise SpecError(f"expected a name of letters, digits, '_', '-', '.' (max 64), got {name!r}",
                        key=f"{key}.name")
    reserved = RESERVED_NAMES.get(name.lower()) or next(
        (what for end, what in RESERVED_SUFFIXES.items() if name.lower().endswith(end)), None)
    if reserved:
        raise SpecError(f"design name {name!r} is reserved: its files would collide with "
                        f"{reserved}; choose another name", key=f"{key}.name")
    ident = re.sub(r"[^a-z0-9]+", "_", name.lower())  # file and C-identifier form
    if ident in seen:
        raise SpecError(f"duplicate design name {name!r}" + ("" if seen[ident] == name else
                        f" (same as {seen[ident]!r}: names differing only in case or in '-', '.', '_' share "
                        "file names on some file systems and C identifiers in exported laws)"),
                        key=f"{key}.name")
    seen[ident] = name
    method = entry.get("method")
    if not isinstance(method, str) or (methods is not None and method not in methods):
        raise SpecError(f"unknown method {method!r}" + unknown_word_hint(method, list(methods or ())),
                        key=f"{key}.method")
    options = {k: v for k, v in entry.items() if k not in ("name", "method")}
    if methods is None:
        return DesignSpec(name, method, options, key)
    validator = methods[method]
    config = validator.validate(options, key, plant, ts)
    real = getattr(validator, "name", method)  # an alias validates as the method it runs
    if real == method:
        return DesignSpec(name, method, options, key, config)
    fixed = getattr(validator, "fixed_options", lambda given, _key: given)(options, key)
    return DesignSpec(name, real, fixed, key, config, alias=method)


#: The ``[operating_point] trim`` values: what is solved for, and from what.
TRIM_MODES = {"states": "the levels x from the given inputs u (f(x, u) = 0)",
              "inputs": "the inputs u and levels x from the given outputs y (f(x, u) = 0, h(x) = y)"}


def _operating_point(plant: Plant, op: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray | None, Trim | None]:
    """The operating levels, the spec's input (None if not given) and the trim solution.

    Without ``trim``: ``x`` (required) and, optionally, ``u`` (checked later, not trusted).
    ``trim = "states"``: ``u`` required, the levels solved (``x``, if given, is the start).
    ``trim = "inputs"``: ``y`` required (every output), ``u`` and the levels solved.
    """
    allowed = ("x", "u", "y", "trim")
    extra = [k for k in op if k not in allowed]
    if extra:
        raise SpecError(f"unknown key(s) {extra}; expected x (levels), u (inputs), y (outputs, with "
                        'trim = "inputs") and trim' + unknown_word_hint(extra[0], allowed),
                        key=f"operating_point.{extra[0]}")
    states, inputs, outputs = ([s.name for s in group] for group in (plant.states, plant.inputs, plant.outputs))
    mode = op.get("trim")
    if mode is not None and (not isinstance(mode, str) or mode not in TRIM_MODES):
        raise SpecError(f"expected one of {', '.join(repr(k) for k in TRIM_MODES)} "
                        f"({'; '.join(f'{k!r}: {v}' for k, v in TRIM_MODES.items())}), got {mode!r}",
                        key="operating_point.trim")
    guess = (np.array(parse_vector(op["x"], "operating_point.x", names=states)) if "x" in op else None)
    u = np.array(parse_vector(op["u"], "operating_point.u", names=inputs)) if "u" in op else None
    if "y" in op and mode != "inputs":
        raise SpecError('outputs y set the operating point only with trim = "inputs" (inputs and levels '
                        "solved from them)", key="operating_point.y")
    if mode is None:
        if guess is None:
            raise SpecError('missing operating levels x (or give u and trim = "states" to solve for them)',
                            key="operating_point.x")
        return _checked(plant, guess), u, None
    if mode == "states":
        if u is None:
            raise SpecError('trim = "states" solves the levels from the inputs: give u', key="operating_point.u")
        found = trim(plant, u, x_guess=guess)
        given = f"u = {np.array2string(u, precision=6)}"
    else:
        if u is not None:
            raise SpecError('trim = "inputs" solves the inputs from y: remove u (or use trim = "states")',
                            key="operating_point.u")
        if "y" not in op:
            raise SpecError('trim = "inputs" solves the inputs and levels from the outputs: give y',
                            key="operating_point.y")
        y = np.array(parse_vector(op["y"], "operating_point.y", names=outputs))
        if plant.q < plant.m:
            raise SpecError(f"{plant.q} output(s) cannot determine {plant.m} inputs: give u and "
                            'trim = "states" instead', key="operating_point.trim")
        found = trim_outputs(plant, y, x_guess=guess)
        given = f"y = {np.array2string(y, precision=6)}"
    if not found.converged:
        where = ("; ".join(found.violations) if found.violations else
                 f"best max |f| = {np.max(np.abs(found.residual)):.3g} state units/s "
                 f"(tolerance {found.tolerance:.3g})")
        raise SpecError(f"no equilibrium inside the operating region for {given} (trim = {mode!r}, "
                        f"{found.starts} starts): {where}; best levels "
                        f"{np.array2string(found.x, precision=6)}", key="operating_point.trim")
    return _checked(plant, found.x), (found.u if mode == "inputs" else u), found


def _checked(plant: Plant, x0: np.ndarray) -> np.ndarray:
    """``x0`` once inside the region with a finite model there."""
    plant.check_point(x0, key="operating_point.x")
    _check_model_numbers(plant, x0)
    return x0


def _check_model_numbers(plant: Plant, x0: np.ndarray) -> None:
    """Refuse a model whose value or Jacobian at the operating point is not finite or is
    beyond `MAX_MODEL_MAGNITUDE` (parameters out of any physical range), naming the
    equation or output (custom plants) or the parameters (built-in families)."""
    lo_hi = np.asarray(plant.input_limits, dtype=float).reshape(plant.m, 2)
    finite = np.isfinite(lo_hi).all(axis=1)
    u = np.zeros(plant.m)
    u[finite] = lo_hi[finite].mean(axis=1)
    custom = plant.source == "spec"
    with np.errstate(all="ignore"):
        try:
            comp = plant.compiled
            rows = [(np.asarray(comp.f(x0, u), dtype=float).reshape(plant.n, -1), "equations",
                     [s.name for s in plant.states]),
                    (np.asarray(comp.jac_x(x0, u), dtype=float).reshape(plant.n, -1), "equations",
                     [s.name for s in plant.states]),
                    (np.asarray(comp.jac_u(x0, u), dtype=float).reshape(plant.n, -1), "equations",
                     [s.name for s in plant.states]),
                    (np.asarray(comp.h(x0), dtype=float).reshape(plant.q, -1), "outputs",
                     [s.name for s in plant.outputs]),
                    (np.asarray(comp.jac_h(x0), dtype=float).reshape(plant.q, -1), "outputs",
                     [s.name for s in plant.outputs])]
        except (RuntimeError, ValueError, OverflowError, TanksynthError) as exc:
            # TanksynthError: the compiler refuses e.g. ComplexInfinity (a parameter of 0 in a
            # denominator simplifies the equation to zoo)
            hint = ("; a division by zero: check the parameter values"
                    if re.search(r"zoo|ComplexInfinity|division", str(exc)) else "")
            raise SpecError(f"the model cannot be evaluated at the operating point: "
                            f"{' '.join(str(exc).split())[:160]}{hint}", key="plant") from None
    for values, group, names in rows:
        for i, row in enumerate(values):
            bad = not np.all(np.isfinite(row))
            big = not bad and row.size and np.max(np.abs(row)) > MAX_MODEL_MAGNITUDE
            if bad or big:
                what = "is not finite" if bad else f"exceeds {MAX_MODEL_MAGNITUDE:.0e} in magnitude"
                key = f"plant.{group}.{names[i]}" if custom else "plant.parameters"
                raise SpecError(f"{'equation' if group == 'equations' else 'output'} {names[i]!r} "
                                f"or its derivative {what} at the operating point "
                                f"{np.round(x0, 6).tolist()} (inputs {np.round(u, 6).tolist()}): check "
                                "the parameter values and units", key=key)
