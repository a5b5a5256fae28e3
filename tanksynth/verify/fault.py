"""Verdict of ``fault_detection`` (residual threshold and detection times)."""


import math
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.analysis.checks import Check
from tanksynth.sim.simulate import run_seeds, simulate
from tanksynth.verify.common import artefact_gain


from tanksynth.verify.common import MAX_STEPS, _fmt, _guard, _matrix, _option, _rel

__all__ = ["FAULT_TS", "FAULT_HORIZON", "FAULT_TIME_TOLERANCE", "FAULT_SLACK", "fault_detection_verdict"]

# ==================================================================== fault detection
#: Sampling period of the fault-detection simulations (s), at most (the spec's ts if finer).
FAULT_TS = 1e-3
#: Search horizon after the fault onset (s), as in `tanksynth.design.fault.detection_time`.
FAULT_HORIZON = 3.0
#: Largest difference between a simulated detection time and the stored one (s).
FAULT_TIME_TOLERANCE = 2e-3
#: Healthy residual allowed above the threshold, as a fraction of the threshold after the transient.
FAULT_SLACK = 1e-6


class _ResidualObserver:
    """Continuous Luenberger observer of the healthy model, as a `BatchEstimator`.

    ``dx_hat/dt = f(x_hat, u) + Psi (y - h(x_hat))`` with the healthy
    parameters, integrated by RK4 between samples with ``y`` interpolated
    linearly between the measured samples; records the residual
    ``y_k - h(x_hat_k)`` of every sample.
    """

    def __init__(self, plant: Any, Psi: np.ndarray, ts: float, substeps: int = 4):
        from tanksynth.sim.simulate import _param_arrays, numpy_model

        healthy = {"delta_bar": 0.0} if "delta_bar" in {p.name for p in plant.parameters} else None
        self.model = numpy_model(plant)
        self.params = _param_arrays(plant, healthy, 1)
        self.Psi = np.asarray(Psi, dtype=float)
        self.ts = float(ts)
        self.substeps = int(substeps)
        self.residuals: list[np.ndarray] = []

    def reset(self, x_hat0: np.ndarray) -> None:
        self._x = np.asarray(x_hat0, dtype=float).copy()
        self._y: np.ndarray | None = None
        self.residuals = []

    def _rhs(self, x: np.ndarray, u: np.ndarray, y: np.ndarray) -> np.ndarray:
        yh = np.asarray(self.model.output(x, self.params), dtype=float).reshape(x.shape[0], -1)
        return self.model.rhs(x, u, self.params) + (y - yh) @ self.Psi.T

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        y = np.asarray(y, dtype=float)
        if self._y is not None:
            h = self.ts / self.substeps
            y0, dy = self._y, (y - self._y) / self.ts
            x = self._x
            for j in range(self.substeps):
                t = j * h
                k1 = self._rhs(x, u, y0 + dy * t)
                k2 = self._rhs(x + 0.5 * h * k1, u, y0 + dy * (t + 0.5 * h))
                k3 = self._rhs(x + 0.5 * h * k2, u, y0 + dy * (t + 0.5 * h))
                k4 = self._rhs(x + h * k3, u, y0 + dy * (t + h))
                x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            self._x = x
        self._y = y
        yh = np.asarray(self.model.output(self._x, self.params), dtype=float).reshape(y.shape)
        self.residuals.append(y - yh)
        return self._x


class _Schedule:
    """Open-loop input: piecewise constant ``(t_start, u)``."""

    def __init__(self, pieces: Sequence[tuple[float, float]], m: int):
        self.pieces = [(float(t), float(v)) for t, v in pieces]
        self.m = m

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        v = [val for start, val in self.pieces if start <= t + 1e-12][-1]
        return np.full((x_hat.shape[0], self.m), v)


