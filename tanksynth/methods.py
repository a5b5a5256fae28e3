"""The one table of design methods: what each spec method is, designs, verifies and states.

Every ``method = "..."`` a spec may name is one row of `TABLE`; nothing is
registered on import and nothing else maps method names to behaviour. A row
holds:

``kind``
    ``"model"``, ``"controller"``, ``"observer"``, ``"estimator"`` or
    ``"detector"`` (``pole_placement`` and ``lmi_placement`` are controllers
    or observers, by their ``target`` option: both kinds are listed).
``options``
    The method's Options dataclass (`tanksynth.spec.method_options`): options,
    defaults, units, validation at parse time (`Method.validate`).
``adapter``
    The design adapter (`tanksynth.design.DesignMethod`): the same Options
    class and ``run(spec, design) -> DesignResult``.
``verdict``
    ``verdict(doc, spec) -> list[Check]`` of `tanksynth.verify`: re-derives what
    it checks from the artefact and simulates it on the nonlinear plant.
``campaign``
    ``runner(doc, spec) -> CampaignRun``: what a Monte-Carlo campaign runs for
    the artefact (a closed loop, an estimator on the noisy measurements, a
    residual test or a model's prediction; `tanksynth.verify.campaign`).
``statement``
    ``statement(diagnostics) -> Tex``: the problem solved, for the report.

A row names these parts (``"tanksynth.design.model.adapters:LINEARIZE"``) and each
is imported on first use, so a command imports only the modules of the methods
its spec uses (``import tanksynth.methods`` loads no numerical library; issue 15).
The table is complete or the package does not import: `_check_table` runs at
import and raises if a row lacks a part its kind needs or names one malformed;
`resolve_table` (run by the test suite) imports every part and checks it.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Callable, Generic, Iterator, Mapping, TypeVar, cast

if TYPE_CHECKING:  # annotations only: the modules load when a row's part is first used
    from tanksynth.design.result import DesignMethod, DesignResult
    from tanksynth.plants.base import Plant
    from tanksynth.spec import DesignSpec, Spec
    from tanksynth.spec.method_options import MethodOptions
    from tanksynth.verify.runner import VerifiableMethod, Verdict, VerdictFn

__all__ = ["KINDS", "FAMILIES", "Method", "Alias", "ALIASES", "home", "TABLE", "METHODS", "VERDICTS", "RUNNERS", "STATEMENTS", "ADAPTERS",
           "method", "resolve", "resolve_table", "design", "load_spec", "parse_spec", "parse_spec_text",
           "load_directory", "verify_directory", "write_report"]

#: The method families: each is a sub-package of the same name in every stage (`home`).
FAMILIES = ("model", "placement", "observer_lmi", "takagi_sugeno", "laws", "decentralized",
            "estimators", "fault", "robust", "synthesis", "fit")

#: What a design method produces.
KINDS = ("model", "controller", "observer", "estimator", "detector")

#: ``"package.module:attribute"``: how a row names a part.
_REF = re.compile(r"tanksynth(\.[a-z_][a-z0-9_]*)+:[A-Za-z_][A-Za-z0-9_]*\Z")


@cache
def resolve(ref: str) -> Any:
    """The object a row names: ``"tanksynth.design.model.adapters:LINEARIZE"`` -> that constant.

    Imports the module on first use; cached.

    Parameters
    ----------
    ref : str
        ``"<module>:<attribute>"``.

    Returns
    -------
    object
        The module's attribute.
    """
    module, _, attr = ref.partition(":")
    __import__(module)  # not importlib.import_module: `python -X importtime` does not see those
    return getattr(sys.modules[module], attr)


#: The type of the object a `_Part` field holds.
_T = TypeVar("_T")


class _Part(Generic[_T]):
    """A field of `Method` given as a reference string (imported on first read, see `resolve`)
    or as the object itself (``dataclasses.replace(row, verdict=fn)``)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self._slot = "_" + name

    def __get__(self, obj: Any, objtype: type | None = None) -> _T:
        if obj is None:
            raise AttributeError(self._slot[1:])  # no class-level default (dataclass fields)
        value = obj.__dict__[self._slot]
        return cast(_T, resolve(value)) if isinstance(value, str) else value

    def __set__(self, obj: Any, value: _T | str) -> None:
        obj.__dict__[self._slot] = value  # reached from the dataclass __init__ only (frozen)


