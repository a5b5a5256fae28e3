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

Residuals are simulated by the toolbox's one integrator: the plant and the
observer are one linear system with piecewise-constant input and fault, and
on a linear system the simulator's RK4 step is a matrix
(`tanksynth.sim.integrate.rk4_matrix`, fourth order: with the default step
of 0.1 ms the residual agrees with the matrix exponential to ~1e-13 of the
threshold), applied to the plant-and-observer state (the plant's levels are
checked against its clipping rule, `Plant.state_bounds`). The scan grid is
the integration grid; a crossing is refined by Brent's method on the RK4
interpolant (a partial step from the last grid point).

The input schedule, the initial states and the fault are arguments: nothing
here belongs to one particular study.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterator, Sequence

import numpy as np
import sympy as sp

from tanksynth.design.placement.canonical import canonical_observer
from tanksynth.errors import DimensionError, SimulationError, SpecError
from tanksynth.plants.base import Plant, exact
from tanksynth.sim.integrate import rk4_matrix

__all__ = [
    "FaultThreshold",
    "fault_threshold",
    "DetectionResult",
    "residual",
    "detection_time",
    "fit_fault_size",
]


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
        """Threshold at times ``t`` (s), eq. 55 (or eq. 54 with ``conservative=False``).

        Parameters
        ----------
        t : float or array_like
            Times [s].
        conservative : bool, optional
            Eq. 55 (True) or eq. 54 (False).
        """
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
        `tanksynth.design.placement.canonical.canonical_observer`); ignored when
        ``gain`` is given.
    bounds : (lower, upper)
        Initial levels satisfy ``lower < x_i(0) <= upper``; the observer
        starts at ``lower``, so ``e_hat_i = upper - lower``.
    gain : array_like or sympy.Matrix, shape (n, 1), optional
        Observer gain ``Psi`` (1/s; floats are read as exact decimals).

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
        Plant initial state (state units, m).
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
        First time before ``t_fault`` the residual exceeds the threshold (s).
    reference : float or None
        A detection time to compare with (s), e.g. one published for this
        initial state; carried through, never used in the computation.
    """

    x0: np.ndarray
    delta_bar: float
    t_fault: float
    t_detect: float | None
    conservative: bool
    false_alarm: float | None
    reference: float | None = None

    def as_dict(self) -> dict:
        """JSON-friendly record."""
        return {"x0": list(map(float, self.x0)), "delta_bar": self.delta_bar,
                "t_fault": self.t_fault, "t_detect": self.t_detect,
                "threshold": ("the sum of |c_i| exp(lambda_i t) over the error modes i (conservative)"
                              if self.conservative else "the sum of c_i exp(lambda_i t) over the error modes i"),
                "false_alarm_before_fault": self.false_alarm, "reference_t_detect": self.reference,
                "difference_to_reference": (None if self.reference is None or self.t_detect is None
                                            else self.t_detect - self.reference)}


@dataclass
class _LinearRun:
    """Plant + observer as one linear system with piecewise-constant input and fault.

    The state ``z = (x, x_hat, 1)`` obeys ``dz/dt = M_i z`` on segment ``i``
    (between consecutive breaks: 0, input changes, fault onset) and is
    advanced by the simulator's RK4 step of ``h`` seconds written as a
    matrix, ``R_i = rk4_matrix(M_i, h)``, from the segment's start; a time
    off the grid is reached by a last partial step.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Psi: np.ndarray
    fault: np.ndarray
    x0: np.ndarray
    x_hat0: np.ndarray
    inputs: tuple
    t_fault: float
    h: float
    lower: np.ndarray
    upper: np.ndarray
    _cache: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.n = self.A.shape[0]
        breaks = sorted({0.0, self.t_fault, *(float(t) for t, _ in self.inputs)})
        self.breaks = [b for b in breaks if b >= 0.0]
        z = np.concatenate([self.x0, self.x_hat0, [1.0]])
        self._check(z[None], 0.0)
        self.states = [z]
        for i, (a, b) in enumerate(zip(self.breaks[:-1], self.breaks[1:])):
            z = self._advance(i, z, b - a)
            self._check(z[None], b)
            self.states.append(z)

    def _segment(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """``(M_i, R_i)`` of segment ``i``."""
        if i in self._cache:
            return self._cache[i]
        n = self.n
        t0 = self.breaks[i]
        Af = self.A + (self.fault if t0 >= self.t_fault else 0.0)
        u = [v for s, v in self.inputs if s <= t0][-1]
        M = np.zeros((2 * n + 1, 2 * n + 1))
        M[:n, :n] = Af
        M[n:2 * n, :n] = self.Psi @ self.C
        M[n:2 * n, n:2 * n] = self.A - self.Psi @ self.C
        M[:n, -1] = self.B @ u
        M[n:2 * n, -1] = self.B @ u
        self._cache[i] = (M, rk4_matrix(M, self.h))
        return self._cache[i]

    def _advance(self, i: int, z: np.ndarray, dt: float) -> np.ndarray:
        """``z`` advanced by ``dt`` >= 0 seconds from the start of segment ``i``."""
        M, R = self._segment(i)
        k = int(np.floor(dt / self.h + 1e-9))
        rest = dt - k * self.h
        z = np.linalg.matrix_power(R, k) @ z
        return rk4_matrix(M, rest) @ z if rest > 1e-9 * self.h else z

    def _check(self, Z: np.ndarray, t: float) -> None:
        X = Z[:, :self.n]
        if np.any(X < self.lower) or np.any(X > self.upper):
            raise SimulationError(f"the plant's levels leave its state bounds near t = {t:.6g} s "
                                  f"(lower {self.lower.tolist()}, upper {self.upper.tolist()}); the "
                                  "linear residual model no longer holds there")

    def _index(self, t: float) -> int:
        return max(j for j, b in enumerate(self.breaks) if b <= t)

    def residual(self, t: float) -> float:
        """``epsilon(t) = C (x(t) - x_hat(t))``."""
        i = self._index(t)
        z = self._advance(i, self.states[i], t - self.breaks[i])
        n = self.n
        return float((self.C @ (z[:n] - z[n:2 * n]))[0])

    def residuals(self, t0: float, t1: float, chunk: int = 512) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Residual on the integration grid from ``t0`` (a break) to ``t1``, in chunks."""
        i = self._index(t0)
        if t0 != self.breaks[i]:
            raise SimulationError(f"a residual scan starts at a break, got t0 = {t0}")
        _, E = self._segment(i)
        powers = np.empty((chunk, *E.shape))
        powers[0] = np.eye(E.shape[0])
        for k in range(1, chunk):
            powers[k] = E @ powers[k - 1]
        step = E @ powers[-1]
        count = int(np.floor((t1 - t0) / self.h + 1e-9)) + 1
        za = self.states[i]
        D = np.concatenate([self.C[0], -self.C[0], [0.0]])
        for start in range(0, count, chunk):
            k = min(chunk, count - start)
            Z = powers[:k] @ za
            ts = t0 + self.h * (start + np.arange(k))
            self._check(Z, float(ts[0]))
            yield ts, Z @ D
            za = step @ za


def _schedule(input_schedule: Any, m: int) -> tuple[tuple[float, np.ndarray], ...]:
    """Validated ``((t_start, u), ...)``: starts increasing from 0, ``u`` of m values."""
    if input_schedule is None:
        return ((0.0, np.zeros(m)),)
    pieces = []
    for piece in input_schedule:
        try:
            start, value = piece
            u = np.asarray(value, dtype=float).reshape(-1)
            start = float(start)
        except (TypeError, ValueError):
            raise SpecError(f"input_schedule entries must be (t_start, u) pairs, got {piece!r}",
                            key="input_schedule") from None
        if u.size != m or not np.all(np.isfinite(u)) or not np.isfinite(start):
            raise SpecError(f"input_schedule: u must have {m} finite values, got {value!r} at "
                            f"t = {start}", key="input_schedule")
        pieces.append((start, u))
    starts = [t for t, _ in pieces]
    if not pieces or starts[0] > 0.0 or any(b <= a for a, b in zip(starts[:-1], starts[1:])):
        raise SpecError(f"input_schedule must start at t <= 0 and increase, got starts {starts}",
                        key="input_schedule")
    return tuple(pieces)


def _linear_run(th: FaultThreshold, x0: Any, delta_bar: float, t_fault: float,
                input_schedule: Any, fault_matrix: Any, dt: float,
                bounds: tuple[np.ndarray, np.ndarray] | None) -> _LinearRun:
    n = th.A.rows
    x0 = np.asarray(x0, dtype=float).reshape(-1)
    if x0.size != n:
        raise DimensionError(f"x0 must have {n} entries, got {x0.size}")
    if not (np.isfinite(dt) and dt > 0):
        raise SpecError(f"dt must be a positive step (s), got {dt!r}", key="dt")
    f = lambda M: np.array(M.evalf(17), dtype=float)  # noqa: E731
    if fault_matrix is None:
        fault_matrix = np.zeros((n, n))
        fault_matrix[1, 1] = -1.0
    F = np.asarray(fault_matrix, dtype=float) * float(delta_bar)
    lower, upper = bounds if bounds is not None else (np.full(n, -np.inf), np.full(n, np.inf))
    return _LinearRun(f(th.A), f(th.B), f(th.C), f(th.Psi), F, x0, f(th.x_hat0).ravel(),
                      _schedule(input_schedule, th.B.cols), float(t_fault), float(dt),
                      np.asarray(lower, dtype=float), np.asarray(upper, dtype=float))


def residual(th: FaultThreshold, x0: Any, t: Any, *, delta_bar: float = 0.0, t_fault: float = 2.0,
             input_schedule: Sequence[tuple[float, Any]] | None = None, fault_matrix: Any = None,
             dt: float = 1e-4, plant: Plant | None = None) -> np.ndarray:
    """Output residual ``epsilon(t) = C (x - x_hat)`` of plant and observer (simulated).

    Parameters
    ----------
    th : FaultThreshold
        Gives the healthy matrices, the gain and the observer's initial state.
    x0 : array_like, shape (n,)
        Plant initial state (state units, m).
    t : array_like
        Times (s), >= 0.
    delta_bar : float
        Fault size (>= 0): from ``t_fault`` on the plant matrix is
        ``A + delta_bar * fault_matrix``.
    t_fault : float
        Fault onset (s).
    input_schedule : sequence of (t_start, u), optional
        Piecewise-constant input: ``u`` (a number, or ``m`` numbers, input
        units) from ``t_start`` (s) on; starts increasing, the first at 0.
        Default: zero input throughout.
    fault_matrix : array_like, shape (n, n), optional
        Direction of the fault; default the leak of tank 2 (``-1`` at (2, 2),
        the ``-delta_bar x2`` term of ``hydraulic_fault``).
    dt : float
        RK4 step of the simulation (s).
    plant : Plant, optional
        The plant whose clipping rule (`Plant.state_bounds`) the levels must
        respect (a `SimulationError` otherwise); default no bounds.

    Returns
    -------
    ndarray
        ``epsilon`` at ``t`` (output units).
    """
    run = _linear_run(th, x0, delta_bar, t_fault, input_schedule, fault_matrix, dt,
                      None if plant is None else plant.state_bounds())
    ts = np.atleast_1d(np.asarray(t, dtype=float))
    return np.array([run.residual(v) for v in ts]).reshape(np.shape(t))


def detection_time(th: FaultThreshold, x0: Any, delta_bar: float, *, t_fault: float = 2.0,
                   conservative: bool = True, horizon: float = 3.0, dt: float = 1e-4,
                   input_schedule: Sequence[tuple[float, Any]] | None = None,
                   fault_matrix: Any = None, reference: float | None = None,
                   check_false_alarm: bool = True, plant: Plant | None = None) -> DetectionResult:
    """First time after the fault at which ``|epsilon| > epsilon_bar``.

    Parameters
    ----------
    th : FaultThreshold
    x0 : array_like, shape (n,)
        Plant initial state (state units, m).
    delta_bar : float
        Fault size (1/s), > 0.
    t_fault : float
        Fault onset (s).
    conservative : bool
        Use eq. 55 (default) or eq. 54 as threshold.
    horizon : float
        Search until ``t_fault + horizon`` (s).
    dt : float
        RK4 step of the simulation and scan step (s); crossings are refined
        by Brent's method to 1e-12 s.
    input_schedule, fault_matrix, plant
        See `residual`.
    reference : float, optional
        A detection time to compare with (s), carried into the result.
    check_false_alarm : bool
        Also scan ``[0, t_fault)`` for a residual above the threshold.

    Returns
    -------
    DetectionResult
    """
    from scipy.optimize import brentq  # deferred: scipy.optimize imports in ~0.3 s
    if not (isinstance(delta_bar, (int, float)) and np.isfinite(delta_bar) and delta_bar > 0):
        raise SpecError(f"delta_bar must be a positive number, got {delta_bar!r}", key="delta_bar")
    run = _linear_run(th, x0, delta_bar, t_fault, input_schedule, fault_matrix, dt,
                      None if plant is None else plant.state_bounds())

    rtol = 1e-9   # |epsilon| equal to the threshold up to rounding is not a crossing

    def margin(t: float) -> float:
        bar = float(th.evaluate(t, conservative))
        return abs(run.residual(t)) - bar - rtol * abs(bar)

    def first_crossing(t0: float, t1: float) -> float | None:
        edges = [b for b in run.breaks if t0 < b < t1]
        previous = None
        for a, b in zip([t0, *edges], [*edges, t1]):
            for ts, eps in run.residuals(a, b):
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
                           conservative, false_alarm, reference)


def fit_fault_size(th: FaultThreshold, x0: Any, t_detect: float, *, t_fault: float = 2.0,
                   conservative: bool = True, bracket: tuple[float, float] = (1e-3, 1e3),
                   input_schedule: Sequence[tuple[float, Any]] | None = None,
                   fault_matrix: Any = None, dt: float = 1e-4) -> float | None:
    """Fault size whose detection time equals ``t_detect`` (None if outside ``bracket``).

    Used to ask which ``delta_bar`` a given (e.g. published) detection time
    would need; the other arguments are those of `detection_time`.

    Parameters
    ----------
    th : FaultThreshold
        The residual threshold.
    x0 : array_like, shape (n,)
        Plant initial state (state units, m).
    t_detect : float
        Detection time to reach [s].
    t_fault : float, optional
        Fault onset [s].
    conservative : bool, optional
        Use eq. 55 (default) or eq. 54 as threshold.
    bracket : (float, float), optional
        Search interval of the fault size [1/s].
    input_schedule, fault_matrix
        See `residual`.
    dt : float, optional
        RK4 step of the simulation and scan step [s].
    """
    from scipy.optimize import brentq  # deferred: scipy.optimize imports in ~0.3 s
    def gap(log_d: float) -> float:
        res = detection_time(th, x0, float(np.exp(log_d)), t_fault=t_fault,
                             conservative=conservative, horizon=max(1.0, 2 * (t_detect - t_fault)),
                             check_false_alarm=False, input_schedule=input_schedule,
                             fault_matrix=fault_matrix, dt=dt)
        return (res.t_detect if res.t_detect is not None else np.inf) - t_detect

    lo, hi = np.log(bracket[0]), np.log(bracket[1])
    g_lo, g_hi = gap(lo), gap(hi)
    if not (g_lo > 0 > g_hi):
        return None
    return float(np.exp(brentq(gap, lo, hi, xtol=1e-10)))
