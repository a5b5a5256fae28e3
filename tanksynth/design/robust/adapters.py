"""Spec design methods ``robust_state_feedback`` and ``robust_observer`` (polytopic LMIs).

=========================  ====================================================
``robust_state_feedback``  one ``K`` (``u = u0 - K (x - x0)``, optionally with
                           integral action ``K1``, ``K2``) with the closed-loop
                           eigenvalues of every vertex model in an LMI region,
                           optional H-infinity bound and saturation-aware
                           invariant ellipsoid
``robust_observer``        one ``L`` with ``eig(A_i - L C_i)`` in the region at
                           every vertex, optional H-infinity bound
=========================  ====================================================

The models are the linearisations at the spec's operating LEVELS at every
corner of the box of uncertain parameters, plus the nominal model, each with
its own equilibrium input (re-trimmed; see `tanksynth.design.robust.polytopic`). The
law applies the NOMINAL equilibrium input: without integral action a plant
whose parameters differ from the nominal ones settles with an offset, which
the diagnostics predict per vertex (``offsets``).
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp

from tanksynth.analysis.lmi_region import region_from_parts
from tanksynth.analysis.rank import controllability_rank, observability_rank
from tanksynth.analysis.statespace import model_names
from tanksynth.design.operating_point import equilibrium_at, time_domain_of
from tanksynth.design.result import DesignMethod, DesignResult, options_of, rekeyed
from tanksynth.design.robust.polytopic import (HinfBound, SaturationBound, ellipsoid_axes,
                                               robust_observer, robust_state_feedback)
from tanksynth.design.robust.vertices import VertexModels, augment_integral, polytope_check, vertex_models
from tanksynth.errors import (DesignWarning, InfeasibleDesign, SpecError, UncontrollableError,
                              UnobservableError)
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.context import resolve
from tanksynth.spec.fit_box import read_fit_box
from tanksynth.spec.method_options.robust import RobustObserverOptions, RobustStateFeedbackOptions

__all__ = ["run_robust_state_feedback", "run_robust_observer", "ROBUST_STATE_FEEDBACK",
           "ROBUST_OBSERVER"]


def _models(spec: Spec, design: DesignSpec, o: Any, Bw: Any) -> tuple[VertexModels, VertexModels,
                                                                          np.ndarray]:
    """Vertex models, the nominal model and the nominal equilibrium input."""
    plant = spec.plant
    ts = spec.ts if o.time_domain == "discrete" else None
    try:
        vm = vertex_models(plant, spec.x0, o.uncertain, o.time_domain, ts, Bw=Bw)
    except SpecError as exc:
        raise rekeyed(design, exc, "uncertain") from None
    nom = vertex_models(plant, spec.x0, (), o.time_domain, ts, Bw=Bw)
    eq = equilibrium_at(plant, spec.x0, spec.given_u0)
    return vm, nom, eq.u0


def _with_fit_box(spec: Spec, design: DesignSpec, o: Any) -> Any:
    """The options with ``uncertain = "fit"`` resolved: the box of the fit result named by ``fit``
    (read again here when the spec was parsed from text), its source kept for the diagnostics."""
    if design.options.get("uncertain") != "fit":
        return o
    if o.fit is None:
        raise SpecError("uncertain = \"fit\" needs fit = \"PATH\": a fit result directory or its "
                        "fit.json, relative to the spec file (tanksynth fit SPEC -o DIR writes one; "
                        "DIR/fitted.toml names it)", key=f"{design.key}.fit", source=spec.source)
    base = Path(spec.source).parent if spec.source and not spec.source.startswith("<") else None
    found = read_fit_box(resolve(o.fit, base), f"{design.key}.fit", spec.plant)
    o = replace(o, uncertain=found.box)
    object.__setattr__(o, "_fit_source", found.source())
    return o


def _stack(vm: VertexModels, nom: VertexModels, name: str) -> np.ndarray:
    """Vertex matrices followed by the nominal one (when there is uncertainty)."""
    mats = getattr(vm, name)
    return np.concatenate([mats, getattr(nom, name)]) if vm.names else mats


def _common_diagnostics(spec: Spec, o: Any, vm: VertexModels, nom: VertexModels, u0: np.ndarray,
                        res: Any) -> dict[str, Any]:
    plant = spec.plant
    poly = polytope_check(plant, spec.x0, o.uncertain, vm, samples=16, seed=o.seed)
    names = list(vm.names)
    labels = [dict(zip(names, map(float, row))) for row in vm.values] + (["nominal"] if names else [])
    worst = res.worst_vertex
    return {
        "time_domain": o.time_domain, "ts": spec.ts,
        "equilibrium": {"x0": list(map(float, spec.x0)), "u0": u0.tolist()},
        "uncertain": [[nm, lo, hi] for nm, lo, hi in o.uncertain],
        **({"uncertain_source": o.__dict__["_fit_source"]} if "_fit_source" in o.__dict__ else {}),
        "nominal_parameters": {nm: float(plant.parameter(nm).value) for nm in names},
        "vertex_models": vm.as_dict(),
        "models": {"count": len(labels), "labels": labels,
                   "rule": ("the 2^k corners of the parameter box and the nominal model, linearised at "
                            "the operating levels x0 (kept), each with its own equilibrium input (re-"
                            "trimmed)") if names else "the nominal model (no uncertain parameter)"},
        "polytope": poly,
        "worst_vertex": {"index": worst, "parameters": labels[worst],
                         "region_margin": float(res.vertex_margins[worst])},
        "robust": res.as_dict(), "solver": res.solver, "status": res.status,
        "assumptions": [a.text for a in plant.assumptions],
    }


#: Fastest continuous closed-loop eigenvalue, times the sampling period, worth a warning: a
#: sampled controller cannot run a loop much faster than its sampling (nor pumps follow it).
STIFF_SAMPLING = 20.0


def _warn_if_stiff(A: np.ndarray, B: np.ndarray, K: np.ndarray, domain: str, ts: float | None) -> None:
    """A continuous design whose closed loop is far faster than the sampling period: a
    `DesignWarning` (the region bounds the eigenvalues from one side only)."""
    if domain != "continuous" or not ts:
        return
    fast = max(float(np.max(np.abs(np.linalg.eigvals(Ai - Bi @ K)))) for Ai, Bi in zip(A, B))
    if fast * float(ts) > STIFF_SAMPLING:
        warnings.warn(f"the closed loop has an eigenvalue of modulus {fast:.3g} 1/s, "
                      f"{fast * float(ts):.3g} times the sampling rate 1/ts (ts = {float(ts):g} s): a "
                      "sampled controller cannot run it and the pumps saturate at once; bound the "
                      "region from the fast side too (a disk or a sector)", DesignWarning, stacklevel=2)


def _channel(design: DesignSpec, o: Any, Cz: np.ndarray, Dzu: np.ndarray | None,
              observer: bool) -> dict:
    """The H-infinity channel w -> z: which of ``Bw``, ``Cz``, ``Dzu`` the spec gave (the others
    are the defaults the report's problem statement names) and the matrices used."""
    given = set(design.options)
    return {"observer": observer,
            "given": sorted(given & {"Bw", "Cz", "Dzu"}),
            "Bw": None if o.Bw is None else np.asarray(o.Bw, dtype=float).tolist(),
            "Cz": np.asarray(Cz, dtype=float).tolist(),
            "Dzu": None if Dzu is None else np.asarray(Dzu, dtype=float).tolist(),
            "note": "B_w in continuous time (state units per s per unit of w), taken at every vertex"}


def _region_halfspaces(plant: Any, x0: Any) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Half-spaces ``c' (x - x0) <= b`` of the operating region: its bounds and its orderings."""
    x0 = np.asarray(x0, dtype=float)
    n = plant.n
    rows, limits, words = [], [], []
    for i, (lo, hi) in enumerate(plant.region.bounds):
        name = plant.states[i].name
        for sign, bound in ((1.0, hi), (-1.0, lo)):
            if bound is not None and np.isfinite(bound):
                c = np.zeros(n)
                c[i] = sign
                rows.append(c)
                limits.append(sign * (bound - x0[i]))
                words.append(f"{name} {'<=' if sign > 0 else '>='} {bound:g}")
    for a, b in plant.region.orderings:
        expr = sp.expand(a - b)
        coeffs = [float(sp.diff(expr, sym)) if not sp.diff(expr, sym).free_symbols else None
                  for sym in plant.x]
        if any(c is None for c in coeffs):
            continue
        c = np.array(coeffs)
        value = float(expr.xreplace(dict(zip(plant.x, map(float, x0)))))
        rows.append(-c)
        limits.append(value)
        words.append(f"{a} >= {b}")
    return np.array(rows).reshape(-1, n), np.array(limits), words


def _offsets(A: np.ndarray, B: np.ndarray, K: np.ndarray, du: np.ndarray, domain: str) -> np.ndarray:
    """Steady deviation of the linear closed loop when the input is off by ``du`` (per model)."""
    out = []
    for Ai, Bi, d in zip(A, B, du):
        Acl = Ai - Bi @ K
        M = -Acl if domain == "continuous" else np.eye(Ai.shape[0]) - Acl
        out.append(np.linalg.solve(M, Bi @ d))
    return np.array(out)


# ----------------------------------------------------------- robust_state_feedback
def run_robust_state_feedback(spec: Spec, design: DesignSpec) -> DesignResult:
    """One state feedback meeting an LMI region at every vertex of the parameter box.

    Gains: ``K`` (``u = u_op - K (x - x_op)``; with integral action ``K1``,
    ``K2`` and ``K = [K1 K2]`` on ``(x - x_op, z)``), ``P`` (common Lyapunov
    matrix; with ``saturation`` the ellipsoid ``x' P x <= 1``), the nominal
    model (``F``, ``B``, ``C`` or ``Ad``, ``Bd``, ``C``: `model_names`) and
    the operating point ``x_op``, ``u_op``.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        The ``[[design]]`` entry (options validated at parse time).

    Returns
    -------
    DesignResult

    Raises
    ------
    SpecError
        ``umax`` beyond the actuator range, a parameter value the plant refuses.
    UncontrollableError
        The nominal pair is not controllable.
    InfeasibleDesign
        No gain meets the request at every vertex (with the largest
        achievable margin as the certificate), or the re-check fails.
    """
    o = _with_fit_box(spec, design, options_of(design, spec, RobustStateFeedbackOptions))
    domain = time_domain_of(o)
    plant = spec.plant
    n, m = plant.n, plant.m
    vm, nom, u0 = _models(spec, design, o, "inputs" if o.Bw is None else o.Bw)
    if not controllability_rank(nom.A[0], nom.B[0]).full:
        raise UncontrollableError(f"the nominal linearisation (A, B) is not controllable: no state "
                                  f"feedback can place every eigenvalue (design '{design.name}')")
    A, B, W = _stack(vm, nom, "A"), _stack(vm, nom, "B"), _stack(vm, nom, "Bw")
    C0 = nom.C[0]
    p = 0
    tracked: list[str] = []
    if o.integral:
        outputs = [s.name for s in plant.outputs]
        tracked = list(o.tracked or ())
        C1 = C0[[outputs.index(t) for t in tracked]]
        p = C1.shape[0]
        aug = [augment_integral(Ai, Bi, C1, domain, spec.ts) for Ai, Bi in zip(A, B)]
        A = np.array([a for a, _ in aug])
        B = np.array([b for _, b in aug])
        W = np.concatenate([W, np.zeros((W.shape[0], p, W.shape[2]))], axis=1)
    hinf = None
    if o.gamma is not None:
        Cz = np.eye(n) if o.Cz is None else np.asarray(o.Cz, dtype=float)
        Cz = np.hstack([Cz, np.zeros((Cz.shape[0], p))])
        Dzu = np.zeros((Cz.shape[0], m)) if o.Dzu is None else np.asarray(o.Dzu, dtype=float)
        hinf = HinfBound(float(o.gamma), W, Cz, Dzu)
    sat = None
    caveats: list[str] = []
    if o.saturation:
        lim = np.asarray(plant.input_limits, dtype=float)
        room = np.minimum(u0 - lim[:, 0], lim[:, 1] - u0)
        if np.any(room <= 0):
            raise InfeasibleDesign(f"the equilibrium input u0 = {u0.tolist()} is at an actuator limit "
                                   f"{lim.tolist()}: no input deviation is available")
        umax = room if o.umax is None else np.asarray(o.umax, dtype=float)
        if np.any(umax > room * (1 + 1e-9)):
            raise SpecError(f"umax = {umax.tolist()} exceeds the room the actuators leave around "
                            f"u0 = {u0.tolist()} (range {lim.tolist()}): at most {room.tolist()}",
                            key=f"{design.key}.umax")
        H, b, words = _region_halfspaces(plant, spec.x0)
        if np.any(b <= 0):
            raise InfeasibleDesign(f"the operating point lies on the boundary of the operating region "
                                   f"({[w for w, v in zip(words, b) if v <= 0]}): no ellipsoid fits")
        sat = SaturationBound(umax, None if o.box is None else np.asarray(o.box, dtype=float), n,
                              H if H.size else None, b if H.size else None)
    region = region_from_parts(o.region)
    try:
        res = robust_state_feedback(A, B, region, domain=domain, hinf=hinf, saturation=sat,
                                    margin=o.margin, kappa=o.kappa, solver=o.solver,
                                    nominal=A.shape[0] - 1 if vm.names else None)
    except SpecError as exc:
        raise rekeyed(design, exc, fallback="region") from None
    K = res.K
    _warn_if_stiff(A, B, K, domain, spec.ts)
    names = model_names(domain)
    gains: dict[str, np.ndarray] = {"K": K, "P": res.P, names["A"]: nom.A[0], names["B"]: nom.B[0],
                                    "C": C0, "x_op": np.asarray(spec.x0, dtype=float), "u_op": u0}
    diagnostics = _common_diagnostics(spec, o, vm, nom, u0, res)
    if hinf is not None:
        diagnostics["hinf_channel"] = _channel(design, o, hinf.Cz[:, :n], hinf.Dzu, observer=False)
    if o.integral:
        gains.update({"K1": K[:, :n], "K2": K[:, n:]})
        # the tracked outputs at the operating point, h(x0) with offsets and sensor gains: the
        # integrators integrate the measured outputs' error y_r - y_op - C1 (x - x_op)
        y_op = np.asarray(plant.compiled.output(np.asarray(spec.x0, dtype=float)[None]),
                          dtype=float).reshape(-1)[[outputs.index(t) for t in tracked]]
        diagnostics["integral"] = {"tracked": tracked, "C1": C1.tolist(), "y_op": y_op.tolist()}
    # offsets without integral action: the law applies the nominal u0 at every vertex
    du = np.array([u0 - ui for ui in vm.u0])
    if not o.integral and vm.names:
        dx = _offsets(vm.A, vm.B, K, du, domain)
        diagnostics["offsets"] = {
            "input_shift": (-du).tolist(), "steady_state_deviation": dx.tolist(),
            "max_abs_deviation": float(np.max(np.abs(dx))),
            "note": "predicted by each vertex's linear model: u0(p) - u0 is the input shift the "
                    "parameters need; without integral action the loop settles at x0 + deviation"}
        caveats.append(f"no integral action: the parameter mismatch leaves a steady offset of up to "
                       f"{float(np.max(np.abs(dx))):.3g} (state units) at the vertices")
    if sat is not None:
        P = res.P
        axes = ellipsoid_axes(P[:n, :n], [s.name for s in plant.states])
        diagnostics["saturation"] = {
            **(res.saturation or {}), "umax_default": o.umax is None,
            "ellipsoid_axes": axes, "units": [s.unit for s in plant.states],
            "inside": words,
            "section": ("z = 0 (integrators start empty)" if o.integral else "full state"),
            "note": ("x' P x <= 1 in deviation coordinates x - x0 is invariant for every vertex "
                     "model under u = u0(p) - K (x - x0); from inside it |u - u0| <= umax. On the "
                     "nonlinear plant the verdict checks it from the boundary at the nominal "
                     "parameters")}
    if not vm.names:
        caveats.append("no uncertain parameter given: a nominal design")
    if not diagnostics["polytope"]["exact"]:
        caveats.append(diagnostics["polytope"]["note"])
    diagnostics["caveats"] = caveats
    return DesignResult(design.name, "robust_state_feedback", plant.name, gains, diagnostics, {})


# --------------------------------------------------------------- robust_observer
def run_robust_observer(spec: Spec, design: DesignSpec) -> DesignResult:
    """One observer gain meeting an LMI region at every vertex of the parameter box.

    Gains: ``L`` (``x_hat' = ... + L (y - C x_hat)``), ``P`` (common
    Lyapunov matrix of the error dynamics, ``V = e' P e``), the nominal model
    (``F``, ``B``, ``C`` or ``Ad``, ``Bd``, ``C``: `model_names`) and the
    operating point ``x_op``, ``u_op``.

    Parameters
    ----------
    spec : Spec
    design : DesignSpec

    Returns
    -------
    DesignResult

    Raises
    ------
    UnobservableError
        The nominal pair is not observable.
    InfeasibleDesign
        No gain meets the request at every vertex, or the re-check fails.
    """
    o = _with_fit_box(spec, design, options_of(design, spec, RobustObserverOptions))
    domain = time_domain_of(o)
    plant = spec.plant
    n = plant.n
    vm, nom, u0 = _models(spec, design, o, "identity" if o.Bw is None else o.Bw)
    if not observability_rank(nom.A[0], nom.C[0]).full:
        raise UnobservableError(f"the nominal linearisation (A, C) is not observable (design "
                                f"'{design.name}')")
    A, C, W = _stack(vm, nom, "A"), _stack(vm, nom, "C"), _stack(vm, nom, "Bw")
    hinf = None
    if o.gamma is not None:
        Cz = np.eye(n) if o.Cz is None else np.asarray(o.Cz, dtype=float)
        hinf = HinfBound(float(o.gamma), W, Cz, np.zeros((Cz.shape[0], 0)))
    region = region_from_parts(o.region)
    try:
        res = robust_observer(A, C, region, domain=domain, hinf=hinf, margin=o.margin,
                              kappa=o.kappa, solver=o.solver,
                              nominal=A.shape[0] - 1 if vm.names else None)
    except SpecError as exc:
        raise rekeyed(design, exc, fallback="region") from None
    names = model_names(domain)
    gains = {"L": res.L, "P": res.P, names["A"]: nom.A[0], names["B"]: nom.B[0], "C": nom.C[0],
             "x_op": np.asarray(spec.x0, dtype=float), "u_op": u0}
    diagnostics = _common_diagnostics(spec, o, vm, nom, u0, res)
    if hinf is not None:
        diagnostics["hinf_channel"] = _channel(design, o, hinf.Cz, None, observer=True)
    caveats = ["the error matrix A(p) - L C is certified for every model of the polytope; an "
               "observer running on the NOMINAL model with a plant whose parameters differ keeps a "
               "bias (the mismatch acts as a disturbance), which the campaign measures"]
    if not diagnostics["polytope"]["exact"]:
        caveats.append(diagnostics["polytope"]["note"])
    diagnostics["caveats"] = caveats
    return DesignResult(design.name, "robust_observer", plant.name, gains, diagnostics, {})


ROBUST_STATE_FEEDBACK = DesignMethod("robust_state_feedback", run_robust_state_feedback,
                                     RobustStateFeedbackOptions)
ROBUST_OBSERVER = DesignMethod("robust_observer", run_robust_observer, RobustObserverOptions)
