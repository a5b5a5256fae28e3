"""Control laws and observer steps of the synthesis, robust and Takagi-Sugeno designs, for
``--export law`` (`tanksynth.artefacts.export.derived_law` dispatches here).

Each law is the one the method's verdict and campaign runner simulate, rebuilt
from the artefact's gains and the spec, as a CasADi SX Function (generated C
with `tanksynth.artefacts.export.export_law`):

``h2_state_feedback``, ``hinf_state_feedback``, ``multiobjective`` (state feedback)
    ``u = law(x)``: ``u = u_op - K (x - x_op)``.
``h2_observer``, ``hinf_observer``, ``multiobjective`` (observer), ``robust_observer``
    the Luenberger observer on the model linearised at the operating point:
    ``x_hat_next = step(x_hat, u, y)`` (predictor form, discrete designs) or
    ``x_hat_dot = step(x_hat, u, y)`` (continuous designs); ``robust_observer`` on
    the NOMINAL model (as deployed; the plant's parameters are unknown to it).
``robust_state_feedback``
    ``u = u_op - K (x - x_op)`` with the nominal ``u_op``; with integral action
    ``u, z_next = law(x, z, y_r)`` (``z_dot`` in continuous time), ``u = u_op - K1
    (x - x_op) - K2 z``, ``z_next = z + ts (y_r - y_op - C1 (x - x_op))`` (the measured
    outputs' error, ``y_op = h(x_op)`` of the tracked outputs, offsets included).
``ts_state_feedback``
    PDC ``u = law(x)``: ``u = u_op - sum_i mu_i(x) K_i (x - x_op)``, memberships from
    the premises' secant slopes; saturated to the pumps' range when the design
    declares ``pump_limits``.
``ts_output_feedback``
    ``u, x_hat_dot = law(x_hat, u_applied, y)``: the PDC on the estimate (premises at
    the estimate with its measured entries replaced by ``y`` for measured premises)
    and the observer's vector field with the input ``u_applied`` and ``y`` held.

Gains are read in one small helper per builder (``_*_gains``), which accepts
today's keys and the renamed ones (``x_op``/``u_op`` for ``x0``/``u0``).
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING, Any, Callable, Literal, Mapping, overload

import casadi as ca
import numpy as np

from tanksynth.analysis.linearize import linearize
from tanksynth.artefacts.export import (observer_law, operating_point, sampling_period, saturate_input,
                                        state_feedback_law)
from tanksynth.errors import ArtefactError
from tanksynth.runtime.laws import tracking_error

if TYPE_CHECKING:
    from tanksynth.plants.base import Plant
    from tanksynth.spec import Spec
    from tanksynth.spec.method_options.base import MethodOptions

__all__ = ["SYNTHESIS_LAW_METHODS", "synthesis_law", "integral_feedback_law",
           "nominal_observer_law", "ts_memberships", "pdc_law", "pdc_output_feedback_law"]

#: Methods whose law `synthesis_law` builds.
SYNTHESIS_LAW_METHODS = ("h2_state_feedback", "h2_observer", "hinf_state_feedback", "hinf_observer",
                         "multiobjective", "robust_state_feedback", "robust_observer",
                         "ts_state_feedback", "ts_output_feedback")

#: ``|a_k . (x - x_op)|`` below which a premise takes its slope at the operating point (state units).
PREMISE_SINGULAR = 1e-12


# ------------------------------------------------------------------------ reading gains
@overload
def _gain(gains: Mapping[str, Any], *keys: str, required: Literal[True] = True) -> np.ndarray:
    ...


@overload
def _gain(gains: Mapping[str, Any], *keys: str, required: bool) -> np.ndarray | None:
    ...


def _gain(gains: Mapping[str, Any], *keys: str, required: bool = True) -> np.ndarray | None:
    """The first of ``keys`` present in ``gains`` as a float array (None if absent and optional)."""
    for key in keys:
        if key in gains and gains[key] is not None:
            return np.asarray(gains[key], dtype=float)
    if required:
        raise ArtefactError(f"the artefact's gains lack {' / '.join(keys)} (law export)")
    return None


def _time_domain(diagnostics: Mapping[str, Any], options: MethodOptions | None, spec: Spec) -> str:
    value = diagnostics.get("time_domain", getattr(options, "time_domain", None))
    if value in ("continuous", "discrete"):
        return str(value)
    return "discrete" if spec.ts is not None else "continuous"


def _synthesis_gains(gains: Mapping[str, Any], plant: Plant) -> dict[str, np.ndarray]:
    """``K`` (m, n) or ``L`` (n, q) of an H2 / H-infinity / multi-objective / robust observer design."""
    if "L" in gains:
        return {"L": _gain(gains, "L").reshape(plant.n, plant.q)}
    return {"K": _gain(gains, "K").reshape(plant.m, -1)}


def _robust_gains(gains: Mapping[str, Any], plant: Plant) -> dict[str, Any]:
    """``K`` (or ``K1``, ``K2``), the model's ``C`` and the operating point of a robust state feedback."""
    n, m = plant.n, plant.m
    out: dict[str, Any] = {"x_op": _gain(gains, "x_op").reshape(n),
                           "u_op": _gain(gains, "u_op").reshape(m),
                           "C": _gain(gains, "C").reshape(plant.q, n)}
    if "K1" in gains and "K2" in gains:
        out["K1"] = _gain(gains, "K1").reshape(m, n)
        out["K2"] = _gain(gains, "K2").reshape(m, -1)
    else:
        out["K"] = _gain(gains, "K").reshape(m, n)
    return out


