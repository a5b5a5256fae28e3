"""Options of ``ts_state_feedback`` and ``ts_output_feedback`` (Takagi-Sugeno PDC controllers)."""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

from tanksynth.spec.method_options.base import MethodOptions, OptionReader, option
from tanksynth.spec.method_options.placement import LMI_SOLVERS
from tanksynth.errors import SpecError
from tanksynth.spec.memory import ConicSize, nonlinear_atoms
from tanksynth.spec.options import (parse_bool, parse_box, parse_choice, parse_integer, parse_number,
                                     parse_vector)

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["PDC_RELAXATIONS", "TsStateFeedbackOptions", "TsOutputFeedbackOptions"]

#: Values of the ``relaxation`` option.
PDC_RELAXATIONS = ("auto", "vertex", "tuan")


@dataclass(frozen=True, eq=False)
class TsStateFeedbackOptions(MethodOptions):
    """Options of ``ts_state_feedback``: PDC ``u = u0 - sum_i mu_i(x) K_i (x - x0)`` on the exact
    TS model of the deviations from the operating point, continuous time, common quadratic
    Lyapunov function, certified region.

    The design is continuous-time even when the spec has ``[sampling] ts``: the LMIs certify
    ``dV/dt <= -2 alpha V`` for the law acting continuously, and ``ts`` changes no gain (the
    gains are not discretised, no sample-and-hold margin is in the certificate). The verdict's
    region simulations (``region_simulation``) hold the law over a period of its own, ``min(1 s,
    0.05 / max |eig(A_i - B K_j)|)``, short enough to resolve the closed loop whatever the
    spec's ``ts``; the campaign runs the law at the spec's ``ts`` (1 s without one), each input
    held over a period (zero-order hold), so a ``ts`` that is long against the closed loop
    degrades the campaign's runs, not the certificate.

    Attributes
    ----------
    relaxation : str
        LMI conditions: ``"vertex"`` (basic: ``Y_ii < 0``, ``Y_ij + Y_ji < 0``),
        ``"tuan"`` (Tuan et al. 2001) or ``"auto"`` (default: vertex, then
        tuan if vertex is infeasible; the one used is reported).
    decay_rate : float
        Decay rate ``alpha`` with ``dV/dt <= -2 alpha V`` (1/s, >= 0); default 0.
        Infeasible: exit 3 with the largest feasible rate (bisection).
    pump_limits : bool
        Keep the pumps inside their range on the certified region (LMIs);
        default true.
    region_margin : float
        The certified region must contain the ball of this radius around the
        operating point (state units, m; >= 0), else the design is refused;
        default 0.01.
    domain : mapping of str to (float, float), or None
        Box ``{state = [min, max]}`` (state units) replacing the plant's
        region bounds of those states; default None (the plant's region).
    orderings : bool
        Add the region's flow-direction orderings to the domain; default false
        (the deviation TS model is exact across flow reversals).
    ordering_gap : float
        Minimum separation kept in each ordering (state units, >= 0); default 0.
    premise_samples : int
        Grid points of each 1-D premise secant (>= 101); default 20001.
    premise_margin : float
        Relative widening of the sampled premise ranges (>= 0); default 1e-3.
    verify_points : int
        Initial points the verdict samples on and inside the region boundary
        (>= 2); default 24.
    seed : int
        Seed of the verdict's sampling (>= 0); default 0.
    setpoint : mapping of str to float, or None
        A second operating point ``{state = level}`` (state units, m; every
        state, an equilibrium inside the domain) for a set-point change: the
        PDC is designed again on the exact TS model of the deviations from it
        (same domain, ``u_op`` balancing it), with its own certified region,
        which must contain the first operating point; the switch is certified
        from the level set ``{V_1 <= gamma c_1}`` (``gamma`` reported, with
        the dwell time that reaches it from anywhere in the first region);
        default None (regulation only).
    setpoint_tolerance : float
        The verdict's set-point runs must end within this distance (largest
        state deviation) of the new operating point (state units, m; > 0);
        default 0.002.
    margin : float
        Strictness margin of the scaled LMIs, in (0, 1); default 1e-6.
    kappa : float
        ``X <= kappa I`` (scaled) when nothing else bounds the LMIs (> 1); default 1e4.
    solver : str
        ``"CLARABEL"`` (default) or ``"SCS"``.
    """

    method_name: ClassVar[str] = "ts_state_feedback"

    relaxation: str = option("auto", unit="-", choices=PDC_RELAXATIONS,
                             default_text='computed: "vertex", then "tuan" if vertex is infeasible')
    decay_rate: float = option(0.0, unit="1/s")
    pump_limits: bool = option(True, unit="-")
    region_margin: float = option(0.01, unit="state units (m)")
    domain: Mapping[str, tuple[float, float]] | None = option(None, unit="state units (m)")
    orderings: bool = option(False, unit="-")
    ordering_gap: float = option(0.0, unit="state units (m)")
    premise_samples: int = option(20001, unit="-")
    premise_margin: float = option(1e-3, unit="-")
    verify_points: int = option(24, unit="-")
    seed: int = option(0, unit="-")
    setpoint: Mapping[str, float] | None = option(None, unit="state units (m)")
    setpoint_tolerance: float = option(0.002, unit="state units (m)")
    margin: float = option(1e-6, unit="-")
    kappa: float = option(1e4, unit="-")
    solver: str = option("CLARABEL", unit="-", choices=LMI_SOLVERS)

    @classmethod
    def _common(cls, r: OptionReader, plant: Plant) -> dict:
        names = [s.name for s in plant.states]
        domain = r.read("domain", parse_box, names)
        return dict(
            relaxation=r.read("relaxation", parse_choice, PDC_RELAXATIONS),
            decay_rate=r.read("decay_rate", parse_number, at_least=0.0),
            pump_limits=r.read("pump_limits", parse_bool),
            region_margin=r.read("region_margin", parse_number, at_least=0.0),
            domain=None if domain is None else MappingProxyType(domain),
            orderings=r.read("orderings", parse_bool),
            ordering_gap=r.read("ordering_gap", parse_number, at_least=0.0),
            premise_samples=r.read("premise_samples", parse_integer, at_least=101,
                                   at_most=10_000_000),
            premise_margin=r.read("premise_margin", parse_number, at_least=0.0),
            verify_points=r.read("verify_points", parse_integer, at_least=2, at_most=100_000),
            seed=r.read("seed", parse_integer, at_least=0),
            setpoint=_setpoint(r, names),
            setpoint_tolerance=r.read("setpoint_tolerance", parse_number, above=0.0),
            margin=r.read("margin", parse_number, above=0.0, below=1.0),
            kappa=r.read("kappa", parse_number, above=1.0),
            solver=r.read("solver", parse_choice, LMI_SOLVERS))

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "TsStateFeedbackOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(**cls._common(r, plant))

    def conic_size(self, plant: Plant, ts: float | None) -> ConicSize:
        """The PDC LMIs (`tanksynth.design.takagi_sugeno.pdc`), from their structure.

        ``r = 2^p`` rules, ``p`` bounded by the plant's distinct nonlinear
        atoms (`nonlinear_atoms`; the exact count needs the quasi-LPV split):
        ``X`` (n x n), one ``F_i X`` (m x n) per rule; one ``n x n``
        block per pair of rules, one ``n + 1`` block per rule and pump limit;
        ``ts_output_feedback`` adds the observer's gains (n x q per rule) and
        its blocks for every pair of rules.
        """
        n, rules = plant.n, 2.0 ** nonlinear_atoms(plant)
        pairs = rules * (rules + 1) / 2
        blocks = [float(n)] * int(min(pairs + 4, 1 << 20))
        if self.pump_limits:
            blocks += [n + 1.0] * int(min(2 * rules, 1 << 20))
        variables = n * (n + 1) / 2 + rules * plant.m * n + 1
        if self.method_name == "ts_output_feedback":
            blocks += [float(n)] * int(min(rules * rules, 1 << 20))
            variables += n * (n + 1) / 2 + rules * n * plant.q
        return ConicSize(variables=variables, psd_orders=tuple(blocks), linear_rows=8,
                         advice="a plant with fewer nonlinear terms (2^p rules), or a linear method "
                                "(lmi_placement, hinf_state_feedback)")


