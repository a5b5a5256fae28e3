"""Simulations of the verdicts on the nonlinear plant, and the time constants that size them.

The rules (horizons, perturbations, tolerances) are those listed in
`tanksynth.verify.common`; every check states its rule and numbers in its
detail. Each simulation takes an optional `TraceRecorder` (keyword
``trace``) that keeps the verdict's main simulation for the report.
"""

from __future__ import annotations

import math
import os
import platform
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.analysis.lmi_region import region_from_parts
from tanksynth.errors import TanksynthError
from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.luenberger import LuenbergerObserver, LuenbergerTuning
from tanksynth.sim.closed_loop import LoopLaw
from tanksynth.sim.simulate import BatchEstimator, EstimatorAdapter, run_seeds, simulate
from tanksynth.spec import Spec
from tanksynth.spec.options import parse_poles, parse_region
from tanksynth.verify.common import (MAX_STEPS, NUMERIC_ERRORS, OBSERVER_TIME_CONSTANTS, OBSERVER_TOLERANCE,
                                     PERTURBATION, SERVO_TIME_CONSTANTS, SERVO_TOLERANCE,
                                     discrete_ts, fmt_signals, option, output_at, required_ts)
from tanksynth.verify.traces import TraceRecorder

__all__ = [
    "requested_poles",
    "slowest_time_constant", "fastest_rate", "eigen_time_constant", "region_time_constant",
    "designed_time_constant", "eigenvector_conditioning", "observer_period", "perturbed_start",
    "observer_convergence", "luenberger_estimator", "StateFeedback", "IntegralStateFeedback",
    "servo_check", "regulation_check", "machine_description", "single_run_step_time",
]


# ===================================================================== time constants
def slowest_time_constant(eigs: np.ndarray, domain: str, ts: float | None) -> float:
    """Slowest time constant (s) of stable eigenvalues; inf if not stable.

    ``1 / min |Re lambda|`` in continuous time, ``-ts / ln max |lambda|`` in
    discrete time (``ts`` in s).

    Parameters
    ----------
    eigs, domain, ts : ndarray of complex, str, float or None
        Eigenvalues (1/s; discrete: dimensionless), time domain, sampling period [s].
    """
    eigs = np.asarray(eigs, dtype=complex)
    if domain == "discrete":
        rho = float(np.max(np.abs(eigs)))
        if not rho < 1:
            return math.inf
        if rho == 0:
            return required_ts(ts)
        return float(-required_ts(ts) / math.log(rho))
    slow = float(np.min(-eigs.real))
    return 1.0 / slow if slow > 0 else math.inf


def fastest_rate(eigs: np.ndarray, domain: str, ts: float | None) -> float:
    """Fastest rate (1/s): ``max |lambda|`` in continuous time, ``1 / ts`` in discrete time.

    Parameters
    ----------
    eigs, domain, ts : ndarray of complex, str, float or None
        Eigenvalues (1/s; discrete: dimensionless), time domain, sampling period [s].
    """
    eigs = np.asarray(eigs, dtype=complex)
    if domain == "discrete":
        return 1.0 / required_ts(ts)
    return float(np.max(np.abs(eigs)))


def eigen_time_constant(eigs: np.ndarray, domain: str, ts: float | None) -> tuple[float, str]:
    """`slowest_time_constant` (s) of ``eigs`` and the rule, in words, that gave it.

    Parameters
    ----------
    eigs, domain, ts : ndarray of complex, str, float or None
        Eigenvalues (1/s; discrete: dimensionless), time domain, sampling period [s].
    """
    tau = slowest_time_constant(eigs, domain, ts)
    if domain == "discrete":
        rule = f"(-ts / ln max|lambda|, max|lambda| = {np.max(np.abs(eigs)):.6g})"
    else:
        rule = f"(1 / min|Re lambda|, min|Re lambda| = {np.min(-np.asarray(eigs).real):.6g} 1/s)"
    return tau, rule


