"""Spec design methods ``ts_state_feedback`` and ``ts_output_feedback`` (Takagi-Sugeno PDC).

=======================  ========================================================
``ts_state_feedback``    PDC ``u = u0 - sum_i mu_i(x) K_i (x - x0)`` on the exact
                         TS model of the deviations (`tanksynth.design.takagi_sugeno.pdc`);
                         gains ``K`` (r, m, n), ``P``, the model and the region
``ts_output_feedback``   the PDC on an estimate: measured premises (PDC observer,
                         separation) or estimated premises (seed 001 observer with
                         the Lipschitz bound, all-pairs PDC conditions, two-step);
                         composite Lyapunov certificate, gains ``K``, ``P``, ``L``,
                         ``Po`` (and ``Q``), ``beta``
=======================  ========================================================

Continuous-time designs: the law acts continuously (the verdict samples it
fast enough to resolve the closed loop). The certified region ``{(x - x0)' P
(x - x0) <= c}`` lies in the TS domain and keeps the pumps unsaturated; a
design whose region does not contain the ball of radius ``region_margin``
around the operating point is refused (exit 3).

With ``setpoint`` the PDC is designed again about the second operating
point (`_setpoint_stage`: gain keys ``sp_*``, diagnostics ``setpoint``),
and the switch to it is certified from a level set of the first design's
Lyapunov function (`tanksynth.design.takagi_sugeno.region.switch_level`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from tanksynth.analysis.takagi_sugeno import domain_from_plant, quasi_lpv, ts_model
from tanksynth.design.bisection import bisect_feasible
from tanksynth.design.matrices import symmetrized
from tanksynth.design.observer_lmi.weighting import lipschitz_bound
from tanksynth.design.operating_point import equilibrium_at
from tanksynth.design.result import DesignMethod, DesignResult, options_of, rekeyed
from tanksynth.design.takagi_sugeno.pdc import certified_decay, max_decay_rate, pdc_lmi
from tanksynth.design.takagi_sugeno.deviation import deviation_ts_model
from tanksynth.design.takagi_sugeno.region import (certified_region, composite_decay, coupling_weight,
                                                   initial_error_allowance, lyapunov_decay,
                                                   observer_decay_lmi, switch_level)
from tanksynth.errors import InfeasibleDesign, SpecError
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options import TsOutputFeedbackOptions, TsStateFeedbackOptions

__all__ = ["run_ts_state_feedback", "run_ts_output_feedback", "TS_STATE_FEEDBACK",
           "TS_OUTPUT_FEEDBACK", "domain_faces", "SETPOINT_PREFIX"]


def domain_faces(domain: Any, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Faces ``G e <= g`` of the domain in deviation coordinates, with names.

    Parameters
    ----------
    domain : Domain
        The design domain (box and extra faces, state units).
    x0 : ndarray, shape (n,)
        Operating point (state units, m).
    """
    n = domain.n
    rows, rhs, names = [], [], []
    for i in range(n):
        rows.append(np.eye(n)[i])
        rhs.append(domain.upper[i] - x0[i])
        names.append(f"{domain.names[i]} <= {domain.upper[i]:g}")
        rows.append(-np.eye(n)[i])
        rhs.append(x0[i] - domain.lower[i])
        names.append(f"{domain.names[i]} >= {domain.lower[i]:g}")
    for Gl, gl in zip(domain.G, domain.g):
        rows.append(-Gl)
        rhs.append(float(Gl @ x0 - gl))
        names.append("ordering " + " + ".join(f"{w:g} {s}" for w, s in zip(Gl, domain.names) if w)
                     + f" >= {gl:g}")
    return np.array(rows), np.array(rhs), names


