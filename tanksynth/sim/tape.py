"""The plant's vector field compiled once to numpy code (and, for small batches, CasADi).

`numpy_model` generates, once per plant structure, Python source code that
evaluates ``f(x, u)``, ``h(x)`` and the hybrid switching functions ``s(x)``
on numpy arrays laid out one row per state, shape (n, M) (M runs), and
compiles it with `compile`/`exec`: the expression trees are walked once, at
build time, never per step. The plant's parameters stay inputs (each run may
carry its own values, an uncertainty draw, and faults switch values
mid-run); every sub-expression that depends on the parameters only (e.g.
``sqrt(2 g) mu13 Phi / A``) is hoisted into a separate ``constants``
function evaluated once per call of the integrator instead of once per
Runge-Kutta stage. Code generation: common-subexpression elimination
(`sympy.cse`), then sympy's `NumPyPrinter` for every assignment; the
generated source is kept in `NumpyModel.source` (readable, for debugging).

For small batches (a verification run, M = 1) numpy's per-call overhead
dominates, so `NumpyModel.casadi_advance` builds the whole sampling period
(RK4 substeps, clipping, the mode-change flag and the clipping flags) as one
CasADi SX function of ``(x, u, p, h, lower, upper)``, evaluated in place
through a CasADi `FunctionBuffer` (`tanksynth.sim.integrate` picks it for
M up to `CASADI_MAX_RUNS` when the plant has no native kernel). That CasADi
function is built by running the generated source itself with CasADi
operations in place of numpy's, in the same order, so the two forms give the
same numbers bit for bit (tested): a run's trajectory does not depend on the
batch it is simulated in. Both agree with the CasADi `CompiledPlant.rhs` to
rounding (tested). The same source is also translated to C, the plant's
native kernel (`tanksynth.sim.csource`, `tanksynth.sim.kernel`), which the
integrator prefers when a C compiler works; again bit for bit (tested).
Dropping a model (`clear_cache`) drops the kernel it holds.

Cache (no hidden state): compiled models live in this module, in
``_MODELS`` (keyed by the plant's name, equations, switching functions and
parameter names, so plants differing only in parameter values share one
model) and ``_BY_ID`` (an identity fast path). `clear_cache` (also
``tanksynth.sim.clear_cache``) empties both; `cache_info` gives their sizes.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from tanksynth.errors import SimulationError
from tanksynth.plants.base import Plant

__all__ = ["NumpyModel", "numpy_model", "clear_cache", "cache_info", "CASADI_MAX_RUNS",
           "CASADI_MAX_RUNS_HYBRID"]

#: Largest batch integrated by the CasADi period function (above it: the numpy code); both
#: give the same numbers bit for bit, the choice is speed only (measured crossover on the
#: 2-core machine: about 100 runs for the three-tank and tank networks).
CASADI_MAX_RUNS = 96
#: The same for hybrid plants, whose numpy form evaluates ``numpy.select`` per pipe and stage.
CASADI_MAX_RUNS_HYBRID = 512


def _printer() -> Any:
    from sympy.printing.numpy import NumPyPrinter

    class _Printer(NumPyPrinter):
        """numpy printer with element-wise Max/Min and DiracDelta = 0."""

        def _nested(self, fn: str, args: Sequence[sp.Expr]) -> str:
            out = self._print(args[0])
            for a in args[1:]:
                out = f"numpy.{fn}({out}, {self._print(a)})"
            return out

        def _print_Max(self, expr: sp.Expr) -> str:
            return self._nested("maximum", expr.args)

        def _print_Min(self, expr: sp.Expr) -> str:
            return self._nested("minimum", expr.args)

        def _print_DiracDelta(self, expr: sp.Expr) -> str:
            return "0.0"

        def _print__SignedSqrt(self, expr: sp.Expr) -> str:
            a = self._print(expr.args[0])
            return f"numpy.copysign(numpy.sqrt(abs({a})), {a})"

        def _print_Heaviside(self, expr: sp.Expr) -> str:
            return f"numpy.heaviside({self._print(expr.args[0])}, 0.5)"

    return _Printer({"fully_qualified_modules": True, "inline": True})


_SUPPORTED = (sp.Symbol, sp.Number, sp.NumberSymbol, sp.Add, sp.Mul, sp.Pow, sp.Abs, sp.sign,
              sp.exp, sp.log, sp.Max, sp.Min, sp.Heaviside, sp.DiracDelta, sp.Piecewise,
              sp.StrictGreaterThan, sp.GreaterThan, sp.StrictLessThan, sp.LessThan, sp.Eq, sp.Ne,
              sp.And, sp.Or, sp.Not, sp.logic.boolalg.BooleanAtom, sp.core.numbers.ImaginaryUnit,
              sp.functions.elementary.piecewise.ExprCondPair)


def _check(exprs: Sequence[sp.Expr], known: set) -> None:
    for e in exprs:
        for node in sp.preorder_traversal(e):
            if not isinstance(node, _SUPPORTED) or isinstance(node, sp.core.numbers.ImaginaryUnit):
                raise SimulationError(f"cannot compile {type(node).__name__} in {e} for simulation")
            if isinstance(node, sp.Symbol) and node not in known:
                raise SimulationError(f"cannot simulate: free symbol {node} has no value")


class _SignedSqrt(sp.Function):
    """``sign(a) sqrt(|a|)``, printed as ``copysign(sqrt(|a|), a)`` (one numpy call less)."""

    nargs = 1


def _signed_sqrt(args: Sequence[sp.Expr]) -> list[sp.Expr]:
    """Mul arguments with every pair ``sign(a)``, ``sqrt(Abs(a))`` fused into `_SignedSqrt`."""
    args = list(args)
    for s in [a for a in args if isinstance(a, sp.sign)]:
        root = sp.sqrt(sp.Abs(s.args[0]))
        if root in args and s in args:
            args.remove(s)
            args.remove(root)
            args.append(_SignedSqrt(s.args[0]))
    return args


class _Hoister:
    """Split expressions into parameter-only constants and state-dependent code."""

    def __init__(self, params: set, prefix: str):
        self.params = params
        self.consts: list[tuple[sp.Symbol, sp.Expr]] = []
        self.const_syms: set = set()
        self._by_expr: dict[sp.Expr, sp.Symbol] = {}
        self.prefix = prefix

    def constant(self, expr: sp.Expr) -> sp.Expr:
        if expr.is_Atom:
            return expr
        sym = self._by_expr.get(expr)
        if sym is None:
            sym = sp.Symbol(f"{self.prefix}{len(self.consts)}")
            self.consts.append((sym, expr))
            self.const_syms.add(sym)
            self._by_expr[expr] = sym
        return sym

    def is_const(self, expr: sp.Expr) -> bool:
        return expr.free_symbols <= (self.params | self.const_syms)

    def hoist(self, expr: sp.Expr) -> sp.Expr:
        """``expr`` with its parameter-only sub-expressions replaced by constants."""
        if expr.is_Atom:
            return expr
        if isinstance(expr, sp.functions.elementary.piecewise.ExprCondPair):
            return expr.func(self.hoist(expr.expr), self.hoist(expr.cond))
        if self.is_const(expr):
            return self.constant(expr)
        if isinstance(expr, (sp.Add, sp.Mul)):
            args = _signed_sqrt(expr.args) if isinstance(expr, sp.Mul) else expr.args
            fixed = [a for a in args if self.is_const(a)]
            rest = [self.hoist(a) for a in args if not self.is_const(a)]
            if len(fixed) > 1 or (len(fixed) == 1 and not fixed[0].is_Atom):
                fixed = [self.constant(expr.func(*fixed))]
            # constants first: one scalar (or per-run) factor times the arrays
            return expr.func(*fixed, *rest, evaluate=False)
        return expr.func(*[self.hoist(a) for a in expr.args])


def _generate(groups: Mapping[str, tuple[list[sp.Expr], list[sp.Symbol]]],
              params: Sequence[sp.Symbol]) -> tuple[str, dict[str, Callable], int]:
    """Source code, compiled functions (``constants(p)`` and one per group), number of constants.

    Each group ``name -> (expressions, row symbols)`` becomes
    ``name(rows, c, p, out)``: ``rows`` a sequence of the row arrays (states
    then inputs), ``c`` the tuple returned by ``constants(p)``, ``p`` the
    parameter values (scalars or (M,) arrays), ``out`` an (len(exprs), M)
    array written in place and returned.
    """
    printer = _printer()
    pnames = {s: sp.Symbol(f"p_{i}") for i, s in enumerate(params)}
    hoister = _Hoister(set(pnames.values()), "c_")
    bodies = {}
    for name, (exprs, rows) in groups.items():
        rnames = {s: sp.Symbol(f"r_{i}") for i, s in enumerate(rows)}
        # strict: converts numbers to sympy, never parses text (the expressions are the parsed plant's)
        renamed = [sp.sympify(e, strict=True).xreplace({**pnames, **rnames}) for e in exprs]
        repl, reduced = sp.cse(renamed, symbols=sp.numbered_symbols(f"t_{name}_"), order="none")
        lines = []
        for sym, e in repl:
            if hoister.is_const(e):          # parameter-only: computed in constants()
                hoister.consts.append((sym, e))
                hoister.const_syms.add(sym)
            else:
                lines.append(f"    {sym} = {printer.doprint(hoister.hoist(e))}")
        for i, e in enumerate(reduced):
            lines.append(f"    out[{i}] = {printer.doprint(hoister.hoist(e))}")
        bodies[name] = ([f"    r_{i} = rows[{i}]" for i in range(len(rows))], lines)
    src = ["def constants(p):"]
    src += [f"    p_{i} = p[{i}]" for i in range(len(params))]
    src += [f"    {sym} = {printer.doprint(e)}" for sym, e in hoister.consts]
    src.append("    return (" + "".join(f"{sym}, " for sym, _ in hoister.consts) + ")")
    for name, (head, lines) in bodies.items():
        used = set(re.findall(r"\b[a-z]\w*", "\n".join(lines)))
        src.append("")
        src.append(f"def {name}(rows, c, p, out):")
        src += [f"    {sym} = c[{k}]" for k, (sym, _) in enumerate(hoister.consts) if str(sym) in used]
        src += [f"    p_{i} = p[{i}]" for i in range(len(params)) if f"p_{i}" in used]
        src += [line for i, line in enumerate(head) if f"r_{i}" in used]
        src += lines
        src.append("    return out")
    source = "\n".join(src) + "\n"
    namespace: dict[str, Any] = {"numpy": np}
    exec(compile(source, "<tanksynth.sim.tape>", "exec"), namespace)  # noqa: S102 - generated from sympy
    fns = {name: namespace[name] for name in ("constants", *groups)}
    return source, fns, len(hoister.consts)


@dataclass(frozen=True)
class NumpyModel:
    """A plant's vector field, output map and switching functions as generated numpy code.

    Parameters are inputs: each run may carry its own values. The ``*_rows``
    methods work on the row layout (n, M) the integrator uses; `rhs`,
    `output` and `switching` take and return the batch layout (M, n).

    Attributes
    ----------
    n, m, q, k : int
        States, inputs, outputs and switching functions (0 if not hybrid).
    parameter_names : tuple of str
    source : str
        The generated Python source.
    n_constants : int
        Number of parameter-only sub-expressions (`constants`).
    output_index : tuple of int or None
        When every output is one state (``h(x) = x[output_index]``), those
        states' indices (the output is then a selection, no code to run).
    compiled : dict
        What the simulator compiled from this model, by key (CasADi period
        functions, the C source of its kernel, the native kernel and why there is
        none); built on first use and dropped with the model (`clear_cache`).
    """

    n: int
    m: int
    q: int
    k: int
    parameter_names: tuple[str, ...]
    source: str = field(repr=False)
    n_constants: int = field(repr=False)
    _fns: Mapping[str, Callable] = field(repr=False)
    compiled: dict = field(default_factory=dict, repr=False, compare=False)
    output_index: tuple[int, ...] | None = field(default=None, repr=False)

    def parameter_values(self, params: Mapping[str, Any]) -> list:
        """Parameter values in the model's order (scalars or (M,) arrays).

        Parameters
        ----------
        params : mapping of str
            Parameter values by name (scalars or (M,) arrays, SI units).
        """
        return [params[name] for name in self.parameter_names]

    def constants(self, pv: Sequence[Any]) -> tuple:
        """The parameter-only sub-expressions for the values ``pv`` (`parameter_values`).

        Parameters
        ----------
        pv : sequence
            Parameter values in the model's order (`parameter_values`, SI units).
        """
        with np.errstate(invalid="ignore", divide="ignore"):
            return self._fns["constants"](pv)

    def rhs_rows(self, rows: Sequence[np.ndarray], c: tuple, pv: Sequence[Any],
                 out: np.ndarray) -> np.ndarray:
        """``f`` on rows: state rows then input rows (each (M,)) -> ``out`` (n, M).

        Parameters
        ----------
        rows : sequence of ndarray
            State rows then input rows, each shape (M,) (state and input units).
        c : tuple
            Parameter-only sub-expressions (`constants`).
        pv : sequence
            Parameter values in the model's order (`parameter_values`, SI units).
        out : ndarray, shape (n, M)
            Written in place with ``f`` (state units per s).
        """
        with np.errstate(invalid="ignore", divide="ignore"):
            return self._fns["f"](rows, c, pv, out)

    @property
    def rhs_rows_unguarded(self) -> Callable:
        """`rhs_rows` without its ``numpy.errstate`` (for a caller that holds one)."""
        return self._fns["f"]

    def switching_rows(self, x: np.ndarray, c: tuple, pv: Sequence[Any]) -> np.ndarray:
        """Switching functions on the row layout: (n, M) -> (k, M).

        Parameters
        ----------
        x : ndarray, shape (n, M)
            States, one row per state (state units, m).
        c : tuple
            Parameter-only sub-expressions (`constants`).
        pv : sequence
            Parameter values in the model's order (`parameter_values`, SI units).
        """
        out = np.empty((self.k, x.shape[1]))
        if self.k:
            with np.errstate(invalid="ignore", divide="ignore"):
                self._fns["s"](x, c, pv, out)
        return out

    def output_rows(self, x: np.ndarray, c: tuple, pv: Sequence[Any]) -> np.ndarray:
        """Output map on the row layout: (n, M) -> (q, M).

        Parameters
        ----------
        x : ndarray, shape (n, M)
            States, one row per state (state units, m).
        c : tuple
            Parameter-only sub-expressions (`constants`).
        pv : sequence
            Parameter values in the model's order (`parameter_values`, SI units).
        """
        out = np.empty((self.q, x.shape[1]))
        with np.errstate(invalid="ignore", divide="ignore"):
            return self._fns["h"](x, c, pv, out)

    def rhs(self, x: np.ndarray, u: np.ndarray, params: Mapping[str, Any]) -> np.ndarray:
        """``f(x, u)`` at M points: (M, n), (M, m), parameters (scalars or (M,)) -> (M, n).

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        u : ndarray, shape (M, m)
            Inputs (input units, m^3/s).
        params : mapping of str
            Parameter values (scalars or (M,) arrays, SI units).
        """
        pv = self.parameter_values(params)
        rows = [*np.asarray(x, dtype=float).T, *np.asarray(u, dtype=float).T]
        out = np.empty((self.n, x.shape[0]))
        return self.rhs_rows(rows, self.constants(pv), pv, out).T

    def output(self, x: np.ndarray, params: Mapping[str, Any]) -> np.ndarray:
        """``h(x)`` at M points: (M, n) -> (M, q).

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        params : mapping of str
            Parameter values (scalars or (M,) arrays, SI units).
        """
        pv = self.parameter_values(params)
        return self.output_rows(np.asarray(x, dtype=float).T, self.constants(pv), pv).T

    def switching(self, x: np.ndarray, params: Mapping[str, Any]) -> np.ndarray:
        """Switching functions ``s(x)`` at M points: (M, n) -> (M, k); (M, 0) if not hybrid.

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        params : mapping of str
            Parameter values (scalars or (M,) arrays, SI units).
        """
        pv = self.parameter_values(params)
        return self.switching_rows(np.asarray(x, dtype=float).T, self.constants(pv), pv).T

    def casadi_advance(self, substeps: int, runs: int) -> Any:
        """The sampling period as one CasADi function mapped over ``runs`` runs (cached).

        ``(x (n), u (m), c (constants), p (parameters), h, lower (n), upper (n)) -> (x_next
        (n), crossed (1), low (substeps), high (substeps))``: ``substeps``
        RK4 steps of ``h`` s under the held input, stage states clipped,
        every end state clipped; ``crossed`` is 1 when some step changed the
        hybrid mode (the caller re-integrates that run with the numeric
        switching-surface location), ``low``/``high`` flag the steps whose
        end state passed a bound (before clipping).

        Parameters
        ----------
        substeps : int
            RK4 steps per sampling period.
        runs : int
            Number of runs the function is mapped over.
        """
        key = (int(substeps), int(runs))
        fn = self.compiled.get(key)
        if fn is None:
            base = self.compiled.get((int(substeps), 1))
            if base is None:
                base = _casadi_period(self, int(substeps))
                self.compiled[(int(substeps), 1)] = base
            fn = base if runs == 1 else base.map(int(runs), "serial")
            self.compiled[key] = fn
        return fn


class _Reduce:
    """``numpy.logical_and``/``logical_or`` stand-ins with ``.reduce`` (CasADi)."""

    def __init__(self, fn: Callable):
        self.fn = fn

    def __call__(self, a: Any, b: Any) -> Any:
        return self.fn(a, b)

    def reduce(self, parts: Sequence[Any]) -> Any:
        out = parts[0]
        for q in parts[1:]:
            out = self.fn(out, q)
        return out


def _casadi_namespace() -> dict[str, Any]:
    """The generated source's ``numpy`` calls, as CasADi SX operations (same order)."""
    import types

    import casadi as ca

    def select(conds: Sequence[Any], values: Sequence[Any], default: float = np.nan) -> Any:
        out = ca.SX(default)
        for cond, value in reversed(list(zip(conds, values))):
            out = value if cond is True else ca.if_else(cond, value, out)
        return out

    def heaviside(a: Any, h0: float) -> Any:
        return ca.if_else(a > 0, 1.0, ca.if_else(a < 0, 0.0, h0))

    shim = types.SimpleNamespace(
        sqrt=ca.sqrt, copysign=ca.copysign, sign=ca.sign, exp=ca.exp, log=ca.log,
        maximum=ca.fmax, minimum=ca.fmin, heaviside=heaviside, select=select,
        less=lambda a, b: a < b, less_equal=lambda a, b: a <= b, greater=lambda a, b: a > b,
        greater_equal=lambda a, b: a >= b, equal=lambda a, b: a == b,
        not_equal=lambda a, b: a != b, logical_not=ca.logic_not,
        logical_and=_Reduce(ca.logic_and), logical_or=_Reduce(ca.logic_or),
        pi=np.pi, e=np.e, nan=np.nan, inf=np.inf)
    return {"numpy": shim}