@dataclass(frozen=True)
class Method:
    """One row of the method table.

    The parts (``options``, ``adapter``, ``verdict``, ``statement``, ``campaign``) are given as
    ``"<module>:<attribute>"`` strings and read as the objects they name, imported on first use
    (`resolve`); an object given instead is used as is.

    Attributes
    ----------
    name : str
        The spec's ``method`` value.
    family : str
        The method family (`FAMILIES`): the sub-package that holds its parts in every stage
        (``tanksynth.design.<family>``, ``tanksynth.verify.<family>``, the options and the
        report statement of that name; `home`).
    kinds : tuple of str
        Some of `KINDS`.
    summary : str
        One line: what the method designs.
    options : type of MethodOptions
        The Options dataclass (``adapter.options``); validates a ``[[design]]`` table.
    adapter : DesignMethod
        The Options class and the design function.
    verdict : callable
        ``verdict(doc, spec) -> list[Check]``.
    statement : callable
        ``statement(diagnostics) -> Tex`` (report).
    campaign : callable
        ``runner(doc, spec) -> CampaignRun`` (campaigns).
    """

    name: str
    family: str
    kinds: tuple[str, ...]
    summary: str
    options: _Part[type[MethodOptions]] = _Part()
    adapter: _Part[DesignMethod] = _Part()
    verdict: _Part[VerdictFn] = _Part()
    statement: _Part[Callable[[Mapping[str, Any]], Any]] = _Part()
    campaign: _Part[Callable[..., Any]] = _Part()

    def refs(self) -> dict[str, Any]:
        """The parts as given: reference strings (or objects), by part name."""
        return {part: self.__dict__["_" + part] for part in _PARTS}

    def __repr__(self) -> str:  # the references, without importing the parts
        parts = ", ".join(f"{part}={ref!r}" for part, ref in self.refs().items())
        return f"Method(name={self.name!r}, family={self.family!r}, kinds={self.kinds!r}, summary={self.summary!r}, {parts})"

    def validate(self, options: Mapping[str, Any], key: str, plant: Plant,
                 ts: float | None) -> MethodOptions:
        """Validate a ``[[design]]`` table's options (the spec parser's check; imports only the
        Options, not the design code).

        Parameters
        ----------
        options : mapping
            The raw options of the ``[[design]]`` table.
        key : str
            Dotted key of the table, for error messages (e.g. ``design[1]``).
        plant : Plant
            The spec's plant.
        ts : float or None
            The spec's sampling period [s].

        Returns
        -------
        MethodOptions
            The options with their defaults (an instance of `options`).
        """
        return self.options.validated(options, key, plant, ts)

    def design(self, spec: Spec, design: DesignSpec) -> DesignResult:
        """Run the design of one ``[[design]]`` entry of ``spec``.

        Every `DesignWarning` (operating point, actuator range, implausible
        parameters, unstable result, the method's own) is issued and listed in
        ``diagnostics["warnings"]`` (`tanksynth.design.audit.designed`); an entry
        written with an alias (``method = "lqr"``) records it as
        ``diagnostics["method_alias"]``.

        Parameters
        ----------
        spec : Spec
            The validated spec.
        design : DesignSpec
            One of its ``[[design]]`` entries (of this method).
        """
        from dataclasses import replace

        from tanksynth.design.audit import designed

        result = designed(self.adapter.run, spec, design)
        if design.alias is None:
            return result
        return replace(result, diagnostics={**result.diagnostics, "method_alias": design.alias})


_PARTS = ("options", "adapter", "verdict", "statement", "campaign")
#: Where each part of a family lives: the family's module in each stage (``_row``).
_HOMES = {"options": "tanksynth.spec.method_options.{family}",
          "adapter": "tanksynth.design.{family}.adapters",
          "verdict": "tanksynth.verify.{family}.verdicts",
          "statement": "tanksynth.reports.statements.{family}",
          "campaign": "tanksynth.verify.{family}.campaign"}