def _ts_gains(gains: Mapping[str, Any], plant: Plant) -> dict[str, Any]:
    """PDC gains, operating point, premise forms and bounds (and observer gain) of a TS design."""
    n, m = plant.n, plant.m
    forms = _gain(gains, "forms").reshape(-1, n)
    r = 2 ** forms.shape[0]
    out: dict[str, Any] = {"x_op": _gain(gains, "x_op").reshape(n),
                           "u_op": _gain(gains, "u_op").reshape(m),
                           "K": _gain(gains, "K").reshape(r, m, n), "forms": forms,
                           "lower": _gain(gains, "z_lower").reshape(-1),
                           "upper": _gain(gains, "z_upper").reshape(-1)}
    L = _gain(gains, "L", required=False)
    if L is not None:
        out["L"] = L.reshape(r, n, plant.q) if L.ndim == 3 else L.reshape(n, plant.q)
    return out


# ----------------------------------------------------------------------------- builders
def integral_feedback_law(name: str, K1: np.ndarray, K2: np.ndarray, C1: np.ndarray,
                          x_op: np.ndarray, u_op: np.ndarray, ts: float | None,
                          input_limits: Any | None = None, y_op: Any | None = None) -> ca.Function:
    """State feedback with integral action on the tracked outputs (robust design's integrators).

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    K1 : ndarray, shape (m, n)
        State gain (input units per state unit).
    K2 : ndarray, shape (m, p)
        Integrator gain (input units per output unit and second).
    C1 : ndarray, shape (p, n)
        Rows of the tracked outputs in the output map linearised at ``x_op``
        (output units per state unit).
    x_op, u_op : ndarray
        Operating point (state units, m) and its input (input units, m^3/s).
    ts : float or None
        Sampling period (s) of a discrete design; None: continuous time.
    input_limits : array_like, shape (m, 2), optional
        Actuator range (input units) ``u`` is clipped to (the integrators are not).
    y_op : array_like, shape (p,), optional
        The tracked outputs at ``x_op``, ``h(x_op)`` (output units, offsets and sensor
        gains included); None: ``C1 x_op`` (an output map linear in the state).

    Returns
    -------
    casadi.Function
        ``u, z_next = law(x, z, y_r)`` with ``u = u_op - K1 (x - x_op) - K2 z`` and
        ``z_next = z + ts (y_r - y_op - C1 (x - x_op))`` (the measured outputs'
        error; ``z`` in output units times s, ``y_r`` the set-points of the tracked
        outputs); continuous time: ``z_dot = y_r - y_op - C1 (x - x_op)``.
    """
    K1, K2, C1 = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (K1, K2, C1))
    x_op, u_op = np.asarray(x_op, dtype=float), np.asarray(u_op, dtype=float)
    p = C1.shape[0]
    y0 = C1 @ x_op if y_op is None else np.asarray(y_op, dtype=float).reshape(-1)
    if y0.shape != (p,):
        raise ArtefactError(f"y_op has {y0.size} values, expected {p} (one per tracked output)")
    x, z, r = ca.SX.sym("x", x_op.size), ca.SX.sym("z", p), ca.SX.sym("y_r", p)
    u = saturate_input(ca.DM(u_op) - ca.DM(K1) @ (x - ca.DM(x_op)) - ca.DM(K2) @ z, input_limits)
    err = tracking_error(r, x, C1, x_op, y0)
    if ts is None:
        return ca.Function(name, [x, z, r], [u, err], ["x", "z", "y_r"], ["u", "z_dot"])
    return ca.Function(name, [x, z, r], [u, z + float(ts) * err], ["x", "z", "y_r"], ["u", "z_next"])


