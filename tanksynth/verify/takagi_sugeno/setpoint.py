"""Verdict of a Takagi-Sugeno PDC set-point change (gain keys ``sp_``), own numerics.

A ``ts_state_feedback`` / ``ts_output_feedback`` artefact designed with a
``setpoint`` carries a second PDC about ``x_op2`` (its TS model, ``K``,
``P``, region level, and ``beta`` with an observer) and the switch level
``gamma``: from ``{V_1 <= gamma c_1}`` the law about ``x_op2`` keeps the
state in ``{V_2 <= c_2}``. Nothing here imports the design code; from the
artefact and the plant this module re-derives:

``setpoint_lmi_recheck``
    ``x_op2`` an equilibrium with ``u_op2``, the TS model about it rebuilt
    from the plant and compared with ``f(x, u)``, its PDC conditions
    (eigvalsh);
``setpoint_region_recheck``
    ``c_2`` in closed form, the first operating point inside ``{V_2 <=
    c_2}``, and ``max V_2`` over ``{V_1 <= gamma c_1}`` (a convex quadratic
    maximised on an ellipsoid: the secular equation of the trust-region
    problem, not the design's S-lemma) at most ``c_2``;
``setpoint_simulation``
    half of ``verify_points`` runs of the nonlinear plant from seeded points
    on and inside the first region:
    the first law for the dwell time, then the law about ``x_op2``; and
    as many runs that switch at once from points on and inside ``{V_1 <=
    gamma c_1}``.
    Every run stays in the domain, never saturates, has ``V_2 <= c_2`` at
    the switch and non-increasing after it, and ends within
    ``setpoint_tolerance`` of ``x_op2``.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, fmt, guard, option
from tanksynth.verify.traces import TraceRecorder
from tanksynth.verify.takagi_sugeno.loops import (GROWTH_LIMIT, loop_setup, region_points,
                                                  region_sample, simulate_region)
from tanksynth.verify.takagi_sugeno.model import model_recheck, pdc_conditions, region_level

__all__ = ["PREFIX", "max_on_ellipsoid", "setpoint_checks", "switch_runs", "setpoint_conditions",
           "setpoint_settle_time"]

#: Prefix of the set-point design's gain keys.
PREFIX = "sp_"


def max_on_ellipsoid(P1: np.ndarray, level: float, P2: np.ndarray, d: np.ndarray) -> float:
    """``max (z - d)' P2 (z - d)`` over ``z' P1 z <= level`` (secular equation).

    With ``w = L' z`` (``P1 = L L'``) the set is the ball ``|w| <= r``; in
    the eigenbasis of ``Q = L^-1 P2 L^-T`` (eigenvalues ``q``, ``b`` the
    centre's coordinates) the maximiser is ``w_i = q_i b_i / (q_i - mu)``
    with ``mu > max q`` solving ``|w(mu)| = r`` (bisection); in the hard
    case (``b`` orthogonal to the top eigenvector) the top direction is
    filled up to the radius.

    Parameters
    ----------
    P1, P2 : ndarray, shape (k, k)
        Positive definite matrices (per squared state unit).
    level : float
        Level of the first set (dimensionless: the units of ``e' P e``).
    d : ndarray, shape (k,)
        Centre of the quadratic (state units).
    """
    Lc = np.linalg.cholesky(0.5 * (P1 + P1.T))
    Li = np.linalg.inv(Lc)
    q, V = np.linalg.eigh(Li @ (0.5 * (P2 + P2.T)) @ Li.T)
    b = V.T @ (Lc.T @ d)
    r = np.sqrt(max(level, 0.0))

    def value(w: np.ndarray) -> float:
        return float(np.sum(q * (w - b) ** 2))

    top = q[-1]
    ties = np.isclose(q, top, rtol=1e-12, atol=0.0)
    if np.linalg.norm(b[ties]) <= 1e-14 * max(float(np.linalg.norm(b)), 1e-300):
        w = np.where(ties, 0.0, q * b / np.where(ties, 1.0, q - top))
        rest = r ** 2 - float(w @ w)
        if rest >= 0:
            k = int(np.flatnonzero(ties)[0])
            w[k] = np.sqrt(rest)
            return value(w)
    lo = top * (1 + 1e-15) + 1e-300
    hi = top + np.sqrt(float(np.sum((q * b) ** 2))) / max(r, 1e-300) + abs(top) + 1.0
    for _ in range(200):
        mu = 0.5 * (lo + hi)
        w = q * b / (q - mu)
        if float(w @ w) > r ** 2:
            lo = mu
        else:
            hi = mu
    w = q * b / (q - hi)
    return value(w)


def _blocks(doc: Mapping[str, Any], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(P1, P2, x_op1, x_op2)`` of the switch: block-diagonal with the observer term."""
    P1 = artefact_gain(doc, "P").reshape(n, n)
    P2 = artefact_gain(doc, PREFIX + "P").reshape(n, n)
    x1 = artefact_gain(doc, "x_op").reshape(n)
    x2 = artefact_gain(doc, PREFIX + "x_op").reshape(n)
    if doc["method"] == "ts_output_feedback":
        Po = artefact_gain(doc, "Po").reshape(n, n)
        Z = np.zeros((n, n))
        P1 = np.block([[P1, Z], [Z, float(artefact_gain(doc, "beta")[0]) * Po]])
        P2 = np.block([[P2, Z], [Z, float(artefact_gain(doc, PREFIX + "beta")[0]) * Po]])
    return P1, P2, x1, x2


def _decay(doc: Mapping[str, Any], n: int, prefix: str) -> float:
    """Certified decay (1/s) of ``V`` about one operating point: the PDC's, or the cascade's
    ``min_j lambda_min(D^-1/2 W_j D^-1/2) / 2`` with an observer (own numerics)."""
    diag = doc.get("diagnostics") or {}
    sub = diag.get("setpoint") or {} if prefix else diag
    alpha_c = float(sub.get("decay_rate", 0.0))
    if doc["method"] != "ts_output_feedback":
        return alpha_c
    alpha_o = float((diag.get("observer") or {}).get("decay_rate", 0.0))
    Pc = artefact_gain(doc, prefix + "P").reshape(n, n)
    Po = artefact_gain(doc, "Po").reshape(n, n)
    beta = float(artefact_gain(doc, prefix + "beta")[0])
    B = artefact_gain(doc, "B").reshape(n, -1)
    K = artefact_gain(doc, prefix + "K").reshape(-1, B.shape[1], n)
    D = np.block([[Pc, np.zeros((n, n))], [np.zeros((n, n)), beta * Po]])
    lam, U = np.linalg.eigh(D)
    R = U @ np.diag(lam ** -0.5) @ U.T
    rates = []
    for Kj in K:
        X = -Pc @ B @ Kj
        W = np.block([[2 * alpha_c * Pc, X], [X.T, 2 * beta * alpha_o * Po]])
        rates.append(float(np.linalg.eigvalsh(R @ W @ R)[0]) / 2)
    return min(rates)


def switch_runs(doc: Mapping[str, Any], spec: Spec, count: int, seed: Any) -> dict:
    """Seeded initial conditions of the set-point runs and the dwell time.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    count : int
        Runs of each kind.
    seed : int or sequence of int
        Seed of the sampling.

    Returns
    -------
    dict
        ``E_region`` (deviations on and inside the first region, with
        ``eps_region``), ``E_switch`` (on and inside ``{V_1 <= gamma c_1}``,
        with ``eps_switch``), ``dwell`` [s], ``gamma``, ``c1``, ``c2``.
    """
    n = spec.plant.n
    P1, _, _, _ = _blocks(doc, n)
    c1 = float(artefact_gain(doc, "region_c")[0])
    c2 = float(artefact_gain(doc, PREFIX + "region_c")[0])
    gamma = float(artefact_gain(doc, PREFIX + "switch_level")[0])
    E_region, eps_region = region_sample(doc, spec, count, seed)
    Z = region_points(P1, gamma * c1, count, [*np.atleast_1d(seed).tolist(), 5]) * (1 - 1e-6)
    E_switch, eps_switch = Z[:, :n], (Z[:, n:] if Z.shape[1] > n else None)
    rate = _decay(doc, n, "")
    dwell = float(np.log(1.0 / gamma) / (2 * rate)) if rate > 0 and gamma > 0 else float("inf")
    return {"E_region": E_region, "eps_region": eps_region, "E_switch": E_switch,
            "eps_switch": eps_switch, "dwell": dwell, "gamma": gamma, "c1": c1, "c2": c2}


def setpoint_settle_time(doc: Mapping[str, Any], n: int) -> float:
    """Simulated time [s] after the switch: the time for ``V_2`` to fall from ``c_2`` to
    ``lambda_min(P_2) tol^2`` at the certified decay (every state then within
    ``setpoint_tolerance``), kept within [100, 2000] s. The certified decay of
    an observer cascade is very conservative; the runs must reach the
    tolerance within this time whatever the bound says.

    Parameters
    ----------
    doc, n : mapping, int
        The artefact and the number of states.
    """
    tol = float(((doc.get("diagnostics") or {}).get("setpoint") or {}).get("tolerance", 0.002))
    P2 = artefact_gain(doc, PREFIX + "P").reshape(n, n)
    c2 = float(artefact_gain(doc, PREFIX + "region_c")[0])
    settle = float(np.log(c2 / (np.linalg.eigvalsh(P2)[0] * tol ** 2))
                   / (2 * max(_decay(doc, n, PREFIX), 1e-9)))
    return float(min(max(settle, 100.0), 2000.0))


def setpoint_conditions(out: Mapping[str, Any], x2: np.ndarray, c2: float, tol: float) -> dict:
    """Per-run conditions of set-point runs (`simulate_region` with a switch).

    Parameters
    ----------
    out : mapping
        `simulate_region` output (with ``switch``).
    x2, c2, tol : ndarray (n,), float, float
        New operating point (state units, m), level of its region, final tolerance (m).

    Returns
    -------
    dict of ndarray
        ``max_growth`` of ``V_2`` after the switch, ``switch_level`` (``V_2 / c_2``
        at the switch), ``final_error`` (largest state deviation from ``x2`` at
        the end, m), ``left_domain``, ``saturated``, ``passed``.
    """
    V, k = out["V"], int(out["switch"])
    after = V[:, k:]
    grow = np.max(np.diff(after, axis=1) / np.maximum(after[:, :-1], 1e-300)
                  * (after[:, :-1] > 1e-10 * c2), axis=1)
    at_switch = after[:, 0] / c2
    err = np.max(np.abs(out["x"][:, -1] - x2), axis=1)
    ok = (~out["left_domain"] & ~out["saturated"] & (grow <= GROWTH_LIMIT) & (at_switch <= 1 + 1e-6)
          & (err <= tol))
    return {"max_growth": grow, "switch_level": at_switch, "final_error": err,
            "left_domain": out["left_domain"], "saturated": out["saturated"], "passed": ok}


def setpoint_checks(doc: Mapping[str, Any], spec: Spec, *,
                    trace: TraceRecorder | None = None) -> list[Check]:
    """The set-point checks of a PDC artefact with ``sp_`` gains (see the module).

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and the recorder of the verdict's runs
        (the set-point runs are added to its arrays as ``setpoint_t``, ``setpoint_x``).
    """
    n = spec.plant.n
    diag = doc.get("diagnostics") or {}
    sp = diag.get("setpoint") or {}
    of = doc["method"] == "ts_output_feedback"

    def lmi() -> list[Check]:
        model = model_recheck(doc, spec, PREFIX, "setpoint_lmi_recheck")
        s = loop_setup(doc, spec, PREFIX)
        rel = str(sp.get("relaxation", ""))
        alpha = float((sp.get("lmi") or {}).get("alpha", 0.0))
        lam = pdc_conditions(s["P"], s["model"].A, s["model"].B, s["K"], alpha, rel)
        pmin = float(np.linalg.eigvalsh(s["P"])[0])
        ok = model.passed and bool(lam.max() < 0 and pmin > 0)
        return [Check("setpoint_lmi_recheck", ok,
                      model.detail + f"; {lam.size} PDC conditions ({rel}) about the set-point with "
                      f"alpha = {alpha:g} 1/s: largest eigenvalue {lam.max():.4g} (< 0), smallest "
                      f"eigenvalue of P2 {pmin:.4g}",
                      {**dict(model.data or {}), "max_eigenvalue": float(lam.max())})]

    def region() -> list[Check]:
        s = loop_setup(doc, spec, PREFIX)
        G, g = s["model"].faces()
        margins = diag.get("input_margins")
        margins = None if margins is None else np.asarray(margins, float)
        if margins is not None:   # the pump margins about x_op2
            lim = np.asarray(spec.plant.input_limits, float).reshape(spec.plant.m, 2)
            margins = np.minimum(s["model"].u0 - lim[:, 0], lim[:, 1] - s["model"].u0)
        extra, est = None, False
        if of:
            Po = artefact_gain(doc, "Po").reshape(n, n)
            extra = np.linalg.inv(Po) / float(artefact_gain(doc, PREFIX + "beta")[0])
            est = diag.get("premises") == "estimated"
        c2 = region_level(s["P"], s["K"], G, g, margins, extra, est)
        stored = float(artefact_gain(doc, PREFIX + "region_c")[0])
        P1, P2, x1, x2 = _blocks(doc, n)
        d = np.concatenate([x2 - x1, np.zeros(P1.shape[0] - n)])
        c1 = float(artefact_gain(doc, "region_c")[0])
        gamma = float(artefact_gain(doc, PREFIX + "switch_level")[0])
        first = float((x1 - x2) @ s["P"] @ (x1 - x2)) / c2
        worst = max_on_ellipsoid(P1, gamma * c1, P2, d) / c2
        inner = float(np.sqrt(c2 / np.linalg.eigvalsh(s["P"])[-1]))
        need = float(option(doc, spec, "region_margin", 0.01))
        ok = (abs(c2 - stored) <= 1e-6 * max(c2, 1e-300) and first < 1 and 0 < gamma <= 1
              and worst <= 1 + 1e-6 and inner >= need)
        return [Check("setpoint_region_recheck", bool(ok),
                      f"level c2 = {c2:.6g} about x_op2 = {fmt(x2)} re-derived (stored {stored:.6g}), "
                      f"inner radius {inner:.4g} (region_margin {need:g}); the first operating point "
                      f"at V2 = {first:.4g} c2 (< 1); max V2 over {{V1 <= gamma c1}} with gamma = "
                      f"{gamma:.4g}: {worst:.6g} c2 (<= 1, secular equation)",
                      {"c2": c2, "stored_c2": stored, "first_point_level": first,
                       "switch_max_level": worst, "gamma": gamma, "inner_radius": inner})]

    def sim() -> list[Check]:
        count = max(2, int(option(doc, spec, "verify_points", 24)) // 2)   # of each kind
        runs = switch_runs(doc, spec, count, int(option(doc, spec, "seed", 0)) + 11)
        x2 = artefact_gain(doc, PREFIX + "x_op").reshape(n)
        tol = float(option(doc, spec, "setpoint_tolerance", 0.002))
        settle = setpoint_settle_time(doc, n)
        dwell = runs["dwell"] if np.isfinite(runs["dwell"]) else settle
        full = simulate_region(doc, spec, runs["E_region"], eps0=runs["eps_region"],
                               horizon=dwell + settle, switch_at=dwell)
        direct = simulate_region(doc, spec, runs["E_switch"], eps0=runs["eps_switch"],
                                 horizon=settle, switch_at=0.0)
        parts = [setpoint_conditions(o, x2, runs["c2"], tol) for o in (full, direct)]
        if trace is not None and trace.trace is not None:
            keep = max(1, int(np.ceil(full["t"].size / 2000)))
            trace.trace["arrays"]["setpoint_t"] = full["t"][::keep]
            trace.trace["arrays"]["setpoint_x"] = full["x"][:, ::keep]
            trace.trace["header"]["setpoint"] = {"x_op2": x2.tolist(), "switch_time": dwell,
                                                 "gamma": runs["gamma"]}
        cat = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        ok = bool(np.all(cat["passed"]))
        return [Check("setpoint_simulation", ok,
                      f"set-point change to x_op2 = {fmt(x2)} on the nonlinear plant: {count} runs from "
                      f"seeded points on and inside the first region (first law for the dwell time "
                      f"{dwell:.4g} s, then the law about x_op2 for {settle:.4g} s) and {count} runs "
                      f"switching at once from {{V1 <= gamma c1}}, gamma = {runs['gamma']:.4g}: "
                      f"{int(cat['left_domain'].sum())} left the TS domain, "
                      f"{int(cat['saturated'].sum())} saturated a pump, largest V2/c2 at the switch "
                      f"{cat['switch_level'].max():.4g} (<= 1), largest relative growth of V2 per "
                      f"sample {cat['max_growth'].max():.3g} (<= {GROWTH_LIMIT:g}), largest final "
                      f"distance to x_op2 {cat['final_error'].max():.3g} m (<= {tol:g})",
                      {"runs": 2 * count, "left_domain": int(cat["left_domain"].sum()),
                       "saturated": int(cat["saturated"].sum()),
                       "max_switch_level": float(cat["switch_level"].max()),
                       "max_growth": float(cat["max_growth"].max()),
                       "max_final_error": float(cat["final_error"].max()), "dwell_time": dwell,
                       "settle_time": settle, "ts": full["ts"]})]

    out: list[Check] = []
    for name, fn in (("setpoint_lmi_recheck", lmi), ("setpoint_region_recheck", region),
                     ("setpoint_simulation", sim)):
        out += guard(name, fn)
    return out
