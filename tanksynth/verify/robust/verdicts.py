"""Verdicts of ``robust_state_feedback`` and ``robust_observer``.

Own numerics, no design import (campaign runners: `tanksynth.verify.robust.campaign`). From the gains and
the options (region, uncertain box, H-infinity bound, saturation):

``model_recheck`` / ``vertex_models``
    the nominal ``A``, ``B``, ``C`` against the linearisation; the 2^k corner models re-linearised here
    (levels ``x0`` kept, each its own equilibrium input) against those the design recorded.
``vertex_region`` / ``vertex_lmi``
    every model's closed loop (augmented with the integrators when the design has integral action) or error
    matrix ``A_i - L C_i`` has its eigenvalues in the region; the region LMI holds at every model with the ONE
    stored Lyapunov matrix (``X = P^-1``, observers ``X = P``). The worst vertex and its parameters are named.
``vertex_hinf``
    (with ``gamma``) the H-infinity norm of every model's closed loop from ``w`` to ``z``, by Hamiltonian
    bisection (discrete time: through the bilinear transform, which preserves the norm), below ``gamma``.
``sampled_region``
    ``samples`` uniform parameter values: their linearisations keep the eigenvalues in the region (the vertex
    certificate is exact only for models multi-affine in the parameters).
``monte_carlo``
    ``mc_runs`` plants with sampled parameters, NONLINEAR model, one batch (each run its own parameter
    values): state feedback from ``x0 + delta``, every run settles (tracked outputs back on their set-points
    with integral action; its own equilibrium otherwise, the offset reported); observers with the run's own
    linear model and the shared ``L``, every error below 5 % of its initial value on ``[H, 1.2 H]``.
``saturation_*``
    (with ``saturation``) ``max |K_j x|`` over the ellipsoid ``x' P x <= 1`` below ``umax_j``, the requested
    box inside it, and nominal nonlinear runs from its boundary (inside the operating region): the UNCLIPPED
    input never leaves ``|u - u0| <= umax`` (tolerance `SATURATION_TOLERANCE` for the nonlinearity).
"""

from __future__ import annotations

import itertools
import math
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.analysis.linearize import discretize_zoh, equilibrium_input
from tanksynth.analysis.lmi_region import region_from_parts
from tanksynth.errors import ArtefactError
from tanksynth.sim.simulate import run_seeds, simulate
from tanksynth.spec import Spec
from tanksynth.spec.options import parse_region
from tanksynth.verify.robust.models import box_corners, box_samples, linear_models, uncertain_box
from tanksynth.verify.robust.traces import PeakRecordingLaw, record_monte_carlo
from tanksynth.verify.common import (MAX_STEPS, OBSERVER_TOLERANCE, artefact_matrix, discrete_ts,
                                     fmt, guard, model_recheck, option, output_at, stability_check,
                                     time_domain)
from tanksynth.verify.numerics import integral_augmentation, region_lmi_matrix
from tanksynth.verify.simulations import (IntegralStateFeedback, StateFeedback, designed_time_constant,
                                          eigen_time_constant, eigenvector_conditioning, observer_period, perturbed_start)
from tanksynth.verify.traces import TraceRecorder

__all__ = ["SATURATION_TOLERANCE", "hinf_norm", "robust_feedback_law",
           "robust_state_feedback_verdict", "robust_observer_verdict"]

#: Relative excess of ``|u - u0|`` over ``umax`` tolerated on the nonlinear plant.
SATURATION_TOLERANCE = 0.02
_MODEL_TOL = 1e-8