def nominal_observer_law(name: str, plant: Plant, L: np.ndarray, x_op: np.ndarray, u_op: np.ndarray,
                         ts: float | None) -> ca.Function:
    """The Luenberger observer the verdicts run, on the plant linearised at the operating point.

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    plant : Plant
        The spec's plant (nominal parameters).
    L : ndarray, shape (n, q)
        Observer gain (state units per output unit; per second in continuous time).
    x_op, u_op : ndarray
        Operating point (state units, m) and its equilibrium input (input units, m^3/s).
    ts : float or None
        Sampling period (s) of a discrete design (predictor form, ZOH model); None: continuous.

    Returns
    -------
    casadi.Function
        ``x_hat_next = step(x_hat, u, y)``: ``x_op + Ad dx + Bd du + L (dy - C dx)`` with ``y``
        measured at the time of ``x_hat`` and ``u`` held over the coming period; continuous
        time ``x_hat_dot = F dx + B du + L (dy - C dx)`` (deviations from the operating point).
    """
    x_op, u_op = np.asarray(x_op, dtype=float), np.asarray(u_op, dtype=float)
    lin = linearize(plant, x_op.tolist(), u_op.tolist(), ts=ts)
    y_op = np.asarray(plant.compiled.output(x_op[None]), dtype=float).reshape(-1)
    if ts is None or lin.Ad is None or lin.Bd is None:  # Ad, Bd: set whenever ts is
        return observer_law(name, lin.F, lin.B, lin.C, L, x_op, u_op, y_op, "continuous")
    return observer_law(name, lin.Ad, lin.Bd, lin.C, L, x_op, u_op, y_op, "predictor")