def home(part: str, family: str) -> str:
    """The module that holds a family's ``part`` (``home("verdict", "placement")`` ->
    ``"tanksynth.verify.placement.verdicts"``).

    Parameters
    ----------
    part : str
        One of ``"options"``, ``"adapter"``, ``"verdict"``, ``"statement"``, ``"campaign"``.
    family : str
        The method family (`FAMILIES`).

    Returns
    -------
    str
        The dotted module name.
    """
    return _HOMES[part].format(family=family)


def _row(name: str, family: str, kinds: tuple[str, ...], summary: str, *, options: str, adapter: str,
         verdict: str, statement: str, campaign: str) -> Method:
    """A row; each part is named by its attribute in its family's module (`home`): a reader who
    knows a method's family finds every part under that name, so there is no other form."""
    given = {"options": options, "adapter": adapter, "verdict": verdict, "statement": statement,
             "campaign": campaign}
    full = {part: f"{home(part, family)}:{ref}" for part, ref in given.items()}
    return Method(name, family, kinds, summary, **full)


_CONTROLLER_OR_OBSERVER = ("controller", "observer")

#: The design methods, in the order the documentation lists them.
TABLE: tuple[Method, ...] = (
    _row("linearize", "model", ("model",),
         "linearisation at the operating point and exact ZOH discretisation",
         options="LinearizeOptions", adapter="LINEARIZE",
         verdict="linearize_verdict", statement="linearize_statement",
         campaign="linearize_run"),
    _row("pole_placement", "placement", _CONTROLLER_OR_OBSERVER,
         "exact pole placement (Tits-Yang place, Ackermann acker), optional integral action",
         options="PolePlacementOptions", adapter="POLE_PLACEMENT",
         verdict="pole_placement_verdict", statement="pole_placement_statement",
         campaign="placement_run"),
    _row("lmi_placement", "placement", _CONTROLLER_OR_OBSERVER,
         "pole placement in an LMI region (cvxpy + Clarabel), optional integral action",
         options="LmiPlacementOptions", adapter="LMI_PLACEMENT",
         verdict="lmi_placement_verdict", statement="lmi_placement_statement",
         campaign="placement_run"),
    _row("canonical_observer", "placement", ("observer",),
         "Luenberger observer by the observable canonical form",
         options="CanonicalObserverOptions", adapter="CANONICAL_OBSERVER",
         verdict="canonical_observer_verdict", statement="canonical_observer_statement",
         campaign="canonical_observer_run"),
    _row("ts_observer", "observer_lmi", ("observer",),
         "Takagi-Sugeno multiple-model observer by an LMI",
         options="TsObserverOptions", adapter="TS_OBSERVER",
         verdict="ts_observer_verdict", statement="ts_observer_statement",
         campaign="ts_observer_run"),
    _row("feedback_linearization", "laws", ("controller",),
         "exact input-output feedback linearisation with decoupling",
         options="FeedbackLinearizationOptions", adapter="FEEDBACK_LINEARIZATION",
         verdict="feedback_linearization_verdict", statement="feedback_linearization_statement",
         campaign="feedback_linearization_loop"),
    _row("integral_tracking", "laws", ("controller",),
         "sampled state feedback with integral action, saturation and anti-windup",
         options="IntegralTrackingOptions", adapter="INTEGRAL_TRACKING",
         verdict="integral_tracking_verdict", statement="integral_tracking_statement",
         campaign="integral_tracking_loop"),
    _row("inverse_dynamics", "laws", ("controller",),
         "estimator-based inverse-dynamics control, ISE-tuned",
         options="InverseDynamicsOptions", adapter="INVERSE_DYNAMICS",
         verdict="inverse_dynamics_verdict", statement="inverse_dynamics_statement",
         campaign="inverse_dynamics_loop"),
    _row("decentralized_kalman", "decentralized", ("estimator",),
         "decentralised Kalman gains under a sparsity pattern (one-step or finite horizon)",
         options="DecentralizedKalmanOptions", adapter="DECENTRALIZED_KALMAN",
         verdict="decentralized_kalman_verdict", statement="decentralized_kalman_statement",
         campaign="decentralized_kalman_run"),
    _row("kalman", "estimators", ("estimator",),
         "Kalman filter on the ZOH linearisation",
         options="KalmanOptions", adapter="KALMAN",
         verdict="kalman_verdict", statement="kalman_statement",
         campaign="kalman_run"),
    _row("ekf", "estimators", ("estimator",),
         "extended Kalman filter on the nonlinear model",
         options="EkfOptions", adapter="EKF",
         verdict="ekf_verdict", statement="ekf_statement",
         campaign="ekf_run"),
    _row("ukf", "estimators", ("estimator",),
         "unscented Kalman filter",
         options="UkfOptions", adapter="UKF",
         verdict="ukf_verdict", statement="ukf_statement",
         campaign="ukf_run"),
    _row("adaptive_kalman", "estimators", ("estimator",),
         "Kalman filter with innovation-window adaptive Q",
         options="AdaptiveKalmanOptions", adapter="ADAPTIVE_KALMAN",
         verdict="adaptive_kalman_verdict", statement="adaptive_kalman_statement",
         campaign="adaptive_kalman_run"),
    _row("adaptive_scaling_kalman", "estimators", ("estimator",),
         "Kalman filter with adaptive process-noise scaling",
         options="AdaptiveScalingKalmanOptions", adapter="ADAPTIVE_SCALING_KALMAN",
         verdict="adaptive_scaling_kalman_verdict", statement="adaptive_scaling_kalman_statement",
         campaign="adaptive_scaling_kalman_run"),
    _row("consensus_filter", "estimators", ("estimator",),
         "information-form consensus filter over redundant sensors",
         options="ConsensusFilterOptions", adapter="CONSENSUS_FILTER",
         verdict="consensus_filter_verdict", statement="consensus_filter_statement",
         campaign="consensus_filter_run"),
    _row("luenberger", "estimators", ("observer",),
         "discrete or continuous Luenberger observer",
         options="LuenbergerOptions", adapter="LUENBERGER",
         verdict="luenberger_verdict", statement="luenberger_statement",
         campaign="luenberger_run"),
    _row("narx", "estimators", ("estimator",),
         "NARX neural estimator trained on EKF data",
         options="NarxOptions", adapter="NARX",
         verdict="narx_verdict", statement="narx_statement",
         campaign="narx_run"),
    _row("fault_detection", "fault", ("detector",),
         "observer residual with a derived fault-detection threshold",
         options="FaultDetectionOptions", adapter="FAULT_DETECTION",
         verdict="fault_detection_verdict", statement="fault_detection_statement",
         campaign="fault_detection_run"),
    _row("robust_state_feedback", "robust", ("controller",),
         "one state feedback for every vertex of a parameter box: LMI region, optional H-infinity "
         "bound, saturation-aware invariant ellipsoid, optional integral action",
         options="RobustStateFeedbackOptions", adapter="ROBUST_STATE_FEEDBACK",
         verdict="robust_state_feedback_verdict", statement="robust_state_feedback_statement",
         campaign="robust_state_feedback_run"),
    _row("robust_observer", "robust", ("observer",),
         "one observer gain for every vertex of a parameter box: LMI region, optional H-infinity bound",
         options="RobustObserverOptions", adapter="ROBUST_OBSERVER",
         verdict="robust_observer_verdict", statement="robust_observer_statement",
         campaign="robust_observer_run"),
    _row("ts_state_feedback", "takagi_sugeno", ("controller",),
         "Takagi-Sugeno PDC state feedback by LMIs (vertex/Tuan relaxations), certified region",
         options="TsStateFeedbackOptions", adapter="TS_STATE_FEEDBACK",
         verdict="ts_control_verdict", statement="ts_state_feedback_statement",
         campaign="ts_control_run"),
    _row("ts_output_feedback", "takagi_sugeno", ("controller",),
         "Takagi-Sugeno PDC on a TS observer (measured or estimated premises), certified region",
         options="TsOutputFeedbackOptions", adapter="TS_OUTPUT_FEEDBACK",
         verdict="ts_control_verdict", statement="ts_output_feedback_statement",
         campaign="ts_control_run"),
    _row("h2_state_feedback", "synthesis", ("controller",),
         "state feedback minimising the H2 norm (Riccati = LQR, or LMI)",
         options="H2StateFeedbackOptions", adapter="H2_STATE_FEEDBACK",
         verdict="synthesis_verdict", statement="h2_state_feedback_statement",
         campaign="synthesis_run"),
    _row("h2_observer", "synthesis", ("observer",),
         "observer minimising the H2 norm (Riccati = steady Kalman, or LMI)",
         options="H2ObserverOptions", adapter="H2_OBSERVER",
         verdict="synthesis_verdict", statement="h2_observer_statement",
         campaign="synthesis_run"),
    _row("hinf_state_feedback", "synthesis", ("controller",),
         "state feedback minimising the H-infinity norm (Riccati gamma iteration, or LMI)",
         options="HinfStateFeedbackOptions", adapter="HINF_STATE_FEEDBACK",
         verdict="synthesis_verdict", statement="hinf_state_feedback_statement",
         campaign="synthesis_run"),
    _row("hinf_observer", "synthesis", ("observer",),
         "observer minimising the H-infinity norm of the error (Riccati gamma iteration, or LMI)",
         options="HinfObserverOptions", adapter="HINF_OBSERVER",
         verdict="synthesis_verdict", statement="hinf_observer_statement",
         campaign="synthesis_run"),
    _row("multiobjective", "synthesis", _CONTROLLER_OR_OBSERVER,
         "H2/H-infinity objective and bounds with an LMI pole region, common Lyapunov matrix",
         options="MultiobjectiveOptions", adapter="MULTIOBJECTIVE",
         verdict="synthesis_verdict", statement="multiobjective_statement",
         campaign="synthesis_run"),
    _row("fit", "fit", ("model",),
         "grey-box fit of free plant parameters and initial states to logged data (CasADi + "
         "IPOPT, multiple shooting)",
         options="FitOptions", adapter="FIT",
         verdict="fit_verdict", statement="fit_statement",
         campaign="fit_run"),
)