def _casadi_period(model: NumpyModel, substeps: int) -> Any:
    """The period of `Integrator` as CasADi SX, built from the generated source itself.

    The same source runs with CasADi operations in place of numpy's, in the
    same order (the constants come in computed by numpy), so both forms give
    the same floating-point numbers (tested bit for bit on the built-in
    plants).
    """
    import casadi as ca

    ns = _casadi_namespace()
    exec(compile(model.source, "<tanksynth.sim.tape casadi>", "exec"), ns)  # noqa: S102
    n, m, k = model.n, model.m, model.k
    nc = model.n_constants
    x = ca.SX.sym("x", n)
    u = ca.SX.sym("u", m)
    c = ca.SX.sym("c", nc)
    p = ca.SX.sym("p", len(model.parameter_names))
    h = ca.SX.sym("h")
    lo = ca.SX.sym("lower", n)
    hi = ca.SX.sym("upper", n)
    cs = [c[i] for i in range(nc)]
    ps = [p[i] for i in range(p.numel())]
    us = [u[i] for i in range(m)]

    def rows(v: Any) -> list:
        return [v[i] for i in range(n)]

    def f(v: Any) -> Any:
        out: list[Any] = [None] * n   # filled with SX entries by the generated function
        ns["f"]([*rows(v), *us], cs, ps, out)
        return ca.vertcat(*[ca.SX(o) for o in out])

    def switching(v: Any) -> list:
        out: list[Any] = [None] * k   # filled with SX entries by the generated function
        ns["s"](rows(v), cs, ps, out)
        return [ca.SX(o) for o in out]

    clip = lambda v: ca.fmin(ca.fmax(v, lo), hi)  # noqa: E731
    half = 0.5 * h
    xt = x
    crossed = ca.SX(0)
    low, high = [], []
    for _ in range(substeps):
        k1 = f(clip(xt))
        k2 = f(clip(k1 * half + xt))
        k3 = f(clip(k2 * half + xt))
        k4 = f(clip(k3 * h + xt))
        acc = ((k2 * 2.0 + k1) + k3 * 2.0 + k4) * (h / 6.0)
        x1 = xt + acc
        if k:
            for a, b in zip(switching(xt), switching(x1)):
                crossed = ca.logic_or(crossed, (a > 0) != (b > 0))
        low.append(ca.mmax(x1 < lo) if n else ca.SX(0))
        high.append(ca.mmax(x1 > hi) if n else ca.SX(0))
        xt = clip(x1)
    return ca.Function("period", [x, u, c, p, h, lo, hi],
                       [xt, crossed, ca.vertcat(*low), ca.vertcat(*high)],
                       ["x", "u", "c", "p", "h", "lower", "upper"],
                       ["x_next", "crossed", "low", "high"])