def region_time_constant(region: Any, domain: str, ts: float | None) -> float:
    """Slowest time constant (s) an LMI region guarantees (inf when it bounds no decay).

    Parameters
    ----------
    region, domain, ts : LMIRegion, str, float or None
        The LMI region, time domain, sampling period [s].
    """
    best = math.inf
    for part in region.parts:
        if domain == "continuous":
            rate = part[1] if part[0] == "half_plane" else (-(part[1] + part[2]) if part[0] == "disk"
                                                            else 0.0)
            if rate > 0:
                best = min(best, 1.0 / rate)
        elif part[0] == "disk" and abs(part[1]) + part[2] < 1:
            rho = abs(part[1]) + part[2]
            best = min(best, required_ts(ts) if rho == 0 else -required_ts(ts) / math.log(rho))
    return best


def requested_poles(doc: Mapping[str, Any], spec: Spec, domain: str) -> np.ndarray | None:
    """The spec's poles in the design's plane (None when the spec gives none).

    ``pole_domain = "s"`` in discrete time is converted here, independently of
    the design, by ``z = exp(p ts)``.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    domain : {"continuous", "discrete"}
        The design's time domain.

    Returns
    -------
    ndarray of complex or None
        Poles in 1/s (continuous) or in the z-plane (discrete, dimensionless).
    """
    poles = option(doc, spec, "poles")
    if poles is None:
        return None
    given = option(doc, spec, "pole_domain")
    values = np.asarray(parse_poles(poles, "poles"), dtype=complex)
    if given == "s" and domain == "discrete":
        values = np.exp(values * discrete_ts(spec))
    return values


def designed_time_constant(doc: Mapping[str, Any], spec: Spec, eigs: np.ndarray, domain: str,
                           ts: float | None) -> tuple[float, str]:
    """Slowest time constant (s) the DESIGN asks for, and the rule that gave it.

    Of the poles requested in the spec (option ``poles``), else of the decay
    the spec's LMI region guarantees (option ``region``), else of the
    stored gain's matrix (``eigs``).

    Parameters
    ----------
    doc, spec, eigs : mapping, Spec, ndarray of complex
        The artefact, the validated spec, the stored gain's eigenvalues (1/s; discrete: dimensionless).
    domain, ts : str, float or None
        ``"continuous"`` or ``"discrete"``; sampling period [s].
    """
    p = requested_poles(doc, spec, domain)
    if p is not None:
        tau, rule = eigen_time_constant(p, domain, ts)
        return tau, rule.replace("(", "(of the poles requested in the spec: ", 1)
    raw = option(doc, spec, "region")
    if raw is not None:
        region = region_from_parts(parse_region(raw, "region"))
        tau = region_time_constant(region, domain, ts)
        if np.isfinite(tau):
            return tau, f"(the decay guaranteed by the spec's region {region.describe()})"
    tau, rule = eigen_time_constant(eigs, domain, ts)
    return tau, rule.replace("(", "(of the stored gain's matrix: ", 1)


def eigenvector_conditioning(M: np.ndarray) -> float:
    """Condition number of the eigenvector matrix of ``M`` (inf if defective).

    Parameters
    ----------
    M : ndarray, shape (n, n)
        A square matrix.
    """
    _, V = np.linalg.eig(M)
    with np.errstate(all="ignore"):
        value = float(np.linalg.cond(V))
    return value if np.isfinite(value) else math.inf


def observer_period(domain: str, spec_ts: float | None, tau: float) -> float:
    """Sampling period (s) of an observer simulation: ``ts`` (discrete), else ``min(ts, tau / 20)``.

    Parameters
    ----------
    domain, spec_ts, tau : str, float or None, float
        Time domain, the spec's sampling period [s], the observer's time constant [s].
    """
    if domain == "discrete":
        return required_ts(spec_ts)
    step = tau / 20.0
    return float(min(spec_ts, step)) if spec_ts else float(step)


def _horizon(tau: float, ts: float, conditioning: float) -> tuple[float, float, float, int, int]:
    """``(kappa, factor, H, k_H, steps)`` of the rule ``H = tau (5 + ln kappa)`` on ``[H, 1.2 H]``."""
    kappa = float(min(max(conditioning, 1.0), 1e8)) if np.isfinite(conditioning) else 1e8
    factor = OBSERVER_TIME_CONSTANTS + math.log(kappa)
    horizon = factor * tau
    k_h = max(int(math.ceil(horizon / ts)), 1)
    steps = max(int(math.ceil(1.2 * horizon / ts)), k_h + 1)
    return kappa, factor, horizon, k_h, steps


