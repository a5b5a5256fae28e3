"""Verdict of ``ts_state_feedback`` and ``ts_output_feedback`` (Takagi-Sugeno PDC), own numerics.

Nothing here imports the design code it judges. From the artefact and the
plant it re-derives:

``ts_model_recheck``
    the premises ``z_k = (n_k(x) - n_k(x0)) / (a_k . (x - x0))`` recomputed
    from the plant's atoms, the stored vertices ``A_i`` rebuilt from them
    and the stored bounds, and ``sum_i mu_i (A_i e + B v)`` compared with
    the plant's ``f(x, u)`` at seeded points of the domain (exactness,
    memberships in ``[0, 1]``);
``lmi_recheck``
    the PDC conditions of the recorded relaxation, ``sum w_ij (He(P (A_i -
    B K_j)) + 2 alpha P) < 0`` (eigvalsh), ``P > 0``;
``region_recheck``
    ``c = min(faces g_l^2 / (G_l P^-1 G_l'), pumps margin_j^2 / (k_ij P^-1
    k_ij'))`` recomputed and compared with the stored ``region_c``; the ball
    of radius ``region_margin`` inside;
``region_simulation``
    the nonlinear plant (`tanksynth.sim.simulate`) in closed loop with the
    PDC law (premises from the state, or the estimate / the measurements)
    from seeded points on and inside the region's boundary: every run stays
    in the domain, never asks the pumps for more than they give, its
    Lyapunov function does not grow and it converges.

An artefact with a set-point change (gain keys ``sp_*``) adds the checks of
`tanksynth.verify.takagi_sugeno.setpoint`. The model, the laws and the region runs
live in `tanksynth.verify.takagi_sugeno.model` and `tanksynth.verify.takagi_sugeno.loops`
(re-exported here); the campaign runs the same conditions
(`tanksynth.verify.takagi_sugeno.campaign.ts_control_run`).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, fmt, guard, option
from tanksynth.verify.traces import TraceRecorder
from tanksynth.verify.takagi_sugeno.loops import (FINAL_RATIO, GROWTH_LIMIT, MeasuredPremiseObserver,
                                                  PDCLaw, SwitchedLaw, loop_setup, region_conditions,
                                                  region_horizon, region_points, region_sample,
                                                  simulate_region)
from tanksynth.verify.takagi_sugeno.model import (RebuiltModel, condition_weights, model_recheck,
                                                  pdc_conditions, rebuild_model, region_level)
from tanksynth.verify.takagi_sugeno.setpoint import setpoint_checks

__all__ = ["RebuiltModel", "rebuild_model", "pdc_conditions", "region_level", "PDCLaw",
           "MeasuredPremiseObserver", "SwitchedLaw", "region_points", "simulate_region", "ts_control_verdict",
           "model_recheck", "region_sample", "region_horizon",
           "region_conditions", "GROWTH_LIMIT", "FINAL_RATIO"]


def ts_control_verdict(doc: Mapping[str, Any], spec: Spec, *,
                       trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``ts_state_feedback`` / ``ts_output_feedback`` artefact (see the module).

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    n = spec.plant.n
    diag = doc.get("diagnostics") or {}
    checks: list[Check] = []

    def model_checks() -> list[Check]:
        return [model_recheck(doc, spec)]

    def lmi_checks() -> list[Check]:
        s = loop_setup(doc, spec)
        rel = str(diag.get("relaxation", ""))
        alpha = float((diag.get("lmi") or {}).get("alpha", option(doc, spec, "decay_rate", 0.0)))
        lam = pdc_conditions(s["P"], s["model"].A, s["model"].B, s["K"], alpha, rel)
        pmin = float(np.linalg.eigvalsh(s["P"])[0])
        out = [Check("lmi_recheck", bool(lam.max() < 0 and pmin > 0),
                     f"{len(lam)} PDC conditions ({rel}) sum w_ij (He(P (A_i - B K_j)) + 2 alpha P) "
                     f"with alpha = {alpha:g} 1/s, recomputed in numpy: largest eigenvalue "
                     f"{lam.max():.4g} (must be < 0); smallest eigenvalue of P {pmin:.4g}",
                     {"max_eigenvalue": float(lam.max()), "count": int(lam.size)})]
        if doc["method"] == "ts_output_feedback":
            out += _observer_checks(doc, s)
        return out

    def region_checks() -> list[Check]:
        s = loop_setup(doc, spec)
        G, g = s["model"].faces()
        margins = diag.get("input_margins")
        margins = None if margins is None else np.asarray(margins, float)
        extra, est = None, False
        if doc["method"] == "ts_output_feedback":
            Po = artefact_gain(doc, "Po").reshape(n, n)
            extra = np.linalg.inv(Po) / float(artefact_gain(doc, "beta")[0])
            est = diag.get("premises") == "estimated"
        c = region_level(s["P"], s["K"], G, g, margins, extra, est)
        stored = float(artefact_gain(doc, "region_c")[0])
        inner = float(np.sqrt(c / np.linalg.eigvalsh(s["P"])[-1]))
        need = float(option(doc, spec, "region_margin", 0.01))
        ok = abs(c - stored) <= 1e-6 * max(c, 1e-300) and inner >= need
        return [Check("region_recheck", bool(ok),
                      f"level c = {c:.6g} re-derived in closed form (domain faces, pump margins) vs "
                      f"stored {stored:.6g}; inner radius {inner:.4g} (region_margin {need:g}); "
                      f"largest deviations {fmt(np.sqrt(c * np.diag(np.linalg.inv(s['P']))))}",
                      {"c": c, "stored_c": stored, "inner_radius": inner})]

    def sim_checks() -> list[Check]:
        count = int(option(doc, spec, "verify_points", 24))
        E0, eps0 = region_sample(doc, spec, count, int(option(doc, spec, "seed", 0)))
        horizon = region_horizon(doc)
        out = simulate_region(doc, spec, E0, horizon=horizon, eps0=eps0, trace=trace)
        cond = region_conditions(out, float(artefact_gain(doc, "region_c")[0]))
        grow, final = float(cond["max_growth"].max()), float(cond["final_ratio"].max())
        left, sat = int(out["left_domain"].sum()), int(out["saturated"].sum())
        ok = bool(np.all(cond["passed"]))
        return [Check("region_simulation", bool(ok),
                      f"{len(E0)} closed-loop runs of the nonlinear plant from seeded points on and "
                      f"inside the certified region (sampled at {out['ts']:.3g} s for {horizon:.4g} s): "
                      f"{left} left the TS domain, {sat} asked for pump flows outside the limits, "
                      f"largest relative growth of V per sample {grow:.3g} (<= {GROWTH_LIMIT:g}), "
                      f"largest V(T)/V(0) {final:.3g} (<= {FINAL_RATIO:g})",
                      {"runs": len(E0), "left_domain": left, "saturated": sat, "max_growth": grow,
                       "max_final_ratio": final, "ts": out["ts"], "horizon": horizon})]

    for name, fn in (("ts_model_recheck", model_checks), ("lmi_recheck", lmi_checks),
                     ("region_recheck", region_checks), ("region_simulation", sim_checks)):
        checks += guard(name, fn)
    if "sp_K" in (doc.get("gains") or {}):
        checks += setpoint_checks(doc, spec, trace=trace)
    return checks


def _observer_checks(doc: Mapping[str, Any], s: dict) -> list[Check]:
    diag = doc.get("diagnostics") or {}
    n = s["P"].shape[0]
    model = s["model"]
    Po = artefact_gain(doc, "Po").reshape(n, n)
    L = artefact_gain(doc, "L")
    if L.ndim == 3:
        obs = diag.get("observer") or {}
        rel = str(obs.get("relaxation", ""))
        alpha = float((obs.get("lmi") or {}).get("alpha", 0.0))
        # Lyapunov for A_i - L_j C with Po: the dual conditions on (A_i', C', L_j') with P = Po^-1
        # are congruent to these.
        r = model.A.shape[0]
        largest = []
        for cond in condition_weights(rel, r):
            S = np.zeros((n, n))
            for (i, j), w in cond.items():
                M = Po @ (model.A[i] - L[j] @ model.C)
                S += w * (M + M.T + 2 * alpha * Po)
            largest.append(np.linalg.eigvalsh(0.5 * (S + S.T))[-1])
        lam = np.array(largest)
        return [Check("observer_lmi_recheck", bool(lam.max() < 0),
                      f"{lam.size} PDC observer conditions ({rel}) on Po, L_j with alpha = {alpha:g} "
                      f"1/s: largest eigenvalue {lam.max():.4g} (< 0)", {"max_eigenvalue": float(lam.max())})]
    Q = artefact_gain(doc, "Q").reshape(n, n)
    A0 = artefact_gain(doc, "A0").reshape(n, n)
    psi = float((diag.get("observer") or {}).get("psi", np.nan))
    Gm = Po @ (A0 - L @ model.C)
    blk = np.block([[Gm + Gm.T + psi ** 2 * Q, Po], [Po, -Q]])
    top = float(np.linalg.eigvalsh(0.5 * (blk + blk.T))[-1])
    dA = float(np.max(np.abs(A0 - model.A.mean(axis=0))))
    return [Check("observer_lmi_recheck", bool(np.isfinite(psi) and top < 0 and dA <= 1e-9),
                  f"observer LMI [[He(Po (A0 - L C)) + psi^2 Q, Po], [Po, -Q]] with psi = {psi:.4g} 1/s: "
                  f"largest eigenvalue {top:.4g} (< 0); stored A0 vs the mean rebuilt vertex: {dA:.3g}",
                  {"max_eigenvalue": top, "psi": psi})]
