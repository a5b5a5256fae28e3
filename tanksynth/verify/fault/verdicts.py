"""Verdict of ``fault_detection`` (residual threshold and detection times).

The scenario the verdict simulates is the one the spec and the artefact
declare, never constants of a particular plant:

initial states
    the design's option ``initial_states`` (list of state vectors, state
    units); else the initial states recorded with the stored detection times
    (``diagnostics.detections[*].x0``); else the rule `rule_initial_states`:
    the operating point, the operating point moved by a quarter of ``hi -
    lo`` with alternating signs (towards the middle of the bounds where the
    move would leave them), and the upper corner ``hi 1`` (the largest
    initial error, where the threshold is tightest). Every start must lie in
    the threshold's bounds ``(lo, hi]``.
input
    the design's option ``input``: a constant (number or one value per
    input) or pieces ``[[t_start, u...], ...]`` (s, input units); else the
    input the design recorded in ``diagnostics.input`` (same forms); else
    the equilibrium input of the spec's operating point, held.
bounds, fault size, fault time
    the design's options ``bounds``, ``delta_bar``, ``t_fault`` and
    ``conservative``; else the values the design recorded beside the
    threshold (``diagnostics.threshold.x_hat0`` / ``e_hat``,
    ``diagnostics.delta_bar``, ...), which `threshold_recheck` ties to the
    stored coefficients.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Mapping, Sequence

import casadi as ca
import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.analysis.linearize import linearize
from tanksynth.artefacts.traces import TRACE_RUNS
from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import rk4_step
from tanksynth.sim.integrate import param_arrays
from tanksynth.sim.simulate import InputSequence, ParameterChange, run_seeds, simulate
from tanksynth.sim.tape import numpy_model
from tanksynth.spec import Spec
from tanksynth.verify.batch_call import BatchCall
from tanksynth.verify.common import (MAX_STEPS, artefact_gain, artefact_matrix, fmt, guard,
                                     operating_point, option, relative_difference)
from tanksynth.verify.traces import Signal, TraceRecorder

__all__ = ["ResidualObserver", "period_function", "FAULT_TS", "FAULT_HORIZON", "FAULT_TIME_TOLERANCE", "FAULT_SLACK", "FAULT_START_OFFSET",
           "FaultScenario", "rule_initial_states", "fault_scenario", "fault_detection_verdict"]

#: Sampling period of the fault-detection simulations (s), at most (the spec's ts if finer).
FAULT_TS = 1e-3
#: Search horizon after the fault onset (s).
FAULT_HORIZON = 3.0
#: Largest difference between a simulated detection time and the stored one (s).
FAULT_TIME_TOLERANCE = 2e-3
#: Healthy residual allowed above the threshold, as a fraction of the threshold after the transient.
FAULT_SLACK = 1e-6
#: Offset of the rule's second initial state from the operating point, as a fraction of ``hi - lo``.
FAULT_START_OFFSET = 0.25


class ResidualObserver:
    """Continuous Luenberger observer of the healthy model, as a `BatchEstimator`.

    ``dx_hat/dt = f(x_hat, u) + Psi (y - h(x_hat))`` with the healthy
    parameters (``delta_bar = 0`` when the plant has a fault size), integrated
    by the toolbox's RK4 (`tanksynth.plants.compile.rk4_step`) over each
    period with ``y`` interpolated linearly between the two latest samples
    (causal) and the input held; records the residual ``y_k - h(x_hat_k)`` of
    every sample. Used by the fault-detection verdict and the detector runs
    of campaigns. One sampling period (all ``substeps`` RK4 steps of every
    run) is one call of a CasADi function built here once from the healthy
    plant's compiled vector field (`period_function`), not 16 numpy calls
    per substep set.

    Parameters
    ----------
    plant : Plant
    Psi : ndarray, shape (n, q)
        Observer gain (1/s).
    ts : float
        Sampling period (s).
    substeps : int
        RK4 steps per period.
    """

    def __init__(self, plant: Plant, Psi: np.ndarray, ts: float, substeps: int = 4):
        healthy = {"delta_bar": 0.0} if "delta_bar" in {p.name for p in plant.parameters} else None
        self.model = numpy_model(plant)
        self.params = param_arrays(plant, healthy, 1)
        self.Psi = np.asarray(Psi, dtype=float)
        self.ts = float(ts)
        self.substeps = int(substeps)
        self.residuals: list[np.ndarray] = []
        self._period = period_function(plant, self.Psi, self.ts, self.substeps, healthy)
        self._maps: dict = {}

    def reset(self, x_hat0: np.ndarray) -> None:
        """Initial estimates (M, n); forgets the recorded residuals.

        Parameters
        ----------
        x_hat0 : ndarray, shape (M, n)
            Initial estimates (state units, m).
        """
        self._x = np.asarray(x_hat0, dtype=float).copy()
        self._y: np.ndarray | None = None
        self.residuals = []

    def output(self, x: np.ndarray) -> np.ndarray:
        """``h(x)`` of the healthy model, (M, n) -> (M, q).

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        """
        x = np.asarray(x, dtype=float)
        return np.asarray(self.model.output(x, self.params), dtype=float).reshape(x.shape[0], -1)

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Measurement (M, q), held input (M, m) -> estimate (M, n).

        Parameters
        ----------
        y, u : ndarray (M, q), ndarray (M, m)
            Measurements (output units, m) and held inputs (input units, m^3/s).
        """
        y = np.asarray(y, dtype=float)
        if self._y is not None:
            M = self._x.shape[0]
            fn = self._maps.get(M)
            if fn is None:
                fn = self._maps[M] = BatchCall(self._period, M)
            self._x = fn(self._x, u, self._y, y.reshape(M, -1))
        self._y = y.copy()
        self.residuals.append(y - self.output(self._x).reshape(y.shape))
        return self._x


