"""Options of the polytopic robust designs ``robust_state_feedback`` and ``robust_observer``.

Both designs take uncertain plant parameters as intervals (option
``uncertain``): the linearisation at the spec's operating levels is taken at
every corner of the parameter box (2^k vertex models) and one gain must put
the eigenvalues of every vertex's closed loop (or observer error matrix) in
an LMI region, with one common Lyapunov matrix, optionally with an
H-infinity bound at every vertex and (state feedback) a saturation-aware
invariant ellipsoid on which the pumps never leave ``|u - u0| <= umax``.

Spec forms of ``uncertain`` (one entry per parameter, named as the plant's
parameters): ``mu13 = [0.6, 0.75]`` (an interval in the parameter's unit),
``mu20 = "15%"`` / ``"+-15%"`` / ``"±15%"`` (nominal times 1 -+ 0.15) or
``A = {relative = 0.1}``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np

from tanksynth.errors import SpecError
from tanksynth.spec.method_options.base import (TIME_DOMAIN_TEXT, MethodOptions, OptionReader, option,
                                                 time_domain_of)
from tanksynth.spec.method_options.synthesis import (DISTURBANCE_FRACTION, auto_disturbance_std,
                                                     nominal_input_matrix)
from tanksynth.spec.context import parse_path, resolve, spec_directory
from tanksynth.spec.fit_box import read_fit_box
from tanksynth.spec.memory import ConicSize, region_order
from tanksynth.spec.options import (did_you_mean, parse_bool, parse_choice, parse_integer,
                                    parse_matrix, parse_names, parse_number, parse_region,
                                    parse_vector, region_is_stable)

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["MAX_UNCERTAIN", "ROBUST_SOLVERS", "parse_uncertain", "RobustStateFeedbackOptions",
           "RobustObserverOptions", "robust_conic_size"]

#: Most uncertain parameters of a design (2^k vertex models).
MAX_UNCERTAIN = 10
#: Conic solvers (cvxpy names).
ROBUST_SOLVERS = ("CLARABEL", "SCS")
_TIME_DOMAINS = ("continuous", "discrete")
_RELATIVE = re.compile(r"^\s*(?:\+-|\+/-|±)?\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*%\s*$")


def parse_uncertain(value: Any, key: str, plant: Plant) -> tuple[tuple[str, float, float], ...]:
    """Intervals of uncertain plant parameters, ``((name, low, high), ...)`` in spec order.

    Parameters
    ----------
    value : mapping
        ``{name = [low, high]}``, ``{name = "15%"}`` (also ``"+-15%"``,
        ``"±15%"``) or ``{name = {relative = 0.15}}``; the parsed tuple is
        accepted too.
    key : str
        Spec key (``design[i].uncertain``).
    plant : Plant
        Names and admissible ranges of the parameters.

    Returns
    -------
    tuple of (str, float, float)
        Parameter name, lower and upper value (the parameter's unit), ``low <= high``.

    Raises
    ------
    SpecError
        Unknown parameter (named, with a suggestion), a malformed interval, a
        bound outside the parameter's admissible range, more than
        `MAX_UNCERTAIN` parameters.
    """
    if isinstance(value, tuple):
        value = {name: [lo, hi] for name, lo, hi in value}
    if not isinstance(value, Mapping):
        raise SpecError("expected a table {parameter = [low, high]} (or \"15%\", or {relative = "
                        f"0.15}}), got {type(value).__name__}", key=key)
    known = {prm.name: prm for prm in plant.parameters}
    out = []
    for name, item in value.items():
        k = f"{key}.{name}"
        if name not in known:
            raise SpecError(f"unknown parameter {name!r} of plant '{plant.name}'"
                            + did_you_mean(name, list(known)) + "; expected some of: "
                            + ", ".join(known), key=k)
        prm = known[name]
        nominal = float(prm.value)
        if isinstance(item, str):
            m = _RELATIVE.match(item)
            if not m:
                raise SpecError(f"expected a relative interval such as \"15%\" or \"+-15%\", got "
                                f"{item!r}", key=k)
            rel = float(m.group(1)) / 100.0
            if not 0 < rel < 1:
                raise SpecError(f"relative uncertainty must be in (0 %, 100 %), got {item!r}", key=k)
            lo, hi = nominal * (1 - rel), nominal * (1 + rel)
        elif isinstance(item, Mapping):
            if set(item) != {"relative"}:
                raise SpecError(f"expected {{relative = r}} with 0 < r < 1, got keys {list(item)}",
                                key=k)
            rel = parse_number(item["relative"], f"{k}.relative", above=0.0, below=1.0)
            lo, hi = nominal * (1 - rel), nominal * (1 + rel)
        elif isinstance(item, (list, tuple)) and len(item) == 2:
            lo, hi = parse_number(item[0], f"{k}[0]"), parse_number(item[1], f"{k}[1]")
            if not lo <= hi:
                raise SpecError(f"low ({lo:g}) must not exceed high ({hi:g})", key=k)
        else:
            unit = "" if prm.unit in ("", "1", "-") else f" in {prm.unit}"
            raise SpecError(f"expected an interval [low, high]{unit}, a relative \"15%\" (meaning "
                            f"+-15 %) or {{relative = 0.15}}, got {item!r}", key=k)
        lo, hi = sorted((lo, hi))
        prm.check(lo, k)
        prm.check(hi, k)
        out.append((str(name), float(lo), float(hi)))
    if len(out) > MAX_UNCERTAIN:
        raise SpecError(f"{len(out)} uncertain parameters give 2^{len(out)} vertex models; at most "
                        f"{MAX_UNCERTAIN} are accepted", key=key)
    return tuple(out)


def _fit_box(r: OptionReader, plant: Plant) -> tuple[tuple[str, float, float], ...]:
    """``uncertain = "fit"``: the intervals of the fit result named by option ``fit`` (read when
    a spec file is being read; a spec parsed from text, e.g. a result directory's copy, has the
    box in its artefact: empty here)."""
    if not r.given("fit"):
        return ()  # the design refuses it, naming the option (the spec may still be fitted)
    path = parse_path(r.options["fit"], r.key("fit"), what="fit result", directory=True)
    if spec_directory() is None:
        return ()
    box = read_fit_box(resolve(path), r.key("fit"), plant).box
    if len(box) > MAX_UNCERTAIN:
        raise r.fail("uncertain", f"the fit has {len(box)} parameters: 2^{len(box)} vertex models; "
                                  f"at most {MAX_UNCERTAIN} are accepted")
    return box


def _common(r: OptionReader, plant: Plant, ts: float | None) -> dict[str, Any]:
    """Options shared by both robust designs."""
    time_domain = r.read("time_domain", parse_choice, _TIME_DOMAINS) or time_domain_of(ts)
    if time_domain == "discrete" and ts is None:
        raise r.fail("time_domain", "a discrete-time design needs a sampling period: add "
                                    "[sampling] ts = ... (or time_domain = \"continuous\")")
    region = r.read("region", parse_region)
    if not region_is_stable(region, time_domain):
        raise r.fail("region", f"the region is not inside the {time_domain}-time stability domain "
                               "(continuous: add a half-plane alpha >= 0, a disk left of 0 or a "
                               "sector; discrete: add a disk with |center| + radius <= 1)")
    if r.given("uncertain") and r.options["uncertain"] == "fit":
        uncertain = _fit_box(r, plant)
    else:
        if r.given("fit"):
            raise r.fail("fit", "fit names the fit result whose intervals are the box: set "
                                "uncertain = \"fit\" too")
        uncertain = r.read("uncertain", parse_uncertain, plant, parse_default=True)
    gamma = r.read("gamma", parse_number, above=0.0, at_most=1e12) if r.given("gamma") else None
    for opt in ("Bw", "Cz", "Dzu"):
        if r.given(opt) and gamma is None:
            raise r.fail(opt, f"{opt} declares an H-infinity channel: give its bound gamma too")
    return {"region": region, "uncertain": uncertain, "fit": r.read("fit", parse_path, what="fit result",
                                                                      directory=True),
            "time_domain": time_domain, "gamma": gamma,
            "margin": r.read("margin", parse_number, above=0.0, below=1.0),
            "kappa": r.read("kappa", parse_number, above=1.0),
            "solver": r.read("solver", parse_choice, ROBUST_SOLVERS),
            "samples": r.read("samples", parse_integer, at_least=1, at_most=100000),
            "mc_runs": r.read("mc_runs", parse_integer, at_least=1, at_most=10000),
            "seed": r.read("seed", parse_integer, at_least=0)}


def _default_Bw(plant: Plant, observer: bool) -> np.ndarray | None:
    """The H-infinity channel's default ``Bw`` (continuous time), sized by the pumps.

    State feedback: ``B diag(0.1 range)``, a disturbance entering like each pump
    with 10 % of its range; observer: ``s I`` with ``s`` 10 % of the pumps'
    authority ``max |B_ik| range_k`` (a level-rate disturbance on every state,
    state unit per s). ``B`` at the region box centre, nominal parameters. None
    (the unscaled ``B`` / identity of every vertex) where the plant gives no
    finite input range or input map.
    """
    if observer:
        s = auto_disturbance_std(plant, np.eye(plant.n))
        return np.diag(s)
    B = nominal_input_matrix(plant)
    ranges = np.array([float(hi) - float(lo) for lo, hi in plant.input_limits], dtype=float)
    if B is None or not np.all(np.isfinite(ranges) & (ranges > 0)):
        return None
    return B * (DISTURBANCE_FRACTION * ranges)[None, :]


_COMMON_DOC = """
    region : tuple of mapping
        Required. The LMI region every vertex's eigenvalues must lie in, a
        list of tables intersected as for ``lmi_placement``: ``{{type =
        "half_plane", alpha = a}}``, ``{{type = "disk", center = c, radius =
        r}}``, ``{{type = "sector", angle_deg = t}}``; one part must lie in the
        stability domain of ``time_domain``.
    uncertain : tuple of (str, float, float)
        Uncertain parameters as intervals ``(name, low, high)`` in the
        parameter's unit (spec: ``{{mu13 = [0.6, 0.75]}}``, ``{{mu20 =
        "15%"}}`` or ``{{A = {{relative = 0.1}}}}``), or ``"fit"``: the
        intervals of the fit result named by ``fit``; default none (a nominal
        design). The linearisation at the spec's operating levels is taken
        at all 2^k corners with each corner's own equilibrium input.
    fit : str or None
        With ``uncertain = "fit"``: a fit result directory (``tanksynth fit
        ... -o DIR``) or its ``fit.json``, relative to the spec file; the box
        is the fit's intervals of its free parameters; default None.
    time_domain : str
        ``"discrete"`` (ZOH vertex models at ``[sampling] ts``; the default
        with a sampling period) or ``"continuous"``.
    gamma : float or None
        H-infinity bound at every vertex (units of ``z`` per unit of ``w``; at most 1e12);
        default None (no H-infinity constraint). A bound the design without it
        already meets is certified but not imposed (the gain is then that
        design's; diagnostics ``robust.hinf.imposed = false``).
    Bw : ndarray or None
        Continuous-time disturbance input matrix of the ``gamma`` channel (n
        x nw, state units per s per unit of the normalised ``w``), default
        with ``gamma`` {bw}, taken at the region box centre with the nominal
        parameters. Without ``gamma`` it is unused (None).
    Cz : ndarray or None
        Performance output matrix on the plant states (nz x n); default the
        identity (every state, state units).{dzu}
    margin : float
        Strictness margin of the normalised LMIs, in (0, 1); default 1e-6.
    kappa : float
        Conditioning bound of the Lyapunov variable (> 1); default 1e4.
    solver : str
        ``"CLARABEL"`` (default) or ``"SCS"``.
    samples : int
        Verdict: parameter values sampled uniformly in the box whose
        linearisations must keep their eigenvalues in the region; default 200.
    mc_runs : int
        Verdict: Monte-Carlo runs on the nonlinear plant with sampled
        parameter values; default 16.
    seed : int
        Seed of the verdict's samples; default 0."""


@dataclass(frozen=True, eq=False)
class RobustStateFeedbackOptions(MethodOptions):
    __doc__ = f"""Options of ``robust_state_feedback``: one state feedback ``u = u0 - K (x - x0)``
    (optionally with integral action) whose closed loop has its eigenvalues in an LMI region at
    every vertex of the parameter box, with a common Lyapunov matrix.

    Attributes
    ----------{_COMMON_DOC.format(bw="``B diag(0.1 (umax - umin))``: a disturbance entering "
                                     "like each pump with 10 % of its range (input units)",
                                  dzu='''
    Dzu : ndarray or None
        Feedthrough of the inputs to ``z`` (nz x m, z units per input unit);
        default zeros.''')}
    integral : bool
        Integral action on the tracked outputs (removes the offset the
        parameter mismatch leaves); default false.
    tracked : tuple of str or None
        Outputs with integral action (at most m); default the first m
        outputs when ``integral`` is set.
    saturation : bool
        Saturation-aware design: an ellipsoid ``x' P x <= 1`` (deviation
        coordinates) invariant at every vertex on which ``|K_j x| <=
        umax_j``; default false.
    umax : ndarray or None
        Largest input deviation ``|u_j - u0_j|`` per input (input units);
        default the distance from the nominal equilibrium input to the
        nearest actuator limit.
    box : ndarray or None
        Half-widths of the box of initial level deviations the ellipsoid
        must contain (state units, one per plant state, ``{{h1 = 0.02,
        ...}}``); default None: the largest cube (in state units) is sought.
        With ``box`` the ellipsoid is as large a multiple of the box as the
        constraints allow (at least 1).
    """

    method_name: ClassVar[str] = "robust_state_feedback"

    region: tuple[tuple, ...] = option(unit="1/s (continuous) or - (discrete, z-plane)")
    uncertain: tuple[tuple[str, float, float], ...] = option((), unit="units of each parameter")
    fit: str | None = option(None, unit="-", default_text="unset: no fit result")
    time_domain: str | None = option(None, unit="-",
                                     default_text=TIME_DOMAIN_TEXT, choices=_TIME_DOMAINS)
    integral: bool = option(False, unit="-")
    tracked: tuple[str, ...] | None = option(None, unit="-")
    gamma: float | None = option(None, unit="-", default_text="unset: no H-infinity constraint")
    Bw: np.ndarray | None = option(None, unit="state units/s per disturbance unit",
                                   default_text=("computed with gamma: pump-sized, B diag(0.1 range); "
                                                 "unused without gamma"))
    Cz: np.ndarray | None = option(None, unit="performance units per state unit")
    Dzu: np.ndarray | None = option(None, unit="performance units per input unit")
    saturation: bool = option(False, unit="-")
    umax: np.ndarray | None = option(None, unit="input units")
    box: np.ndarray | None = option(None, unit="state units")
    margin: float = option(1e-6, unit="-")
    kappa: float = option(1e4, unit="-")
    solver: str = option("CLARABEL", unit="-", choices=ROBUST_SOLVERS)
    samples: int = option(200, unit="-")
    mc_runs: int = option(16, unit="-")
    seed: int = option(0, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "RobustStateFeedbackOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        common = _common(r, plant, ts)
        n, m = plant.n, plant.m
        integral = r.read("integral", parse_bool)
        outputs = [s.name for s in plant.outputs]
        tracked = r.read("tracked", parse_names, outputs, what="output", at_most=m)
        if tracked is not None and not integral:
            raise r.fail("tracked", "tracked outputs need integral = true")
        if integral and tracked is None:
            tracked = tuple(outputs[:m])
        Bw = r.read("Bw", parse_matrix, (n, None))
        if Bw is None and common["gamma"] is not None:
            Bw = _default_Bw(plant, observer=False)
        Cz = r.read("Cz", parse_matrix, (None, n))
        nz = Cz.shape[0] if Cz is not None else n
        Dzu = r.read("Dzu", parse_matrix, (nz, m))
        saturation = r.read("saturation", parse_bool)
        names = [s.name for s in plant.states]
        umax = r.read("umax", parse_vector, m, names=None, above=0.0)
        box = r.read("box", parse_vector, n, names=names, above=0.0)
        for opt in ("umax", "box"):
            if r.given(opt) and not saturation:
                raise r.fail(opt, f"{opt} belongs to the saturation-aware design: set saturation = true")
        if saturation and n > 12:
            raise r.fail("saturation", f"the box containment uses the 2^n corners of the box; n = {n} "
                                       "> 12 states is too many")
        return cls(**common, integral=integral, tracked=tracked, Bw=Bw, Cz=Cz, Dzu=Dzu,
                   saturation=saturation, umax=umax, box=box)

    def conic_size(self, plant: Plant, ts: float | None) -> ConicSize:
        """See `robust_conic_size`; ``na`` counts the integrators."""
        na = plant.n + (len(self.tracked or ()) if self.integral else 0)
        return robust_conic_size(self, plant, ts, na, plant.m, self.saturation)


@dataclass(frozen=True, eq=False)
class RobustObserverOptions(MethodOptions):
    __doc__ = f"""Options of ``robust_observer``: one observer gain ``L`` whose error matrix ``A(p)
    - L C(p)`` has its eigenvalues in an LMI region at every vertex of the parameter box, with a
    common Lyapunov matrix (dual of `RobustStateFeedbackOptions`).

    Attributes
    ----------{_COMMON_DOC.format(bw="``s I``: a disturbance on every state's rate of 10 % of the "
                                     "pumps' authority ``s = 0.1 max_ik |B_ik| range_k`` (state "
                                     "units per s)", dzu="")}
    """

    method_name: ClassVar[str] = "robust_observer"

    region: tuple[tuple, ...] = option(unit="1/s (continuous) or - (discrete, z-plane)")
    uncertain: tuple[tuple[str, float, float], ...] = option((), unit="units of each parameter")
    fit: str | None = option(None, unit="-", default_text="unset: no fit result")
    time_domain: str | None = option(None, unit="-",
                                     default_text=TIME_DOMAIN_TEXT, choices=_TIME_DOMAINS)
    gamma: float | None = option(None, unit="-", default_text="unset: no H-infinity constraint")
    Bw: np.ndarray | None = option(None, unit="state units/s per disturbance unit",
                                   default_text=("computed with gamma: 0.1 max|B| range I; unused "
                                                 "without gamma"))
    Cz: np.ndarray | None = option(None, unit="performance units per state unit")
    margin: float = option(1e-6, unit="-")
    kappa: float = option(1e4, unit="-")
    solver: str = option("CLARABEL", unit="-", choices=ROBUST_SOLVERS)
    samples: int = option(200, unit="-")
    mc_runs: int = option(16, unit="-")
    seed: int = option(0, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "RobustObserverOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        common = _common(r, plant, ts)
        n = plant.n
        Bw = r.read("Bw", parse_matrix, (n, None))
        if Bw is None and common["gamma"] is not None:
            Bw = _default_Bw(plant, observer=True)
        return cls(**common, Bw=Bw, Cz=r.read("Cz", parse_matrix, (None, n)))

    def conic_size(self, plant: Plant, ts: float | None) -> ConicSize:
        """See `robust_conic_size` (the observer's gain has q columns)."""
        return robust_conic_size(self, plant, ts, plant.n, plant.q, False)


def robust_conic_size(options: Any, plant: Plant, ts: float | None, na: int, gains: int,
                      saturation: bool) -> ConicSize:
    """The polytopic LMI problem of `tanksynth.design.robust.polytopic`, from its structure.

    One ``X`` (na x na) and ``Y`` (gains x na) for the ``2^p + 1`` models (the
    box's vertices and its centre, ``p`` uncertain parameters); per model the
    region block (``order na``), the bounded real lemma with ``gamma``, and with
    ``saturation`` an invariance block and one ``na + 1`` block per input.

    Parameters
    ----------
    options : RobustStateFeedbackOptions or RobustObserverOptions
    plant : Plant
    ts : float or None
        Sampling period (s).
    na : int
        States of the design model (with integrators).
    gains : int
        Columns of the gain's transpose (inputs, or outputs for an observer).
    saturation : bool
        The saturation-aware design.

    Returns
    -------
    ConicSize
    """
    models = 2.0 ** len(options.uncertain) + 1
    per_model = [float(region_order(options.region) * na)]
    if options.gamma is not None:
        nw = int(np.shape(options.Bw)[1]) if options.Bw is not None else na
        nz = int(np.shape(options.Cz)[0]) if options.Cz is not None else na + gains
        per_model.append(2.0 * na + nw + nz)
    if saturation:
        per_model += [2.0 * na] + [na + 1.0] * gains
    blocks = tuple(per_model) * int(min(models, 1 << 20)) + (float(na), float(na))
    return ConicSize(variables=na * (na + 1) / 2 + gains * na + 4, psd_orders=blocks,
                     linear_rows=16, advice="fewer uncertain parameters (2^p + 1 models), fewer "
                                             "states (a smaller plant), a region of lower order, "
                                             "or no gamma / saturation")
