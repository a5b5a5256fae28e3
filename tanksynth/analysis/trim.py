"""Trim: the levels at which given pump flows hold the plant still.

`tanksynth.analysis.linearize.equilibrium_input` answers "which input holds
these levels?"; tank users usually know the other side: "the pumps run at
these flows, where do the levels settle?". `trim` solves ``f(x, u) = 0`` for
``x`` with ``u`` given, by `scipy.optimize.root` (hybrid Powell with the
model's Jacobian ``df/dx``) from several starting points of the operating
region, and keeps the solution inside the region with the smallest residual.
"""

from __future__ import annotations

from dataclasses import dataclass
import numpy as np
import numpy.typing as npt

from tanksynth.errors import DimensionError
from tanksynth.plants.base import Plant

__all__ = ["Trim", "trim", "LevelFix", "balancing_levels", "balancing_hint"]


@dataclass(frozen=True)
class Trim:
    """Levels that balance given inputs, with the evidence.

    Attributes
    ----------
    x : ndarray, shape (n,)
        Levels (state units) with ``f(x, u) = 0``.
    u : ndarray, shape (m,)
        The given inputs (input units).
    residual : ndarray, shape (n,)
        ``f(x, u)`` (state units per s) at the solution.
    converged : bool
        ``max |residual| <= tolerance`` and ``x`` inside the operating region.
    tolerance : float
        Absolute tolerance on ``max |f|`` (state units/s).
    in_region : bool
        ``x`` satisfies the region's bounds and orderings.
    violations : tuple of str
        Region conditions ``x`` violates (empty when inside).
    starts : int
        Starting points tried.
    """

    x: np.ndarray
    u: np.ndarray
    residual: np.ndarray
    converged: bool
    tolerance: float
    in_region: bool
    violations: tuple[str, ...]
    starts: int

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"x": self.x.tolist(), "u": self.u.tolist(), "residual": self.residual.tolist(),
                "max_abs_residual": float(np.max(np.abs(self.residual))),
                "converged": self.converged, "tolerance": self.tolerance,
                "in_region": self.in_region, "violations": list(self.violations),
                "starts": self.starts}


def trim(plant: Plant, u: npt.ArrayLike, x_guess: npt.ArrayLike | None = None,
         starts: int = 20, seed: int = 0, tolerance: float | None = None) -> Trim:
    """Levels ``x`` with ``f(x, u) = 0`` for given inputs ``u`` (root finding on the model).

    Parameters
    ----------
    plant : Plant
    u : array_like, shape (m,)
        Inputs (pump flows) in the input units.
    x_guess : array_like, shape (n,), optional
        First starting point (state units); then the region's centre and
        ``starts`` seeded samples of the region.
    starts : int
        Sampled starting points (>= 0).
    seed : int
        Seed of the sampling.
    tolerance : float, optional
        Absolute tolerance on ``max |f(x, u)|`` (state units/s); default
        ``1e-9`` times the largest input term ``max |df/du u|`` (at least 1e-15).

    Returns
    -------
    Trim
        The best solution found (``converged`` False when no start reached
        the tolerance inside the region: the inputs cannot hold the plant in
        its region, e.g. more inflow than the outlets can drain).
    """
    from scipy.optimize import root  # deferred: scipy.optimize imports in ~0.15 s
    u_vec = np.asarray(u, dtype=float).reshape(-1)
    if u_vec.size != plant.m or not np.all(np.isfinite(u_vec)):
        raise DimensionError(f"u must have {plant.m} finite entries, got {u_vec.tolist()}")
    comp = plant.compiled
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    points = []
    if x_guess is not None:
        g = np.asarray(x_guess, dtype=float).reshape(-1)
        if g.size != plant.n:
            raise DimensionError(f"x_guess has {g.size} entries, expected {plant.n}")
        points.append(g)
    try:
        points += list(plant.region.sample(max(int(starts), 1), plant.x, seed=seed, margin=0.01))
    except Exception:  # a region too thin to sample: the box centre only
        pass
    points.append(0.5 * (lo + hi))
    G = comp.jacobians(points[-1][None], u_vec[None])[1][0]
    scale = float(np.max(np.abs(G @ u_vec))) if u_vec.size else 0.0
    tol = float(tolerance) if tolerance is not None else max(1e-9 * scale, 1e-15)

    def fun(x):
        return comp.rhs(x[None], u_vec[None])[0]

    def jac(x):
        return comp.jacobians(x[None], u_vec[None])[0][0]

    best = None
    for x0 in points:
        with np.errstate(all="ignore"):
            sol = root(fun, x0, jac=jac, method="hybr", options={"xtol": 1e-14})
        x = np.asarray(sol.x, dtype=float)
        if not np.all(np.isfinite(x)):
            continue
        r = fun(x)
        if not np.all(np.isfinite(r)):
            continue
        bad = tuple(plant.region.violations(x, plant.x))
        key = (len(bad) > 0, float(np.max(np.abs(r))))
        if best is None or key < best[0]:
            best = (key, x, r, bad)
        if not bad and key[1] <= tol:
            break
    if best is None:
        x = points[-1]
        return Trim(x, u_vec, fun(x), False, tol, False, ("no start converged",), len(points))
    (_, worst), x, r, bad = best
    return Trim(x, u_vec, r, bool(not bad and worst <= tol), tol, not bad, bad, len(points))


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
