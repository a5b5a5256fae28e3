"""Spec design methods for optimal convex synthesis (`tanksynth.design.synthesis.synthesize`).

=======================  ==========================================================
``h2_state_feedback``    ``u = -K x`` minimising ``||T_zw||_2`` (LMI; the LQR optimum)
``h2_observer``          observer ``L`` minimising the H2 norm from ``(w, v)`` to the
                         weighted error (LMI; the steady Kalman filter)
``hinf_state_feedback``  ``u = -K x`` minimising ``||T_zw||_inf`` (bounded real lemma)
``hinf_observer``        observer ``L`` minimising the H-infinity norm of the error
``multiobjective``       H2 and/or H-infinity objective and bounds with an LMI pole
                         region, one common Lyapunov matrix (msfsyn-style)
=======================  ==========================================================

Route (option ``route``, default ``"auto"``): the four single-objective methods
solve their Riccati equation (LQR / Kalman; gamma bisection on the game Riccati
equation for H-infinity), which has the LMI's optimum and takes well under a
second at N = 64 where the LMI takes minutes; ``route = "lmi"`` forces the LMI;
``multiobjective`` always uses the LMIs. The route taken is in the diagnostics.

The model is the Jacobian linearisation at the operating point with the
equilibrium input computed from the model (ZOH at ``[sampling] ts`` in discrete
time, the disturbance input ``Bw diag(disturbance_std)`` discretised with it).
Gains: ``K`` or ``L``, the model (``F``, ``B``, ``C`` and the disturbance
matrix ``Bw`` in continuous time, ``Ad``, ``Bd``, ``C``, ``Bwd`` in discrete
time: `model_names`), the synthesis data (``Cz``, ``Dzu`` or ``Dv``) and the
Lyapunov variable ``X``.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import scipy.linalg as sla

from tanksynth.analysis.linearize import discretize_zoh
from tanksynth.analysis.lmi_region import region_from_parts
from tanksynth.analysis.statespace import model_names
from tanksynth.design.operating_point import (discrete_pair, equilibrium_at, linearized_at,
                                              sampling_period)
from tanksynth.design.result import DesignMethod, DesignResult, options_of, rekeyed
from tanksynth.design.synthesis.synthesize import (GeneralizedPlant, SynthesisResult,
                                                   synthesize_observer, synthesize_state_feedback)
from tanksynth.errors import DesignWarning, SpecError
from tanksynth.plants.base import Plant
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options import (H2ObserverOptions, H2StateFeedbackOptions,
                                           HinfObserverOptions, HinfStateFeedbackOptions,
                                           MultiobjectiveOptions)

__all__ = ["run_h2_state_feedback", "run_h2_observer", "run_hinf_state_feedback",
           "run_hinf_observer", "run_multiobjective", "H2_STATE_FEEDBACK", "H2_OBSERVER",
           "HINF_STATE_FEEDBACK", "HINF_OBSERVER", "MULTIOBJECTIVE", "CONSERVATISM"]

#: What the common Lyapunov matrix costs (report and diagnostics).
CONSERVATISM = ("one Lyapunov matrix X serves every objective and the region (msfsyn-style): the "
                "bounds returned are guaranteed, but the best gain for the combined problem may need "
                "different matrices, so the bounds (and the optimum found) can be conservative; the "
                "achieved norms are recomputed from the closed loop")

_DOC = """
    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        The ``[[design]]`` entry; its options were validated when the spec
        was parsed.

    Returns
    -------
    DesignResult

    Raises
    ------
    SpecError
        A value the design itself refuses (the key is named).
    InfeasibleDesign
        The LMIs are infeasible, or the gain fails the independent re-check
        (closed-loop stability, recomputed norms against the claimed bounds,
        region).