# ================================================================ numerics
def hinf_norm(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray | None = None,
              domain: str = "continuous", rtol: float = 1e-7) -> float:
    """H-infinity norm of a stable system, Hamiltonian bisection (discrete: bilinear transform).

    Parameters
    ----------
    A, B, C, D : ndarray
        State space (``D`` zeros when None).
    domain : {"continuous", "discrete"}
    rtol : float
        Relative width of the final bisection interval.

    Returns
    -------
    float
        The norm (units of the output per unit of the input); ``inf`` if ``A`` is not stable.
    """
    A, B, C = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (A, B, C))
    n = A.shape[0]
    D = np.zeros((C.shape[0], B.shape[1])) if D is None else np.atleast_2d(np.asarray(D, dtype=float))
    eig = np.linalg.eigvals(A)
    if domain == "discrete":
        if np.max(np.abs(eig)) >= 1:
            return math.inf
        Ei = np.linalg.inv(A + np.eye(n))
        A, B, C, D = Ei @ (A - np.eye(n)), math.sqrt(2) * Ei @ B, math.sqrt(2) * C @ Ei, D - C @ Ei @ B
    elif np.max(eig.real) >= 0:
        return math.inf

    def sigma(w: float) -> float:
        G = C @ np.linalg.solve(1j * w * np.eye(n) - A, B) + D
        return float(np.linalg.norm(G, 2))

    freqs = np.concatenate([[0.0], np.logspace(-6, 6, 121) * max(float(np.max(np.abs(eig))), 1e-12)])
    lo = max(max(sigma(w) for w in freqs), float(np.linalg.norm(D, 2)), 1e-300)
    hi = 2.0 * lo

    def crossing(g: float) -> bool:
        R = g * g * np.eye(D.shape[1]) - D.T @ D
        Ri = np.linalg.inv(R)
        Ah = A + B @ Ri @ D.T @ C
        H = np.block([[Ah, B @ Ri @ B.T],
                      [-C.T @ (np.eye(C.shape[0]) + D @ Ri @ D.T) @ C, -Ah.T]])
        ev = np.linalg.eigvals(H)
        return bool(np.any(np.abs(ev.real) <= 1e-9 * max(1.0, float(np.max(np.abs(ev))))))

    while crossing(hi):
        hi *= 2.0
    while hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        if crossing(mid):
            lo = mid
        else:
            hi = mid
    return hi


def _models(spec: Spec, box: Sequence[Sequence[Any]], values: np.ndarray, domain: str,
            Bw: Any) -> list[dict]:
    """Linearisations at the spec's levels for parameter values (rows of ``values``), the plant
    compiled once with the parameters as arguments (`tanksynth.verify.robust.models`)."""
    plant = spec.plant
    names = [b[0] for b in box]
    values = np.asarray(values, dtype=float)
    values = values.reshape(values.shape[0] if values.ndim else 1, len(names))
    u0s, Fs, Bs, Cs = linear_models(plant, names, values, spec.x0)
    out = []
    for row, u0, F, Bc, C in zip(values, u0s, Fs, Bs, Cs):
        W = Bc if isinstance(Bw, str) and Bw == "inputs" else (
            np.eye(plant.n) if isinstance(Bw, str) else np.asarray(Bw, dtype=float))
        A, B = F, Bc
        if domain == "discrete":
            Ad, BB = discretize_zoh(F, np.hstack([Bc, W]), discrete_ts(spec))
            A, B, W = Ad, BB[:, :plant.m], BB[:, plant.m:]
        out.append({"A": A, "B": B, "C": C, "Bw": W, "u0": u0, "F": F, "Bc": Bc,
                    "params": dict(zip(names, map(float, row)))})
    return out


def _label(params: Mapping[str, float]) -> str:
    return ", ".join(f"{k} = {v:.6g}" for k, v in params.items()) or "nominal"


# ============================================================ shared context
def _context(doc: Mapping[str, Any], spec: Spec, observer: bool) -> dict:
    plant = spec.plant
    n, m, q = plant.n, plant.m, plant.q
    domain = time_domain(doc, spec)
    raw = option(doc, spec, "region")
    if raw is None:
        raise ArtefactError(f"artefact '{doc['name']}': the spec entry gives no region")
    region = region_from_parts(parse_region(raw, "region"))
    box = uncertain_box(doc, spec)
    Bw = option(doc, spec, "Bw")
    Bw = ("identity" if observer else "inputs") if Bw is None else np.asarray(Bw, dtype=float)
    corners = box_corners(box)
    models = _models(spec, box, corners, domain, Bw)
    if box:
        models += _models(spec, (), np.zeros((1, 0)), domain, Bw)
        models[-1]["params"] = {"nominal": 1.0}
    x0 = np.asarray(spec.x0, dtype=float)
    u0 = equilibrium_input(plant, spec.x0, spec.given_u0).u0
    c: dict[str, Any] = dict(plant=plant, n=n, m=m, q=q, domain=domain, region=region, box=box, Bw=Bw, models=models,
             x0=x0, u0=u0, A=artefact_matrix(doc, "A", (n, n), domain), B=artefact_matrix(doc, "B", (n, m), domain),
             C=artefact_matrix(doc, "C", (q, n)))
    integral = "K1" in doc["gains"] and "K2" in doc["gains"]
    c["integral"] = integral
    if observer:
        c["L"] = artefact_matrix(doc, "L", (n, q))
        c["size"] = n
    else:
        if integral:
            integ = (doc.get("diagnostics") or {}).get("integral") or {}
            outputs = [s.name for s in plant.outputs]
            tracked = list(option(doc, spec, "tracked") or integ.get("tracked") or outputs[:m])
            c["rows"] = [outputs.index(t) for t in tracked]
            c["tracked"] = tracked
            c["y0"] = output_at(plant, x0)[c["rows"]]   # the measured outputs at x0, offsets included
        p = len(c["rows"]) if integral else 0
        c["K"] = artefact_matrix(doc, "K", (m, n + p))
        c["size"] = n + p
    c["P"] = artefact_matrix(doc, "P", (c["size"], c["size"]))
    return c


