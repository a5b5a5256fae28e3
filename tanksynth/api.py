"""Design from Python objects, python-control style: ``tanksynth.design(plant, method, ...)``.

::

    import control, tanksynth
    from tanksynth.plants import three_tank

    k = tanksynth.design(three_tank(outputs="h1h2"), "lmi_placement", target="state_feedback",
                         region=[{"type": "disk", "center": 0.9, "radius": 0.08}],
                         x0=[0.40, 0.20, 0.30], ts=1.0)
    k.gains["K"]                      # the gain, as `tanksynth.load` gives it
    k.verify().passed                 # simulated on the nonlinear plant
    k2 = tanksynth.design(control.ss(A, B, C, 0), "lqr")     # a linear model

No second validator: the keyword arguments are written as the spec document a TOML user
would write (`spec_document`, `spec_text`) and validated by the spec parser the CLI uses
(`tanksynth.methods.parse_spec_text`), so a bad value is the same `SpecError` naming the same
key (``design[0].region``). The design then runs and is written exactly as ``tanksynth
design`` writes it (``plant.json``, ``spec.toml``, ``<name>.json``, ``<name>.npz``) and is
read back with `tanksynth.load`: the result is a `tanksynth.loading.Design`.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import tempfile
from pathlib import Path
from typing import Any, Mapping, Sequence, cast

import numpy as np

from tanksynth.loading import Design, load

__all__ = ["LINEAR_MODEL_METHODS", "design", "spec_document", "spec_text", "plant_table"]

#: The methods that design on the linearisation at the operating point: the ones a linear model
#: (a ``control.StateSpace``) can be given to (with their aliases, `tanksynth.methods.ALIASES`).
#: The others use the nonlinear model itself (its Takagi-Sugeno form, its relative degree, an
#: EKF/UKF on it, a parameter box...) and need a plant family or a custom plant.
LINEAR_MODEL_METHODS = ("linearize", "pole_placement", "lmi_placement", "canonical_observer",
                        "kalman", "luenberger", "integral_tracking", "h2_state_feedback",
                        "h2_observer", "hinf_state_feedback", "hinf_observer", "multiobjective")

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+\Z")


def _is_statespace(plant: Any) -> bool:
    return all(hasattr(plant, name) for name in ("A", "B", "C", "D", "dt"))


def plant_table(plant: Any, *, state_bound: float = 1.0, input_bound: float = 1.0) -> dict[str, Any]:
    """The ``[plant]`` table of a plant given in Python.

    Parameters
    ----------
    plant : str, mapping, Plant or control.StateSpace
        A built-in family's name (``"three_tank"``); a ``[plant]`` table as a mapping
        (``{"model": "tank_network", "N": ...}``, or a custom plant); a `tanksynth.plants.Plant`
        built by a family (``three_tank(outputs="h1")``, with parameters changed by
        ``with_parameters`` and a region by ``with_region``); or a continuous-time
        ``control.StateSpace`` (`tanksynth.plants.linear.linear_plant_table`: states ``x1..``,
        inputs ``u1..``, outputs ``y1..``, deviations from the origin).
    state_bound, input_bound : float
        A StateSpace's operating region ``|x_i| <= state_bound`` and actuator range
        ``|u_j| <= input_bound`` (its units).

    Returns
    -------
    dict
        The table (validated later, with the rest of the spec).

    Raises
    ------
    TypeError
        Another type, or a `Plant` that is not a built-in family's (write its ``[plant]`` table).
    """
    from tanksynth.plants import BUILTIN_PLANTS, Plant
    from tanksynth.plants.linear import linear_plant_table, statespace_matrices

    if isinstance(plant, str):
        return {"model": plant}
    if isinstance(plant, Mapping):
        return dict(plant)
    if _is_statespace(plant):
        return linear_plant_table(*statespace_matrices(plant), state_bound=state_bound,
                                  input_bound=input_bound)
    if isinstance(plant, Plant):
        if plant.name not in BUILTIN_PLANTS:
            raise TypeError(f"plant {plant.name!r} is not a built-in family's: give its [plant] "
                            "table as a mapping (model = \"custom\", its equations)")
        table: dict[str, Any] = {"model": plant.name, **dict(plant.options)}
        built = BUILTIN_PLANTS[plant.name](**dict(plant.options))
        defaults = {p.name: p.value for p in built.parameters}
        changed = {p.name: p.value for p in plant.parameters if defaults.get(p.name) != p.value}
        if changed:
            table["parameters"] = changed
        if tuple(plant.region.bounds) != tuple(built.region.bounds):
            table["region"] = {s.name: list(b) for s, b in zip(plant.states, plant.region.bounds)}
        return table
    raise TypeError(f"expected a plant (a family name, a [plant] table, a tanksynth Plant or a "
                    f"control.StateSpace), got {type(plant).__name__}")


def _toml_form(value: Any) -> Any:
    """A Python value in the form the spec's TOML has (arrays as lists, complex as [re, im])."""
    if isinstance(value, np.ndarray):
        return _toml_form(value.tolist())
    if isinstance(value, np.generic):
        return _toml_form(value.item())
    if isinstance(value, complex):
        return [value.real, value.imag]
    if isinstance(value, Mapping):
        return {str(k): _toml_form(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_toml_form(v) for v in value]
    return value


def spec_document(plant: Any, method: str, *, x0: Any = None, u0: Any = None, ts: float | None = None,
                  y0: Any = None, trim: str | None = None, x_hat0: Any = None, name: str | None = None, title: str = "", state_bound: float = 1.0,
                  input_bound: float = 1.0, **options: Any) -> dict[str, Any]:
    """The spec document (the parsed TOML) of one design given as Python objects.

    Parameters
    ----------
    plant : str, mapping, Plant or control.StateSpace
        See `plant_table`.
    method : str
        A method of `tanksynth.methods.TABLE` or an alias (``"lqr"``).
    x0 : array_like or mapping, optional
        Operating levels (state units), in state order or by state name; default the origin
        for a StateSpace (required otherwise).
    u0 : array_like or mapping, optional
        Operating inputs (input units); checked against the equilibrium.
    y0 : array_like or mapping, optional
        Operating outputs (output units), with ``trim="inputs"`` only.
    trim : {"states", "inputs"}, optional
        ``[operating_point] trim``: ``"states"`` solves the levels from ``u0`` (``x0``, if
        given, is the solver's start); ``"inputs"`` solves the inputs and levels from ``y0``.
    ts : float, optional
        Sampling period (s); None for a continuous-time spec.
    x_hat0 : array_like, optional
        An estimator's initial estimate (state units): its option ``x0`` in a ``[[design]]``
        table (``x0`` here is the operating point; the artefact stores it as ``x_hat0``).
    name : str, optional
        The design's name (default the method's).
    title : str
        The spec's title.
    state_bound, input_bound : float
        See `plant_table` (StateSpace only).
    **options
        The method's options, each in the units ``tanksynth methods NAME`` lists, as in a
        ``[[design]]`` table (``region=[{"type": "disk", ...}]``,
        ``poles=[...]``, ``target="observer"``; numpy arrays and complex numbers allowed). With
        a StateSpace, the disturbance input ``Bw`` of the H2 / H-infinity methods defaults to
        its ``B`` (python-control's ``lqe(sys, QN, RN)`` takes ``G = B``).

    Returns
    -------
    dict
        ``{"title", "plant", "operating_point", "sampling", "design": [...]}``.

    Raises
    ------
    TypeError
        A StateSpace given to a method that needs a nonlinear plant.
    """
    from tanksynth.methods import ALIASES, METHODS

    real = ALIASES[method].method if method in ALIASES else method
    if _is_statespace(plant) and real not in LINEAR_MODEL_METHODS:
        raise TypeError(f"method {method!r} needs a nonlinear plant model (a plant family or a custom "
                        "plant); a control.StateSpace runs only the methods that design on a linear "
                        f"model: {', '.join(LINEAR_MODEL_METHODS)} (and the aliases "
                        f"{', '.join(ALIASES)})")
    table = plant_table(plant, state_bound=state_bound, input_bound=input_bound)
    if _is_statespace(plant):
        if x0 is None:
            x0 = np.zeros(np.shape(plant.A)[0])
        if "Bw" not in options and "Bw" in METHODS[real].options.option_names():
            options = {**options, "Bw": np.asarray(plant.B)}  # python-control's G = B
    op: dict[str, Any] = {}
    if x0 is not None:
        op["x"] = _toml_form(x0)
    if u0 is not None:
        op["u"] = _toml_form(u0)
    if y0 is not None:
        op["y"] = _toml_form(y0)
    if trim is not None:
        op["trim"] = trim
    doc: dict[str, Any] = {"plant": table, "operating_point": op}
    if title:
        doc["title"] = title
    if ts is not None:
        doc["sampling"] = {"ts": _toml_form(ts)}
    if x_hat0 is not None:   # the [[design]] option x0 (x0 here is the operating point)
        options = {**options, "x0": x_hat0}
    doc["design"] = [{"name": method if name is None else name, "method": method,
                      **_toml_form(options)}]
    return doc


def _key(key: str) -> str:
    return key if _BARE_KEY.match(key) else json.dumps(key)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string (JSON's escapes are TOML's)
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{_key(str(k))} = {_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, Sequence):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} {value!r} in a spec")