"""


def _model(spec: Spec, o: Any) -> dict[str, Any]:
    plant = spec.plant
    eq = equilibrium_at(plant, spec.x0, spec.given_u0)
    discrete = o.time_domain == "discrete"
    lin = linearized_at(plant, spec.x0, eq.u0, ts=spec.ts if discrete else None)
    Bw_c = np.asarray(o.Bw, float) * np.asarray(o.disturbance_std, float)[None, :]
    _warn_disturbance_size(plant, lin.B, Bw_c)
    if discrete:
        (A, B), Bw = discrete_pair(lin), discretize_zoh(lin.F, Bw_c, sampling_period(spec))[1]
    else:
        A, B, Bw = lin.F, lin.B, Bw_c
    return {"A": A, "B": B, "C": lin.C, "Bw": Bw, "eq": eq, "dt": spec.ts if discrete else None}


def _model_gains(m: dict[str, Any], time_domain: str) -> dict[str, np.ndarray]:
    """The model's matrices under their artefact names (`model_names`)."""
    names = model_names(time_domain)
    out = {names[role]: m[role] for role in ("A", "B", "C", "Bw")}
    # the operating point the deviation model (and so the gain) is about
    out["x_op"], out["u_op"] = np.asarray(m["eq"].x0, dtype=float), np.asarray(m["eq"].u0, dtype=float)
    return out


#: Disturbances larger than this multiple of the pumps' full authority get a warning.
DISTURBANCE_AUTHORITY_RATIO = 10.0


def _warn_disturbance_size(plant: Plant, B: np.ndarray, Bw: np.ndarray) -> None:
    """Warn when ``Bw diag(disturbance_std)`` moves the states far faster than the pumps can.

    The H2/H-infinity figures are in the units of ``w``; ``disturbance_std = 1`` with
    ``Bw = "inflows"`` on the SI three-tank means inflows of 1 m^3/s, thousands of times its
    pumps (the default ``"auto"`` is 10 % of the pumps' authority).
    """
    ranges = np.array([float(hi - lo) for lo, hi in plant.input_limits])
    if not np.all(np.isfinite(ranges)) or not np.any(ranges > 0):
        return
    authority = float(np.max(np.abs(np.asarray(B, float)) * ranges[None, :]))
    effect = float(np.max(np.abs(Bw))) if Bw.size else 0.0
    if authority > 0 and effect > DISTURBANCE_AUTHORITY_RATIO * authority:
        warnings.warn(f"the declared disturbances move the states {effect / authority:.3g} times "
                      f"faster than the pumps at full range (Bw diag(disturbance_std) against "
                      f"B diag(input range)): H2/H-infinity figures are in those units; set "
                      f"disturbance_std to a realistic size (with Bw = \"inflows\": an inflow in "
                      f"{_flow_unit(plant)}) or leave it \"auto\" (10 % of the pumps' authority)",
                      DesignWarning, stacklevel=3)


def _flow_unit(plant: Plant) -> str:
    """The plant's volume-flow unit (level unit x tank-area unit per s), e.g. ``"m^3/s"``."""
    units = {p.name: str(getattr(p, "unit", "")) for p in plant.parameters}
    area = units.get("A1", units.get("A", ""))
    level = str(plant.states[0].unit) if plant.n else ""
    if area and level and area.replace(" ", "") == f"{level}^2":
        return f"{level}^3/s"
    if area and level:
        return f"{level} {area}/s"
    return "the unit of w"


def _base_diagnostics(spec: Spec, o: Any, m: dict[str, Any], res: SynthesisResult) -> dict[str, Any]:
    return {"equilibrium": m["eq"].as_dict(), "time_domain": o.time_domain, "ts": spec.ts,
            "assumptions": [a.text for a in spec.plant.assumptions],
            "synthesis": res.as_dict(), "route": res.route, "solver": res.solver, "status": res.status,
            "gamma": res.gamma, "h2": res.h2,
            "disturbances": {"Bw_continuous": np.asarray(o.Bw).tolist(),
                             "disturbance_std": np.asarray(o.disturbance_std).tolist(),
                             "note": "w normalised: the stored Bw includes diag(disturbance_std)"
                                     + (" and the ZOH over ts" if o.time_domain == "discrete" else "")},
            "weights": {"Q": np.asarray(o.Q).tolist(),
                        **({"R": np.asarray(o.R).tolist()} if getattr(o, "R", None) is not None else {})}}