def _setup(spec: Spec, design: DesignSpec, o: Any, x_op: Any = None) -> dict:
    plant = spec.plant
    names = [s.name for s in plant.states]
    box = list(plant.region.bounds)
    for nm, b in (o.domain or {}).items():
        box[names.index(nm)] = b
    try:
        domain = domain_from_plant(plant, box, o.orderings, o.ordering_gap)
        qlpv = quasi_lpv(plant)
    except SpecError as exc:
        raise rekeyed(design, exc, "domain") from None
    if x_op is None:
        x0 = np.asarray(spec.x0, dtype=float)
        eq = equilibrium_at(plant, x0, spec.given_u0)
    else:
        x0 = np.asarray(x_op, dtype=float)
        eq = equilibrium_at(plant, x0)
        if not (eq.is_equilibrium and eq.within_bounds and bool(domain.contains(x0)[0])):
            raise SpecError(f"setpoint {x0.tolist()} is not an equilibrium inside the domain with "
                            f"the pumps in range: input {eq.u0.tolist()}, residual "
                            f"{np.max(np.abs(eq.residual)):.3g} (tolerance {eq.tolerance:.3g}), "
                            f"domain {domain.description}", key=f"{design.key}.setpoint")
    try:
        model = deviation_ts_model(qlpv, domain, x0, eq.u0, o.premise_samples, o.premise_margin)
    except SpecError as exc:
        raise rekeyed(design, exc, "domain") from None
    X = domain.sample(2000, o.seed)
    lim = np.asarray(plant.input_limits, dtype=float).reshape(plant.m, 2)
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -1.0)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], 1.0)
    U = np.random.default_rng(o.seed + 1).uniform(lo, hi, size=(len(X), plant.m))
    f = plant.compiled.rhs(X, U)
    err = float(np.max(np.abs(model.rhs(X, U) - f)) / max(np.max(np.abs(f)), 1e-300))
    mu = model.memberships(X)
    if not (err <= 1e-9 and mu.min() >= 0):
        raise InfeasibleDesign(f"the deviation TS model is not exact on the domain: relative error "
                               f"{err:.3g}, smallest membership {mu.min():.3g}")
    G, g, face_names = domain_faces(domain, x0)
    margins = None
    if o.pump_limits:
        if not np.all(np.isfinite(lim)):
            raise SpecError("pump_limits = true needs finite input limits on the plant",
                            key=f"{design.key}.pump_limits")
        margins = np.minimum(eq.u0 - lim[:, 0], lim[:, 1] - eq.u0)
        if np.any(margins <= 0):
            raise InfeasibleDesign(f"the equilibrium input u0 = {eq.u0.tolist()} sits on a pump limit "
                                   f"{lim.tolist()}: no input is left for feedback")
    exact = {"points": len(X), "max_relative_error": err, "min_membership": float(mu.min()),
             "max_sum_deviation": float(np.max(np.abs(mu.sum(axis=1) - 1)))}
    return dict(plant=plant, domain=domain, qlpv=qlpv, eq=eq, model=model, faces=(G, g),
                face_names=face_names, margins=margins, exactness=exact)


def _controller(s: dict, o: Any, relaxations: list[str]) -> tuple[Any, list[dict]]:
    """Solve the PDC LMIs with the first feasible relaxation; exit 3 with the largest alpha."""
    model = s["model"]
    G, g = s["faces"]
    room = float(np.min(g / np.linalg.norm(G, axis=1)))
    if o.region_margin >= room:
        raise InfeasibleDesign(f"region_margin = {o.region_margin:g} is not below the distance "
                               f"{room:.4g} from the operating point to the nearest face of the TS "
                               "domain: no certified region can contain that ball")
    kw = dict(faces=s["faces"], input_margins=s["margins"], margin=o.margin, kappa=o.kappa,
              solver=o.solver, inner_radius=o.region_margin)
    tried = []
    for rel in relaxations:
        try:
            res = pdc_lmi(model.A, model.B, alpha=o.decay_rate, relaxation=rel, **kw)
            tried.append({"relaxation": rel, "feasible": True})
            return res, tried
        except InfeasibleDesign as exc:
            tried.append({"relaxation": rel, "feasible": False, "reason": str(exc)})
    last = relaxations[-1]
    text = "; ".join(f"{t['relaxation']}: {t['reason']}" for t in tried)
    if o.decay_rate > 0:
        best, hist = max_decay_rate(model.A, model.B, last, **kw)
        what = ("no decay rate is feasible" if best < 0 else
                f"the largest feasible decay rate is {best:.4g} 1/s (bisection, {len(hist)} solves, "
                f"relaxation {last})")
        raise InfeasibleDesign(f"PDC LMIs infeasible for decay_rate = {o.decay_rate:g} 1/s ({text}); "
                               f"{what}")
    raise InfeasibleDesign(f"PDC LMIs infeasible ({text})")


def _relaxations(o: Any) -> list[str]:
    return ["vertex", "tuan"] if o.relaxation == "auto" else [o.relaxation]


