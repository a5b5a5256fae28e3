"""The one table of design methods: what each spec method is, designs, verifies and states.

Every ``method = "..."`` a spec may name is one row of `TABLE`; nothing is
registered on import and nothing else maps method names to behaviour. A row
holds:

``kind``
    ``"model"``, ``"controller"``, ``"observer"``, ``"estimator"`` or
    ``"detector"`` (``pole_placement`` and ``lmi_placement`` are controllers
    or observers, by their ``target`` option: both kinds are listed).
``adapter``
    The design adapter (`tanksynth.design.DesignMethod`): the method's
    Options dataclass (``Method.options``: options, defaults, units,
    validation at parse time) and ``run(spec, design) -> DesignResult``.
``verdict``
    ``verdict(doc, spec) -> list[Check]`` of `tanksynth.verify`: re-derives what
    it checks from the artefact and simulates it on the nonlinear plant.
``campaign``
    ``runner(doc, spec) -> CampaignRun``: what a Monte-Carlo campaign runs for
    the artefact (a closed loop, an estimator on the noisy measurements, a
    residual test or a model's prediction; `tanksynth.verify.campaign`).
``statement``
    ``statement(diagnostics) -> Tex``: the problem solved, for the report.

The table is complete or the package does not import: `_check_table` runs at
import and raises if a row lacks a part its kind needs.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any, Callable, Mapping

from tanksynth.design import control_methods, convex_methods, decentralized_methods, model_methods
from tanksynth.design import estimator_methods as est
from tanksynth.design import robust_methods
from tanksynth.design import ts_control_methods
from tanksynth.design import synthesis_methods as syn
from tanksynth.design.audit import designed
from tanksynth.design.result import DesignMethod, DesignResult
from tanksynth.reports import statements as st
from tanksynth.spec import DesignSpec, Spec, load_spec as _load_spec, parse_spec as _parse_spec
from tanksynth.spec import parse_spec_text as _parse_spec_text
from tanksynth.spec.method_options import MethodOptions
from tanksynth.verify import campaign, decentralized, estimators, fault, laws, model, narx, placement
from tanksynth.verify import robust as robust_verdicts
from tanksynth.verify import robust_runs
from tanksynth.verify import ts_observer
from tanksynth.verify import ts_control
from tanksynth.verify import synthesis as syn_verdict
from tanksynth.verify.runner import Verdict, VerdictFn
from tanksynth.verify.runner import verify_directory as _verify_directory

__all__ = ["KINDS", "Method", "TABLE", "METHODS", "VERDICTS", "RUNNERS", "STATEMENTS",
           "method", "design", "load_spec", "parse_spec", "parse_spec_text", "verify_directory",
           "write_report"]

#: What a design method produces.
KINDS = ("model", "controller", "observer", "estimator", "detector")


@dataclass(frozen=True)
class Method:
    """One row of the method table.

    Attributes
    ----------
    name : str
        The spec's ``method`` value.
    kinds : tuple of str
        Some of `KINDS`.
    summary : str
        One line: what the method designs.
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
    kinds: tuple[str, ...]
    summary: str
    adapter: DesignMethod
    verdict: VerdictFn
    statement: Callable[[Mapping[str, Any]], Any]
    campaign: Callable[..., Any]

    @property
    def options(self) -> type[MethodOptions]:
        """The method's Options dataclass (`tanksynth.spec.method_options`)."""
        return self.adapter.options

    def design(self, spec: Spec, design: DesignSpec) -> DesignResult:
        """Run the design of one ``[[design]]`` entry of ``spec``.

        Every `DesignWarning` (operating point, actuator range, implausible
        parameters, unstable result, the method's own) is issued and listed in
        ``diagnostics["warnings"]`` (`tanksynth.design.audit.designed`).

        Parameters
        ----------
        spec : Spec
            The validated spec.
        design : DesignSpec
            One of its ``[[design]]`` entries (of this method).
        """
        return designed(self.adapter.run, spec, design)


