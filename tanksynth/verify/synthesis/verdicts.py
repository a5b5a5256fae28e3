"""Verdicts of ``h2_state_feedback``, ``h2_observer``, ``hinf_state_feedback``, ``hinf_observer``
and ``multiobjective``, with the verdicts' own norm numerics.

Re-derived from the artefact (its gains) and the spec, never from the design code:

``model_recheck`` / ``synthesis_data``
    stored model (``F``, ``B``, ``C``; discrete time ``Ad``, ``Bd``, ``C``)
    against the linearisation; stored ``Bw`` (discrete time ``Bwd``) against
    the spec's ``Bw diag(disturbance_std)`` (ZOH at ``ts`` in discrete time,
    recomputed here), stored ``Cz``, ``Dzu`` / ``Dv`` against the options.
``stability`` / ``region`` / ``lmi_recheck``
    eigenvalues of ``A - B K`` (``A - L C``); multi-objective: inside the spec's
    region, and the region LMI with the stored ``X``.
``h2_norm`` / ``hinf_norm``
    the closed loop's (error system's) H2 norm from the Gramian and H-infinity
    norm by bisection on the Hamiltonian test (discrete time: bilinear map),
    against the bound the artefact claims (``<= bound (1 + 1e-6)``) and the
    norm it reports as achieved (agreement within `NORM_TOLERANCE`).
``h2_optimality`` (H2 methods)
    the recomputed H2 norm against the Riccati optimum (scipy ARE, LQR or
    Kalman predictor) within `OPTIMALITY_TOLERANCE`.
``regulation`` / ``observer_convergence``
    from an initial perturbation on the nonlinear plant (`tanksynth.verify.simulations`).
``disturbance_step``
    the nonlinear plant with the declared disturbances as extra inputs (``dx/dt
    = f(x, u) + Bw w``): a step of ``w`` (sized so the linear steady offset is
    2 % of the region span) on, then off. State feedback: the state settles
    within 25 % of the linear prediction of the offset and returns to ``x0``
    (5 %); observers (the plant under ``u0``): the estimation error settles at
    the linear observer's fixed point for the plant's settled state (within 5 %
    of the plant's offset; the linear prediction of the bias is reported) and
    returns to zero (5 %).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Mapping

import numpy as np
import scipy.linalg as sla
import sympy as sp

from tanksynth.analysis.checks import Check
from tanksynth.analysis.linearize import linearize
from tanksynth.analysis.lmi_region import region_from_parts
from tanksynth.analysis.rank import controllability_rank, observability_rank
from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant, Quantity
from tanksynth.sim.simulate import InputSequence, run_seeds, simulate
from tanksynth.spec import Spec
from tanksynth.spec.options import parse_region
from tanksynth.verify.common import (MAX_STEPS, artefact_matrix, discrete_ts, fmt, guard,
                                     model_recheck, operating_point, option, rank_check, region_check,
                                     region_lmi_check, relative_difference, stability_check,
                                     time_domain)
from tanksynth.verify.simulations import (eigenvector_conditioning, luenberger_estimator,
                                          observer_convergence, observer_period, regulation_check,
                                          slowest_time_constant)
from tanksynth.verify.traces import TraceRecorder

__all__ = ["NORM_TOLERANCE", "OPTIMALITY_TOLERANCE", "OFFSET_TOLERANCE", "h2_norm", "hinf_norm",
           "synthesis_verdict", "disturbance_plant"]

#: Relative agreement of recomputed norms with the artefact's claims.
NORM_TOLERANCE = 1e-6
#: Relative distance of an H2 design to the Riccati optimum.
OPTIMALITY_TOLERANCE = 1e-5
#: Steady offset under the disturbance step vs the linear prediction (fraction of it).
OFFSET_TOLERANCE = 0.25


# ================================================================== own norm numerics
def h2_norm(A: np.ndarray, B: np.ndarray, C: np.ndarray, dt: float | None) -> float:
    """H2 norm of ``(A, B, C, 0)`` from the controllability Gramian; inf if not stable.

    Parameters
    ----------
    A, B, C : ndarray
        State, disturbance-input and performance-output matrices.
    dt : float or None
        Sampling period [s]; None: continuous time.
    """
    A, B, C = (np.asarray(M, float) for M in (A, B, C))
    lam = np.linalg.eigvals(A)
    if (dt is None and np.max(lam.real) >= 0) or (dt is not None and np.max(np.abs(lam)) >= 1):
        return math.inf
    if dt is None:
        G = sla.solve_continuous_lyapunov(A, -B @ B.T)
    else:
        G = sla.solve_discrete_lyapunov(A, B @ B.T)
    return float(math.sqrt(max(float(np.trace(C @ G @ C.T)), 0.0)))


def _hamiltonian_crosses(A, B, C, D, g: float) -> bool:
    """True if some frequency has sigma_max(G(jw)) >= g (Hamiltonian eigenvalue on the axis)."""
    R = g * g * np.eye(B.shape[1]) - D.T @ D
    if np.linalg.eigvalsh(R)[0] <= 0:
        return True
    S = g * g * np.eye(C.shape[0]) - D @ D.T
    Ri, Si = np.linalg.inv(R), np.linalg.inv(S)
    H11 = A + B @ Ri @ D.T @ C
    H = np.block([[H11, g * B @ Ri @ B.T], [-g * C.T @ Si @ C, -H11.T]])
    lam = np.linalg.eigvals(H)
    return bool(np.any(np.abs(lam.real) < 1e-9 * np.maximum(np.abs(lam), 1.0)))


def hinf_norm(A: np.ndarray, B: np.ndarray, C: np.ndarray, dt: float | None,
              rtol: float = 1e-9) -> tuple[float, float]:
    """H-infinity norm of ``(A, B, C, 0)``: bracket ``(lower, upper)`` by Hamiltonian bisection.

    Discrete time goes through ``z = (1 + s) / (1 - s)`` (same norm). Returns
    ``(inf, inf)`` for an unstable system.

    Parameters
    ----------
    A, B, C : ndarray
        State, disturbance-input and performance-output matrices.
    dt : float or None
        Sampling period [s]; None: continuous time.
    rtol : float, optional
        Relative width of the bracket (dimensionless).
    """
    A, B, C = (np.asarray(M, float) for M in (A, B, C))
    n = A.shape[0]
    D = np.zeros((C.shape[0], B.shape[1]))
    lam = np.linalg.eigvals(A)
    if dt is None:
        if np.max(lam.real) >= 0:
            return math.inf, math.inf
    else:
        if np.max(np.abs(lam)) >= 1:
            return math.inf, math.inf
        E = np.linalg.inv(A + np.eye(n))
        A, B, C, D = E @ (A - np.eye(n)), math.sqrt(2) * E @ B, math.sqrt(2) * C @ E, D - C @ E @ B
    # lower bound: the gain at a few frequencies (0 and the eigenvalue magnitudes)
    freqs = np.concatenate([[0.0], np.abs(np.linalg.eigvals(A))])
    lower = max(float(np.linalg.norm(C @ np.linalg.solve(1j * w * np.eye(A.shape[0]) - A, B) + D, 2))
                for w in freqs)
    if lower == 0.0:
        return 0.0, 0.0
    upper = 2.0 * lower
    while _hamiltonian_crosses(A, B, C, D, upper):
        lower, upper = upper, 2.0 * upper
    for _ in range(200):
        if upper - lower <= rtol * upper:
            break
        mid = 0.5 * (lower + upper)
        if _hamiltonian_crosses(A, B, C, D, mid):
            lower = mid
        else:
            upper = mid
    return float(lower), float(upper)


def _zoh(F: np.ndarray, G: np.ndarray, ts: float) -> np.ndarray:
    n, k = G.shape
    M = np.zeros((n + k, n + k))
    M[:n, :n], M[:n, n:] = F, G
    return sla.expm(M * ts)[:n, n:]


def _riccati_h2(c: dict) -> float:
    """The H2 optimum of the same data by the algebraic Riccati equation (scipy)."""
    A, B, C, Bw, Cz, dt = c["A"], c["B"], c["C"], c["Bw"], c["Cz"], c["dt"]
    if c["observer"]:
        Qn, Rn = Bw @ Bw.T, c["Dv"] @ c["Dv"].T
        S = (sla.solve_discrete_are(A.T, C.T, Qn, Rn) if dt is not None
             else sla.solve_continuous_are(A.T, C.T, Qn, Rn))
        return float(math.sqrt(max(float(np.trace(Cz @ S @ Cz.T)), 0.0)))
    Dzu = c["Dzu"]
    Q, R, N = Cz.T @ Cz, Dzu.T @ Dzu, Cz.T @ Dzu
    P = (sla.solve_discrete_are(A, B, Q, R, s=N) if dt is not None
         else sla.solve_continuous_are(A, B, Q, R, s=N))
    return float(math.sqrt(max(float(np.trace(Bw.T @ P @ Bw)), 0.0)))


# ============================================================================ reading
def _read(doc: Mapping[str, Any], spec: Spec) -> dict:
    plant = spec.plant
    n, m, q = plant.n, plant.m, plant.q
    domain = time_domain(doc, spec)
    dt = discrete_ts(spec) if domain == "discrete" else None
    gains = doc["gains"]
    A = artefact_matrix(doc, "A", (n, n), domain)
    B = artefact_matrix(doc, "B", (n, m), domain)
    C = artefact_matrix(doc, "C", (q, n))
    Bw = artefact_matrix(doc, "Bw", None, domain)
    Bw = Bw.reshape(n, -1) if Bw.size % n == 0 else Bw
    Cz = np.atleast_2d(np.asarray(gains["Cz"], float)) if "Cz" in gains else None
    x0, u0 = operating_point(spec)
    out: dict[str, Any] = dict(plant=plant, domain=domain, dt=dt, A=A, B=B, C=C, Bw=Bw, Cz=Cz, x0=x0, u0=u0,
               observer="L" in gains)
    if out["observer"]:
        L = artefact_matrix(doc, "L", (n, q))
        Dv = artefact_matrix(doc, "Dv", (q, q))
        out.update(L=L, Dv=Dv, Acl=A - L @ C, Bcl=np.hstack([Bw, -L @ Dv]), Ccl=Cz,
                   what="the observer error matrix A - L C")
    else:
        if Cz is None:
            raise ArtefactError(f"artefact '{doc['name']}' ({doc['method']}) has no gain 'Cz'")
        K = artefact_matrix(doc, "K", (m, n))
        Dzu = artefact_matrix(doc, "Dzu", (Cz.shape[0], m))
        out.update(K=K, Dzu=Dzu, Acl=A - B @ K, Bcl=Bw, Ccl=Cz - Dzu @ K,
                   what="the closed loop A - B K")
    out["eigs"] = np.linalg.eigvals(out["Acl"])
    return out


def _data_check(doc: Mapping[str, Any], spec: Spec, c: dict) -> Check:
    """Stored Bw, Cz, Dzu / Dv against the spec's options (validated values)."""
    Bw_c = np.asarray(option(doc, spec, "Bw"), float)
    std = np.asarray(option(doc, spec, "disturbance_std"), float)
    want = {"Bw": Bw_c * std[None, :]}
    if c["dt"] is not None:
        want["Bw"] = _zoh(_continuous_F(c), want["Bw"], c["dt"])
    want["Cz"] = np.asarray(option(doc, spec, "Cz"), float)
    if c["observer"]:
        want["Dv"] = np.diag(np.asarray(option(doc, spec, "measurement_std"), float))
        have = {"Bw": c["Bw"], "Cz": c["Cz"], "Dv": c["Dv"]}
    else:
        want["Dzu"] = np.asarray(option(doc, spec, "Dzu"), float)
        have = {"Bw": c["Bw"], "Cz": c["Cz"], "Dzu": c["Dzu"]}
    diffs = {k: (math.inf if have[k].shape != want[k].shape else relative_difference(have[k], want[k]))
             for k in want}
    worst = max(diffs.values())
    return Check("synthesis_data", bool(worst <= 1e-9),
                 f"stored {', '.join(have)} against the spec's options (Bw diag(disturbance_std)"
                 f"{', ZOH at ts' if c['dt'] is not None else ''}): largest relative difference "
                 f"{worst:.3g} (tolerance 1e-9)", {"relative_differences": diffs})


