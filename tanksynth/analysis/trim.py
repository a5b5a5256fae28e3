"""Trim: the levels at which given pump flows hold the plant still, and hints for a wrong point.

`tanksynth.analysis.linearize.equilibrium_input` answers "which input holds
these levels?"; tank users usually know the other side: "the pumps run at
these flows, where do the levels settle?". `trim` solves ``f(x, u) = 0`` for
``x`` with ``u`` given, by `scipy.optimize.root` (hybrid Powell with the
model's Jacobian ``df/dx``) from several starting points of the operating
region, and keeps the solution inside the region with the smallest residual;
`trim_outputs` solves for the inputs and levels that give required outputs.
Both live in `tanksynth.plants.trim` (the spec's ``[operating_point] trim``
calls them) and are re-exported here.

For an operating point that is not an equilibrium, `balancing_hint` names the
single-state changes that balance it and `trim_hint` the nearest equilibrium
for the inputs (and the spec line that uses it).
"""

from __future__ import annotations

from dataclasses import dataclass
import numpy as np
import numpy.typing as npt

from tanksynth.errors import DimensionError
from tanksynth.plants.base import Plant
from tanksynth.plants.trim import Trim, trim, trim_outputs

__all__ = ["Trim", "trim", "trim_outputs", "LevelFix", "balancing_levels", "balancing_hint", "trim_hint"]


@dataclass(frozen=True)
class LevelFix:
    """One state changed so that the others stay where the user put them and the plant balances.

    Attributes
    ----------
    state : str
        The state changed.
    value : float
        Its balancing value (state units).
    u : ndarray, shape (m,)
        The equilibrium input there (input units), inside the actuator range.
    max_abs_residual : float
        ``max |f(x, u)|`` at the solution (state units per s).
    """

    state: str
    value: float
    u: np.ndarray
    max_abs_residual: float

    def describe(self, unit: str = "") -> str:
        """``"h3 = 0.325 m"``.

        Parameters
        ----------
        unit : str
            The state's unit (appended when not empty).
        """
        return f"{self.state} = {self.value:.4g}" + (f" {unit}" if unit else "")


def balancing_levels(plant: Plant, x: npt.ArrayLike, tolerance: float) -> list[LevelFix]:
    """Equilibria that differ from ``x`` in one state only (a hint for a wrong operating point).

    For each state ``i``, the other states are held at ``x`` and ``x_i`` and the
    inputs are solved from ``f(x, u) = 0`` (bounded least squares: ``x_i`` in the
    region's box, ``u`` in the actuator range); a solution is kept when its
    residual is within ``tolerance`` and the point satisfies the region.

    Parameters
    ----------
    plant : Plant
    x : array_like, shape (n,)
        The operating point given (state units).
    tolerance : float
        Absolute tolerance on ``max |f(x, u)|`` (state units per s), e.g. the
        equilibrium check's.

    Returns
    -------
    list of LevelFix
        Sorted by the size of the change relative to the state's range; empty
        when no single state can balance the plant.
    """
    from scipy.optimize import least_squares  # deferred: only for an operating point that is wrong

    level = np.asarray(x, dtype=float).reshape(-1)   # the operating point given
    if level.size != plant.n or not np.all(np.isfinite(level)):
        raise DimensionError(f"x must have {plant.n} finite entries, got {level.tolist()}")
    comp = plant.compiled
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    ulim = np.asarray(plant.input_limits, dtype=float).reshape(plant.m, 2)
    fixes = []
    for i, st in enumerate(plant.states):
        if not lo[i] < hi[i]:
            continue

        def point(z, i=i):
            xi = level.copy()
            xi[i] = z[0]
            return xi, z[1:]

        def fun(z):
            xi, u = point(z)
            return comp.rhs(xi[None], u[None])[0]

        def jac(z, i=i):
            xi, u = point(z)
            A, B = (J[0] for J in comp.jacobians(xi[None], u[None]))
            return np.column_stack([A[:, i], B])

        z0 = np.concatenate([[np.clip(level[i], lo[i], hi[i])], ulim.mean(axis=1)])
        with np.errstate(all="ignore"):
            try:
                sol = least_squares(fun, z0, jac=jac, bounds=(np.r_[lo[i], ulim[:, 0]],
                                                              np.r_[hi[i], ulim[:, 1]]),
                                    xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200)
            except ValueError:
                continue
        xi, u = point(sol.x)
        r = fun(sol.x)
        if not np.all(np.isfinite(r)) or float(np.max(np.abs(r))) > tolerance:
            continue
        if (plant.region.violations(xi, plant.x)
                or abs(xi[i] - level[i]) <= 1e-12 * max(1.0, abs(level[i]))):
            continue
        fixes.append((abs(xi[i] - level[i]) / (hi[i] - lo[i]),
                      LevelFix(st.name, float(xi[i]), np.asarray(u, dtype=float),
                               float(np.max(np.abs(r))))))
    return [f for _, f in sorted(fixes, key=lambda t: t[0])]


