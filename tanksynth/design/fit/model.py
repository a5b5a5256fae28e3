"""The plant as the fit sees it: the simulator's step with the free parameters as CasADi symbols.

`FitModel` rebuilds the plant's vector field and output map with the free parameters left
symbolic (`tanksynth.plants.compile.to_casadi`) and the fixed ones at the plant's values, and
discretises it exactly as `tanksynth.sim` does between two samples: ``substeps`` classical RK4
steps (`tanksynth.plants.compile.rk4_step`, the toolbox's one formula) of ``dt / substeps``,
stage states and every end state clipped to `Plant.state_bounds`, the held input saturated
to the actuators' range. The step length ``dt`` is an argument, so non-uniform sampling is
the same step with another ``dt``.
"""

from __future__ import annotations

import contextlib
import io

from dataclasses import dataclass
from typing import Any, Protocol, Sequence

import casadi as ca
import numpy as np
import sympy as sp

from tanksynth.errors import SpecError
from tanksynth.plants.base import Plant, exact
from tanksynth.plants.compile import rk4_step, to_casadi

__all__ = ["FreeParameterLike", "FitModel", "fit_model", "direct_states", "quiet_solve"]


class FreeParameterLike(Protocol):
    """What the fit reads of a free parameter (``tanksynth.spec.FreeParameter`` has it).

    Attributes
    ----------
    name : str
        Plant parameter name.
    start : float
        Starting value (parameter unit).
    lower, upper : float
        Search box (parameter unit), ``lower < upper``.
    unit : str
        The parameter's unit.
    """

    @property
    def name(self) -> str: ...  # noqa: D102

    @property
    def start(self) -> float: ...  # noqa: D102

    @property
    def lower(self) -> float: ...  # noqa: D102

    @property
    def upper(self) -> float: ...  # noqa: D102

    @property
    def unit(self) -> str: ...  # noqa: D102


@dataclass(frozen=True)
class FitModel:
    """The plant's sampled model with symbolic free parameters.

    Attributes
    ----------
    names : tuple of str
        Free parameter names, in the order of ``theta``.
    lower, upper, start : ndarray, shape (k,)
        Box and starting point (parameter units).
    step : casadi.Function
        ``(x (n), u (m), dt (1), theta (k)) -> x_next (n)``: one sampling interval of ``dt``
        seconds under the held (saturated) input, ``substeps`` clipped RK4 steps.
    output : casadi.Function
        ``(x (n), theta (k)) -> y (q)``: all the plant's outputs.
    n, m, q : int
        Numbers of states, inputs and outputs.
    substeps : int
        RK4 steps per sampling interval.
    state_lower, state_upper : ndarray, shape (n,)
        The clipping bounds at the plant's values (``-inf``/``inf`` where none).
    output_names : tuple of str
        The plant's output names (rows of ``output``).
    """

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    start: np.ndarray
    step: ca.Function
    output: ca.Function
    n: int
    m: int
    q: int
    substeps: int
    state_lower: np.ndarray
    state_upper: np.ndarray
    output_names: tuple[str, ...] = ()


def _free_arrays(plant: Plant, free: Sequence[FreeParameterLike], allow_empty: bool = False
                 ) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, np.ndarray]:
    """Names, lower, upper and start of the free parameters, checked against the plant."""
    known = {prm.name for prm in plant.parameters}
    names: list[str] = []
    for p in free:
        key = f"plant.parameters.{p.name}"
        if p.name not in known:
            raise SpecError(f"free parameter {p.name!r} is not a parameter of plant '{plant.name}'; "
                            f"expected one of: {', '.join(sorted(known))}", key=key)
        if p.name in names:
            raise SpecError(f"free parameter {p.name!r} is given twice", key=key)
        lo, hi, st = float(p.lower), float(p.upper), float(p.start)
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise SpecError(f"free parameter {p.name}: the box [{lo:g}, {hi:g}] must be finite with "
                            "min < max", key=key)
        if not lo <= st <= hi:
            raise SpecError(f"free parameter {p.name}: start {st:g} is outside [{lo:g}, {hi:g}]", key=key)
        names.append(p.name)
    if not names and not allow_empty:
        raise SpecError("no free parameter to fit (mark some with fit = true)", key="plant.parameters")
    return (tuple(names), np.array([float(p.lower) for p in free], dtype=float),
            np.array([float(p.upper) for p in free], dtype=float),
            np.array([float(p.start) for p in free], dtype=float))


