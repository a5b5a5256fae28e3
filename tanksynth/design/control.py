"""Control laws as artefacts: integral tracking, inverse dynamics, export.

Linear tracking with integral action (seed 000 eq. 13-16)
    Discrete law in deviation variables about ``(x0, u0)``, sampled with
    period ``ts``::

        v(k)   = u0 - K1 (x(k) - x0) - K2 z(k)
        u(k)   = sat(v(k))                       pump range, e.g. 0 .. qmax
        z(k+1) = z(k) + ts (y_r(k) - C1 x(k)) + Kaw (u(k) - v(k))

    ``K = [K1 K2]`` places the poles of the augmented pair (the augmentation
    and the placement are `tanksynth.design.placement`'s
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

The fixed-step RK4 helpers here (`_rk4_step`, `_simulate_sampled`) exist only
for the ISE tuning and the tests; the simulator proper lives in
``tanksynth.verify``.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import casadi as ca
import numpy as np
import sympy as sp
from scipy.optimize import minimize_scalar

from tanksynth.errors import ArtefactError, DimensionError, InfeasibleDesign, SpecError
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import compile_matrix
from tanksynth.design.feedback_linearization import _batch, region_points
from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.design.placement import integral_augmentation, place_state_feedback
from tanksynth.analysis.symbolic import control_affine

__all__ = [
    "ANTI_WINDUP",
    "IntegralTracking",
    "integral_tracking_law",
    "design_integral_tracking",
    "InverseDynamicsLaw",
    "inverse_dynamics_law",
    "ServoScenario",
    "ISETuning",
    "servo_ise",
    "tune_inverse_dynamics",
    "ExportedLaw",
    "law_document",
    "law_from_document",
    "rename_law",
    "export_law",
    "compile_law",
    "load_compiled_law",
]

#: Anti-windup schemes of `integral_tracking_law`.
ANTI_WINDUP = ("back_calculation", "clamping", "none")


# ======================================================================= helpers
def _vec(value: Any, size: int, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be numbers, got {value!r}") from None
    if arr.size != size:
        raise DimensionError(f"{name} has {arr.size} entries, expected {size}")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def _mat(value: Any, shape: tuple[int, int], name: str) -> np.ndarray:
    try:
        arr = np.atleast_2d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a real matrix") from None
    if arr.shape != shape:
        raise DimensionError(f"{name} has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be finite")
    return arr


def _limits(limits: Any, m: int) -> np.ndarray:
    if limits is None:
        return np.tile([-np.inf, np.inf], (m, 1))
    arr = np.asarray(limits, dtype=float).reshape(m, 2)
    if np.any(arr[:, 0] > arr[:, 1]):
        raise DimensionError(f"input limits must be (lower, upper) with lower <= upper, got {arr.tolist()}")
    return arr


def _saturate(u: ca.SX, limits: np.ndarray) -> ca.SX:
    out = ca.SX(u)
    for i, (lo, hi) in enumerate(limits):
        if np.isfinite(lo):
            out[i] = ca.fmax(out[i], lo)
        if np.isfinite(hi):
            out[i] = ca.fmin(out[i], hi)
    return out


def _level_bounds(plant: Plant) -> tuple[np.ndarray, np.ndarray]:
    """Clipping bounds of the private RK4: levels >= 0, <= hmax when the plant has one."""
    lo = np.zeros(plant.n)
    hmax = next((p.value for p in plant.parameters if p.name == "hmax"), np.inf)
    hi = np.full(plant.n, float(hmax))
    return lo, hi


def _rk4_step(plant: Plant, dt: float, law: ca.Function | None = None,
              substeps: int = 1) -> ca.Function:
    """One fixed step of RK4 on the plant (private helper of the tuning and the tests).

    Parameters
    ----------
    plant : Plant
        Its general model ``plant.compiled.f`` is integrated.
    dt : float
        Step (s); split in ``substeps`` RK4 steps.
    law : casadi.Function, optional
        ``(x, r) -> u, ...``: evaluated at every RK4 stage (continuous-time
        law). Without it the input is held over the step (ZOH).
    substeps : int

    Returns
    -------
    casadi.Function
        ``(x, u) -> x_next`` or ``(x, r) -> x_next``; levels clipped to
        ``[0, hmax]`` after each substep.
    """
    f = plant.compiled.f
    x = ca.SX.sym("x", plant.n)
    lo, hi = _level_bounds(plant)
    if law is None:
        v = ca.SX.sym("u", plant.m)
        rhs = lambda s: f(s, v)  # noqa: E731
    else:
        v = ca.SX.sym("r", law.size1_in(1))
        rhs = lambda s: f(s, law(s, v)[0] if law.n_out() > 1 else law(s, v))  # noqa: E731
    h = float(dt) / substeps
    s = x
    for _ in range(substeps):
        k1 = rhs(s)
        k2 = rhs(s + h / 2 * k1)
        k3 = rhs(s + h / 2 * k2)
        k4 = rhs(s + h * k3)
        s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        s = ca.fmin(ca.fmax(s, lo), hi)
    return ca.Function("rk4_step", [x, v], [s], ["x", "u" if law is None else "r"], ["x_next"])


def _simulate_sampled(step: ca.Function, x0: np.ndarray, signal: np.ndarray) -> np.ndarray:
    """Iterate ``x(k+1) = step(x(k), signal[k])``; returns (N+1, n)."""
    xs = [np.asarray(x0, dtype=float)]
    for s in signal:
        xs.append(np.asarray(step(xs[-1], s), dtype=float).reshape(-1))
    return np.array(xs)


# ====================================================== linear integral tracking
@dataclass(frozen=True)
class IntegralTracking:
    """Sampled linear tracking law with integral action, saturation and anti-windup.

    Attributes
    ----------
    K1 : ndarray, shape (m, n)
        State gain (input unit per state unit).
    K2 : ndarray, shape (m, p)
        Integrator gain (input unit per state unit second).
    Kaw : ndarray, shape (p, m)
        Back-calculation gain (zero unless ``anti_windup == "back_calculation"``).
    x0, u0 : ndarray
        Operating point (state units, input units).
    C1 : ndarray, shape (p, n)
        Tracked outputs.
    ts : float
        Sampling period (s).
    input_limits : ndarray, shape (m, 2)
    anti_windup : str
        One of `ANTI_WINDUP`.
    tracked : tuple of str
    law : casadi.Function
        ``(x[n], z[p], y_r[p]) -> (u[m], z_next[p])``, absolute units
        (levels, references and inputs; deviations are formed inside).
    diagnostics : dict
    """

    K1: np.ndarray
    K2: np.ndarray
    Kaw: np.ndarray
    x0: np.ndarray
    u0: np.ndarray
    C1: np.ndarray
    ts: float
    input_limits: np.ndarray
    anti_windup: str
    tracked: tuple[str, ...]
    law: ca.Function
    diagnostics: dict = field(default_factory=dict)

    @property
    def K(self) -> np.ndarray:
        """``[K1 K2]``, shape (m, n + p)."""
        return np.hstack([self.K1, self.K2])

    def latex(self) -> dict[str, str]:
        """LaTeX of the law (report)."""
        return {"law": r"u(k) = \mathrm{sat}\big(u_0 - K_1 (x(k) - x_0) - K_2 z(k)\big),\quad "
                       r"z(k+1) = z(k) + t_s (y_r(k) - C_1 x(k)) + K_{aw} (u(k) - v(k))",
                "K": sp.latex(sp.Matrix(self.K).evalf(6))}


def integral_tracking_law(K1: Any, K2: Any, x0: Any, u0: Any, C1: Any, ts: float,
                          input_limits: Any = None, *, anti_windup: str = "back_calculation",
                          aw_gain: float = 1.0, tracked: Sequence[str] | None = None,
                          name: str = "integral_tracking") -> IntegralTracking:
    """Build the sampled integral-action law (seed 000 eq. 13-16) with saturation.

    Parameters
    ----------
    K1 : array_like, shape (m, n)
    K2 : array_like, shape (m, p)
        Gains of ``u = -[K1 K2] [x; z]`` in deviation variables.
    x0 : array_like, shape (n,)
        Operating state (state units).
    u0 : array_like, shape (m,)
        Equilibrium input (input units).
    C1 : array_like, shape (p, n)
        Tracked outputs ``y1 = C1 x``.
    ts : float
        Sampling period (s, > 0).
    input_limits : array_like, shape (m, 2), optional
        Actuator range (input units); None = unbounded.
    anti_windup : {"back_calculation", "clamping", "none"}
    aw_gain : float
        ``gamma`` in ``Kaw = -gamma pinv(K2)`` (0 < gamma <= 1).
    tracked : sequence of str, optional
        Names of the tracked outputs.
    name : str
        Name of the CasADi Function.

    Returns
    -------
    IntegralTracking

    Raises
    ------
    DimensionError, SpecError
    """
    K1 = np.atleast_2d(np.asarray(K1, dtype=float))
    m, n = K1.shape
    K2 = np.atleast_2d(np.asarray(K2, dtype=float))
    p = K2.shape[1]
    K2 = _mat(K2, (m, p), "K2")
    K1 = _mat(K1, (m, n), "K1")
    x0 = _vec(x0, n, "x0")
    u0 = _vec(u0, m, "u0")
    C1 = _mat(C1, (p, n), "C1")
    if not (isinstance(ts, (int, float)) and np.isfinite(ts) and ts > 0):
        raise SpecError(f"sampling period must be > 0 s, got {ts!r}", key="sampling.ts")
    if anti_windup not in ANTI_WINDUP:
        raise SpecError(f"anti_windup must be one of {list(ANTI_WINDUP)}, got {anti_windup!r}",
                        key="anti_windup")
    if not (isinstance(aw_gain, (int, float)) and 0 < aw_gain <= 1):
        raise SpecError(f"aw_gain must be in (0, 1], got {aw_gain!r}", key="aw_gain")
    limits = _limits(input_limits, m)
    Kaw = -float(aw_gain) * np.linalg.pinv(K2) if anti_windup == "back_calculation" else np.zeros((p, m))
    x = ca.SX.sym("x", n)
    z = ca.SX.sym("z", p)
    r = ca.SX.sym("y_r", p)
    v = ca.DM(u0) - ca.mtimes(ca.DM(K1), x - ca.DM(x0)) - ca.mtimes(ca.DM(K2), z)
    u = _saturate(v, limits)
    e = r - ca.mtimes(ca.DM(C1), x)
    if anti_windup == "back_calculation":
        z_next = z + ts * e + ca.mtimes(ca.DM(Kaw), u - v)
    elif anti_windup == "clamping":
        active = ca.SX(0)
        for i in range(m):
            active = ca.fmax(active, ca.if_else(ca.fabs(u[i] - v[i]) > 0, 1, 0))
        z_next = z + (1 - active) * ts * e
    else:
        z_next = z + ts * e
    law = ca.Function(name, [x, z, r], [u, z_next], ["x", "z", "y_r"], ["u", "z_next"])
    names = tuple(tracked) if tracked is not None else tuple(f"y{i + 1}" for i in range(p))
    diagnostics = {"anti_windup": anti_windup, "aw_gain": float(aw_gain), "ts": float(ts),
                   "input_limits": limits.tolist(), "tracked": list(names),
                   "law": "v = u0 - K1 (x - x0) - K2 z; u = sat(v); z+ = z + ts (y_r - C1 x) "
                          + {"back_calculation": "+ Kaw (u - v), Kaw = -gamma pinv(K2)",
                             "clamping": "(frozen while any input saturates)", "none": ""}[anti_windup]}
    return IntegralTracking(K1, K2, Kaw, x0, u0, C1, float(ts), limits, anti_windup, names, law,
                            diagnostics)


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
        Discrete-time closed-loop poles of the augmented system.
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
    eq = equilibrium_input(plant, x0, given_u0)
    if not eq.is_equilibrium:
        raise InfeasibleDesign(f"x0 = {np.asarray(x0).tolist()} is not an equilibrium of plant "
                               f"'{plant.name}' (residual {eq.residual.tolist()})")
    lin = linearize(plant, x0, eq.u0, ts=ts)
    names = [s.name for s in plant.outputs]
    chosen = list(tracked) if tracked is not None else names[: plant.m]
    unknown = [c for c in chosen if c not in names]
    if unknown:
        raise SpecError(f"unknown output(s) {unknown}; expected some of {names}", key="tracked")
    if len(chosen) > plant.m:
        raise DimensionError(f"more tracked outputs than inputs: {len(chosen)} outputs {chosen} but "
                             f"{plant.m} inputs (seed 000 II-B needs p <= m)")
    C1 = lin.C[[names.index(c) for c in chosen]]
    aug = integral_augmentation(lin.Ad, lin.Bd, C1, ts)
    res = place_state_feedback(aug.A, aug.B, poles, method,
                               state_names=[s.name for s in plant.states] + [f"z_{c}" for c in chosen])
    K = res.gain
    law = integral_tracking_law(K[:, : plant.n], K[:, plant.n:], lin.x0, eq.u0, C1, ts,
                                plant.input_limits, anti_windup=anti_windup, aw_gain=aw_gain,
                                tracked=chosen)
    diag = dict(law.diagnostics)
    diag.update({"equilibrium": eq.as_dict(), "placement": res.as_dict(),
                 "augmented_A": aug.A.tolist(), "augmented_B": aug.B.tolist(),
                 "Ad": lin.Ad.tolist(), "Bd": lin.Bd.tolist()})
    return IntegralTracking(law.K1, law.K2, law.Kaw, law.x0, law.u0, law.C1, law.ts,
                            law.input_limits, law.anti_windup, law.tracked, law.law, diag)


# ============================================================== inverse dynamics
@dataclass(frozen=True)
class InverseDynamicsLaw:
    """Estimator-based inverse-dynamics law (seed 002 eq. 46-47).

    Attributes
    ----------
    plant : str
    controlled : tuple of str
        Controlled states (one per input), e.g. ``("h1", "h2")``.
    C : ndarray, shape (m,)
        Closed-loop rates ``C_i`` (1/s): ``dh_i/dt = C_i (h_i,sp - h_i)``.
    input_limits : ndarray, shape (m, 2)
        Pump range (input units).
    saturated : bool
    law : casadi.Function
        ``(x_hat[n], h_sp[m]) -> u[m]`` with ``C`` fixed.
    parametric : casadi.Function
        ``(x_hat[n], h_sp[m], C[m]) -> u[m]`` (used by the tuning).
    expression : sympy.Matrix
        Unsaturated law in state, set-point, ``C_i`` and parameter symbols.
    setpoint_symbols, gain_symbols : tuple of sympy.Symbol
    diagnostics : dict
    """

    plant: str
    controlled: tuple[str, ...]
    C: np.ndarray
    input_limits: np.ndarray
    saturated: bool
    law: ca.Function
    parametric: ca.Function
    expression: sp.Matrix
    setpoint_symbols: tuple[sp.Symbol, ...]
    gain_symbols: tuple[sp.Symbol, ...]
    diagnostics: dict = field(default_factory=dict)

    def latex(self) -> dict[str, str]:
        """LaTeX of the law (report)."""
        return {"law": sp.latex(self.expression), "C": sp.latex(sp.Matrix(self.C).evalf(6).T)}

    def with_gains(self, C: Any) -> "InverseDynamicsLaw":
        """The same law with other rates ``C`` (1/s)."""
        C = _gains(C, len(self.controlled))
        law = _fix_gains(self.parametric, C, self.law.name())
        diag = dict(self.diagnostics, C=C.tolist())
        return InverseDynamicsLaw(self.plant, self.controlled, C, self.input_limits, self.saturated,
                                  law, self.parametric, self.expression, self.setpoint_symbols,
                                  self.gain_symbols, diag)


def _gains(C: Any, m: int) -> np.ndarray:
    C = _vec(C, m, "C")
    if np.any(C < 0):
        raise SpecError(f"inverse-dynamics rates C must be >= 0 (1/s), got {C.tolist()}", key="C")
    return C


def _fix_gains(parametric: ca.Function, C: np.ndarray, name: str) -> ca.Function:
    x = ca.SX.sym("x_hat", parametric.size1_in(0))
    r = ca.SX.sym("h_sp", parametric.size1_in(1))
    return ca.Function(name, [x, r], [parametric(x, r, ca.DM(C))], ["x_hat", "h_sp"], ["u"])


def _default_controlled(plant: Plant, G: sp.Matrix) -> list[str]:
    rows = [i for i in range(plant.n) if any(G[i, j] != 0 for j in range(plant.m))]
    if len(rows) != plant.m:
        raise DimensionError(
            f"cannot choose the controlled states of plant '{plant.name}' automatically: "
            f"{len(rows)} states ({[plant.states[i].name for i in rows]}) are fed by the "
            f"{plant.m} inputs; give 'controlled' (one state per input)")
    return [plant.states[i].name for i in rows]


def inverse_dynamics_law(plant: Plant, C: Any, controlled: Sequence[str] | None = None, *,
                         saturate: bool = True, name: str = "inverse_dynamics",
                         per_axis: int = 9, samples: int = 200) -> InverseDynamicsLaw:
    """Inverse-dynamics law ``u = G_c^-1 (diag(C) (h_sp - x_c) - f0_c(x_hat))``.

    For the hybrid three-tank this is seed 002 eq. (46)-(47): ``Q1in = A C1
    (h1sp - h1) + Q1 + Q3 + Q5``, ``Q2in = A C2 (h2sp - h2) + Q2 + Q4 +
    Q7``, the flows evaluated at the estimate (general model: ``sgn``,
    ``max`` and the middle-pipe switching kept).

    Parameters
    ----------
    plant : Plant
        Control-affine in its inputs.
    C : array_like, shape (m,)
        Rates ``C_i`` (1/s, >= 0).
    controlled : sequence of str, optional
        One state per input (default: the states the inputs enter).
    saturate : bool
        Clip to ``plant.input_limits`` (0-240 lph for the hybrid plant).
    name : str
        Name of the CasADi Function.
    per_axis, samples : int
        Region points on which ``G_c(x)`` is checked invertible.

    Returns
    -------
    InverseDynamicsLaw

    Raises
    ------
    DimensionError
        Wrong number of controlled states.
    SpecError
        Unknown state, negative rate.
    InfeasibleDesign
        ``G_c(x)`` singular somewhere on the region (named).
    """
    f0, G = control_affine(plant.f, plant.u)
    names = [s.name for s in plant.states]
    chosen = list(controlled) if controlled is not None else _default_controlled(plant, G)
    unknown = [c for c in chosen if c not in names]
    if unknown:
        raise SpecError(f"unknown state(s) {unknown}; expected some of {names}", key="controlled")
    if len(chosen) != plant.m:
        raise DimensionError(f"{len(chosen)} controlled states {chosen} for {plant.m} inputs "
                             f"{[s.name for s in plant.inputs]}: the inversion needs one per input")
    idx = [names.index(c) for c in chosen]
    Gc = G.extract(idx, list(range(plant.m)))
    f0c = f0.extract(idx, [0])
    if Gc.free_symbols & set(plant.x):
        pts = region_points(plant, per_axis, samples, 0, 0.02)
        fn = compile_matrix("Gc", Gc.xreplace(plant.parameter_values), [plant.x], ["x"])
        dets = np.linalg.det(_batch(fn, pts)[0])
        k = int(np.argmin(np.abs(dets)))
        if not np.all(np.isfinite(dets)) or np.abs(dets[k]) <= 1e-12 * np.max(np.abs(dets)) or \
                (dets.max() > 0 > dets.min()):
            raise InfeasibleDesign(f"cannot invert the dynamics of {chosen}: the input matrix is "
                                   f"singular near x = {dict(zip(names, pts[k].tolist()))}")
    elif Gc.det() == 0:
        raise InfeasibleDesign(f"cannot invert the dynamics of {chosen}: the inputs do not act "
                               f"independently on them (input matrix {Gc.tolist()} is singular "
                               "everywhere)")
    sps = tuple(sp.Symbol(f"{c}sp", real=True) for c in chosen)
    Cs = tuple(sp.Symbol(f"C{i + 1}", nonnegative=True) for i in range(plant.m))
    desired = sp.Matrix([Cs[i] * (sps[i] - plant.x[j]) for i, j in enumerate(idx)])
    expr = (Gc.inv(method="LU") * (desired - f0c)).applyfunc(sp.expand)
    numeric = expr.xreplace(plant.parameter_values)
    core = compile_matrix("id_core", numeric, [plant.x, sps, Cs], ["x_hat", "h_sp", "C"])
    x = ca.SX.sym("x_hat", plant.n)
    r = ca.SX.sym("h_sp", plant.m)
    c = ca.SX.sym("C", plant.m)
    limits = plant.input_limits
    u = core(x, r, c)
    if saturate:
        u = _saturate(u, limits)
    parametric = ca.Function(name + "_parametric", [x, r, c], [u], ["x_hat", "h_sp", "C"], ["u"])
    Cv = _gains(C, plant.m)
    law = _fix_gains(parametric, Cv, name)
    diagnostics = {"controlled": chosen, "C": Cv.tolist(), "saturated": bool(saturate),
                   "input_limits": limits.tolist(),
                   "law": [f"{plant.inputs[i].name} = {e}" for i, e in enumerate(expr)],
                   "flows_at": "the estimate x_hat (any estimator; the true state in the tuning)"}
    return InverseDynamicsLaw(plant.name, tuple(chosen), Cv, limits, bool(saturate), law, parametric,
                              expr, sps, Cs, diagnostics)


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
    """``(x, h_sp, C) -> (x_next, ise_increment)`` over one control period (ZOH, RK4)."""
    f = plant.compiled.f
    lo, hi = _level_bounds(plant)
    idx = [[s.name for s in plant.states].index(c) for c in law.controlled]
    x = ca.SX.sym("x", plant.n)
    r = ca.SX.sym("h_sp", plant.m)
    c = ca.SX.sym("C", plant.m)
    u = law.parametric(x, r, c)                 # x_hat = x (true state as the estimate)
    h = scenario.ts / scenario.substeps
    s = x
    ise = ca.SX.zeros(plant.m)
    err = lambda v: ca.vertcat(*[(r[i] - v[j]) ** 2 for i, j in enumerate(idx)])  # noqa: E731
    for _ in range(scenario.substeps):
        e0 = err(s)
        k1 = f(s, u)
        k2 = f(s + h / 2 * k1, u)
        k3 = f(s + h / 2 * k2, u)
        k4 = f(s + h * k3, u)
        s = ca.fmin(ca.fmax(s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), lo), hi)
        ise = ise + h / 2 * (e0 + err(s))       # trapezoid on the RK4 grid
    return ca.Function("servo_step", [x, r, c], [s, ise], ["x", "h_sp", "C"], ["x_next", "ise"])


def servo_ise(plant: Plant, law: InverseDynamicsLaw, scenario: ServoScenario,
              gains: Any, _step: ca.Function | None = None) -> np.ndarray:
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

    Returns
    -------
    ndarray, shape (M, m)
        ``int_0^T (h_i,sp - h_i)^2 dt`` (m^2 s), trapezoid on the RK4 grid.
    """
    C = np.atleast_2d(np.asarray(gains, dtype=float))
    M = C.shape[0]
    step = (_step or _servo_step(plant, law, scenario)).map(M, "serial")
    x = np.tile(scenario.x0[:, None], (1, M))
    ise = np.zeros((plant.m, M))
    for sp_k in scenario.setpoints():
        x, inc = step(x, np.tile(sp_k[:, None], (1, M)), C.T)
        ise += np.asarray(inc, dtype=float)
    x = np.asarray(x, dtype=float)
    out = ise.T
    out[~np.all(np.isfinite(x), axis=0)] = np.inf
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
        ISE of each controlled level at ``C``.
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
                          grid: Sequence[float] = tuple(np.round(np.linspace(0.1, 1.0, 10), 10)),
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
    grid : sequence of float
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