def _refuse_small(region: Any, P: np.ndarray, o: Any) -> float:
    inner = float(np.sqrt(region.c / np.linalg.eigvalsh(P)[-1]))
    if inner < o.region_margin:
        raise InfeasibleDesign(f"the certified region (c = {region.c:.4g}, bound by {region.binding}) "
                               f"contains only the ball of radius {inner:.4g} around the operating "
                               f"point, less than region_margin = {o.region_margin:g}")
    return inner


def _common_diag(s: dict, res: Any, tried: list, region: Any, inner: float, spec: Spec) -> dict:
    return {"ts_model": s["model"].as_dict(), "exactness": s["exactness"],
            "equilibrium": s["eq"].as_dict(), "relaxations_tried": tried,
            "lmi": res.as_dict(), "relaxation": res.relaxation, "decay_rate": res.decay,
            "solver": res.solver if hasattr(res, "solver") else "", "status": res.status,
            "faces": {"G": s["faces"][0].tolist(), "g": s["faces"][1].tolist(),
                      "names": s["face_names"]},
            "input_margins": None if s["margins"] is None else s["margins"].tolist(),
            "region": {**region.as_dict(), "inner_radius": inner,
                       "states": [st.name for st in spec.plant.states]},
            "time_domain": "continuous",
            "assumptions": [a.text for a in spec.plant.assumptions]}


def _gains(s: dict, res: Any, region: Any) -> dict:
    m = s["model"]
    return {"K": res.K, "P": res.P, "x_op": m.x0, "u_op": m.u0, "F": m.A, "B": m.B, "forms": m.forms,
            "z_lower": m.lower, "z_upper": m.upper, "region_c": np.array([region.c]),
            "semi_axes": region.semi_axes, "axes": region.axes}


def run_ts_state_feedback(spec: Spec, design: DesignSpec) -> DesignResult:
    """PDC state feedback on the exact deviation TS model, certified region.

    Gains: ``K`` (r, m, n: ``u = u_op - sum_i mu_i(x) K_i (x - x_op)``), ``P``
    (Lyapunov matrix), ``x_op``, ``u_op``, the vertex matrices ``F`` (r, n, n,
    continuous time) and ``B``,
    the premises' linear forms and bounds (``forms``, ``z_lower``,
    ``z_upper``), the region level ``region_c`` and its ``semi_axes`` (m)
    and ``axes``.

    Parameters
    ----------
    spec : Spec
    design : DesignSpec

    Returns
    -------
    DesignResult

    Raises
    ------
    InfeasibleDesign
        LMIs infeasible (with the largest feasible decay rate), re-check
        failed, or a region too small.
    """
    o = options_of(design, spec, TsStateFeedbackOptions)
    s = _setup(spec, design, o)
    res, tried = _controller(s, o, _relaxations(o))
    region = certified_region(res.P, res.K, s["faces"], s["margins"], s["face_names"])
    inner = _refuse_small(region, res.P, o)
    diag = _common_diag(s, res, tried, region, inner, spec)
    diag["solver"] = o.solver
    gains = _gains(s, res, region)
    if o.setpoint is not None:
        sp_gains, diag["setpoint"] = _setpoint_stage(spec, design, o, s, res, region, _relaxations(o))
        gains.update(sp_gains)
    return DesignResult(design.name, "ts_state_feedback", spec.plant.name, gains, diag, {})


def _measured(model: Any) -> bool:
    """True if the output is a selection of states covering every premise's linear form."""
    C = model.C
    rows_unit = all(np.count_nonzero(r) == 1 and np.isclose(r[np.flatnonzero(r)[0]], 1.0) for r in C)
    seen = set(int(np.flatnonzero(r)[0]) for r in C) if rows_unit else set()
    return rows_unit and all(set(np.flatnonzero(a).tolist()) <= seen for a in model.forms)


