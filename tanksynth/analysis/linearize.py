"""Equilibrium, linearisation and exact ZOH discretisation.

The numeric matrices come from the compiled CasADi functions (automatic
differentiation of the symbolic model); the symbolic Jacobians (for reports
and errata) come from `symbolic_jacobians`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import sympy as sp

from tanksynth.errors import DimensionError, SpecError
from tanksynth.plants.base import Plant
from tanksynth.analysis.blas import small_dense
from tanksynth.analysis.symbolic import jacobian

__all__ = [
    "Equilibrium",
    "equilibrium_input",
    "LinearModel",
    "linearize",
    "discretize_zoh",
    "symbolic_jacobians",
]


@dataclass(frozen=True)
class Equilibrium:
    """Input that holds the plant at given levels, with its balance residual.

    Attributes
    ----------
    x0 : ndarray, shape (n,)
        Levels (state units).
    u0 : ndarray, shape (m,)
        Least-squares input (input units; exact when the system is square and
        solvable).
    residual : ndarray, shape (n,)
        ``f(x0, u0)`` in state units per second; zero at a true equilibrium.
    is_equilibrium : bool
        ``|residual|`` below ``tolerance``.
    tolerance : float
        Absolute tolerance used on ``max |residual|``.
    within_bounds : bool
        ``u0`` inside the actuators' range.
    given_u0 : ndarray or None
        A user-given input (e.g. a paper's printed value), if any.
    given_residual : ndarray or None
        ``f(x0, given_u0)``: non-zero when the given input does not balance
        the model (seed 000's printed u0 does not).
    """

    x0: np.ndarray
    u0: np.ndarray
    residual: np.ndarray
    is_equilibrium: bool
    tolerance: float
    within_bounds: bool
    given_u0: np.ndarray | None = None
    given_residual: np.ndarray | None = None

    def as_dict(self) -> dict:
        """JSON-friendly form for artefact diagnostics."""
        out = {
            "x0": self.x0.tolist(), "u0": self.u0.tolist(), "residual": self.residual.tolist(),
            "max_abs_residual": float(np.max(np.abs(self.residual))),
            "is_equilibrium": self.is_equilibrium, "tolerance": self.tolerance,
            "within_input_bounds": self.within_bounds,
        }
        if self.given_u0 is not None and self.given_residual is not None:  # set together
            out["given_u0"] = self.given_u0.tolist()
            out["given_u0_residual"] = self.given_residual.tolist()
            out["given_u0_balances"] = bool(np.max(np.abs(self.given_residual)) <= self.tolerance)
        return out


def _vector(value: npt.ArrayLike, size: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.size != size:
        raise DimensionError(f"{name} has {arr.size} entries, expected {size}")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def equilibrium_input(plant: Plant, x0: npt.ArrayLike, given_u0: npt.ArrayLike | None = None,
                      tolerance: float | None = None) -> Equilibrium:
    """Input balancing ``f(x0, u) = 0`` (least squares when over-determined).

    Parameters
    ----------
    plant : Plant
    x0 : array_like, shape (n,)
        Levels in the state units.
    given_u0 : array_like, shape (m,), optional
        An input to check against the model (its residual is reported).
    tolerance : float, optional
        Absolute tolerance on ``max |f(x0, u0)|`` (state units/s). Default:
        ``1e-6`` times the largest term ``|f0|, |G u0|`` (at least 1e-15),
        i.e. levels given to about seven significant digits balance.

    Returns
    -------
    Equilibrium
    """
    x = _vector(x0, plant.n, "x0")
    comp = plant.compiled
    zero = np.zeros((1, plant.m))
    f0 = comp.rhs(x[None], zero)[0]
    G = comp.jacobians(x[None], zero)[1][0]
    with small_dense():   # an n x m least-squares problem: one BLAS thread
        u0, *_ = np.linalg.lstsq(G, -f0, rcond=None)
    # One Newton refinement in case the model is not affine in u.
    for _ in range(5 if plant.m else 0):  # no inputs (autonomous plant): nothing to solve
        r = comp.rhs(x[None], u0[None])[0]
        Gk = comp.jacobians(x[None], u0[None])[1][0]
        with small_dense():
            step, *_ = np.linalg.lstsq(Gk, -r, rcond=None)
        u0 = u0 + step
        if np.max(np.abs(step)) <= 1e-15 * (1 + np.max(np.abs(u0))):
            break
    residual = comp.rhs(x[None], u0[None])[0]
    scale = max(np.max(np.abs(f0)), np.max(np.abs(G @ u0)) if u0.size else 0.0)
    tol = float(tolerance) if tolerance is not None else float(max(1e-6 * scale, 1e-15))
    within = bool(all(lo - 1e-12 <= v <= hi + 1e-12 for v, (lo, hi) in zip(u0, plant.input_limits)))
    given = given_res = None
    if given_u0 is not None:
        given = _vector(given_u0, plant.m, "given u0")
        given_res = comp.rhs(x[None], given[None])[0]
    return Equilibrium(x, u0, residual, bool(np.max(np.abs(residual)) <= tol), tol, within,
                       given, given_res)


@dataclass(frozen=True)
class LinearModel:
    """Linearisation ``dx/dt = F dx + B du``, ``dy = C dx`` about ``(x0, u0)``.

    Attributes
    ----------
    F, B, C : ndarray
        Continuous-time matrices (units: 1/s; state unit per input unit per s).
    x0, u0 : ndarray
        Operating point (state and input units).
    offset : ndarray
        ``f(x0, u0)``, zero at an equilibrium (the affine term otherwise).
    ts : float or None
        Sampling period (s) when discretised.
    Ad, Bd : ndarray or None
        Exact ZOH discretisation with period ``ts`` (``Ad`` dimensionless,
        ``Bd`` in state units per input unit).
    state_names, input_names, output_names : tuple of str
        Signal names (the plant's), used by `to_statespace`.
    """

    F: np.ndarray
    B: np.ndarray
    C: np.ndarray
    x0: np.ndarray
    u0: np.ndarray
    offset: np.ndarray
    ts: float | None = None
    Ad: np.ndarray | None = None
    Bd: np.ndarray | None = None
    state_names: tuple[str, ...] = ()
    input_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()

    @property
    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues of ``F`` (1/s)."""
        return np.linalg.eigvals(self.F)

    def to_statespace(self, discrete: bool | None = None) -> Any:
        """The deviation model as a python-control `StateSpace` (names, ``dt``).

        Parameters
        ----------
        discrete : bool, optional
            ``True``: the ZOH model ``(Ad, Bd, C, 0)`` with ``dt = ts`` (s);
            ``False``: ``(F, B, C, 0)`` in continuous time; default: discrete
            when the model was discretised.

        Returns
        -------
        control.StateSpace
            States, inputs and outputs named as the plant's (deviations from
            ``x0``, ``u0``).

        Raises
        ------
        SpecError
            ``discrete=True`` for a model without a sampling period.
        """
        import control

        if discrete is None:
            discrete = self.Ad is not None
        dt: float   # 0: continuous time, as python-control reads it
        if not discrete:
            A, B, dt = self.F, self.B, 0
        elif self.Ad is None or self.Bd is None or self.ts is None:
            raise SpecError("the linear model was not discretised: linearize(..., ts=...) first",
                            key="sampling.ts")
        else:
            A, B, dt = self.Ad, self.Bd, float(self.ts)
        D = np.zeros((self.C.shape[0], B.shape[1]))
        kw: dict[str, Any] = {}
        for key, names, size in (("states", self.state_names, A.shape[0]),
                                 ("inputs", self.input_names, B.shape[1]),
                                 ("outputs", self.output_names, self.C.shape[0])):
            if len(names) == size:
                kw[key] = list(names)
        return control.ss(A, B, self.C, D, dt, **kw)


def linearize(plant: Plant, x0: npt.ArrayLike, u0: npt.ArrayLike, ts: float | None = None) -> LinearModel:
    """Jacobian linearisation of a plant, optionally ZOH-discretised.

    Parameters
    ----------
    plant : Plant
    x0 : array_like, shape (n,)
        Operating state (state units, e.g. m).
    u0 : array_like, shape (m,)
        Operating input (input units, e.g. m^3/s).
    ts : float, optional
        Sampling period in s; if given, ``Ad`` and ``Bd`` are filled.

    Returns
    -------
    LinearModel
    """
    x = _vector(x0, plant.n, "x0")
    u = _vector(u0, plant.m, "u0")
    comp = plant.compiled
    F, B = comp.jacobians(x[None], u[None])
    C = np.asarray(comp.jac_h(x)).reshape(plant.q, plant.n)
    offset = comp.rhs(x[None], u[None])[0]
    Ad = Bd = None
    if ts is not None:
        Ad, Bd = discretize_zoh(F[0], B[0], ts)
    return LinearModel(F[0], B[0], C, x, u, offset, ts, Ad, Bd,
                       tuple(s.name for s in plant.states), tuple(s.name for s in plant.inputs),
                       tuple(s.name for s in plant.outputs))


def discretize_zoh(F: np.ndarray, B: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation (seed 000 eq. 11).

    ``Ad = exp(F ts)``, ``Bd = int_0^ts exp(F s) ds B``, both from one
    matrix exponential of ``[[F, B], [0, 0]] ts``.

    Parameters
    ----------
    F : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    ts : float
        Sampling period in s (> 0).
    """
    F = np.atleast_2d(np.asarray(F, dtype=float))
    B = np.asarray(B, dtype=float).reshape(F.shape[0], -1)
    if not (isinstance(ts, (int, float)) and np.isfinite(ts) and ts > 0):
        raise SpecError(f"sampling period must be a positive number of seconds, got {ts!r}",
                        key="sampling.ts")
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = F
    M[:n, n:] = B
    with small_dense():
        E = sla.expm(M * ts)
    return E[:n, :n], E[:n, n:]


def symbolic_jacobians(plant: Plant, smooth: bool = True) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    """Symbolic ``df/dx``, ``df/du``, ``dh/dx`` in states and parameters.

    Parameters
    ----------
    plant : Plant
    smooth : bool
        Differentiate the region's smooth form (sign/abs resolved by the
        flow-direction assumptions) rather than the general model.
    """
    f = plant.f_smooth if smooth else plant.f
    return jacobian(f, plant.x), jacobian(f, plant.u), jacobian(plant.h, plant.x)