def _check_table(table: tuple[Method, ...]) -> None:
    """Raise if a row is incomplete or names a part malformed; runs at import (names only: no
    part is imported, `resolve_table` does that)."""
    seen: set[str] = set()
    for row in table:
        problems = []
        if row.name in seen:
            problems.append("listed twice")
        seen.add(row.name)
        if not row.kinds or any(k not in KINDS for k in row.kinds):
            problems.append(f"kinds {row.kinds} not among {KINDS}")
        if row.family not in FAMILIES:
            problems.append(f"family {row.family!r} not among {FAMILIES}")
        for part, ref in row.refs().items():
            if isinstance(ref, str) and not _REF.match(ref):
                problems.append(f"{part} {ref!r} is not '<module>:<attribute>'")
            elif not isinstance(ref, str) and not callable(ref):
                problems.append(f"no {part}")
        if not row.summary:
            problems.append("no summary")
        if problems:
            raise TypeError(f"method table row {row.name!r}: " + "; ".join(problems))


def resolve_table(table: tuple[Method, ...] | None = None) -> None:
    """Import every part of every row and check it: the adapter and the Options are the
    method's, the verdict, statement and campaign runner are callables.

    Parameters
    ----------
    table : tuple of Method, optional
        Default `TABLE`.

    Raises
    ------
    TypeError
        Naming the row and what is wrong.
    ImportError, AttributeError
        A part names a module or attribute that does not exist.
    """
    from tanksynth.spec.method_options import MethodOptions

    for row in TABLE if table is None else table:
        problems = []
        opts = row.options
        if not (isinstance(opts, type) and issubclass(opts, MethodOptions)):
            problems.append("no Options class")
        elif opts.method_name != row.name or row.adapter.name != row.name:
            problems.append(f"adapter is for method {row.adapter.name!r}, options for "
                            f"{opts.method_name!r}")
        elif row.adapter.options is not opts:
            problems.append(f"options {opts.__name__} are not the adapter's "
                            f"({row.adapter.options.__name__})")
        if not callable(getattr(row.adapter, "run", None)):
            problems.append("no design function")
        for part in ("verdict", "statement", "campaign"):
            if not callable(getattr(row, part)):
                problems.append(f"no {part}")
        if problems:
            raise TypeError(f"method table row {row.name!r}: " + "; ".join(problems))