#: Compiled models by plant structure (name, equations, switching functions, parameter names).
_MODELS: dict[tuple, NumpyModel] = {}
#: Fast path: ``id(plant) -> (plant, model)`` (the plant is held, so its id is not reused);
#: emptied when it holds more than 256 plants.
_BY_ID: dict[int, tuple[Plant, NumpyModel]] = {}


def clear_cache() -> int:
    """Forget every compiled numpy model (`numpy_model` rebuilds them on demand).

    Returns
    -------
    int
        Number of compiled models dropped.
    """
    count = len(_MODELS)
    _MODELS.clear()
    _BY_ID.clear()
    return count


def cache_info() -> dict[str, int]:
    """Sizes of the model caches: ``models`` (by structure) and ``plants`` (by identity)."""
    return {"models": len(_MODELS), "plants": len(_BY_ID)}


def numpy_model(plant: Plant) -> NumpyModel:
    """Generate and compile (once per plant structure) the numpy code of a plant.

    Parameters
    ----------
    plant : Plant

    Returns
    -------
    NumpyModel
        Cached by the model's equations and parameter names, so plants that
        differ only in parameter values share one model.

    Raises
    ------
    SimulationError
        A free symbol without a value, or a function the code generator does
        not support.
    """
    hit = _BY_ID.get(id(plant))
    if hit is not None and hit[0] is plant:
        return hit[1]
    names = tuple(prm.name for prm in plant.parameters)
    switching = tuple(plant.hybrid.switching) if plant.hybrid is not None else ()
    key = (plant.name, tuple(map(sp.srepr, plant.f)), tuple(map(sp.srepr, plant.h)),
           tuple(map(sp.srepr, switching)), names)
    model = _MODELS.get(key)
    if model is None:
        params = [plant.p[nm] for nm in names]
        xs, us = list(plant.x), list(plant.u)
        f, h, s = list(plant.f), list(plant.h), list(switching)
        _check(f, set(xs) | set(us) | set(params))
        _check(h + s, set(xs) | set(params))
        groups = {"f": (f, xs + us), "h": (h, xs)}
        if s:
            groups["s"] = (s, xs)
        source, fns, n_constants = _generate(groups, params)
        index = tuple(xs.index(e) if e in xs else -1 for e in h)
        model = NumpyModel(plant.n, plant.m, plant.q, len(switching), names, source,
                           n_constants, fns,
                           output_index=None if -1 in index else index)
        _MODELS[key] = model
    if len(_BY_ID) > 256:
        _BY_ID.clear()
    _BY_ID[id(plant)] = (plant, model)
    return model