def ts_memberships(plant: Plant, x_op: np.ndarray, forms: np.ndarray, lower: np.ndarray,
                   upper: np.ndarray) -> Callable[[ca.SX], ca.SX]:
    """Memberships ``mu_i(x)`` of the deviation TS model of a design, as CasADi expressions.

    The premises are the secant slopes ``z_k = (n_k(x) - n_k(x_op)) / (a_k . (x - x_op))``
    of the plant's quasi-LPV atoms ``n_k`` (`tanksynth.analysis.quasi_lpv.quasi_lpv`),
    their slope at ``x_op`` (central difference, step 1e-6 m along ``a_k``) where
    ``|a_k . (x - x_op)| < 1e-12``; ``F_k = (z_k - lower_k) / (upper_k - lower_k)`` and
    ``mu_i = prod_k (F_k or 1 - F_k)`` over the vertices in ``itertools.product((1, 2),
    repeat=p)`` order (1: the upper bound), the order of the gains ``K_i``.

    Parameters
    ----------
    plant : Plant
        The spec's plant.
    x_op : ndarray, shape (n,)
        Operating point (state units, m).
    forms : ndarray, shape (p, n)
        The premises' linear forms ``a_k`` (dimensionless).
    lower, upper : ndarray, shape (p,)
        Premise bounds (units of ``n_k`` per state unit).

    Returns
    -------
    callable
        ``mu(x)`` for an SX column ``x`` (n): an SX column of the ``2^p`` memberships.
    """
    from tanksynth.analysis.takagi_sugeno import quasi_lpv
    from tanksynth.plants.compile import to_casadi

    q = quasi_lpv(plant)
    x_op, forms = np.asarray(x_op, dtype=float), np.asarray(forms, dtype=float)
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    p = forms.shape[0]
    if len(q.atoms) != p:
        raise ArtefactError(f"the artefact records {p} premise forms, the plant's quasi-LPV form has "
                            f"{len(q.atoms)} atoms")
    at0 = q.atom_values(x_op[None, :])[0]
    h = 1e-6
    d = forms / np.sum(forms ** 2, axis=1, keepdims=True)
    slope0 = np.array([(q.atom_values((x_op + h * d[k])[None, :])[0, k]
                        - q.atom_values((x_op - h * d[k])[None, :])[0, k]) / (2 * h) for k in range(p)])
    sigmas = list(itertools.product((1, 2), repeat=p))

    def mu(x: ca.SX) -> ca.SX:
        symbols = dict(zip(q.states, ca.vertsplit(x)))
        cache: dict = {}
        F = []
        for k in range(p):
            atom = to_casadi(q.atoms[k], symbols, cache)
            dt = ca.dot(ca.DM(forms[k]), x - ca.DM(x_op))
            small = ca.fabs(dt) < PREMISE_SINGULAR
            z = ca.if_else(small, float(slope0[k]), (atom - float(at0[k])) / ca.if_else(small, 1.0, dt))
            F.append((z - float(lower[k])) / float(upper[k] - lower[k]))
        out = []
        for sig in sigmas:
            w = ca.SX(1.0)
            for k, s in enumerate(sig):
                w = w * (F[k] if s == 1 else 1.0 - F[k])
            out.append(w)
        return ca.vertcat(*out)

    return mu


def _pdc(mu: ca.SX, K: np.ndarray, e: ca.SX, u_op: np.ndarray) -> ca.SX:
    u = ca.SX(ca.DM(u_op))
    for i in range(K.shape[0]):
        u = u - mu[i] * (ca.DM(K[i]) @ e)
    return u


def pdc_law(name: str, K: np.ndarray, x_op: np.ndarray, u_op: np.ndarray,
            memberships: Callable[[ca.SX], ca.SX], limits: np.ndarray | None = None) -> ca.Function:
    """The parallel distributed compensation ``u = u_op - sum_i mu_i(x) K_i (x - x_op)``.

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    K : ndarray, shape (r, m, n)
        Vertex gains (input units per state unit, m^3/s per m).
    x_op, u_op : ndarray
        Operating point (state units, m) and its input (input units, m^3/s).
    memberships : callable
        `ts_memberships` of the design.
    limits : ndarray, shape (m, 2), optional
        Actuator range (input units): the input is clipped to it (infinite bounds ignored).

    Returns
    -------
    casadi.Function
        ``u = law(x)``.
    """
    K = np.asarray(K, dtype=float)
    x_op = np.asarray(x_op, dtype=float)
    x = ca.SX.sym("x", x_op.size)
    u = saturate_input(_pdc(memberships(x), K, x - ca.DM(x_op), u_op), limits)
    return ca.Function(name, [x], [u], ["x"], ["u"])