def _closed(c: dict, mdl: Mapping[str, Any]) -> np.ndarray:
    """Closed-loop (or error) matrix of one model."""
    if "L" in c:
        return mdl["A"] - c["L"] @ mdl["C"]
    if c["integral"]:
        C1 = mdl["C"][c["rows"]]
        Aa, Ba = integral_augmentation(mdl["A"], mdl["B"], C1, c.get("ts"))
        return Aa - Ba @ c["K"]
    return mdl["A"] - mdl["B"] @ c["K"]


def _closed_loops(c: dict, spec: Spec, models: Sequence[Mapping[str, Any]]) -> list[np.ndarray]:
    c["ts"] = discrete_ts(spec) if c["domain"] == "discrete" else None
    return [_closed(c, mdl) for mdl in models]


# =================================================================== checks
def _vertex_checks(doc: Mapping[str, Any], spec: Spec, c: dict) -> list[Check]:
    region, models = c["region"], c["models"]
    checks = [model_recheck(c["plant"], c["x0"], c["u0"], c["domain"], spec.ts,
                            {"A": c["A"], "B": c["B"], "C": c["C"]})]
    stored = ((doc.get("diagnostics") or {}).get("vertex_models") or {})
    if stored.get("A") is not None and c["box"]:
        SA = np.asarray(stored["A"], dtype=float)
        SB = np.asarray(stored["B"], dtype=float)
        mine_A = np.array([mdl["A"] for mdl in models[:-1]])
        mine_B = np.array([mdl["B"] for mdl in models[:-1]])
        if SA.shape != mine_A.shape or SB.shape != mine_B.shape:
            diff = math.inf
        else:
            diff = max(float(np.max(np.abs(SA - mine_A)) / max(np.max(np.abs(mine_A)), 1e-300)),
                       float(np.max(np.abs(SB - mine_B)) / max(np.max(np.abs(mine_B)), 1e-300)))
        checks.append(Check("vertex_models", bool(diff <= _MODEL_TOL),
                            f"the {len(models) - 1} corner models re-linearised here (levels x0 kept, "
                            f"each with its own equilibrium input) against those the design recorded: "
                            f"largest relative difference {diff:.3g} (tolerance {_MODEL_TOL:g})",
                            {"relative_difference": diff}))
    loops = _closed_loops(c, spec, models)
    margins = [min(region.margin(complex(z)) for z in np.linalg.eigvals(M)) for M in loops]
    w = int(np.argmin(margins))
    what = "A_i - L C_i" if "L" in c else ("Aa_i - Ba_i K" if c["integral"] else "A_i - B_i K")
    checks.append(Check("vertex_region", bool(min(margins) > 0),
                        f"eigenvalues of {what} at all {len(models)} models ({2 ** len(c['box'])} corners"
                        f"{' + nominal' if c['box'] else ''}) against the region {region.describe()}: "
                        f"smallest margin -lambda_max(f_D) = {min(margins):.3g} at the worst vertex "
                        f"({_label(models[w]['params'])}), eigenvalues {fmt(np.linalg.eigvals(loops[w]), 5)}",
                        {"margins": [float(v) for v in margins], "worst_vertex": w,
                         "worst_parameters": models[w]["params"]}))
    P = c["P"]
    X = P if "L" in c else np.linalg.inv(P)
    worst_lmi, wl = -math.inf, 0
    for i, M in enumerate(loops):
        Acl = M.T if "L" in c else M
        lam = float(np.max(np.linalg.eigvalsh(region_lmi_matrix(region.L, region.M, Acl, X))))
        if lam > worst_lmi:
            worst_lmi, wl = lam, i
    xmin = float(np.min(np.linalg.eigvalsh(0.5 * (X + X.T))))
    checks.append(Check("vertex_lmi", bool(worst_lmi < 0 and xmin > 0),
                        f"region LMI with the ONE stored Lyapunov matrix ({'X = P' if 'L' in c else 'X = P^-1'}) "
                        f"at every model, recomputed in numpy: largest eigenvalue {worst_lmi:.4g} at "
                        f"({_label(models[wl]['params'])}) (must be < 0); smallest eigenvalue of X "
                        f"{xmin:.4g}", {"lmi_max_eigenvalue": worst_lmi, "X_min_eigenvalue": xmin}))
    gamma = option(doc, spec, "gamma")
    if gamma is not None:
        checks += guard("vertex_hinf", lambda: [_hinf_check(doc, spec, c, loops, float(gamma))])
    nominal = loops[-1]
    checks.append(stability_check(np.linalg.eigvals(nominal), c["domain"], f"the nominal {what}"))
    return checks


