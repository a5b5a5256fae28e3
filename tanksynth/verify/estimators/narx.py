"""The NARX estimator as the verify stage sees it: its network from the stored weights, its
tuning rebuilt from the artefact, and fresh EKF data drawn by the verdict itself.

Used by the ``narx`` verdict (`tanksynth.verify.estimators.verdicts.narx_verdict`) and its
campaign runner (`tanksynth.verify.estimators.campaign.narx_run`).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.kalman import ExtendedKalmanFilter, KalmanTuning
from tanksynth.runtime.estimators.narx import NARXTuning
from tanksynth.sim.excitation import designed_excitation
from tanksynth.sim.simulate import simulate_inputs
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, option

__all__ = ["fresh_ekf_data", "NARX_FIT_FACTOR", "NARX_FRESH_DRAW", "narx_network",
           "narx_tuning", "teacher_forced_inputs", "steady_state_noise_floor"]


#: Fresh one-step fit error allowed, as a multiple of the training fit error.
NARX_FIT_FACTOR = 3.0
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


def narx_tuning(doc: Mapping[str, Any], spec: Spec, ts: float) -> NARXTuning:
    """The NARX estimator an artefact ships: its stored weights, normalisation and delays.

    Parameters
    ----------
    doc : mapping
        The artefact (gains ``W1``, ``b1``, ``W2``, ``b2``, ``in_mean``, ``in_scale``,
        ``out_mean``, ``out_scale``, ``x_hat0``, ``delays``).
    spec : Spec
        The validated spec (options ``substeps``, ``clip``).
    ts : float
        Sampling period [s].
    """
    n = spec.plant.n

    def g(key: str) -> np.ndarray:
        return np.asarray(artefact_gain(doc, key), dtype=float)

    W1 = np.atleast_2d(g("W1"))
    H = W1.shape[0]
    return NARXTuning(W1, g("b1").reshape(H), np.atleast_2d(g("W2")).reshape(n, H),
                      g("b2").reshape(n), g("in_mean").reshape(-1), g("in_scale").reshape(-1),
                      g("out_mean").reshape(n), g("out_scale").reshape(n), x0=g("x_hat0").reshape(n),
                      ts=ts, delays=int(round(float(np.ravel(g("delays"))[0]))),
                      substeps=int(option(doc, spec, "substeps", 1)),
                      clip=bool(option(doc, spec, "clip", False)))


def fresh_ekf_data(plant: Plant, ekf_tuning: KalmanTuning, *, runs: int, steps: int, seed: int,
                   input_range: Any = None, hold: Any = (30, 150), noise_std: Any = None,
                   sim_substeps: int = 10, excitation: str = "random", setpoint_range: Any = None,
                   prbs_amplitude: float = 0.0, prbs_hold: Any = (3, 20)) -> dict[str, np.ndarray]:
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
    excitation : {"random", "designed"}
        ``designed``: `tanksynth.sim.excitation.designed_excitation` (set-point steps in
        ``setpoint_range`` held ``hold`` samples, PRBS ``prbs_amplitude`` held ``prbs_hold``)
        instead of the random levels above.
    setpoint_range : array_like (2,) or None
        Set-point range of the designed excitation (state units, m).
    prbs_amplitude : float
        PRBS amplitude of the designed excitation (input units, m^3/s).
    prbs_hold : (int, int)
        PRBS hold range of the designed excitation (samples).

    Returns
    -------
    dict
        ``x`` (steps + 1, runs, n), ``u`` (steps, runs, m), ``y`` (steps, runs, q),
        ``x_ekf`` and ``prior`` (steps, runs, n), ``innovation`` (steps, runs, q).
    """
    rng = np.random.default_rng(seed)
    ranges = np.asarray(plant.input_limits if input_range is None else input_range,
                        dtype=float).reshape(plant.m, 2)
    low, high = int(hold[0]), int(hold[1])
    if excitation == "designed":
        X0, U = designed_excitation(plant, rng, steps=steps, runs=runs,
                                    setpoint_range=setpoint_range, hold=(low, high),
                                    prbs_amplitude=float(prbs_amplitude),
                                    prbs_hold=(int(prbs_hold[0]), int(prbs_hold[1])))
    else:
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


def steady_state_noise_floor(plant: Plant, spec: Spec, ekf_tuning: KalmanTuning) -> float:
    """RMS standard deviation of the steady-state Kalman posterior at the operating point.

    ``sqrt(mean diag P)`` with ``P = P- - P- C' (C P- C' + R)^-1 C P-`` and ``P-`` the
    solution of the discrete Riccati equation of the linearisation at the spec's operating
    point (``Ad = expm(A ts)``, the stored ``Q``, ``R``): what the best linear estimator's
    error settles to under the declared noise. NaN when the Riccati equation has no
    stabilising solution.

    Parameters
    ----------
    plant : Plant
    spec : Spec
        The validated spec (operating point, sampling period).
    ekf_tuning : KalmanTuning
        ``Q`` (state units^2), ``R`` (output units^2), ``ts`` (s).

    Returns
    -------
    float
        State units (m for levels).
    """
    import scipy.linalg

    from tanksynth.analysis.linearize import equilibrium_input

    x = np.asarray(spec.x0, dtype=float)
    u = np.asarray(spec.given_u0, dtype=float) if spec.given_u0 is not None else \
        equilibrium_input(plant, x).u0
    A = np.asarray(plant.compiled.jacobians(x[None], u[None])[0], dtype=float)[0]
    step = 1e-7 * np.maximum(1.0, np.abs(x))      # central differences of the output map
    C = np.column_stack([(np.asarray(plant.compiled.output((x + e)[None]), dtype=float)[0]
                          - np.asarray(plant.compiled.output((x - e)[None]), dtype=float)[0])
                         / (2 * e[i]) for i, e in enumerate(np.diag(step))])
    Ad = scipy.linalg.expm(A * ekf_tuning.ts)
    try:
        Pm = scipy.linalg.solve_discrete_are(Ad.T, C.T, ekf_tuning.Q, ekf_tuning.R)
    except (np.linalg.LinAlgError, ValueError):
        return float("nan")
    S = C @ Pm @ C.T + ekf_tuning.R
    P = Pm - Pm @ C.T @ np.linalg.solve(S, C @ Pm)
    return float(np.sqrt(np.mean(np.diag(P))))