def fit_model(plant: Plant, free: Sequence[FreeParameterLike], substeps: int = 4, *,
              allow_empty: bool = False) -> FitModel:
    """Build the plant's sampled model with the free parameters symbolic.

    Parameters
    ----------
    plant : Plant
        The plant (fixed parameters at its values).
    free : sequence of FreeParameterLike
        The parameters to estimate (name, start, lower, upper, unit).
    substeps : int
        RK4 steps per sampling interval (as ``substeps`` of `tanksynth.sim.simulate`).
    allow_empty : bool
        Accept no free parameter (a model of the plant at its values, e.g. to fit an initial
        state only).

    Returns
    -------
    FitModel

    Raises
    ------
    SpecError
        An unknown or repeated name, a bad box or start, ``substeps < 1``.
    """
    names, lower, upper, start = _free_arrays(plant, free, allow_empty)
    if int(substeps) < 1:
        raise SpecError(f"substeps must be >= 1, got {substeps}", key="substeps")
    substeps = int(substeps)
    n, m, q, k = plant.n, plant.m, plant.q, len(names)
    xs, us, th = ca.SX.sym("x", n), ca.SX.sym("u", m), ca.SX.sym("theta", k)
    dt = ca.SX.sym("dt")
    fixed = {plant.p[prm.name]: exact(prm.value) for prm in plant.parameters if prm.name not in names}
    symbols: dict[sp.Symbol, Any] = {plant.p[nm]: th[i] for i, nm in enumerate(names)}
    symbols.update({s: xs[i] for i, s in enumerate(plant.x)})
    symbols.update({s: us[i] for i, s in enumerate(plant.u)})
    cache: dict = {}

    def build(matrix: sp.Matrix, args: dict) -> ca.SX:
        rows = [to_casadi(e, args, cache) if e != 0 else ca.SX(0.0) for e in matrix.xreplace(fixed)]
        return ca.vertcat(*rows) if rows else ca.SX(0, 1)

    f_expr = build(plant.f, symbols)
    h_expr = build(plant.h, {s: v for s, v in symbols.items() if s not in set(plant.u)})
    f_fun = ca.Function("f", [xs, us, th], [f_expr])
    # bounds: the plant's clipping rule and actuator range; a bound naming a free parameter
    # (hmax, qmax) moves with it
    values = {prm.name: prm.value for prm in plant.parameters}
    lo_x, hi_x = plant.state_bounds()

    def bound(b: float | str) -> Any:
        if isinstance(b, str):
            return th[names.index(b)] if b in names else float(values[b])
        return float(b)

    upper_x: list[Any] = [float(v) for v in hi_x]
    if "hmax" in names:
        upper_x = [th[names.index("hmax")]] * n
    held = []
    for i in range(m):
        v = us[i]
        if plant.input_bounds:
            lo_b, hi_b = (bound(b) for b in plant.input_bounds[i])
            if not (isinstance(lo_b, float) and not np.isfinite(lo_b)):
                v = ca.fmax(v, lo_b)
            if not (isinstance(hi_b, float) and not np.isfinite(hi_b)):
                v = ca.fmin(v, hi_b)
        held.append(v)
    u_held = ca.vertcat(*held) if held else us

    def clip(v: Any) -> Any:
        parts = []
        for i in range(n):
            c = v[i]
            if np.isfinite(lo_x[i]):
                c = ca.fmax(c, float(lo_x[i]))
            if not (isinstance(upper_x[i], float) and not np.isfinite(upper_x[i])):
                c = ca.fmin(c, upper_x[i])
            parts.append(c)
        return ca.vertcat(*parts)

    h = dt / substeps
    s = xs
    for _ in range(substeps):
        s = clip(rk4_step(lambda z: f_fun(z, u_held, th), s, h, clip))
    step = ca.Function("fit_step", [xs, us, dt, th], [s], ["x", "u", "dt", "theta"], ["x_next"])
    output = ca.Function("fit_output", [xs, th], [h_expr], ["x", "theta"], ["y"])
    return FitModel(names, lower, upper, start, step, output, n, m, q, substeps,
                    np.asarray(lo_x, dtype=float), np.asarray(hi_x, dtype=float),
                    tuple(o.name for o in plant.outputs))


def direct_states(model: FitModel, theta: np.ndarray) -> dict[int, tuple[int, float, float]]:
    """Outputs that measure one state affinely: ``y_j = a x_i + b`` (``a``, ``b`` may depend on
    the parameters, e.g. a sensor gain ``kc*h1`` or an offset ``h2 + b2``).

    An output counts when its Jacobian in the states has one nonzero entry, the same at two
    probe states (affine in that state, independent of the others).

    Parameters
    ----------
    model : FitModel
        The sampled model.
    theta : ndarray, shape (k,)
        Parameter values at which ``a`` and ``b`` are evaluated (parameter units).

    Returns
    -------
    dict
        Output index -> ``(state index, a, b)``: the state is ``(y - b) / a`` (state units).
    """
    x = ca.SX.sym("x", model.n)
    th = np.asarray(theta, dtype=float).ravel()
    y = model.output(x, ca.DM(th))
    jac = ca.Function("jy", [x], [ca.jacobian(y, x), y])
    out: dict[int, tuple[int, float, float]] = {}
    probes = [np.linspace(0.3, 0.7, model.n), np.linspace(0.55, 0.15, model.n)]
    evals = [tuple(np.asarray(v, dtype=float) for v in jac(p)) for p in probes]
    (A1, y1), (A2, _) = evals
    for j in range(model.q):
        nz = np.flatnonzero(np.abs(A1[j]) > 0)
        if nz.size != 1 or not np.all(np.isfinite(A1[j])) or not np.allclose(A1[j], A2[j], rtol=1e-12,
                                                                               atol=0.0):
            continue
        i = int(nz[0])
        a = float(A1[j, i])
        b = float(y1.ravel()[j] - a * probes[0][i])
        if np.isfinite(a) and np.isfinite(b) and a != 0.0:
            out[j] = (i, a, b)
    return out


def quiet_solve(solver: Any, **args: Any) -> Any:
    """Call a CasADi solver with its messages kept off the console.

    CasADi writes its warnings (e.g. ``Inf detected for grad_f``, ``Failed to calculate
    multipliers``) through Python's ``sys.stdout``/``sys.stderr``; the solver's status says
    what went wrong, so the text is dropped.

    Parameters
    ----------
    solver : casadi.Function
        An ``nlpsol`` solver.
    **args
        Its arguments (``x0``, ``lbx``, ...).

    Returns
    -------
    dict
        The solver's outputs.
    """
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        return solver(**args)
