"""Training of the NARX state estimator (seed 002 section 3.3, Table 3): design work.

`train_narx` generates the training data the way the paper did ("data
obtained from the EKF based state estimation ... covering the entire
operating region"): the plant is simulated by the toolbox's one simulator
(`tanksynth.sim.simulate_inputs`: seeded piecewise-constant random inputs,
the plant's clipping rule, switching surfaces located), measured with the
noise of the EKF's ``R``, an EKF runs on it, and the network is fitted to the
EKF estimates in open loop (teacher forcing, MATLAB's ``narxnet`` default) by
Levenberg-Marquardt on the mean squared error (`levenberg_marquardt`: the
``trainlm`` iteration on ``J'J + mu I``; MINPACK's ``lmder`` behind
``scipy.optimize.least_squares(method="lm")`` gives the same fits but its
unblocked QR of the 7200 x 73 Jacobian is about 20 times slower). The
closed-loop estimator is then validated on held-out runs. The network, its
forward pass and the estimator the artefact ships are in
`tanksynth.runtime.estimators.narx`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tanksynth.errors import CovarianceError, InfeasibleDesign, SpecError
from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.tuning import as_matrix, as_vector, positive_int
from tanksynth.runtime.estimators.kalman import ExtendedKalmanFilter, KalmanTuning
from tanksynth.runtime.estimators.narx import NARXEstimator, NARXTuning, forward_pass, open_loop_regressors
from tanksynth.sim.excitation import designed_excitation
from tanksynth.sim.simulate import simulate_inputs

__all__ = ["NARXTraining", "train_narx", "generate_ekf_data", "levenberg_marquardt", "LMResult",
           "EXCITATIONS"]

#: Training-data excitations: ``random`` (uniform piecewise-constant pump levels over the
#: input range) and ``designed`` (set-point steps over a level range that straddles the
#: threshold, each held by its equilibrium input, plus a three-level PRBS on every pump).
EXCITATIONS = ("random", "designed")


def _input_schedule(rng: np.random.Generator, steps: int, runs: int, ranges: np.ndarray,
                    hold: tuple[int, int]) -> np.ndarray:
    m = ranges.shape[0]
    U = np.empty((steps, runs, m))
    for r in range(runs):
        k = 0
        while k < steps:
            length = int(rng.integers(hold[0], hold[1] + 1))
            U[k:k + length, r] = rng.uniform(ranges[:, 0], ranges[:, 1])
            k += length
    return U


def generate_ekf_data(plant: Plant, ekf_tuning: KalmanTuning, *, runs: int, steps: int, seed: int,
                      input_range: Any = None, hold: tuple[int, int] = (30, 150),
                      noise_std: Any = None, sim_substeps: int = 10, excitation: str = "random",
                      setpoint_range: Any = None, prbs_amplitude: float = 0.0,
                      prbs_hold: tuple[int, int] = (3, 20)) -> dict[str, np.ndarray]:
    """Simulate the plant and run an EKF on it (seeded): the NARX training data.

    Parameters
    ----------
    plant : Plant
    ekf_tuning : KalmanTuning
    runs, steps : int
        Parallel trajectories and samples per trajectory.
    seed : int
        Seed of the numpy generator (initial states, inputs, noise).
    input_range : array_like, shape (m, 2), optional
        Range of the random input levels (input units); default the
        actuator range.
    hold : (int, int)
        Range of the number of samples an input level is held.
    noise_std : array_like, shape (q,), optional
        Measurement noise standard deviation (output units); default
        ``sqrt(diag(R))`` of the EKF tuning.
    sim_substeps : int
        RK4 steps per period of the plant simulation (the toolbox's one
        integrator, `tanksynth.sim.simulate_inputs`: levels clipped by the
        plant's rule, switching surfaces located, inputs saturated).
    excitation : {"random", "designed"}
        ``random``: levels uniform in ``input_range`` held ``hold`` samples, initial
        states sampled in the region; ``designed``: `designed_excitation` (set-point
        steps in ``setpoint_range`` held ``hold`` samples, PRBS of amplitude
        ``prbs_amplitude`` held ``prbs_hold`` samples).
    setpoint_range : array_like, shape (2,), optional
        Set-point range of the designed excitation (state units).
    prbs_amplitude : float
        PRBS amplitude of the designed excitation (input units).
    prbs_hold : (int, int)
        PRBS hold range of the designed excitation (samples).

    Returns
    -------
    dict
        ``x`` (steps + 1, runs, n) true states, ``u`` (steps, runs, m) the
        applied (saturated) inputs, ``y``
        (steps, runs, q), ``x_ekf``, ``prior`` (steps, runs, n), ``innovation``
        (steps, runs, q).
    """
    rng = np.random.default_rng(seed)
    runs = positive_int(runs, "runs")
    steps = positive_int(steps, "steps")
    ranges = plant.input_limits if input_range is None else as_matrix(input_range, "input_range",
                                                                      (plant.m, 2))
    if not np.all(np.isfinite(ranges)) or np.any(ranges[:, 1] < ranges[:, 0]):
        raise SpecError("input_range must be finite (m x 2, min <= max); the plant's actuators "
                        "are unbounded, give input_range", key="input_range")
    std = np.sqrt(np.diag(ekf_tuning.R)) if noise_std is None else as_vector(noise_std, "noise_std",
                                                                              plant.q)
    if excitation == "designed":
        if setpoint_range is None:
            raise SpecError("the designed excitation needs setpoint_range", key="setpoint_range")
        X0, U = designed_excitation(plant, rng, steps=steps, runs=runs, setpoint_range=setpoint_range,
                                    hold=hold, prbs_amplitude=prbs_amplitude, prbs_hold=prbs_hold)
    elif excitation == "random":
        X0 = plant.region.sample(runs, plant.x, seed=seed, margin=0.1)
        U = _input_schedule(rng, steps, runs, ranges, hold)
    else:
        raise SpecError(f"excitation must be one of {', '.join(EXCITATIONS)}, got {excitation!r}",
                        key="excitation")
    sim = simulate_inputs(plant, X0, U, ekf_tuning.ts, substeps=sim_substeps)
    X = np.ascontiguousarray(sim.x.transpose(1, 0, 2))            # (steps + 1, runs, n)
    U = np.ascontiguousarray(sim.u.transpose(1, 0, 2))            # as applied (saturated)
    Yt = np.stack([np.asarray(plant.compiled.output(X[k + 1])) for k in range(steps)])
    Y = Yt + rng.normal(size=Yt.shape) * std
    ekf = ExtendedKalmanFilter(plant, ekf_tuning, runs=runs, backend="vm")
    n, q = plant.n, plant.q
    x_ekf = np.empty((steps, runs, n))
    prior = np.empty((steps, runs, n))
    innov = np.empty((steps, runs, q))
    for k in range(steps):
        x_ekf[k] = ekf.step(Y[k], U[k])
        prior[k] = ekf.prediction
        innov[k] = ekf.innovation
    return {"x": X, "u": U, "y": Y, "x_ekf": x_ekf, "prior": prior, "innovation": innov}


@dataclass(frozen=True, eq=False)
class NARXTraining:
    """A trained NARX estimator with its data and fit evidence.

    Attributes
    ----------
    tuning : NARXTuning
    inputs : ndarray, shape (N, n + q + d n)
        Training inputs (state/output units), open loop.
    targets : ndarray, shape (N, n)
        Training targets (state units).
    diagnostics : dict
        Seed, data sizes, fit errors (training and validation MSE,
        closed-loop RMSE against the true states and the EKF), solver status.
    """

    tuning: NARXTuning
    inputs: np.ndarray
    targets: np.ndarray
    diagnostics: dict = field(default_factory=dict)


def _jacobian(theta: np.ndarray, Z: np.ndarray, H: int, n: int) -> np.ndarray:
    N, nin = Z.shape
    params = _unpack(theta, H, nin, n)
    W1, _, W2, _ = params
    _, A = forward_pass(params, Z)
    D = 1.0 - A * A
    J = np.zeros((N, n, theta.size))
    o1 = H * nin
    J[:, :, :o1] = (W2[None, :, :, None] * D[:, None, :, None] * Z[:, None, None, :]).reshape(N, n, o1)
    J[:, :, o1:o1 + H] = W2[None] * D[:, None, :]
    o2 = o1 + H
    for j in range(n):
        J[:, j, o2 + j * H:o2 + (j + 1) * H] = A
    J[:, :, o2 + n * H:] = np.eye(n)
    return J.reshape(N * n, theta.size)


@dataclass(frozen=True, eq=False)
class LMResult:
    """Result of `levenberg_marquardt`.

    Attributes
    ----------
    x : ndarray
        Parameters.
    fun : ndarray
        Residuals at ``x``.
    nit : int
        Iterations (accepted or rejected steps).
    mu : float
        Final damping.
    success : bool
        Stopped on a tolerance rather than the iteration budget.
    message : str
    """

    x: np.ndarray
    fun: np.ndarray
    nit: int
    mu: float
    success: bool
    message: str


def levenberg_marquardt(residual: Any, jacobian: Any, x0: np.ndarray, *, max_iter: int = 300,
                        mu: float = 1e-3, mu_dec: float = 0.1, mu_inc: float = 10.0,
                        mu_max: float = 1e10, gtol: float = 1e-9, ftol: float = 1e-12,
                        validation: Any = None, max_fail: int = 6,
                        time_limit: float | None = None) -> LMResult:
    """Levenberg-Marquardt least squares, ``(J'J + mu I) dx = -J'r`` (MATLAB ``trainlm``).

    Parameters
    ----------
    residual : callable
        ``r(x) -> ndarray`` (N,).
    jacobian : callable
        ``J(x) -> ndarray`` (N, P).
    x0 : ndarray, shape (P,)
        Initial parameters, in the units ``residual`` takes (the NARX
        network's weights: dimensionless).
    max_iter : int
        Budget of trial steps (accepted or rejected).
    mu, mu_dec, mu_inc, mu_max : float
        Damping, its decrease/increase factors and its ceiling.
    gtol : float
        Stop when ``max |J'r|`` falls below it.
    ftol : float
        Stop when an accepted step reduces ``r'r`` by less than ``ftol`` relative.
    validation : callable, optional
        ``v(x) -> float`` validation error; with it, the parameters with the
        smallest validation error are returned and training stops after
        ``max_fail`` accepted steps without improving it (early stopping).
    max_fail : int
    time_limit : float, optional
        Wall-clock budget (s): stop after the iteration that exceeds it.

    Returns
    -------
    LMResult
    """
    import time

    start = time.perf_counter()
    x = np.asarray(x0, dtype=float).copy()
    r = residual(x)
    cost = float(r @ r)
    best_x, best_r = x.copy(), r.copy()
    best_v = validation(x) if validation is not None else None
    fails = 0
    message, success, it = "iteration budget exhausted", False, 0
    while it < max_iter:
        J = jacobian(x)
        g = J.T @ r
        if np.max(np.abs(g)) < gtol:
            message, success = "gradient below gtol", True
            break
        JJ = J.T @ J
        improved = False
        rel = 0.0
        while it < max_iter and mu <= mu_max:
            it += 1
            step = np.linalg.solve(JJ + mu * np.eye(x.size), -g)
            r_new = residual(x + step)
            cost_new = float(r_new @ r_new)
            if np.isfinite(cost_new) and cost_new < cost:
                rel = (cost - cost_new) / max(cost, 1e-300)
                x, r, cost = x + step, r_new, cost_new
                mu *= mu_dec
                improved = True
                break
            mu *= mu_inc
        if not improved:
            if mu > mu_max:
                message, success = "damping reached mu_max", True
            break
        if validation is not None:
            v = validation(x)
            if v < best_v:
                best_v, best_x, best_r, fails = v, x.copy(), r.copy(), 0
            else:
                fails += 1
                if fails >= max_fail:
                    message, success = f"validation error not improved in {max_fail} steps", True
                    break
        if rel < ftol:
            message, success = "relative cost decrease below ftol", True
            break
        if time_limit is not None and time.perf_counter() - start > time_limit:
            message = f"time limit {time_limit:g} s reached"
            break
    if validation is None:
        best_x, best_r = x, r
    return LMResult(best_x, best_r, it, float(mu), success, message)


def _unpack(theta: np.ndarray, H: int, nin: int, n: int) -> tuple[np.ndarray, ...]:
    i = 0
    W1 = theta[i:i + H * nin].reshape(H, nin)
    i += H * nin
    b1 = theta[i:i + H]
    i += H
    W2 = theta[i:i + n * H].reshape(n, H)
    i += n * H
    return W1, b1, W2, theta[i:i + n]


def train_narx(plant: Plant, ekf_tuning: KalmanTuning, *, hidden: int = 5, delays: int = 2,
               runs: int = 4, validation_runs: int = 1, steps: int = 600, seed: int = 0,
               input_range: Any = None, hold: tuple[int, int] = (30, 150), noise_std: Any = None,
               sim_substeps: int = 10, target: str = "ekf", restarts: int = 3,
               max_iter: int = 300, max_fail: int = 6, clip: bool = False,
               excitation: str = "random", setpoint_range: Any = None, prbs_amplitude: float = 0.0,
               prbs_hold: tuple[int, int] = (3, 20), time_limit: float | None = None) -> NARXTraining:
    """Generate EKF data over the operating region and fit the NARX estimator by LM.

    Parameters
    ----------
    plant : Plant
    ekf_tuning : KalmanTuning
        The EKF that produces the training data (its ``x0``, ``ts``,
        ``substeps`` are also the NARX's).
    hidden : int
        Hidden ``tanh`` neurons (Table 3: 5).
    delays : int
        Output feedback delays (Table 3: 2).
    runs, validation_runs : int
        Training and held-out trajectories.
    steps : int
        Samples per trajectory.
    seed : int
        Seed of the data and of the weight initialisation.
    input_range, hold, noise_std, sim_substeps, excitation, setpoint_range, prbs_amplitude, prbs_hold
        See `generate_ekf_data`.
    target : {"ekf", "true"}
        Fit the EKF estimates (the paper) or the simulated true states.
    restarts : int
        Random initialisations; the one with the smallest closed-loop error
        on the validation runs is kept.
    max_iter : int
        Levenberg-Marquardt iterations per restart.
    clip : bool
        Clamp the NARX's predictions and estimates to the region box.
    max_fail : int
        Early stopping: stop after this many accepted iterations without a
        better open-loop validation error (MATLAB's ``max_fail``, 6) and keep
        the best-validated weights.
    time_limit : float, optional
        Wall-clock budget of the Levenberg-Marquardt iterations of one restart (s); the
        best-validated weights so far are kept when it runs out.

    Returns
    -------
    NARXTraining

    Raises
    ------
    InfeasibleDesign
        The fitted estimator is not finite in closed loop on the held-out runs.
    """
    if target not in ("ekf", "true"):
        raise SpecError(f"target must be 'ekf' or 'true', got {target!r}", key="target")
    hidden = positive_int(hidden, "hidden")
    delays = positive_int(delays, "delays")
    validation_runs = positive_int(validation_runs, "validation_runs")
    total = positive_int(runs, "runs") + validation_runs
    data = generate_ekf_data(plant, ekf_tuning, runs=total, steps=steps, seed=seed,
                             input_range=input_range, hold=hold, noise_std=noise_std,
                             sim_substeps=sim_substeps, excitation=excitation,
                             setpoint_range=setpoint_range, prbs_amplitude=prbs_amplitude,
                             prbs_hold=prbs_hold)
    train = {k: v[:, :runs] for k, v in data.items()}
    valid = {k: v[:, runs:] for k, v in data.items()}
    X_in, T, prior = open_loop_regressors(train, ekf_tuning.x0, delays, target)
    Xv_in, Tv, prior_v = open_loop_regressors(valid, ekf_tuning.x0, delays, target)
    base, base_v = 0.0, 0.0
    in_mean, in_scale = X_in.mean(axis=0), X_in.std(axis=0)
    in_scale = np.where(in_scale > 0, in_scale, 1.0)
    out_mean, out_scale = (T - base).mean(axis=0), (T - base).std(axis=0)
    out_scale = np.where(out_scale > 0, out_scale, 1.0)
    Z = (X_in - in_mean) / in_scale
    Tn = (T - base - out_mean) / out_scale
    n, nin = plant.n, X_in.shape[1]
    rng = np.random.default_rng(seed)

    Zv = (Xv_in - in_mean) / in_scale
    Tvn = (Tv - out_mean) / out_scale

    def residual(theta: np.ndarray) -> np.ndarray:
        out, _ = forward_pass(_unpack(theta, hidden, nin, n), Z)
        return (out - Tn).ravel()

    def validation(theta: np.ndarray) -> float:
        out, _ = forward_pass(_unpack(theta, hidden, nin, n), Zv)
        return float(np.mean((out - Tvn) ** 2))

    def closed_loop(tuning: NARXTuning) -> np.ndarray:
        narx = NARXEstimator(plant, tuning, runs=validation_runs, backend="vm")
        out = np.empty_like(valid["x_ekf"])
        with np.errstate(all="ignore"):
            for k in range(steps):
                try:
                    out[k] = narx.step(valid["y"][k], valid["u"][k])
                except CovarianceError:
                    out[k:] = np.nan
                    break
        return out

    target_v = valid["x_ekf"] if target == "ekf" else valid["x"][1:]
    best: tuple[float, Any, NARXTuning, np.ndarray] | None = None
    candidates = []
    for _ in range(positive_int(restarts, "restarts")):
        theta0 = np.concatenate([rng.normal(0, 1 / np.sqrt(nin), hidden * nin), np.zeros(hidden),
                                 rng.normal(0, 1 / np.sqrt(hidden), n * hidden), np.zeros(n)])
        sol = levenberg_marquardt(residual, lambda t: _jacobian(t, Z, hidden, n), theta0,
                                  max_iter=max_iter, validation=validation, max_fail=max_fail,
                                  time_limit=time_limit)
        W1, b1, W2, b2 = (np.array(a) for a in _unpack(sol.x, hidden, nin, n))
        cand = NARXTuning(W1, b1, W2, b2, in_mean, in_scale, out_mean, out_scale, x0=ekf_tuning.x0,
                          ts=ekf_tuning.ts, delays=delays, substeps=ekf_tuning.substeps, clip=clip)
        closed = closed_loop(cand)
        score = float(np.sqrt(np.mean((closed - target_v) ** 2)))
        score = score if np.isfinite(score) else np.inf
        candidates.append({"closed_loop_rmse": score, "mse_standardised": float(np.mean(sol.fun ** 2)),
                           "iterations": sol.nit, "message": sol.message})
        if best is None or score < best[0]:
            best = (score, sol, cand, closed)
    if best is None:        # restarts >= 1: one candidate at least
        raise InfeasibleDesign("no NARX estimator was trained (restarts = 0)")
    score, sol, tuning, closed = best
    if not np.isfinite(score):
        raise InfeasibleDesign("no trained NARX estimator stays finite in closed loop on the "
                               "validation runs; try more data, restarts or another seed")
    mse_norm = float(np.mean(sol.fun ** 2))
    params = (tuning.W1, tuning.b1, tuning.W2, tuning.b2)

    def mse_units(Xi: np.ndarray, Ti: np.ndarray, Bi: Any) -> list[float]:
        out, _ = forward_pass(params, (Xi - in_mean) / in_scale)
        return (np.mean((Bi + out * out_scale + out_mean - Ti) ** 2, axis=0)).tolist()

    truth = valid["x"][1:]
    rmse = lambda a, b: np.sqrt(np.mean((a - b) ** 2, axis=(0, 1))).tolist()  # noqa: E731
    diagnostics = {
        "structure": {"inputs": nin, "exogenous_inputs": n + plant.q, "hidden": hidden,
                      "outputs": n, "output_delays": delays, "input_delays": 0,
                      "hidden_activation": "tanh", "output_activation": "linear",
                      "parameters": int(sol.x.size)},
        "training": {"seed": seed, "runs": runs, "validation_runs": validation_runs,
                     "steps": steps, "samples": int(len(T)), "target": target,
                     "input_range": np.asarray(plant.input_limits if input_range is None
                                               else input_range, dtype=float).tolist(),
                     "hold": list(hold), "sim_substeps": sim_substeps,
                     "excitation": excitation,
                     "setpoint_range": (None if setpoint_range is None
                                        else np.asarray(setpoint_range, dtype=float).tolist()),
                     "prbs_amplitude": float(prbs_amplitude), "prbs_hold": list(prbs_hold),
                     "time_limit": time_limit,
                     "noise_std": (np.sqrt(np.diag(ekf_tuning.R)) if noise_std is None
                                   else np.asarray(noise_std, dtype=float)).tolist(),
                     "algorithm": "Levenberg-Marquardt on J'J + mu I (MATLAB trainlm)",
                     "restarts": restarts, "max_iter": max_iter, "max_fail": max_fail,
                     "iterations": int(sol.nit), "mu": float(sol.mu),
                     "stopped": str(sol.message),
                     "selection": "restart with the smallest closed-loop RMSE on the validation "
                                  "runs (against the training target)",
                     "candidates": candidates},
        "fit": {"mse_standardised": mse_norm, "mse_train": mse_units(X_in, T, base),
                "mse_validation_open_loop": mse_units(Xv_in, Tv, base_v)},
        "closed_loop_validation": {"rmse_vs_true": rmse(closed, truth),
                                   "rmse_vs_ekf": rmse(closed, valid["x_ekf"]),
                                   "ekf_rmse_vs_true": rmse(valid["x_ekf"], truth)},
    }
    return NARXTraining(tuning, X_in, T, diagnostics)