def _continuous_F(c: dict) -> np.ndarray:
    return linearize(c["plant"], c["x0"], c["u0"]).F


# ============================================================================ checks
def _claims(doc: Mapping[str, Any]) -> Mapping[str, Any]:
    diag = doc.get("diagnostics") or {}
    syn = diag.get("synthesis") if isinstance(diag, Mapping) else None
    return syn if isinstance(syn, Mapping) else {}


def _number(value: Any) -> float | None:
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def _first(value: Any) -> float | None:
    if isinstance(value, (list, tuple)) and value:
        return _number(value[0])
    return _number(value)


def _norm_checks(doc: Mapping[str, Any], c: dict) -> list[Check]:
    claims = _claims(doc)
    dt = c["dt"]
    h2 = h2_norm(c["Acl"], c["Bcl"], c["Ccl"], dt)
    lo, hi = hinf_norm(c["Acl"], c["Bcl"], c["Ccl"], dt)
    system = ("the error system (A - L C, [Bw, -L Dv], Cz)" if c["observer"]
              else "the closed loop (A - B K, Bw, Cz - Dzu K)")
    checks = []
    for name, value, bound, achieved, unit in (
            ("h2_norm", h2, _number(claims.get("h2_bound")), _first(claims.get("achieved_h2")),
             "Gramian"),
            ("hinf_norm", hi, _number(claims.get("gamma")), _first(claims.get("achieved_hinf")),
             f"Hamiltonian bisection, bracket [{lo:.10g}, {hi:.10g}]")):
        parts, ok = [], True
        if bound is not None:
            holds = bool(value <= bound * (1 + NORM_TOLERANCE))
            ok &= holds
            parts.append(f"claimed bound {bound:.8g} ({'holds' if holds else 'VIOLATED'}, tolerance "
                         f"{NORM_TOLERANCE:g} relative)")
        if achieved is not None:
            rel = abs(value - achieved) / max(abs(achieved), 1e-300)
            ok &= bool(rel <= NORM_TOLERANCE * 10)
            parts.append(f"reported achieved {achieved:.8g} (relative difference {rel:.2g}, "
                         f"tolerance {10 * NORM_TOLERANCE:g})")
        if not parts:
            if name == "h2_norm" and c["method"] in ("h2_state_feedback", "h2_observer"):
                checks.append(Check(name, False, "the artefact claims no H2 norm"))
            continue
        checks.append(Check(name, bool(ok and math.isfinite(value)),
                            f"{'H2' if name == 'h2_norm' else 'H-infinity'} norm of {system} "
                            f"recomputed ({unit}): {value:.8g}; " + "; ".join(parts),
                            {"value": value, "bound": bound, "achieved_reported": achieved}))
    if c["method"] in ("h2_state_feedback", "h2_observer"):
        opt = _riccati_h2(c)
        rel = (h2 - opt) / max(opt, 1e-300)
        checks.append(Check("h2_optimality", bool(abs(rel) <= OPTIMALITY_TOLERANCE),
                            f"recomputed H2 norm {h2:.10g} against the Riccati optimum {opt:.10g} "
                            f"({'Kalman predictor' if c['observer'] else 'LQR'} by scipy's ARE on the "
                            f"stored data): relative difference {rel:.3g} (tolerance "
                            f"{OPTIMALITY_TOLERANCE:g})", {"riccati": opt, "relative": rel}))
    return checks