# ======================================================================== export
def law_document(law: ca.Function) -> dict:
    """The law as a JSON-friendly document (serialised CasADi Function).

    Returns
    -------
    dict
        ``function`` (name), ``inputs``/``outputs`` (names and sizes),
        ``casadi_serialized`` (``Function.serialize()``) and its sha256.
    """
    text = law.serialize()
    return {"function": law.name(),
            "inputs": [{"name": law.name_in(i), "size": int(law.nnz_in(i))} for i in range(law.n_in())],
            "outputs": [{"name": law.name_out(i), "size": int(law.nnz_out(i))}
                        for i in range(law.n_out())],
            "casadi_serialized": text,
            "sha256": hashlib.sha256(text.encode("ascii")).hexdigest()}


def law_from_document(doc: dict) -> ca.Function:
    """Rebuild the CasADi Function from `law_document` output (checks the sha256).

    Raises
    ------
    ArtefactError
        Missing or altered serialisation.
    """
    text = doc.get("casadi_serialized") if isinstance(doc, dict) else None
    if not isinstance(text, str):
        raise ArtefactError("law document has no 'casadi_serialized' string")
    if doc.get("sha256") and hashlib.sha256(text.encode("ascii")).hexdigest() != doc["sha256"]:
        raise ArtefactError("serialised law does not match its sha256 (edited after design?)")
    try:
        return ca.Function.deserialize(text)
    except RuntimeError as exc:
        raise ArtefactError(f"cannot deserialise the law: {exc}") from None