@dataclass(frozen=True, eq=False)
class TsOutputFeedbackOptions(TsStateFeedbackOptions):
    """Options of ``ts_output_feedback``: the PDC of ``ts_state_feedback`` on an estimate.

    Every option of ``ts_state_feedback`` (listed first below), plus ``premises``,
    ``observer_decay``, ``lipschitz_method`` and ``coupling_factor``.

    Continuous-time, controller and observer, even when the spec has ``[sampling] ts`` (see
    ``ts_state_feedback``): the verdict and the campaign integrate the observer between
    samples (RK4 substeps, measured premises; exponential Euler, estimated premises) with the
    measurement and the input held over each period of the simulation.

    Attributes
    ----------
    premises : str
        ``"auto"`` (default: ``"measured"`` when every premise depends on
        measured states only), ``"measured"`` (PDC observer with the measured
        premises, separation) or ``"estimated"`` (seed 001 observer with the
        premises at the estimate, the Lipschitz bound ``psi`` of the remainder
        and the all-pairs PDC conditions; two-step design).
    observer_decay : float
        Decay rate of the PDC observer, measured premises (1/s, > 0); default 0.02.
    lipschitz_method : str
        Estimated premises: ``"interval"`` (default, guaranteed) or
        ``"sampling"`` bound of the remainder's Lipschitz constant.
    coupling_factor : float
        Safety factor on the weight ``beta`` of the composite Lyapunov function
        (> 1); default 2.
    """

    method_name: ClassVar[str] = "ts_output_feedback"

    premises: str = option("auto", unit="-", choices=("auto", "measured", "estimated"),
                           default_text='computed: "measured" when every premise depends on measured '
                                        'states only, else "estimated"')
    observer_decay: float = option(0.02, unit="1/s")
    lipschitz_method: str = option("interval", unit="-", choices=("interval", "sampling"))
    coupling_factor: float = option(2.0, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "TsOutputFeedbackOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(**cls._common(r, plant),
                   premises=r.read("premises", parse_choice, ("auto", "measured", "estimated")),
                   observer_decay=r.read("observer_decay", parse_number, above=0.0),
                   lipschitz_method=r.read("lipschitz_method", parse_choice, ("interval", "sampling")),
                   coupling_factor=r.read("coupling_factor", parse_number, above=1.0))


def _setpoint(r: OptionReader, names: list[str]) -> Mapping[str, float] | None:
    """The ``setpoint`` table ``{state = level}`` (every state), or None."""
    value = r.read("setpoint", lambda v, key: (v, key))
    if value is None:
        return None
    v, key = value
    if not isinstance(v, Mapping):
        raise SpecError(f"expected a table {{{', '.join(f'{n} = <level>' for n in names)}}} "
                        f"(state units, m), got {type(v).__name__}", key=key)
    vec = parse_vector(v, key, names=names)
    return MappingProxyType({n: float(x) for n, x in zip(names, vec)})


def _with_shared_attributes() -> None:
    """Put the shared options' documentation into ``TsOutputFeedbackOptions.__doc__``."""
    base = TsStateFeedbackOptions.__doc__ or ""
    shared = base[base.index("    relaxation : str"):].rstrip() + "\n"
    doc = TsOutputFeedbackOptions.__doc__ or ""
    head = "    Attributes\n    ----------\n"
    TsOutputFeedbackOptions.__doc__ = doc.replace(head, head + shared, 1)


_with_shared_attributes()