def _region_checks(doc: Mapping[str, Any], spec: Spec, c: dict) -> list[Check]:
    raw = option(doc, spec, "region")
    if raw is None:
        return [Check("region", None, "the spec entry of this artefact gives no region")]
    region = region_from_parts(parse_region(raw, "region") if not isinstance(raw, tuple) else raw)
    n = c["plant"].n
    X = artefact_matrix(doc, "X", (n, n))
    Acl = c["Acl"].T if c["observer"] else c["Acl"]
    return [region_check(c["eigs"], region, c["what"]),
            region_lmi_check(region, Acl, X, ("(A - L C)'" if c["observer"] else "A - B K")
                             + " with the stored X")]


# ======================================================================= simulations
def disturbance_plant(plant: Plant, Bw: np.ndarray) -> Any:
    """The plant with the disturbances as extra (unbounded) inputs: ``f(x, u) + Bw w``.

    Parameters
    ----------
    plant : Plant
    Bw : ndarray, shape (n, nw)
        Continuous-time disturbance input (state unit per s per disturbance unit).
    """
    Bw = np.asarray(Bw, float)
    names = {s.name for s in plant.states} | {s.name for s in plant.inputs} | set(plant.p)
    tags = []
    for j in range(Bw.shape[1]):
        tag = f"w{j + 1}"
        while tag in names:
            tag = "_" + tag
        tags.append(tag)
    w = sp.Matrix([sp.Symbol(t, real=True) for t in tags])
    # each entry as the exact rational value of its double: every route computes with the stored
    # Bw bit for bit (nsimplify took 0.2 s a design and rounded to a nearby 'nice' rational)
    f = plant.f + sp.Matrix([[sp.Rational(float(v)) for v in row] for row in Bw]) * w
    bounds = tuple(plant.input_bounds) + ((-math.inf, math.inf),) * len(tags) if plant.input_bounds else ()
    return replace(plant, inputs=tuple(plant.inputs) + tuple(Quantity(t, "w", "declared disturbance")
                                                           for t in tags),
                   f=f, input_bounds=bounds, name=plant.name)