def _hinf_check(doc: Mapping[str, Any], spec: Spec, c: dict, loops: Sequence[np.ndarray],
                gamma: float) -> Check:
    n = c["n"]
    Cz = option(doc, spec, "Cz")
    Cz = np.eye(n) if Cz is None else np.asarray(Cz, dtype=float)
    norms = []
    for mdl, M in zip(c["models"], loops):
        size = M.shape[0]
        Bw = np.zeros((size, mdl["Bw"].shape[1]))
        Bw[:n] = mdl["Bw"]
        if "L" in c:
            Cc = Cz
        else:
            Dzu = option(doc, spec, "Dzu")
            Dzu = np.zeros((Cz.shape[0], c["m"])) if Dzu is None else np.asarray(Dzu, dtype=float)
            Cc = np.hstack([Cz, np.zeros((Cz.shape[0], size - n))]) - Dzu @ c["K"]
        norms.append(hinf_norm(M, Bw, Cc, None, c["domain"]))
    w = int(np.argmax(norms))
    return Check("vertex_hinf", bool(max(norms) <= gamma * (1 + 1e-6)),
                 f"H-infinity norm from w to z of every model's closed loop by Hamiltonian bisection"
                 f"{' (bilinear transform of the discrete loop)' if c['domain'] == 'discrete' else ''}: "
                 f"largest {max(norms):.6g} at ({_label(c['models'][w]['params'])}), bound gamma = "
                 f"{gamma:g}", {"norms": [float(v) for v in norms], "gamma": gamma})


def _sampled_check(doc: Mapping[str, Any], spec: Spec, c: dict) -> list[Check]:
    if not c["box"]:
        return [Check("sampled_region", None, "no uncertain parameter: nothing to sample")]
    count = int(option(doc, spec, "samples", 200))
    seed = int(option(doc, spec, "seed", 0))
    values = box_samples(c["box"], count, seed)
    models = _models(spec, c["box"], values, c["domain"], c["Bw"])
    loops = _closed_loops(c, spec, models)
    region = c["region"]
    margins = np.array([min(region.margin(complex(z)) for z in np.linalg.eigvals(M)) for M in loops])
    w = int(np.argmin(margins))
    bad = int(np.sum(margins <= 0))
    return [Check("sampled_region", bool(bad == 0),
                  f"{count} parameter values drawn uniformly in the box (seed {seed}), linearised at "
                  f"the operating levels: {bad} with an eigenvalue outside {region.describe()}; "
                  f"smallest margin {margins[w]:.3g} at ({_label(models[w]['params'])})",
                  {"outside": bad, "samples": count, "min_margin": float(margins[w]),
                   "worst_parameters": models[w]["params"]})]


def _horizon(doc: Mapping[str, Any], spec: Spec, c: dict, ts: float) -> tuple[float, int, int, str]:
    loops = _closed_loops(c, spec, c["models"])
    eigs = np.concatenate([np.linalg.eigvals(M) for M in loops])
    tau, rule = designed_time_constant(doc, spec, eigs, c["domain"], spec.ts)
    kappa = max(eigenvector_conditioning(M) for M in loops)
    kappa = min(max(kappa, 1.0), 1e8) if np.isfinite(kappa) else 1e8
    own = eigen_time_constant(eigs, c["domain"], spec.ts)[0]
    if 1.2 * tau * (5.0 + math.log(kappa)) / ts > 10 * MAX_STEPS and own < tau:  # a weak promise
        tau, rule = own, f"(the vertex loops' own: {rule[1:-1]} would take too long to simulate)"
    H = tau * (5.0 + math.log(kappa))
    k_h = max(int(math.ceil(H / ts)), 1)
    return H, k_h, max(int(math.ceil(1.2 * H / ts)), k_h + 1), f"tau = {tau:.4g} s {rule}, kappa = {kappa:.3g}"