# ========================================================================== observers
def perturbed_start(plant: Plant, x0: np.ndarray, inside: Callable[[np.ndarray], bool] | None = None
                    ) -> tuple[np.ndarray, float]:
    """``x0 + delta`` in the region (and ``inside``), delta = 5 % of the span, alternating signs.

    Parameters
    ----------
    plant, x0, inside : Plant, ndarray (n,), callable or None
        The plant, operating point (state units, m), extra admissibility test of a start.

    Returns
    -------
    x : ndarray
        The start (state units).
    fraction : float
        ``|delta_i|`` as a fraction of the region span (scaled down from
        `PERTURBATION` until the start lies in the region).

    Raises
    ------
    TanksynthError
        No such start lies in the region (and ``inside``).
    """
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    span = hi - lo
    span = np.where(np.isfinite(span) & (span > 0), span, np.maximum(np.abs(x0), 1.0))
    n = x0.size
    base = PERTURBATION * span
    patterns = [np.array([1.0 if (i + k) % 2 == 0 else -1.0 for i in range(n)]) for k in range(2)]
    patterns += [np.ones(n), -np.ones(n)]
    patterns += [np.array([1.0 if i == j else 0.0 for i in range(n)]) for j in range(min(n, 8))]
    for scale in (1.0, 0.5, 0.25, 0.1):
        for sgn in patterns:
            x = x0 + scale * base * sgn
            if np.all(x >= lo) and np.all(x <= hi) and not plant.region.violations(x, plant.x) \
                    and (inside is None or inside(x)):
                return x, scale * PERTURBATION
    raise TanksynthError("no perturbed start x0 + delta (delta up to 5 % of the region span) lies in "
                         "the operating region" + (" and the TS domain" if inside else ""))