def run_ts_output_feedback(spec: Spec, design: DesignSpec) -> DesignResult:
    """PDC on an estimate with a composite Lyapunov certificate.

    Measured premises (the outputs select every state a premise depends
    on): PDC controller and PDC observer ``dx_hat/dt = sum_i mu_i(y) (A_i
    e_hat + B v) + sum_j mu_j(y) L_j (y - C x_hat)`` designed separately
    (separation holds: the error ``eps = x - x_hat`` obeys ``d eps/dt = sum
    mu_i mu_j (A_i - L_j C) eps`` whatever the control). Estimated premises:
    the observer of seed 001 eq. (20) (the TS model at the estimate, which
    equals the plant's ``f(x_hat)``) with LMI (28) for ``psi`` = the
    Lipschitz bound of the remainder, and the PDC with the all-pairs
    conditions (the controller's premises ``mu_j(x_hat)`` differ from the
    plant's); two-step design. Both are tied by ``V = e' P e + beta eps' Po
    eps`` (`coupling_weight`); the region is the slice ``eps = 0`` of ``{V <=
    c}`` with ``x`` (and, estimated premises, ``x_hat``) in the domain and the
    pumps unsaturated.

    Gains: those of ``ts_state_feedback`` plus ``L`` ((r, n, q) measured, (n,
    q) estimated), ``Po``, ``Q`` (estimated) and ``beta``.

    Parameters
    ----------
    spec : Spec
        The whole spec (plant, scenario).
    design : DesignSpec
        This design's entry (method and options).

    Raises
    ------
    InfeasibleDesign
        Controller or observer infeasible, no finite Lipschitz bound, region
        too small.
    """
    o = options_of(design, spec, TsOutputFeedbackOptions)
    s = _setup(spec, design, o)
    model = s["model"]
    measured = _measured(model)
    mode = o.premises if o.premises != "auto" else ("measured" if measured else "estimated")
    if mode == "measured" and not measured:
        raise SpecError("premises = 'measured' but the premises' linear forms "
                        f"{model.forms.tolist()} involve states the outputs do not measure "
                        f"(C = {model.C.tolist()})", key=f"{design.key}.premises")
    diag_extra: dict[str, Any] = {"premises": mode}
    gains_extra: dict[str, Any] = {}
    if mode == "measured":
        res, tried = _controller(s, o, _relaxations(o))
        alpha_c = res.decay
        od = dataclasses.replace(o, decay_rate=o.observer_decay)
        dual, dtried = None, []
        for rel in _relaxations(o):
            try:
                dual = pdc_lmi(np.transpose(model.A, (0, 2, 1)), model.C.T, alpha=od.decay_rate,
                               relaxation=rel, margin=o.margin, kappa=o.kappa, solver=o.solver)
                dtried.append({"relaxation": rel, "feasible": True})
                break
            except InfeasibleDesign as exc:
                dtried.append({"relaxation": rel, "feasible": False, "reason": str(exc)})
        if dual is None:
            raise InfeasibleDesign("PDC observer LMIs infeasible for observer_decay = "
                                   f"{o.observer_decay:g} 1/s: " + "; ".join(
                                       f"{t['relaxation']}: {t['reason']}" for t in dtried))
        Po = symmetrized(np.linalg.inv(dual.P))
        L = np.transpose(dual.K, (0, 2, 1))
        alpha_o = certified_decay(dual.P, np.transpose(model.A, (0, 2, 1)), model.C.T, dual.K,
                                  dual.relaxation)
        diag_extra["observer"] = {"kind": "PDC observer, measured premises (separation)",
                                  "relaxation": dual.relaxation, "relaxations_tried": dtried,
                                  "decay_rate": alpha_o, "lmi": dual.as_dict()}
        gains_extra.update(L=L, Po=Po)
        hat_in_domain = False
    else:
        if o.relaxation not in ("auto",):
            diag_extra["relaxation_note"] = (f"relaxation = {o.relaxation!r} ignored: estimated "
                                             "premises need the all-pairs conditions")
        res, tried = _controller(s, o, ["all_pairs"])
        alpha_c = res.decay
        ts = ts_model(s["qlpv"], s["domain"], method="sampling", samples=4000, seed=o.seed)
        ts = dataclasses.replace(ts, A0=model.A0)
        lip = lipschitz_bound(ts, "jacobian", o.lipschitz_method, seed=o.seed)
        if not np.isfinite(lip.value):
            raise InfeasibleDesign("estimated premises: the remainder f(x) - A0 x has no finite "
                                   "Lipschitz bound on the domain (" + str(lip.detail.get("text"))
                                   + "); set orderings = true with ordering_gap > 0")
        def feasible(a: float) -> bool:
            try:
                observer_decay_lmi(model.A0, model.C, lip.value, a, margin=o.margin, kappa=o.kappa,
                                   solver=o.solver)
                return True
            except InfeasibleDesign:
                return False

        if not feasible(0.0):
            raise InfeasibleDesign(f"estimated premises: observer LMI (28) infeasible with psi = "
                                   f"{lip.value:.4g} 1/s (Lipschitz bound, {o.lipschitz_method}): "
                                   "restrict the domain (larger ordering_gap) or measure more states")
        a_max, a_infeasible, hist = bisect_feasible(feasible, start=max(lip.value, 1e-4), rtol=0.02)
        a_obs = min(o.observer_decay, 0.5 * a_max)
        L, Po, Q = observer_decay_lmi(model.A0, model.C, lip.value, a_obs, margin=o.margin,
                                      kappa=o.kappa, solver=o.solver)
        Gm = Po @ (model.A0 - L @ model.C)
        W = -(Gm + Gm.T + lip.value ** 2 * Q + Po @ np.linalg.solve(Q, Po))
        alpha_o = lyapunov_decay(Po, W)
        diag_extra["observer"] = {"kind": "seed 001 observer (20), premises at the estimate, LMI (28) "
                                          "with Q = q I, the Lipschitz bound and a decay rate "
                                          "(two-step design)",
                                  "psi": lip.value, "lipschitz": lip.as_dict(), "decay_rate": alpha_o,
                                  "imposed_decay": a_obs, "largest_feasible_decay": a_max,
                                  "largest_feasible_decay_bracket": [a_max, a_infeasible],
                                  "bisection_solves": len(hist),
                                  "rule": "imposed decay = min(observer_decay, half the largest "
                                          "feasible)"}
        gains_extra.update(L=L, Po=Po, Q=Q, A0=model.A0)
        hat_in_domain = True
    beta = coupling_weight(res.P, res.K, model.B, alpha_c, Po, alpha_o, o.coupling_factor)
    extra = np.linalg.inv(Po) / beta
    region = certified_region(res.P, res.K, s["faces"], s["margins"], s["face_names"],
                              extra_inverse=extra)
    if hat_in_domain:   # x_hat = x - eps must stay in the domain too (Lipschitz bound, memberships)
        region = _estimate_faces(region, s, res.P, extra)
    inner = _refuse_small(region, res.P, o)
    diag = _common_diag(s, res, tried, region, inner, spec)
    diag.update(diag_extra)
    diag["solver"] = o.solver
    diag["composite"] = {"beta": beta, "controller_decay": alpha_c, "observer_decay": alpha_o,
                         "estimation_budget": "beta eps' Po eps <= c - e' P e",
                         "coupling_factor": o.coupling_factor,
                         "initial_error": initial_error_allowance(res.P, Po, beta, region.c)}
    gains = _gains(s, res, region)
    gains.update(gains_extra)
    gains["beta"] = np.array([beta])
    if o.setpoint is not None:
        obs = dict(Po=Po, alpha_o=alpha_o, beta=beta, alpha_c=alpha_c, estimate_faces=hat_in_domain)
        sp_gains, diag["setpoint"] = _setpoint_stage(
            spec, design, o, s, res, region, ["all_pairs"] if hat_in_domain else _relaxations(o), obs)
        gains.update(sp_gains)
    return DesignResult(design.name, "ts_output_feedback", spec.plant.name, gains, diag, {})


