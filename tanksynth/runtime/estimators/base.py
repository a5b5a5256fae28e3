"""Common machinery of the state estimators: one interface, single and batch runs.

Every estimator is built from a plant and a frozen *tuning* (the artefact:
gains, ``Q``, ``R``, ``P0``, window, weights) and runs through the same
interface:

* ``est.step(y, u) -> x_hat`` for one run (``y`` shape (q,), ``u`` shape
  (m,), result shape (n,)), or, for an estimator made with ``runs=M``, for
  ``M`` independent runs at once (``y`` (M, q), ``u`` (M, m) or (m,),
  result (M, n)). ``est.batch(M)`` makes the batch twin of a single-run
  estimator; a batch run equals ``M`` single runs bit for bit.
* ``u`` is the input held over the sampling interval that ends at the
  measurement ``y`` (seed 000 eq. 30 and seed 002 eq. 13 both predict
  ``x(k|k-1) = F(x(k-1), u(k))``): a simulator that applies ``u[k-1]`` on
  ``[t_{k-1}, t_k)`` and then measures ``y[k]`` calls ``step(y[k], u[k-1])``.

Two implementations share that interface:

* `KernelEstimator`: the whole step (prediction, update, Joseph-form
  covariance, positive-definiteness pivots) is one CasADi SX function built
  once from the plant's compiled functions and evaluated on numpy buffers
  (``casadi.Function.buffer``) with no per-step conversion; ``M`` runs go
  through ``Function.map``. With a C compiler on the machine the kernel is
  compiled to native code once and cached (``backend="native"``), otherwise
  CasADi's virtual machine evaluates it (``backend="vm"``).
* `ArrayEstimator`: vectorised numpy over the run axis, for the linear-model
  filters (adaptive Kalman, adaptive scaling, consensus, Luenberger).

Covariances are updated in Joseph form and symmetrised; a covariance that
stops being positive definite (or a state that stops being finite) raises
`CovarianceError` naming the step, the run and the matrix, never a silent
NaN. The estimator keeps its last valid state when that happens.
"""

from __future__ import annotations

import abc
import hashlib
import math
import os
import shutil
import subprocess
import tempfile
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import casadi as ca
import numpy as np
import sympy as sp

from tanksynth.errors import CovarianceError, DimensionError, SpecError, TanksynthError
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import compile_matrix
from tanksynth.analysis.linearize import discretize_zoh, equilibrium_input, linearize

__all__ = [
    "CovarianceError",
    "DiscreteModel",
    "discrete_model",
    "regularized_jacobian",
    "Estimator",
    "KernelEstimator",
    "ArrayEstimator",
    "as_matrix",
    "as_vector",
    "as_spd",
    "sx_cholesky",
    "sx_spd_inverse",
    "sx_symmetrize",
    "joseph_update",
    "mv",
    "BACKENDS",
]

#: Kernel evaluation back ends (``"auto"`` = native when a C compiler works).
BACKENDS = ("auto", "native", "vm")