def period_function(plant: Plant, Psi: np.ndarray, ts: float, substeps: int,
                    parameters: Mapping[str, float] | None = None) -> Any:
    """One sampling period of the residual observer as a CasADi function.

    ``x_next = period(x_hat, u, y_prev, y)``: ``substeps`` RK4 steps
    (`tanksynth.plants.compile.rk4_step`) of ``dx_hat/dt = f(x_hat, u) +
    Psi (y(t) - h(x_hat))``, ``y(t)`` linear from ``y_prev`` to ``y`` over
    the period and ``u`` held; ``f``, ``h`` the compiled functions of
    ``plant`` with ``parameters`` (e.g. the healthy ``delta_bar = 0``).
    Cached per plant object, parameters, gain, period and substeps.

    Parameters
    ----------
    plant : Plant
    Psi : ndarray, shape (n, q)
        Observer gain (1/s).
    ts : float
        Sampling period (s).
    substeps : int
        RK4 steps per period.
    parameters : mapping of str to float, optional
        Parameter values replacing the plant's (parameter units).

    Returns
    -------
    casadi.Function
        Arguments ``x_hat`` (n, state units), ``u`` (m, input units),
        ``y_prev`` and ``y`` (q, output units); result ``x_hat_next`` (n).
    """
    Psi = np.asarray(Psi, dtype=float).reshape(plant.n, plant.q)
    key = (id(plant), tuple(sorted((parameters or {}).items())), Psi.tobytes(), float(ts), int(substeps))
    hit = _PERIODS.get(key)
    if hit is not None and hit[0] is plant:
        return hit[1]
    comp = (plant.with_parameters(parameters) if parameters else plant).compiled
    f, hfun = comp.f, comp.h
    xh, u = ca.SX.sym("x_hat", plant.n), ca.SX.sym("u", plant.m)
    y0, y1 = ca.SX.sym("y_prev", plant.q), ca.SX.sym("y", plant.q)
    h = float(ts) / int(substeps)
    dy = (y1 - y0) / float(ts)
    P = ca.DM(Psi)
    x = xh
    for j in range(int(substeps)):
        x = rk4_step(lambda v, t: f(v, u) + P @ (y0 + dy * t - hfun(v)), x, h, t=j * h)
    fn = ca.Function("residual_observer_period", [xh, u, y0, y1], [x],
                     ["x_hat", "u", "y_prev", "y"], ["x_hat_next"])
    if len(_PERIODS) >= 16:
        _PERIODS.pop(next(iter(_PERIODS)))
    _PERIODS[key] = (plant, fn)
    return fn


