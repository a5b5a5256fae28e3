"""Options of the linear gain designs: ``linearize``, ``pole_placement``, ``lmi_placement``,
``canonical_observer``.

Linear designs use the Jacobian linearisation at the spec's operating point,
ZOH-discretised with ``[sampling] ts`` in discrete time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np

from tanksynth.errors import SpecError
from tanksynth.spec.method_options.base import (TIME_DOMAIN_TEXT, MethodOptions, OptionReader, option,
                                                 time_domain_of)
from tanksynth.spec.memory import ConicSize, kappa_tries, region_order
from tanksynth.spec.options import (parse_bool, parse_choice, parse_matrix, parse_names, parse_number,
                                    parse_poles, parse_region, region_is_stable)

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["LMI_SOLVERS", "PLACE_METHODS", "TARGETS", "TIME_DOMAINS", "POLE_DOMAINS",
           "PolePlacementOptions", "LmiPlacementOptions",
           "CanonicalObserverOptions"]

#: Conic solvers of the LMI designs (cvxpy names).
LMI_SOLVERS = ("CLARABEL", "SCS")
#: What a linear gain design computes.
TARGETS = ("observer", "state_feedback")
#: Routines of exact pole placement (Tits-Yang `place` by scipy.signal.place_poles, as python-control; Ackermann `acker`).
PLACE_METHODS = ("auto", "place", "acker")
#: Time domains of a linear design.
TIME_DOMAINS = ("continuous", "discrete")
#: Planes requested poles may be written in (``poles = {values = [...], domain = "s"}``).
POLE_DOMAINS = ("s", "z")

_FRAGILE_DOC = """
    allow_fragile : bool
        Accept a gain whose closed loop a relative change of ``A`` smaller than
        1e-6 destabilises (stability radius, see the diagnostics'
        ``robustness``); default false (such a design is refused, exit 3)."""


def _poles_in_plane(value: Any, key: str, *, count: int, count_note: str, time_domain: str
                    ) -> tuple[tuple[complex, ...], str | None]:
    """``poles = [...]`` or ``poles = {values = [...], domain = "s" | "z"}``.

    Returns the poles as written and their plane (None when not said). s-plane
    poles (1/s) of a discrete design are converted by the design (``z = exp(p
    ts)``); z-plane poles need a discrete design.
    """
    if not isinstance(value, Mapping):
        return parse_poles(value, key, count=count, count_note=count_note,
                           stable_in=time_domain), None
    unknown = set(value) - {"values", "domain"}
    if unknown:
        raise SpecError(f"unknown key(s) {sorted(unknown)} in the poles table; expected "
                        "{values = [...], domain = \"s\" | \"z\"}", key=key)
    if "values" not in value:
        raise SpecError("the poles table needs values = [...]", key=f"{key}.values")
    plane = parse_choice(value.get("domain"), f"{key}.domain", POLE_DOMAINS) \
        if "domain" in value else None
    if plane == "z" and time_domain == "continuous":
        raise SpecError("z-plane poles need a discrete design: set time_domain = \"discrete\" "
                        "(with [sampling] ts) or give s-plane poles", key=f"{key}.domain")
    stable = time_domain if plane is None else ("continuous" if plane == "s" else "discrete")
    return parse_poles(value["values"], f"{key}.values", count=count, count_note=count_note,
                       stable_in=stable), plane


def _gain_setup(r: OptionReader, plant: Plant, ts: float | None) -> dict[str, Any]:
    """``target``, ``time_domain``, ``integral`` and ``tracked`` of a linear gain design."""
    target = r.read("target", parse_choice, TARGETS)
    time_domain = r.read("time_domain", parse_choice, TIME_DOMAINS) or time_domain_of(ts)
    if time_domain == "discrete" and ts is None:
        raise r.fail("time_domain", "a discrete-time design needs a sampling period: add "
                                    "[sampling] ts = ... (or time_domain = \"continuous\")")
    integral = r.read("integral", parse_bool)
    if integral and target == "observer":
        raise r.fail("integral", "integral action applies to state feedback (target = "
                                 "\"state_feedback\"), not to an observer")
    outputs = [s.name for s in plant.outputs]
    tracked = r.read("tracked", parse_names, outputs, what="output", at_most=plant.m)
    if integral and tracked is None:
        tracked = tuple(outputs[: plant.m])
    return {"target": target, "time_domain": time_domain, "integral": integral, "tracked": tracked}


def _gain_shape(setup: Mapping[str, Any], plant: Plant) -> tuple[int, int]:
    """Shape of ``K`` (m x n, or m x (n + p) with integral action) or ``L`` (n x q)."""
    if setup["target"] == "observer":
        return plant.n, plant.q
    p = len(setup["tracked"]) if setup["integral"] else 0
    return plant.m, plant.n + p


_GAIN_DOC = """
    target : str
        Required: ``"state_feedback"`` (gain ``K``, ``u = -K x``) or ``"observer"``
        (gain ``L``); the method designs both, so a spec says which.
    time_domain : str
        ``"discrete"`` (the ZOH model at ``[sampling] ts``; the default when the
        spec has a sampling period) or ``"continuous"`` (the default without).
    integral : bool
        Integral action on the tracked outputs (state feedback only); default
        false.
    tracked : tuple of str or None
        Outputs with integral action (at most m, named as the plant's
        outputs); default the first m outputs when ``integral`` is set, None
        without integral action."""


@dataclass(frozen=True, eq=False)
class PolePlacementOptions(MethodOptions):
    __doc__ = f"""Options of ``pole_placement``: exact pole placement (Tits-Yang ``place``
    by scipy.signal.place_poles, which python-control's ``place`` calls; Ackermann ``acker``) on the linearisation at the operating point.

    Attributes
    ----------
    poles : tuple of complex, or table {{values, domain}}
        Required. Eigenvalues to place, of ``A - B K`` (n; with integral
        action n + p, of the augmented system) or of ``A - L C`` (n): 1/s in
        continuous time, dimensionless (z-plane) in discrete time. Complex
        poles come in conjugate pairs, written ``[re, im]``. Written as a
        table ``{{values = [...], domain = "s"}}`` the plane is explicit:
        s-plane poles (1/s) of a discrete design are placed at ``z = exp(p
        ts)``; ``domain = "z"`` needs a discrete design. Without it, a
        discrete design whose poles are all real and negative warns (they
        look like s-plane poles).{_GAIN_DOC}
    pole_domain : str or None
        The plane the poles are written in (``"s"`` or ``"z"``), from the
        poles table; default None (the plane of ``time_domain``).
    algorithm : str
        ``"auto"`` (default), ``"place"`` (Tits-Yang) or ``"acker"``.
    reference_gain : ndarray or None
        A gain to compare with the derived one (the shape of ``K`` or ``L``,
        in its units), e.g. a published one; default None.{_FRAGILE_DOC}
    """

    method_name: ClassVar[str] = "pole_placement"

    poles: tuple[complex, ...] = option(unit="1/s (continuous) or - (discrete, z-plane)")
    target: str = option(unit="-", choices=TARGETS)
    time_domain: str | None = option(None, unit="-",
                                     default_text=TIME_DOMAIN_TEXT, choices=TIME_DOMAINS)
    integral: bool = option(False, unit="-")
    tracked: tuple[str, ...] | None = option(None, unit="-")
    algorithm: str = option("auto", unit="-", choices=PLACE_METHODS)
    reference_gain: np.ndarray | None = option(None, unit="units of K or L",
                                               default_text="unset: no comparison")
    pole_domain: str | None = option(None, unit="-", choices=POLE_DOMAINS)
    allow_fragile: bool = option(False, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "PolePlacementOptions":
        """See `MethodOptions.from_table`; the pole count follows ``target`` and ``integral``."""
        r = OptionReader(cls, options, key, ts)
        setup = _gain_setup(r, plant, ts)
        shape = _gain_shape(setup, plant)
        count = shape[1] if setup["target"] == "state_feedback" else plant.n
        note = (f"{plant.n} states + {count - plant.n} integrators of the tracked outputs "
                f"{list(setup['tracked'])}" if count > plant.n else f"{plant.n} states")
        if r.given("pole_domain"):
            raise r.fail("pole_domain", "write the plane with the poles: poles = {values = [...], "
                                        "domain = \"s\" | \"z\"}")
        poles, plane = r.read("poles", _poles_in_plane, count=count, count_note=note,
                              time_domain=setup["time_domain"])
        return cls(poles=poles, pole_domain=plane, **setup,
                   algorithm=r.read("algorithm", parse_choice, PLACE_METHODS),
                   reference_gain=r.read("reference_gain", parse_matrix, shape),
                   allow_fragile=r.read("allow_fragile", parse_bool))


@dataclass(frozen=True, eq=False)
class LmiPlacementOptions(MethodOptions):
    __doc__ = f"""Options of ``lmi_placement``: a gain whose closed-loop eigenvalues lie in an LMI
    region (cvxpy + Clarabel), on the linearisation at the operating point.

    Attributes
    ----------
    region : tuple of mapping
        Required. A list of tables whose intersection is the region:
        ``{{type = "half_plane", alpha = a}}`` (Re s < -a, 1/s), ``{{type = "disk",
        center = c, radius = r}}``, ``{{type = "sector", angle_deg = t}}`` (half-angle
        about the negative real axis); e.g. ``region = [{{type = "disk", center =
        0.9, radius = 0.08}}]``. Parsed to ``("half_plane", alpha)``, ``("disk",
        center, radius)``, ``("sector", theta)`` (rad); one part must lie in the
        stability domain of ``time_domain``.{_GAIN_DOC}
    margin : float
        Strictness margin of the LMIs, in (0, 1); default 1e-6.
    kappa : float
        Bound ``I <= X <= kappa I`` of the LMI variable ``X`` (``X = P^-1`` for a
        state feedback, ``X = P`` for an observer, ``P`` the stored Lyapunov
        matrix; > 1); default 1e4.
    kappa_max : float
        Ceiling of the automatic relaxation of ``kappa``: when the bound is
        active at the optimum of a refused LMI, it is retried with ``kappa``
        multiplied by 100 up to ``kappa_max`` (>= kappa; equal to ``kappa``
        disables the retry); default 1e8.
    solver : str
        Conic solver, ``"CLARABEL"`` (default) or ``"SCS"``.{_FRAGILE_DOC}
    """

    method_name: ClassVar[str] = "lmi_placement"

    region: tuple[tuple, ...] = option(unit="1/s (continuous) or - (discrete, z-plane)")
    target: str = option(unit="-", choices=TARGETS)
    time_domain: str | None = option(None, unit="-",
                                     default_text=TIME_DOMAIN_TEXT, choices=TIME_DOMAINS)
    integral: bool = option(False, unit="-")
    tracked: tuple[str, ...] | None = option(None, unit="-")
    margin: float = option(1e-6, unit="-")
    kappa: float = option(1e4, unit="-")
    solver: str = option("CLARABEL", unit="-", choices=LMI_SOLVERS)
    kappa_max: float = option(1e8, unit="-")
    allow_fragile: bool = option(False, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "LmiPlacementOptions":
        """See `MethodOptions.from_table`; the region must be stable in the time domain."""
        r = OptionReader(cls, options, key, ts)
        setup = _gain_setup(r, plant, ts)
        region = r.read("region", parse_region)
        if not region_is_stable(region, setup["time_domain"]):
            raise r.fail("region", f"the region is not inside the {setup['time_domain']}-time "
                                   "stability domain (continuous: add a half-plane alpha >= 0, a disk "
                                   "left of 0 or a sector; discrete: add a disk with |center| + "
                                   "radius <= 1)")
        kappa = r.read("kappa", parse_number, above=1.0)
        kappa_max = r.read("kappa_max", parse_number, above=1.0)
        if kappa_max < kappa:
            raise r.fail("kappa_max", f"kappa_max = {kappa_max:g} is below kappa = {kappa:g}")
        return cls(region=region, **setup,
                   margin=r.read("margin", parse_number, above=0.0, below=1.0),
                   kappa=kappa, kappa_max=kappa_max,
                   solver=r.read("solver", parse_choice, LMI_SOLVERS),
                   allow_fragile=r.read("allow_fragile", parse_bool))

    def conic_size(self, plant: Plant, ts: float | None) -> ConicSize:
        """Variables ``X`` (na x na, symmetric), ``Y`` (gain inputs x na), two scalars; blocks the
        region (``order na``) and ``I <= X <= kappa I``; ``na`` counts the integrators; two
        problems (phases 1 and 2) for each try of the ``kappa`` relaxation (`kappa_tries`)."""
        na = plant.n + (len(self.tracked or ()) or plant.q if self.integral else 0)
        gains = plant.q if self.target == "observer" else plant.m
        return ConicSize(variables=na * (na + 1) / 2 + gains * na + 2,
                         psd_orders=(region_order(self.region) * na, na, na), linear_rows=12,
                         problems=2 * kappa_tries(self.kappa, self.kappa_max),
                         advice="fewer states (a smaller plant, e.g. fewer tanks N), a region of "
                                "lower order (one disk or half-plane), or pole_placement")


@dataclass(frozen=True, eq=False)
class CanonicalObserverOptions(MethodOptions):
    """Options of ``canonical_observer``: the observer gain by the observer canonical form, in
    exact arithmetic (single-output plants with n <= 8, continuous time).

    Attributes
    ----------
    poles : tuple of complex
        Required. Eigenvalues of ``F - L C`` (n of them, 1/s); complex poles in
        conjugate pairs, written ``[re, im]``.
    reference_gain : ndarray or None
        An n x 1 gain to compare with the derived one (output to state
        units per s), e.g. a published one; default None.
    reference_closed_loop : ndarray or None
        An n x n matrix to compare with the derived ``F - L C`` (1/s);
        default None.
    allow_fragile : bool
        Accept an error matrix ``F - L C`` that a relative change of ``F``
        smaller than 1e-6 destabilises (stability radius); default false
        (refused, exit 3).
    """

    method_name: ClassVar[str] = "canonical_observer"

    poles: tuple[complex, ...] = option(unit="1/s")
    reference_gain: np.ndarray | None = option(None, unit="(state units)/(output units)/s",
                                               default_text="unset: no comparison")
    reference_closed_loop: np.ndarray | None = option(None, unit="1/s", default_text="unset: no comparison")
    allow_fragile: bool = option(False, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "CanonicalObserverOptions":
        """See `MethodOptions.from_table`; the plant must have one output and n <= 8."""
        r = OptionReader(cls, options, key, ts)
        if plant.q != 1:
            raise r.fail("method", f"the canonical-form route needs a single output, plant "
                                   f"'{plant.name}' has {plant.q}")
        if plant.n > 8:
            raise r.fail("method", "the canonical-form route is for small plants (n <= 8); use "
                                   "pole_placement")
        n = plant.n
        return cls(poles=r.read("poles", parse_poles, count=n, stable_in="continuous"),
                   reference_gain=r.read("reference_gain", parse_matrix, (n, plant.q)),
                   reference_closed_loop=r.read("reference_closed_loop", parse_matrix, (n, n)),
                   allow_fragile=r.read("allow_fragile", parse_bool))