def _sim_period(c: dict, spec: Spec, loops: Sequence[np.ndarray]) -> float:
    if c["domain"] == "discrete":
        return discrete_ts(spec)
    fast = max(float(np.max(np.abs(np.linalg.eigvals(M)))) for M in loops)
    step = 0.05 / fast if fast > 0 else 1.0
    return float(min(step, spec.ts)) if spec.ts else step


def robust_feedback_law(K: np.ndarray, C: np.ndarray, rows: Sequence[int] | None, x0: np.ndarray,
                        u0: np.ndarray, ts: float, y0: np.ndarray | None = None
                        ) -> StateFeedback | IntegralStateFeedback:
    """The robust state feedback as a batch control law, with integral action when it tracks.

    Parameters
    ----------
    K : ndarray, shape (m, n) or (m, n + p)
        The stored gain (input units per state unit; its last p columns act on the integrators).
    C : ndarray, shape (q, n)
        The stored output matrix (output units per state unit).
    rows : sequence of int or None
        The tracked outputs' rows of ``C`` (p of them); None: no integral action.
    x0, u0 : ndarray (n,), ndarray (m,)
        Operating point (state units, m) and its input (input units, m^3/s).
    ts : float
        Sampling period of the integrators [s].
    y0 : ndarray, shape (p,), optional
        The tracked outputs at ``x0``, ``h(x0)`` (output units, offsets included): the
        integrators integrate ``y_r - y0 - C1 (x - x0)``. None: ``C1 x0``.
    """
    if rows is not None:
        n = C.shape[1]
        C1 = np.zeros((len(rows), n))
        for i, r in enumerate(rows):
            C1[i] = C[r]
        return IntegralStateFeedback(K[:, :n], K[:, n:], C1, x0, u0, ts,
                                     y0=None if y0 is None else np.asarray(y0, dtype=float).reshape(-1))
    return StateFeedback(K, x0, u0)


def _law(c: dict, ts: float) -> StateFeedback | IntegralStateFeedback:
    """`robust_feedback_law` of a verdict's context."""
    return robust_feedback_law(c["K"], c["C"], c["rows"] if c["integral"] else None, c["x0"], c["u0"], ts,
                               c.get("y0"))


def _too_stiff(c: dict, spec: Spec, ts: float, H: float, steps: int, rule: str) -> Check:
    """The Monte-Carlo check of a loop too stiff to simulate: failed (the gain cannot be trusted
    without its run on the nonlinear plant), with the loop's time scales and which one is to blame."""
    eigs = np.concatenate([np.linalg.eigvals(M) for M in _closed_loops(c, spec, c["models"])])
    fast, unit = float(np.max(np.abs(eigs))), " 1/s" if c["domain"] == "continuous" else ""
    why = ("a gain this fast saturates the pumps at once and cannot be run by a sampled controller: bound the "
           "region (e.g. a disk or sector as well as the half-plane) so that the eigenvalues stay slow"
           if ts < float(spec.ts or np.inf) else f"the horizon is that long because of {rule}: ask the region "
           "for a faster guaranteed decay (the gain is not too fast)")   # a slow decay, not a fast gain
    return Check("monte_carlo", False, f"not simulated: the closed loop spans {fast:.3g}{unit} (largest "
                 f"|eigenvalue|) to a horizon of {H:.4g} s, {steps} samples of {ts:.3g} s (limit "
                 f"{10 * MAX_STEPS}); {why}", {"samples": int(steps), "fastest_eigenvalue": fast, "horizon_s": H})