_check_table(TABLE)


@dataclass(frozen=True)
class Alias:
    """A name a control engineer types for a method of the table (``lqr``, ``dlqr``, ``lqe``).

    A spec's ``method = "<alias>"`` runs `method` with `options` set (a spec that sets one of
    them to another value is refused); the artefact records the real method as its ``method``
    and the alias as ``diagnostics["method_alias"]``.

    Attributes
    ----------
    name : str
        The alias.
    method : str
        The method it runs (a row of `TABLE`).
    options : mapping
        The options the alias fixes, in the spec's TOML form (``{"time_domain": "continuous"}``).
    meaning : str
        One line: the textbook (python-control) function it stands for.
    """

    name: str
    method: str
    options: Mapping[str, Any]
    meaning: str

    def describe(self) -> str:
        """``"alias of h2_state_feedback with time_domain = \"continuous\": ..."`` (one line)."""
        fixed = ", ".join(f"{k} = {_toml_value(v)}" for k, v in self.options.items())
        return f"alias of {self.method}" + (f" with {fixed}" if fixed else "") + f": {self.meaning}"


def _toml_value(value: Any) -> str:
    return f'"{value}"' if isinstance(value, str) else repr(value)


#: Textbook names of methods: alias -> `Alias` (never a method's own name).
ALIASES: Mapping[str, Alias] = MappingProxyType({a.name: a for a in (
    Alias("lqr", "h2_state_feedback", MappingProxyType({"time_domain": "continuous"}),
          "continuous-time LQR gain K of u = -K x minimising the integral of x'Qx + u'Ru "
          "(python-control lqr; Riccati route)"),
    Alias("dlqr", "h2_state_feedback", MappingProxyType({"time_domain": "discrete"}),
          "discrete-time LQR gain K on the ZOH model at [sampling] ts, minimising the sum of "
          "x'Qx + u'Ru (python-control dlqr)"),
    Alias("lqe", "h2_observer", MappingProxyType({"time_domain": "continuous"}),
          "continuous-time steady-state Kalman (Kalman-Bucy) observer gain L "
          "(python-control lqe with G = Bw, QN = diag(disturbance_std^2), "
          "RN = diag(measurement_std^2))"),
    Alias("dlqe", "h2_observer", MappingProxyType({"time_domain": "discrete"}),
          "discrete-time steady-state Kalman gain L of the predictor x_hat+ = Ad x_hat + Bd u + "
          "L (y - C x_hat) (python-control dlqe)"),
)})