def _row(name: str, kinds: tuple[str, ...], summary: str, adapter: DesignMethod, verdict: VerdictFn,
         statement: Callable[[Mapping[str, Any]], Any], campaign: Callable[..., Any]) -> Method:
    return Method(name, kinds, summary, adapter, verdict, statement, campaign)


_CONTROLLER_OR_OBSERVER = ("controller", "observer")

#: The design methods, in the order the documentation lists them.
TABLE: tuple[Method, ...] = (
    _row("linearize", ("model",), "linearisation at the operating point and exact ZOH discretisation",
         model_methods.LINEARIZE, model.linearize_verdict, st.linearize_statement,
         campaign.linearize_run),
    _row("pole_placement", _CONTROLLER_OR_OBSERVER,
         "exact pole placement (python-control place/acker), optional integral action",
         convex_methods.POLE_PLACEMENT, placement.pole_placement_verdict,
         st.pole_placement_statement, campaign.placement_run),
    _row("lmi_placement", _CONTROLLER_OR_OBSERVER,
         "pole placement in an LMI region (cvxpy + Clarabel), optional integral action",
         convex_methods.LMI_PLACEMENT, placement.lmi_placement_verdict, st.lmi_placement_statement,
         campaign.placement_run),
    _row("canonical_observer", ("observer",), "Luenberger observer by the observable canonical form",
         convex_methods.CANONICAL_OBSERVER, placement.canonical_observer_verdict,
         st.canonical_observer_statement, campaign.canonical_observer_run),
    _row("ts_observer", ("observer",), "Takagi-Sugeno multiple-model observer by an LMI",
         convex_methods.TS_OBSERVER, ts_observer.ts_observer_verdict, st.ts_observer_statement,
         campaign.ts_observer_run),
    _row("feedback_linearization", ("controller",),
         "exact input-output feedback linearisation with decoupling",
         control_methods.FEEDBACK_LINEARIZATION, laws.feedback_linearization_verdict,
         st.feedback_linearization_statement, campaign.feedback_linearization_loop),
    _row("integral_tracking", ("controller",),
         "sampled state feedback with integral action, saturation and anti-windup",
         control_methods.INTEGRAL_TRACKING, laws.integral_tracking_verdict,
         st.integral_tracking_statement, campaign.integral_tracking_loop),
    _row("inverse_dynamics", ("controller",), "estimator-based inverse-dynamics control, ISE-tuned",
         control_methods.INVERSE_DYNAMICS, laws.inverse_dynamics_verdict,
         st.inverse_dynamics_statement, campaign.inverse_dynamics_loop),
    _row("decentralized_kalman", ("estimator",),
         "decentralised Kalman gains under a sparsity pattern (one-step or finite horizon)",
         decentralized_methods.DECENTRALIZED_KALMAN, decentralized.decentralized_kalman_verdict,
         st.decentralized_kalman_statement, campaign.decentralized_kalman_run),
    _row("kalman", ("estimator",), "Kalman filter on the ZOH linearisation",
         est.KALMAN, estimators.kalman_verdict, st.kalman_statement, campaign.kalman_run),
    _row("ekf", ("estimator",), "extended Kalman filter on the nonlinear model",
         est.EKF, estimators.ekf_verdict, st.ekf_statement, campaign.ekf_run),
    _row("ukf", ("estimator",), "unscented Kalman filter", est.UKF, estimators.ukf_verdict,
         st.ukf_statement, campaign.ukf_run),
    _row("adaptive_kalman", ("estimator",), "Kalman filter with innovation-window adaptive Q",
         est.ADAPTIVE_KALMAN, estimators.adaptive_kalman_verdict, st.adaptive_kalman_statement,
         campaign.adaptive_kalman_run),
    _row("adaptive_scaling_kalman", ("estimator",), "Kalman filter with adaptive process-noise scaling",
         est.ADAPTIVE_SCALING_KALMAN, estimators.adaptive_scaling_kalman_verdict,
         st.adaptive_scaling_kalman_statement, campaign.adaptive_scaling_kalman_run),
    _row("consensus_filter", ("estimator",), "information-form consensus filter over redundant sensors",
         est.CONSENSUS_FILTER, estimators.consensus_filter_verdict, st.consensus_filter_statement,
         campaign.consensus_filter_run),
    _row("luenberger", ("observer",), "discrete or continuous Luenberger observer",
         est.LUENBERGER, estimators.luenberger_verdict, st.luenberger_statement,
         campaign.luenberger_run),
    _row("narx", ("estimator",), "NARX neural estimator trained on EKF data",
         est.NARX, narx.narx_verdict, st.narx_statement, campaign.narx_run),
    _row("fault_detection", ("detector",), "observer residual with a derived fault-detection threshold",
         est.FAULT_DETECTION, fault.fault_detection_verdict, st.fault_detection_statement,
         campaign.fault_detection_run),
    _row("robust_state_feedback", ("controller",),
         "one state feedback for every vertex of a parameter box: LMI region, optional H-infinity "
         "bound, saturation-aware invariant ellipsoid, optional integral action",
         robust_methods.ROBUST_STATE_FEEDBACK, robust_verdicts.robust_state_feedback_verdict,
         st.robust_state_feedback_statement, robust_runs.robust_state_feedback_run),
    _row("robust_observer", ("observer",),
         "one observer gain for every vertex of a parameter box: LMI region, optional H-infinity bound",
         robust_methods.ROBUST_OBSERVER, robust_verdicts.robust_observer_verdict,
         st.robust_observer_statement, robust_runs.robust_observer_run),
    _row("ts_state_feedback", ("controller",),
         "Takagi-Sugeno PDC state feedback by LMIs (vertex/Tuan relaxations), certified region",
         ts_control_methods.TS_STATE_FEEDBACK, ts_control.ts_control_verdict,
         st.ts_state_feedback_statement, ts_control.ts_control_run),
    _row("ts_output_feedback", ("controller",),
         "Takagi-Sugeno PDC on a TS observer (measured or estimated premises), certified region",
         ts_control_methods.TS_OUTPUT_FEEDBACK, ts_control.ts_control_verdict,
         st.ts_output_feedback_statement, ts_control.ts_control_run),
    _row("h2_state_feedback", ("controller",), "state feedback minimising the H2 norm (Riccati = LQR, or LMI)",
         syn.H2_STATE_FEEDBACK, syn_verdict.synthesis_verdict, st.h2_state_feedback_statement,
         syn_verdict.synthesis_run),
    _row("h2_observer", ("observer",), "observer minimising the H2 norm (Riccati = steady Kalman, or LMI)",
         syn.H2_OBSERVER, syn_verdict.synthesis_verdict, st.h2_observer_statement,
         syn_verdict.synthesis_run),
    _row("hinf_state_feedback", ("controller",),
         "state feedback minimising the H-infinity norm (Riccati gamma iteration, or LMI)",
         syn.HINF_STATE_FEEDBACK, syn_verdict.synthesis_verdict, st.hinf_state_feedback_statement,
         syn_verdict.synthesis_run),
    _row("hinf_observer", ("observer",),
         "observer minimising the H-infinity norm of the error (Riccati gamma iteration, or LMI)",
         syn.HINF_OBSERVER, syn_verdict.synthesis_verdict, st.hinf_observer_statement,
         syn_verdict.synthesis_run),
    _row("multiobjective", _CONTROLLER_OR_OBSERVER,
         "H2/H-infinity objective and bounds with an LMI pole region, common Lyapunov matrix",
         syn.MULTIOBJECTIVE, syn_verdict.synthesis_verdict, st.multiobjective_statement,
         syn_verdict.synthesis_run),
)