def _mc_feedback(doc: Mapping[str, Any], spec: Spec, c: dict, trace: TraceRecorder | None = None) -> list[Check]:
    plant = spec.plant
    runs = int(option(doc, spec, "mc_runs", 16))
    seed = int(option(doc, spec, "seed", 0))
    ts = _sim_period(c, spec, _closed_loops(c, spec, c["models"]))
    H, k_h, steps, rule = _horizon(doc, spec, c, ts)
    if steps > 10 * MAX_STEPS:
        return [_too_stiff(c, spec, ts, H, steps, rule)]
    values = box_samples(c["box"], runs, seed + 1) if c["box"] else np.zeros((runs, 0))
    params = {b[0]: values[:, j] for j, b in enumerate(c["box"])}
    x_start, frac = perturbed_start(plant, c["x0"])
    law = _law(c, ts)
    ref = None
    if c["integral"]:
        y0 = np.asarray(plant.compiled.output(c["x0"][None]), dtype=float).reshape(-1)[c["rows"]]
        ref = np.tile(y0, (steps + 1, 1))
    res = simulate(plant, ts=ts, steps=steps, x0=x_start, seeds=run_seeds(seed, runs), controller=law,
                   reference=ref, u_init=c["u0"], parameters=params)
    record_monte_carlo(trace, res, plant, observer=False,
                       reference_names=c["tracked"] if ref is not None else None)
    X = res.x
    d0 = float(np.max(np.abs(x_start - c["x0"])))
    tol = OBSERVER_TOLERANCE * d0
    settle = np.max(np.abs(X[:, k_h:] - X[:, -1:]), axis=(1, 2))
    offset = np.max(np.abs(X[:, -1] - c["x0"]), axis=1)
    if c["integral"] and ref is not None:
        track = np.max(np.abs(res.y[:, k_h:][..., c["rows"]] - ref[0][None, None, :]), axis=(1, 2))
        err = np.maximum(settle, track)
        what = (f"tracked outputs {c['tracked']} back within {tol:.3g} of their set-points and every "
                "state settled")
    else:
        err = settle
        what = "every state settled (to the run's own equilibrium)"
    ok_runs = np.isfinite(err) & (err <= tol)
    w = int(np.nanargmax(np.where(np.isfinite(err), err, np.inf)))
    worst = {b[0]: float(values[w, j]) for j, b in enumerate(c["box"])}
    return [Check("monte_carlo", bool(np.all(ok_runs)),
                  f"{runs} plants with parameters drawn uniformly in the box (seed {seed + 1}), NONLINEAR "
                  f"model with pump saturation, from x0 + delta ({100 * frac:g} % of the region span), "
                  f"u = u0 - K (x - x0){' - K2 z' if c['integral'] else ''} sampled every {ts:.4g} s: "
                  f"{int(np.sum(~ok_runs))} run(s) fail '{what}' on [H, 1.2 H] (tolerance {tol:.3g} = "
                  f"{100 * OBSERVER_TOLERANCE:g} % of |delta|); worst run {w} ({_label(worst)}): "
                  f"{err[w]:.3g}; largest final offset |x - x0|_inf = {float(np.max(offset)):.3g}; rule "
                  f"H = tau (5 + ln kappa) = {H:.4g} s, {rule}",
                  {"failed_runs": int(np.sum(~ok_runs)), "errors": err.tolist(),
                   "offsets": offset.tolist(), "worst_parameters": worst, "horizon_s": H, "ts": ts})]


def _saturation_checks(doc: Mapping[str, Any], spec: Spec, c: dict) -> list[Check]:
    plant, n = spec.plant, c["n"]
    P, K = c["P"], c["K"]
    lim = np.asarray(plant.input_limits, dtype=float)
    room = np.minimum(c["u0"] - lim[:, 0], lim[:, 1] - c["u0"])
    umax = option(doc, spec, "umax")
    umax = room if umax is None else np.asarray(umax, dtype=float)
    Xo = np.linalg.inv(P)
    peak = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", K, Xo, K), 0.0))
    ratio = float(np.max(peak / umax))
    checks = [Check("saturation_bound", bool(ratio <= 1 + 1e-6),
                    f"max over the ellipsoid x' P x <= 1 of |K_j x| = sqrt(K_j P^-1 K_j') = {fmt(peak)} "
                    f"against umax = {fmt(umax)} (input units): largest ratio {ratio:.6g} (must be <= 1)",
                    {"peak": peak.tolist(), "umax": umax.tolist()})]
    lyap = -math.inf
    for M in _closed_loops(c, spec, c["models"]):
        Lm = M.T @ P + P @ M if c["domain"] == "continuous" else M.T @ P @ M - P
        lyap = max(lyap, float(np.max(np.linalg.eigvalsh(0.5 * (Lm + Lm.T)))) / float(np.linalg.norm(P, 2)))
    form = "A_cl' P + P A_cl" if c["domain"] == "continuous" else "A_cl' P A_cl - P"
    checks.append(Check("saturation_invariance", bool(lyap <= 1e-9),
                        f"the ellipsoid is invariant at every model: largest eigenvalue of {form} "
                        f"relative to |P| = {lyap:.3g} (must be <= 0)", {"value": lyap}))
    Pxx = P[:n, :n]
    box = option(doc, spec, "box")
    if box is not None:
        half = np.asarray(box, dtype=float)
        worst = max(float(v @ Pxx @ v) for v in (np.array(sg) * half
                                                 for sg in itertools.product((-1.0, 1.0), repeat=n)))
        checks.append(Check("saturation_box", bool(worst <= 1 + 1e-6),
                            f"the requested box |x - x0| <= {fmt(half)} inside the ellipsoid (section "
                            f"z = 0): largest v' P v over its corners {worst:.6g} (must be <= 1)",
                            {"value": worst}))
    checks += guard("saturation_nonlinear", lambda: [_saturation_sim(doc, spec, c, Pxx, umax)])
    return checks


