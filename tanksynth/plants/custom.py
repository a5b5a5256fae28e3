"""A plant written in the spec as equations (``model = "custom"``).

Example::

    [plant]
    model = "custom"
    name = "single_tank"
    [plant.states]
    h = {unit = "m", min = 0.0, max = 1.0}
    [plant.inputs]
    q = {unit = "m^3/s", min = 0.0, max = 1e-4}
    [plant.parameters]
    A = {value = 0.0154, unit = "m^2", min = 0.0}
    a = {value = 5e-5, unit = "m^2", min = 0.0}
    g = {value = 9.81, unit = "m/s^2"}
    [plant.equations]
    h = "(q - a*sqrt(2*g*h))/A"
    [plant.outputs]
    y = {expr = "h", unit = "m", min = 0.0, max = 0.95}   # min/max: the sensor range

A parameter table may carry ``fit = true`` (estimated from measured data, ``tanksynth fit``):
its ``min``/``max`` are then the closed search box and both are required.

Every equation goes through the whitelist parser; nothing is evaluated.
"""

from __future__ import annotations

import math
from typing import Any, Literal, Mapping, overload

import sympy as sp

from tanksynth.errors import SpecError
from tanksynth.plants.base import (Assumption, Parameter, Plant, Quantity, Region,
                                   check_search_box)
from tanksynth.plants.parser import parse_expression, validate_name

__all__ = ["custom_plant"]


def _table(value: Any, key: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping) or not value:
        raise SpecError("expected a non-empty table", key=key)
    return value