def fault_detection_verdict(doc: Mapping[str, Any], spec: Any) -> list[Check]:
    """Verdict of a ``fault_detection`` artefact (seed 004 section II-F).

    Nothing is re-derived symbolically. ``threshold_recheck``: the stored
    ``Gamma_d`` equals ``A - Psi C`` (``A, C`` the Jacobians of the healthy
    plant, ``Psi`` the stored gain), and the stored threshold rates and
    coefficients equal, in floating point, the eigenvalues of ``A - Psi C``
    and ``C V diag(V^-1 e_hat)`` (``e_hat = (hi - lo) 1`` from the spec's
    bounds); relative tolerance 1e-6. Then the plant is simulated
    (``simulate``, sampling ``min(ts, 1 ms)``, 4 RK4 substeps) from seed
    004's three initial states (inside the bounds) under seed 004's input
    (2 on [0, 1 s), then 1), with the observer (stored ``Psi``) started at
    ``lo``: ``no_false_alarm`` -- the healthy plant's residual stays at or
    below the stored threshold on ``[0.02 t_f, t_f + horizon]``, up to
    `FAULT_SLACK` times the threshold at ``0.02 t_f`` (integration error; the
    first 2 % of ``t_f`` is the initial transient, where the threshold equals
    the largest possible residual), and so does the faulty plant's before
    ``t_f``; ``fault_detected`` -- with the declared
    ``delta_bar`` from ``t_f``, the residual exceeds the threshold at some
    ``t_d`` in ``(t_f, t_f + horizon]`` for every start (``horizon`` =
    `FAULT_HORIZON`), and, where the artefact stores detection times,
    ``|t_d - stored| <= FAULT_TIME_TOLERANCE``.
    """
    from tanksynth.design.fault import SEED004_INITIAL_STATES, SEED004_INPUT
    from tanksynth.analysis.linearize import linearize
    from tanksynth.sim.simulate import ParameterChange

    plant = spec.plant
    n, m = plant.n, plant.m
    Psi = _matrix(doc, "Psi", (n, 1))
    Gd = _matrix(doc, "Gamma_d", (n, n))
    coef = np.asarray(artefact_gain(doc, "threshold_coefficients"), dtype=float).reshape(-1)
    rates = np.asarray(artefact_gain(doc, "threshold_rates"), dtype=float).reshape(-1)
    if coef.size != rates.size or coef.size == 0:
        raise ArtefactError(f"artefact '{doc['name']}': threshold has {coef.size} coefficients and "
                            f"{rates.size} rates")
    bounds = [float(b) for b in _option(doc, spec, "bounds", [0.25, 4.0])]
    lo, hi = bounds
    delta_bar = float(_option(doc, spec, "delta_bar", 1.0))
    t_f = float(_option(doc, spec, "t_fault", 2.0))
    conservative = bool(_option(doc, spec, "conservative", True))
    params = {"delta_bar": 0.0} if "delta_bar" in {p.name for p in plant.parameters} else {}
    healthy = plant.with_parameters(params) if params else plant
    x_op = np.asarray(spec.x0, dtype=float)
    u_op = np.asarray(spec.given_u0 if spec.given_u0 is not None else np.zeros(m), dtype=float)
    lin = linearize(healthy, x_op, u_op)
    A, C = np.asarray(lin.F, float), np.asarray(lin.C, float)
    checks: list[Check] = []

    def recheck() -> list[Check]:
        G = A - Psi @ C
        dg = _rel(Gd, G)
        lam, V = np.linalg.eig(G)
        w = (C @ V).ravel() * np.linalg.solve(V, np.full(n, hi - lo))
        order = np.argsort(-lam.real)
        lam, w = lam[order].real, w[order].real
        ok_shape = lam.size == rates.size
        dr = _rel(np.sort(rates), np.sort(lam)) if ok_shape else math.inf
        dc = math.inf
        if ok_shape:
            pairs = sorted(zip(rates, coef))
            dc = _rel(np.array([c for _, c in pairs]), np.array([c for _, c in sorted(zip(lam, w))]))
        ok = bool(max(dg, dr, dc) <= 1e-6)
        return [Check("threshold_recheck", ok,
                      f"stored Gamma_d against A - Psi C from the stored Psi {_fmt(Psi.ravel())}: "
                      f"relative difference {dg:.3g}; stored threshold rates {_fmt(rates)} against "
                      f"eig(A - Psi C) {_fmt(lam)}: {dr:.3g}; coefficients {_fmt(coef)} against "
                      f"C V diag(V^-1 e_hat) {_fmt(w)} with e_hat = {hi - lo:g}: {dc:.3g} (tolerance "
                      "1e-06 each)", {"gamma_difference": dg, "rate_difference": dr,
                                      "coefficient_difference": dc})]

    checks += _guard("threshold_recheck", recheck)

    def simulate_detection() -> list[Check]:
        if n == 3:
            starts = np.array(SEED004_INITIAL_STATES, dtype=float)
        else:
            starts = np.array([[hi] * n, [0.5 * (lo + hi)] * n])
        starts = np.clip(starts, np.nextafter(lo, math.inf), hi)
        R = starts.shape[0]
        ts = min(float(spec.ts) if spec.ts else FAULT_TS, FAULT_TS)
        k_f = int(round(t_f / ts))
        steps = int(math.ceil((t_f + FAULT_HORIZON) / ts))
        if steps > 10 * MAX_STEPS:
            return [Check("fault_detected", None, f"not simulated: {steps} samples of {ts:g} s")]
        x0 = np.vstack([starts, starts])
        faults = np.concatenate([np.zeros(R), np.full(R, delta_bar)])
        obs = _ResidualObserver(plant, Psi, ts)
        change = [ParameterChange(k_f, {"delta_bar": faults})] if params else []
        res = simulate(plant, ts=ts, steps=steps, x0=x0, seeds=run_seeds(0, 2 * R),
                       controller=_Schedule(SEED004_INPUT, m), estimator=obs,
                       x_hat0=np.full((2 * R, n), lo), parameters=params or None,
                       changes=change, substeps=4)
        t = res.t
        r = np.abs(np.array(obs.residuals)[:, :, 0]).T            # (2R, N + 1)
        tt = t[None, :]
        if conservative:
            thr = np.sum(np.abs(coef)[:, None] * np.exp(rates[:, None] * t[None, :]), axis=0)
        else:
            thr = np.sum(coef[:, None] * np.exp(rates[:, None] * t[None, :]), axis=0)
        margin = r - thr[None, :]
        t_skip = 0.02 * t_f
        quiet = (tt >= t_skip)
        worst_h = float(np.max(np.where(quiet, margin[:R], -np.inf)))
        pre_fault = (tt >= t_skip) & (tt < t_f)
        worst_pre = float(np.max(np.where(pre_fault, margin[R:], -np.inf)))
        slack = FAULT_SLACK * float(np.interp(t_skip, t, thr))
        ok_h = bool(worst_h <= slack and worst_pre <= slack and np.all(np.isfinite(r)))
        detect = []
        for i in range(R, 2 * R):
            idx = np.flatnonzero((t > t_f) & (margin[i] > 0))
            if idx.size == 0:
                detect.append(None)
                continue
            k = int(idx[0])
            a, b = margin[i, k - 1], margin[i, k]
            frac = (-a / (b - a)) if (a < 0 < b) else 1.0
            detect.append(float(t[k - 1] + frac * ts))
        stored = None
        if "detection_times" in doc["gains"] and n == 3:
            stored = np.asarray(artefact_gain(doc, "detection_times"), dtype=float).reshape(-1)
        diffs = [None if (d is None or stored is None or i >= stored.size or stored[i] < 0)
                 else abs(d - float(stored[i])) for i, d in enumerate(detect)]
        ok_d = all(d is not None and t_f < d <= t_f + FAULT_HORIZON for d in detect) and \
            all(df is None or df <= FAULT_TIME_TOLERANCE for df in diffs)
        thr_name = "eq. 55 (conservative)" if conservative else "eq. 54"
        setup = (f"{R} starts {_fmt(starts)}, observer from x_hat = {lo:g}, input 2 on [0, 1 s) then "
                 f"1, sampled every {ts:g} s (4 RK4 substeps), stored Psi, threshold {thr_name} from "
                 "the stored coefficients and rates")
        td = ", ".join("none" if d is None else f"{d:.5g} s" for d in detect)
        sd = "" if stored is None else f"; stored {_fmt(stored[:R], 6)} s, differences " + ", ".join(
            "-" if df is None else f"{df:.3g}" for df in diffs) + \
            f" s (tolerance {FAULT_TIME_TOLERANCE:g} s)"
        return [
            Check("no_false_alarm", ok_h,
                  f"{setup}: healthy plant, largest |epsilon| - threshold on [{t_skip:g}, "
                  f"{t[-1]:g}] s = {worst_h:.3g}; faulty plant before t_f = {t_f:g} s: "
                  f"{worst_pre:.3g} (both must be <= {slack:.3g} = {FAULT_SLACK:g} x the threshold at "
                  f"{t_skip:g} s, integration error; the first {t_skip:g} s = 2 % of t_f are the "
                  "initial transient)", {"healthy_margin": worst_h, "pre_fault_margin": worst_pre,
                                         "slack": slack, "transient_s": t_skip, "ts": ts}),
            Check("fault_detected", bool(ok_d),
                  f"{setup}: fault delta_bar = {delta_bar:g} from t_f = {t_f:g} s: detection at "
                  f"t_d = {td} (must lie in ({t_f:g}, {t_f + FAULT_HORIZON:g}] s){sd}",
                  {"t_detect": detect, "stored": None if stored is None else stored.tolist(),
                   "differences": diffs, "t_fault": t_f, "delta_bar": delta_bar,
                   "horizon_s": FAULT_HORIZON, "tolerance_s": FAULT_TIME_TOLERANCE}),
        ]

    checks += _guard("fault_detected", simulate_detection)
    return checks