def _riccati_state_feedback(P: GeneralizedPlant) -> dict:
    """The LQR (Riccati) optimum for ``Q = Cz'Cz``, ``R = Dzu'Dzu``, ``S = Cz'Dzu``: evidence."""
    Q, R, S = P.Cz.T @ P.Cz, P.Dzu.T @ P.Dzu, P.Cz.T @ P.Dzu
    try:
        if P.domain == "continuous":
            X = sla.solve_continuous_are(P.A, P.B, Q, R, s=S)
            K = np.linalg.solve(R, P.B.T @ X + S.T)
        else:
            X = sla.solve_discrete_are(P.A, P.B, Q, R, s=S)
            K = np.linalg.solve(R + P.B.T @ X @ P.B, P.B.T @ X @ P.A + S.T)
    except (np.linalg.LinAlgError, ValueError) as exc:
        return {"available": False, "reason": str(exc)}
    return {"available": True, "h2": float(np.sqrt(max(np.trace(P.Bw.T @ X @ P.Bw), 0.0))),
            "K": K.tolist(), "method": "scipy solve_%s_are" % ("continuous" if P.domain == "continuous"
                                                                 else "discrete")}


def _riccati_observer(A: np.ndarray, C: np.ndarray, Bw: np.ndarray, Dv: np.ndarray, Cz: np.ndarray,
                      domain: str) -> dict[str, Any]:
    """The steady Kalman filter (predictor in discrete time) for ``Bw w``, ``Dv v``: evidence."""
    Qn, Rn = Bw @ Bw.T, Dv @ Dv.T
    try:
        if domain == "continuous":
            S = sla.solve_continuous_are(A.T, C.T, Qn, Rn)
            L = S @ C.T @ np.linalg.inv(Rn)
        else:
            S = sla.solve_discrete_are(A.T, C.T, Qn, Rn)
            L = A @ S @ C.T @ np.linalg.inv(C @ S @ C.T + Rn)
    except (np.linalg.LinAlgError, ValueError) as exc:
        return {"available": False, "reason": str(exc)}
    return {"available": True, "h2": float(np.sqrt(max(np.trace(Cz @ S @ Cz.T), 0.0))),
            "L": L.tolist(), "method": "scipy solve_%s_are (dual)" % domain}


def _state_feedback(spec: Spec, design: DesignSpec, o: Any, method: str, objective: str, *,
                    extra_diagnostics: dict[str, Any] | None = None, **kw: Any) -> DesignResult:
    m = _model(spec, o)
    P = GeneralizedPlant(m["A"], m["B"], m["Bw"], o.Cz, o.Dzu, o.time_domain, m["dt"])
    try:
        res = synthesize_state_feedback(P, objective=objective, margin=o.margin, solver=o.solver,
                                        route=getattr(o, "route", "lmi"), **kw)
    except SpecError as exc:
        raise rekeyed(design, exc) from None
    diag = _base_diagnostics(spec, o, m, res)
    if method == "h2_state_feedback":
        ref = _riccati_state_feedback(P)
        if ref["available"] and res.h2 is not None:
            ref["relative_difference"] = abs(res.h2 - ref["h2"]) / max(ref["h2"], 1e-300)
        diag["riccati_reference"] = ref
    diag.update(extra_diagnostics or {})
    gains = {"K": res.K, **_model_gains(m, o.time_domain),
             "Cz": np.asarray(o.Cz), "Dzu": np.asarray(o.Dzu), "X": res.X}
    return DesignResult(design.name, method, spec.plant.name, gains, diag, {})