def pdc_output_feedback_law(name: str, plant: Plant, K: np.ndarray, L: np.ndarray, x_op: np.ndarray,
                            u_op: np.ndarray, memberships: Callable[[ca.SX], ca.SX],
                            vertices: np.ndarray | None = None, limits: np.ndarray | None = None
                            ) -> ca.Function:
    """The PDC on the TS observer's estimate, and the observer (continuous time).

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    plant : Plant
        The spec's plant (its ``f`` is the estimated-premise observer's model).
    K : ndarray, shape (r, m, n)
        Vertex controller gains (input units per state unit).
    L : ndarray, shape (r, n, q) or (n, q)
        Vertex observer gains (measured premises) or the one gain of the seed 001 observer
        (estimated premises), 1/s.
    x_op, u_op : ndarray
        Operating point (state units, m) and its input (input units, m^3/s).
    memberships : callable
        `ts_memberships` of the design.
    vertices : ndarray, shape (r, n, n), optional
        Vertex matrices ``A_i`` of the deviation TS model (1/s); needed with measured premises.
    limits : ndarray, shape (m, 2), optional
        Actuator range (input units) the control is clipped to.

    Returns
    -------
    casadi.Function
        ``u, x_hat_dot = law(x_hat, u_applied, y)``. The output ``u`` is the PDC at the
        estimate; ``u_applied`` is the input applied over the period (the law's own output
        after any actuator saturation; CasADi refuses one name for an input and an output)
        and ``y`` the latest measurement (held). Measured premises
        (``L`` 3-D): premises at ``x_hat`` with its measured entries replaced by ``y``;
        ``x_hat_dot = sum_i mu_i (A_i (x_hat - x_op) + B (u - u_op)) + sum_j mu_j L_j (y -
        C x_hat)``. Estimated premises: premises at ``x_hat``; ``x_hat_dot = f(x_hat, u) + L
        (y - C x_hat)`` (seed 001 eq. 20: the TS model at the estimate is the plant's ``f``).
    """
    from tanksynth.analysis.takagi_sugeno import quasi_lpv

    q = quasi_lpv(plant)
    B, C = q.B, q.C
    K, L = np.asarray(K, dtype=float), np.asarray(L, dtype=float)
    x_op = np.asarray(x_op, dtype=float)
    n = x_op.size
    xh, ua, y = ca.SX.sym("x_hat", n), ca.SX.sym("u", plant.m), ca.SX.sym("y", plant.q)
    innovation = y - ca.DM(C) @ xh
    if L.ndim == 3:
        if vertices is None:
            raise ArtefactError("measured premises: the PDC observer needs the vertex matrices A_i")
        rows = [int(np.flatnonzero(row)[0]) for row in C]
        parts = ca.vertsplit(xh)
        for i, rr in enumerate(rows):
            parts[rr] = y[i]
        mu = memberships(ca.vertcat(*parts))
        e = xh - ca.DM(x_op)
        drift = ca.DM(B) @ (ua - ca.DM(u_op))
        xdot = ca.SX.zeros(n)
        for i in range(K.shape[0]):
            xdot = xdot + mu[i] * (ca.DM(np.asarray(vertices[i], dtype=float)) @ e + drift
                                   + ca.DM(L[i]) @ innovation)
    else:
        mu = memberships(xh)
        xdot = plant.compiled.f(xh, ua) + ca.DM(L) @ innovation
    u = saturate_input(_pdc(mu, K, xh - ca.DM(x_op), u_op), limits)
    return ca.Function(name, [xh, ua, y], [u, xdot], ["x_hat", "u_applied", "y"], ["u", "x_hat_dot"])