def _c_ident(text: str) -> str:
    ident = "".join(c if (c.isascii() and c.isalnum()) else "_" for c in str(text))
    return ident if ident[:1].isalpha() else "law_" + ident


def rename_law(law: ca.Function, name: str) -> ca.Function:
    """The same SX law under another (C-identifier) name."""
    ins = [ca.SX.sym(law.name_in(i), law.sparsity_in(i)) for i in range(law.n_in())]
    outs = law.call(ins)
    return ca.Function(_c_ident(name), ins, outs, law.name_in(), law.name_out())


@dataclass(frozen=True)
class ExportedLaw:
    """Files of an exported law.

    Attributes
    ----------
    function : str
        C symbol / CasADi Function name.
    casadi : Path
        ``<name>.casadi`` (``Function.save``; load with ``casadi.Function.load``).
    c_source, c_header : Path
        ``<name>.c`` and ``<name>.h`` (CasADi codegen; ``int <function>(const
        casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w,
        int mem)`` plus the work-size helpers).
    sha256 : dict
        sha256 of each file.
    """

    function: str
    casadi: Path
    c_source: Path
    c_header: Path
    sha256: dict


def export_law(law: ca.Function, directory: str | Path, name: str | None = None) -> ExportedLaw:
    """Write the law as ``<name>.casadi``, ``<name>.c`` and ``<name>.h``, atomically.

    Everything is generated in a temporary directory beside the targets and
    renamed only when all files exist; a failure leaves nothing behind.

    Parameters
    ----------
    law : casadi.Function
        An SX Function (as built by this module).
    directory : str or Path
        Created if missing.
    name : str, optional
        File stem and C symbol (made a C identifier); default the law's name.

    Returns
    -------
    ExportedLaw
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    fn = rename_law(law, name or law.name())
    stem = fn.name()
    final = {ext: directory / f"{stem}{ext}" for ext in (".casadi", ".c", ".h")}
    # CasADi's code generator refuses an output prefix that contains
    # "<stem>.c" (a guard for its old API); such a target directory is built
    # in the system temp directory, then copied beside the targets.
    tmpdir = Path(tempfile.mkdtemp(prefix=".law-build-", suffix=".tmp", dir=directory))
    build = tmpdir
    renamed: list[Path] = []
    try:
        if f"{stem}.c" in str(tmpdir) + os.sep:
            build = Path(tempfile.mkdtemp(prefix="tanksynth-law-"))
        fn.save(str(build / f"{stem}.casadi"))
        cg = ca.CodeGenerator(f"{stem}.c", {"with_header": True})
        cg.add(fn)
        cg.generate(str(build) + os.sep)
        for ext, target in final.items():
            if not (build / target.name).is_file():
                raise ArtefactError(f"export of law '{stem}': {target.name} was not generated")
            if build != tmpdir:
                shutil.copyfile(build / target.name, tmpdir / target.name)
        try:
            for ext in (".c", ".h", ".casadi"):
                os.replace(tmpdir / final[ext].name, final[ext])
                renamed.append(final[ext])
        except BaseException:
            for path in renamed:
                path.unlink(missing_ok=True)
            raise
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
        if build != tmpdir:
            shutil.rmtree(build, ignore_errors=True)
    digests = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in final.values()}
    return ExportedLaw(stem, final[".casadi"], final[".c"], final[".h"], digests)


def compile_law(c_source: str | Path, output: str | Path | None = None, *, compiler: str = "gcc",
                flags: Sequence[str] = ("-O2",)) -> Path:
    """Compile generated C into a shared library.

    Parameters
    ----------
    c_source : str or Path
        ``<name>.c`` from `export_law`.
    output : str or Path, optional
        Library path (default ``<name>.so`` beside the source).
    compiler : str
        C compiler command.
    flags : sequence of str
        Extra flags (``-shared -fPIC`` are always added).

    Returns
    -------
    Path

    Raises
    ------
    ArtefactError
        Compiler missing or compilation failed (with its message).
    """
    src = Path(c_source)
    out = Path(output) if output is not None else src.with_suffix(".so")
    cmd = [compiler, "-shared", "-fPIC", *flags, "-o", str(out), str(src), "-lm"]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    except FileNotFoundError:
        raise ArtefactError(f"C compiler {compiler!r} not found; cannot compile {src}") from None
    if proc.returncode != 0:
        raise ArtefactError(f"compiling {src} failed ({' '.join(cmd)}): {proc.stderr.strip()[:2000]}")
    return out


def load_compiled_law(library: str | Path, function: str) -> ca.Function:
    """Load a compiled law (``casadi.external``) to evaluate the C code from Python."""
    path = Path(library)
    if not path.is_file():
        raise ArtefactError(f"compiled law {path} not found")
    return ca.external(function, str(path.resolve()))
