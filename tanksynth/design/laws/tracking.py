"""Control laws as artefacts: integral tracking, inverse dynamics, export.

Linear tracking with integral action (seed 000 eq. 13-16)
    Discrete law in deviation variables about ``(x0, u0)``, sampled with
    period ``ts``::

        v(k)   = u0 - K1 (x(k) - x0) - K2 z(k)
        u(k)   = sat(v(k))                       pump range, e.g. 0 .. qmax
        z(k+1) = z(k) + ts (y_r(k) - y0 - C1 (x(k) - x0)) + Kaw (u(k) - v(k))

    ``y0 = h(x0)`` are the tracked outputs at the operating point (offsets and
    sensor gains of the output map included) and ``C1`` their Jacobian: the
    integrators integrate the error of the measured outputs, so the loop
    settles with the outputs (not the states) at their references.

    ``K = [K1 K2]`` places the poles of the augmented pair (the augmentation
    and the placement are `tanksynth.design.placement.canonical`'s
    `integral_augmentation` and `place_state_feedback`). Anti-windup by
    back-calculation, ``Kaw = -gamma K2^+`` (``gamma = 1`` re-conditions the
    integrator so that the unsaturated command equals the applied one), by
    clamping (integration frozen while an input saturates) or none.
Inverse dynamics (seed 002 eq. 46-47, notes/plants.md 1.6)
    For the states fed directly by the pumps (``h1``, ``h2`` of the hybrid
    three-tank), imposing ``dh_i/dt = C_i (h_i,sp - h_i)`` and inverting the
    model at the estimate ``x_hat``::

        Q1in = A C1 (h1sp - h1_hat) + Q1 + Q3 + Q5    (flows at x_hat)
        Q2in = A C2 (h2sp - h2_hat) + Q2 + Q4 + Q7

    derived from the plant's equations (``u = G_c^-1 (diag(C) (h_sp - x_c) -
    f0_c(x_hat))``), saturated to the pumps' range (0-240 lph). The law takes
    ``x_hat`` from any estimator. ``C1, C2`` are tuned by minimising the ISE
    of a simulated servo scenario over ``C_i in [0, 1]`` (coarse grid, then a
    1-D refinement of each gain), as in the paper.
Export
    Every law is a CasADi Function; `export_law` writes it serialised
    (``Function.save``) and as generated C (CasADi codegen, with header),
    atomically; `compile_law` builds a shared library with gcc and
    `load_compiled_law` loads it back (``casadi.external``) for checks.
    `law_document` / `law_from_document` carry the serialised law inside
    artefact diagnostics.

The ISE tuning simulates through the toolbox's one integrator
(`tanksynth.sim.integrate`): the servo step is its symbolic form
(`symbolic_rk4`: same RK4, same clipping, same saturation), mapped over the
candidate gains; a run whose step crosses a hybrid switching surface is
simulated again by the numeric batch simulator, which locates the crossing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from tanksynth.design.operating_point import discrete_pair, equilibrium_at, linearized_at
from tanksynth.design.placement.canonical import integral_augmentation, place_state_feedback
from tanksynth.errors import DimensionError, InfeasibleDesign, SimulationError, SpecError
from tanksynth.plants.base import Plant
from tanksynth.runtime.laws import (IntegralTracking, InverseDynamicsLaw, integral_tracking_law,
                                    inverse_dynamics_law)
from tanksynth.sim.integrate import symbolic_rk4
from tanksynth.sim.simulate import simulate

__all__ = [
    "design_integral_tracking",
    "ServoScenario",
    "ISETuning",
    "servo_ise",
    "tune_inverse_dynamics",
]


# ====================================================== linear integral tracking


def design_integral_tracking(plant: Plant, x0: Any, poles: Any, ts: float, *,
                             tracked: Sequence[str] | None = None, method: str = "auto",
                             anti_windup: str = "back_calculation", aw_gain: float = 1.0,
                             given_u0: Any = None) -> IntegralTracking:
    """Linearise, augment with integrators and place the poles (seed 000 section II-B).

    Uses the equilibrium input of the model at ``x0`` (the spec's input is
    only checked), exact ZOH with period ``ts``,
    `placement.integral_augmentation` and `placement.place_state_feedback`.

    Parameters
    ----------
    plant : Plant
    x0 : array_like, shape (n,)
        Operating levels (state units).
    poles : array_like, length n + p
        Discrete-time closed-loop poles of the augmented system (z-plane,
        dimensionless).
    ts : float
        Sampling period (s).
    tracked : sequence of str, optional
        Output names to track (default: the first ``m`` outputs).
    method : {"auto", "place", "acker"}
    anti_windup, aw_gain
        See `integral_tracking_law`.
    given_u0 : array_like, optional
        An input to check against the model (residual in the diagnostics).

    Returns
    -------
    IntegralTracking
        Pump saturation from ``plant.input_limits``.
    """
    eq = equilibrium_at(plant, x0, given_u0)
    if not eq.is_equilibrium:
        raise InfeasibleDesign(f"x0 = {np.asarray(x0).tolist()} is not an equilibrium of plant "
                               f"'{plant.name}' (residual {eq.residual.tolist()})")
    lin = linearized_at(plant, x0, eq.u0, ts=ts)
    names = [s.name for s in plant.outputs]
    chosen = list(tracked) if tracked is not None else names[: plant.m]
    unknown = [c for c in chosen if c not in names]
    if unknown:
        raise SpecError(f"unknown output(s) {unknown}; expected some of {names}", key="tracked")
    if len(chosen) > plant.m:
        raise DimensionError(f"more tracked outputs than inputs: {len(chosen)} outputs {chosen} but "
                             f"{plant.m} inputs (seed 000 II-B needs p <= m)")
    rows = [names.index(c) for c in chosen]
    C1 = lin.C[rows]
    y0 = np.asarray(plant.compiled.output(np.asarray(lin.x0, dtype=float)[None]), dtype=float).reshape(-1)[rows]
    Ad, Bd = discrete_pair(lin)
    aug = integral_augmentation(Ad, Bd, C1, ts)
    res = place_state_feedback(aug.A, aug.B, poles, method,
                               state_names=[s.name for s in plant.states] + [f"z_{c}" for c in chosen])
    K = res.K
    law = integral_tracking_law(K[:, : plant.n], K[:, plant.n:], lin.x0, eq.u0, C1, ts,
                                plant.input_limits, anti_windup=anti_windup, aw_gain=aw_gain,
                                tracked=chosen, y0=y0)
    diag = dict(law.diagnostics)
    diag.update({"equilibrium": eq.as_dict(), "placement": res.as_dict(),
                 "augmented_A": aug.A.tolist(), "augmented_B": aug.B.tolist(),
                 "Ad": Ad.tolist(), "Bd": Bd.tolist()})
    return IntegralTracking(law.K1, law.K2, law.Kaw, law.x0, law.u0, law.C1, law.ts,
                            law.input_limits, law.anti_windup, law.tracked, law.law, diag, law.y0)


# ============================================================== inverse dynamics


# ==================================================================== ISE tuning
@dataclass(frozen=True)
class ServoScenario:
    """Servo scenario of seed 002 section 5.1: a set-point step at the 100th sample.

    Attributes
    ----------
    x0 : ndarray, shape (n,)
        Initial state, an equilibrium (state units).
    setpoint : ndarray, shape (m,)
        Initial set points (default: the controlled states at ``x0``).
    step : ndarray, shape (m,)
        Set-point step (m; seed 002: 0.04 m).
    step_time : float
        Time of the step (s; seed 002: 100th sampling instant).
    horizon : float
        End of the run (s).
    ts : float
        Control period (s; the law is sampled and held).
    substeps : int
        RK4 steps per control period.
    """

    x0: np.ndarray
    setpoint: np.ndarray
    step: np.ndarray
    step_time: float = 100.0
    horizon: float = 300.0
    ts: float = 1.0
    substeps: int = 10

    def setpoints(self) -> np.ndarray:
        """Set points at each control instant, shape (N, m)."""
        t = np.arange(self.samples) * self.ts
        return self.setpoint[None, :] + (t[:, None] >= self.step_time - 1e-9) * self.step[None, :]

    @property
    def samples(self) -> int:
        """Number of control periods."""
        return int(round(self.horizon / self.ts))

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"x0": self.x0.tolist(), "setpoint": self.setpoint.tolist(), "step": self.step.tolist(),
                "step_time_s": self.step_time, "horizon_s": self.horizon, "ts_s": self.ts,
                "rk4_substeps": self.substeps}


def _servo_step(plant: Plant, law: InverseDynamicsLaw, scenario: ServoScenario) -> ca.Function:
    """``(x, h_sp, C) -> (x_next, ise_increment, crossed)`` over one control period (ZOH).

    The integrator's symbolic step (`tanksynth.sim.integrate.symbolic_rk4`)
    with the law evaluated once at the start of the period, the true state
    as the estimate, and the squared errors of the controlled levels
    integrated by the trapezoid rule on the RK4 grid.
    """
    idx = [[s.name for s in plant.states].index(c) for c in law.controlled]
    x = ca.SX.sym("x", plant.n)
    r = ca.SX.sym("h_sp", plant.m)
    c = ca.SX.sym("C", plant.m)
    u = law.parametric(x, r, c)                 # x_hat = x (true state as the estimate)
    err = lambda v: ca.vertcat(*[(r[i] - v[j]) ** 2 for i, j in enumerate(idx)])  # noqa: E731
    out = symbolic_rk4(plant, x, u, scenario.ts, scenario.substeps, integrand=err)
    return ca.Function("servo_step", [x, r, c], [out.x, out.integral, out.crossed],
                       ["x", "h_sp", "C"], ["x_next", "ise", "crossed"])


class _HeldLaw:
    """The parametric law with per-run gains, evaluated every ``every`` samples and held."""

    def __init__(self, law: InverseDynamicsLaw, C: np.ndarray, every: int):
        self.fn = law.parametric
        self.C = C
        self.every = every

    def reset(self, runs: int) -> None:
        self.k = 0
        self.u: np.ndarray | None = None
        self.map = self.fn.map(runs, "serial")

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        if self.k % self.every == 0 or self.u is None:
            self.u = np.asarray(self.map(x_hat.T, reference.T, self.C.T), dtype=float).T.copy()
        self.k += 1
        return self.u


def _servo_ise_numeric(plant: Plant, law: InverseDynamicsLaw, scenario: ServoScenario,
                       C: np.ndarray) -> np.ndarray:
    """`servo_ise` through the numeric batch simulator (switching surfaces located)."""
    S = int(scenario.substeps)
    h = scenario.ts / S
    idx = [[s.name for s in plant.states].index(c) for c in law.controlled]
    ref = np.repeat(scenario.setpoints(), S, axis=0)              # set point of each RK4 step
    M = C.shape[0]

    def run(rows: np.ndarray) -> np.ndarray:
        res = simulate(plant, ts=h, steps=ref.shape[0], x0=scenario.x0,
                       seeds=np.zeros(rows.size, dtype=np.uint64), controller=_HeldLaw(law, C[rows], S),
                       reference=np.vstack([ref, ref[-1:]]), substeps=1)
        X = res.x[:, :, idx]
        e = (ref[None] - X[:, :-1]) ** 2 + (ref[None] - X[:, 1:]) ** 2
        return h / 2 * e.sum(axis=1)

    try:
        return run(np.arange(M))
    except SimulationError:                      # a diverging run: the others still count
        out = np.full((M, len(idx)), np.inf)
        for i in range(M):
            try:
                out[i] = run(np.array([i]))[0]
            except SimulationError:
                pass
        return out


def servo_ise(plant: Plant, law: InverseDynamicsLaw, scenario: ServoScenario,
              gains: Any, _step: ca.Function | None = None, *, numeric: bool = False) -> np.ndarray:
    """ISE of each controlled level on the servo scenario, for a batch of gains.

    Parameters
    ----------
    plant : Plant
    law : InverseDynamicsLaw
        Its ``parametric`` Function is used with the true state as the
        estimate.
    scenario : ServoScenario
    gains : array_like, shape (M, m)
        Candidate rates ``C`` (1/s).
    numeric : bool
        Simulate every run with the numeric batch simulator
        (`tanksynth.sim.simulate`) instead of the symbolic step; the
        symbolic path does so only for runs that cross a switching surface.
        Both give the same numbers (to rounding).

    Returns
    -------
    ndarray, shape (M, m)
        ``int_0^T (h_i,sp - h_i)^2 dt`` (m^2 s), trapezoid on the RK4 grid;
        ``inf`` for a run whose state is not finite.
    """
    C = np.atleast_2d(np.asarray(gains, dtype=float))
    if numeric:
        return _servo_ise_numeric(plant, law, scenario, C)
    M = C.shape[0]
    sps = scenario.setpoints()
    N = len(sps)
    # the whole horizon in one call: the step mapped over the runs, accumulated over the
    # periods (``mapaccum``: the same step, evaluated N times inside CasADi instead of N calls)
    horizon = (_step or _servo_step(plant, law, scenario)).map(M, "serial").mapaccum(N)
    X, inc, cr = horizon(np.tile(scenario.x0[:, None], (1, M)), np.repeat(sps.T, M, axis=1),
                         np.tile(C.T, (1, N)))
    x = np.asarray(X, dtype=float)[:, -M:]
    inc = np.asarray(inc, dtype=float).reshape(-1, N, M)
    ise = np.zeros((len(law.controlled), M))
    for k in range(N):                          # summed period by period, in time order
        ise += inc[:, k]
    crossed = np.any(np.asarray(cr, dtype=float).reshape(N, M) > 0, axis=0)
    out = ise.T
    out[~np.all(np.isfinite(x), axis=0)] = np.inf
    if crossed.any():
        out[crossed] = _servo_ise_numeric(plant, law, scenario, C[crossed])
    return out


@dataclass(frozen=True)
class ISETuning:
    """Result of the ISE tuning of ``C1, C2`` (seed 002 section 4).

    Attributes
    ----------
    C : ndarray, shape (m,)
        Tuned rates (1/s).
    ise : float
        Total ISE at ``C`` (m^2 s).
    ise_outputs : ndarray, shape (m,)
        ISE of each controlled level at ``C`` (m^2 s: squared level error times time).
    grid : ndarray, shape (k,)
        Coarse grid of each ``C_i``.
    grid_ise : ndarray, shape (k,) * m
        Total ISE on the coarse grid.
    refinement : tuple of dict
        One entry per 1-D refinement (gain index, bracket, optimum, evaluations).
    evaluations : int
        Simulated runs (grid + refinement).
    scenario : ServoScenario
    """

    C: np.ndarray
    ise: float
    ise_outputs: np.ndarray
    grid: np.ndarray
    grid_ise: np.ndarray
    refinement: tuple[dict, ...]
    evaluations: int
    scenario: ServoScenario

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"C": self.C.tolist(), "ise_total_m2s": self.ise,
                "ise_outputs_m2s": self.ise_outputs.tolist(), "grid": self.grid.tolist(),
                "grid_ise_m2s": self.grid_ise.tolist(), "refinement": list(self.refinement),
                "evaluations": self.evaluations, "scenario": self.scenario.as_dict(),
                "estimate": "true state (state feedback); estimator-in-the-loop tuning is the "
                            "estimators issue's"}


def tune_inverse_dynamics(plant: Plant, scenario: ServoScenario, *,
                          controlled: Sequence[str] | None = None,
                          grid: ArrayLike = tuple(np.round(np.linspace(0.1, 1.0, 10), 10)),
                          bounds: tuple[float, float] = (0.0, 1.0), xatol: float = 1e-3,
                          saturate: bool = True, name: str = "inverse_dynamics"
                          ) -> tuple[InverseDynamicsLaw, ISETuning]:
    """Tune ``C`` by minimising the total ISE of the servo scenario (seed 002 section 4).

    A coarse grid over ``bounds^m`` (every combination, simulated in one
    batch), then, in turn for each ``C_i`` with the others fixed, a bounded
    1-D minimisation (Brent) within one grid spacing of the best grid point.

    Parameters
    ----------
    plant : Plant
    scenario : ServoScenario
    controlled : sequence of str, optional
    grid : array_like of float
        Coarse values of each ``C_i`` (1/s), inside ``bounds``.
    bounds : (float, float)
        Admissible range of each ``C_i`` (seed 002: 0 to 1).
    xatol : float
        Absolute tolerance of the refinement (1/s).
    saturate : bool
    name : str
        Name of the law's CasADi Function.

    Returns
    -------
    law : InverseDynamicsLaw
        With the tuned ``C``.
    tuning : ISETuning
    """
    from scipy.optimize import minimize_scalar  # deferred: scipy.optimize imports in ~0.15 s
    lo, hi = map(float, bounds)
    g = np.asarray(grid, dtype=float).reshape(-1)
    if g.size < 2 or np.any(g < lo) or np.any(g > hi) or not (0 <= lo < hi):
        raise SpecError(f"grid must hold >= 2 values inside bounds [{lo}, {hi}], got {g.tolist()}",
                        key="grid")
    law = inverse_dynamics_law(plant, np.full(plant.m, g[0]), controlled, saturate=saturate, name=name)
    step = _servo_step(plant, law, scenario)
    combos = np.array(np.meshgrid(*([g] * plant.m), indexing="ij")).reshape(plant.m, -1).T
    ise_grid = servo_ise(plant, law, scenario, combos, step).sum(axis=1)
    best = combos[int(np.argmin(ise_grid))].copy()
    evaluations = len(combos)
    spacing = float(np.max(np.diff(np.sort(g))))
    refinement = []
    for i in range(plant.m):
        a, b = max(lo, best[i] - spacing), min(hi, best[i] + spacing)
        count = [0]

        def total(ci: float, i: int = i) -> float:
            cand = best.copy()
            cand[i] = ci
            count[0] += 1
            return float(servo_ise(plant, law, scenario, cand[None], step).sum())

        res = minimize_scalar(total, bounds=(a, b), method="bounded", options={"xatol": xatol})
        start = total(best[i])
        if res.fun < start:
            best[i] = float(res.x)
        refinement.append({"gain": f"C{i + 1}", "bracket": [float(a), float(b)], "optimum": float(best[i]),
                           "ise_total_m2s": float(min(res.fun, start)), "evaluations": count[0]})
        evaluations += count[0]
    per = servo_ise(plant, law, scenario, best[None], step)[0]
    tuned = law.with_gains(best)
    tuning = ISETuning(best, float(per.sum()), per, g, ise_grid.reshape([g.size] * plant.m),
                       tuple(refinement), evaluations, scenario)
    return tuned, tuning