def spec_text(document: Mapping[str, Any]) -> str:
    """The TOML text of a spec document (`spec_document`).

    Top-level values first, then each table (its sub-tables inline), then each ``[[design]]``.

    Parameters
    ----------
    document : mapping
        The spec as parsed TOML.

    Returns
    -------
    str
    """
    lines = [f"{_key(k)} = {_value(v)}" for k, v in document.items()
             if not isinstance(v, Mapping) and k != "design"]
    for key, table in document.items():
        if isinstance(table, Mapping):
            lines += ["", f"[{_key(key)}]", *(f"{_key(str(k))} = {_value(v)}" for k, v in table.items())]
    for entry in document.get("design", ()):
        lines += ["", "[[design]]", *(f"{_key(str(k))} = {_value(v)}" for k, v in entry.items())]
    return "\n".join(lines) + "\n"


def _same_plant(given: Any, built: Any) -> None:
    """Refuse a `Plant` its ``[plant]`` table does not rebuild (changed by other means than
    ``with_parameters`` / ``with_region``)."""
    from tanksynth.plants import Plant

    if isinstance(given, Plant) and (given.f != built.f or given.h != built.h
                                     or tuple(given.region.bounds) != tuple(built.region.bounds)
                                     or given.input_bounds != built.input_bounds):
        raise TypeError(f"plant {given.name!r} differs from what its family builds with its options, "
                        "parameters and region: give its [plant] table as a mapping")


