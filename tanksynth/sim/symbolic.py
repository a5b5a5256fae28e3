"""The integrator's step in closed form: CasADi expressions, and a matrix for linear systems.

Part of the one integrator (`tanksynth.sim.integrate`, which re-exports these
names): design code that needs the step as a CasADi expression (the ISE
tuning of the inverse-dynamics gains, laws evaluated at every Runge-Kutta
stage) builds it with `symbolic_rk4` / `casadi_step`; a linear system (the
fault-detection residual of plant and observer) is advanced by
`rk4_matrix`, the same step written as a matrix. Same scheme as the numeric
`tanksynth.sim.integrate.Integrator`: classical RK4
(`tanksynth.plants.compile.rk4_step`), stage states and end states clipped
to `Plant.state_bounds`, inputs saturated; the symbolic step cannot branch
per run, so it returns a ``crossed`` flag when a hybrid mode changed and its
users hand those runs to the numeric integrator.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import numpy as np

from tanksynth.errors import DimensionError
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import rk4_step

__all__ = ["SymbolicStep", "symbolic_rk4", "casadi_step", "rk4_matrix"]


# ----------------------------------------------------------------------------- symbolic
class SymbolicStep(NamedTuple):
    """CasADi expressions of `symbolic_rk4`.

    Attributes
    ----------
    x : casadi.SX, shape (n, 1)
        State after the step (clipped).
    integral : casadi.SX or None
        Trapezoid integral of the integrand over the RK4 grid.
    crossed : casadi.SX, scalar
        1 when a substep changed the hybrid mode (the numeric `Integrator`
        would have located the crossing: hand that run to it), else 0.
    """

    x: Any
    integral: Any
    crossed: Any


def _saturation(plant: Plant) -> Callable[[Any], Any]:
    import casadi as ca

    limits = plant.input_limits

    def sat(u: Any) -> Any:
        out = ca.SX(u) if not isinstance(u, ca.MX) else u
        parts: list[Any] = []   # all SX, or all MX (as ``out``)
        for i, (lo, hi) in enumerate(limits):
            v = out[i]
            if np.isfinite(lo):
                v = ca.fmax(v, lo)
            if np.isfinite(hi):
                v = ca.fmin(v, hi)
            parts.append(v)
        return ca.vertcat(*parts) if parts else out

    return sat


def symbolic_rk4(plant: Plant, x: Any, u: Any, dt: float, substeps: int = 1, *,
                 integrand: Callable[[Any], Any] | None = None) -> SymbolicStep:
    """The integrator's step as CasADi expressions (same scheme as `Integrator`).

    ``substeps`` RK4 steps of ``dt / substeps`` on the compiled plant
    ``plant.compiled.f`` (parameters at the plant's values): stage states and
    every end state clipped to `Plant.state_bounds`, inputs saturated to the
    actuators' range. The mode bits are compared across every substep;
    a change sets ``crossed`` (no location here: the caller must hand such
    runs to the numeric `Integrator`).

    Parameters
    ----------
    plant : Plant
    x : casadi.SX, shape (n, 1)
        State at the start (state units).
    u : casadi.SX or callable
        Input (input units) held over ``dt``, or ``s -> u(s)`` evaluated at
        every RK4 stage (a continuous-time law).
    dt : float
        Length of the step (s).
    substeps : int
        RK4 steps inside ``dt``.
    integrand : callable, optional
        ``s -> g(s)`` (casadi column): its integral over the step by the
        trapezoid rule on the RK4 grid, at the clipped grid states.

    Returns
    -------
    SymbolicStep
    """
    import casadi as ca

    f = plant.compiled.f
    lo, hi = plant.state_bounds()
    lo_dm, hi_dm = ca.DM(lo), ca.DM(hi)
    clip = lambda v: ca.fmin(ca.fmax(v, lo_dm), hi_dm)  # noqa: E731
    sat = _saturation(plant)
    if callable(u):
        rhs = lambda s: f(s, sat(u(s)))  # noqa: E731
    else:
        held = sat(u)
        rhs = lambda s: f(s, held)  # noqa: E731
    switching = plant.compiled.switching
    h = float(dt) / int(substeps)
    s = x
    crossed = ca.SX(0)
    integral = None
    for _ in range(int(substeps)):
        g0 = integrand(s) if integrand is not None else None
        end = rk4_step(rhs, s, h, clip)
        if switching is not None:
            b0, b1 = switching(s) > 0, switching(end) > 0
            for j in range(b0.numel()):
                crossed = ca.logic_or(crossed, b0[j] != b1[j])
        s = clip(end)
        if integrand is not None:
            inc = h / 2 * (g0 + integrand(s))
            integral = inc if integral is None else integral + inc
    return SymbolicStep(s, integral, crossed)


def casadi_step(plant: Plant, dt: float, law: Any = None, substeps: int = 1) -> Any:
    """One step of the integrator as a CasADi Function (`symbolic_rk4`).

    Parameters
    ----------
    plant : Plant
    dt : float
        Step (s), split into ``substeps`` RK4 steps.
    law : casadi.Function, optional
        ``(x, r) -> u, ...``: evaluated at every RK4 stage (a continuous-time
        law). Without it the input is held over the step (zero-order hold).
    substeps : int

    Returns
    -------
    casadi.Function
        ``(x, u) -> (x_next, crossed)`` or ``(x, r) -> (x_next, crossed)``;
        ``crossed`` is 1 when the step changed the hybrid mode (see
        `SymbolicStep`).
    """
    import casadi as ca

    x = ca.SX.sym("x", plant.n)
    if law is None:
        v = ca.SX.sym("u", plant.m)
        u: Any = v
    else:
        v = ca.SX.sym("r", law.size1_in(1))
        u = lambda s: law(s, v)[0] if law.n_out() > 1 else law(s, v)  # noqa: E731
    out = symbolic_rk4(plant, x, u, dt, substeps)
    return ca.Function("rk4_step", [x, v], [out.x, out.crossed],
                       ["x", "u" if law is None else "r"], ["x_next", "crossed"])


# ----------------------------------------------------------------------------- linear
def rk4_matrix(M: Any, h: float) -> np.ndarray:
    """The integrator's RK4 step of a linear system ``dz/dt = M z``, as a matrix.

    `rk4_step` applied to the columns of the identity: ``z(t + h) = R z(t)``
    with ``R = I + hM + (hM)^2/2 + (hM)^3/6 + (hM)^4/24`` (RK4 is exact to
    fourth order). An affine system is written with a constant state
    ``z[-1] = 1``. No clipping: the caller checks that the states stay
    within the plant's bounds.

    Parameters
    ----------
    M : array_like, shape (k, k)
        System matrix (1/s).
    h : float
        Step (s), >= 0.

    Returns
    -------
    ndarray, shape (k, k)
    """
    M = np.asarray(M, dtype=float)
    if M.ndim != 2 or M.shape[0] != M.shape[1]:
        raise DimensionError(f"M must be a square matrix, got shape {M.shape}")
    return rk4_step(lambda Z: M @ Z, np.eye(M.shape[0]), float(h))
