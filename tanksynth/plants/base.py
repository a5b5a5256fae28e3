"""The `Plant` object: a symbolic nonlinear model with units and a region.

A plant is ``dx/dt = f(x, u)``, ``y = h(x)`` written in sympy, with named
states, inputs and outputs (each with a unit), named parameters (value and
unit), a box operating region plus the strict orderings (flow-direction
assumptions) that make the model smooth there, and the list of assumptions
the model makes. Plants are immutable; `Plant.with_parameters` returns a new
one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from fractions import Fraction
from functools import cached_property
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

import numpy as np
import sympy as sp

from tanksynth.errors import DimensionError, RegionError, SpecError

if TYPE_CHECKING:  # compiled on first use (CasADi loads then)
    from tanksynth.plants.compile import CompiledPlant

__all__ = [
    "Quantity",
    "Parameter",
    "Assumption",
    "Region",
    "HybridModes",
    "Plant",
    "OptionValue",
    "exact",
    "check_search_box",
]

#: The value of a plant family's construction option (``N = 4``, ``parameter_set = "decenter"``).
OptionValue = int | float | str | bool


def exact(value: float) -> sp.Rational:
    """Exact rational of a float's shortest decimal representation.

    ``exact(0.0154)`` is ``77/5000``, so symbolic work with parameter values
    stays exact (seed 004's threshold is pinned as fractions).

    Parameters
    ----------
    value : float
        The number (any unit).
    """
    frac = Fraction(repr(float(value)))
    return sp.Rational(frac.numerator, frac.denominator)


def check_search_box(name: str, value: float, lower: float | None, upper: float | None, fit: bool,
                     key: str) -> None:
    """Refuse an inconsistent box of a parameter: a fit without both bounds, ``min >= max``,
    ``value`` outside ``[min, max]``.

    Parameters
    ----------
    name : str
        The parameter.
    value : float
        Its value (the start of a fit), in its unit.
    lower, upper : float or None
        ``min`` and ``max`` as given (its unit).
    fit : bool
        ``fit = true`` (estimated from data: both bounds required).
    key : str
        The parameter's spec key.

    Raises
    ------
    SpecError
        Naming ``key`` (or its ``.min``, ``.max``, ``.value``).
    """
    if fit and (lower is None or upper is None):
        absent = " and ".join(b for b, v in (("min", lower), ("max", upper)) if v is None)
        raise SpecError(f"a free parameter (fit = true) needs a search box: give {absent}",
                        key=f"{key}.{'min' if lower is None else 'max'}")
    if lower is not None and upper is not None and not lower < upper:
        raise SpecError(f"min ({lower:g}) must be smaller than max ({upper:g})", key=key)
    if lower is not None and value < lower:
        raise SpecError(f"value {value:g} of {name!r} is below min ({lower:g}); the value (the "
                        "start of a fit) must lie in [min, max]", key=f"{key}.value")
    if upper is not None and value > upper:
        raise SpecError(f"value {value:g} of {name!r} is above max ({upper:g}); the value (the "
                        "start of a fit) must lie in [min, max]", key=f"{key}.value")


@dataclass(frozen=True)
class Quantity:
    """A named signal (state, input or output) with its unit.

    Parameters
    ----------
    name : str
        Signal name (an identifier, e.g. ``h1``).
    unit : str
        Its unit (e.g. ``m``, ``m^3/s``).
    description : str, optional
        One line of meaning.
    limits : (float, float) or None, optional
        Sensor range of an output (its unit): a logged sample at a limit is censored (the
        true output is at or beyond it, `tanksynth.measurements`). None: no range declared.
    """

    name: str
    unit: str
    description: str = ""
    limits: tuple[float, float] | None = None


@dataclass(frozen=True)
class Parameter:
    """A named model constant.

    Attributes
    ----------
    name, unit, description : str
    value : float
        Value in ``unit``.
    lower, upper : float or None
        Admissible range (``lower < value <= upper``; ``lower = 0`` means
        strictly positive). Checked by `Plant.with_parameters`.
    inclusive : bool
        The lower bound is admissible too (``lower <= value``), e.g. a valve
        coefficient that may be 0 (closed).
    plausible : (float, float) or None
        Range (in ``unit``) of values a real plant of this family has; a
        value outside it is admissible but draws a `DesignWarning` (a unit
        slip such as cm^2 written as m^2). None: no such range.
    """

    name: str
    value: float
    unit: str
    description: str = ""
    lower: float | None = None
    upper: float | None = None
    inclusive: bool = False
    plausible: tuple[float, float] | None = None

    def implausible(self) -> str | None:
        """A one-line warning when ``value`` lies outside ``plausible``, else None."""
        if self.plausible is None:
            return None
        lo, hi = self.plausible
        if lo <= self.value <= hi:
            return None
        return (f"parameter {self.name} = {self.value:g} {self.unit} is outside the plausible range "
                f"[{lo:g}, {hi:g}] {self.unit} ({self.description}): check its unit")

    @property
    def symbol(self) -> sp.Symbol:
        """The sympy symbol (positive or nonnegative when ``lower >= 0``)."""
        if self.lower is not None and self.lower >= 0:
            if self.inclusive and self.lower == 0:
                return sp.Symbol(self.name, real=True, nonnegative=True)
            return sp.Symbol(self.name, real=True, positive=True)
        return sp.Symbol(self.name, real=True)

    def check(self, value: Any, key: str) -> float:
        """Validate a candidate value for this parameter and return it as float.

        Parameters
        ----------
        value : float
            Candidate value (the parameter's unit).
        key : str
            Dotted spec key, for error messages.
        """
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SpecError(
                f"expected a number for parameter '{self.name}' ({self.unit}), "
                f"got {type(value).__name__} {value!r}",
                key=key,
            )
        try:
            value = float(value)
        except OverflowError:  # an int beyond float range (TOML ints are unbounded)
            value = math.inf if value > 0 else -math.inf
        if not math.isfinite(value):
            raise SpecError(f"parameter '{self.name}' must be finite, got {value}", key=key)
        if self.lower is not None and not (value >= self.lower if self.inclusive else value > self.lower):
            relation = ">=" if self.inclusive else ">"
            raise SpecError(
                f"parameter '{self.name}' must be {relation} {self.lower} {self.unit}, got {value}", key=key
            )
        if self.upper is not None and not value <= self.upper:
            raise SpecError(
                f"parameter '{self.name}' must be <= {self.upper} {self.unit}, got {value}", key=key
            )
        return value


@dataclass(frozen=True)
class Assumption:
    """Something the model takes for granted, shown in reports.

    ``kind`` is one of ``"flow_direction"`` (makes the model smooth on the
    region), ``"reconstructed"`` (not in the source paper; our reconstruction),
    ``"omitted"`` (a value the paper does not give; our choice), or
    ``"modelling"`` (a physical simplification).

    Parameters
    ----------
    text : str
        The assumption, one sentence.
    kind : str, optional
        ``"flow_direction"``, ``"reconstructed"``, ``"omitted"`` or ``"modelling"``.
    source : str, optional
        Where it comes from (paper, section), if anywhere.
    """

    text: str
    kind: str = "modelling"
    source: str = ""


@dataclass(frozen=True)
class Region:
    """Operating region: box bounds on the states plus strict orderings.

    Attributes
    ----------
    bounds : tuple of (float, float)
        ``(lower, upper)`` for each state, in the state's unit.
    orderings : tuple of (sympy.Expr, sympy.Expr)
        Pairs ``(a, b)`` meaning ``a > b`` holds on the region (flow
        directions, e.g. ``h1 > h3``).
    """

    bounds: tuple[tuple[float, float], ...]
    orderings: tuple[tuple[sp.Expr, sp.Expr], ...] = ()

    def violations(self, x: Sequence[float] | np.ndarray, states: Sequence[sp.Symbol]) -> list[str]:
        """List the region conditions violated by the numeric state ``x``.

        Parameters
        ----------
        x : sequence of float or ndarray, shape (n,)
            State (state units, m).
        states : sequence of sympy.Symbol
            The state symbols.
        """
        out = []
        for sym, (lo, hi), xi in zip(states, self.bounds, x):
            if not (lo <= xi <= hi):
                out.append(f"{sym} = {xi:g} outside [{lo:g}, {hi:g}]")
        subs = dict(zip(states, x))
        for a, b in self.orderings:
            av = float(a.subs(subs))
            bv = float(b.subs(subs))
            if not av > bv:
                out.append(f"{a} > {b} violated ({av:g} <= {bv:g})")
        return out

    def positive_expressions(self, states: Sequence[sp.Symbol]) -> list[sp.Expr]:
        """Expressions that are >= 0 everywhere on the region.

        Parameters
        ----------
        states : sequence of sympy.Symbol
            The state symbols.
        """
        facts = [sym for sym, (lo, _) in zip(states, self.bounds) if lo >= 0]
        facts += [sp.expand(a - b) for a, b in self.orderings]
        return facts

    def sample(self, count: int, states: Sequence[sp.Symbol], seed: int = 0,
               margin: float = 0.0) -> np.ndarray:
        """Draw ``count`` points of the region (seeded, rejection sampling).

        Parameters
        ----------
        count : int
            Number of points.
        states : sequence of sympy.Symbol
            State symbols, in order.
        seed : int
            Seed of the numpy generator.
        margin : float
            Relative margin kept from the box faces (0 <= margin < 0.5).

        Returns
        -------
        numpy.ndarray, shape (count, n)
        """
        rng = np.random.default_rng(seed)
        lo = np.array([b[0] for b in self.bounds], dtype=float)
        hi = np.array([b[1] for b in self.bounds], dtype=float)
        span = hi - lo
        lo, hi = lo + margin * span, hi - margin * span
        checks = [
            sp.lambdify([list(states)], sp.expand(a - b), "numpy") for a, b in self.orderings
        ]
        points = np.empty((0, len(states)))
        for _ in range(200):
            cand = rng.uniform(lo, hi, size=(max(4 * count, 64), len(states)))
            keep = np.ones(len(cand), dtype=bool)
            for fn in checks:
                keep &= np.asarray(fn(cand.T), dtype=float) > 0
            points = np.vstack([points, cand[keep]])
            if len(points) >= count:
                return points[:count]
        raise RegionError("the operating region is empty or too thin to sample", key="region")


@dataclass(frozen=True)
class HybridModes:
    """Discrete modes of an autonomous hybrid plant.

    The mode is the tuple of bits ``[s_j(x) > 0]`` for the switching
    functions ``s_j``; e.g. for the hybrid three-tank ``s = (h1 - h0,
    h2 - h0, h3 - h0)`` gives the bits ``(a, b, c)``.

    Attributes
    ----------
    names : tuple of str
        Bit names (``"a", "b", "c"``).
    switching : tuple of sympy.Expr
        Switching functions, in the plant's symbols.
    """

    names: tuple[str, ...]
    switching: tuple[sp.Expr, ...]


@dataclass(frozen=True)
class Plant:
    """A symbolic nonlinear plant ``dx/dt = f(x, u)``, ``y = h(x)``.

    Attributes
    ----------
    name : str
        Model name (``"three_tank"``, ``"custom"``, ...).
    description : str
        One line for listings and reports.
    states, inputs, outputs : tuple of Quantity
    parameters : tuple of Parameter
    f : sympy.Matrix, shape (n, 1)
        General vector field in states, inputs and parameter symbols.
    h : sympy.Matrix, shape (q, 1)
        Output map.
    region : Region
    input_bounds : tuple of (float or str, float or str)
        Actuator range of each input (saturation); an entry may name a
        parameter (e.g. ``"qmax"``) so that overriding it moves the range.
        `input_limits` gives the numbers.
    assumptions : tuple of Assumption
    hybrid : HybridModes or None
    source : str
        Where the model comes from (seed paper, notes).
    options : tuple of (str, object)
        Construction options of the plant family (e.g. ``("N", 3)``), see `option`.
    """

    name: str
    description: str
    states: tuple[Quantity, ...]
    inputs: tuple[Quantity, ...]
    outputs: tuple[Quantity, ...]
    parameters: tuple[Parameter, ...]
    f: sp.Matrix
    h: sp.Matrix
    region: Region
    input_bounds: tuple[tuple[float | str, float | str], ...] = ()
    assumptions: tuple[Assumption, ...] = ()
    hybrid: HybridModes | None = None
    source: str = ""
    options: tuple[tuple[str, OptionValue], ...] = field(default=())

    def __post_init__(self) -> None:
        n, m, q = len(self.states), len(self.inputs), len(self.outputs)
        if self.f.shape != (n, 1):
            raise DimensionError(f"plant {self.name}: f has shape {self.f.shape}, expected ({n}, 1)")
        if self.h.shape != (q, 1):
            raise DimensionError(f"plant {self.name}: h has shape {self.h.shape}, expected ({q}, 1)")
        if len(self.region.bounds) != n:
            raise DimensionError(f"plant {self.name}: region has {len(self.region.bounds)} bounds, expected {n}")
        names = {prm.name for prm in self.parameters}
        for pair in self.input_bounds:
            for b in pair:
                if isinstance(b, str) and b not in names:
                    raise DimensionError(f"plant {self.name}: input bound {b!r} is not a parameter")
        if self.input_bounds and len(self.input_bounds) != m:
            raise DimensionError(f"plant {self.name}: {len(self.input_bounds)} input bounds, expected {m}")

    # ------------------------------------------------------------------ symbols
    @property
    def n(self) -> int:
        """Number of states."""
        return len(self.states)

    @property
    def m(self) -> int:
        """Number of inputs."""
        return len(self.inputs)

    @property
    def q(self) -> int:
        """Number of outputs."""
        return len(self.outputs)

    @cached_property
    def x(self) -> tuple[sp.Symbol, ...]:
        """State symbols (real)."""
        return tuple(sp.Symbol(s.name, real=True) for s in self.states)

    @cached_property
    def u(self) -> tuple[sp.Symbol, ...]:
        """Input symbols (real)."""
        return tuple(sp.Symbol(s.name, real=True) for s in self.inputs)

    @cached_property
    def p(self) -> dict[str, sp.Symbol]:
        """Parameter symbols by name (positive when the parameter must be > 0)."""
        return {prm.name: prm.symbol for prm in self.parameters}

    @cached_property
    def parameter_values(self) -> dict[sp.Symbol, sp.Rational]:
        """Parameter symbol -> exact value, for substitution."""
        return {self.p[prm.name]: exact(prm.value) for prm in self.parameters}

    @property
    def input_limits(self) -> np.ndarray:
        """Actuator ranges as numbers, shape (m, 2); ``(-inf, inf)`` if unbounded."""
        values = {prm.name: prm.value for prm in self.parameters}
        if not self.input_bounds:
            return np.tile([-np.inf, np.inf], (self.m, 1))
        return np.array([[values[b] if isinstance(b, str) else float(b) for b in pair]
                         for pair in self.input_bounds], dtype=float)

    def state_bounds(self, params: Mapping[str, Any] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The clipping rule: bounds every simulation of this plant keeps its states in.

        The one rule of the toolbox (the batch simulator, the symbolic steps
        used in design, the training-data and residual simulations, and the
        estimators' optional clamping all use it): lower bound 0 for every
        state whose operating region starts at or above 0 (a level cannot be
        negative, Torricelli's square root stays real), ``-inf`` for a state
        whose region extends below 0; upper bound the plant's ``hmax``
        parameter (overflow height) when it has one, ``+inf`` otherwise.

        Parameters
        ----------
        params : mapping of str to float, optional
            Parameter values to use instead of the plant's (only ``hmax``
            matters; it must be one number, not a per-run array).

        Returns
        -------
        lower, upper : ndarray, shape (n,)
            In state units.

        Raises
        ------
        DimensionError
            ``hmax`` given as an array (one overflow height per run).
        """
        lower = np.array([0.0 if lo >= 0 else -np.inf for lo, _ in self.region.bounds])
        values: dict[str, Any] = {prm.name: prm.value for prm in self.parameters}
        values.update(params or {})
        upper = np.full(self.n, np.inf)
        if "hmax" in values:
            if np.ndim(values["hmax"]) != 0:
                raise DimensionError(f"plant {self.name}: the overflow height hmax must be one "
                                     f"value for all runs, got shape {np.shape(values['hmax'])}")
            upper[:] = float(values["hmax"])
        return lower, upper

    def mode_of(self, x: Sequence[float] | np.ndarray) -> tuple[int, ...] | np.ndarray:
        """Hybrid mode bits at ``x``: a tuple for one point, (M, k) ints for (M, n).

        Parameters
        ----------
        x : sequence of float or ndarray, shape (M, n)
            One state or M states (state units, m).

        Raises
        ------
        TanksynthError
            If the plant has no hybrid modes.
        """
        arr = np.asarray(x, dtype=float)
        bits = self.compiled.modes(np.atleast_2d(arr))
        return tuple(int(b) for b in bits[0]) if arr.ndim == 1 else bits

    def parameter(self, name: str) -> Parameter:
        """The parameter called ``name``.

        Parameters
        ----------
        name : str
            Parameter name.
        """
        for prm in self.parameters:
            if prm.name == name:
                return prm
        raise KeyError(name)

    def implausible_parameters(self) -> list[str]:
        """One warning line per parameter outside its plausible range (see `Parameter.plausible`)."""
        return [w for w in (prm.implausible() for prm in self.parameters) if w]

    def option(self, name: str, default: OptionValue | None = None) -> OptionValue | None:
        """A construction option of the plant family (e.g. ``N``).

        Parameters
        ----------
        name : str
            Option name.
        default : object, optional
            Returned when the family has no such option.
        """
        return dict(self.options).get(name, default)

    # --------------------------------------------------------------- numeric f
    @cached_property
    def f_numeric(self) -> sp.Matrix:
        """General ``f(x, u)`` with parameter values substituted (exact)."""
        return self.f.xreplace(self.parameter_values)

    @cached_property
    def h_numeric(self) -> sp.Matrix:
        """Output map with parameter values substituted."""
        return self.h.xreplace(self.parameter_values)

    @cached_property
    def f_smooth(self) -> sp.Matrix:
        """``f`` with sign/abs resolved by the region's sign facts.

        On the region (box bounds with non-negative lower bounds and the
        declared orderings), every ``sign(e)`` / ``Abs(e)`` whose argument is
        known to be non-negative (or non-positive) is replaced by ``1``/``e``
        (``-1``/``-e``). What cannot be resolved is left as is.
        """
        return resolve_signs(self.f, self.region.positive_expressions(self.x))

    @cached_property
    def f_smooth_numeric(self) -> sp.Matrix:
        """`f_smooth` with parameter values substituted."""
        return self.f_smooth.xreplace(self.parameter_values)

    def with_parameters(self, overrides: Mapping[str, Any], key: str = "plant.parameters") -> "Plant":
        """A copy of the plant with some parameter values replaced.

        Parameters
        ----------
        overrides : mapping of str to float
            New values by parameter name (in the parameter's unit).
        key : str
            Spec key prefix for error messages.

        Raises
        ------
        SpecError
            Unknown parameter name, non-numeric or out-of-range value.
        """
        known = {prm.name: prm for prm in self.parameters}
        new = []
        for name in overrides:
            if name not in known:
                raise SpecError(
                    f"unknown parameter {name!r} for plant '{self.name}'; expected one of: "
                    + ", ".join(known),
                    key=f"{key}.{name}",
                )
        for prm in self.parameters:
            if prm.name in overrides:
                value = prm.check(overrides[prm.name], f"{key}.{prm.name}")
                new.append(replace(prm, value=value))
            else:
                new.append(prm)
        return replace(self, parameters=tuple(new))

    def with_region(self, bounds: Sequence[tuple[float, float]] | None = None) -> "Plant":
        """A copy with other box bounds (orderings are kept).

        Parameters
        ----------
        bounds : sequence of (float, float), optional
            Lower and upper bound of each state (state units, m); None: the current box.
        """
        if bounds is None:
            return self
        return replace(self, region=replace(self.region,
                                            bounds=tuple((float(lo), float(hi)) for lo, hi in bounds)))

    def check_point(self, x: Sequence[float] | np.ndarray, key: str = "operating_point") -> None:
        """Raise `RegionError` if ``x`` is outside the operating region.

        Parameters
        ----------
        x : sequence of float or ndarray, shape (n,)
            State (state units, m).
        key : str, optional
            Spec key named in the error.
        """
        bad = self.region.violations(x, self.x)
        if bad:
            raise RegionError(
                f"operating point {list(map(float, x))} is outside the operating region of "
                f"plant '{self.name}': " + "; ".join(bad),
                key=key,
            )

    @cached_property
    def compiled(self) -> CompiledPlant:
        """Numeric functions compiled once (see `tanksynth.plants.compile`)."""
        from tanksynth.plants.compile import compile_plant

        return compile_plant(self)

    def latex_equations(self) -> dict[str, list[str]]:
        """LaTeX of the model: ``general`` and ``smooth`` state equations, ``outputs``.

        Each entry is one equation ``\\dot{x}_i = f_i`` or ``y_j = h_j`` in the
        parameter symbols (values are listed separately in reports).
        """
        symbols = set(self.f.free_symbols | self.f_smooth.free_symbols | self.h.free_symbols)
        symbols |= {sp.Symbol(v.name) for v in (*self.states, *self.outputs)}
        # sympy typesets a name ending in "scr" as \mathscr{...}, whose package the reports
        # do not load (and their LaTeX check refuses): \mathcal is the script face they have.
        names = {sym: sp.latex(sym).replace(r"\mathscr{", r"\mathcal{") for sym in symbols}

        def tex(expr: Any) -> str:
            return sp.latex(expr, symbol_names=names)

        def lhs(name: str, dot: bool) -> str:
            sym = tex(sp.Symbol(name))
            return rf"\dot{{{sym}}}" if dot else sym

        return {
            "general": [f"{lhs(s.name, True)} = {tex(e)}" for s, e in zip(self.states, self.f)],
            "smooth": [f"{lhs(s.name, True)} = {tex(e)}" for s, e in zip(self.states, self.f_smooth)],
            "outputs": [f"{lhs(o.name, False)} = {tex(e)}" for o, e in zip(self.outputs, self.h)],
        }

    def summary(self) -> dict[str, Any]:
        """A JSON-friendly description (for ``tanksynth plants`` and reports)."""
        return {
            "name": self.name,
            "description": self.description,
            "states": [{"name": s.name, "unit": s.unit, "description": s.description} for s in self.states],
            "inputs": [{"name": s.name, "unit": s.unit, "description": s.description} for s in self.inputs],
            "outputs": [{"name": s.name, "unit": s.unit, "description": s.description,
                         **({} if s.limits is None else {"limits": list(s.limits)})}
                        for s in self.outputs],
            "parameters": [
                {"name": p.name, "value": p.value, "unit": p.unit, "description": p.description,
                 **({} if p.plausible is None else {"plausible": list(p.plausible)})}
                for p in self.parameters
            ],
            "region": {
                "bounds": {s.name: list(b) for s, b in zip(self.states, self.region.bounds)},
                "orderings": [f"{a} > {b}" for a, b in self.region.orderings],
            },
            "input_bounds": {s.name: lim.tolist() for s, lim in zip(self.inputs, self.input_limits)},
            "assumptions": [{"kind": a.kind, "text": a.text, "source": a.source} for a in self.assumptions],
            "hybrid": None if self.hybrid is None else {
                "bits": list(self.hybrid.names), "switching": [str(s) for s in self.hybrid.switching]
            },
            "source": self.source,
        }


def resolve_signs(expr: sp.Matrix | sp.Expr, positive: Iterable[sp.Expr]) -> Any:
    """Replace ``sign(e)`` and ``Abs(e)`` where the sign of ``e`` is known.

    Parameters
    ----------
    expr : sympy expression or matrix
    positive : iterable of sympy.Expr
        Expressions known to be >= 0.

    Returns
    -------
    Same type as ``expr``.
    """
    facts = [sp.expand(e) for e in positive]

    def sign_of(arg: sp.Expr) -> int:
        a = sp.expand(arg)
        for fact in facts:
            if sp.expand(a - fact) == 0:
                return 1
            if sp.expand(a + fact) == 0:
                return -1
        return 0

    def fix_sign(e: sp.Expr) -> sp.Expr:
        s = sign_of(e.args[0])
        return sp.Integer(s) if s else e

    def fix_abs(e: sp.Expr) -> sp.Expr:
        s = sign_of(e.args[0])
        return s * e.args[0] if s else e

    return expr.replace(lambda e: isinstance(e, sp.sign), fix_sign).replace(
        lambda e: isinstance(e, sp.Abs), fix_abs
    )
