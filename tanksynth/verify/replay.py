"""Replay: every estimator, observer and detector artefact run on logged data, as on the rig.

`tanksynth replay DIR --data FILE...` feeds each logged experiment
(`tanksynth.measurements.Experiment`: inputs held between samples, outputs sampled) to what an
artefact ships, rebuilt by its method's campaign runner (the method table's ``campaign``
column: the same runtime estimator, observer or residual observer that verification and the
campaigns run; nothing is re-implemented here). At sample ``k`` the estimator gets
``(y_k, u_{k-1})`` (``u_{-1} = u_0``), exactly as the simulator feeds it.

Per artefact and experiment:

* the estimate trajectory ``x_hat(k)``;
* the one-step output prediction ``y(k|k-1) = h(F(x_hat(k-1), u_{k-1}))`` with the estimator's
  own sampled model when it has one (Kalman-type filters), else the plant's Runge-Kutta model,
  and the output prediction error (the innovation) ``y_k - y(k|k-1)``;
* where the estimator carries a covariance ``P`` and noise covariances ``Q``, ``R``: the
  innovation covariance ``S = H (Phi P Phi' + Q) H' + R`` (exact for the Kalman and extended
  Kalman filters, the linearised one for the unscented filter) and the normalised innovation
  squared ``NIS_k = nu_k' S_k^-1 nu_k`` (chi-square with ``p`` degrees of freedom under the
  filter's own assumptions); and, where the log has reference states, the normalised estimation
  error squared ``NEES_k = e_k' P_k^-1 e_k`` (``n`` degrees of freedom);
* for a fault detector: the residual ``max_j |y_j - h_j(x_hat)|`` of its residual observer
  against the stored threshold, and the alarms (times and count).

A sample that is missing (NaN) or censored (at a sensor limit) is not a measurement; the
estimator's update skips it. The Kalman, extended Kalman and unscented filters run the same step
with only the observed outputs in the correction
(`tanksynth.runtime.estimators.base.KernelEstimator.step_observed`: with nothing observed the
step is the prediction, state and covariance); the other estimators are fed their own prediction
``y(k|k-1)`` for that output, so their correction from it is zero. Such samples count in no
statistic and their number is reported.

Checks (each explained in its own ``detail`` line; statistics start after the warm-up
`tanksynth.sim.metrics.ESTIMATION_WARMUP` of the samples):

``nis_mean``
    Time-averaged NIS inside the two-sided 95 % chi-square band for the ``D = sum p_k`` degrees
    of freedom (innovations consistent with the filter's covariance).
``nis_exceedance``
    Fraction of samples whose NIS exceeds the 95 % chi-square quantile of its ``p_k`` degrees of
    freedom within 3 binomial standard deviations of 5 %.
``prediction_rmse``
    Output prediction RMSE of each output at most the predicted innovation standard deviation
    ``sqrt(mean S_jj)`` times ``sqrt(chi2_0.975(N_j) / N_j)`` (the 97.5 % quantile of a mean of
    ``N_j`` squared standard normal innovations).
``nees_mean``
    Only with reference states: time-averaged NEES inside its 95 % chi-square band.
``finite``, ``in_range``, ``prediction_fit``
    Observers without covariance: the estimate stays finite and inside the plant's state bounds
    (no divergence), and the one-step output prediction error of each output is smaller than the
    output's own spread about its mean (NRMSE fit above 0 %: better than a constant).
``alarms``
    Detectors: the alarms with their times (information, not a pass/fail: whether the logged
    run had a fault is not known; an alarm on a run the user knows is fault-free is a warning).

`write_replay` writes ``DIR/replay.json`` (schema ``tanksynth.replay/1``) and one trace per
artefact and experiment ``DIR/replay/<artefact>__<experiment>.npz``
(`tanksynth.artefacts.traces.write_trace`, bounded, atomic); `read_replay` reads it back
bounded for the report.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import casadi as ca
import numpy as np
from scipy import stats

from tanksynth.analysis.checks import Check
from tanksynth.artefacts.atomic import atomic_write
from tanksynth.artefacts.io import file_sha256, read_limited, to_jsonable
from tanksynth.artefacts.jsontext import dumps
from tanksynth.artefacts.traces import TRACE_MAX_SAMPLES, read_trace, write_trace
from tanksynth.errors import ArtefactError, DataError, SpecError, TanksynthError
from tanksynth.measurements import Experiment
from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.base import CovarianceKernelEstimator, KernelEstimator
from tanksynth.runtime.estimators.horizon import horizon_backend
from tanksynth.runtime.estimators.model import DiscreteModel, discrete_model
from tanksynth.sim.metrics import warmup_samples
from tanksynth.sim.simulate import EstimatorAdapter
from tanksynth.spec import Spec
from tanksynth.verify.common import sampling_period
from tanksynth.verify.fault.verdicts import ResidualObserver

__all__ = ["SCHEMA", "REPLAY_FILE", "TRACE_DIR", "TRACE_STEM", "MAX_REPLAY_BYTES", "Replay",
           "trace_stem", "replay_estimator", "replay_detector", "replay_artefacts", "check_experiment", "write_replay", "read_replay",
           "replay_line"]

#: Schema of ``DIR/replay.json``.
SCHEMA = "tanksynth.replay/1"
#: The replay's record in a result directory.
REPLAY_FILE = "replay.json"
#: Sub-directory of the replay traces.
TRACE_DIR = "replay"
#: Longest experiment name kept as written in a trace file name (characters).
TRACE_STEM = 64
_PLAIN = re.compile(r"[A-Za-z0-9._-]+")
#: Largest ``replay.json`` read (bytes).
MAX_REPLAY_BYTES = 16 * 1024 ** 2
#: Relative tolerance between the log's sampling period and the artefact's.
PERIOD_RTOL = 1e-6
#: Substeps of the plant's Runge-Kutta model when the estimator has no sampled model of its own.
PREDICTION_SUBSTEPS = 4
#: Binomial standard deviations allowed around 5 % for the NIS exceedance fraction.
EXCEEDANCE_SIGMAS = 3.0


@dataclass(frozen=True, eq=False)
class Replay:
    """One artefact replayed on one logged experiment.

    Attributes
    ----------
    artefact, method : str
        The artefact's name and design method.
    kind : str
        ``"estimator"`` (with a covariance), ``"observer"`` (without) or ``"detector"``.
    experiment : Experiment
        The log.
    checks : tuple of Check
        The verdicts on the data (``data`` holds ``value`` and ``bound``/``band``).
    summary : dict
        Statistics (JSON-friendly): samples, skipped (missing, censored), RMSE per output (output
        units), NIS/NEES means, alarms.
    x_hat : ndarray, shape (N, n)
        Estimates (state units).
    y_pred : ndarray, shape (N, p)
        One-step output predictions of the logged outputs (output units).
    nis : ndarray, shape (N,)
        NIS per sample (dimensionless; NaN where not computed: no covariance, nothing observed).
    residual, threshold : ndarray, shape (N,) or None
        Detectors: residual ``max_j |y_j - h_j(x_hat)|`` and threshold (output units).
    y_names, y_units : tuple of str
        Names and units of the plant's outputs (the columns of ``y_pred``).
    artefact_sha256 : str
        The artefact's ``provenance.content_sha256`` (the report marks a replay of an artefact
        designed again since as stale).
    """

    artefact: str
    method: str
    kind: str
    experiment: Experiment
    checks: tuple[Check, ...]
    summary: dict
    x_hat: np.ndarray
    y_pred: np.ndarray
    nis: np.ndarray
    residual: np.ndarray | None = field(default=None)
    threshold: np.ndarray | None = field(default=None)
    y_names: tuple[str, ...] = field(default=())
    y_units: tuple[str, ...] = field(default=())
    artefact_sha256: str = field(default="")

    @property
    def passed(self) -> bool | None:
        """False when a check fails, True when one passes and none fails, None when all are info."""
        decided = [c.passed for c in self.checks if c.passed is not None]
        if not decided:
            return None
        return all(decided)

    @property
    def trace_name(self) -> str:
        """The trace file's name in ``DIR/replay/``: ``<artefact>__<experiment>.npz``, the
        experiment's name (a file stem: any characters, any length) kept when it is short and
        plain, else shortened and made unique by a digest of it (a file name the file system
        takes, one per experiment)."""
        return f"{self.artefact}__{trace_stem(self.experiment.name)}.npz"


def trace_stem(name: str) -> str:
    """``name`` as part of a trace file name: unchanged when it is at most `TRACE_STEM` plain
    characters (letters, digits, ``._-``, no leading dot, no ``__``), else its first plain
    characters and 12 hex digits of its sha256.

    Parameters
    ----------
    name : str
        An experiment's name (its file's stem).

    Returns
    -------
    str
    """
    if len(name) <= TRACE_STEM and _PLAIN.fullmatch(name) and "__" not in name \
            and not name.startswith("."):
        return name
    head = re.sub(r"[^A-Za-z0-9_-]+", "_", name)[:TRACE_STEM - 13].strip("_") or "log"
    return f"{head}-{hashlib.sha256(name.encode('utf-8', 'surrogatepass')).hexdigest()[:12]}"


# ----------------------------------------------------------------------------- data checks
def check_experiment(plant: Plant, experiment: Experiment, period: float, artefact: str) -> None:
    """Refuse a log an artefact cannot run on: signals missing, another sampling period.

    Parameters
    ----------
    plant : Plant
        The artefact's plant.
    experiment : Experiment
        The log.
    period : float
        The artefact's sampling period (s).
    artefact : str
        Its name (for the message).

    Raises
    ------
    DataError
        A plant input or output the log lacks (named), a non-uniform log, or a sampling period
        other than the artefact's (both named); key ``--data``, source the file.
    """
    lacking = [name for name in _names(plant.inputs) if name not in experiment.input_names]
    lacking += [name for name in _names(plant.outputs) if name not in experiment.output_names]
    if lacking:
        raise DataError(f"artefact '{artefact}' needs the plant signal(s) {', '.join(lacking)}, "
                        f"which the log does not have (it has {', '.join(experiment.input_names + experiment.output_names)})",
                        key="--data", source=experiment.source)
    dt = experiment.uniform_period
    if dt is None:
        raise DataError("the log's samples are not equally spaced; an estimator runs at one "
                        f"sampling period (artefact '{artefact}': {period:g} s)", key="--data",
                        source=experiment.source)
    if not math.isclose(dt, period, rel_tol=PERIOD_RTOL):
        raise DataError(f"the log is sampled every {dt:g} s, artefact '{artefact}' runs every "
                        f"{period:g} s; resample the log to {period:g} s (or design at {dt:g} s)",
                        key="--data", source=experiment.source)


def _digest(doc: Mapping[str, Any]) -> str:
    prov = doc.get("provenance")
    return str(prov.get("content_sha256", "")) if isinstance(prov, Mapping) else ""


def _names(signals: Sequence[Any]) -> list[str]:
    return [s.name for s in signals]


def _columns(plant: Plant, experiment: Experiment) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inputs (N, m) and outputs (N, q) in the plant's order, and the mask of usable samples."""
    iu = [experiment.input_names.index(name) for name in _names(plant.inputs)]
    iy = [experiment.output_names.index(name) for name in _names(plant.outputs)]
    U = np.asarray(experiment.u, dtype=float)[:, iu]
    Y = np.asarray(experiment.y, dtype=float)[:, iy]
    usable = np.asarray(experiment.observed, dtype=bool)[:, iy]
    return U, Y, usable