def _saturation_sim(doc: Mapping[str, Any], spec: Spec, c: dict, Pxx: np.ndarray,
                    umax: np.ndarray) -> Check:
    plant, n = spec.plant, c["n"]
    w, V = np.linalg.eigh(0.5 * (Pxx + Pxx.T))
    dirs = [s * V[:, i] for i in range(n) for s in (1.0, -1.0)]
    rng = np.random.default_rng([int(option(doc, spec, "seed", 0)), 7])
    dirs += list(rng.standard_normal((24, n)))
    starts = []
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    skipped = 0
    for d in dirs:
        d = d / math.sqrt(float(d @ Pxx @ d))
        x = c["x0"] + d
        if np.all(x >= lo) and np.all(x <= hi) and not plant.region.violations(x, plant.x):
            starts.append(x)
        else:
            skipped += 1
    if not starts:
        return Check("saturation_nonlinear", None, "no boundary point of the ellipsoid lies in the "
                                                   "operating region: not simulated")
    loops = _closed_loops(c, spec, c["models"])
    ts = _sim_period(c, spec, loops)
    H, k_h, steps, rule = _horizon(doc, spec, c, ts)
    law = PeakRecordingLaw(_law(c, ts), c["u0"], umax)
    ref = None
    if c["integral"]:
        y0 = np.asarray(plant.compiled.output(c["x0"][None]), dtype=float).reshape(-1)[c["rows"]]
        ref = np.tile(y0, (steps + 1, 1))
    simulate(plant, ts=ts, steps=steps, x0=np.array(starts), seeds=run_seeds(0, len(starts)),
             controller=law, reference=ref, u_init=c["u0"])
    peak = float(np.max(law.peak)) if law.peak is not None else 0.0
    return Check("saturation_nonlinear", bool(peak <= 1 + SATURATION_TOLERANCE),
                 f"{len(starts)} starts on the ellipsoid's boundary (semi-axes {fmt(1 / np.sqrt(w))} in "
                 f"the states' units, +-each axis and 24 random directions; {skipped} outside the "
                 f"operating region skipped), NOMINAL nonlinear plant, {steps} samples of {ts:.4g} s: "
                 f"largest unclipped |u_j - u0_j| / umax_j = {peak:.4g} (must be <= 1 + "
                 f"{SATURATION_TOLERANCE:g}, the nonlinearity's allowance)",
                 {"peak_ratio": peak, "starts": len(starts), "skipped": skipped})