def _ts_vertices(plant: Plant, forms: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Vertex matrices ``A_lin + sum_k incidence_k forms_k (upper_k or lower_k)`` (1/s)."""
    from tanksynth.analysis.takagi_sugeno import quasi_lpv

    q = quasi_lpv(plant)
    return np.array([q.A_lin + sum(np.outer(q.incidence[:, k], forms[k])
                                   * (upper[k] if s == 1 else lower[k]) for k, s in enumerate(sig))
                     for sig in itertools.product((1, 2), repeat=forms.shape[0])])


# ---------------------------------------------------------------------------- dispatch
def synthesis_law(gains: Mapping[str, Any], diagnostics: Mapping[str, Any], method: str, spec: Spec,
                  options: MethodOptions | None, name: str) -> ca.Function | None:
    """The law or observer step of a synthesis, robust or Takagi-Sugeno design (see the module).

    Parameters
    ----------
    gains : mapping of str to ndarray
        The design's gains (in the plant's units).
    diagnostics : mapping
        Its diagnostics (time domain, integral action, input margins).
    method : str
        Its method (one of `SYNTHESIS_LAW_METHODS`).
    spec : Spec
        The spec it was designed from (plant, operating point, sampling).
    options : MethodOptions
        Its validated options.
    name : str
        Function name (a C identifier).

    Returns
    -------
    casadi.Function or None
        None for a method not in `SYNTHESIS_LAW_METHODS`.
    """
    if method not in SYNTHESIS_LAW_METHODS:
        return None
    plant = spec.plant
    if method.startswith("ts_"):
        g = _ts_gains(gains, plant)
        mu = ts_memberships(plant, g["x_op"], g["forms"], g["lower"], g["upper"])
        pumps = getattr(options, "pump_limits", diagnostics.get("input_margins") is not None)
        limits = np.asarray(plant.input_limits, dtype=float).reshape(plant.m, 2) if pumps else None
        if method == "ts_state_feedback":
            return pdc_law(name, g["K"], g["x_op"], g["u_op"], mu, limits)
        if "L" not in g:
            raise ArtefactError("ts_output_feedback artefact without an observer gain L")
        vertices = _ts_vertices(plant, g["forms"], g["lower"], g["upper"]) if g["L"].ndim == 3 else None
        return pdc_output_feedback_law(name, plant, g["K"], g["L"], g["x_op"], g["u_op"], mu,
                                       vertices, limits)
    discrete = _time_domain(diagnostics, options, spec) == "discrete"
    ts = sampling_period(spec, method) if discrete else None
    limits = plant.input_limits  # u clipped as the plant the verdict simulates clips it
    if method == "robust_state_feedback":
        g = _robust_gains(gains, plant)
        if "K" in g:
            return state_feedback_law(name, g["K"], g["x_op"], g["u_op"], input_limits=limits)
        integral = diagnostics.get("integral")
        integ: Mapping[str, Any] = integral if isinstance(integral, Mapping) else {}
        outputs = [s.name for s in plant.outputs]
        tracked = list(getattr(options, "tracked", None) or integ.get("tracked")
                       or outputs[:plant.m])
        rows = [outputs.index(t) for t in tracked]
        C1 = integ.get("C1")
        if C1 is None:
            C1 = g["C"][rows]
        y_op = integ.get("y_op")   # h(x_op) of the tracked outputs, offsets included
        if y_op is None:
            y_op = np.asarray(plant.compiled.output(np.asarray(g["x_op"], dtype=float)[None]),
                              dtype=float).reshape(-1)[rows]
        return integral_feedback_law(name, g["K1"], g["K2"], np.asarray(C1, dtype=float), g["x_op"],
                                     g["u_op"], ts, limits, y_op)
    x_op, u_op = operating_point(spec)
    if method == "robust_observer":
        return nominal_observer_law(name, plant, _synthesis_gains(gains, plant)["L"], x_op, u_op, ts)
    g = _synthesis_gains(gains, plant)
    if "L" in g:
        return nominal_observer_law(name, plant, g["L"], x_op, u_op, ts)
    return state_feedback_law(name, g["K"], x_op, u_op, input_limits=limits)