def _check_table(table: tuple[Method, ...]) -> None:
    """Raise if a row is incomplete; runs at import, so an incomplete table cannot be used."""
    seen: set[str] = set()
    for row in table:
        problems = []
        if row.name in seen:
            problems.append("listed twice")
        seen.add(row.name)
        if not row.kinds or any(k not in KINDS for k in row.kinds):
            problems.append(f"kinds {row.kinds} not among {KINDS}")
        if row.adapter.name != row.name or row.options.method_name != row.name:
            problems.append(f"adapter is for method {row.adapter.name!r}, options for "
                            f"{row.options.method_name!r}")
        if not (isinstance(row.options, type) and issubclass(row.options, MethodOptions)):
            problems.append("no Options class")
        for part in ("verdict", "statement"):
            if not callable(getattr(row, part)):
                problems.append(f"no {part}")
        if not callable(row.campaign):
            problems.append("no campaign runner")
        if not row.summary:
            problems.append("no summary")
        if problems:
            raise TypeError(f"method table row {row.name!r}: " + "; ".join(problems))


_check_table(TABLE)

#: Rows by method name.
METHODS: Mapping[str, Method] = MappingProxyType({row.name: row for row in TABLE})
#: Verdict of each method (what `verify_directory` runs).
VERDICTS: Mapping[str, VerdictFn] = MappingProxyType({row.name: row.verdict for row in TABLE})
#: Campaign runner of each method (what `campaign_tasks` runs for its artefacts).
RUNNERS: Mapping[str, Callable[..., Any]] = MappingProxyType({row.name: row.campaign for row in TABLE})
#: Problem statement of each method (report).
STATEMENTS: Mapping[str, Callable[[Mapping[str, Any]], Any]] = MappingProxyType(
    {row.name: row.statement for row in TABLE})