def observer_convergence(plant: Plant, estimator: BatchEstimator, x0: np.ndarray, u0: np.ndarray,
                         tau: float, ts: float, *, conditioning: float = 1.0,
                         inside: Callable[[np.ndarray], bool] | None = None,
                         rule: str = "", substeps: int = 4, name: str = "observer_convergence",
                         outside: Callable[[np.ndarray], np.ndarray] | None = None,
                         trace: TraceRecorder | None = None,
                         start: tuple[np.ndarray, np.ndarray] | None = None) -> Check:
    """Estimation error of an observer on the nonlinear plant, started away from it.

    The plant starts at ``x0 + delta`` (see `PERTURBATION`) and holds the
    input ``u0``; the estimate starts at ``x0``. With ``H = tau (5 + ln
    kappa)`` (``kappa`` the condition number of the error matrix's
    eigenvectors: ``|e(t)| <= kappa exp(-t / tau) |e(0)|`` for the linear
    error dynamics, so a non-normal, peaking observer gets the time its
    transient needs) the check passes if ``|x_hat - x|_inf <= 5 %`` of the
    initial error at every sample of ``[H, 1.2 H]``.

    Parameters
    ----------
    plant : Plant
    estimator : BatchEstimator
    x0, u0 : ndarray
        Operating point (state units) and input (input units).
    tau : float
        Slowest designed error time constant (s).
    ts : float
        Sampling period of the simulation (s).
    conditioning : float
        Condition number ``kappa`` of the eigenvector matrix of the designed
        error dynamics (>= 1; capped at 1e8).
    inside : callable, optional
        Extra condition on the plant's start (e.g. the TS domain).
    rule : str
        How ``tau`` was obtained (for the detail).
    substeps : int
        RK4 steps per period for the plant.
    name : str
        Name of the check.
    outside : callable, optional
        ``outside(X) -> bool array`` on estimates (N, n): samples reported
        as outside the observer's validity domain (e.g. the TS domain).
    trace : TraceRecorder, optional
        Records this simulation.
    start : tuple of ndarray, optional
        Declared ``(x_start, x_hat_start)`` (state units): the plant starts at
        ``x_start`` and the estimate at ``x_hat_start`` instead of ``x0 + delta``
        and ``x0``.

    Returns
    -------
    Check
    """
    if not np.isfinite(tau) or tau <= 0:
        return Check(name, False, f"no finite error time constant (tau = {tau}): the designed error "
                                  "dynamics are not stable, nothing to converge")
    kappa, factor, horizon, k_h, steps = _horizon(tau, ts, conditioning)
    if steps > MAX_STEPS:
        return Check(name, None, f"not simulated: the horizon {horizon:.3g} s needs {steps} samples "
                                 f"of {ts:.3g} s (> {MAX_STEPS})")
    if start is None:
        x_start, frac = perturbed_start(plant, x0, inside)
        x_hat_start = np.asarray(x0, dtype=float)
        how = f"plant from x0 + delta ({100 * frac:g} % of the region span), estimate from x0"
    else:
        x_start, x_hat_start = (np.asarray(v, dtype=float) for v in start)
        how = (f"plant from the declared initial state {np.round(x_start, 6).tolist()}, estimate "
               f"from the declared initial estimate {np.round(x_hat_start, 6).tolist()}")
    res = simulate(plant, ts=ts, steps=steps, x0=x_start, seeds=run_seeds(0, 1), estimator=estimator,
                   x_hat0=x_hat_start, u_init=u0, substeps=substeps)
    if trace is not None:
        trace.record(res, plant, check=name, estimator=True,
                     scenario=("initial-state mismatch: plant from x0 + delta, estimate from x0, "
                               "equilibrium input held") if start is None else
                     "declared initial state and initial estimate, equilibrium input held")
    err = np.max(np.abs(res.x_hat[0] - res.x[0]), axis=1)
    e0 = float(err[0])
    tail = float(np.max(err[k_h:]))
    tol = OBSERVER_TOLERANCE * e0
    ok = bool(np.all(np.isfinite(err)) and tail <= tol)
    where = ""
    if outside is not None:
        out = np.asarray(outside(res.x_hat[0]), dtype=bool)
        where = (f"; the estimate is outside the domain at {int(out.sum())} of {out.size} samples"
                 + (f" (first at t = {float(res.t[np.argmax(out)]):.4g} s)" if out.any() else ""))
    return Check(name, ok,
                 f"{how}, equilibrium input held, nonlinear plant sampled every {ts:.4g} s: |e|_inf = "
                 f"{e0:.3g} at t = 0, largest on [H, 1.2 H] = {tail:.3g} (tolerance {tol:.3g} = "
                 f"{100 * OBSERVER_TOLERANCE:g} % of |e(0)|); rule H = tau ({OBSERVER_TIME_CONSTANTS:g} "
                 f"+ ln kappa) = {factor:.3g} tau = {horizon:.4g} s with kappa = {kappa:.3g} (eigenvector "
                 f"conditioning of the error matrix), tau = {tau:.4g} s {rule}".rstrip() + where,
                 {"e0": e0, "tail_max": tail, "tolerance": tol, "horizon_s": horizon, "tau_s": tau,
                  "kappa": kappa, "ts": ts, "x_start": x_start.tolist(),
                  "x_hat_start": x_hat_start.tolist(), "error_inf": err.tolist(),
                  "estimator_time_s": float(res.timing.get("estimator", 0.0))
                  / max(int(res.timing.get("calls", 0)), 1),
                  "machine": machine_description()})


def single_run_step_time(estimator: Any, Y: np.ndarray, U: np.ndarray, warmup: int = 5) -> float:
    """Wall-clock time of one estimator step on one run, median over a sequence (s).

    The first ``warmup`` steps (kernel loading, caches) are not counted.

    Parameters
    ----------
    estimator : tanksynth.runtime.estimators.base.Estimator
        A single-run estimator (its ``step(y, u)``).
    Y : ndarray, shape (N, q)
        Measurements (output units).
    U : ndarray, shape (N, m)
        Inputs held before each measurement (input units).
    warmup : int
        Steps run before the timing.

    Returns
    -------
    float
        Median step time (s); NaN when a step fails or fewer than ``warmup + 1`` samples.
    """
    times = []
    try:
        with np.errstate(all="ignore"):
            for k in range(len(Y)):
                t0 = time.perf_counter()
                estimator.step(Y[k], U[k])
                if k >= warmup:
                    times.append(time.perf_counter() - t0)
    except NUMERIC_ERRORS:
        return float("nan")
    return float(np.median(times)) if times else float("nan")