def robust_state_feedback_verdict(doc: Mapping[str, Any], spec: Spec, *, trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``robust_state_feedback`` artefact (see the module docstring).

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    c = _context(doc, spec, observer=False)
    checks = _vertex_checks(doc, spec, c)
    checks += guard("sampled_region", lambda: _sampled_check(doc, spec, c))
    checks += guard("monte_carlo", lambda: _mc_feedback(doc, spec, c, trace))
    if option(doc, spec, "saturation", False):
        checks += guard("saturation", lambda: _saturation_checks(doc, spec, c))
    return checks


# ================================================================= observer
class _InstanceObserver:
    """Batch observer, each run on its own linear model, one shared gain ``L``.

    ``e_k = Phi_r e_{k-1} + Gamma_r [u_{k-1} - u0_r; y_{k-1} - y0]`` with ``e = x_hat - x0``
    (the predictor form; a continuous design's ``F - L C`` is integrated exactly over each period).
    """

    def __init__(self, Phi: np.ndarray, Gamma: np.ndarray, x0: np.ndarray, u0: np.ndarray,
                 y0: np.ndarray):
        self.Phi, self.Gamma, self.x0, self.u0, self.y0 = Phi, Gamma, x0, u0, y0
        self.e: np.ndarray = np.empty((0, x0.shape[0]))    # set by reset
        self.y_prev: np.ndarray | None = None

    def reset(self, x_hat0: np.ndarray) -> None:
        self.e = np.asarray(x_hat0, dtype=float) - self.x0
        self.y_prev = None

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        if self.y_prev is not None:
            v = np.concatenate([u - self.u0, self.y_prev - self.y0], axis=1)
            self.e = np.einsum("rij,rj->ri", self.Phi, self.e) + np.einsum("rij,rj->ri", self.Gamma, v)
        self.y_prev = np.asarray(y, dtype=float).copy()
        return self.x0 + self.e


def _mc_observer(doc: Mapping[str, Any], spec: Spec, c: dict, trace: TraceRecorder | None = None) -> list[Check]:
    plant = spec.plant
    runs = int(option(doc, spec, "mc_runs", 16))
    seed = int(option(doc, spec, "seed", 0))
    loops = _closed_loops(c, spec, c["models"])
    eigs = np.concatenate([np.linalg.eigvals(M) for M in loops])
    tau, _ = designed_time_constant(doc, spec, eigs, c["domain"], spec.ts)
    ts = observer_period(c["domain"], spec.ts, tau)
    H, k_h, steps, rule = _horizon(doc, spec, c, ts)
    values = box_samples(c["box"], runs, seed + 1) if c["box"] else np.zeros((runs, 0))
    models = _models(spec, c["box"], values, "continuous", "identity")
    L = c["L"]
    Phi, Gam, inputs = [], [], []
    for mdl in models:
        if c["domain"] == "discrete":
            Ad, Bd = discretize_zoh(mdl["F"], mdl["Bc"], ts)
            Phi.append(Ad - L @ mdl["C"])
            Gam.append(np.hstack([Bd, L]))
        else:
            Ph, G = discretize_zoh(mdl["F"] - L @ mdl["C"], np.hstack([mdl["Bc"], L]), ts)
            Phi.append(Ph)
            Gam.append(G)
        inputs.append(mdl["u0"])
    U0 = np.array(inputs)
    y0 = np.asarray(plant.compiled.output(c["x0"][None]), dtype=float).reshape(-1)
    est = _InstanceObserver(np.array(Phi), np.array(Gam), c["x0"], U0, y0)
    x_start, frac = perturbed_start(plant, c["x0"])
    params = {b[0]: values[:, j] for j, b in enumerate(c["box"])}
    res = simulate(plant, ts=ts, steps=steps, x0=x_start, seeds=run_seeds(seed, runs), estimator=est,
                   x_hat0=c["x0"], u_init=U0, parameters=params)
    record_monte_carlo(trace, res, plant, observer=True)
    err = np.max(np.abs(res.x_hat - res.x), axis=2)
    e0 = err[:, 0]
    tail = np.max(err[:, k_h:], axis=1)
    ratio = tail / np.maximum(e0, 1e-300)
    ok = np.isfinite(ratio) & (ratio <= OBSERVER_TOLERANCE)
    w = int(np.argmax(np.where(np.isfinite(ratio), ratio, np.inf)))
    worst = {b[0]: float(values[w, j]) for j, b in enumerate(c["box"])}
    return [Check("monte_carlo", bool(np.all(ok)),
                  f"{runs} plants with parameters drawn uniformly in the box (seed {seed + 1}), NONLINEAR "
                  f"model from x0 + delta ({100 * frac:g} % of the region span) holding its own "
                  f"equilibrium input, the observer on that plant's linearisation with the ONE stored L "
                  f"(estimate from x0), sampled every {ts:.4g} s: {int(np.sum(~ok))} run(s) with |e|_inf "
                  f"above {100 * OBSERVER_TOLERANCE:g} % of |e(0)| on [H, 1.2 H]; worst run {w} "
                  f"({_label(worst)}): {ratio[w]:.3g}; rule H = tau (5 + ln kappa) = {H:.4g} s, {rule}",
                  {"failed_runs": int(np.sum(~ok)), "ratios": ratio.tolist(), "worst_parameters": worst,
                   "horizon_s": H, "ts": ts})]


def robust_observer_verdict(doc: Mapping[str, Any], spec: Spec, *, trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``robust_observer`` artefact (see the module docstring).

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    c = _context(doc, spec, observer=True)
    checks = _vertex_checks(doc, spec, c)
    checks += guard("sampled_region", lambda: _sampled_check(doc, spec, c))
    checks += guard("monte_carlo", lambda: _mc_observer(doc, spec, c, trace))
    return checks
