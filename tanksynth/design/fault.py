"""Observer-based fault detection with a derived threshold (seed 004 section II-F).

With the Luenberger observer ``dx_hat/dt = A x_hat + B u + Psi (y - C x_hat)``
of the healthy model, the error ``e = x - x_hat`` of the healthy plant obeys
``de/dt = Gamma_d e`` (``Gamma_d = A - Psi C``) and the output residual is
``epsilon(t) = C e(t) = C exp(Gamma_d t) e(0)`` (eq. 52). With every initial
level in ``(x_lo, x_hi]`` and the observer started at ``x_hat_i(0) = x_lo``,
the largest initial error is ``e_hat_i = x_hi - x_lo`` and the threshold is
(eq. 53)::

    epsilon_bar(t) = C exp(Gamma_d t) e_hat = sum_i c_i exp(lambda_i t)

derived here in exact arithmetic (sympy, rational parameter values of the
plant). With seed 004's numbers (``Psi = (855, 509/3, 41)``, poles
``-5, -8, -10``, ``1/4 < x_i(0) <= 4``) it is exactly
``78/64 e^{-5t} - 765/64 e^{-8t} + 807/64 e^{-10t}`` (eq. 54); the
conservative threshold takes every term positive (eq. 55). A fault is
detected at the first ``t_d > t_f`` with ``|epsilon(t_d)| > epsilon_bar(t_d)``.

Residuals are computed exactly for the linear plant: the plant and observer
are one linear system with piecewise-constant input and fault, propagated by
matrix exponentials (no integration error), and the crossing is refined by
Brent's method.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterator, Sequence

import numpy as np
import scipy.linalg as sla
import sympy as sp
from scipy.optimize import brentq

from tanksynth.errors import DimensionError, SpecError
from tanksynth.plants.base import Plant, exact

__all__ = [
    "FaultThreshold",
    "fault_threshold",
    "DetectionResult",
    "residual",
    "detection_time",
    "SEED004_INITIAL_STATES",
    "SEED004_DETECTION_TIMES",
    "seed004_detection",
    "fit_fault_size",
]

#: Initial states x0(1), x0(2), x0(3) of seed 004 section IV.
SEED004_INITIAL_STATES = ((0.26, 0.26, 0.26), (4.0, 4.0, 4.0), (2.4, 3.6, 1.8))
#: Detection times printed in seed 004 section IV (s), in the same order.
SEED004_DETECTION_TIMES = (2.0235, 2.015, 2.0165)
#: Seed 004's input: 2 on [0, 1), then 1 (section IV).
SEED004_INPUT = ((0.0, 2.0), (1.0, 1.0))


def _linear_matrices(plant: Plant) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    """Exact ``A, B, C`` of a linear plant (Jacobians with rational parameter values)."""
    x, u = sp.Matrix(plant.x), sp.Matrix(plant.u)
    A = plant.f_numeric.jacobian(x)
    B = plant.f_numeric.jacobian(u)
    C = plant.h_numeric.jacobian(x)
    syms = set(plant.x) | set(plant.u)
    for name, M in (("A", A), ("B", B), ("C", C)):
        if any(e.free_symbols & syms for e in M):
            raise SpecError(f"fault detection needs a linear plant; d f/d x ({name}) depends on "
                            "the state or input", key="plant.model")
    return A, B, C


def _exact_rational_matrix(M: Any, shape: tuple[int, int], name: str) -> sp.Matrix:
    if isinstance(M, sp.MatrixBase):
        out = sp.Matrix(M)
    else:
        arr = np.asarray(M, dtype=float)
        if arr.size != shape[0] * shape[1]:
            raise DimensionError(f"{name} must have shape {shape}, got {arr.shape}")
        arr = arr.reshape(shape)
        if not np.all(np.isfinite(arr)):
            raise DimensionError(f"{name} has non-finite entries")
        out = sp.Matrix(shape[0], shape[1], [exact(v) for v in arr.ravel()])
    if out.shape != shape:
        raise DimensionError(f"{name} must have shape {shape}, got {out.shape}")
    return out


@dataclass(frozen=True, eq=False)
class FaultThreshold:
    """The residual threshold of seed 004 eq. 53-55, exact.

    Attributes
    ----------
    A, B, C : sympy.Matrix
        Healthy plant matrices (exact).
    Psi : sympy.Matrix, shape (n, 1)
        Observer gain.
    Gamma_d : sympy.Matrix
        ``A - Psi C``.
    e_hat : sympy.Matrix, shape (n, 1)
        Largest initial error ``x_hi - x_lo``.
    x_hat0 : sympy.Matrix, shape (n, 1)
        Observer initial state (``x_lo`` in every entry).
    t : sympy.Symbol
        Time (s).
    expression : sympy.Expr
        ``C exp(Gamma_d t) e_hat`` (eq. 54).
    conservative : sympy.Expr
        Same terms with positive coefficients (eq. 55).
    terms : tuple of (sympy.Rational, sympy.Expr)
        ``(c_i, lambda_i)`` with ``expression = sum c_i exp(lambda_i t)``,
        sorted by decreasing ``lambda_i``.
    """

    A: sp.Matrix
    B: sp.Matrix
    C: sp.Matrix
    Psi: sp.Matrix
    Gamma_d: sp.Matrix
    e_hat: sp.Matrix
    x_hat0: sp.Matrix
    t: sp.Symbol
    expression: sp.Expr
    conservative: sp.Expr
    terms: tuple

    def evaluate(self, t: Any, conservative: bool = True) -> np.ndarray:
        """Threshold at times ``t`` (s), eq. 55 (or eq. 54 with ``conservative=False``)."""
        t = np.asarray(t, dtype=float)
        out = np.zeros_like(t)
        for c, lam in self.terms:
            coef = abs(float(c)) if conservative else float(c)
            out = out + coef * np.exp(complex(lam).real * t)
        return out

    def as_dict(self) -> dict:
        """JSON-friendly record (exact values as strings)."""
        return {"Psi": [str(v) for v in self.Psi], "Gamma_d": [[str(v) for v in self.Gamma_d.row(i)]
                                                               for i in range(self.Gamma_d.rows)],
                "e_hat": [str(v) for v in self.e_hat], "x_hat0": [str(v) for v in self.x_hat0],
                "threshold": str(self.expression), "threshold_conservative": str(self.conservative),
                "terms": [[str(c), str(lam)] for c, lam in self.terms]}


def fault_threshold(plant: Plant, poles: Sequence[Any] = (-5, -8, -10), *,
                    bounds: tuple[Any, Any] = (sp.Rational(1, 4), 4),
                    gain: Any = None) -> FaultThreshold:
    """Derive the detection threshold of seed 004 eq. 53-55 symbolically.

    Parameters
    ----------
    plant : Plant
        A linear single-output plant (``hydraulic_fault``); its healthy
        matrices are taken with exact rational parameter values.
    poles : sequence
        Observer poles (1/s) for the canonical-form gain (seed 004 eq. 27-29,
        `tanksynth.design.placement.canonical_observer`); ignored when
        ``gain`` is given.
    bounds : (lower, upper)
        Initial levels satisfy ``lower < x_i(0) <= upper``; the observer
        starts at ``lower``, so ``e_hat_i = upper - lower``.
    gain : array_like or sympy.Matrix, shape (n, 1), optional
        Observer gain ``Psi`` (floats are read as exact decimals).

    Returns
    -------
    FaultThreshold

    Raises
    ------
    SpecError
        Nonlinear plant, ``lower >= upper``, or repeated/complex observer
        poles (the threshold is then not a plain sum of exponentials).
    DimensionError
        Gain of the wrong shape, or more than one output.
    """
    A, B, C = _linear_matrices(plant)
    n = A.rows
    if C.rows != 1:
        raise DimensionError(f"the threshold of eq. 53 is for one output; C is {C.shape}")
    if gain is None:
        values = [complex(p) for p in poles]
        if any(v.imag != 0 for v in values) or len(set(values)) != len(values):
            raise SpecError("the threshold is derived for distinct real observer poles, got "
                            f"{list(poles)}", key="poles")
        poles = [p if isinstance(p, sp.Basic) else exact(complex(p).real) for p in poles]
        from tanksynth.design.placement import canonical_observer

        Psi = canonical_observer(A, C, list(poles)).Psi
    else:
        Psi = _exact_rational_matrix(gain, (n, 1), "gain")
    lo, hi = (b if isinstance(b, sp.Basic) else exact(b) for b in bounds)
    if not lo < hi:
        raise SpecError(f"bounds must satisfy lower < upper, got {bounds}", key="bounds")
    Gamma = (A - Psi * C).applyfunc(sp.nsimplify)
    eig = Gamma.eigenvals()
    if any(mult > 1 or not sp.im(lam) == 0 for lam, mult in eig.items()):
        raise SpecError(f"Gamma_d = A - Psi C must have distinct real eigenvalues, got {eig}",
                        key="gain")
    t = sp.Symbol("t", nonnegative=True)
    e_hat = sp.Matrix([hi - lo] * n)
    P, D = Gamma.diagonalize()
    expo = P * sp.diag(*[sp.exp(D[i, i] * t) for i in range(n)]) * P.inv()
    expr = sp.expand(sp.simplify((C * expo * e_hat)[0]))
    terms = []
    for lam in sorted(set(D[i, i] for i in range(n)), key=lambda v: -complex(v).real):
        coef = sp.nsimplify(sp.simplify(expr.coeff(sp.exp(lam * t))))
        if coef != 0:
            terms.append((coef, lam))
    rebuilt = sum(c * sp.exp(lam * t) for c, lam in terms)
    if sp.simplify(rebuilt - expr) != 0:
        raise SpecError("the threshold is not a plain sum of exponentials (repeated or complex "
                        "observer poles); choose distinct real poles", key="poles")
    conservative = sum(abs(c) * sp.exp(lam * t) for c, lam in terms)
    return FaultThreshold(A, B, C, Psi, Gamma, e_hat, sp.Matrix([lo] * n), t, rebuilt,
                          conservative, tuple(terms))


@dataclass(frozen=True, eq=False)
class DetectionResult:
    """Detection of one simulated fault.

    Attributes
    ----------
    x0 : ndarray
        Plant initial state.
    delta_bar : float
        Fault size (leak coefficient of tank 2, 1/s).
    t_fault : float
        Fault onset (s).
    t_detect : float or None
        First time after ``t_fault`` with ``|epsilon| > epsilon_bar`` (s);
        None if not within the horizon.
    conservative : bool
        Threshold eq. 55 (True) or eq. 54.
    false_alarm : float or None
        First time before ``t_fault`` the residual exceeds the threshold.
    paper : float or None
        The seed's printed detection time for this initial state.
    """

    x0: np.ndarray
    delta_bar: float
    t_fault: float
    t_detect: float | None
    conservative: bool
    false_alarm: float | None
    paper: float | None = None

    def as_dict(self) -> dict:
        """JSON-friendly record."""
        return {"x0": list(map(float, self.x0)), "delta_bar": self.delta_bar,
                "t_fault": self.t_fault, "t_detect": self.t_detect,
                "threshold": "eq. 55 (conservative)" if self.conservative else "eq. 54",
                "false_alarm_before_fault": self.false_alarm, "paper_t_detect": self.paper,
                "difference_to_paper": (None if self.paper is None or self.t_detect is None
                                        else self.t_detect - self.paper)}


@dataclass
class _Simulator:
    """Plant + observer as one linear system with piecewise-constant input and fault."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Psi: np.ndarray
    fault: np.ndarray
    x0: np.ndarray
    x_hat0: np.ndarray
    inputs: tuple
    t_fault: float
    _cache: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = self.A.shape[0]
        breaks = sorted({0.0, self.t_fault, *(float(t) for t, _ in self.inputs)})
        self.breaks = [b for b in breaks if b >= 0.0]
        z = np.concatenate([self.x0, self.x_hat0])
        self.states = [z]
        for a, b in zip(self.breaks[:-1], self.breaks[1:]):
            z = self._propagate(a, z, b - a)
            self.states.append(z)
        self.n = n

    def _segment(self, t0: float) -> np.ndarray:
        if t0 in self._cache:
            return self._cache[t0]
        n = self.A.shape[0]
        Af = self.A + (self.fault if t0 >= self.t_fault else 0.0)
        u = [v for s, v in self.inputs if s <= t0][-1]
        M = np.zeros((2 * n + 1, 2 * n + 1))
        M[:n, :n] = Af
        M[n:2 * n, :n] = self.Psi @ self.C
        M[n:2 * n, n:2 * n] = self.A - self.Psi @ self.C
        M[:n, -1] = (self.B * u).ravel()
        M[n:2 * n, -1] = (self.B * u).ravel()
        self._cache[t0] = M
        return M

    def _propagate(self, t0: float, z: np.ndarray, dt: float) -> np.ndarray:
        E = sla.expm(self._segment(t0) * dt)
        return (E @ np.append(z, 1.0))[:-1]

    def residual(self, t: float) -> float:
        """``epsilon(t) = C (x(t) - x_hat(t))``."""
        i = max(j for j, b in enumerate(self.breaks) if b <= t)
        z = self._propagate(self.breaks[i], self.states[i], t - self.breaks[i])
        n = self.n
        return float((self.C @ (z[:n] - z[n:]))[0])

    def residuals(self, t0: float, t1: float, dt: float,
                  chunk: int = 512) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Residual on a uniform grid inside one segment, in chunks (exact propagation)."""
        i = max(j for j, b in enumerate(self.breaks) if b <= t0)
        z = self._propagate(self.breaks[i], self.states[i], t0 - self.breaks[i])
        E = sla.expm(self._segment(self.breaks[i]) * dt)
        powers = np.empty((chunk, *E.shape))
        powers[0] = np.eye(E.shape[0])
        for k in range(1, chunk):
            powers[k] = E @ powers[k - 1]
        step = E @ powers[-1]
        count = int(np.floor((t1 - t0) / dt + 1e-9)) + 1
        za = np.append(z, 1.0)
        D = np.concatenate([self.C[0], -self.C[0], [0.0]])
        for start in range(0, count, chunk):
            k = min(chunk, count - start)
            Z = powers[:k] @ za
            yield t0 + dt * (start + np.arange(k)), Z @ D
            za = step @ za


def _simulator(th: FaultThreshold, x0: Any, delta_bar: float, t_fault: float,
               inputs: Sequence[tuple[float, float]], fault_matrix: Any) -> _Simulator:
    n = th.A.rows
    x0 = np.asarray(x0, dtype=float).reshape(-1)
    if x0.size != n:
        raise DimensionError(f"x0 must have {n} entries, got {x0.size}")
    f = lambda M: np.array(M.evalf(17), dtype=float)  # noqa: E731
    if fault_matrix is None:
        fault_matrix = np.zeros((n, n))
        fault_matrix[1, 1] = -1.0
    F = np.asarray(fault_matrix, dtype=float) * float(delta_bar)
    return _Simulator(f(th.A), f(th.B), f(th.C), f(th.Psi), F, x0, f(th.x_hat0).ravel(),
                      tuple((float(t), float(v)) for t, v in inputs), float(t_fault))


def residual(th: FaultThreshold, x0: Any, t: Any, *, delta_bar: float = 0.0, t_fault: float = 2.0,
             inputs: Sequence[tuple[float, float]] = SEED004_INPUT,
             fault_matrix: Any = None) -> np.ndarray:
    """Exact output residual ``epsilon(t) = C (x - x_hat)`` of plant and observer.

    Parameters
    ----------
    th : FaultThreshold
        Gives the healthy matrices, the gain and the observer's initial state.
    x0 : array_like, shape (n,)
        Plant initial state.
    t : array_like
        Times (s), >= 0.
    delta_bar : float
        Fault size (>= 0): from ``t_fault`` on the plant matrix is
        ``A + delta_bar * fault_matrix``.
    t_fault : float
        Fault onset (s).
    inputs : sequence of (t_start, u)
        Piecewise-constant input (seed 004: 2 on [0, 1), then 1).
    fault_matrix : array_like, shape (n, n), optional
        Direction of the fault; default the leak of tank 2 (``-1`` at (2, 2),
        the ``-delta_bar x2`` term of ``hydraulic_fault``).

    Returns
    -------
    ndarray
        ``epsilon`` at ``t`` (output units).
    """
    sim = _simulator(th, x0, delta_bar, t_fault, inputs, fault_matrix)
    ts = np.atleast_1d(np.asarray(t, dtype=float))
    return np.array([sim.residual(v) for v in ts]).reshape(np.shape(t))


def detection_time(th: FaultThreshold, x0: Any, delta_bar: float, *, t_fault: float = 2.0,
                   conservative: bool = True, horizon: float = 3.0, dt: float = 1e-4,
                   inputs: Sequence[tuple[float, float]] = SEED004_INPUT,
                   fault_matrix: Any = None, paper: float | None = None,
                   check_false_alarm: bool = True) -> DetectionResult:
    """First time after the fault at which ``|epsilon| > epsilon_bar``.

    Parameters
    ----------
    th : FaultThreshold
    x0 : array_like, shape (n,)
        Plant initial state.
    delta_bar : float
        Fault size (1/s), > 0.
    t_fault : float
        Fault onset (s).
    conservative : bool
        Use eq. 55 (default) or eq. 54 as threshold.
    horizon : float
        Search until ``t_fault + horizon`` (s).
    dt : float
        Scan step (s); crossings are refined by Brent's method to 1e-12 s.
    inputs, fault_matrix
        See `residual`.
    paper : float, optional
        Printed detection time, carried into the result.
    check_false_alarm : bool
        Also scan ``[0, t_fault)`` for a residual above the threshold.

    Returns
    -------
    DetectionResult
    """
    if not (isinstance(delta_bar, (int, float)) and np.isfinite(delta_bar) and delta_bar > 0):
        raise SpecError(f"delta_bar must be a positive number, got {delta_bar!r}", key="delta_bar")
    sim = _simulator(th, x0, delta_bar, t_fault, inputs, fault_matrix)

    rtol = 1e-9   # |epsilon| equal to the threshold up to rounding is not a crossing

    def margin(t: float) -> float:
        bar = float(th.evaluate(t, conservative))
        return abs(sim.residual(t)) - bar - rtol * abs(bar)

    def first_crossing(t0: float, t1: float) -> float | None:
        edges = [b for b in sim.breaks if t0 < b < t1]
        previous = None
        for a, b in zip([t0, *edges], [*edges, t1]):
            for ts, eps in sim.residuals(a, b, dt):
                bar = th.evaluate(ts, conservative)
                idx = np.flatnonzero(np.abs(eps) - bar - rtol * np.abs(bar) > 0)
                if idx.size:
                    k = int(idx[0])
                    lo = ts[k - 1] if k > 0 else previous
                    if lo is None or not (margin(lo) < 0 < margin(ts[k])):
                        return float(ts[k])
                    return float(brentq(margin, lo, ts[k], xtol=1e-12))
                previous = ts[-1]
        return None

    false_alarm = first_crossing(0.0, t_fault) if check_false_alarm else None
    t_detect = first_crossing(t_fault, t_fault + horizon)
    return DetectionResult(np.asarray(x0, dtype=float), float(delta_bar), float(t_fault), t_detect,
                           conservative, false_alarm, paper)


def seed004_detection(th: FaultThreshold, delta_bar: float, *, conservative: bool = True,
                      t_fault: float = 2.0) -> tuple[DetectionResult, ...]:
    """Detection times for the three initial states of seed 004, beside the printed ones."""
    return tuple(detection_time(th, x0, delta_bar, t_fault=t_fault, conservative=conservative,
                                paper=paper)
                 for x0, paper in zip(SEED004_INITIAL_STATES, SEED004_DETECTION_TIMES))


def fit_fault_size(th: FaultThreshold, x0: Any, t_detect: float, *, t_fault: float = 2.0,
                   conservative: bool = True, bracket: tuple[float, float] = (1e-3, 1e3)) -> float | None:
    """Fault size whose detection time equals ``t_detect`` (None if outside ``bracket``).

    Used to ask which ``delta_bar`` the seed's printed times would need.
    """
    def gap(log_d: float) -> float:
        res = detection_time(th, x0, float(np.exp(log_d)), t_fault=t_fault,
                             conservative=conservative, horizon=max(1.0, 2 * (t_detect - t_fault)),
                             check_false_alarm=False)
        return (res.t_detect if res.t_detect is not None else np.inf) - t_detect

    lo, hi = np.log(bracket[0]), np.log(bracket[1])
    g_lo, g_hi = gap(lo), gap(hi)
    if not (g_lo > 0 > g_hi):
        return None
    return float(np.exp(brentq(gap, lo, hi, xtol=1e-10)))
