"""Verdict of ``narx`` (NARX estimator trained on EKF data)."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.verify.common import (NUMERIC_ERRORS, artefact_gain, design_options, fmt, guard,
                                     one_line, option, relative_difference)
from tanksynth.verify.traces import TraceRecorder

__all__ = ["fresh_ekf_data", "NARX_FIT_FACTOR", "NARX_CLOSED_LOOP_FACTOR", "NARX_FRESH_DRAW", "narx_network",
           "teacher_forced_inputs", "narx_verdict"]


#: Fresh one-step fit error allowed, as a multiple of the training fit error.
NARX_FIT_FACTOR = 3.0
#: Fresh closed-loop RMSE allowed, as a multiple of the validation RMSE claimed by the design.
NARX_CLOSED_LOOP_FACTOR = 3.0
#: Offset added to the training's random-generator seed for the fresh verification data (so the
#: verdict never draws the training data again).
NARX_FRESH_DRAW = 1_000_003


def narx_network(weights: Mapping[str, np.ndarray], inputs: np.ndarray) -> np.ndarray:
    """One-step prediction of the stored NARX network (seed 002 eq. 42-45).

    ``x = out_mean + out_scale * (W2 tanh(W1 z + b1) + b2)`` with the
    normalised input ``z = (inputs - in_mean) / in_scale``.

    Parameters
    ----------
    weights : mapping
        ``W1`` (H, k), ``b1`` (H,), ``W2`` (n, H), ``b2`` (n,), ``in_mean``,
        ``in_scale`` (k,), ``out_mean``, ``out_scale`` (n,).
    inputs : ndarray, shape (N, k)
        Network inputs (state and output units; see `teacher_forced_inputs`).

    Returns
    -------
    ndarray, shape (N, n)
        Estimated states (state units).
    """
    z = (np.asarray(inputs, dtype=float) - weights["in_mean"]) / weights["in_scale"]
    hidden = np.tanh(np.einsum("hk,nk->nh", weights["W1"], z) + weights["b1"])
    out = np.einsum("jh,nh->nj", weights["W2"], hidden) + weights["b2"]
    return weights["out_mean"] + weights["out_scale"] * out


def teacher_forced_inputs(data: Mapping[str, np.ndarray], x0: np.ndarray, delays: int,
                          target: str) -> tuple[np.ndarray, np.ndarray]:
    """Network inputs and targets of recorded data, past estimates taken from the data.

    The input at step ``k`` is ``[x(k|k-1), gamma(k), x(k-1), ..., x(k-d)]``
    (EKF prior, innovation, the ``d`` previous targets; before the first
    sample the past is ``x0``); the target is ``x(k)``: the EKF estimate
    (``target = "ekf"``) or the true state.

    Parameters
    ----------
    data : mapping
        `fresh_ekf_data` output: ``x`` (steps + 1, runs, n), ``x_ekf``,
        ``prior`` (steps, runs, n), ``innovation`` (steps, runs, q).
    x0 : ndarray, shape (n,)
        Initial estimate (state units).
    delays : int
        ``d``.
    target : {"ekf", "true"}

    Returns
    -------
    inputs : ndarray, shape (steps runs, n + q + d n)
    targets : ndarray, shape (steps runs, n)
    """
    est = np.asarray(data["x_ekf"] if target == "ekf" else data["x"][1:], dtype=float)
    steps, runs, n = est.shape
    padded = np.concatenate([np.broadcast_to(np.asarray(x0, dtype=float), (delays, runs, n)), est])
    columns = [np.asarray(data["prior"], dtype=float), np.asarray(data["innovation"], dtype=float)]
    columns += [padded[delays - 1 - j: delays - 1 - j + steps] for j in range(delays)]
    inputs = np.concatenate(columns, axis=2)
    return inputs.reshape(steps * runs, -1), est.reshape(steps * runs, n)


def fresh_ekf_data(plant: Any, ekf_tuning: Any, *, runs: int, steps: int, seed: int,
                   input_range: Any = None, hold: Any = (30, 150), noise_std: Any = None,
                   sim_substeps: int = 10) -> dict[str, np.ndarray]:
    """Fresh EKF data for the NARX verdict, drawn by the verdict itself (not by the design code).

    Random piecewise-constant inputs (levels uniform in ``input_range``, default the
    actuator range, held ``hold`` samples), initial states sampled in the region,
    the plant simulated by `tanksynth.sim.simulate_inputs`, measurements with
    Gaussian noise (``noise_std``, default ``sqrt(diag(R))``), and the runtime EKF
    run on them.

    Parameters
    ----------
    plant, ekf_tuning : Plant, KalmanTuning
        The plant model and the stored EKF tuning.
    runs, steps, seed : int
        Number of runs, samples per run and random seed.
    input_range, hold : array_like (m, 2) or None, (int, int)
        Input levels (input units, m^3/s; None: actuator range), hold lengths (samples).
    noise_std, sim_substeps : array_like (q,) or None, int
        Measurement noise standard deviation (output units, m), RK4 steps per sample.

    Returns
    -------
    dict
        ``x`` (steps + 1, runs, n), ``u`` (steps, runs, m), ``y`` (steps, runs, q),
        ``x_ekf`` and ``prior`` (steps, runs, n), ``innovation`` (steps, runs, q).
    """
    from tanksynth.runtime.estimators.kalman import ExtendedKalmanFilter
    from tanksynth.sim.simulate import simulate_inputs

    rng = np.random.default_rng(seed)
    ranges = np.asarray(plant.input_limits if input_range is None else input_range,
                        dtype=float).reshape(plant.m, 2)
    low, high = int(hold[0]), int(hold[1])
    U = np.empty((steps, runs, plant.m))
    for r in range(runs):
        k = 0
        while k < steps:
            length = int(rng.integers(low, high + 1))
            U[k:k + length, r] = rng.uniform(ranges[:, 0], ranges[:, 1])
            k += length
    X0 = plant.region.sample(runs, plant.x, seed=seed, margin=0.1)
    sim = simulate_inputs(plant, X0, U, ekf_tuning.ts, substeps=sim_substeps)
    X = np.ascontiguousarray(sim.x.transpose(1, 0, 2))
    U = np.ascontiguousarray(sim.u.transpose(1, 0, 2))
    std = np.sqrt(np.diag(ekf_tuning.R)) if noise_std is None else np.asarray(noise_std, dtype=float)
    Y = np.stack([np.asarray(plant.compiled.output(X[k + 1])) for k in range(steps)])
    Y = Y + rng.normal(size=Y.shape) * std
    ekf = ExtendedKalmanFilter(plant, ekf_tuning, runs=runs, backend="vm")
    x_ekf = np.empty((steps, runs, plant.n))
    prior = np.empty((steps, runs, plant.n))
    innovation = np.empty((steps, runs, plant.q))
    for k in range(steps):
        x_ekf[k] = ekf.step(Y[k], U[k])
        prior[k] = ekf.prediction
        innovation[k] = ekf.innovation
    return {"x": X, "u": U, "y": Y, "x_ekf": x_ekf, "prior": prior, "innovation": innovation}


def narx_verdict(doc: Mapping[str, Any], spec: Any, *,
                 trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``narx`` artefact (seed 002 section 3.3).

    The network is evaluated from the stored weights and normalisation by
    the verdict's own `narx_network` (the shipped `NARXEstimator` runs the
    closed loop); fresh data come from `fresh_ekf_data` with the stored EKF tuning
    (``ekf_Q``, ``ekf_R``, ``ekf_P0``, ``x_hat0``) and the spec's data options,
    on a seed the training never used (2 runs, the spec's ``steps``).

    ``training_fit_recheck``
        the one-step (teacher-forced) MSE of the stored weights on the
        stored training data equals the training MSE the diagnostics report
        (relative tolerance 1e-6).
    ``one_step_fit``
        on the fresh data, the mean over states of the one-step MSE is at
        most `NARX_FIT_FACTOR` (3) times the reference: the larger of the
        mean training MSE and the mean held-out (validation) one-step MSE
        the design reports.
    ``closed_loop_bounded``
        the estimator runs in closed loop on the fresh measurements
        (`NARXEstimator`, own predictions fed back): every estimate finite
        and the RMSE against the true states (mean over states) at most
        `NARX_CLOSED_LOOP_FACTOR` (3) times the larger of the design's
        validation RMSE against the true states and the EKF's RMSE on the
        same fresh data.

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    from tanksynth.runtime.estimators.kalman import KalmanTuning
    from tanksynth.runtime.estimators.narx import NARXEstimator, NARXTuning

    plant = spec.plant
    n, q = plant.n, plant.q

    def g(key: str) -> np.ndarray:
        return np.asarray(artefact_gain(doc, key), dtype=float)

    W1 = np.atleast_2d(g("W1"))
    H = W1.shape[0]
    delays = int(round(float(np.ravel(g("delays"))[0])))
    substeps = int(option(doc, spec, "substeps", 1))
    clip = bool(option(doc, spec, "clip", False))
    tuning = NARXTuning(W1, g("b1").reshape(H), np.atleast_2d(g("W2")).reshape(n, H),
                        g("b2").reshape(n), g("in_mean").reshape(-1), g("in_scale").reshape(-1),
                        g("out_mean").reshape(n), g("out_scale").reshape(n), x0=g("x_hat0").reshape(n),
                        ts=float(spec.ts), delays=delays, substeps=substeps, clip=clip)
    weights = {"W1": tuning.W1, "b1": tuning.b1, "W2": tuning.W2, "b2": tuning.b2,
               "in_mean": tuning.in_mean, "in_scale": tuning.in_scale,
               "out_mean": tuning.out_mean, "out_scale": tuning.out_scale}

    def predict(X_in: np.ndarray) -> np.ndarray:
        return narx_network(weights, X_in)

    diag = doc.get("diagnostics", {}) or {}
    fit = diag.get("fit", {}) or {}
    claimed = np.asarray(fit.get("mse_train", []), dtype=float).reshape(-1)
    checks: list[Check] = []

    def recheck() -> list[Check]:
        Xt, Tt = np.atleast_2d(g("training_inputs")), np.atleast_2d(g("training_targets"))
        mse = np.mean((predict(Xt) - Tt) ** 2, axis=0)
        if claimed.size != n:
            return [Check("training_fit_recheck", None, "the diagnostics report no training MSE")]
        diff = relative_difference(mse, claimed)
        return [Check("training_fit_recheck", bool(diff <= 1e-6),
                      f"one-step MSE of the stored weights on the {Xt.shape[0]} stored training "
                      f"samples {fmt(mse)} against the reported training MSE {fmt(claimed)}: "
                      f"relative difference {diff:.3g} (tolerance 1e-06)",
                      {"mse": mse.tolist(), "reported": claimed.tolist(), "difference": diff})]

    checks += guard("training_fit_recheck", recheck)

    def fresh() -> list[Check]:
        train = diag.get("training", {}) or {}
        seed = int(option(doc, spec, "seed", train.get("seed", 0))) + NARX_FRESH_DRAW
        steps = int(option(doc, spec, "steps", train.get("steps", 600)))
        target = str(option(doc, spec, "target", train.get("target", "ekf")))
        input_range = option(doc, spec, "input_range")
        hold = tuple(option(doc, spec, "hold", [30, 150]))
        noise = option(doc, spec, "noise_std")
        ekf = KalmanTuning(Q=np.atleast_2d(g("ekf_Q")).reshape(n, n),
                           R=np.atleast_2d(g("ekf_R")).reshape(q, q),
                           P0=np.atleast_2d(g("ekf_P0")).reshape(n, n), x0=tuning.x0,
                           ts=float(spec.ts), substeps=substeps, clip=clip,
                           **{k: v for k, v in design_options(doc, spec).items()
                              if k in ("jacobian_eps", "switch_tol")})
        runs = 2
        data = fresh_ekf_data(plant, ekf, runs=runs, steps=steps, seed=seed,
                                 input_range=input_range, hold=hold, noise_std=noise,
                                 sim_substeps=int(option(doc, spec, "sim_substeps", 10)))
        X_in, T = teacher_forced_inputs(data, tuning.x0, delays, target)
        mse = np.mean((predict(X_in) - T) ** 2, axis=0)
        out: list[Check] = []
        if claimed.size == n:
            held = np.asarray(fit.get("mse_validation_open_loop", []), dtype=float).reshape(-1)
            ref = max(float(np.mean(claimed)), float(np.mean(held)) if held.size == n else 0.0)
            ratio = float(np.mean(mse) / max(ref, 1e-300))
            out.append(Check("one_step_fit", bool(np.all(np.isfinite(mse)) and
                                                  ratio <= NARX_FIT_FACTOR),
                             f"one-step (teacher-forced) MSE on fresh EKF data ({runs} runs x {steps} "
                             f"samples, seed {seed}, target {target}): {fmt(mse)}, mean "
                             f"{float(np.mean(mse)):.4g}; reference max(training MSE mean "
                             f"{float(np.mean(claimed)):.4g}, held-out validation MSE mean "
                             f"{float(np.mean(held)) if held.size == n else float('nan'):.4g}) = "
                             f"{ref:.4g}; ratio {ratio:.3g} (must be <= "
                             f"{NARX_FIT_FACTOR:g})", {"mse": mse.tolist(), "ratio": ratio,
                                                       "factor": NARX_FIT_FACTOR, "seed": seed}))
        else:
            out.append(Check("one_step_fit", None, "the diagnostics report no training MSE"))
        est = NARXEstimator(plant, tuning, runs=runs, backend="vm")
        X_hat = np.empty_like(data["x_ekf"])
        failed = None
        with np.errstate(all="ignore"):
            for k in range(steps):
                try:
                    X_hat[k] = est.step(data["y"][k], data["u"][k])
                except NUMERIC_ERRORS as exc:
                    X_hat[k:] = np.nan
                    failed = (k, one_line(exc))
                    break
        truth = data["x"][1:]
        rmse = float(np.sqrt(np.mean((X_hat - truth) ** 2)))
        ekf_rmse = float(np.sqrt(np.mean((data["x_ekf"] - truth) ** 2)))
        val = (diag.get("closed_loop_validation", {}) or {}).get("rmse_vs_true")
        claim = float(np.sqrt(np.mean(np.square(val)))) if val else 0.0
        bound = NARX_CLOSED_LOOP_FACTOR * max(claim, ekf_rmse)
        ok = bool(failed is None and np.all(np.isfinite(X_hat)) and rmse <= bound)
        out.append(Check("closed_loop_bounded", ok,
                         f"NARX in closed loop (own estimates fed back) on the fresh measurements: "
                         f"RMSE against the true states {rmse:.4g}"
                         + (f" (stopped at step {failed[0]}: {failed[1]})" if failed else "")
                         + f"; bound {NARX_CLOSED_LOOP_FACTOR:g} x max(design's validation RMSE "
                           f"{claim:.4g}, EKF RMSE on the same data {ekf_rmse:.4g}) = {bound:.4g} "
                           "(every estimate must be finite and the RMSE within the bound)",
                         {"rmse": rmse, "bound": bound, "claimed_rmse": claim,
                          "ekf_rmse": ekf_rmse}))
        return out

    checks += guard("one_step_fit", fresh)
    return checks