def machine_description() -> str:
    """One line naming the machine a timing was measured on (CPU model, cores, Python).

    Returns
    -------
    str
        E.g. ``"Intel(R) Xeon(R) CPU @ 2.20GHz, 2 cores, Linux x86_64, Python 3.11.7"``.
    """
    cpu = ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            cpu = next((ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), "")
    except OSError:
        pass
    return (f"{cpu or platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
            f"{platform.system()} {platform.machine()}, Python {platform.python_version()}")


def luenberger_estimator(plant: Plant, L: np.ndarray, x0: np.ndarray, u0: np.ndarray, ts: float,
                         form: str) -> EstimatorAdapter:
    """The runtime's Luenberger observer on the model linearised at ``(x0, u0)``.

    `tanksynth.runtime.estimators.luenberger.LuenbergerObserver` (the one
    implementation), wrapped by `EstimatorAdapter`: ``form = "predictor"``
    (error matrix ``Ad - L C``, discrete designs), ``"current"`` (``(I - L
    C) Ad``) or ``"continuous"`` (``F - L C``, integrated exactly over each
    period with the input and the sampled measurement held).

    Parameters
    ----------
    plant : Plant
    L : ndarray, shape (n, q)
    x0, u0 : ndarray
        Operating point and its equilibrium input (state and input units).
    ts : float
        Sampling period (s).
    form : {"predictor", "current", "continuous"}

    Returns
    -------
    EstimatorAdapter
    """
    tuning = LuenbergerTuning(L=np.asarray(L, dtype=float), x0=np.asarray(x0, dtype=float),
                              ts=float(ts), form=form, operating_point=(x0, u0))
    return EstimatorAdapter(LuenbergerObserver(plant, tuning))