def _number(value: Any, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SpecError(f"expected a number, got {type(value).__name__} {value!r}", key=key)
    try:
        value = float(value)
    except OverflowError:  # an int beyond float range (TOML ints are unbounded)
        value = math.inf if value > 0 else -math.inf
    if value != value or value in (float("inf"), float("-inf")):
        raise SpecError(f"expected a finite number, got {value}", key=key)
    return value


@overload
def _signal(name: str, declared: Any, key: str, need_bounds: Literal[True]) -> tuple[Quantity, tuple[float, float]]:
    ...


@overload
def _signal(name: str, declared: Any, key: str, need_bounds: Literal[False]
            ) -> tuple[Quantity, tuple[float, float] | None]:
    ...


def _signal(name: str, declared: Any, key: str, need_bounds: bool) -> tuple[Quantity, tuple[float, float] | None]:
    """A state's or input's `Quantity` and its box bounds from its spec entry ``declared`` (a unit
    string or a table ``{unit, min, max, description}``, as written: checked here)."""
    validate_name(name, key)
    if isinstance(declared, str):
        declared = {"unit": declared}
    if not isinstance(declared, Mapping):
        raise SpecError("expected a unit string or a table {unit, min, max}", key=key)
    unknown = set(declared) - {"unit", "min", "max", "description"}
    if unknown:
        raise SpecError(f"unknown field(s) {sorted(unknown)}; expected unit, min, max, description", key=key)
    unit = declared.get("unit", "1")
    if not isinstance(unit, str):
        raise SpecError(f"unit must be a string, got {unit!r}", key=f"{key}.unit")
    desc = declared.get("description", "")
    if not isinstance(desc, str):
        raise SpecError("description must be a string", key=f"{key}.description")
    bounds = _range(declared, key, "the operating region", need_bounds)
    return Quantity(name, unit, desc), bounds


def _range(declared: Mapping[str, Any], key: str, what: str, required: bool = False
           ) -> tuple[float, float] | None:
    """``(min, max)`` of a signal's table (both or neither; ``required``: both), None if absent."""
    if "min" not in declared and "max" not in declared and not required:
        return None
    if "min" not in declared or "max" not in declared:
        raise SpecError(f"expected both 'min' and 'max' ({what})", key=key)
    lo, hi = _number(declared["min"], f"{key}.min"), _number(declared["max"], f"{key}.max")
    if not lo < hi:
        raise SpecError(f"min ({lo}) must be smaller than max ({hi})", key=key)
    return (lo, hi)


def _inputs_outside_domain_free(expr: sp.Expr, inputs: set[sp.Symbol], key: str) -> None:
    """Refuse an input under ``sqrt``, a fractional power or ``log``: the equilibrium input is
    found by least squares over all reals and the simulators clip nothing before evaluating,
    so such a model is undefined for part of its input range (use a state or a parameter)."""
    for node in sp.preorder_traversal(expr):
        inside = None
        if node.is_Pow and not node.exp.is_Integer:
            inside = node.base
        elif isinstance(node, sp.log):
            inside = node.args[0]
        if inside is not None and inside.free_symbols & inputs:
            names = ", ".join(sorted(str(u) for u in inside.free_symbols & inputs))
            raise SpecError(f"input {names} appears under a square root, fractional power or log "
                            f"({node}); inputs must enter the equations through +, -, *, / and "
                            "integer powers", key=key)


def custom_plant(spec: Mapping[str, Any], key: str = "plant") -> Plant:
    """Build a `Plant` from a ``[plant]`` table with ``model = "custom"``.

    Parameters
    ----------
    spec : mapping
        The ``[plant]`` table: ``states``, ``inputs``, ``parameters``,
        ``equations``, ``outputs`` and optionally ``name``, ``description``,
        ``orderings`` (list of ``"a > b"`` strings that hold on the region)
        and ``assumptions`` (list of strings).
    key : str
        Spec key of the table, for error messages.

    Raises
    ------
    SpecError
        Naming the key for every malformed entry; `ParseError` (a
        `SpecError`) for equation text outside the whitelist grammar.
    """
    allowed = {"model", "name", "description", "states", "inputs", "parameters", "equations",
               "outputs", "orderings", "assumptions"}
    unknown = set(spec) - allowed
    if unknown:
        raise SpecError(f"unknown key(s) {sorted(unknown)} in a custom plant; expected: "
                        + ", ".join(sorted(allowed)), key=key)
    name = spec.get("name", "custom")
    if not isinstance(name, str):
        raise SpecError("expected a string", key=f"{key}.name")
    description = spec.get("description", "plant written in the spec")
    if not isinstance(description, str):
        raise SpecError("expected a string", key=f"{key}.description")

    states: list[Quantity] = []
    bounds: list[tuple[float, float]] = []
    for nm, sig in _table(spec.get("states"), f"{key}.states").items():
        qty, b = _signal(nm, sig, f"{key}.states.{nm}", need_bounds=True)
        states.append(qty)
        bounds.append(b)
    inputs: list[Quantity] = []
    input_bounds: list[tuple[float, float]] = []
    raw_inputs = spec.get("inputs", {})
    if not isinstance(raw_inputs, Mapping):
        raise SpecError("expected a table of inputs", key=f"{key}.inputs")
    for nm, sig in raw_inputs.items():
        qty, limits = _signal(nm, sig, f"{key}.inputs.{nm}", need_bounds=False)
        inputs.append(qty)
        input_bounds.append(limits or (float("-inf"), float("inf")))

    params = []
    raw_params = spec.get("parameters", {})
    if not isinstance(raw_params, Mapping):
        raise SpecError("expected a table of parameters", key=f"{key}.parameters")
    for nm, prm in raw_params.items():
        pkey = f"{key}.parameters.{nm}"
        validate_name(nm, pkey)
        if isinstance(prm, (int, float)) and not isinstance(prm, bool):
            prm = {"value": prm}
        if not isinstance(prm, Mapping) or "value" not in prm:
            raise SpecError("expected a number or a table {value, unit, min, max, fit}", key=pkey)
        unknown_fields = set(prm) - {"value", "unit", "min", "max", "description", "fit"}
        if unknown_fields:
            raise SpecError(f"unknown field(s) {sorted(unknown_fields)}; expected value, unit, min, "
                            "max, description, fit", key=pkey)
        unit = prm.get("unit", "1")
        if not isinstance(unit, str):
            raise SpecError("unit must be a string", key=f"{pkey}.unit")
        fit = prm.get("fit", False)
        if not isinstance(fit, bool):
            raise SpecError(f"expected true or false (estimate the parameter from data), got "
                            f"{type(fit).__name__} {fit!r}", key=f"{pkey}.fit")
        lower = _number(prm["min"], f"{pkey}.min") if "min" in prm else None
        upper = _number(prm["max"], f"{pkey}.max") if "max" in prm else None
        # a free parameter's search box is closed: the fit may end on min
        proto = Parameter(nm, 0.0, unit, str(prm.get("description", "")), lower, upper, inclusive=fit)
        check_search_box(nm, _number(prm["value"], f"{pkey}.value"), lower, upper, fit, pkey)
        value = proto.check(prm["value"], f"{pkey}.value")
        params.append(Parameter(nm, value, unit, proto.description, lower, upper, inclusive=fit))

    declared: dict[str, sp.Expr] = {}
    for group, items in (("states", states), ("inputs", inputs)):
        for qty in items:
            if qty.name in declared:
                raise SpecError(f"name {qty.name!r} declared twice", key=f"{key}.{group}.{qty.name}")
            declared[qty.name] = sp.Symbol(qty.name, real=True)
    for prm in params:
        if prm.name in declared:
            raise SpecError(f"name {prm.name!r} declared twice", key=f"{key}.parameters.{prm.name}")
        declared[prm.name] = prm.symbol

    equations = _table(spec.get("equations"), f"{key}.equations")
    missing = [s.name for s in states if s.name not in equations]
    extra = [k for k in equations if k not in {s.name for s in states}]
    if missing or extra:
        raise SpecError(
            "expected exactly one equation d(state)/dt per state"
            + (f"; missing: {missing}" if missing else "") + (f"; not a state: {extra}" if extra else ""),
            key=f"{key}.equations",
        )
    f = sp.Matrix([parse_expression(equations[s.name], declared, f"{key}.equations.{s.name}")
                   for s in states])
    input_symbols = {declared[i.name] for i in inputs}
    for s, expr in zip(states, f):
        _inputs_outside_domain_free(expr, input_symbols, f"{key}.equations.{s.name}")

    outputs, h = [], []
    for nm, out in _table(spec.get("outputs"), f"{key}.outputs").items():
        okey = f"{key}.outputs.{nm}"
        validate_name(nm, okey)
        unit, desc = "1", ""
        sensor: tuple[float, float] | None = None
        if isinstance(out, Mapping):
            if "expr" not in out:
                raise SpecError("expected an equation string or a table {expr, unit, min, max}", key=okey)
            fields = set(out) - {"expr", "unit", "min", "max", "description"}
            if fields:
                raise SpecError(f"unknown field(s) {sorted(fields)}; expected expr, unit, min, max "
                                "(the sensor range), description", key=okey)
            unit = out.get("unit", "1")
            if not isinstance(unit, str):
                raise SpecError("unit must be a string", key=f"{okey}.unit")
            desc = out.get("description", "")
            if not isinstance(desc, str):
                raise SpecError("description must be a string", key=f"{okey}.description")
            sensor = _range(out, okey, "the sensor range")
            out = out["expr"]
        expr = parse_expression(out, declared, okey)
        if any(s in expr.free_symbols for s in (declared[i.name] for i in inputs)):
            raise SpecError("outputs may depend on states and parameters only (no feedthrough)", key=okey)
        outputs.append(Quantity(nm, unit, desc, sensor))
        h.append(expr)

    orderings = []
    raw_ord = spec.get("orderings", [])
    if not isinstance(raw_ord, list):
        raise SpecError("expected a list of strings like \"h1 > h3\"", key=f"{key}.orderings")
    for i, text in enumerate(raw_ord):
        okey = f"{key}.orderings[{i}]"
        if not isinstance(text, str) or text.count(">") != 1 or ">=" in text:
            raise SpecError(f"expected a strict ordering 'a > b', got {text!r}", key=okey)
        lhs, rhs = text.split(">")
        sides = (parse_expression(lhs, declared, okey), parse_expression(rhs, declared, okey))
        state_symbols = {declared[s.name] for s in states}
        other = sorted(str(v) for side in sides for v in side.free_symbols - state_symbols)
        if other:
            raise SpecError(f"an ordering compares states only; {text!r} names {', '.join(other)} "
                            "(a parameter or an input)", key=okey)
        orderings.append(sides)

    raw_assume = spec.get("assumptions", [])
    if not isinstance(raw_assume, list) or not all(isinstance(a, str) for a in raw_assume):
        raise SpecError("expected a list of strings", key=f"{key}.assumptions")
    assumptions = [Assumption(t, kind="modelling", source="spec") for t in raw_assume]
    assumptions += [Assumption(f"{a} > {b} on the operating region", kind="flow_direction", source="spec")
                    for a, b in orderings]

    return Plant(
        name=name,
        description=description,
        states=tuple(states),
        inputs=tuple(inputs),
        outputs=tuple(outputs),
        parameters=tuple(params),
        f=f,
        h=sp.Matrix(h),
        region=Region(tuple(bounds), tuple(orderings)),
        input_bounds=tuple(input_bounds),
        assumptions=tuple(assumptions),
        source="spec",
    )