class _StepLaw:
    """``[u(x), w(t)]``: the control law (or ``u0``) and a disturbance step on ``[t_on, t_off)``."""

    def __init__(self, K, x0, u0, w, t_on, t_off):
        self.K, self.x0, self.u0, self.w, self.t_on, self.t_off = K, x0, u0, w, t_on, t_off

    def __call__(self, x_hat, reference, t):
        M = x_hat.shape[0]
        u = np.tile(self.u0, (M, 1)) if self.K is None else self.u0 - (x_hat - self.x0) @ self.K.T
        w = self.w if self.t_on <= t + 1e-12 < self.t_off else np.zeros_like(self.w)
        return np.hstack([u, np.tile(w, (M, 1))])

    def affine(self, steps: int, ts: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The law as ``[u, w]_k = b_k - [K; 0] (x_k - x0)`` (`tanksynth.sim.affine`; ``K = 0``
        without a gain).

        Parameters
        ----------
        steps : int
            Number of periods N.
        ts : float
            Sampling period (s): the step is on over ``[t_on, t_off)``.
        """
        m = len(self.u0)
        n = len(self.x0)
        t = np.arange(int(steps)) * float(ts)          # t_k = k ts, as the simulator's samples
        on = (self.t_on <= t + 1e-12) & (t + 1e-12 < self.t_off)
        b = np.zeros((int(steps), m + len(self.w)))
        b[:, :m] = self.u0
        b[on, m:] = self.w
        K = np.zeros((m + len(self.w), n))
        if self.K is not None:
            K[:m] = self.K
        return b, K, np.asarray(self.x0, dtype=float)


class _SliceInput:
    """An estimator that sees only the first ``m`` inputs (the controls)."""

    def __init__(self, est, m):
        self.est, self.m = est, m

    def reset(self, x_hat0):
        self.est.reset(x_hat0)

    def step(self, y, u):
        return self.est.step(y, u[:, : self.m])

    def run(self, Y, U):
        return self.est.run(Y, U[..., : self.m])


def _disturbance_step(doc: Mapping[str, Any], spec: Spec, c: dict,
                      trace: TraceRecorder | None) -> Check:
    plant, dt, x0, u0 = c["plant"], c["dt"], c["x0"], c["u0"]
    n = plant.n
    Bw_c = np.asarray(option(doc, spec, "Bw"), float) * np.asarray(option(doc, spec, "disturbance_std"),
                                                                 float)[None, :]
    I = np.eye(n)
    # linear static gains from w (unit, normalised) to the offset
    if c["observer"]:
        F = _continuous_F(c)
        plant_gain = -np.linalg.solve(F, Bw_c)
        err_gain = (np.linalg.solve(I - c["Acl"], c["Bw"]) if dt is not None
                    else -np.linalg.solve(c["Acl"], c["Bw"]))
        base = plant_gain
    else:
        base = (np.linalg.solve(I - c["Acl"], c["Bw"]) if dt is not None
                else -np.linalg.solve(c["Acl"], c["Bw"]))
    lo_b = np.array([b[0] for b in plant.region.bounds], float)
    hi_b = np.array([b[1] for b in plant.region.bounds], float)
    span = np.where(np.isfinite(hi_b - lo_b) & (hi_b > lo_b), hi_b - lo_b, 1.0)
    direction = np.ones(Bw_c.shape[1])
    dx1 = base @ direction
    a = 0.02 / max(float(np.max(np.abs(dx1) / span)), 1e-300)
    if not c["observer"]:
        du = -c["K"] @ (a * dx1)
        lim = plant.input_limits
        head = np.where(du > 0, lim[:, 1] - u0, u0 - lim[:, 0])
        ratio = np.max(np.abs(du) / np.maximum(head, 1e-300))
        if ratio > 0.5:
            a *= 0.5 / ratio
    w = a * direction
    x_ss = a * dx1
    # horizon from the slowest of the designed loop (and the plant's own response for observers)
    tau = slowest_time_constant(c["eigs"], c["domain"], dt)
    if c["observer"]:
        tau = max(tau, slowest_time_constant(np.linalg.eigvals(_continuous_F(c)), "continuous", None))
    if not math.isfinite(tau):
        return Check("disturbance_step", False, "the designed loop is not stable")
    kappa = min(max(eigenvector_conditioning(c["Acl"]), 1.0), 1e8)
    ts_sim = dt if dt is not None else observer_period("continuous", spec.ts, tau if not c["observer"]
                                                       else slowest_time_constant(c["eigs"], "continuous",
                                                                                  None))
    phase = max(int(math.ceil(tau * (5 + math.log(kappa)) / ts_sim)), 10)
    steps = 2 * phase
    if steps > MAX_STEPS:
        return Check("disturbance_step", None, f"not simulated: {steps} samples needed (> {MAX_STEPS})")
    dplant = disturbance_plant(plant, Bw_c)
    step_law = _StepLaw(None if c["observer"] else c["K"], x0, u0, w, 0.0, phase * ts_sim)
    law: _StepLaw | InputSequence = step_law
    est = None
    if c["observer"]:
        form = "predictor" if dt is not None else "continuous"
        est = _SliceInput(luenberger_estimator(plant, c["L"], x0, u0, ts_sim, form), plant.m)
        # the inputs do not depend on the estimate: the same law's values, given in advance (the
        # plant is then integrated over the whole horizon in one call)
        law = InputSequence(step_law.affine(steps, ts_sim)[0])     # K = 0: b_k are the inputs
    res = simulate(dplant, ts=ts_sim, steps=steps, x0=x0, seeds=run_seeds(0, 1), controller=law,
                   estimator=est, u_init=np.concatenate([u0, np.zeros_like(w)]))
    if trace is not None:
        trace.record(res, dplant, check="disturbance_step", estimator=c["observer"],
                     disturbances=[q.name for q in dplant.inputs[plant.m:]],
                     scenario=f"declared disturbances stepped to {fmt(w)} at t = 0, removed at "
                              f"t = {phase * ts_sim:g} s")
    win = max(phase // 10, 1)
    X = res.x[0]
    if c["observer"]:
        e = res.x_hat[0] - X
        # the linear observer's fixed point for the plant's settled state x_f (exact, no linearisation)
        dxf = np.mean(X[phase - win:phase + 1], axis=0) - x0
        LC = c["L"] @ c["C"]
        shift = (np.linalg.solve(I - c["Acl"], LC @ dxf) if dt is not None
                 else -np.linalg.solve(c["Acl"], LC @ dxf))
        bias = shift - dxf
        lin_bias = -a * (err_gain @ direction)   # e = x_hat - x: w drives the plant, not the observer
        tol_on = 0.05 * float(np.max(np.abs(dxf)))
        on = float(np.max(np.abs(e[phase - win:phase + 1] - bias)))
        off = float(np.max(np.abs(e[-win:])))
        tol_off = 0.05 * float(np.max(np.abs(x_ss)))
        what = (f"the plant settles at x_op + {fmt(dxf)} (linear prediction {fmt(x_ss)}); the estimation "
                f"error settles at the observer's fixed point for that state, bias {fmt(bias)} (linear "
                f"prediction {fmt(lin_bias)}): largest deviation over the last {win} samples {on:.3g} "
                f"(tolerance {tol_on:.3g} = 5 % of the plant's offset); after the step, |e|_inf = "
                f"{off:.3g} (tolerance {tol_off:.3g})")
    else:
        on = float(np.max(np.abs(X[phase - win:phase + 1] - (x0 + x_ss))))
        tol_on = OFFSET_TOLERANCE * float(np.max(np.abs(x_ss)))
        off = float(np.max(np.abs(X[-win:] - x0)))
        tol_off = 0.05 * float(np.max(np.abs(x_ss)))
        what = (f"state settles at x_op + {fmt(x_ss)} predicted by the linear closed loop (largest "
                f"deviation over the last {win} samples {on:.3g}, tolerance {tol_on:.3g} = "
                f"{100 * OFFSET_TOLERANCE:g} %); after the step, |x - x0|_inf = {off:.3g} (tolerance "
                f"{tol_off:.3g})")
    ok = bool(np.all(np.isfinite(X)) and on <= tol_on and off <= tol_off)
    return Check("disturbance_step", ok,
                 f"nonlinear plant with the declared disturbances as inputs (dx/dt = f(x, u) + Bw w), "
                 f"w stepped to {fmt(w)} (normalised units; linear offset 2 % of the region span) for "
                 f"{phase * ts_sim:.4g} s then removed, sampled every {ts_sim:.4g} s (phase = tau (5 + ln "
                 f"kappa), tau = {tau:.4g} s, kappa = {kappa:.3g}): " + what,
                 {"w": w.tolist(), "offset_error": on, "offset_tolerance": tol_on, "return_error": off,
                  "return_tolerance": tol_off, "ts": ts_sim, "phase_samples": phase})


def _simulations(doc: Mapping[str, Any], spec: Spec, c: dict, trace: TraceRecorder | None) -> list[Check]:
    plant, dt, x0, u0 = c["plant"], c["dt"], c["x0"], c["u0"]
    tau = slowest_time_constant(c["eigs"], c["domain"], dt)
    kappa = eigenvector_conditioning(c["Acl"])
    rule = "(slowest eigenvalue of the stored gain's matrix)"
    if c["observer"]:
        ts_sim = observer_period(c["domain"], spec.ts, tau)
        form = "predictor" if dt is not None else "continuous"
        est = luenberger_estimator(plant, c["L"], x0, u0, ts_sim, form)
        first = observer_convergence(plant, est, x0, u0, tau, ts_sim, conditioning=kappa,
                                     rule=f"{rule}; Luenberger observer, {form} form", trace=trace)
    else:
        if dt is not None:
            ts_sim = dt
        else:
            fast = float(np.max(np.abs(c["eigs"])))
            ts_sim = min(0.05 / fast if fast > 0 else tau / 20, spec.ts or math.inf)
        first = regulation_check(plant, c["K"], x0, u0, tau, ts_sim, kappa, rule=rule, trace=trace)
    return [first] + guard("disturbance_step", lambda: [_disturbance_step(doc, spec, c, trace)])


def synthesis_verdict(doc: Mapping[str, Any], spec: Spec, *,
                      trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of an H2 / H-infinity / multi-objective artefact (controller or observer).

    Checks: ``model_recheck``, ``synthesis_data``, ``stability``, ``rank_*``,
    ``h2_norm`` / ``hinf_norm`` (recomputed here vs the claims),
    ``h2_optimality`` (H2 methods), ``region`` + ``lmi_recheck``
    (multi-objective), then ``regulation`` or ``observer_convergence`` and
    ``disturbance_step`` on the nonlinear plant.

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
        The validated spec.
    trace : TraceRecorder, optional
        Records the simulated runs when given.
    """
    c = _read(doc, spec)
    c["method"] = doc["method"]
    checks = [model_recheck(c["plant"], c["x0"], c["u0"], c["domain"], c["dt"],
                            {"A": c["A"], "B": c["B"], "C": c["C"]})]
    checks += guard("synthesis_data", lambda: [_data_check(doc, spec, c)])
    checks.append(stability_check(c["eigs"], c["domain"], c["what"]))
    if c["observer"]:
        checks.append(rank_check("rank_observability", observability_rank(c["A"], c["C"]), "(A, C)"))
    else:
        checks.append(rank_check("rank_controllability", controllability_rank(c["A"], c["B"]),
                                 "(A, B)"))
    checks += guard("norms", lambda: _norm_checks(doc, c))
    if doc["method"] == "multiobjective":
        checks += guard("region", lambda: _region_checks(doc, spec, c))
    checks += guard("simulation", lambda: _simulations(doc, spec, c, trace))
    return checks