# ====================================================================== control loops
@dataclass
class StateFeedback:
    """``u = u0 - K (x - x0)`` (a `ControlLaw`; the regulation check).

    Attributes
    ----------
    K : ndarray, shape (m, n)
    x0, u0 : ndarray
        Operating point (state units) and its input (input units).
    """

    K: np.ndarray
    x0: np.ndarray
    u0: np.ndarray

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m) from the state (M, n) (each run's numbers independent of M: einsum)."""
        return self.u0 - np.einsum("ij,kj->ik", x_hat - self.x0, self.K)

    def loop_law(self, runs: int) -> LoopLaw:
        """The law for the closed-loop kernel (`tanksynth.sim.closed_loop`), no state of its own.

        The products summed in ``j`` order as ``einsum`` sums them.

        Parameters
        ----------
        runs : int
            Number of runs M.
        """
        import casadi as ca

        K = np.atleast_2d(np.asarray(self.K, dtype=float))
        x0 = np.asarray(self.x0, dtype=float).reshape(-1)
        u0 = np.asarray(self.u0, dtype=float).reshape(-1)
        key = (K.tobytes(), K.shape, x0.tobytes(), u0.tobytes())
        held = self.__dict__.get("_loop_fn")
        if held is not None and held[0] == key:
            return LoopLaw(held[1], np.zeros((int(runs), 0)))
        x, z, r = ca.SX.sym("x", K.shape[1]), ca.SX.sym("z", 0), ca.SX.sym("r", 0)
        d = [x[j] - x0[j] for j in range(K.shape[1])]
        u = ca.vertcat(*[u0[i] - _dot(K[i], d) for i in range(K.shape[0])])
        fn = ca.Function("state_feedback", [x, z, r], [u, z])
        self.__dict__["_loop_fn"] = (key, fn)
        return LoopLaw(fn, np.zeros((int(runs), 0)))

    def affine(self, steps: int, ts: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The law as ``u_k = b_k - K (x_k - x0)``: ``(b (steps, m), K, x0)`` (`tanksynth.sim.affine`).

        Parameters
        ----------
        steps : int
            Number of periods N.
        ts : float
            Sampling period (s; not used: the law does not depend on time).
        """
        u0 = np.asarray(self.u0, dtype=float).reshape(-1)
        return (np.tile(u0, (int(steps), 1)), np.asarray(self.K, dtype=float),
                np.asarray(self.x0, dtype=float))


@dataclass
class IntegralStateFeedback:
    """``u = u0 - K1 (x - x0) - K2 z``, ``z(k+1) = z(k) + ts (r(k) - y0 - C1 (x(k) - x0))`` (a `ControlLaw`).

    The law of a state feedback designed on the plant augmented with the
    integral of the tracking error (`integral_augmentation`), in deviation
    variables, one integrator state per run. The integrators integrate the
    error of the measured outputs ``y = h(x)`` linearised at ``x0``, offsets and
    sensor gains included (``y0 = h(x0)``), so the loop settles with the
    outputs, not the states, at their references.

    Attributes
    ----------
    K1 : ndarray, shape (m, n)
    K2 : ndarray, shape (m, p)
    C1 : ndarray, shape (p, n)
        Rows of the tracked outputs.
    x0, u0 : ndarray
        Operating point (state and input units).
    ts : float
        Sampling period (s).
    z : ndarray, shape (M, p)
        Integrator states, one row per run (output units times s; set by `reset`).
    y0 : ndarray, shape (p,), optional
        The tracked outputs at ``x0``, ``h(x0)`` (output units); None: ``C1 x0``
        (an output map linear in the state, without offset).
    """

    K1: np.ndarray
    K2: np.ndarray
    C1: np.ndarray
    x0: np.ndarray
    u0: np.ndarray
    ts: float
    z: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    y0: np.ndarray | None = None

    def reset(self, runs: int) -> None:
        """Zero the integrators of ``runs`` runs.

        Parameters
        ----------
        runs : int
            Number of runs M.
        """
        self.z = np.zeros((int(runs), self.C1.shape[0]))

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m) from the state (M, n) and the reference (M, p)."""
        # einsum, not @: BLAS rounds a row differently with the batch size, and a run must give
        # the same numbers alone or in any campaign chunk
        u = (self.u0 - np.einsum("ij,kj->ik", x_hat - self.x0, self.K1)
             - np.einsum("ij,kj->ik", self.z, self.K2))
        err = reference - np.einsum("ij,kj->ik", x_hat, self.C1)
        if self.y0 is not None:   # y_r - y0 - C1 (x - x0) = y_r - C1 x - (y0 - C1 x0)
            d = (np.asarray(self.y0, dtype=float).reshape(-1)
                 - np.asarray(self.C1, dtype=float) @ np.asarray(self.x0, dtype=float).reshape(-1))
            if np.any(d != 0):
                err = err - d
        self.z = self.z + self.ts * err
        return u

    def loop_law(self, runs: int) -> LoopLaw | None:
        """The law for the closed-loop kernel (`tanksynth.sim.closed_loop`), from the current ``z``.

        The products summed in ``j`` order as ``einsum`` sums them.

        Parameters
        ----------
        runs : int
            Number of runs M.

        Returns
        -------
        LoopLaw or None
            None when ``z`` does not have one row per run (`reset` not called).
        """
        import casadi as ca

        K1, K2 = np.atleast_2d(self.K1).astype(float), np.atleast_2d(self.K2).astype(float)
        C1 = np.atleast_2d(np.asarray(self.C1, dtype=float))
        x0 = np.asarray(self.x0, dtype=float).reshape(-1)
        u0 = np.asarray(self.u0, dtype=float).reshape(-1)
        m, n = K1.shape
        p = C1.shape[0]
        if self.z.shape != (int(runs), p):
            return None

        def commit(zf: np.ndarray) -> None:
            self.z = np.array(zf, dtype=float)

        y0 = None if self.y0 is None else np.asarray(self.y0, dtype=float).reshape(-1)
        key = tuple(a.tobytes() for a in (K1, K2, C1, x0, u0)) + (K1.shape, C1.shape, float(self.ts),
                                                                 None if y0 is None else y0.tobytes())
        held = self.__dict__.get("_loop_fn")
        if held is not None and held[0] == key:
            return LoopLaw(held[1], np.array(self.z, dtype=float), commit)
        x, z, r = ca.SX.sym("x", n), ca.SX.sym("z", p), ca.SX.sym("r", p)
        d = [x[j] - x0[j] for j in range(n)]
        zs = [z[j] for j in range(p)]
        u = ca.vertcat(*[(u0[i] - _dot(K1[i], d)) - _dot(K2[i], zs) for i in range(m)])
        err = [r[i] - _dot(C1[i], [x[j] for j in range(n)]) for i in range(p)]
        if y0 is not None:
            off = y0 - C1 @ x0
            if np.any(off != 0):
                err = [e - off[i] for i, e in enumerate(err)]
        z_next = ca.vertcat(*[zs[i] + self.ts * err[i] for i in range(p)])
        fn = ca.Function("integral_state_feedback", [x, z, r], [u, z_next])
        self.__dict__["_loop_fn"] = (key, fn)
        return LoopLaw(fn, np.array(self.z, dtype=float), commit)


def _dot(row: np.ndarray, terms: Sequence[Any]) -> Any:
    """``sum_j row[j] terms[j]`` summed in ``j`` order (CasADi), as ``einsum`` sums it."""
    acc = terms[0] * row[0]
    for j in range(1, len(terms)):
        acc = acc + terms[j] * row[j]
    return acc


def servo_check(plant: Plant, controller: Callable, x0: np.ndarray, u0: np.ndarray,
                out_idx: Sequence[int], tau: float, ts: float, substeps: int = 4,
                rule: str = "", *, trace: TraceRecorder | None = None) -> list[Check]:
    """``servo_tracking`` and ``bounded_inputs``: step the tracked set-points by 5 %.

    Horizon `SERVO_TIME_CONSTANTS` ``tau`` (s); the tracking error over the
    last 10 % of the samples must be <= `SERVO_TOLERANCE` of the step and
    the inputs must settle strictly inside the actuator range.

    Parameters
    ----------
    plant, controller, x0, u0 : Plant, callable, ndarray (n,), ndarray (m,)
        The plant, the control law, operating point (m) and input (m^3/s).
    out_idx, tau, ts, substeps : sequence of int, float, float, int
        Tracked outputs, time constant [s], sampling period [s], RK4 steps per period.
    rule, trace : str, TraceRecorder or None
        The rule that gave ``tau``; recorder of the simulated runs.
    """
    if not np.isfinite(tau) or tau <= 0:
        return [Check("servo_tracking", False, f"the closed loop has no finite time constant "
                                               f"(tau = {tau}): not stable")]
    y0 = output_at(plant, x0)[list(out_idx)]
    step = PERTURBATION * np.where(np.abs(y0) > 0, np.abs(y0), 1.0)
    k_step = 5
    steps = k_step + max(int(math.ceil(SERVO_TIME_CONSTANTS * tau / ts)), 10)
    if steps > MAX_STEPS:
        return [Check("servo_tracking", None, f"not simulated: {steps} samples of {ts:g} s needed "
                                              f"(> {MAX_STEPS})")]
    ref = np.tile(y0, (steps + 1, 1))
    ref[k_step:] += step
    res = simulate(plant, ts=ts, steps=steps, x0=x0, seeds=run_seeds(0, 1), controller=controller,
                   reference=ref, u_init=u0, substeps=substeps)
    if trace is not None:
        trace.record(res, plant, check="servo_tracking",
                     reference_names=[plant.outputs[i].name for i in out_idx],
                     scenario=f"set-point step of 5 % at t = {k_step * ts:g} s (servo)")
    y = res.y[0][:, list(out_idx)]
    err = ref - y
    window = max(1, (steps + 1) // 10)
    final = float(np.max(np.abs(err[-window:]) / step))
    lim = plant.input_limits
    u = res.u[0]
    lo, hi = lim[:, 0], lim[:, 1]
    tail_u = u[-window:]
    inside = bool(np.all(np.isfinite(u)) and np.all(tail_u > lo) and np.all(tail_u < hi))
    saturated = int(np.sum(np.any((u <= lo) | (u >= hi), axis=1)))
    names = [plant.outputs[i].name for i in out_idx]
    ok = bool(np.all(np.isfinite(err)) and final <= SERVO_TOLERANCE)
    return [Check("servo_tracking", ok,
                  f"set-points of {', '.join(names)} step by {fmt_signals(step, [plant.outputs[i] for i in out_idx])} "
                  f"(5 % of their operating values) at "
                  f"t = {k_step * ts:g} s, nonlinear plant with pump saturation, sampled every "
                  f"{ts:g} s; largest tracking error over the last {window} samples "
                  f"{100 * final:.3g} % of the step (tolerance {100 * SERVO_TOLERANCE:g} %); "
                  f"horizon {SERVO_TIME_CONSTANTS:g} tau = {steps * ts:.4g} s with tau = {tau:.4g} s "
                  f"{rule or '(slowest closed-loop pole)'}",
                  {"step": step.tolist(), "final_relative_error": final, "tau_s": tau, "ts": ts,
                   "steps": steps, "tolerance": SERVO_TOLERANCE}),
            Check("bounded_inputs", inside,
                  f"inputs finite, {saturated} of {steps} samples at an actuator limit, and strictly "
                  f"inside the actuator range {fmt_signals(lim, plant.inputs)} over the last {window} "
                  f"samples (final input {fmt_signals(u[-1], plant.inputs)})",
                  {"saturated_samples": saturated, "final_input": u[-1].tolist()})]


def regulation_check(plant: Plant, K: np.ndarray, x0: np.ndarray, u0: np.ndarray, tau: float,
                     ts: float, conditioning: float = 1.0, rule: str = "", *,
                     trace: TraceRecorder | None = None) -> Check:
    """``regulation``: ``u = u0 - K (x - x0)`` from ``x0 + delta`` back to ``x0``.

    Passes if ``|x - x0|_inf <= 5 %`` of ``|delta|_inf`` on ``[H, 1.2 H]``
    with ``H = tau (5 + ln kappa)`` (s), as for observers.

    Parameters
    ----------
    plant, K, x0, u0 : Plant, ndarray (m, n), ndarray (n,), ndarray (m,)
        The plant, gain (input per state unit), operating point (m) and input (m^3/s).
    tau, ts, conditioning, rule : float, float, float, str
        Time constant [s], sampling period [s], eigenvector conditioning ``kappa``, rule that gave ``tau``.
    trace : TraceRecorder, optional
        Recorder of the simulated runs.
    """
    if not np.isfinite(tau) or tau <= 0:
        return Check("regulation", False, f"the closed loop has no finite time constant (tau = {tau})")
    kappa, factor, horizon, k_h, steps = _horizon(tau, ts, conditioning)
    if steps > MAX_STEPS:
        return Check("regulation", None, f"not simulated: {steps} samples needed (> {MAX_STEPS})")
    x_start, frac = perturbed_start(plant, x0)
    res = simulate(plant, ts=ts, steps=steps, x0=x_start, seeds=run_seeds(0, 1),
                   controller=StateFeedback(K, x0, u0), u_init=u0)
    if trace is not None:
        trace.record(res, plant, check="regulation",
                     scenario="regulation to x0 from x0 + delta, u = u0 - K (x - x0)")
    dev = np.max(np.abs(res.x[0] - x0), axis=1)
    tail = float(np.max(dev[k_h:]))
    tol = OBSERVER_TOLERANCE * float(dev[0])
    return Check("regulation", bool(np.all(np.isfinite(dev)) and tail <= tol),
                 f"u = u0 - K (x - x0) on the nonlinear plant from x0 + delta ({100 * frac:g} % of the "
                 f"region span), sampled every {ts:.4g} s: |x - x0|_inf = {dev[0]:.3g} at t = 0, "
                 f"largest on [H, 1.2 H] = {tail:.3g} (tolerance {tol:.3g} = "
                 f"{100 * OBSERVER_TOLERANCE:g} %); rule H = tau ({OBSERVER_TIME_CONSTANTS:g} + ln kappa) "
                 f"= {factor:.3g} tau = {horizon:.4g} s, kappa = {kappa:.3g} (eigenvector conditioning of "
                 f"the closed loop), tau = {tau:.4g} s {rule or '(slowest closed-loop pole)'}",
                 {"tail_max": tail, "tolerance": tol, "tau_s": tau, "kappa": kappa, "ts": ts})