# ----------------------------------------------------------------------------- validation
def as_matrix(value: Any, name: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A finite float matrix of a given shape (scalars become 1 x 1).

    Parameters
    ----------
    value : array_like
    name : str
        Name for error messages (``"Q"``, ``"L"``).
    shape : (int, int), optional
        Required shape.

    Raises
    ------
    DimensionError
        Wrong shape or non-finite entries.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a numeric matrix, got {value!r}") from None
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim == 1 and shape is not None and shape[1] == 1 and arr.size == shape[0]:
        arr = arr.reshape(-1, 1)
    if arr.ndim != 2:
        raise DimensionError(f"{name} must be a 2-D matrix, got an array of shape {arr.shape}")
    if shape is not None and arr.shape != tuple(shape):
        raise DimensionError(f"{name} must have shape {tuple(shape)}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} has non-finite entries")
    return arr


def as_vector(value: Any, name: str, size: int | None = None) -> np.ndarray:
    """A finite float vector (any 1-D-compatible input; scalars allowed when size is 1).

    Raises
    ------
    DimensionError
        Wrong size or non-finite entries.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a numeric vector, got {value!r}") from None
    if arr.ndim > 1 and sum(d > 1 for d in arr.shape) <= 1:
        arr = arr.reshape(-1)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise DimensionError(f"{name} must be a vector, got an array of shape {arr.shape}")
    if size is not None and arr.size != size:
        raise DimensionError(f"{name} must have {size} entries, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} has non-finite entries")
    return arr


def as_spd(value: Any, name: str, size: int | None = None, semidefinite: bool = False,
           rtol: float = 1e-10) -> np.ndarray:
    """A symmetric positive definite (or semidefinite) matrix.

    A scalar ``s`` with ``size`` given is accepted as ``s I``; a vector of
    length ``size`` as a diagonal matrix. Asymmetry up to ``rtol`` (relative
    to the largest entry) is symmetrised away; more is an error.

    Raises
    ------
    DimensionError
        Wrong shape or non-finite entries.
    SpecError
        Not symmetric, or not positive (semi)definite; the key is ``name``.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a numeric matrix, got {value!r}") from None
    if size is not None and arr.ndim == 0:
        arr = float(arr) * np.eye(size)
    elif size is not None and arr.ndim == 1 and arr.size == size and size > 1:
        arr = np.diag(arr)
    arr = as_matrix(arr, name, None if size is None else (size, size))
    if arr.shape[0] != arr.shape[1]:
        raise DimensionError(f"{name} must be square, got shape {arr.shape}")
    scale = float(np.max(np.abs(arr))) if arr.size else 0.0
    if np.max(np.abs(arr - arr.T), initial=0.0) > rtol * max(scale, 1e-300):
        raise SpecError(f"{name} must be symmetric", key=name)
    arr = 0.5 * (arr + arr.T)
    eig = np.linalg.eigvalsh(arr)
    if semidefinite:
        if eig.size and eig[0] < -rtol * max(scale, 1e-300):
            raise SpecError(f"{name} must be positive semidefinite; smallest eigenvalue {eig[0]:.3g}",
                            key=name)
    else:
        try:
            np.linalg.cholesky(arr)
        except np.linalg.LinAlgError:
            raise SpecError(f"{name} must be positive definite; smallest eigenvalue "
                            f"{eig[0]:.3g}", key=name) from None
        if eig.size and not eig[0] > 0:
            raise SpecError(f"{name} must be positive definite; smallest eigenvalue {eig[0]:.3g}",
                            key=name)
    return arr


def _positive_int(value: Any, name: str, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise SpecError(f"{name} must be an integer >= {minimum}, got {value!r}", key=name)
    return int(value)


def _positive_float(value: Any, name: str, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SpecError(f"{name} must be a number, got {value!r}", key=name)
    v = float(value)
    if not np.isfinite(v) or (v < 0 if allow_zero else v <= 0):
        raise SpecError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {value!r}", key=name)
    return v


# ----------------------------------------------------------------------------- SX helpers
def sx_symmetrize(A: ca.SX) -> ca.SX:
    """``(A + A') / 2``."""
    return 0.5 * (A + A.T)


def sx_cholesky(A: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Lower Cholesky factor of a symmetric matrix, with its pivots.

    Parameters
    ----------
    A : casadi.SX, shape (n, n)

    Returns
    -------
    L : casadi.SX, shape (n, n)
        ``L L' = A`` when ``A`` is positive definite.
    pivots : casadi.SX, shape (n, 1)
        ``d_j = A_jj - sum_k L_jk^2``; ``A`` is positive definite iff all are
        > 0. (A non-positive pivot is clamped to 1e-300 inside the square
        root so that the kernel never produces NaN; the caller raises.)
    """
    n = A.shape[0]
    L = [[ca.SX(0) for _ in range(n)] for _ in range(n)]
    piv = []
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d = d - L[j][k] * L[j][k]
        piv.append(d)
        r = ca.sqrt(ca.fmax(d, 1e-300))
        L[j][j] = r
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / r
    return ca.blockcat(L), ca.vertcat(*piv)


def _sx_lower_inverse(L: ca.SX) -> ca.SX:
    n = L.shape[0]
    X = [[ca.SX(0) for _ in range(n)] for _ in range(n)]
    for j in range(n):
        X[j][j] = 1 / L[j, j]
        for i in range(j + 1, n):
            s = ca.SX(0)
            for k in range(j, i):
                s = s - L[i, k] * X[k][j]
            X[i][j] = s / L[i, i]
    return ca.blockcat(X)


def sx_spd_inverse(A: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Inverse of a symmetric positive definite matrix by Cholesky, with pivots.

    Returns
    -------
    inverse : casadi.SX
    pivots : casadi.SX
        Cholesky pivots of ``A`` (see `sx_cholesky`).
    """
    if A.shape == (1, 1):
        return 1 / A, A
    L, piv = sx_cholesky(A)
    Li = _sx_lower_inverse(L)
    return Li.T @ Li, piv


def _mmin(v: ca.SX) -> ca.SX:
    out = v[0]
    for i in range(1, v.numel()):
        out = ca.fmin(out, v[i])
    return out


# ----------------------------------------------------------------------------- the model
def regularized_jacobian(plant: Plant, eps: float) -> sp.Matrix:
    """``df/dx`` of the plant with singular Torricelli derivatives regularised.

    ``d/dx sqrt(|x|)`` is infinite at ``x = 0`` (equal heads, an empty tank,
    a level at a threshold pipe) and automatic differentiation gives inf/NaN
    there. The symbolic Jacobian (sympy, parameters substituted) has every
    power ``b^e`` with a negative non-integer exponent replaced by
    ``(b + eps)^e`` and every ``sign(b)^2`` by 1, so that
    ``d/dx [sgn(x) sqrt(2 g |x|)] = sqrt(2 g) / (2 sqrt(|x| + eps))``
    (notes/plants.md 1.3). Derivatives of ``max``/``sign`` give Heaviside and
    Dirac terms: the Dirac terms vanish (they only differ from 0 on a set of
    measure zero) and the Heaviside terms select the mode's Jacobian.

    Parameters
    ----------
    plant : Plant
    eps : float
        Regularisation in the unit of the powered base (m for heads), > 0.

    Returns
    -------
    sympy.Matrix, shape (n, n)
    """
    e = sp.Float(eps) if not isinstance(eps, sp.Basic) else eps
    J = plant.f_numeric.jacobian(sp.Matrix(plant.x))

    def is_singular_power(a: sp.Basic) -> bool:
        return (a.is_Pow and a.exp.is_number and bool(a.exp < 0) and not a.exp.is_integer
                and not a.base.is_number)

    def fix(entry: sp.Expr) -> sp.Expr:
        entry = entry.replace(lambda a: isinstance(a, sp.DiracDelta), lambda a: sp.Integer(0))
        entry = entry.replace(lambda a: a.is_Pow and isinstance(a.base, sp.sign) and a.exp == 2,
                              lambda a: sp.Integer(1))
        return entry.replace(is_singular_power, lambda a: sp.Pow(a.base + e, a.exp))

    return J.applyfunc(fix)


def _affine(expr: sp.Matrix, symbols: Sequence[sp.Symbol]) -> bool:
    """Every entry is a polynomial of degree <= 1 in ``symbols``."""
    syms = list(symbols)
    if not syms:
        return True
    for entry in expr:
        if not entry.free_symbols & set(syms):
            continue
        if not entry.is_polynomial(*syms) or sp.Poly(entry, *syms).total_degree() > 1:
            return False
    return True


_PLANT_CACHE: dict[int, tuple[weakref.ref, dict]] = {}


def _plant_cache(plant: Plant) -> dict:
    """Per-plant cache of compiled estimator pieces (dropped with the plant)."""
    key = id(plant)
    entry = _PLANT_CACHE.get(key)
    if entry is None or entry[0]() is not plant:
        ref = weakref.ref(plant, lambda _r, k=key: _PLANT_CACHE.pop(k, None))
        entry = (ref, {})
        _PLANT_CACHE[key] = entry
    return entry[1]


class _PlantDimensions:
    """``n``, ``m``, ``q`` read from ``self.plant`` (states, inputs, outputs)."""

    plant: Plant

    @property
    def n(self) -> int:
        """Number of states."""
        return self.plant.n

    @property
    def m(self) -> int:
        """Number of plant inputs."""
        return self.plant.m

    @property
    def q(self) -> int:
        """Number of measured outputs."""
        return self.plant.q


@dataclass(frozen=True, eq=False)
class DiscreteModel(_PlantDimensions):
    """The sampled model an estimator predicts with, built once from a plant.

    Either linear affine (``kind == "linear"``) in absolute coordinates::

        x(k) = Ad x(k-1) + Bd u(k) + cd,        y = C x + dy

    (exact ZOH of a linear plant, or the ZOH of the Jacobian linearisation
    at an operating point: seed 000 eq. 10-11), or nonlinear
    (``kind == "nonlinear"``): ``x(k) = F(x(k-1), u(k))`` by ``substeps``
    classical Runge-Kutta steps of ``f`` over ``ts``, ``y = h(x)``, and the
    transition Jacobian ``Phi = prod (I + hJ + (hJ)^2/2 + (hJ)^3/6 +
    (hJ)^4/24)`` with the regularised Jacobian ``J`` frozen at ``x(k-1)``
    (seed 002 eq. 14-15: "partial derivative of F at x(k-1)"; for a linear
    plant this is exactly the derivative of the Runge-Kutta map).

    Attributes
    ----------
    plant : Plant
    ts : float
        Sampling period (s).
    kind : {"linear", "nonlinear"}
    exact : bool
        The model equals the plant (linear plant, or nonlinear model).
    substeps : int
        Runge-Kutta steps per sampling period (nonlinear).
    jacobian_eps : float
        Jacobian regularisation (state units, see `regularized_jacobian`).
    switch_tol : float
        On a hybrid plant, a switching function with ``|s(x)| <= switch_tol``
        at ``x(k-1)`` means "on the switching surface": the previous
        Jacobian is kept (seed 002 section 3). 0 = exactly on it.
    clip : bool
        Clamp predicted and corrected states to the plant's region box.
    Ad, Bd, cd, C, dy : ndarray or None
        Linear model matrices (kind ``"linear"``).
    operating_point : tuple of ndarray or None
        ``(x0, u0)`` of a linearisation.
    """

    plant: Plant
    ts: float
    kind: str
    exact: bool
    substeps: int = 1
    jacobian_eps: float = 1e-6
    switch_tol: float = 0.0
    clip: bool = False
    Ad: np.ndarray | None = None
    Bd: np.ndarray | None = None
    cd: np.ndarray | None = None
    C: np.ndarray | None = None
    dy: np.ndarray | None = None
    operating_point: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def hybrid(self) -> bool:
        """The model is nonlinear on a plant with switching surfaces."""
        return self.kind == "nonlinear" and self.plant.hybrid is not None

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Region box ``(lower, upper)``, state units."""
        b = np.array(self.plant.region.bounds, dtype=float)
        return b[:, 0], b[:, 1]

    # -- symbolic pieces (CasADi SX) used to build kernels -------------------------
    def _funcs(self) -> dict:
        cache = self.__dict__.get("_cache_funcs")
        if cache is None:
            cache = {}
            if self.kind == "nonlinear":
                comp = self.plant.compiled
                shared = _plant_cache(self.plant)
                key = ("J", self.jacobian_eps)
                if key not in shared:
                    J = regularized_jacobian(self.plant, self.jacobian_eps)
                    shared[key] = compile_matrix("J", J, [self.plant.x, self.plant.u], ["x", "u"])
                cache["f"] = comp.f
                cache["J"] = shared[key]
                cache["h"] = comp.h
                cache["H"] = comp.jac_h
                cache["s"] = comp.switching
            object.__setattr__(self, "_cache_funcs", cache)
        return cache

    def clip_sx(self, x: ca.SX) -> ca.SX:
        """Clamp to the region box when ``clip`` is set (symbolic)."""
        if not self.clip:
            return x
        lo, hi = self.bounds
        return ca.fmin(ca.fmax(x, ca.DM(lo)), ca.DM(hi))

    def predict_sx(self, x: ca.SX, u: ca.SX) -> ca.SX:
        """``x(k)`` from ``x(k-1)`` and ``u(k)`` (symbolic)."""
        if self.kind == "linear":
            out = ca.DM(self.Ad) @ x + ca.DM(self.cd)
            if self.m:
                out = out + ca.DM(self.Bd) @ u
            return self.clip_sx(out)
        f = self._funcs()["f"]
        h = self.ts / self.substeps
        for _ in range(self.substeps):
            k1 = f(x, u)
            k2 = f(x + h / 2 * k1, u)
            k3 = f(x + h / 2 * k2, u)
            k4 = f(x + h * k3, u)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return self.clip_sx(x)

    def transition_jacobian_sx(self, x: ca.SX, u: ca.SX) -> ca.SX:
        """``Phi = dF/dx`` at ``x(k-1)`` (symbolic; constant ``Ad`` when linear)."""
        n = self.n
        if self.kind == "linear":
            return ca.SX(ca.DM(self.Ad))
        J = self._funcs()["J"](x, u)
        h = self.ts / self.substeps
        I = ca.SX.eye(n)
        hJ = h * J
        T = I + hJ / 4
        T = I + hJ / 3 @ T
        T = I + hJ / 2 @ T
        T = I + hJ @ T
        Phi = T
        for _ in range(self.substeps - 1):
            Phi = T @ Phi
        return Phi

    def output_sx(self, x: ca.SX) -> ca.SX:
        """``y = h(x)`` (symbolic)."""
        if self.kind == "linear":
            return ca.DM(self.C) @ x + ca.DM(self.dy)
        return self._funcs()["h"](x)

    def output_jacobian_sx(self, x: ca.SX) -> ca.SX:
        """``H = dh/dx`` (symbolic; constant ``C`` when linear)."""
        if self.kind == "linear":
            return ca.SX(ca.DM(self.C))
        return self._funcs()["H"](x)

    def on_surface_sx(self, x: ca.SX) -> ca.SX | None:
        """1 when ``x`` lies on a switching surface (hybrid plants), else None."""
        if not self.hybrid:
            return None
        s = self._funcs()["s"](x)
        flag = ca.SX(0)
        for i in range(s.numel()):
            flag = ca.logic_or(flag, ca.fabs(s[i]) <= self.switch_tol)
        return flag

    # -- numeric helpers ------------------------------------------------------------
    def describe(self) -> dict:
        """JSON-friendly description for artefact diagnostics."""
        out: dict[str, Any] = {"kind": self.kind, "exact": self.exact, "ts": self.ts,
                               "clip_to_region": self.clip}
        if self.kind == "nonlinear":
            out.update({"integrator": "rk4", "substeps": self.substeps,
                        "jacobian": "regularised symbolic df/dx frozen at x(k-1), "
                                    "Phi = 4th-order Taylor of expm(J h) per substep",
                        "jacobian_eps": self.jacobian_eps})
            if self.hybrid:
                out["switching"] = {"rule": "keep the previous Jacobian when |s_j(x(k-1))| <= "
                                            "switch_tol (seed 002 section 3)",
                                    "switch_tol": self.switch_tol}
        else:
            out["discretisation"] = "exact zero-order hold"
            if self.operating_point is not None:
                out["operating_point"] = {"x0": self.operating_point[0].tolist(),
                                          "u0": self.operating_point[1].tolist()}
        return out


def discrete_model(plant: Plant, ts: float, *, operating_point: Any = None, substeps: int = 1,
                   jacobian_eps: float = 1e-6, switch_tol: float = 0.0,
                   clip: bool = False) -> DiscreteModel:
    """Build the sampled model of a plant for an estimator.

    Parameters
    ----------
    plant : Plant
    ts : float
        Sampling period (s), > 0.
    operating_point : sequence or (x0, u0), optional
        Linearise at this point (levels ``x0`` in state units; ``u0`` in
        input units, computed as the equilibrium input when only ``x0`` is
        given) and discretise exactly: the CKF model of seed 000 eq. 8-11.
        Without it a plant whose ``f`` and ``h`` are affine gets its exact
        ZOH model and any other plant the nonlinear Runge-Kutta model.
    substeps : int
        Runge-Kutta steps per sampling period (nonlinear model), >= 1.
    jacobian_eps : float
        Regularisation of the Torricelli derivative (see
        `regularized_jacobian`), > 0, state units (m).
    switch_tol : float
        Distance to a switching surface treated as "on it", >= 0.
    clip : bool
        Clamp estimates to the plant's region box after prediction and
        correction (keeps Torricelli square roots real).

    Returns
    -------
    DiscreteModel

    Raises
    ------
    SpecError
        Bad ``ts``, ``substeps``, ``jacobian_eps`` or ``switch_tol``.
    DimensionError
        Operating point of the wrong size.
    """
    ts = _positive_float(ts, "ts")
    substeps = _positive_int(substeps, "substeps")
    jacobian_eps = _positive_float(jacobian_eps, "jacobian_eps")
    switch_tol = _positive_float(switch_tol, "switch_tol", allow_zero=True)
    common = dict(plant=plant, ts=ts, substeps=substeps, jacobian_eps=jacobian_eps,
                  switch_tol=switch_tol, clip=bool(clip))
    if operating_point is not None:
        if isinstance(operating_point, tuple) and len(operating_point) == 2 and \
                np.ndim(operating_point[0]) == 1:
            x0 = as_vector(operating_point[0], "operating_point x0", plant.n)
            u0 = as_vector(operating_point[1], "operating_point u0", plant.m)
        else:
            x0 = as_vector(operating_point, "operating_point x0", plant.n)
            u0 = equilibrium_input(plant, x0).u0
        lin = linearize(plant, x0, u0, ts=ts)
        # affine term of the exact ZOH of F (x - x0) + B (u - u0) + f(x0, u0)
        _, Gd = discretize_zoh(lin.F, np.eye(plant.n), ts)
        cd = x0 - lin.Ad @ x0 - lin.Bd @ u0 + Gd @ lin.offset
        y0 = np.asarray(plant.compiled.output(x0[None]))[0]
        dy = y0 - lin.C @ x0
        return DiscreteModel(kind="linear", exact=False, Ad=lin.Ad, Bd=lin.Bd, cd=cd, C=lin.C,
                             dy=dy, operating_point=(x0, u0), **common)
    shared = _plant_cache(plant)
    if "affine" not in shared:
        shared["affine"] = (_affine(plant.f_numeric, [*plant.x, *plant.u])
                            and _affine(plant.h_numeric, list(plant.x)))
    if shared["affine"]:
        zero_x = np.zeros(plant.n)
        zero_u = np.zeros(plant.m)
        lin = linearize(plant, zero_x, zero_u, ts=ts)
        _, Gd = discretize_zoh(lin.F, np.eye(plant.n), ts)
        cd = Gd @ lin.offset
        dy = np.asarray(plant.compiled.output(zero_x[None]))[0]
        return DiscreteModel(kind="linear", exact=True, Ad=lin.Ad, Bd=lin.Bd, cd=cd, C=lin.C,
                             dy=dy, **common)
    return DiscreteModel(kind="nonlinear", exact=True, **common)


# ----------------------------------------------------------------------------- native kernels
def _cache_dir() -> Path:
    """Directory of compiled kernels: ``$TANKSYNTH_CACHE`` or ``~/.cache/tanksynth/kernels``."""
    if os.environ.get("TANKSYNTH_CACHE"):
        return Path(os.environ["TANKSYNTH_CACHE"])
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "tanksynth" / "kernels"


_NATIVE_FLAGS = ("-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-math-errno")
_NATIVE_CACHE: dict[str, ca.Function] = {}


def _compiler() -> str | None:
    return shutil.which("gcc") or shutil.which("cc")


def _native(fn: ca.Function) -> ca.Function | None:
    """Compile an SX function to a shared library (cached by source hash) and load it."""
    cc = _compiler()
    if cc is None:
        return None
    gen = ca.CodeGenerator("tk_kernel.c", {"with_header": False})
    gen.add(fn)
    code = gen.dump()
    digest = hashlib.sha256((code + " ".join(_NATIVE_FLAGS) + ca.__version__).encode()).hexdigest()
    if digest in _NATIVE_CACHE:
        return _NATIVE_CACHE[digest]
    name = f"tk_{digest[:20]}"
    try:
        directory = _cache_dir()
        directory.mkdir(parents=True, exist_ok=True)
        so_path = directory / f"{name}.so"
        if not so_path.exists():
            renamed = ca.Function(name, fn.sx_in(), fn.call(fn.sx_in()), fn.name_in(),
                                  fn.name_out())
            gen = ca.CodeGenerator(f"{name}.c", {"with_header": False})
            gen.add(renamed)
            with tempfile.TemporaryDirectory(dir=directory) as tmp:
                src = Path(tmp) / f"{name}.c"
                src.write_text(gen.dump())
                out = Path(tmp) / f"{name}.so"
                subprocess.run([cc, *_NATIVE_FLAGS, str(src), "-o", str(out), "-lm"], check=True,
                               capture_output=True, timeout=300)
                os.replace(out, so_path)
        loaded = ca.external(name, str(so_path))
    except (OSError, subprocess.SubprocessError, RuntimeError):
        return None
    _NATIVE_CACHE[digest] = loaded
    return loaded


# ----------------------------------------------------------------------------- estimators
class Estimator(_PlantDimensions, abc.ABC):
    """Interface of every estimator (single run or ``runs`` parallel runs).

    Subclasses implement `_advance` (one step on the run-stacked state) and
    the state bookkeeping; this class validates ``y`` and ``u`` and counts
    steps.

    Attributes
    ----------
    plant : Plant
    tuning : frozen dataclass
        The design (the artefact).
    runs : int or None
        None for a single run, else the number of parallel runs ``M``.
    k : int
        Steps taken since the last reset.
    """

    #: Method name used in artefacts.
    method: str = "estimator"

    def __init__(self, plant: Plant, tuning: Any, runs: int | None):
        if runs is not None:
            runs = _positive_int(runs, "runs")
        self.plant = plant
        self.tuning = tuning
        self.runs = runs
        self.k = 0
        self._n, self._m, self._q = plant.n, plant.m, plant.q
        self._no_input = np.zeros((1 if runs is None else runs, 0))

    # -- dimensions (n, m, q: from _PlantDimensions) ----------------------------------
    @property
    def _M(self) -> int:
        return 1 if self.runs is None else self.runs

    # -- input checks -----------------------------------------------------------------
    def _inputs(self, y: Any, u: Any) -> tuple[np.ndarray, np.ndarray]:
        """Validate ``y`` and ``u`` and return them as (M, q), (M, m) arrays."""
        M, q, m = self._M, self._q, self._m
        Y = np.asarray(y, dtype=float)
        if self.runs is None:
            if Y.shape != (q,) and not (q == 1 and Y.shape == ()):
                raise DimensionError(f"y must have shape ({q},) for a single run, got {Y.shape}")
            Y = Y.reshape(1, q)
        elif Y.shape != (M, q):
            raise DimensionError(f"y must have shape ({M}, {q}) for {M} runs, got {Y.shape}")
        if u is None:
            if m:
                raise DimensionError(f"u is required: the plant has {m} inputs")
            U = self._no_input
        else:
            U = np.asarray(u, dtype=float)
            if self.runs is None:
                if U.shape != (m,) and not (m == 1 and U.shape == ()):
                    raise DimensionError(f"u must have shape ({m},) for a single run, got {U.shape}")
                U = U.reshape(1, m)
            elif U.shape == (m,):
                U = np.broadcast_to(U, (M, m))
            elif U.shape != (M, m):
                raise DimensionError(f"u must have shape ({M}, {m}) or ({m},) for {M} runs, "
                                     f"got {U.shape}")
        if self.runs is None:
            finite = all(map(math.isfinite, Y[0].tolist())) and all(map(math.isfinite, U[0].tolist()))
        else:
            finite = bool(np.isfinite(Y).all() and np.isfinite(U).all())
        if not finite:
            raise DimensionError(f"step {self.k + 1}: y and u must be finite")
        return Y, U

    # -- public API -------------------------------------------------------------------
    def step(self, y: Any, u: Any = None) -> np.ndarray:
        """Take one measurement and return the state estimate.

        Parameters
        ----------
        y : array_like, shape (q,) or (M, q)
            Measurement at ``t_k`` (output units).
        u : array_like, shape (m,) or (M, m) (or (m,) for all runs)
            Input held over ``[t_{k-1}, t_k)`` (input units).

        Returns
        -------
        ndarray, shape (n,) or (M, n)
            ``x_hat(k)`` in state units (a copy).

        Raises
        ------
        DimensionError
            Wrong shapes or non-finite ``y``/``u``.
        CovarianceError
            A covariance stopped being positive definite at this step.
        """
        Y, U = self._inputs(y, u)
        X = self._advance(Y, U)
        self.k += 1
        return X[0].copy() if self.runs is None else X.copy()

    def run(self, Y: Any, U: Any) -> np.ndarray:
        """Filter a whole sequence.

        Parameters
        ----------
        Y : array_like, shape (N, q) (single) or (N, M, q) (batch)
        U : array_like, shape (N, m) (single) or (N, M, m) / (N, m) (batch)

        Returns
        -------
        ndarray, shape (N, n) or (N, M, n)
        """
        Y = np.asarray(Y, dtype=float)
        U = np.asarray(U, dtype=float)
        if Y.ndim < 1 or U.ndim < 1 or len(Y) != len(U):
            raise DimensionError(f"Y and U must have the same number of steps, got {Y.shape} and "
                                 f"{U.shape}")
        out = np.empty((len(Y), *(((self.n,)) if self.runs is None else (self.runs, self.n))))
        for i in range(len(Y)):
            out[i] = self.step(Y[i], U[i])
        return out

    @property
    @abc.abstractmethod
    def x_hat(self) -> np.ndarray:
        """Current estimate, shape (n,) or (M, n) (a copy)."""

    @abc.abstractmethod
    def reset(self, x0: Any = None) -> None:
        """Back to the initial state (``x0`` overrides the tuning's initial estimate)."""

    @abc.abstractmethod
    def batch(self, runs: int) -> "Estimator":
        """A fresh estimator of the same design for ``runs`` parallel runs."""

    @abc.abstractmethod
    def _advance(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        """One step on run-stacked arrays; returns the (M, n) estimates (may be a view)."""

    def _x0_rows(self, x0: Any, default: np.ndarray) -> np.ndarray:
        M, n = self._M, self.n
        if x0 is None:
            return np.tile(default, (M, 1))
        arr = np.asarray(x0, dtype=float)
        if arr.shape == (n,):
            return np.tile(arr, (M, 1))
        if self.runs is not None and arr.shape == (M, n):
            if not np.all(np.isfinite(arr)):
                raise DimensionError("x0 has non-finite entries")
            return arr.copy()
        raise DimensionError(f"x0 must have shape ({n},)" +
                             (f" or ({M}, {n})" if self.runs is not None else "") +
                             f", got {arr.shape}")

    def _raise(self, run: int, matrix: str, value: float) -> None:
        where = "" if self.runs is None else f" (run {run})"
        raise CovarianceError(
            f"{type(self).__name__}: {matrix} is not positive definite at step {self.k + 1}"
            f"{where}: smallest Cholesky pivot {value:.3g}. Check Q, R and P0 (scaling, "
            "definiteness) and the model; the estimator keeps its state of step "
            f"{self.k}.", self.k + 1, None if self.runs is None else run, matrix, float(value))


class KernelEstimator(Estimator):
    """An estimator whose step is one compiled CasADi function (see module notes).

    Subclasses implement `_build` returning the SX kernel
    ``(state, y, u, params) -> (state_new, checks, extra)`` with
    ``checks = [pivots..., sum(x_new)]`` (all pivots must be > 0 and all
    finite), `_params` (the numeric tuning vector) and `_initial_state`.
    """

    #: Names of the matrices whose minimum Cholesky pivot is in ``checks``.
    check_names: tuple[str, ...] = ()

    def __init__(self, plant: Plant, tuning: Any, model: DiscreteModel, runs: int | None,
                 backend: str, _shared: dict | None = None):
        super().__init__(plant, tuning, runs)
        if backend not in BACKENDS:
            raise SpecError(f"backend must be one of {BACKENDS}, got {backend!r}", key="backend")
        self.model = model
        if _shared is None:
            kernel = self._build()
            fn = kernel
            used = "vm"
            if backend in ("auto", "native"):
                native = _native(kernel)
                if native is not None:
                    fn, used = native, "native"
                elif backend == "native":
                    raise TanksynthError("backend 'native' needs a working C compiler (gcc/cc)")
            _shared = {"fn": fn, "backend": used, "sx": kernel, "maps": {}}
        self._shared = _shared
        self.backend = _shared["backend"]
        fn = _shared["fn"]
        M = self._M
        if self.runs is None:
            run_fn = fn
        else:
            maps = _shared["maps"]
            if M not in maps:
                maps[M] = fn.map(f"{fn.name()}_map{M}", "serial", M, [3], [])
            run_fn = maps[M]
        self._s = fn.size1_in(0)
        self._c = fn.size1_out(1)
        self._e = fn.size1_out(2)
        self._states = [np.zeros((M, self._s)), np.zeros((M, self._s))]
        self._Y = np.zeros((M, self.q))
        self._U = np.zeros((M, self.m))
        self._P = np.ascontiguousarray(self._params(), dtype=float).reshape(-1)
        self._checks = np.zeros((M, self._c))
        self._extra = np.zeros((M, self._e))
        self._buffers = []
        for a, b in ((0, 1), (1, 0)):
            fb, ev = run_fn.buffer()
            fb.set_arg(0, memoryview(self._states[a].reshape(-1)))
            fb.set_arg(1, memoryview(self._Y.reshape(-1)))
            fb.set_arg(2, memoryview(self._U.reshape(-1)))
            fb.set_arg(3, memoryview(self._P))
            fb.set_res(0, memoryview(self._states[b].reshape(-1)))
            fb.set_res(1, memoryview(self._checks.reshape(-1)))
            fb.set_res(2, memoryview(self._extra.reshape(-1)))
            self._buffers.append((fb, ev, b))
        self._cur = 0
        self._backend_request = backend
        self.reset()

    # -- to implement -------------------------------------------------------------------
    @abc.abstractmethod
    def _build(self) -> ca.Function:
        """The SX kernel ``(state, y, u, params) -> (state_new, checks, extra)``."""

    @abc.abstractmethod
    def _params(self) -> np.ndarray:
        """Numeric tuning vector fed to the kernel's ``params`` input."""

    @abc.abstractmethod
    def _initial_state(self, X0: np.ndarray) -> np.ndarray:
        """(M, s) kernel state for initial estimates ``X0`` (M, n)."""

    # -- machinery ------------------------------------------------------------------------
    @property
    def state(self) -> np.ndarray:
        """Raw kernel state, shape (M, s) (a copy; layout per subclass)."""
        return self._states[self._cur].copy()

    @property
    def x_hat(self) -> np.ndarray:
        """Current estimate, shape (n,) or (M, n) (a copy)."""
        X = self._states[self._cur][:, :self.n]
        return X[0].copy() if self.runs is None else X.copy()

    @property
    def extra(self) -> np.ndarray:
        """Kernel's extra outputs of the last step (innovation, ...), (M, e) (a copy)."""
        return self._extra.copy()

    def reset(self, x0: Any = None) -> None:
        """Back to the initial state.

        Parameters
        ----------
        x0 : array_like, shape (n,) or (M, n), optional
            Initial estimate overriding the tuning's ``x0`` (state units).
        """
        X0 = self._x0_rows(x0, self.tuning.x0)
        self._states[self._cur][:] = self._initial_state(X0)
        self.k = 0

    def _advance(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        self._Y[:] = Y
        if self.m:
            self._U[:] = U
        fb, ev, nxt = self._buffers[self._cur]
        ev()
        chk = self._checks
        if self.runs is None:
            vals = chk[0].tolist()
            ok = all(0.0 < v < math.inf for v in vals[:-1]) and math.isfinite(vals[-1])
        else:
            npiv = self._c - 1
            ok = bool(np.isfinite(chk).all() and (chk[:, :npiv] > 0).all())
        if not ok:
            self._failure(chk)
        self._cur = nxt
        return self._states[nxt][:, :self._n]

    def _failure(self, chk: np.ndarray) -> None:
        npiv = self._c - 1
        for run in range(chk.shape[0]):
            for j in range(npiv):
                v = chk[run, j]
                if not (np.isfinite(v) and v > 0):
                    self._raise(run, self.check_names[j], v)
            if not np.isfinite(chk[run, npiv]):
                where = "" if self.runs is None else f" (run {run})"
                raise CovarianceError(
                    f"{type(self).__name__}: the state estimate is not finite at step {self.k + 1}"
                    f"{where}; the estimator keeps its state of step {self.k}.", self.k + 1,
                    None if self.runs is None else run, "state estimate", float(chk[run, npiv]))

    def batch(self, runs: int) -> "KernelEstimator":
        """A fresh estimator of the same design for ``runs`` parallel runs (shares the kernel)."""
        clone = object.__new__(type(self))
        clone._clone_from(self, runs)
        return clone

    def _clone_from(self, other: "KernelEstimator", runs: int | None) -> None:
        KernelEstimator.__init__(self, other.plant, other.tuning, other.model, runs,
                                 other._backend_request, _shared=other._shared)

    @property
    def instructions(self) -> int:
        """Number of elementary operations of the step kernel (per run)."""
        return int(self._shared["sx"].n_instructions())


class ArrayEstimator(Estimator):
    """An estimator written in vectorised numpy over the run axis.

    Subclasses keep their state in arrays with a leading run axis and
    implement `_advance`, `_reset_arrays` and `_clone_args`.
    """

    def __init__(self, plant: Plant, tuning: Any, runs: int | None):
        super().__init__(plant, tuning, runs)

    @property
    def x_hat(self) -> np.ndarray:
        """Current estimate, shape (n,) or (M, n) (a copy)."""
        return self._x[0].copy() if self.runs is None else self._x.copy()

    def reset(self, x0: Any = None) -> None:
        """Back to the initial state (``x0``: (n,) or (M, n) overrides the tuning's)."""
        self._x = self._x0_rows(x0, self.tuning.x0)
        self._reset_arrays()
        self.k = 0

    @abc.abstractmethod
    def _reset_arrays(self) -> None:
        """Re-initialise the arrays other than ``_x``."""

    @abc.abstractmethod
    def _clone_args(self) -> tuple[tuple, dict]:
        """Positional and keyword arguments rebuilding this estimator (without ``runs``)."""

    def batch(self, runs: int) -> "ArrayEstimator":
        """A fresh estimator of the same design for ``runs`` parallel runs."""
        args, kwargs = self._clone_args()
        return type(self)(*args, runs=runs, **kwargs)

    def _check_spd(self, P: np.ndarray, matrix: str) -> None:
        """Raise `CovarianceError` if any (M, n, n) slice is not positive definite."""
        try:
            L = np.linalg.cholesky(P)
            ok = bool(np.isfinite(L).all())
        except np.linalg.LinAlgError:
            ok = False
        if not ok:
            for run in range(P.shape[0]):
                Pi = P[run]
                if not np.isfinite(Pi).all():
                    self._raise(run, matrix, float("nan"))
                try:
                    np.linalg.cholesky(Pi)
                except np.linalg.LinAlgError:
                    self._raise(run, matrix, float(np.linalg.eigvalsh(Pi)[0]))

    def _check_state(self, X: np.ndarray) -> None:
        if not np.isfinite(X).all():
            run = int(np.argwhere(~np.isfinite(X))[0, 0])
            where = "" if self.runs is None else f" (run {run})"
            raise CovarianceError(
                f"{type(self).__name__}: the state estimate is not finite at step {self.k + 1}"
                f"{where}", self.k + 1, None if self.runs is None else run, "state estimate",
                float("nan"))


def mv(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``A x`` for every row ``x`` of ``X`` (M, k) -> (M, n).

    An ``einsum`` loop rather than ``X @ A.T``: a 2-D matrix product goes to
    BLAS, whose blocking depends on ``M``, so a batch would not equal its
    single runs bit for bit.
    """
    return np.einsum("ij,mj->mi", A, X)


def _sym(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def joseph_update(P: np.ndarray, K: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Joseph-form covariance update, symmetrised, on stacked arrays.

    ``(I - K H) P (I - K H)' + K R K'`` for ``P`` (M, n, n), ``K`` (M, n, q),
    ``H`` (q, n) or (M, q, n), ``R`` (q, q).
    """
    n = P.shape[-1]
    IKH = np.eye(n) - K @ H
    return _sym(IKH @ P @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2))