def _observer(spec: Spec, design: DesignSpec, o: Any, method: str, objective: str, *,
              extra_diagnostics: dict[str, Any] | None = None, **kw: Any) -> DesignResult:
    m = _model(spec, o)
    Dv = np.diag(np.asarray(o.measurement_std, float))
    Cz = np.asarray(o.Cz)
    try:
        res = synthesize_observer(m["A"], m["C"], m["Bw"], Dv, Cz, domain=o.time_domain, dt=m["dt"],
                                  objective=objective, margin=o.margin, solver=o.solver,
                                  route=getattr(o, "route", "lmi"), **kw)
    except SpecError as exc:
        raise rekeyed(design, exc) from None
    diag = _base_diagnostics(spec, o, m, res)
    diag["measurement_std"] = np.asarray(o.measurement_std).tolist()
    diag["observer_form"] = "predictor" if o.time_domain == "discrete" else "continuous"
    if method == "h2_observer":
        ref = _riccati_observer(m["A"], m["C"], m["Bw"], Dv, Cz, o.time_domain)
        if ref["available"] and res.h2 is not None:
            ref["relative_difference"] = abs(res.h2 - ref["h2"]) / max(ref["h2"], 1e-300)
        diag["riccati_reference"] = ref
    diag.update(extra_diagnostics or {})
    gains = {"L": res.L, **_model_gains(m, o.time_domain), "Dv": Dv,
             "Cz": Cz, "X": res.X}
    return DesignResult(design.name, method, spec.plant.name, gains, diag, {})


def run_h2_state_feedback(spec: Spec, design: DesignSpec) -> DesignResult:
    """``u = -K x`` minimising the H2 norm from ``w`` to ``z`` (LMI; diagnostics: the LQR optimum)."""
    return _state_feedback(spec, design, options_of(design, spec, H2StateFeedbackOptions),
                           "h2_state_feedback", "h2")


def run_h2_observer(spec: Spec, design: DesignSpec) -> DesignResult:
    """Observer ``L`` minimising the H2 norm of the weighted error (diagnostics: the Kalman optimum)."""
    return _observer(spec, design, options_of(design, spec, H2ObserverOptions), "h2_observer", "h2")


def run_hinf_state_feedback(spec: Spec, design: DesignSpec) -> DesignResult:
    """``u = -K x`` minimising the H-infinity norm from ``w`` to ``z`` (bounded real lemma)."""
    o = options_of(design, spec, HinfStateFeedbackOptions)
    return _state_feedback(spec, design, o, "hinf_state_feedback", "hinf", backoff=o.backoff)


def run_hinf_observer(spec: Spec, design: DesignSpec) -> DesignResult:
    """Observer ``L`` minimising the H-infinity norm from ``(w, v)`` to the weighted error."""
    o = options_of(design, spec, HinfObserverOptions)
    return _observer(spec, design, o, "hinf_observer", "hinf", backoff=o.backoff)


def run_multiobjective(spec: Spec, design: DesignSpec) -> DesignResult:
    """H2 / H-infinity objective and bounds with an LMI pole region, one common Lyapunov matrix."""
    o = options_of(design, spec, MultiobjectiveOptions)
    try:
        region = region_from_parts(o.region)
    except SpecError as exc:
        raise rekeyed(design, exc, "region") from None
    kw = dict(region=region, h2_bound=o.h2_bound, hinf_bound=o.hinf_bound, backoff=o.backoff)
    extra = {"conservatism": CONSERVATISM, "target": o.target}
    if o.target == "observer":
        return _observer(spec, design, o, "multiobjective", o.objective, extra_diagnostics=extra,
                         **kw)
    return _state_feedback(spec, design, o, "multiobjective", o.objective, extra_diagnostics=extra,
                           **kw)


for _fn in (run_h2_state_feedback, run_h2_observer, run_hinf_state_feedback, run_hinf_observer,
            run_multiobjective):
    _fn.__doc__ = (_fn.__doc__ or "") + "\n" + _DOC

H2_STATE_FEEDBACK = DesignMethod("h2_state_feedback", run_h2_state_feedback, H2StateFeedbackOptions)
H2_OBSERVER = DesignMethod("h2_observer", run_h2_observer, H2ObserverOptions)
HINF_STATE_FEEDBACK = DesignMethod("hinf_state_feedback", run_hinf_state_feedback,
                                   HinfStateFeedbackOptions)
HINF_OBSERVER = DesignMethod("hinf_observer", run_hinf_observer, HinfObserverOptions)
MULTIOBJECTIVE = DesignMethod("multiobjective", run_multiobjective, MultiobjectiveOptions)