#: Design adapters by name (``adapter.validate`` gives the Options the spec parser stores).
ADAPTERS: Mapping[str, DesignMethod] = MappingProxyType({row.name: row.adapter for row in TABLE})


def method(name: str) -> Method:
    """The row of a method; `SpecError` (listing the methods) for an unknown name.

    Parameters
    ----------
    name : str
        A spec's ``method`` value.
    """
    from tanksynth.errors import SpecError

    if name not in METHODS:
        from tanksynth.spec.options import unknown_word_hint

        raise SpecError(f"unknown method {name!r}" + unknown_word_hint(name, list(METHODS)))
    return METHODS[name]


def load_spec(path: str | Path) -> Spec:
    """Read and validate a TOML spec, every design's options included (see `tanksynth.spec`).

    Parameters
    ----------
    path : str or Path
        The TOML spec.
    """
    return _load_spec(path, methods=ADAPTERS)


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
    return _parse_spec(table, source, sha256, methods=ADAPTERS)


def parse_spec_text(data: bytes | str, source: str | None = None) -> Spec:
    """Validate a spec given as TOML text, every design's options included.

    Parameters
    ----------
    data : bytes or str
        TOML text.
    source : str, optional
        Where it came from (for messages).
    """
    return _parse_spec_text(data, source, methods=ADAPTERS)


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
                     started: Callable[[int, int, str, str], None] | None = None) -> list[Verdict]:
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
    """
    return _verify_directory(directory, METHODS, scheduler=scheduler, progress=progress,
                             connect_timeout=connect_timeout, started=started)


def write_report(directory: str | Path, pdf: bool = False, timeout: float = 180.0) -> Any:
    """Write the design report of a result directory (see `tanksynth.reports.write_report`).

    Parameters
    ----------
    directory : str or Path
        A result directory.
    pdf : bool
        Also compile ``report.pdf`` (latexmk/pdflatex).
    timeout : float
        LaTeX time limit (s).
    """
    from tanksynth.reports import write_report as _write_report

    return _write_report(directory, pdf, timeout, statements=STATEMENTS)
