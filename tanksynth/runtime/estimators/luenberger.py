"""Luenberger observers (discrete and continuous) and the TS multi-observer (seed 001 eq. 20).

The gain ``L`` is an argument (from `tanksynth.design.placement.canonical`, the
canonical form of seed 004 eq. 27-29, an LMI design, or any other source),
so these observers do not depend on how it was designed.

Forms, with ``u(k)`` held over ``[t_{k-1}, t_k)`` and ``y(k)`` measured at
``t_k`` (see `tanksynth.runtime.estimators.base`):

``"current"`` (discrete, default)
    ``x- = Ad x(k-1) + Bd u(k) + cd``, ``x(k) = x- + L (y(k) - C x- - dy)``;
    error dynamics ``(I - L C) Ad``.
``"predictor"`` (discrete)
    ``x(k) = Ad x(k-1) + Bd u(k) + cd + L (y(k-1) - C x(k-1) - dy)``; error
    dynamics ``Ad - L C``. The estimate of ``x(k)`` does not use ``y(k)``.
``"continuous"``
    ``dx/dt = f(x, u) + L (y - h(x))`` over ``[t_{k-1}, t_k)`` with
    ``y(k-1)`` held (the latest sample; causal); exact ZOH for a linear
    model, Runge-Kutta substeps otherwise. Error dynamics ``F - L C``.

In the predictor and continuous forms the first step has no earlier
measurement and runs the model open loop.

`TSMultiObserver` is the continuous form with the Takagi-Sugeno multiple
model as vector field: ``dx/dt = sum_i mu_i(x) (A_i x + B u) + d + L (y -
C x)``, i.e. seed 001 eq. 20 (``A0 + sum mu_i (A_i - A0) = sum mu_i A_i``
as the memberships sum to 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from tanksynth.errors import DimensionError, SpecError
from tanksynth.plants.compile import rk4_step
from tanksynth.plants.base import Plant
from tanksynth.analysis.linearize import discretize_zoh, linearize
from tanksynth.runtime.estimators.base import ArrayEstimator, discrete_model, mv
from tanksynth.runtime.estimators.tuning import (artefact_gains, as_matrix, as_vector, choice,
                                                 fits_plant, operating_point, positive_float,
                                                 positive_int, require_tuning, set_fields)

__all__ = ["LuenbergerTuning", "LuenbergerObserver", "TSMultiObserver", "OBSERVER_FORMS"]

#: Observer forms.
OBSERVER_FORMS = ("current", "predictor", "continuous")


@dataclass(frozen=True, eq=False)
class LuenbergerTuning:
    """Tuning of a Luenberger observer: the artefact.

    Attributes
    ----------
    L : ndarray, shape (n, q)
        Observer gain (state units per output unit; per second in the
        continuous form).
    x0 : ndarray, shape (n,)
        Initial estimate (state units).
    ts : float
        Sampling period (s).
    form : {"current", "predictor", "continuous"}
    substeps : int
        Runge-Kutta steps per period (continuous form on a nonlinear model).
    operating_point : (x0, u0) or None
        Linearise a nonlinear plant here.
    """

    L: np.ndarray
    x0: np.ndarray
    ts: float
    form: str = "current"
    substeps: int = 10
    operating_point: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        set_fields(self, L=as_matrix(self.L, "L"), x0=as_vector(self.x0, "x0"))
        if self.L.shape[0] != self.x0.size:
            raise DimensionError(f"L has {self.L.shape[0]} rows, x0 has {self.x0.size} entries")
        set_fields(self, ts=positive_float(self.ts, "ts"),
                   form=choice(self.form, "form", OBSERVER_FORMS),
                   substeps=positive_int(self.substeps, "substeps"),
                   operating_point=operating_point(self.operating_point))

    def gains(self) -> dict[str, np.ndarray]:
        """Tuning arrays for the artefact; the initial estimate ``x0`` is stored as ``x_hat0``."""
        return artefact_gains(self, L=self.L, x_hat0=self.x0)


class _ContinuousBase(ArrayEstimator):
    """Continuous observer integrated by RK4 on a numpy vector field."""

    def _setup_field(self, rhs: Callable[[np.ndarray, np.ndarray], np.ndarray],
                     output: Callable[[np.ndarray], np.ndarray]) -> None:
        self._rhs = rhs
        self._out = output

    def _reset_arrays(self) -> None:
        self._yprev: np.ndarray | None = None   # the previous measurement (none before the first)

    def _field(self, X: np.ndarray, U: np.ndarray, Yh: np.ndarray | None) -> np.ndarray:
        dX = self._rhs(X, U)
        if Yh is not None:
            dX = dX + mv(self.tuning.L, Yh - self._out(X))
        return dX

    def _integrate(self, X: np.ndarray, U: np.ndarray, Yh: np.ndarray | None) -> np.ndarray:
        h = self.tuning.ts / self.tuning.substeps
        for _ in range(self.tuning.substeps):
            X = rk4_step(lambda x: self._field(x, U, Yh), X, h)
        return X


class LuenbergerObserver(_ContinuousBase):
    """Luenberger observer, discrete (current/predictor) or continuous.

    Parameters
    ----------
    plant : Plant
    tuning : LuenbergerTuning
    runs : int, optional

    Attributes
    ----------
    model : DiscreteModel
        Sampled model (linear for the discrete forms and for the exact
        continuous form).
    error_matrix : ndarray
        Error dynamics: ``(I - L C) Ad``, ``Ad - L C`` or ``F - L C``
        (None for the continuous form on a nonlinear model).

    Raises
    ------
    SpecError
        A discrete form on a nonlinear plant without operating point.
    DimensionError
        ``L`` is not (n, q).
    """

    method = "luenberger"

    def __init__(self, plant: Plant, tuning: LuenbergerTuning, runs: int | None = None):
        require_tuning(self, tuning, LuenbergerTuning)
        super().__init__(plant, tuning, runs)
        fits_plant(tuning, plant, L=(plant.n, plant.q))
        self.model = discrete_model(plant, tuning.ts, operating_point=tuning.operating_point)
        mdl, L = self.model, tuning.L
        self.error_matrix: np.ndarray | None = None
        if mdl.kind == "linear":
            sampled = mdl.linear_matrices()
            if tuning.form == "current":
                self.error_matrix = (np.eye(plant.n) - L @ sampled.C) @ sampled.Ad
            elif tuning.form == "predictor":
                self.error_matrix = sampled.Ad - L @ sampled.C
            else:
                if mdl.operating_point is not None:
                    lin = linearize(plant, *mdl.operating_point)
                    x_op, u_op = mdl.operating_point
                    c = lin.offset - lin.F @ x_op - lin.B @ u_op
                else:
                    lin = linearize(plant, np.zeros(plant.n), np.zeros(plant.m))
                    c = lin.offset
                Ao = lin.F - L @ sampled.C
                G = np.hstack([lin.B, L, (c - L @ sampled.dy)[:, None]])
                self._Phi, Gam = discretize_zoh(Ao, G, tuning.ts)
                m, q = plant.m, plant.q
                self._Gu, self._Gy, self._g = Gam[:, :m], Gam[:, m:m + q], Gam[:, -1]
                self.error_matrix = Ao
        elif tuning.form != "continuous":
            raise SpecError(f"plant '{plant.name}' is nonlinear: the '{tuning.form}' form needs "
                            "operating_point = (x0, u0), or use form = 'continuous'",
                            key="operating_point")
        else:
            comp = plant.compiled
            self._setup_field(comp.rhs, comp.output)
        self.reset()

    def _clone_args(self) -> tuple[tuple, dict]:
        return (self.plant, self.tuning), {}

    @property
    def error_eigenvalues(self) -> np.ndarray | None:
        """Eigenvalues of `error_matrix` (None when not linear)."""
        return None if self.error_matrix is None else np.linalg.eigvals(self.error_matrix)

    def _advance(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        mdl, tun = self.model, self.tuning
        L = tun.L
        X = self._x
        if tun.form == "current":
            Ad, Bd, cd, C, dy = mdl.linear_matrices()
            xp = mv(Ad, X) + mv(Bd, U) + cd
            X = xp + mv(L, Y - mv(C, xp) - dy)
        elif tun.form == "predictor":
            Ad, Bd, cd, C, dy = mdl.linear_matrices()
            Xn = mv(Ad, X) + mv(Bd, U) + cd
            if self._yprev is not None:
                Xn = Xn + mv(L, self._yprev - mv(C, X) - dy)
            X = Xn
        elif mdl.kind == "linear":
            if self._yprev is None:
                Ad, Bd, cd, _, _ = mdl.linear_matrices()
                X = mv(Ad, X) + mv(Bd, U) + cd
            else:
                X = (mv(self._Phi, X) + mv(self._Gu, U) + mv(self._Gy, self._yprev)
                     + self._g)
        else:
            X = self._integrate(X, np.ascontiguousarray(U), self._yprev)
        self._check_state(X)
        self._yprev = Y.copy()
        self._x = X
        return X


class TSMultiObserver(_ContinuousBase):
    """Takagi-Sugeno multi-observer (seed 001 eq. 20), continuous, RK4 substeps.

    Parameters
    ----------
    plant : Plant
        The plant the TS model was built from (dimensions, names).
    ts_model : object
        Multiple model with ``rhs(X (M, n), U (M, m)) -> (M, n)`` (state
        units/s; memberships evaluated at the estimate) and ``C`` (q, n),
        e.g. `tanksynth.design.observer_lmi.weighting.TSModel`.
    tuning : LuenbergerTuning
        ``form`` must be ``"continuous"``; ``L`` from the LMI (28).
    runs : int, optional
    """

    method = "ts_multi_observer"

    def __init__(self, plant: Plant, ts_model: Any, tuning: LuenbergerTuning,
                 runs: int | None = None):
        if not isinstance(tuning, LuenbergerTuning) or tuning.form != "continuous":
            raise SpecError("TSMultiObserver needs a LuenbergerTuning with form = 'continuous'",
                            key="tuning")
        if not hasattr(ts_model, "rhs") or not hasattr(ts_model, "C"):
            raise SpecError("ts_model must provide rhs(X, U) and C (a TSModel)", key="ts_model")
        super().__init__(plant, tuning, runs)
        C = as_matrix(ts_model.C, "ts_model.C")
        if C.shape != (plant.q, plant.n) or tuning.L.shape != (plant.n, plant.q):
            raise DimensionError(f"C is {C.shape} and L is {tuning.L.shape}; expected "
                                 f"({plant.q}, {plant.n}) and ({plant.n}, {plant.q})")
        fits_plant(tuning, plant)
        self.ts_model = ts_model
        self._C = C
        self._setup_field(ts_model.rhs, lambda X: mv(C, X))
        A0 = getattr(ts_model, "A0", None)
        self.error_matrix = None if A0 is None else np.asarray(A0) - tuning.L @ C
        self.reset()

    def _clone_args(self) -> tuple[tuple, dict]:
        return (self.plant, self.ts_model, self.tuning), {}

    def _advance(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        X = self._integrate(self._x, np.ascontiguousarray(U), self._yprev)
        self._check_state(X)
        self._yprev = Y.copy()
        self._x = X
        return X