def _check_aliases(aliases: Mapping[str, Alias], table: tuple[Method, ...]) -> None:
    """Raise if an alias shadows a method or names one that does not exist (runs at import)."""
    names = {row.name for row in table}
    for alias in aliases.values():
        if alias.name in names or alias.method not in names:
            raise TypeError(f"method alias {alias.name!r}: "
                            + ("shadows a method" if alias.name in names else
                               f"names no method ({alias.method!r})"))


_check_aliases(ALIASES, TABLE)


class _View(Mapping[str, Any]):
    """A read-only map method name -> one part of its row, imported on first lookup."""

    def __init__(self, part: str | None) -> None:
        self._part = part

    def __getitem__(self, name: str) -> Any:
        row = METHODS[name]
        return row if self._part is None else getattr(row, self._part)

    def __iter__(self) -> Iterator[str]:
        return iter(METHODS)

    def __len__(self) -> int:
        return len(METHODS)

    def __repr__(self) -> str:
        return f"<method table view {self._part or 'rows'}: {', '.join(METHODS)}>"


#: Rows by method name.
METHODS: Mapping[str, Method] = MappingProxyType({row.name: row for row in TABLE})
#: Verdict of each method (what `verify_directory` runs); imported on lookup.
VERDICTS: Mapping[str, VerdictFn] = _View("verdict")
#: Campaign runner of each method (what `campaign_tasks` runs for its artefacts); imported on lookup.
RUNNERS: Mapping[str, Callable[..., Any]] = _View("campaign")
#: Problem statement of each method (report); imported on lookup.
STATEMENTS: Mapping[str, Callable[[Mapping[str, Any]], Any]] = _View("statement")
#: Design adapters by name; imported on lookup (the spec parser validates with the rows'
#: `Method.validate`, which imports only the Options).
ADAPTERS: Mapping[str, DesignMethod] = _View("adapter")


