"""The sampled model an estimator predicts with (`DiscreteModel`), built once from a plant.

Linear (exact zero-order hold of a linear plant, or of the Jacobian
linearisation at an operating point) or nonlinear (Runge-Kutta steps of the
plant's ``f`` with the toolbox's one RK4 formula, `tanksynth.plants.compile.rk4_step`,
and the plant's clipping rule when clipping is asked for), with the
regularised Jacobian the extended filters linearise with.

Cache (no hidden state): per-plant compiled pieces (the regularised
Jacobian Function, the affinity test) live in ``_PLANT_CACHE``, keyed by the
plant's identity and dropped with the plant (weak reference);
``tanksynth.runtime.clear_cache`` empties it (`clear_cache`; `cached_plants` counts it).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any, NamedTuple, Sequence

import casadi as ca
import numpy as np
import sympy as sp

from tanksynth.analysis.linearize import discretize_zoh, equilibrium_input, linearize
from tanksynth.errors import SpecError
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import compile_matrix, rk4_step
from tanksynth.runtime.estimators.tuning import as_vector, positive_float, positive_int

__all__ = ["DiscreteModel", "LinearMatrices", "PlantDimensions", "discrete_model",
           "regularized_jacobian", "clear_cache", "cached_plants"]


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
        # sign(-b) sign(b) is -sign(b)^2 = -1 away from b = 0: write sign(-b) as -sign(b) first,
        # or the product stays and evaluates to 0 at equal heads (a lost Jacobian entry)
        entry = entry.replace(lambda a: isinstance(a, sp.sign) and a.args[0].could_extract_minus_sign(),
                              lambda a: -sp.sign(-a.args[0]))
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


def clear_cache() -> int:
    """Forget the per-plant compiled pieces (rebuilt on demand); returns how many plants."""
    count = len(_PLANT_CACHE)
    _PLANT_CACHE.clear()
    return count


def cached_plants() -> int:
    """Number of plants whose compiled pieces are held (`clear_cache` drops them)."""
    return len(_PLANT_CACHE)


def _plant_cache(plant: Plant) -> dict:
    """Per-plant cache of compiled estimator pieces (dropped with the plant)."""
    key = id(plant)
    entry = _PLANT_CACHE.get(key)
    if entry is None or entry[0]() is not plant:
        def forget(_ref: weakref.ref, key: int = key) -> None:   # the plant was collected
            _PLANT_CACHE.pop(key, None)

        entry = (weakref.ref(plant, forget), {})
        _PLANT_CACHE[key] = entry
    return entry[1]


class PlantDimensions:
    """Mixin: ``n``, ``m``, ``q`` read from ``self.plant`` (states, inputs, outputs).

    Attributes
    ----------
    plant : Plant
        Set by the class that mixes it in (a model, an estimator).
    """

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


class LinearMatrices(NamedTuple):
    """The matrices of a linear sampled model ``x(k) = Ad x(k-1) + Bd u(k) + cd``, ``y = C x + dy``.

    Attributes
    ----------
    Ad : ndarray, shape (n, n)
        State transition over one period (dimensionless).
    Bd : ndarray, shape (n, m)
        Input matrix (state units per input unit).
    cd : ndarray, shape (n,)
        Affine term (state units).
    C : ndarray, shape (q, n)
        Output matrix (output units per state unit).
    dy : ndarray, shape (q,)
        Output offset (output units).
    """

    Ad: np.ndarray
    Bd: np.ndarray
    cd: np.ndarray
    C: np.ndarray
    dy: np.ndarray


@dataclass(frozen=True, eq=False)
class DiscreteModel(PlantDimensions):
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
        Clip the predicted and the corrected states by the plant's clipping
        rule (`Plant.state_bounds`). Unlike the simulator, the Runge-Kutta
        stages inside one prediction are not clipped: the states an
        estimator predicts from (sigma points, linearisation points) are
        hypotheses about the plant, not levels, and clipping them inside the
        step would distort the predicted spread (a UKF started with a wide
        ``P0`` goes from an RMSE of 0.0085 m to 0.065 m on seed 002's
        mismatch scenario).
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

    def linear_matrices(self) -> LinearMatrices:
        """``(Ad, Bd, cd, C, dy)`` of a linear model (kind ``"linear"``).

        Returns
        -------
        LinearMatrices

        Raises
        ------
        SpecError
            The model is nonlinear (it has no such matrices).
        """
        if self.Ad is None or self.Bd is None or self.cd is None or self.C is None or self.dy is None:
            raise SpecError(f"the sampled model of plant '{self.plant.name}' is nonlinear: it has no "
                            "linear matrices; give operating_point = (x0, u0) to linearise about",
                            key="operating_point")
        return LinearMatrices(self.Ad, self.Bd, self.cd, self.C, self.dy)

    @property
    def hybrid(self) -> bool:
        """The model is nonlinear on a plant with switching surfaces."""
        return self.kind == "nonlinear" and self.plant.hybrid is not None

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The plant's state bounds ``(lower, upper)`` (`Plant.state_bounds`), state units."""
        return self.plant.state_bounds()

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
        """Clip to the plant's state bounds when ``clip`` is set (symbolic).

        Parameters
        ----------
        x : casadi.SX
            State (state units).
        """
        if not self.clip:
            return x
        lo, hi = self.bounds
        return ca.fmin(ca.fmax(x, ca.DM(lo)), ca.DM(hi))

    def predict_sx(self, x: ca.SX, u: ca.SX) -> ca.SX:
        """``x(k)`` from ``x(k-1)`` and ``u(k)`` (symbolic).

        Parameters
        ----------
        x : casadi.SX
            State ``x(k-1)`` (state units).
        u : casadi.SX
            Input held over the period (input units).
        """
        if self.kind == "linear":
            lin = self.linear_matrices()
            out = ca.DM(lin.Ad) @ x + ca.DM(lin.cd)
            if self.m:
                out = out + ca.DM(lin.Bd) @ u
            return self.clip_sx(out)
        f = self._funcs()["f"]
        h = self.ts / self.substeps
        for _ in range(self.substeps):      # the toolbox's one RK4 step (plants.compile)
            x = rk4_step(lambda s: f(s, u), x, h)
        return self.clip_sx(x)

    def transition_jacobian_sx(self, x: ca.SX, u: ca.SX) -> ca.SX:
        """``Phi = dF/dx`` at ``x(k-1)`` (symbolic; constant ``Ad`` when linear).

        Parameters
        ----------
        x : casadi.SX
            State ``x(k-1)`` (state units).
        u : casadi.SX
            Input held over the period (input units).
        """
        n = self.n
        if self.kind == "linear":
            return ca.SX(ca.DM(self.linear_matrices().Ad))
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
        """``y = h(x)`` (symbolic).

        Parameters
        ----------
        x : casadi.SX
            State (state units).
        """
        if self.kind == "linear":
            lin = self.linear_matrices()
            return ca.DM(lin.C) @ x + ca.DM(lin.dy)
        return self._funcs()["h"](x)

    def output_jacobian_sx(self, x: ca.SX) -> ca.SX:
        """``H = dh/dx`` (symbolic; constant ``C`` when linear).

        Parameters
        ----------
        x : casadi.SX
            State (state units).
        """
        if self.kind == "linear":
            return ca.SX(ca.DM(self.linear_matrices().C))
        return self._funcs()["H"](x)

    def on_surface_sx(self, x: ca.SX) -> ca.SX | None:
        """1 when ``x`` lies on a switching surface (hybrid plants), else None.

        Parameters
        ----------
        x : casadi.SX
            State (state units).
        """
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
                               "clip_to_state_bounds": self.clip}
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
        Clip estimates by the plant's clipping rule (`Plant.state_bounds`:
        levels >= 0, <= ``hmax``) after the prediction and after the
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
    ts = positive_float(ts, "ts")
    substeps = positive_int(substeps, "substeps")
    jacobian_eps = positive_float(jacobian_eps, "jacobian_eps")
    switch_tol = positive_float(switch_tol, "switch_tol", allow_zero=True)
    common: dict[str, Any] = dict(plant=plant, ts=ts, substeps=substeps,
                                  jacobian_eps=jacobian_eps, switch_tol=switch_tol, clip=bool(clip))
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
