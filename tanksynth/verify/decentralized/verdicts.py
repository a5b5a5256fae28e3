"""Verdict of ``decentralized_kalman`` (decentralised Kalman gains on the nonlinear network)."""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant
from tanksynth.sim.integrate import Integrator, param_arrays
from tanksynth.sim.simulate import run_seeds, simulate
from tanksynth.spec import Spec
from tanksynth.verify.decentralized.long_run import long_run
from tanksynth.verify.common import (artefact_gain, artefact_matrix, discrete_ts, fmt, guard,
                                     operating_point, option)
from tanksynth.verify.traces import TraceRecorder

__all__ = ["DecentralizedFilter", "decentralized_kalman_verdict"]


class DecentralizedFilter:
    """The window's decentralised filter with fixed gains (a `BatchEstimator`).

    Prediction by one simulator step of the nominal nonlinear plant
    (``x_hat(k|k-1)`` from ``x_hat(k-1|k-1)`` and the held input), update
    ``x_hat(k|k) = x_hat(k|k-1) + K_{k-1} (y_k - h(x_hat(k|k-1)))`` for the
    window steps ``k = 1..T``; without gains (or after the window) the
    prediction is returned: the open-loop predictor.

    Parameters
    ----------
    plant : Plant
    gains : sequence of ndarray, shape (n, q)
        ``K_0 .. K_{T-1}``.
    ts : float
        Sampling period (s).
    substeps : int
        RK4 steps of the prediction.
    """

    def __init__(self, plant: Plant, gains: Sequence[np.ndarray], ts: float, substeps: int = 4):
        self.plant = plant
        self.gains = [np.asarray(K, dtype=float) for K in gains]
        self.ts = float(ts)
        self.substeps = int(substeps)
        self._x: np.ndarray = np.empty((0, plant.n))    # set by reset
        self._k = 0
        # The simulator's own integrator, model, parameters and bounds, built once: one
        # `predict` is exactly the state `simulate(..., steps=1, u_init=u).x[:, 1]` returns.
        self._params = param_arrays(plant, None, 1)
        self._integ = Integrator.for_plant(plant, self._params)
        self._u_lo = np.full(plant.m, -np.inf)
        self._u_hi = np.full(plant.m, np.inf)
        for j, pair in enumerate(plant.input_bounds):
            for arr, b in ((self._u_lo, pair[0]), (self._u_hi, pair[1])):
                arr[j] = self._params[b] if isinstance(b, str) else float(b)

    def reset(self, x_hat0: np.ndarray) -> None:
        """Initial estimates (M, n).

        Parameters
        ----------
        x_hat0 : ndarray, shape (M, n)
            Initial estimates (state units, m).
        """
        self._x = np.asarray(x_hat0, dtype=float).copy()
        self._k = 0

    def predict(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One sampling period of the nominal plant from ``x`` (M, n) under the held ``u`` (M, m).

        The simulator's step without noise: states clipped, input saturated,
        ``substeps`` RK4 steps (switching surfaces located), clipped again.

        Parameters
        ----------
        x, u : ndarray (M, n), ndarray (M, m)
            States (state units, m) and held inputs (input units, m^3/s).
        """
        integ = self._integ
        x = integ.clip(np.asarray(x, dtype=float))
        u = np.minimum(np.maximum(np.asarray(u, dtype=float), self._u_lo), self._u_hi)
        return integ.clip(integ.advance(x, u, self._params, self.ts, self.substeps))

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Measurement (M, q), previous input (M, m) -> estimate (M, n).

        Parameters
        ----------
        y, u : ndarray (M, q), ndarray (M, m)
            Measurements (output units, m) and previous inputs (input units, m^3/s).
        """
        if self._k > 0:
            M = self._x.shape[0]
            pred = self.predict(self._x, u)
            if self._k <= len(self.gains):
                yhat = np.asarray(self.plant.compiled.output(pred), dtype=float).reshape(M, -1)
                pred = pred + (y - yhat) @ self.gains[self._k - 1].T
            self._x = pred
        self._k += 1
        return self._x


def decentralized_kalman_verdict(doc: Mapping[str, Any], spec: Spec, *,
                                 trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``decentralized_kalman`` artefact (seed 003).

    Checks: ``sparsity`` (every gain entry outside ``E`` exactly 0),
    ``covariances`` (``P0_pred`` symmetric positive definite, ``P_diag >
    0``), then on the nonlinear network over the window (8 runs; initial
    error drawn from ``P0_pred``, process noise ``sqrt(Qc_ii ts)`` per state
    and sample, measurement noise ``sqrt(R_ii)``, the spec's window input):
    ``filter_vs_open_loop`` (RMSE of the filter below that of the open-loop
    predictor from the same start) and ``filter_error_bounded`` (RMS error
    over the last quarter of the window <= 3 sqrt(mean P_diag) there); with the option
    ``run_steps`` > 0, ``long_run`` (`tanksynth.verify.decentralized.long_run`: centralised,
    one-step and finite-horizon decentralised filters on one noisy run of that length, the last
    with the design's ``window``, ``tolerance`` and ``max_iter``; all three below the
    measurement RMSE).

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    plant = spec.plant
    n, q, m = plant.n, plant.q, plant.m
    E = artefact_matrix(doc, "E", (n, q))
    T = 0
    while f"K_{T}" in doc["gains"]:
        T += 1
    if T == 0:
        raise ArtefactError(f"artefact '{doc['name']}' has no gain K_0")
    Ks = [artefact_matrix(doc, f"K_{j}", (n, q)) for j in range(T)]
    mask = E != 0
    bad = [(j, int(np.sum(K[~mask] != 0))) for j, K in enumerate(Ks) if np.any(K[~mask] != 0)]
    checks = [Check("sparsity", not bad,
                    f"entries of K_0 .. K_{T - 1} outside the pattern E ({int(mask.sum())} free of "
                    f"{mask.size}) are exactly 0" if not bad else
                    "nonzero entries outside E in " + ", ".join(f"K_{j} ({c})" for j, c in bad[:5]),
                    {"violations": bad})]
    P0 = artefact_matrix(doc, "P0_pred", (n, n))
    Pd = np.atleast_2d(artefact_gain(doc, "P_diag")).reshape(T, n)
    sym = float(np.max(np.abs(P0 - P0.T)) / max(float(np.max(np.abs(P0))), 1e-300))
    pmin = float(np.min(np.linalg.eigvalsh(0.5 * (P0 + P0.T))))
    checks.append(Check("covariances", bool(sym <= 1e-12 and pmin > 0 and np.all(Pd > 0)),
                        f"P0_pred symmetric to {sym:.3g} (tolerance 1e-12), smallest eigenvalue "
                        f"{pmin:.3g} (must be > 0); smallest P_diag entry {float(np.min(Pd)):.3g} "
                        "(must be > 0)", {"asymmetry": sym, "P0_min_eigenvalue": pmin}))

    def simulate_window() -> list[Check]:
        ts = discrete_ts(spec)
        x0 = np.asarray(spec.x0, dtype=float)
        u = _input(option(doc, spec, "input"), m, operating_point(spec)[1])
        qdiag = np.diag(_noise_matrix(option(doc, spec, "process_noise", 0.0), n))
        rdiag = np.diag(_noise_matrix(option(doc, spec, "measurement_noise", 1.0), q))
        runs = 8
        rng = np.random.default_rng(11)
        chol = np.linalg.cholesky(0.5 * (P0 + P0.T))
        starts = x0 + rng.standard_normal((runs, n)) @ chol.T
        lo = np.array([b[0] for b in plant.region.bounds], float)
        starts = np.maximum(starts, np.where(np.isfinite(lo), lo, -np.inf))
        seeds = run_seeds(5, runs)
        common: dict[str, Any] = dict(ts=ts, steps=T, x0=starts, seeds=seeds, x_hat0=np.tile(x0, (runs, 1)),
                      u_init=u, process_std=np.sqrt(np.maximum(qdiag, 0) * ts),
                      measurement_std=np.sqrt(np.maximum(rdiag, 0)), substeps=4)
        filt = simulate(plant, estimator=DecentralizedFilter(plant, Ks, ts), **common)
        if trace is not None:
            trace.record(filt, plant, check="filter_vs_open_loop", estimator=True,
                         scenario="random initial states, process and measurement noise, "
                                  "decentralised Kalman filter")
        open_loop = simulate(plant, estimator=DecentralizedFilter(plant, [], ts), **common)
        e_f = filt.x_hat[:, 1:] - filt.x[:, 1:]
        e_o = open_loop.x_hat[:, 1:] - open_loop.x[:, 1:]
        rmse_f = float(np.sqrt(np.mean(e_f ** 2)))
        rmse_o = float(np.sqrt(np.mean(e_o ** 2)))
        tail = slice(T - max(1, T // 4), T)
        rms_tail = float(np.sqrt(np.mean(e_f[:, tail] ** 2)))
        bound = 3.0 * float(np.sqrt(np.mean(Pd[tail])))
        finite = bool(np.all(np.isfinite(e_f)))
        return [
            Check("filter_vs_open_loop", bool(finite and rmse_f < rmse_o),
                  f"{runs} runs of the nonlinear plant over the {T}-step window (input {fmt(u[:4])}"
                  f"{' ...' if m > 4 else ''}, initial error drawn from P0_pred, process noise std "
                  f"sqrt(Qc_ii ts), measurement noise std sqrt(R_ii)): RMSE of the decentralised "
                  f"filter {rmse_f:.4g} against {rmse_o:.4g} for the open-loop predictor from the "
                  "same start (must be smaller)",
                  {"rmse_filter": rmse_f, "rmse_open_loop": rmse_o, "runs": runs}),
            Check("filter_error_bounded", bool(finite and rms_tail <= bound),
                  f"RMS estimation error over the last {tail.stop - tail.start} window steps "
                  f"{rms_tail:.4g} against 3 sqrt(mean P_diag) = {bound:.4g} there (must not exceed)",
                  {"rms_tail": rms_tail, "bound": bound}),
        ]

    checks += guard("filter_simulation", simulate_window)
    steps = int(option(doc, spec, "run_steps", 0) or 0)
    if steps > 0:
        checks += guard("long_run", lambda: [_long_run_check(doc, spec, steps, E)])
    return checks


def _input(value: Any, m: int, default: np.ndarray) -> np.ndarray:
    """The spec's input option (list or array of m values), else ``default``."""
    if value is None:
        return np.asarray(default, dtype=float)
    arr = np.asarray(value, dtype=float).reshape(-1)
    return arr if arr.size == m else np.asarray(default, dtype=float)


def _noise_matrix(value: Any, size: int, correlation: float = 0.0) -> np.ndarray:
    """A number ``v`` (``v ((1 - rho) I + rho 1 1')``), a diagonal or a matrix, as a matrix."""
    if isinstance(value, (list, tuple, np.ndarray)):
        arr = np.asarray(value, dtype=float)
        return np.diag(arr) if arr.ndim == 1 else arr
    v = float(value)
    return v * ((1 - correlation) * np.eye(size) + correlation * np.ones((size, size)))


def _long_run_check(doc: Mapping[str, Any], spec: Spec, steps: int, E: np.ndarray) -> Check:
    """``long_run``: `tanksynth.verify.decentralized.long_run.long_run` on the spec's schedule."""
    plant = spec.plant
    n, q, m = plant.n, plant.q, plant.m
    ts = discrete_ts(spec)
    u1 = _input(option(doc, spec, "input"), m, operating_point(spec)[1])
    after = option(doc, spec, "input_after")
    u2 = _input(after, m, u1)
    switch = float(option(doc, spec, "input_switch", 0.0) or 0.0)
    t = np.arange(steps) * ts
    inputs = np.where((t < switch)[:, None] if after is not None else np.ones((steps, 1), bool), u1, u2)
    rho = float(option(doc, spec, "process_noise_correlation", 0.0) or 0.0)
    Qc = _noise_matrix(option(doc, spec, "process_noise", 0.0), n, rho)
    R = _noise_matrix(option(doc, spec, "measurement_noise", 1.0), q)
    P0 = _noise_matrix(option(doc, spec, "initial_covariance", 10.0), n)
    relin = int(option(doc, spec, "relinearize_every", 10) or 10)
    seed = int(option(doc, spec, "run_seed", 7))
    start = _input(option(doc, spec, "run_x0"), n, np.asarray(spec.x0, dtype=float))
    window = int(option(doc, spec, "window", 40) or 40)
    tol = float(option(doc, spec, "tolerance", 1e-6) or 1e-6)
    max_iter = int(option(doc, spec, "max_iter", 100) or 100)
    run = long_run(plant, start, inputs, ts, Qc, R, P0, E, relin, seed, window, tol, max_iter)
    r = run.rmse
    meas = r.get("measurement")
    fh = run.fh_windows
    ok = bool(all(np.isfinite(v) for v in r.values())
              and (meas is None or all(r[f] < meas for f in ("centralized", "one_step", "finite_horizon"))))
    return Check("long_run", ok,
                 f"{steps} samples of the nonlinear plant from "
                 + ("the operating point" if option(doc, spec, "run_x0") is None
                    else f"x0 = {fmt(start[:2])} ...")
                 + f" (input "
                 f"{fmt(u1[:2])}{' ...' if m > 2 else ''}"
                 + (f", then {fmt(u2[:2])}{' ...' if m > 2 else ''} from t = {switch:g} s" if after is not None else "")
                 + f"; seed {seed}), filters relinearised at their estimates every {relin} samples: "
                 f"RMSE centralised {r['centralized']:.4g}, one-step decentralised "
                 f"{r['one_step']:.4g}, finite-horizon decentralised {r['finite_horizon']:.4g} "
                 f"({window}-sample windows, {fh['converged']}/{fh['windows']} converged to {tol:g})"
                 + (f", measurements {meas:.4g} (every filter must be below it)" if meas is not None else "")
                 + f"; sum of tr P(k|k) centralised {run.trace_P['centralized']:.5g}, one-step "
                 f"{run.trace_P['one_step']:.5g}, finite-horizon {run.trace_P['finite_horizon']:.5g}",
                 {"steps": steps, "rmse": r, "trace_P": run.trace_P, "seed": seed,
                  "input_switch_s": switch, "relinearize_every": relin, "x0": start.tolist(),
                  "window": window, "tolerance": tol, "fh_windows": fh})