class _Verifiable:
    """What the verify runner reads of a row (``verdict``; ``adapter.validate`` for the spec)
    without importing the design code: the row validates with its Options."""

    __slots__ = ("_row",)

    def __init__(self, row: Method) -> None:
        self._row = row

    @property
    def verdict(self) -> Any:
        return self._row.verdict

    @property
    def adapter(self) -> Method:
        return self._row


def _verifiable() -> Mapping[str, VerifiableMethod]:
    # cast: the rows' parts are read-only properties (imported on first read); the runner only
    # reads them, though its Protocol declares them as plain (settable) attributes
    return cast("Mapping[str, VerifiableMethod]",
                _with_aliases({name: _Verifiable(row) for name, row in METHODS.items()}))


class _AliasRow:
    """What the spec parser validates an alias's ``[[design]]`` table with: the real row's
    Options, with the alias's fixed options set (`Alias`)."""

    __slots__ = ("alias", "row")

    def __init__(self, alias: Alias, row: Method | _Verifiable) -> None:
        self.alias = alias
        self.row = row

    @property
    def name(self) -> str:
        """The real method's name (what the `DesignSpec` records)."""
        return self.alias.method

    @property
    def adapter(self) -> _AliasRow:  # the verify runner validates with ``row.adapter``
        return self

    @property
    def verdict(self) -> Any:
        return self.row.verdict

    def fixed_options(self, options: Mapping[str, Any], key: str) -> dict[str, Any]:
        """``options`` with the alias's fixed ones added; `SpecError` for a conflicting one."""
        from tanksynth.errors import SpecError

        for opt, value in self.alias.options.items():
            if opt in options and options[opt] != value:
                raise SpecError(f"method {self.alias.name!r} ({self.alias.describe()}) sets "
                                f"{opt} = {_toml_value(value)}; remove {opt} or use method = "
                                f"{self.alias.method!r}", key=f"{key}.{opt}")
        return {**options, **self.alias.options}

    def validate(self, options: Mapping[str, Any], key: str, plant: Plant,
                 ts: float | None) -> MethodOptions:
        """See `Method.validate`, with the alias's fixed options."""
        validator = self.row if isinstance(self.row, Method) else self.row.adapter
        return validator.validate(self.fixed_options(options, key), key, plant, ts)


def _with_aliases(rows: Mapping[str, Any]) -> dict[str, Any]:
    """``rows`` (method name -> row) and every alias validating as its method's row."""
    return {**rows, **{a.name: _AliasRow(a, rows[a.method]) for a in ALIASES.values()}}


def method(name: str) -> Method:
    """The row of a method, or of the method an alias (`ALIASES`) runs; `SpecError` (listing the
    methods and aliases) for an unknown name.

    Parameters
    ----------
    name : str
        A spec's ``method`` value.
    """
    from tanksynth.errors import SpecError

    if name in ALIASES:
        return METHODS[ALIASES[name].method]
    if name not in METHODS:
        from tanksynth.spec.options import unknown_word_hint

        raise SpecError(f"unknown method {name!r}"
                        + unknown_word_hint(name, [*METHODS, *ALIASES]))
    return METHODS[name]


