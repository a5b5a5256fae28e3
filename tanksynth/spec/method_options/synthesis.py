"""Options of the optimal convex syntheses: ``h2_state_feedback``, ``h2_observer``,
``hinf_state_feedback``, ``hinf_observer`` and ``multiobjective``.

All use the Jacobian linearisation at the operating point (ZOH-discretised with
``[sampling] ts`` in discrete time) and the generalised plant::

    dx/dt = A x + Bw diag(disturbance_std) w + B u,   z = Cz x + Dzu u   (state feedback)
    y = C x + diag(measurement_std) v,                 z = Cz e           (observers, e = x - xhat)

``w`` and ``v`` are normalised (unit intensity); ``Bw`` is given in continuous
time (the physical disturbance) and ZOH-discretised with the plant in discrete
time. ``disturbance_std = "auto"`` (the default) sizes each disturbance from the
pumps (`auto_disturbance_std`): its largest effect on a state's rate is
`DISTURBANCE_FRACTION` (10 %) of the largest rate a pump produces over its full
range, so with ``Bw = "inflows"`` each tank receives an unknown inflow in the
plant's own volume-flow unit (1.2e-5 m^3/s, 10 % of a pump, for the SI
three-tank; 2.3 - 2.7 cm^3/s for ``tank_network`` whose pumps are driven in V). Defaults follow Bryson's rule, so ``z`` is dimensionless:
``Q = diag(1 / span_i^2)`` over the operating region's box and ``R = diag(1 /
range_j^2)`` over the actuators' ranges; ``Cz = [Q^1/2; 0]``, ``Dzu = [0;
R^1/2]`` for state feedback and ``Cz = Q^1/2`` for observers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np

from tanksynth.spec.method_options.base import (TIME_DOMAIN_TEXT, MethodOptions, OptionReader, option,
                                                 time_domain_of)
from tanksynth.spec.memory import ConicSize, region_order
from tanksynth.spec.options import (parse_choice, parse_covariance, parse_matrix, parse_number,
                                    parse_region, parse_vector, region_is_stable)

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["DISTURBANCE_SHORTCUTS", "DISTURBANCE_FRACTION", "SYNTHESIS_OBJECTIVES", "SYNTHESIS_SOLVERS", "SYNTHESIS_TARGETS",
           "SYNTHESIS_ROUTES",
           "inflow_matrix", "auto_disturbance_std", "nominal_input_matrix", "bryson_state_weight", "bryson_input_weight",
           "H2StateFeedbackOptions", "H2ObserverOptions", "HinfStateFeedbackOptions",
           "HinfObserverOptions", "MultiobjectiveOptions"]

#: Shortcuts for ``Bw``.
DISTURBANCE_SHORTCUTS = ("inflows",)
#: ``disturbance_std = "auto"``: each disturbance's largest effect on a state's rate, as a
#: fraction of the largest rate a pump produces over its full range (`auto_disturbance_std`).
DISTURBANCE_FRACTION = 0.1
#: Largest disturbance or measurement standard deviation accepted (in the signal's unit; far
#: beyond any physical tank signal, and its square keeps the Riccati/LMI data representable).
MAX_STD = 1e10
#: Largest norm bound (``gamma``, ``h2_bound``, ``hinf_bound``): beyond it the scaled LMIs lose
#: all precision and a bound that large constrains nothing a tank plant can show.
MAX_NORM_BOUND = 1e12
#: What ``multiobjective`` minimises.
SYNTHESIS_OBJECTIVES = ("hinf", "h2")
#: Conic solvers (cvxpy names).
SYNTHESIS_SOLVERS = ("CLARABEL", "SCS")
#: How a pure H2 / H-infinity design is solved (``multiobjective`` always uses the LMIs).
SYNTHESIS_ROUTES = ("auto", "riccati", "lmi")
#: What ``route = "auto"`` does (the catalogue's default text).
_ROUTE_TEXT = 'computed: "riccati", "lmi" when the Riccati route does not apply'

#: What ``multiobjective`` designs.
SYNTHESIS_TARGETS = ("state_feedback", "observer")


def inflow_matrix(plant: Plant, key: str = "Bw") -> np.ndarray:
    """``Bw`` of the ``"inflows"`` shortcut: a unit inflow into each tank, ``diag(1 / A_i)``.

    The tank areas are the plant's parameters ``A1 .. An`` (one per tank), else
    its common cross-section ``A``; the state ``i`` must be the level of tank
    ``i`` (level unit per s per inflow unit: m/s per m^3/s with SI parameters).

    Parameters
    ----------
    plant : Plant
        The plant (tank areas in m^2, states the tank levels in m).
    key : str, optional
        The spec key named in an error (default ``"Bw"``).

    Raises
    ------
    SpecError
        The plant has no tank-area parameter.
    """
    from tanksynth.errors import SpecError

    values = {p.name: float(p.value) for p in plant.parameters}
    n = plant.n
    if all(f"A{i}" in values for i in range(1, n + 1)):
        areas = np.array([values[f"A{i}"] for i in range(1, n + 1)])
    elif "A" in values:
        areas = np.full(n, values["A"])
    else:
        raise SpecError(f"Bw = \"inflows\" needs the tank areas (parameters A1..A{n} or A) of plant "
                        f"'{plant.name}', which has none: give Bw as an {n} x nw matrix", key=key)
    if np.any(areas <= 0):
        raise SpecError(f"tank areas must be > 0, got {areas.tolist()}", key=key)
    return np.diag(1.0 / areas)


def auto_disturbance_std(plant: Plant, Bw: np.ndarray) -> np.ndarray:
    """The ``disturbance_std = "auto"`` size of each disturbance (disturbance units).

    Each column ``j`` of ``Bw`` is scaled so that its largest effect on a state's
    rate is `DISTURBANCE_FRACTION` (10 %) of the pumps' authority, the largest
    ``|B_ik| (umax_k - umin_k)`` (state unit per s)::

        std_j = 0.1 max_ik |B_ik| range_k / max_i |Bw_ij|

    ``B`` is the input Jacobian at the centre of the operating region's box with
    every input at mid-range (constant for tank plants, whose pumps enter
    affinely). With ``Bw = "inflows"`` (``diag(1 / A_i)``) this is an unknown
    inflow into each tank that raises its level at 10 % of the fastest rate a
    pump raises any level at full range, in the plant's volume-flow unit (level
    unit x area unit per s): 1.2e-5 m^3/s for the three-tank (pumps of 1.2e-4
    m^3/s straight into tanks of equal area), ``0.1 x 0.7 x 3.33 cm^3/(V s) x
    10 V x A_j / 28 cm^2`` = 2.33 / 2.66 cm^3/s for ``tank_network``
    (``"decenter"``: 28 / 32 cm^2 tanks). A column of zeros, or a plant without
    finite input ranges or input authority, gets 1 (disturbance unit).

    Parameters
    ----------
    plant : Plant
        The plant (input limits in input units, region box in state units).
    Bw : ndarray, shape (n, nw)
        Continuous-time disturbance input matrix (state unit per s per disturbance unit).

    Returns
    -------
    ndarray, shape (nw,)
        One standard deviation per disturbance (disturbance units), > 0.
    """
    Bw = np.asarray(Bw, dtype=float)
    std = np.ones(Bw.shape[1])
    ranges = np.array([float(hi) - float(lo) for lo, hi in plant.input_limits], dtype=float)
    if not np.all(np.isfinite(ranges)) or not np.any(ranges > 0):
        return std
    B = nominal_input_matrix(plant)
    if B is None:
        return std
    authority = float(np.max(np.abs(B) * ranges[None, :]))
    if not np.isfinite(authority) or authority <= 0:
        return std
    col = np.max(np.abs(Bw), axis=0) if Bw.size else np.zeros(0)
    ok = np.isfinite(col) & (col > 0)
    std[ok] = DISTURBANCE_FRACTION * authority / col[ok]
    return np.minimum(std, MAX_STD)


def nominal_input_matrix(plant: Plant) -> np.ndarray | None:
    """The input Jacobian ``B = df/du`` at the centre of the region box, inputs at mid-range.

    Tank plants take their pumps affinely, so ``B`` (state unit per s per input
    unit) does not depend on the point; the operating point is not known when
    options are read, hence the box centre (a finite bound where the other is
    infinite, else 0).

    Parameters
    ----------
    plant : Plant
        The plant (region box in state units, input limits in input units).

    Returns
    -------
    ndarray, shape (n, m), or None
        ``B``, or None where the input map cannot be evaluated there (not finite).
    """
    lo = np.array([float(b[0]) for b in plant.region.bounds], dtype=float)
    hi = np.array([float(b[1]) for b in plant.region.bounds], dtype=float)
    x = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi),
                 np.where(np.isfinite(lo), lo, np.where(np.isfinite(hi), hi, 0.0)))
    u = np.array([0.5 * (float(a) + float(b)) if np.isfinite(float(a)) and np.isfinite(float(b))
                  else 0.0 for a, b in plant.input_limits], dtype=float)
    try:
        B = np.asarray(plant.compiled.jacobians(x[None], u[None])[1], float).reshape(plant.n, plant.m)
    except Exception:  # noqa: BLE001 - an input map that cannot be evaluated at the box centre
        return None
    return B if np.all(np.isfinite(B)) else None


def _span(bounds: Any, size: int) -> np.ndarray:
    arr = np.array([[float(a), float(b)] for a, b in bounds], dtype=float).reshape(size, 2)
    span = arr[:, 1] - arr[:, 0]
    return np.where(np.isfinite(span) & (span > 0), span, 1.0)


def bryson_state_weight(plant: Plant) -> np.ndarray:
    """Bryson's ``Q = diag(1 / span_i^2)`` over the operating region's box (1 / state unit^2).

    Parameters
    ----------
    plant : Plant
        The plant; its operating region's box gives each state's span (state units).
    """
    return np.diag(1.0 / _span(plant.region.bounds, plant.n) ** 2)


def bryson_input_weight(plant: Plant) -> np.ndarray:
    """Bryson's ``R = diag(1 / range_j^2)`` over the actuators' ranges (1 / input unit^2).

    Parameters
    ----------
    plant : Plant
        The plant; its input limits give each actuator's range (input units, m^3/s).
    """
    return np.diag(1.0 / _span(plant.input_limits, plant.m) ** 2)


def _output_span(plant: Plant) -> np.ndarray:
    """``|h(x_max) - h(x_min)|`` over the region box (output units; 1 where zero or undefined)."""
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    try:
        out = plant.compiled.output(np.vstack([lo, hi]))
        span = np.abs(np.asarray(out, float)[1] - np.asarray(out, float)[0]).reshape(-1)
    except Exception:  # noqa: BLE001 - an output map that cannot be evaluated on the box
        span = np.ones(plant.q)
    return np.where(np.isfinite(span) & (span > 0), span, 1.0)


def _sqrtm_psd(M: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(0.5 * (M + M.T))
    return (V * np.sqrt(np.maximum(w, 0.0))) @ V.T


_COMMON_DOC = """
    time_domain : str
        ``"discrete"`` (ZOH model at ``[sampling] ts``; the default when the
        spec has a sampling period) or ``"continuous"``.
    Bw : ndarray
        Disturbance input matrix in continuous time, n x nw (state unit per s
        per disturbance unit), or ``"inflows"`` (default): a unit inflow into
        each tank, ``diag(1 / A_i)`` from the plant's tank areas.
    disturbance_std : ndarray or str
        Size of each disturbance, default ``"auto"``: each moves a state at
        most 10 % as fast as the pumps at full range (``std_j = 0.1 max|B
        diag(range)| / max_i |Bw_ij|``; with ``"inflows"`` an inflow in the
        plant's volume-flow unit, 1.2e-5 m^3/s on the three-tank, 2.3 - 2.7
        cm^3/s on ``tank_network``). Else one number for all or nw numbers,
        each in (0, 1e10], in disturbance units (with ``"inflows"``: level
        unit x tank-area unit per s); see ``auto_disturbance_std``.
    Q : ndarray
        State weight (n x n, symmetric positive semidefinite, 1 / state unit^2);
        default Bryson's ``diag(1 / span_i^2)`` over the region box.
    Cz : ndarray or None
        Performance output matrix (nz x n); default ``[Q^1/2; 0]`` (state
        feedback) or ``Q^1/2`` (observers: weight of the estimation error).
    margin : float
        Strictness margin of the scaled LMIs, in (0, 0.01); default 1e-9.
    solver : str
        ``"CLARABEL"`` (default) or ``"SCS"``."""

_ROUTE_DOC = """
    route : str
        ``"auto"`` (default): the Riccati solution (scipy ARE: the LQR /
        Kalman filter for H2; gamma bisection on the game Riccati equation for
        H-infinity, as ``hinfsyn``), which has the LMI's optimum and scales to
        large plants, falling back to the LMI if it does not apply (``Dzu'Dzu``
        or ``Dv`` singular) or fails; ``"riccati"`` (refused where it does not
        apply) or ``"lmi"`` (cvxpy; ``margin`` and ``solver`` apply). Either
        gain is re-checked by the same independent numerics."""

_SF_DOC = """
    R : ndarray
        Input weight (m x m, positive definite, 1 / input unit^2); default
        Bryson's ``diag(1 / range_j^2)`` over the actuator ranges.
    Dzu : ndarray or None
        Performance feedthrough (nz x m); default ``[0; R^1/2]``; given
        together with ``Cz``."""

_OBS_DOC = """
    measurement_std : ndarray
        Measurement noise size of each output (output units): one number or
        q numbers; default 1 % of ``|h(x_max) - h(x_min)|`` over the region box."""


def _common(r: OptionReader, plant: Plant, ts: float | None, observer: bool) -> dict[str, Any]:
    time_domain = r.read("time_domain", parse_choice, ("continuous", "discrete")) or time_domain_of(ts)
    if time_domain == "discrete" and ts is None:
        raise r.fail("time_domain", "a discrete-time design needs a sampling period: add "
                                    "[sampling] ts = ... (or time_domain = \"continuous\")")
    n, m = plant.n, plant.m
    raw = r.options.get("Bw", "inflows")
    if isinstance(raw, str):
        parse_choice(raw, r.key("Bw"), DISTURBANCE_SHORTCUTS)
        Bw = inflow_matrix(plant, r.key("Bw"))
    else:
        Bw = np.array(parse_matrix(raw, r.key("Bw"), (n, None)))
    nw = Bw.shape[1]
    raw_w = r.options.get("disturbance_std", "auto")
    if isinstance(raw_w, str):
        parse_choice(raw_w, r.key("disturbance_std"), ("auto",))
        std = auto_disturbance_std(plant, Bw)
    elif _is_scalar(raw_w):
        std = np.full(nw, parse_number(raw_w, r.key("disturbance_std"), above=0.0, at_most=MAX_STD))
    else:
        std = parse_vector(raw_w, r.key("disturbance_std"), nw)
    std = np.asarray(std, dtype=float)
    if np.any(std <= 0) or np.any(std > MAX_STD):
        raise r.fail("disturbance_std", f"must be > 0 and <= {MAX_STD:g}, got {std.tolist()}")
    Q = r.read("Q", parse_covariance, n, semidefinite=True) if r.given("Q") else \
        bryson_state_weight(plant)
    out: dict[str, Any] = {"time_domain": time_domain, "Bw": _ro(Bw), "disturbance_std": _ro(std),
                           "Q": _ro(np.asarray(Q, float))}
    if observer:
        Cz = np.array(r.read("Cz", parse_matrix, (None, n))) if r.given("Cz") else _sqrtm_psd(Q)
        raw_v = r.options.get("measurement_std")
        if raw_v is None:
            vstd = 0.01 * _output_span(plant)
        elif _is_scalar(raw_v):
            vstd = np.full(plant.q, r.read("measurement_std", parse_number, above=0.0, at_most=MAX_STD))
        else:
            vstd = np.asarray(r.read("measurement_std", parse_vector, plant.q), float)
            if np.any(vstd <= 0) or np.any(vstd > MAX_STD):
                raise r.fail("measurement_std", f"must be > 0 and <= {MAX_STD:g}, got {vstd.tolist()}")
        out.update({"Cz": _ro(Cz), "measurement_std": _ro(np.asarray(vstd, float))})
    else:
        if r.given("Cz") != r.given("Dzu"):
            raise r.fail("Cz" if r.given("Cz") else "Dzu", "give Cz and Dzu together (or neither: "
                                                            "[Q^1/2; 0] and [0; R^1/2])")
        R = r.read("R", parse_covariance, m) if r.given("R") else bryson_input_weight(plant)
        if r.given("Cz"):
            Cz = np.array(r.read("Cz", parse_matrix, (None, n)))
            Dzu = np.array(r.read("Dzu", parse_matrix, (Cz.shape[0], m)))
        else:
            Cz = np.vstack([_sqrtm_psd(Q), np.zeros((m, n))])
            Dzu = np.vstack([np.zeros((n, m)), _sqrtm_psd(R)])
        out.update({"R": _ro(np.asarray(R, float)), "Cz": _ro(Cz), "Dzu": _ro(Dzu)})
    out["margin"] = r.read("margin", parse_number, above=0.0, below=1e-2)
    out["solver"] = r.read("solver", parse_choice, SYNTHESIS_SOLVERS)
    return out


def _route(r: OptionReader) -> str:
    return r.read("route", parse_choice, SYNTHESIS_ROUTES)


def _is_scalar(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _ro(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class _SynthesisOptions(MethodOptions):
    """Shared fields (see the subclasses)."""

    time_domain: str | None = option(None, unit="-",
                                     default_text=TIME_DOMAIN_TEXT, choices=("continuous", "discrete"))
    Bw: Any = option("inflows", unit="state units/s per disturbance unit", choices=DISTURBANCE_SHORTCUTS)
    disturbance_std: Any = option("auto", unit="disturbance units (\"inflows\": level unit x "
                                                  "area unit / s)")
    Q: Any = option(None, unit="1/(state units)^2")
    Cz: Any = option(None, unit="performance units per state unit")
    margin: float = option(1e-9, unit="-")
    solver: str = option("CLARABEL", unit="-", choices=SYNTHESIS_SOLVERS)

    def conic_size(self, plant: Plant, ts: float | None) -> ConicSize | None:
        """The LMI route's problem (`tanksynth.design.synthesis.synthesize`); None on the Riccati route.

        Variables ``X`` (n x n, symmetric), ``Y`` (m x n), ``W`` (nz x nz, H2),
        ``gamma`` and the phase-2 margin; blocks ``X > 0``, the H2 pair, the
        bounded real lemma (reduced without H2), the region (``order n``) and
        phase 2's ``X < cap I``. An observer is the dual (``m -> q``, ``nw <->
        nz``).
        """
        region = tuple(getattr(self, "region", ()) or ())
        bounds = getattr(self, "h2_bound", None) is not None or getattr(self, "hinf_bound", None) is not None
        if self.method_name != "multiobjective" and getattr(self, "route", "auto") != "lmi":
            return None  # one model, no region, no bound: the Riccati route applies
        objective = getattr(self, "objective", "h2" if self.method_name.startswith("h2") else "hinf")
        use_h2 = objective == "h2" or getattr(self, "h2_bound", None) is not None
        use_hinf = objective == "hinf" or getattr(self, "hinf_bound", None) is not None
        n, nw = plant.n, int(np.shape(self.Bw)[1])
        nz = int(np.shape(self.Cz)[0]) if self.Cz is not None else n
        if getattr(self, "target", "observer" if "observer" in self.method_name else "") == "observer":
            m, nw, nz = plant.q, nz, nw + plant.q
        else:
            m = plant.m
        discrete = (self.time_domain or time_domain_of(ts)) == "discrete"
        blocks: list[float] = [n, n]  # X > 0 and phase 2's X < cap I
        if use_h2:
            blocks += [2 * n if discrete else n, nz + n]
        if use_hinf:
            blocks.append((2 * n if discrete else n) + nz + (0 if not use_h2 else nw))
        if region:
            blocks.append(region_order(region) * n)
        advice = ("fewer states (a smaller plant, e.g. fewer tanks N)"
                  + (", a region of lower order (one disk or half-plane)" if region else "")
                  + ("" if region or bounds or self.method_name == "multiobjective"
                     else ', route = "auto" (Riccati)')
                  + ", or a decentralised method (decentralized_kalman)")
        return ConicSize(variables=n * (n + 1) / 2 + m * n + (nz * (nz + 1) / 2 if use_h2 else 0) + 2,
                         psd_orders=tuple(blocks), linear_rows=4, advice=advice)


@dataclass(frozen=True, eq=False)
class _StateFeedbackOptions(_SynthesisOptions):
    R: Any = option(None, unit="1/(input units)^2")
    Dzu: Any = option(None, unit="performance units per input unit")


@dataclass(frozen=True, eq=False)
class H2StateFeedbackOptions(_StateFeedbackOptions):
    __doc__ = f"""Options of ``h2_state_feedback``: ``u = -K x`` minimising the H2 norm from ``w`` to
    ``z`` by an LMI (the LQR optimum for ``Q = Cz' Cz``, ``R = Dzu' Dzu``).

    Attributes
    ----------{_COMMON_DOC}{_SF_DOC}{_ROUTE_DOC}
    """

    method_name: ClassVar[str] = "h2_state_feedback"
    route: str = option("auto", unit="-", choices=SYNTHESIS_ROUTES, default_text=_ROUTE_TEXT)

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "H2StateFeedbackOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(**_common(r, plant, ts, observer=False), route=_route(r))


@dataclass(frozen=True, eq=False)
class H2ObserverOptions(_SynthesisOptions):
    __doc__ = f"""Options of ``h2_observer``: observer gain ``L`` minimising the H2 norm from ``(w, v)``
    to the weighted estimation error (the steady Kalman filter, predictor form in discrete time).

    Attributes
    ----------{_COMMON_DOC}{_OBS_DOC}{_ROUTE_DOC}
    """

    method_name: ClassVar[str] = "h2_observer"
    measurement_std: Any = option(None, unit="output units")
    route: str = option("auto", unit="-", choices=SYNTHESIS_ROUTES, default_text=_ROUTE_TEXT)

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "H2ObserverOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(**_common(r, plant, ts, observer=True), route=_route(r))


_BACKOFF_DOC = """
    backoff : float
        Relative back-off from the optimum (0 to 1; default 1e-3): the gain
        keeps the bound within ``(1 + backoff)`` of the optimum (a moderate
        gain instead of the boundary). LMI route: a second solve maximises the
        LMIs' margin under that bound; Riccati route: the central gain at
        ``gamma = (1 + backoff) gamma_optimum`` (one more Riccati solve)."""


@dataclass(frozen=True, eq=False)
class HinfStateFeedbackOptions(_StateFeedbackOptions):
    __doc__ = f"""Options of ``hinf_state_feedback``: ``u = -K x`` minimising the H-infinity norm
    (L2 gain) from ``w`` to ``z`` by the bounded-real-lemma LMI.

    Attributes
    ----------{_COMMON_DOC}{_SF_DOC}{_BACKOFF_DOC}{_ROUTE_DOC}
    """

    method_name: ClassVar[str] = "hinf_state_feedback"
    backoff: float = option(1e-3, unit="-")
    route: str = option("auto", unit="-", choices=SYNTHESIS_ROUTES, default_text=_ROUTE_TEXT)

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "HinfStateFeedbackOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(**_common(r, plant, ts, observer=False),
                   backoff=r.read("backoff", parse_number, at_least=0.0, at_most=1.0), route=_route(r))


@dataclass(frozen=True, eq=False)
class HinfObserverOptions(_SynthesisOptions):
    __doc__ = f"""Options of ``hinf_observer``: observer gain ``L`` minimising the H-infinity norm
    from ``(w, v)`` to the weighted estimation error.

    Attributes
    ----------{_COMMON_DOC}{_OBS_DOC}{_BACKOFF_DOC}{_ROUTE_DOC}
    """

    method_name: ClassVar[str] = "hinf_observer"
    measurement_std: Any = option(None, unit="output units")
    backoff: float = option(1e-3, unit="-")
    route: str = option("auto", unit="-", choices=SYNTHESIS_ROUTES, default_text=_ROUTE_TEXT)

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "HinfObserverOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(**_common(r, plant, ts, observer=True),
                   backoff=r.read("backoff", parse_number, at_least=0.0, at_most=1.0), route=_route(r))


@dataclass(frozen=True, eq=False)
class MultiobjectiveOptions(_StateFeedbackOptions):
    __doc__ = f"""Options of ``multiobjective``: H2 and/or H-infinity objective and bounds with the
    closed-loop eigenvalues in an LMI region, one common Lyapunov matrix (msfsyn-style;
    conservative: the bounds hold, the achieved norms are recomputed).

    Attributes
    ----------
    region : tuple of mapping
        Required. LMI region, a list of tables as for ``lmi_placement`` (e.g.
        ``[{{type = "disk", center = 0.9, radius = 0.08}}]``); one part must lie
        in the stability domain of ``time_domain``.
    target : str
        Required: ``"state_feedback"`` (gain ``K``) or ``"observer"`` (gain ``L``).
    objective : str
        ``"hinf"`` (default) or ``"h2"``: the norm minimised.
    h2_bound : float or None
        Required bound on the H2 norm (its units); default None.
    hinf_bound : float or None
        Required bound on the H-infinity norm (z unit per w unit); default None.{_COMMON_DOC}{_SF_DOC}
        (state feedback only){_OBS_DOC} (observer only){_BACKOFF_DOC}
    """

    method_name: ClassVar[str] = "multiobjective"
    region: tuple = option(unit="1/s (continuous) or - (discrete, z-plane)")
    target: str = option(unit="-", choices=SYNTHESIS_TARGETS)
    objective: str = option("hinf", unit="-", choices=SYNTHESIS_OBJECTIVES)
    h2_bound: float | None = option(None, unit="-", default_text="unset: no H2 bound")
    hinf_bound: float | None = option(None, unit="-", default_text="unset: no H-infinity bound")
    measurement_std: Any = option(None, unit="output units")
    backoff: float = option(1e-3, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "MultiobjectiveOptions":
        """See `MethodOptions.from_table`; the region must be stable in the time domain."""
        r = OptionReader(cls, options, key, ts)
        target = r.read("target", parse_choice, SYNTHESIS_TARGETS)
        observer = target == "observer"
        for opt in (("R", "Dzu") if observer else ("measurement_std",)):
            if r.given(opt):
                raise r.fail(opt, f"option {opt!r} does not apply to target = {target!r}")
        common = _common(r, plant, ts, observer=observer)
        region = r.read("region", parse_region)
        if not region_is_stable(region, common["time_domain"]):
            raise r.fail("region", f"the region is not inside the {common['time_domain']}-time "
                                   "stability domain (continuous: add a half-plane alpha >= 0, a disk "
                                   "left of 0 or a sector; discrete: add a disk with |center| + "
                                   "radius <= 1)")
        h2_bound, hinf_bound = (r.read(name, parse_number, above=0.0, at_most=MAX_NORM_BOUND)
                                if r.given(name) else None for name in ("h2_bound", "hinf_bound"))
        return cls(**common, region=region, target=target,
                   objective=r.read("objective", parse_choice, SYNTHESIS_OBJECTIVES),
                   h2_bound=h2_bound, hinf_bound=hinf_bound,
                   backoff=r.read("backoff", parse_number, at_least=0.0, at_most=1.0))