def balancing_hint(plant: Plant, x: npt.ArrayLike, tolerance: float) -> str:
    """One sentence naming the single-state changes that make ``x`` an equilibrium ("" if none).

    Parameters
    ----------
    plant : Plant
    x : array_like, shape (n,)
        The operating point given (state units).
    tolerance : float
        Absolute tolerance on ``max |f(x, u)|`` (state units per s).

    Returns
    -------
    str
        E.g. ``"the plant balances with h3 = 0.325 m (or h1 = 0.55 m), the other
        levels as given"``.
    """
    fixes = balancing_levels(plant, x, tolerance)
    if not fixes:
        return ""
    units = {s.name: s.unit for s in plant.states}
    first, rest = fixes[0], fixes[1:]
    text = f"the plant balances with {first.describe(units[first.state])}"
    if rest:
        text += " (or " + ", or ".join(f.describe(units[f.state]) for f in rest) + ")"
    return text + ", the other states as given"


def trim_hint(plant: Plant, x: npt.ArrayLike, u: npt.ArrayLike, u_given: bool = True) -> str:
    """The nearest equilibrium for inputs ``u`` and the spec lines that use it ("" if none).

    `trim` from ``x`` first (so the equilibrium the solver reaches first is the
    one nearest the levels written).

    Parameters
    ----------
    plant : Plant
    x : array_like, shape (n,)
        The operating levels given (state units).
    u : array_like, shape (m,)
        The inputs (input units): the spec's ``u``, or the least-squares input.
    u_given : bool
        ``u`` is the spec's own (else the hint also says to write it).

    Returns
    -------
    str
        E.g. ``'nearest equilibrium for these inputs (u1 = 3 V, u2 = 3 V): h1 = 12.263 cm,
        h2 = 12.7832 cm, h3 = 1.63394 cm, h4 = 1.40904 cm; write trim = "states" in
        [operating_point] to use it (x, if kept, is then only the solver's start)'``.
    """
    found = trim(plant, u, x_guess=x)
    if not found.converged:
        return ""

    def unit(q) -> str:
        return "" if str(q.unit) in ("", "1", "-") else f" {q.unit}"

    inputs = ", ".join(f"{q.name} = {v:.6g}{unit(q)}" for q, v in zip(plant.inputs, found.u))
    levels = ", ".join(f"{s.name} = {v:.6g}{unit(s)}" for s, v in zip(plant.states, found.x))
    write = ('write trim = "states" in [operating_point] (Python: tanksynth.design(..., '
             'trim="states"))' if u_given else
             'write u = {' + ", ".join(f"{q.name} = {v:.6g}" for q, v in zip(plant.inputs, found.u))
             + '} and trim = "states" in [operating_point]')
    return (f"nearest equilibrium for these inputs ({inputs}): {levels}; {write} to use it "
            "(x, if kept, is then only the solver's start)")