def load_spec(path: str | Path) -> Spec:
    """Read and validate a TOML spec, every design's options included (see `tanksynth.spec`).

    Parameters
    ----------
    path : str or Path
        The TOML spec.
    """
    from tanksynth.spec import load_spec as _load_spec

    return _load_spec(path, methods=_with_aliases(METHODS))


def parse_spec(table: Mapping[str, Any], source: str | None = None, sha256: str = "") -> Spec:
    """Validate a spec given as a mapping, every design's options included.

    Parameters
    ----------
    table : mapping
        The spec as parsed TOML.
    source : str, optional
        Where it came from (for messages).
    sha256 : str
        sha256 of the spec text (provenance).
    """
    from tanksynth.spec import parse_spec as _parse_spec

    return _parse_spec(table, source, sha256, methods=_with_aliases(METHODS))


def parse_spec_text(data: bytes | str, source: str | None = None) -> Spec:
    """Validate a spec given as TOML text, every design's options included.

    Parameters
    ----------
    data : bytes or str
        TOML text.
    source : str, optional
        Where it came from (for messages).
    """
    from tanksynth.spec import parse_spec_text as _parse_spec_text

    return _parse_spec_text(data, source, methods=_with_aliases(METHODS))


def design(spec: Spec, entry: DesignSpec) -> DesignResult:
    """Design one ``[[design]]`` entry of a spec with its method's row.

    Parameters
    ----------
    spec : Spec
        The validated spec.
    entry : DesignSpec
        One of its ``[[design]]`` entries.
    """
    return method(entry.method).design(spec, entry)


def verify_directory(directory: str | Path, scheduler: str | None = None,
                     progress: Callable[[int, int], None] | None = None,
                     connect_timeout: float = 10.0,
                     started: Callable[[int, int, str, str], None] | None = None,
                     **cluster: Any) -> list[Verdict]:
    """Run the verdict of every artefact of a result directory (see `tanksynth.verify.runner`).

    Parameters
    ----------
    directory : str or Path
        A result directory.
    scheduler : str, optional
        Dask scheduler address (``tcp://host:port``); default this machine.
    progress : callable, optional
        ``progress(done, total)`` after each artefact.
    connect_timeout : float
        Seconds to wait for the scheduler (s).
    started : callable, optional
        ``started(done, total, name, method)`` as an artefact's verdict starts.
    **cluster
        ``worker_timeout`` and ``waiting`` of `tanksynth.verify.runner.verify_directory`.
    """
    from tanksynth.verify.runner import verify_directory as _verify_directory

    return _verify_directory(directory, _verifiable(), scheduler=scheduler, progress=progress,
                             connect_timeout=connect_timeout, started=started, **cluster)


def load_directory(directory: str | Path) -> tuple[Spec, list[tuple[Path, dict]]]:
    """Read a result directory's spec and artefacts, refusing bad ones (see
    `tanksynth.verify.runner.load_directory`); imports no design code.

    Parameters
    ----------
    directory : str or Path
        A result directory.

    Returns
    -------
    spec : Spec
    artefacts : list of (Path, dict)
        Each artefact's path and document (gains as arrays), sorted by name.
    """
    from tanksynth.verify.runner import load_directory as _load_directory

    return _load_directory(directory, _verifiable())


def write_report(directory: str | Path, pdf: bool = False, timeout: float = 180.0, *,
                 drawn: Mapping[str, Any] | None = None) -> Any:
    """Write the design report of a result directory (see `tanksynth.reports.write_report`).

    Parameters
    ----------
    directory : str or Path
        A result directory.
    pdf : bool
        Also compile ``report.pdf`` (latexmk/pdflatex).
    timeout : float
        LaTeX time limit (s).
    drawn : mapping, optional
        Figures drawn ahead from the directory's current files (file stem -> figure).
    """
    from tanksynth.reports import write_report as _write_report

    return _write_report(directory, pdf, timeout, statements=STATEMENTS, drawn=drawn)