_PERIODS: dict = {}


class _Schedule:
    """Open-loop input: piecewise constant, ``(t_start, u)`` pieces (s, input units)."""

    def __init__(self, pieces: Sequence[tuple[float, np.ndarray]]):
        self.pieces = [(float(t), np.asarray(v, dtype=float)) for t, v in pieces]

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        v = [val for start, val in self.pieces if start <= t + 1e-12][-1]
        return np.tile(v, (x_hat.shape[0], 1))

    def sequence(self, steps: int, ts: float) -> np.ndarray:
        """The inputs of periods ``0 .. steps - 1`` (at ``t = k ts``), (steps, m): the same values
        as the calls, for `tanksynth.sim.simulate.InputSequence`.

        Parameters
        ----------
        steps : int
            Number of periods.
        ts : float
            Sampling period (s).
        """
        t = np.arange(int(steps)) * float(ts)
        out = np.full((int(steps), self.pieces[0][1].size), np.nan)
        set_ = np.zeros(int(steps), dtype=bool)
        for start, val in self.pieces:
            on = start <= t + 1e-12
            out[on] = val
            set_ |= on
        if not set_.all():
            raise IndexError(f"no input piece starts at or before t = {t[~set_][0]:g} s")
        return out


@dataclass(frozen=True, eq=False)
class FaultScenario:
    """What the fault-detection verdict simulates.

    Attributes
    ----------
    lo, hi : float
        Bounds of the initial levels ``lo < x_i(0) <= hi`` (state units); the
        observer starts at ``lo``.
    starts : ndarray, shape (R, n)
        Plant initial states (state units).
    starts_source : str
        Where they come from (for the detail).
    inputs : tuple of (float, ndarray)
        Piecewise-constant input ``(t_start, u)`` (s, input units).
    inputs_source : str
    delta_bar : float
        Fault size (the plant parameter ``delta_bar`` from ``t_fault`` on).
    t_fault : float
        Fault onset (s).
    conservative : bool
        Threshold with every coefficient taken positive (eq. 55) or as stored
        (eq. 54).
    """

    lo: float
    hi: float
    starts: np.ndarray
    starts_source: str
    inputs: tuple
    inputs_source: str
    delta_bar: float
    t_fault: float
    conservative: bool