def _estimate_faces(region: Any, s: dict, P: np.ndarray, extra: np.ndarray) -> Any:
    """The region with the faces seen by the estimate ``x_hat = x - eps`` too (estimated premises)."""
    G, g = s["faces"]
    Pi = np.linalg.inv(P)
    lim = dict(region.limits)
    for l, nm in enumerate(s["face_names"]):
        lim[f"estimate face {nm}"] = float(g[l] ** 2 / (G[l] @ (Pi + extra) @ G[l]))
    binding = min(lim, key=lambda face: lim[face])
    k = np.sqrt(lim[binding] / region.c)
    return dataclasses.replace(region, c=lim[binding], limits=lim, binding=binding,
                               semi_axes=region.semi_axes * k, extents=region.extents * k)


#: Gain keys of the set-point design (prefix ``sp_`` on the first design's keys).
SETPOINT_PREFIX = "sp_"


def _setpoint_stage(spec: Spec, design: DesignSpec, o: Any, s1: dict, res1: Any, region1: Any,
                    relaxations: list[str], obs: dict | None = None) -> tuple[dict, dict]:
    """The PDC about the set-point ``x_op2`` and the certificate of the switch to it.

    The TS model of the deviations is exact about any point of the domain,
    but its premises (secant slopes from the point) and so its vertices
    depend on that point: the law designed about ``x_op`` says nothing about
    ``x_op2``. The set-point change is therefore a second PDC design on the
    exact model about ``x_op2`` (same domain, ``u_op2`` balancing it), with
    its own certified region ``{V_2 <= c_2}``; the observer of the output
    feedback is kept (its error dynamics do not depend on the set-point).
    The switch is certified from ``{V_1 <= gamma c_1}`` when that set lies in
    ``{V_2 <= c_2}`` (`switch_level`, S-lemma); ``V_1`` decays at least at
    ``2 alpha_1``, so from anywhere in the first region the switch is safe
    after the dwell time ``ln(1/gamma) / (2 alpha_1)``. Refused (exit 3) when
    the second region does not contain the first operating point.
    """
    names = [st.name for st in spec.plant.states]
    x2 = np.array([o.setpoint[nm] for nm in names])
    s2 = _setup(spec, design, o, x_op=x2)
    res2, tried2 = _controller(s2, o, relaxations)
    n = x2.size
    d = x2 - s1["model"].x0
    if obs is None:
        region2 = certified_region(res2.P, res2.K, s2["faces"], s2["margins"], s2["face_names"])
        P1b, P2b, db = res1.P, res2.P, d
        rate1 = float(res1.decay)
        extra_gains: dict[str, Any] = {}
    else:
        Po = obs["Po"]
        beta2 = coupling_weight(res2.P, res2.K, s2["model"].B, res2.decay, Po, obs["alpha_o"],
                                o.coupling_factor)
        extra = np.linalg.inv(Po) / beta2
        region2 = certified_region(res2.P, res2.K, s2["faces"], s2["margins"], s2["face_names"],
                                   extra_inverse=extra)
        if obs["estimate_faces"]:
            region2 = _estimate_faces(region2, s2, res2.P, extra)
        Z = np.zeros((n, n))
        P1b = np.block([[res1.P, Z], [Z, obs["beta"] * Po]])
        P2b = np.block([[res2.P, Z], [Z, beta2 * Po]])
        db = np.concatenate([d, np.zeros(n)])
        rate1 = composite_decay(res1.P, s1["model"].B, res1.K, obs["alpha_c"], Po, obs["alpha_o"],
                                obs["beta"])
        extra_gains = {"beta": np.array([beta2])}
    inner2 = _refuse_small(region2, res2.P, o)
    gamma = switch_level(P1b, region1.c, P2b, region2.c, db)
    v_at = float(d @ res2.P @ d) / region2.c
    if gamma <= 0.0:
        raise InfeasibleDesign(f"set-point change to {x2.tolist()} not certified: the first operating "
                               f"point lies outside the certified region about the set-point "
                               f"((x_op - x_op2)' P2 (x_op - x_op2) = {v_at:.4g} c2); choose a set-point "
                               "closer to the operating point")
    dwell = float(np.log(1.0 / gamma) / (2.0 * rate1)) if rate1 > 0 else float("inf")
    gains = {SETPOINT_PREFIX + k: v for k, v in {**_gains(s2, res2, region2), **extra_gains}.items()}
    gains[SETPOINT_PREFIX + "switch_level"] = np.array([gamma])
    diag = {"x_op2": x2.tolist(), "u_op2": s2["eq"].u0.tolist(), "relaxation": res2.relaxation,
            "relaxations_tried": tried2, "decay_rate": res2.decay, "lmi": res2.as_dict(),
            "exactness": s2["exactness"], "ts_model": s2["model"].as_dict(),
            "region": {**region2.as_dict(), "inner_radius": inner2},
            "switch_level": gamma, "first_point_level": v_at, "first_decay_rate": rate1,
            "dwell_time": dwell, "tolerance": o.setpoint_tolerance,
            "rule": "switch to the law about x_op2 once V1 <= gamma c1 (certain after the dwell "
                    "time from anywhere in the first region); V2 then decays inside {V2 <= c2}"}
    return gains, diag


TS_STATE_FEEDBACK = DesignMethod("ts_state_feedback", run_ts_state_feedback, TsStateFeedbackOptions)
TS_OUTPUT_FEEDBACK = DesignMethod("ts_output_feedback", run_ts_output_feedback,
                                  TsOutputFeedbackOptions)