def design(plant: Any, method: str, *, x0: Any = None, u0: Any = None, ts: float | None = None,
           y0: Any = None, trim: str | None = None, x_hat0: Any = None, name: str | None = None, directory: str | Path | None = None, title: str = "",
           state_bound: float = 1.0, input_bound: float = 1.0, **options: Any) -> Design:
    """Design one gain from Python objects, as ``tanksynth design`` designs a spec's entry.

    Parameters
    ----------
    plant : str, mapping, Plant or control.StateSpace
        See `plant_table`; a StateSpace only for `LINEAR_MODEL_METHODS`.
    method : str
        A design method (``tanksynth methods``) or an alias (``"lqr"``, ``"dlqr"``, ``"lqe"``).
    x0 : array_like or mapping, optional
        Operating levels (state units); see `spec_document`.
    u0 : array_like or mapping, optional
        Operating inputs (input units); see `spec_document`.
    y0 : array_like or mapping, optional
        Operating outputs (output units), with ``trim="inputs"``; see `spec_document`.
    trim : {"states", "inputs"}, optional
        Solve the operating point (``[operating_point] trim``); see `spec_document`.
    ts : float, optional
        Sampling period (s); None for a continuous-time spec.
    x_hat0 : array_like, optional
        An estimator's initial estimate (state units): the ``[[design]]`` option ``x0``; see
        `spec_document`.
    name, title : str, optional
        The design's name (default the method's) and the spec's title.
    state_bound, input_bound : float
        A StateSpace's region and actuator range (its state and input units; see `plant_table`).
    directory : str or Path, optional
        Where the files go (created; it must not exist or be empty); default a new temporary
        directory (kept: the `Design` reads its files).
    **options
        The method's options, each in the units ``tanksynth methods NAME`` lists, as in a
        ``[[design]]`` table.

    Returns
    -------
    tanksynth.loading.Design
        What ``tanksynth.load(<directory>/<name>.json)`` returns: gains, diagnostics,
        ``verify()``, ``to_statespace()``.

    Raises
    ------
    SpecError
        A bad option or argument, named by its spec key (the CLI's message).
    InfeasibleDesign
        The design is refused (nothing is written).
    TypeError
        A plant of another type; a StateSpace for a method that needs a nonlinear plant.
    FileExistsError
        ``directory`` exists and is not empty.
    """
    from tanksynth.artefacts.io import file_sha256, write_artefact, write_plant_record
    from tanksynth.methods import METHODS, parse_spec_text

    document = spec_document(plant, method, x0=x0, u0=u0, ts=ts, y0=y0, trim=trim, x_hat0=x_hat0, name=name,
                             title=title,
                             state_bound=state_bound, input_bound=input_bound, **options)
    spec = parse_spec_text(spec_text(document), source="<tanksynth.design>")
    _same_plant(plant, spec.plant)
    entry = spec.designs[0]
    target = None if directory is None else Path(directory)
    if target is not None and target.exists() and (not target.is_dir() or any(target.iterdir())):
        raise FileExistsError(f"{target}: exists and is not an empty directory")
    parent = Path(tempfile.gettempdir()) if target is None else target.absolute().parent
    parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=".tanksynth-design-" if target else "tanksynth-", dir=parent))
    try:
        result = METHODS[entry.method].design(spec, entry)
        plant_sha = file_sha256(write_plant_record(spec, work))
        write_artefact(result, work, spec.sha256, plant_record_sha256=plant_sha)
        if target is not None:
            if target.exists():
                target.rmdir()  # empty (checked above)
            work.rename(target)
            work = target
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    return cast(Design, load(work / f"{entry.name}.json"))  # a file loads as one Design