def rule_initial_states(x_op: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """The documented initial states when the design declares none.

    The operating point; the operating point moved by `FAULT_START_OFFSET`
    ``(hi - lo)`` with alternating signs ``+, -, +, ...`` (a component that
    would leave ``(lo, hi]`` moves the other way); the upper corner ``hi 1``.
    Every component is clipped into ``(lo, hi]`` and duplicates are dropped.

    Parameters
    ----------
    x_op : ndarray, shape (n,)
        Operating point (state units).
    lo, hi : float
        Bounds of the initial levels (state units).

    Returns
    -------
    ndarray, shape (R, n), R <= 3
    """
    x_op = np.asarray(x_op, dtype=float).reshape(-1)
    n = x_op.size
    inside_lo = np.nextafter(lo, math.inf)
    step = FAULT_START_OFFSET * (hi - lo)
    signs = np.array([1.0 if i % 2 == 0 else -1.0 for i in range(n)])
    moved = x_op + signs * step
    leaves = (moved <= lo) | (moved > hi)
    moved = np.where(leaves, x_op - signs * step, moved)
    out: list[np.ndarray] = []
    for x in (x_op, moved, np.full(n, hi)):
        x = np.clip(x, inside_lo, hi)
        if not any(np.array_equal(x, y) for y in out):
            out.append(x)
    return np.array(out)


def _recorded(doc: Mapping[str, Any], key: str) -> Any:
    diag = doc.get("diagnostics") or {}
    return diag.get(key) if isinstance(diag, Mapping) else None


def _bounds(doc: Mapping[str, Any], spec: Spec) -> tuple[float, float, str]:
    raw = option(doc, spec, "bounds")
    if raw is not None:
        lo, hi = (float(v) for v in raw)
        return lo, hi, "the spec's bounds"
    th = _recorded(doc, "threshold")
    try:
        # exact values written as text ("1/4", "15/4")
        lo = float(Fraction(str(th["x_hat0"][0])))
        hi = lo + float(Fraction(str(th["e_hat"][0])))
    except (TypeError, KeyError, IndexError, ValueError, ZeroDivisionError):
        raise ArtefactError(f"artefact '{doc['name']}': the spec declares no bounds and the "
                            "diagnostics record no threshold x_hat0/e_hat") from None
    return lo, hi, "the bounds the design recorded (x_hat0, x_hat0 + e_hat)"


def _number(doc: Mapping[str, Any], spec: Spec, name: str) -> float:
    value = option(doc, spec, name)
    if value is None:
        value = _recorded(doc, name)
    if value is None:
        raise ArtefactError(f"artefact '{doc['name']}': neither the spec nor the diagnostics give "
                            f"{name}")
    return float(value)


def _inputs(doc: Mapping[str, Any], spec: Spec) -> tuple[tuple, str]:
    m = spec.plant.m
    raw, whose = option(doc, spec, "input"), "the spec's"
    if raw is None:
        raw, whose = _recorded(doc, "input"), "the design's recorded"
    if raw is None:
        u0 = operating_point(spec)[1]
        return ((0.0, u0),), f"the equilibrium input {fmt(u0)} of the operating point, held"
    if isinstance(raw, (int, float)) or (isinstance(raw, list) and raw
                                         and all(isinstance(v, (int, float)) for v in raw)):
        u = np.broadcast_to(np.asarray(raw, dtype=float), (m,)).copy()
        return ((0.0, u),), f"{whose} input {fmt(u)}, held"
    pieces = []
    for piece in raw:
        arr = np.asarray(piece, dtype=float).reshape(-1)
        if arr.size != m + 1:
            raise ArtefactError(f"design '{doc['name']}': input piece {piece!r} must be "
                                f"[t_start, u...] with {m} input value(s)")
        pieces.append((float(arr[0]), arr[1:]))
    pieces.sort(key=lambda p: p[0])
    if not pieces or pieces[0][0] > 0:
        raise ArtefactError(f"design '{doc['name']}': the input schedule must start at t = 0")
    text = ", then ".join(f"{fmt(u)} from t = {t:g} s" for t, u in pieces)
    return tuple(pieces), f"{whose} input schedule {text}"


def fault_scenario(doc: Mapping[str, Any], spec: Spec) -> FaultScenario:
    """The scenario of the fault-detection verdict (see the module docstring).

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.

    Raises
    ------
    ArtefactError
        A declared initial state of the wrong size or outside ``(lo, hi]``,
        an input schedule that is not ``[[t_start, u...], ...]`` from 0, or no
        bounds, fault size or fault time declared anywhere.
    """
    n = spec.plant.n
    lo, hi, bounds_source = _bounds(doc, spec)
    if not lo < hi:
        raise ArtefactError(f"artefact '{doc['name']}': bounds [{lo:g}, {hi:g}] need lower < upper")
    declared = option(doc, spec, "initial_states")
    recorded = [d.get("x0") for d in (_recorded(doc, "detections") or [])
                if isinstance(d, Mapping)]
    if declared is not None:
        starts, source = declared, "the spec's initial_states"
    elif recorded and all(isinstance(x, list) for x in recorded):
        starts, source = recorded, "the initial states recorded with the stored detection times"
    else:
        starts = rule_initial_states(operating_point(spec)[0], lo, hi)
        source = (f"the rule: operating point, operating point +- {FAULT_START_OFFSET:g} (hi - lo) "
                  "alternately, upper corner")
    try:
        starts = np.asarray(starts, dtype=float).reshape(-1, n)
    except ValueError:
        raise ArtefactError(f"artefact '{doc['name']}': initial states {starts!r} are not vectors "
                            f"of {n} states") from None
    bad = [i for i, x in enumerate(starts) if not (np.all(x > lo) and np.all(x <= hi))]
    if bad:
        raise ArtefactError(f"artefact '{doc['name']}': initial state(s) {starts[bad].tolist()} "
                            f"({source}) lie outside the threshold's bounds ({lo:g}, {hi:g}]")
    inputs, inputs_source = _inputs(doc, spec)
    conservative = option(doc, spec, "conservative")
    if conservative is None:
        conservative = _recorded(doc, "conservative")
    return FaultScenario(lo, hi, starts, f"{source}; bounds from {bounds_source}", inputs,
                         inputs_source, _number(doc, spec, "delta_bar"),
                         _number(doc, spec, "t_fault"),
                         True if conservative is None else bool(conservative))


def _threshold_recheck(Psi: np.ndarray, Gd: np.ndarray, coef: np.ndarray, rates: np.ndarray,
                       A: np.ndarray, C: np.ndarray, e_hat: float) -> list[Check]:
    n = A.shape[0]
    G = A - Psi @ C
    dg = relative_difference(Gd, G)
    lam, V = np.linalg.eig(G)
    w = (C @ V).ravel() * np.linalg.solve(V, np.full(n, e_hat))
    order = np.argsort(-lam.real)
    lam, w = lam[order].real, w[order].real
    ok_shape = lam.size == rates.size
    dr = relative_difference(np.sort(rates), np.sort(lam)) if ok_shape else math.inf
    dc = math.inf
    if ok_shape:
        pairs = sorted(zip(rates, coef))
        dc = relative_difference(np.array([c for _, c in pairs]),
                                 np.array([c for _, c in sorted(zip(lam, w))]))
    ok = bool(max(dg, dr, dc) <= 1e-6)
    return [Check("threshold_recheck", ok,
                  f"stored Gamma_d against A - Psi C from the stored Psi {fmt(Psi.ravel())}: "
                  f"relative difference {dg:.3g}; stored threshold rates {fmt(rates)} against "
                  f"eig(A - Psi C) {fmt(lam)}: {dr:.3g}; coefficients {fmt(coef)} against "
                  f"C V diag(V^-1 e_hat) {fmt(w)} with e_hat = {e_hat:g}: {dc:.3g} (tolerance "
                  "1e-06 each)", {"gamma_difference": dg, "rate_difference": dr,
                                  "coefficient_difference": dc})]


def fault_detection_verdict(doc: Mapping[str, Any], spec: Spec, *,
                            trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``fault_detection`` artefact (seed 004 section II-F).

    Nothing is re-derived symbolically. ``threshold_recheck``: the stored
    ``Gamma_d`` equals ``A - Psi C`` (``A, C`` the Jacobians of the healthy
    plant, ``Psi`` the stored gain), and the stored threshold rates and
    coefficients equal, in floating point, the eigenvalues of ``A - Psi C``
    and ``C V diag(V^-1 e_hat)`` (``e_hat = (hi - lo) 1``); relative
    tolerance 1e-6. Then the plant is simulated (``simulate``, sampling
    ``min(ts, 1 ms)``, 4 RK4 substeps) from the scenario's initial states
    under its input (`fault_scenario`), with the observer (stored ``Psi``)
    started at ``lo``: ``no_false_alarm`` -- the healthy plant's residual
    stays at or below the stored threshold on ``[0.02 t_f, t_f + horizon]``,
    up to `FAULT_SLACK` times the threshold at ``0.02 t_f`` (integration
    error; the first 2 % of ``t_f`` is the initial transient, where the
    threshold equals the largest possible residual), and so does the faulty
    plant's before ``t_f``; ``fault_detected`` -- with the declared
    ``delta_bar`` from ``t_f``, the residual exceeds the threshold at some
    ``t_d`` in ``(t_f, t_f + horizon]`` for every start (``horizon`` =
    `FAULT_HORIZON`), and, where the artefact stores detection times for the
    same initial states, ``|t_d - stored| <= FAULT_TIME_TOLERANCE``.

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    plant = spec.plant
    n = plant.n
    Psi = artefact_matrix(doc, "Psi", (n, 1))
    Gd = artefact_matrix(doc, "Gamma_d", (n, n))
    coef = np.asarray(artefact_gain(doc, "threshold_coefficients"), dtype=float).reshape(-1)
    rates = np.asarray(artefact_gain(doc, "threshold_rates"), dtype=float).reshape(-1)
    if coef.size != rates.size or coef.size == 0:
        raise ArtefactError(f"artefact '{doc['name']}': threshold has {coef.size} coefficients and "
                            f"{rates.size} rates")
    sc = fault_scenario(doc, spec)
    lo, hi, t_f, delta_bar = sc.lo, sc.hi, sc.t_fault, sc.delta_bar
    params = {"delta_bar": 0.0} if "delta_bar" in {p.name for p in plant.parameters} else {}
    healthy = plant.with_parameters(params) if params else plant
    x_op, u_op = operating_point(spec)
    lin = linearize(healthy, x_op, u_op)
    A, C = np.asarray(lin.F, float), np.asarray(lin.C, float)
    checks = guard("threshold_recheck",
                   lambda: _threshold_recheck(Psi, Gd, coef, rates, A, C, hi - lo))

    def simulate_detection() -> list[Check]:
        starts = sc.starts
        R = starts.shape[0]
        ts = min(float(spec.ts) if spec.ts else FAULT_TS, FAULT_TS)
        k_f = int(round(t_f / ts))
        steps = int(math.ceil((t_f + FAULT_HORIZON) / ts))
        if steps > 10 * MAX_STEPS:
            return [Check("fault_detected", None, f"not simulated: {steps} samples of {ts:g} s")]
        x0 = np.vstack([starts, starts])
        faults = np.concatenate([np.zeros(R), np.full(R, delta_bar)])
        obs = ResidualObserver(plant, Psi, ts)
        change = [ParameterChange(k_f, {"delta_bar": faults})] if params else []
        # the inputs are scheduled in advance: given as a sequence, the plant is integrated
        # over whole stretches between the parameter changes (`simulate`)
        res = simulate(plant, ts=ts, steps=steps, x0=x0, seeds=run_seeds(0, 2 * R),
                       controller=InputSequence(_Schedule(sc.inputs).sequence(steps, ts)),
                       estimator=obs,
                       x_hat0=np.full((2 * R, n), lo), parameters=params or None,
                       changes=change, substeps=4)
        t = res.t
        r = np.abs(np.array(obs.residuals)[:, :, 0]).T            # (2R, N + 1)
        tt = t[None, :]
        weights = np.abs(coef) if sc.conservative else coef
        thr = np.sum(weights[:, None] * np.exp(rates[:, None] * t[None, :]), axis=0)
        margin = r - thr[None, :]
        t_skip = 0.02 * t_f
        quiet = (tt >= t_skip)
        worst_h = float(np.max(np.where(quiet, margin[:R], -np.inf)))
        pre_fault = (tt >= t_skip) & (tt < t_f)
        worst_pre = float(np.max(np.where(pre_fault, margin[R:], -np.inf)))
        slack = FAULT_SLACK * float(np.interp(t_skip, t, thr))
        ok_h = bool(worst_h <= slack and worst_pre <= slack and np.all(np.isfinite(r)))
        detect: list[float | None] = []
        for i in range(R, 2 * R):
            idx = np.flatnonzero((t > t_f) & (margin[i] > 0))
            if idx.size == 0:
                detect.append(None)
                continue
            k = int(idx[0])
            a, b = margin[i, k - 1], margin[i, k]
            frac = (-a / (b - a)) if (a < 0 < b) else 1.0
            detect.append(float(t[k - 1] + frac * ts))
        stored = _stored_times(doc, starts)
        diffs = [None if (d is None or s is None) else abs(d - s) for d, s in zip(detect, stored)]
        ok_d = all(d is not None and t_f < d <= t_f + FAULT_HORIZON for d in detect) and \
            all(df is None or df <= FAULT_TIME_TOLERANCE for df in diffs)
        thr_name = ("the sum of |c_i| exp(lambda_i t) over the error modes i (every term positive, "
                    "conservative)" if sc.conservative
                    else "the sum of c_i exp(lambda_i t) over the error modes i (exact)")
        starts_text = "; ".join(f"start {i + 1} at ({', '.join(f'{v:.4g}' for v in row)})"
                                for i, row in enumerate(starts))
        setup = (f"{R} starts ({sc.starts_source}: {starts_text}), observer from x_hat = {lo:g}, "
                 f"input: {sc.inputs_source}; sampled every {ts:g} s (4 RK4 substeps), stored Psi, "
                 f"threshold {thr_name} from the stored coefficients and rates")
        td = ", ".join("none" if d is None else f"{d:.5g} s" for d in detect)
        if trace is not None:
            _record(trace, res, plant, sc, r, thr, detect, setup)
        compared = [i for i, s in enumerate(stored) if s is not None]
        sd = "; no stored detection time for these initial states" if not compared else (
            f"; stored {fmt(np.array([stored[i] for i in compared]), 6)} s for start(s) "
            f"{[i + 1 for i in compared]}, differences " + ", ".join(
                f"{diffs[i]:.3g}" if diffs[i] is not None else "-" for i in compared)
            + f" s (tolerance {FAULT_TIME_TOLERANCE:g} s)")
        return [
            Check("no_false_alarm", ok_h,
                  f"{setup}: healthy plant, largest |epsilon| - threshold on [{t_skip:g}, "
                  f"{t[-1]:g}] s = {worst_h:.3g}; faulty plant before t_f = {t_f:g} s: "
                  f"{worst_pre:.3g} (both must be <= {slack:.3g} = {FAULT_SLACK:g} x the threshold at "
                  f"{t_skip:g} s, integration error; the first {t_skip:g} s = 2 % of t_f are the "
                  "initial transient)", {"healthy_margin": worst_h, "pre_fault_margin": worst_pre,
                                         "slack": slack, "transient_s": t_skip, "ts": ts,
                                         "starts": starts.tolist()}),
            Check("fault_detected", bool(ok_d),
                  f"{setup}: fault delta_bar = {delta_bar:g} from t_f = {t_f:g} s: detection at "
                  f"t_d = {td} (must lie in ({t_f:g}, {t_f + FAULT_HORIZON:g}] s){sd}",
                  {"t_detect": detect, "stored": stored, "differences": diffs, "t_fault": t_f,
                   "delta_bar": delta_bar, "horizon_s": FAULT_HORIZON,
                   "tolerance_s": FAULT_TIME_TOLERANCE, "starts": starts.tolist()}),
        ]

    return checks + guard("fault_detected", simulate_detection)


def _record(trace: TraceRecorder, res: Any, plant: Plant, sc: FaultScenario, r: np.ndarray,
            thr: np.ndarray, detect: list, setup: str) -> None:
    """Record the faulty runs (the second half of the batch; the first `TRACE_RUNS` starts) with
    their residual ``|epsilon|`` and the threshold (output units) as signals, the onset marked."""
    R, unit = sc.starts.shape[0], plant.outputs[0].unit
    shown = list(range(min(R, TRACE_RUNS)))
    td = ", ".join("none" if detect[i] is None else f"{detect[i]:.5g} s" for i in shown)
    trace.record(res, plant, check="fault_detected", estimator=True, rows=[R + i for i in shown],
                 scenario=f"fault delta_bar = {sc.delta_bar:g} from t_f = {sc.t_fault:g} s, runs from "
                 f"start(s) {[i + 1 for i in shown]} of {setup}; the residual first exceeds the threshold "
                 f"at t_d = {td}", signal_title=r"residual $|y - h(\hat{x})|$ against its threshold",
                 signals=(Signal(r"$|\varepsilon|$", unit, r), Signal("threshold", unit, np.broadcast_to(thr, r.shape), "--")),
                 events=[(sc.t_fault, f"fault onset, {sc.t_fault:g} s")])


def _stored_times(doc: Mapping[str, Any], starts: np.ndarray) -> list[float | None]:
    """The design's detection time of each start (None where the artefact records none for it).

    Read from ``diagnostics.detections``: records ``{"x0": [...], "t_detect": s or None}``,
    matched to the starts by initial state (never by position).
    """
    records = [d for d in (_recorded(doc, "detections") or []) if isinstance(d, Mapping)]
    out: list[float | None] = []
    for x in starts:
        found = None
        for r in records:
            x0, td = r.get("x0"), r.get("t_detect")
            if x0 is None or not isinstance(td, (int, float)) or isinstance(td, bool) or td < 0:
                continue
            x0 = np.asarray(x0, dtype=float).reshape(-1)
            if x0.shape == x.shape and np.allclose(x0, x, rtol=1e-12, atol=1e-12):
                found = float(td)
                break
        out.append(found)
    return out