def _skipped(plant: Plant, experiment: Experiment) -> dict[str, int]:
    iy = [experiment.output_names.index(name) for name in _names(plant.outputs)]
    missing = np.isnan(np.asarray(experiment.y, dtype=float)[:, iy])
    censored = (np.asarray(experiment.censored_low)[:, iy] | np.asarray(experiment.censored_high)[:, iy]) & ~missing
    return {"missing": int(missing.sum()), "censored": int(censored.sum()),
            "samples_not_updated": int((missing | censored).any(axis=1).sum())}


# ----------------------------------------------------------------------------- prediction
class _Predictor:
    """``x, u -> (y(k|k-1), Phi, H)`` of a sampled model (one CasADi function)."""

    def __init__(self, model: DiscreteModel):
        x = ca.SX.sym("x", model.n)
        u = ca.SX.sym("u", model.m)
        xp = model.predict_sx(x, u)
        self.fn = ca.Function("replay_prediction", [x, u],
                              [model.output_sx(xp), model.transition_jacobian_sx(x, u),
                               model.output_jacobian_sx(xp)])

    def __call__(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        yp, Phi, H = self.fn(x, u)
        return (np.asarray(yp, dtype=float).reshape(-1), np.asarray(Phi, dtype=float),
                np.asarray(H, dtype=float))


def _runtime(est: Any) -> Any:
    """The runtime estimator behind a plain `EstimatorAdapter` (a one-run twin), else None."""
    if type(est) is EstimatorAdapter:
        return est.template.batch(1)
    return None


def _noise(rt: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """``(Q, R)`` of a Kalman-type runtime estimator with a covariance, else None."""
    if rt is None or not hasattr(rt, "covariance"):
        return None
    tuning = getattr(rt, "tuning", None)
    R = getattr(tuning, "R", None)
    Q = getattr(rt, "Q", None) if hasattr(type(rt), "Q") else getattr(tuning, "Q", None)
    if Q is None or R is None:
        return None
    return np.asarray(Q, dtype=float), np.asarray(R, dtype=float)


def _replay_horizon(rt: Any, predict: _Predictor, noise: tuple[np.ndarray, np.ndarray] | None,
                    x0: np.ndarray, U: np.ndarray, Y: np.ndarray, usable: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None] | None:
    """``(x_hat, y(k|k-1), S, P)`` of the replay loop through the estimator's horizon kernel.

    The same numbers as stepping (`KernelEstimator.run_states`; the predictions and ``S`` from
    the states, all samples at once). None (the caller steps) for estimators without a kernel,
    for a log with missing or censored values when the estimator cannot leave outputs out of a
    step (it is fed its own prediction, which depends on the estimate), on any failure (the
    stepping loop names the step), and with ``TANKSYNTH_ESTIMATOR_BACKEND=step`` (or
    ``TANKSYNTH_SIM_BACKEND=numpy``: the stepping loop as before horizon kernels).
    """
    if (horizon_backend() == "step" or not isinstance(rt, KernelEstimator) or not isinstance(rt.model, DiscreteModel)
            or (noise is not None and not isinstance(rt, CovarianceKernelEstimator))):
        return None
    partial = not usable.all()
    N, n = Y.shape[0], rt.n
    if N < 2 or (partial and not rt.noise_in_parameters):
        return None
    U_prev = np.concatenate([U[:1], U[:-1]])
    rt.reset(x0)
    state0 = rt.state
    try:
        states = rt.run_states(np.where(usable, Y, 0.0)[:, None, :], U_prev[:, None, :],
                               usable if partial else None)[:, 0]
    except (TanksynthError, FloatingPointError, np.linalg.LinAlgError):
        return None
    X = np.ascontiguousarray(states[:, :n])
    before = np.concatenate([state0, states[:-1]])
    yp, Phi, H = predict.fn.map(N)(before[:, :n].T, U_prev.T)
    Yp = np.asarray(yp, dtype=float).T.copy()
    if noise is None or not isinstance(rt, CovarianceKernelEstimator):
        return X, Yp, np.full((N, rt.q, rt.q), np.nan), None
    Phi = np.asarray(Phi, dtype=float).reshape(n, N, n).transpose(1, 0, 2)
    H = np.asarray(H, dtype=float).reshape(rt.q, N, n).transpose(1, 0, 2)
    P = rt.covariance_of(before)
    Q, R = noise[0].reshape(n, n), noise[1]
    S = H @ (Phi @ P @ Phi.swapaxes(1, 2) + Q) @ H.swapaxes(1, 2) + R
    return X, Yp, S, np.ascontiguousarray(rt.covariance_of(states))


def _chi2_band(dof: int) -> tuple[float, float]:
    return float(stats.chi2.ppf(0.025, dof)), float(stats.chi2.ppf(0.975, dof))


def _window(N: int) -> slice:
    return slice(warmup_samples(N), N)


# ----------------------------------------------------------------------------- estimators
def replay_estimator(doc: Mapping[str, Any], spec: Spec, run: Any, experiment: Experiment) -> Replay:
    """Run an estimator or observer artefact on a log (see the module notes).

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
        The spec it was designed from.
    run : EstimatorRun
        Its method's campaign run (``estimator``, ``x_hat0``, ``x_op``).
    experiment : Experiment
        The log, checked by `check_experiment`.

    Returns
    -------
    Replay
    """
    plant = spec.plant
    name, method = str(doc["name"]), str(doc["method"])
    ts = sampling_period(spec)
    check_experiment(plant, experiment, ts, name)
    U, Y, usable = _columns(plant, experiment)
    N, n, q = Y.shape[0], plant.n, plant.q
    est = run.estimator
    rt = _runtime(est)
    own = getattr(rt, "model", None)
    model = own if isinstance(own, DiscreteModel) else discrete_model(plant, ts, substeps=PREDICTION_SUBSTEPS)
    predict = _Predictor(model)
    noise = _noise(rt)
    x0 = np.asarray(run.x_hat0 if run.x_hat0 is not None else run.x_op, dtype=float).reshape(1, n)
    stepper = rt if rt is not None else est
    subset = bool(getattr(rt, "noise_in_parameters", False))
    fast = _replay_horizon(rt, predict, noise, x0, U, Y, usable)
    stepper.reset(x0)
    X = np.empty((N, n))
    Yp = np.full((N, q), np.nan)
    S_all = np.full((N, q, q), np.nan)
    P_all = np.full((N, n, n), np.nan) if noise is not None else None
    x_prev = x0[0]
    failure = None
    k = 0
    if fast is not None:
        X, Yp, S_all, P_all = fast
    try:
        for k in range(N if fast is None else 0):
            u_prev = U[k - 1] if k else U[0]
            yp, Phi, H = predict(x_prev, u_prev)
            Yp[k] = yp
            if noise is not None:
                P = np.asarray(rt.covariance, dtype=float).reshape(n, n)
                Q, R = noise[0].reshape(n, n), noise[1]
                S_all[k] = H @ (Phi @ P @ Phi.T + Q) @ H.T + R
            y = np.where(usable[k], Y[k], yp)
            if subset and not usable[k].all():   # the correction of the observed outputs only
                xh = np.asarray(rt.step_observed(y[None, :], u_prev[None, :], usable[k]), dtype=float)
            else:
                xh = np.asarray(stepper.step(y[None, :], u_prev[None, :]), dtype=float)
            xh = xh.reshape(n)
            X[k] = xh
            if P_all is not None:
                P_all[k] = np.asarray(rt.covariance, dtype=float).reshape(n, n)
            x_prev = xh
    except (TanksynthError, FloatingPointError, np.linalg.LinAlgError) as exc:
        failure = f"step {k}: {' '.join(str(exc).split())}"
        X[k:] = np.nan
    kind = "estimator" if noise is not None else "observer"
    nu = np.where(usable, Y - Yp, np.nan)
    win = _window(N)
    checks: list[Check] = []
    summary: dict[str, Any] = {"samples": N, "warmup": win.start, **_skipped(plant, experiment),
                               "rmse": {}, "fit_percent": {}}
    if failure is not None:
        checks.append(Check("finite", False, f"the estimator failed at {failure}: no estimate "
                                             "from there on", {"step": k}))
    for j, out in enumerate(_names(plant.outputs)):
        e = nu[win, j]
        e = e[np.isfinite(e)]
        summary["rmse"][out] = float(np.sqrt(np.mean(e ** 2))) if e.size else None
    nis = np.full(N, np.nan)
    if noise is not None and failure is None:
        checks += _covariance_checks(plant, nu, S_all, usable, win, nis, summary)
        if experiment.x_ref is not None and P_all is not None:
            checks += _nees_check(plant, experiment, X, P_all, win, summary)
    elif failure is None:
        checks += _observer_checks(plant, X, Y, nu, usable, win, summary)
    return Replay(name, method, kind, experiment, tuple(checks), summary, X, Yp, nis,
                  y_names=tuple(_names(plant.outputs)), y_units=tuple(o.unit for o in plant.outputs),
                  artefact_sha256=_digest(doc))


def _covariance_checks(plant: Plant, nu: np.ndarray, S: np.ndarray, usable: np.ndarray, win: slice,
                       nis: np.ndarray, summary: dict) -> list[Check]:
    """NIS mean and exceedance, prediction RMSE against the predicted innovation spread."""
    N = nu.shape[0]
    dofs = np.zeros(N, dtype=int)
    for k in range(win.start, N):
        obs = usable[k]
        if not obs.any():
            continue
        e = nu[k, obs]
        Sk = S[k][np.ix_(obs, obs)]
        nis[k] = float(e @ np.linalg.solve(Sk, e))
        dofs[k] = int(obs.sum())
    counted = dofs > 0
    D = int(dofs.sum())
    checks = []
    if D == 0:
        return [Check("nis_mean", None, "no measured sample after the warm-up: no NIS")]
    total = float(np.nansum(nis[counted]))
    lo, hi = _chi2_band(D)
    samples = int(counted.sum())
    mean = total / samples
    per = D / samples
    checks.append(Check(
        "nis_mean", lo <= total <= hi,
        f"time-averaged NIS {mean:.3g} over {samples} samples, 95 % chi-square band "
        f"[{lo / samples:.3g}, {hi / samples:.3g}] for {D} degrees of freedom (mean {per:.3g} "
        "expected): the innovations are " + ("consistent with" if lo <= total <= hi else
                                              ("larger than" if total > hi else "smaller than"))
        + " the filter's covariance",
        {"value": mean, "band": [lo / samples, hi / samples], "dof": D, "samples": samples}))
    q95 = stats.chi2.ppf(0.95, dofs[counted])
    frac = float(np.mean(nis[counted] > q95))
    tol = EXCEEDANCE_SIGMAS * math.sqrt(0.05 * 0.95 / samples)
    ok = abs(frac - 0.05) <= tol
    checks.append(Check(
        "nis_exceedance", ok,
        f"{100 * frac:.1f} % of the samples have an NIS above its 95 % chi-square quantile, "
        f"expected 5 % +- {100 * tol:.1f} % (3 binomial standard deviations for {samples} samples)",
        {"value": frac, "band": [max(0.0, 0.05 - tol), 0.05 + tol], "samples": samples}))
    summary["nis_mean"] = mean
    summary["nis_band"] = [lo / samples, hi / samples]
    summary["nis_exceedance"] = frac
    summary["dof"] = D
    rows, fails = [], []
    data: dict[str, Any] = {"value": {}, "bound": {}}
    for j, out in enumerate(_names(plant.outputs)):
        mask = usable[win, j] & np.isfinite(nu[win, j])
        Nj = int(mask.sum())
        if not Nj:
            continue
        rmse = float(np.sqrt(np.mean(nu[win, j][mask] ** 2)))
        sigma = float(np.sqrt(np.mean(S[win, j, j][mask])))
        bound = sigma * math.sqrt(float(stats.chi2.ppf(0.975, Nj)) / Nj)
        data["value"][out] = rmse
        data["bound"][out] = bound
        rows.append(f"{out} {rmse:.3g} <= {bound:.3g}" if rmse <= bound else f"{out} {rmse:.3g} > {bound:.3g}")
        if rmse > bound:
            fails.append(out)
    unit = plant.outputs[0].unit if plant.outputs else ""
    checks.append(Check(
        "prediction_rmse", not fails,
        f"one-step output prediction RMSE ({unit}) at most the predicted innovation standard "
        "deviation (root of the mean innovation variance) times the root of q/N, q the 97.5 % "
        "chi-square quantile of N degrees of freedom (N samples): " + "; ".join(rows), data))
    return checks


def _nees_check(plant: Plant, experiment: Experiment, X: np.ndarray, P: np.ndarray, win: slice,
                summary: dict) -> list[Check]:
    """Time-averaged NEES against logged reference states, in its 95 % chi-square band."""
    ref = np.asarray(experiment.x_ref, dtype=float)
    N, n = X.shape
    values = []
    for k in range(win.start, N):
        if not np.isfinite(ref[k]).all():
            continue
        e = X[k] - ref[k]
        values.append(float(e @ np.linalg.solve(P[k], e)))
    if not values:
        return [Check("nees_mean", None, "no complete reference state after the warm-up: no NEES")]
    samples = len(values)
    D = samples * n
    lo, hi = _chi2_band(D)
    total = float(np.sum(values))
    mean = total / samples
    summary["nees_mean"] = mean
    ok = lo <= total <= hi
    return [Check("nees_mean", ok,
                  f"time-averaged NEES {mean:.3g} against the logged reference states over {samples} "
                  f"samples, 95 % chi-square band [{lo / samples:.3g}, {hi / samples:.3g}] ({D} "
                  "degrees of freedom): the estimation error is "
                  + ("consistent with" if ok else ("larger than" if total > hi else "smaller than"))
                  + " the filter's covariance",
                  {"value": mean, "band": [lo / samples, hi / samples], "dof": D, "samples": samples})]


def _observer_checks(plant: Plant, X: np.ndarray, Y: np.ndarray, nu: np.ndarray, usable: np.ndarray,
                     win: slice, summary: dict) -> list[Check]:
    """No divergence (finite, inside the plant's state bounds) and a useful output prediction."""
    lo, hi = plant.state_bounds()
    Xw = X[win]
    finite = bool(np.isfinite(Xw).all())
    below = Xw < lo - 1e-12
    above = Xw > hi + 1e-12
    outside = int((below | above).any(axis=1).sum())
    checks = [Check("finite", finite, "every estimate is finite" if finite else
                    "the estimate became non-finite (diverged)"),
              Check("in_range", outside == 0,
                    f"the estimate stays inside the plant's state bounds (levels in [0, hmax]) at every "
                    f"sample after the warm-up" if outside == 0 else
                    f"the estimate leaves the plant's state bounds at {outside} of {Xw.shape[0]} samples "
                    "after the warm-up (diverging or far off the data)", {"value": outside, "bound": 0})]
    rows, fails = [], []
    data: dict[str, Any] = {"value": {}, "bound": {}}
    for j, out in enumerate(_names(plant.outputs)):
        mask = usable[win, j] & np.isfinite(nu[win, j])
        if mask.sum() < 2:
            continue
        rmse = float(np.sqrt(np.mean(nu[win, j][mask] ** 2)))
        spread = float(np.std(Y[win, j][mask]))
        fit = 100.0 * (1.0 - rmse / spread) if spread > 0 else float("-inf")
        summary["fit_percent"][out] = fit
        data["value"][out] = rmse
        data["bound"][out] = spread
        rows.append(f"{out} {rmse:.3g} {'<' if rmse < spread else '>='} {spread:.3g} (fit {fit:.0f} %)")
        if not rmse < spread:
            fails.append(out)
    checks.append(Check("prediction_fit", not fails,
                        "one-step output prediction RMSE below the output's standard deviation about "
                        "its mean (the observer predicts the data better than a constant): "
                        + "; ".join(rows), data))
    return checks


# ----------------------------------------------------------------------------- detectors
def replay_detector(doc: Mapping[str, Any], spec: Spec, run: Any, experiment: Experiment) -> Replay:
    """Run a fault detector's residual test on a log: residual, threshold, alarms.

    The residual observer (`tanksynth.verify.fault.verdicts.ResidualObserver`, the artefact's
    ``Psi``, continuous time) is integrated over each logged period; it starts at the spec's
    operating point, and the threshold's time starts with the log.

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
        The spec it was designed from.
    run : DetectorRun
        Its method's campaign run (``Psi``, ``threshold``, ``x_op``).
    experiment : Experiment
        The log.

    Returns
    -------
    Replay
    """
    plant = spec.plant
    name, method = str(doc["name"]), str(doc["method"])
    dt = experiment.uniform_period
    period = float(spec.ts) if spec.ts else (dt if dt is not None else 1.0)
    check_experiment(plant, experiment, period, name)
    U, Y, usable = _columns(plant, experiment)
    N, n, q = Y.shape[0], plant.n, plant.q
    obs = ResidualObserver(plant, run.Psi, period)
    obs.reset(np.asarray(run.x_op, dtype=float).reshape(1, n))
    X = np.empty((N, n))
    Yp = np.empty((N, q))
    x_prev = np.asarray(run.x_op, dtype=float).reshape(1, n)
    for k in range(N):
        u_prev = U[k - 1] if k else U[0]
        held = obs.output(x_prev).reshape(q)
        y = np.where(usable[k], Y[k], held)
        x_prev = np.asarray(obs.step(y[None, :], u_prev[None, :]), dtype=float).reshape(1, n)
        X[k] = x_prev[0]
        Yp[k] = obs.output(x_prev).reshape(q)
    r = np.where(usable, np.abs(Y - Yp), 0.0).max(axis=1)
    t = np.asarray(experiment.t, dtype=float)
    thr = run.threshold(t - t[0])
    alarm = r > thr
    times = [float(v) for v in t[alarm]]
    shown = ", ".join(f"{v:g}" for v in times[:8]) + (", ..." if len(times) > 8 else "")
    detail = (f"no alarm in {N} samples (residual max {float(r.max()):.3g} against a threshold down to "
              f"{float(thr.min()):.3g})" if not times else
              f"{len(times)} alarm(s), first at t = {times[0]:g} s (times: {shown}); on a run known to be "
              "fault-free this is a false alarm")
    summary = {"samples": N, **_skipped(plant, experiment), "alarms": len(times),
               "alarm_times": times[:1000], "first_alarm": times[0] if times else None,
               "residual_max": float(r.max())}
    checks = (Check("alarms", None, detail, {"value": len(times), "times": times[:1000]}),)
    return Replay(name, method, "detector", experiment, checks, summary, X, Yp, np.full(N, np.nan),
                  r, thr, tuple(_names(plant.outputs)), tuple(o.unit for o in plant.outputs), _digest(doc))


# ----------------------------------------------------------------------------- all artefacts
def replay_artefacts(spec: Spec, docs: Sequence[Mapping[str, Any]], experiments: Sequence[Experiment],
                     runners: Mapping[str, Callable[..., Any]]) -> list[Replay]:
    """Replay every estimator, observer and detector artefact on every experiment.

    Controllers and models are left out (nothing to replay open loop).

    Parameters
    ----------
    spec : Spec
        The result directory's spec.
    docs : sequence of mapping
        Its artefacts (gains as arrays).
    experiments : sequence of Experiment
        The logs.
    runners : mapping of str to callable
        The method table's campaign runners (``tanksynth.methods.RUNNERS``).

    Returns
    -------
    list of Replay
        Artefact-major, in the order given.

    Raises
    ------
    SpecError
        No artefact to replay, or a log an artefact cannot run on (`check_experiment`).
    ArtefactError
        An artefact's method has no runner.
    """
    out = []
    for doc in docs:
        method = str(doc["method"])
        runner = runners.get(method)
        if runner is None:
            raise ArtefactError(f"artefact '{doc['name']}': method {method!r} has no runner")
        run = runner(doc, spec)
        if run.kind == "estimator":
            out += [replay_estimator(doc, spec, run, e) for e in experiments]
        elif run.kind == "detector":
            out += [replay_detector(doc, spec, run, e) for e in experiments]
    if not out:
        raise SpecError("no estimator, observer or detector artefact to replay (controllers and "
                        "models are not replayed)", key="replay")
    return out


def replay_line(r: Replay) -> str:
    """One line: artefact on experiment, verdict, the main numbers.

    Parameters
    ----------
    r : Replay
        A replay.
    """
    s = r.summary
    verdict = {True: "pass", False: "FAIL", None: "info"}[r.passed]
    parts = [f"{r.artefact} ({r.method}) on {r.experiment.name}: {verdict}"]
    if "nis_mean" in s:
        lo, hi = s["nis_band"]
        parts.append(f"NIS {s['nis_mean']:.3g} in [{lo:.3g}, {hi:.3g}]")
        parts.append(f"{100 * s['nis_exceedance']:.1f} % above q95")
    if "nees_mean" in s:
        parts.append(f"NEES {s['nees_mean']:.3g}")
    rmse = {k: v for k, v in s.get("rmse", {}).items() if v is not None}
    if rmse:
        units = dict(zip(r.y_names, r.y_units))
        parts.append("RMSE " + ", ".join(
            f"{k} {v:.3g}" + (f" {units[k]}" if units.get(k) not in (None, "", "1", "-") else "")
            for k, v in rmse.items()))
    if r.kind == "detector":
        parts.append(f"{s['alarms']} alarm(s)" + (f", first at {s['first_alarm']:g} s" if s["alarms"] else ""))
    if s.get("samples_not_updated"):
        parts.append(f"{s['samples_not_updated']} samples with outputs left out of the update "
                     f"({s['missing']} missing and {s['censored']} censored output values)")
    failed = [c.name for c in r.checks if c.passed is False]
    if failed:
        parts.append("failed: " + ", ".join(failed))
    return " · ".join(parts)


# ----------------------------------------------------------------------------- files
def _stride(N: int) -> int:
    return max(1, -(-N // TRACE_MAX_SAMPLES))


def _trace(r: Replay) -> dict:
    e = r.experiment
    columns = [e.output_names.index(name) for name in r.y_names]
    s = _stride(e.samples)
    arrays: dict[str, Any] = {"t": np.asarray(e.t, float)[::s], "x": r.x_hat[::s],
                              "y": np.asarray(e.y, float)[:, columns][::s], "y_pred": r.y_pred[::s], "nis": r.nis[::s]}
    if r.residual is not None and r.threshold is not None:
        arrays["residual"] = r.residual[::s]
        arrays["threshold"] = r.threshold[::s]
    header = {"artefact": r.artefact, "method": r.method, "kind": r.kind, "experiment": e.name,
              "stride": s, "y_names": list(r.y_names), "y_units": list(r.y_units), "passed": r.passed}
    return {"header": header, "arrays": arrays}


def _entry(r: Replay, trace_sha: str) -> dict:
    return {"artefact": r.artefact, "method": r.method, "kind": r.kind, "experiment": r.experiment.name,
            "artefact_sha256": r.artefact_sha256,
            "passed": r.passed, "checks": [c.as_dict() for c in r.checks], "summary": r.summary,
            "line": replay_line(r), "trace": {"file": f"{TRACE_DIR}/{r.trace_name}", "sha256": trace_sha}}


def write_replay(directory: str | Path, replays: Sequence[Replay],
                 files: Sequence[str | Path] = ()) -> Path:
    """Write ``DIR/replay.json`` and the traces ``DIR/replay/<artefact>__<experiment>.npz``.

    Each file is written atomically; traces of an earlier replay not written again are removed.
    The caller holds the directory's lock.

    Parameters
    ----------
    directory : str or Path
        The result directory.
    replays : sequence of Replay
        What `replay_artefacts` returned.
    files : sequence of path
        The data files read (their sha256 is recorded).

    Returns
    -------
    Path
        ``DIR/replay.json``.
    """
    directory = Path(directory)
    tdir = directory / TRACE_DIR
    tdir.mkdir(exist_ok=True)
    written = set()
    entries = []
    for r in replays:
        path = write_trace(tdir / r.trace_name, _trace(r))
        written.add(path.name)
        entries.append(_entry(r, file_sha256(path)))
    for old in tdir.glob("*.npz"):
        if old.name not in written:
            old.unlink(missing_ok=True)
    decided = [r.passed for r in replays if r.passed is not None]
    experiments = {r.experiment.name: r.experiment for r in replays}
    by_source = {str(Path(f)): f for f in files}
    doc = {"schema": SCHEMA, "passed": all(decided) if decided else None,
           "files": [{"name": e.name, "source": e.source, "samples": e.samples,
                      "sha256": file_sha256(by_source[e.source]) if e.source in by_source else None}
                     for e in experiments.values()],
           "replays": entries}
    return atomic_write(directory / REPLAY_FILE, dumps(to_jsonable(doc)) + "\n")


def read_replay(directory: str | Path) -> dict | None:
    """``DIR/replay.json`` read bounded (`MAX_REPLAY_BYTES`), with each entry's trace when it
    matches its recorded sha256; None when the directory has no replay.

    Parameters
    ----------
    directory : str or Path
        A result directory.

    Returns
    -------
    dict or None
        The document; each entry of ``replays`` gains ``"trace_data"`` (`read_trace`'s dict, or
        None when the file is missing or differs).

    Raises
    ------
    ArtefactError
        The file is not a replay record (bad JSON, other schema).
    """
    path = Path(directory) / REPLAY_FILE
    if not path.exists():
        return None
    try:
        doc = json.loads(read_limited(path, MAX_REPLAY_BYTES).decode("utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise ArtefactError(f"{path}: not a replay record ({' '.join(str(exc).split())[:120]})") from None
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA or not isinstance(doc.get("replays"), list):
        raise ArtefactError(f"{path}: not a replay record (schema {SCHEMA!r} expected)")
    for entry in doc["replays"]:
        if not isinstance(entry, dict):
            raise ArtefactError(f"{path}: a replay entry is not a table")
        given = entry.get("trace")
        trace: dict = given if isinstance(given, dict) else {}
        rel = str(trace.get("file", ""))
        target = Path(directory) / rel
        ok = rel.startswith(TRACE_DIR + "/") and ".." not in Path(rel).parts and target.is_file()
        try:
            entry["trace_data"] = read_trace(target, str(trace.get("sha256"))) if ok else None
        except ArtefactError:
            entry["trace_data"] = None
    return doc
