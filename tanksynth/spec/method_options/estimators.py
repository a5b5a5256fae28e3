"""Options of the state estimators: ``kalman``, ``ekf``, ``ukf``, ``adaptive_kalman``,
``adaptive_scaling_kalman``, ``consensus_filter``, ``luenberger``, ``narx``.

Covariances are given as a number (``s I``), a list (the diagonal) or a list
of rows, in the squared state (``Q``, ``P0``) or output (``R``) units. The
initial estimate ``x0`` defaults to the operating point.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np

from tanksynth.errors import SpecError
from tanksynth.spec.method_options.base import MethodOptions, OptionReader, option
from tanksynth.spec.options import (parse_bool, parse_choice, parse_covariance, parse_integer,
                                    parse_matrix, parse_number, parse_poles, parse_vector)

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["OBSERVER_FORMS", "KalmanOptions", "EkfOptions", "UkfOptions", "AdaptiveKalmanOptions",
           "AdaptiveScalingKalmanOptions", "ConsensusFilterOptions", "LuenbergerOptions",
           "NarxOptions"]

#: Largest RK4 substeps per sample: beyond it the model step is a huge expression and no
#: accuracy is gained (an RK4 error of ts^5 / substeps^4 is below rounding far earlier).
MAX_SUBSTEPS = 1000
#: Largest window or sample count an option may ask for (memory and time stay reasonable).
MAX_SAMPLES = 1_000_000
#: Largest NARX sizes: hidden neurons, delays, data runs and samples, substeps, optimiser budget.
NARX_LIMITS = {"hidden": 1000, "delays": 100, "runs": 1000, "validation_runs": 1000,
               "steps": MAX_SAMPLES, "sim_substeps": MAX_SUBSTEPS, "restarts": 100,
               "max_iter": 100_000, "max_fail": 1000}

#: Forms of the Luenberger observer.
OBSERVER_FORMS = ("current", "predictor", "continuous")

_LINEAR_DOC = """
    R : ndarray
        Required. Measurement-noise covariance (q x q, squared output units,
        positive definite).
    P0 : ndarray
        Required. Initial estimate covariance (n x n, squared state units,
        positive definite).
    x0 : ndarray or None
        Initial estimate (n values, state units); default None: the operating
        point."""

_NOISE_DOC = """
    Q : ndarray
        Required. Process-noise covariance per sample (n x n, squared state
        units, positive semidefinite).""" + _LINEAR_DOC + """
    substeps : int
        RK4 substeps of the prediction per sample (1 to 1000); default 1.
    clip : bool
        Clip the predicted levels at 0 (the plant's rule); default false."""

_JACOBIAN_DOC = """
    jacobian_eps : float
        Relative step of the finite-difference Jacobians (> 0); default 1e-6.
    switch_tol : float
        Distance to a hybrid switching surface below which the Jacobian is
        one-sided (state units, >= 0); default 0."""


def _x0(r: OptionReader, plant: Plant) -> np.ndarray | None:
    return r.read("x0", parse_vector, names=[s.name for s in plant.states])


def _filter_fields(r: OptionReader, plant: Plant, Q: str = "Q", q_size: int | None = None
                   ) -> dict[str, Any]:
    """``Q`` (``q_size`` square, default n), ``R``, ``P0``, ``x0`` (and ``substeps``, ``clip``
    when the class has them)."""
    n, q = plant.n, plant.q
    out = {Q: r.read(Q, parse_covariance, q_size or n, semidefinite=True),
           "R": r.read("R", parse_covariance, q),
           "P0": r.read("P0", parse_covariance, n), "x0": _x0(r, plant)}
    if "substeps" in r.cls.option_names():
        out["substeps"] = r.read("substeps", parse_integer, at_least=1, at_most=MAX_SUBSTEPS)
        out["clip"] = r.read("clip", parse_bool)
    return out


@dataclass(frozen=True, eq=False)
class _FilterOptions(MethodOptions):
    """Fields shared by the Kalman-type filters (documented in each method's class)."""

    needs_sampling: ClassVar[bool] = True

    Q: np.ndarray = option(unit="(state units)^2")
    R: np.ndarray = option(unit="(output units)^2")
    P0: np.ndarray = option(unit="(state units)^2")
    x0: np.ndarray | None = option(None, unit="state units")
    substeps: int = option(1, unit="-")
    clip: bool = option(False, unit="-")


@dataclass(frozen=True, eq=False)
class KalmanOptions(_FilterOptions):
    __doc__ = f"""Options of ``kalman``: the Kalman filter (CKF) on the ZOH linearisation at the
    operating point, with its steady-state gain.

    Attributes
    ----------{_NOISE_DOC}{_JACOBIAN_DOC}
    """

    method_name: ClassVar[str] = "kalman"

    jacobian_eps: float = option(1e-6, unit="-")
    switch_tol: float = option(0.0, unit="state units")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "KalmanOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(**_filter_fields(r, plant), **_jacobian_fields(r))


def _jacobian_fields(r: OptionReader) -> dict[str, Any]:
    return {"jacobian_eps": r.read("jacobian_eps", parse_number, above=0.0),
            "switch_tol": r.read("switch_tol", parse_number, at_least=0.0)}


@dataclass(frozen=True, eq=False)
class EkfOptions(KalmanOptions):
    __doc__ = f"""Options of ``ekf``: the extended Kalman filter on the nonlinear model.

    Attributes
    ----------{_NOISE_DOC}{_JACOBIAN_DOC}
    """

    method_name: ClassVar[str] = "ekf"


@dataclass(frozen=True, eq=False)
class UkfOptions(_FilterOptions):
    __doc__ = f"""Options of ``ukf``: the unscented Kalman filter on the nonlinear model.

    Attributes
    ----------{_NOISE_DOC}
    alpha : float
        Spread of the sigma points, in (0, 1]; default 1e-3. Dimensionless.
    beta : float
        Prior-distribution weight (>= 0; 2 is optimal for a Gaussian); default 2.
    kappa : float
        Secondary scaling, with n + kappa > 0; default 0.
    redraw : bool
        Redraw the sigma points after the prediction; default true.
    """

    method_name: ClassVar[str] = "ukf"

    alpha: float = option(1e-3, unit="-")
    beta: float = option(2.0, unit="-")
    kappa: float = option(0.0, unit="-")
    redraw: bool = option(True, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "UkfOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(**_filter_fields(r, plant),
                   alpha=r.read("alpha", parse_number, above=0.0, at_most=1.0),
                   beta=r.read("beta", parse_number, at_least=0.0),
                   kappa=r.read("kappa", parse_number, above=-float(plant.n)),
                   redraw=r.read("redraw", parse_bool))


@dataclass(frozen=True, eq=False)
class AdaptiveKalmanOptions(MethodOptions):
    __doc__ = f"""Options of ``adaptive_kalman``: Kalman filter on the linearisation whose process
    noise ``Q`` is re-estimated from an innovation window (seed 000 eq. 35-37).

    Attributes
    ----------
    Q0 : ndarray
        Required. Initial process-noise covariance (n x n, squared state
        units, positive semidefinite).{_LINEAR_DOC}
    window : int
        Required. Innovation window length in samples (>= 1).
    form : str
        ``"full"`` (default) or ``"steady_state"`` estimate of ``Q``.
    q_floor : float
        Lower bound of the estimated variances (squared state units, >= 0);
        default 0.
    """

    method_name: ClassVar[str] = "adaptive_kalman"
    needs_sampling: ClassVar[bool] = True

    Q0: np.ndarray = option(unit="(state units)^2")
    R: np.ndarray = option(unit="(output units)^2")
    P0: np.ndarray = option(unit="(state units)^2")
    window: int = option(unit="samples")
    x0: np.ndarray | None = option(None, unit="state units")
    form: str = option("full", unit="-", choices=("full", "steady_state"))
    q_floor: float = option(0.0, unit="(state units)^2")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "AdaptiveKalmanOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(**_filter_fields(r, plant, Q="Q0"),
                   window=r.read("window", parse_integer, at_least=1, at_most=MAX_SAMPLES),
                   form=r.read("form", parse_choice, ("full", "steady_state")),
                   q_floor=r.read("q_floor", parse_number, at_least=0.0))


def _abc(value: Any, key: str) -> tuple[float, float, float]:
    """``[a, b, c]``: three weights >= 0 summing to 1."""
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise SpecError("expected abc = [a, b, c] with a, b, c >= 0 and a + b + c = 1", key=key)
    a, b, c = (float(v) for v in parse_vector(value, key, 3, at_least=0.0))
    if abs(a + b + c - 1.0) > 1e-12:
        raise SpecError(f"a + b + c must equal 1, got {a:g} + {b:g} + {c:g} = {a + b + c!r}", key=key)
    return a, b, c


@dataclass(frozen=True, eq=False)
class AdaptiveScalingKalmanOptions(MethodOptions):
    __doc__ = f"""Options of ``adaptive_scaling_kalman``: Kalman filter on the linearisation with
    an adaptive scaling ``phi`` of the process noise (seed 004 eq. 30-41).

    Attributes
    ----------
    Q : ndarray
        Required. Process-noise covariance (r x r, r the columns of ``G``,
        squared state units, positive semidefinite).{_LINEAR_DOC}
    abc : tuple of float
        Required. Weights ``(a, b, c)`` of the scaling update (dimensionless,
        >= 0, summing to 1).
    G : ndarray or None
        Noise input matrix (n x r); default None: the identity.
    phi0 : float
        Initial scaling (dimensionless, >= 0); default 1.
    """

    method_name: ClassVar[str] = "adaptive_scaling_kalman"
    needs_sampling: ClassVar[bool] = True

    Q: np.ndarray = option(unit="(state units)^2")
    R: np.ndarray = option(unit="(output units)^2")
    P0: np.ndarray = option(unit="(state units)^2")
    abc: tuple[float, float, float] = option(unit="-")
    x0: np.ndarray | None = option(None, unit="state units")
    G: np.ndarray | None = option(None, unit="-")
    phi0: float = option(1.0, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "AdaptiveScalingKalmanOptions":
        """See `MethodOptions.from_table`; ``Q`` is r x r for an n x r ``G``."""
        r = OptionReader(cls, options, key, ts)
        G = r.read("G", parse_matrix, (plant.n, None))
        size = plant.n if G is None else G.shape[1]
        return cls(**_filter_fields(r, plant, q_size=size), abc=r.read("abc", _abc), G=G,
                   phi0=r.read("phi0", parse_number, at_least=0.0))


def _sensor_covariances(value: Any, key: str, q: int) -> tuple[np.ndarray, ...]:
    """``[R_1, ..., R_N]``: one covariance per redundant sensor."""
    if not isinstance(value, (list, tuple)) or not value:
        raise SpecError("expected R = [R_1, ..., R_N]: one covariance per sensor (numbers for "
                        "scalar outputs)", key=key)
    return tuple(parse_covariance(Ri, f"{key}[{i}]", q) for i, Ri in enumerate(value))


@dataclass(frozen=True, eq=False)
class ConsensusFilterOptions(MethodOptions):
    """Options of ``consensus_filter``: information-form consensus filter of N redundant
    sensors of the plant's outputs (seed 004 eq. 42-51), on the linearisation.

    Attributes
    ----------
    Q : ndarray
        Required. Process-noise covariance (n x n, squared state units,
        positive semidefinite).
    R : tuple of ndarray
        Required. One measurement-noise covariance per sensor (q x q each,
        squared output units, positive definite), written as a list.
    P0 : ndarray
        Required. Initial estimate covariance (n x n, squared state units,
        positive definite).
    x0 : ndarray or None
        Initial estimate (n values, state units); default None: the operating
        point.
    """

    method_name: ClassVar[str] = "consensus_filter"
    needs_sampling: ClassVar[bool] = True

    Q: np.ndarray = option(unit="(state units)^2")
    R: tuple[np.ndarray, ...] = option(unit="(output units)^2")
    P0: np.ndarray = option(unit="(state units)^2")
    x0: np.ndarray | None = option(None, unit="state units")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "ConsensusFilterOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        n = plant.n
        return cls(Q=r.read("Q", parse_covariance, n, semidefinite=True),
                   R=r.read("R", _sensor_covariances, plant.q),
                   P0=r.read("P0", parse_covariance, n), x0=_x0(r, plant))


@dataclass(frozen=True, eq=False)
class LuenbergerOptions(MethodOptions):
    """Options of ``luenberger``: a Luenberger observer from a gain ``L`` or from poles placed on
    the linearisation at the operating point.

    Attributes
    ----------
    L : ndarray or None
        Observer gain (n x q, state per output units); give ``L`` or ``poles``.
    poles : tuple of complex or None
        Observer poles (n of them): of ``F - L C`` (1/s) for ``form =
        "continuous"``, else in the z-plane, of ``Ad - L C`` (``predictor``) or
        ``(I - L C) Ad`` (``current``); complex poles in conjugate pairs.
    form : str
        ``"current"`` (default), ``"predictor"`` or ``"continuous"``.
    x0 : ndarray or None
        Initial estimate (n values, state units); default None: the operating
        point.
    substeps : int
        RK4 substeps per sample of the continuous form (1 to 1000); default 10.
    nonlinear : bool
        Run the continuous form on the plant's own vector field instead of
        the linearisation (needs ``form = "continuous"``); default false.
    """

    method_name: ClassVar[str] = "luenberger"
    one_of: ClassVar[tuple[tuple[str, ...], ...]] = (("L", "poles"),)
    needs_sampling: ClassVar[bool] = True

    L: np.ndarray | None = option(None, unit="(state units)/(output units)")
    poles: tuple[complex, ...] | None = option(None, unit="1/s (continuous) or - (discrete, z-plane)")
    form: str = option("current", unit="-", choices=OBSERVER_FORMS)
    x0: np.ndarray | None = option(None, unit="state units")
    substeps: int = option(10, unit="-")
    nonlinear: bool = option(False, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "LuenbergerOptions":
        """See `MethodOptions.from_table`; exactly one of ``L`` and ``poles``."""
        r = OptionReader(cls, options, key, ts)
        form = r.read("form", parse_choice, OBSERVER_FORMS)
        nonlinear = r.read("nonlinear", parse_bool)
        if nonlinear and form != "continuous":
            raise r.fail("nonlinear", "nonlinear = true needs form = 'continuous'")
        return cls(L=r.read("L", parse_matrix, (plant.n, plant.q)),
                   poles=r.read("poles", parse_poles, count=plant.n,
                                stable_in="continuous" if form == "continuous" else "discrete"),
                   form=form, x0=_x0(r, plant),
                   substeps=r.read("substeps", parse_integer, at_least=1, at_most=MAX_SUBSTEPS),
                   nonlinear=nonlinear)


def _hold(value: Any, key: str) -> tuple[int, int]:
    """``[min, max]`` samples an input is held (integers, 1 <= min <= max)."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise SpecError("expected hold = [min, max] samples (integers, 1 <= min <= max)", key=key)
    lo, hi = (parse_integer(v, f"{key}[{i}]", at_least=1) for i, v in enumerate(value))
    if lo > hi:
        raise SpecError(f"expected hold = [min, max] with min <= max, got [{lo}, {hi}]", key=key)
    return lo, hi


def _input_range(value: Any, key: str, m: int) -> np.ndarray:
    """m x 2 ``[min, max]`` of each input (input units)."""
    M = parse_matrix(value, key, (m, 2))
    if np.any(M[:, 0] > M[:, 1]):
        raise SpecError("input_range rows must be [min, max] with min <= max", key=key)
    return M


@dataclass(frozen=True, eq=False)
class NarxOptions(KalmanOptions):
    __doc__ = f"""Options of ``narx``: a NARX neural estimator trained by Levenberg-Marquardt on
    data of an EKF (its tuning below) run on the simulated plant.

    Attributes
    ----------{_NOISE_DOC}{_JACOBIAN_DOC}
    hidden : int
        Hidden neurons (1 to 1000); default 5.
    delays : int
        Delayed estimates fed back (>= 1); default 2.
    runs : int
        Training runs (>= 1); default 4.
    validation_runs : int
        Held-out runs (>= 1); default 1.
    steps : int
        Samples per run (>= 1); default 600.
    seed : int
        Seed of the training data and initial weights (>= 0); default 0.
    input_range : ndarray or None
        m x 2 ``[min, max]`` of the random inputs (input units); default None:
        the actuator range.
    hold : tuple of int
        ``(min, max)`` samples each random input (or designed set-point) is held (1 <= min <= max);
        default (30, 150).
    noise_std : ndarray or None
        Measurement-noise standard deviation (q values, output units, >= 0);
        default None: ``sqrt(diag R)``.
    sim_substeps : int
        RK4 substeps per sample of the data simulation (1 to 1000); default 10.
    target : str
        Training target: ``"ekf"`` (default, the EKF estimate) or ``"true"``.
    restarts : int
        Training restarts (>= 1); default 3.
    max_iter : int
        Levenberg-Marquardt iterations per restart (>= 1); default 200.
    max_fail : int
        Validation failures before stopping (>= 1); default 6.
    excitation : str
        Training-data excitation: ``"random"`` (default: random levels in ``input_range``
        held ``hold`` samples) or ``"designed"`` (set-point steps in ``setpoint_range`` held
        ``hold`` samples by their equilibrium inputs, plus a three-level PRBS).
    setpoint_range : ndarray or None
        ``[low, high]`` of the designed excitation's set-points (state units); required
        with ``excitation = "designed"``.
    prbs_amplitude : float
        Amplitude of the designed excitation's PRBS on every input (input units, >= 0);
        default 0.
    prbs_hold : tuple of int
        ``(min, max)`` samples a PRBS level is held; default (3, 20).
    """

    method_name: ClassVar[str] = "narx"

    hidden: int = option(5, unit="-")
    delays: int = option(2, unit="-")
    runs: int = option(4, unit="-")
    validation_runs: int = option(1, unit="-")
    steps: int = option(600, unit="samples")
    seed: int = option(0, unit="-")
    input_range: np.ndarray | None = option(None, unit="input units")
    hold: tuple[int, int] = option((30, 150), unit="samples")
    noise_std: np.ndarray | None = option(None, unit="output units")
    sim_substeps: int = option(10, unit="-")
    target: str = option("ekf", unit="-", choices=("ekf", "true"))
    restarts: int = option(3, unit="-")
    max_iter: int = option(200, unit="-")
    max_fail: int = option(6, unit="-")
    excitation: str = option("random", unit="-", choices=("random", "designed"))
    setpoint_range: np.ndarray | None = option(None, unit="state units",
                                                 default_text="unset: needed only with excitation = \"designed\"")
    prbs_amplitude: float = option(0.0, unit="input units")
    prbs_hold: tuple[int, int] = option((3, 20), unit="samples")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "NarxOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        counts = {name: r.read(name, parse_integer, at_least=1, at_most=NARX_LIMITS[name])
                  for name in ("hidden", "delays", "runs", "validation_runs", "steps", "sim_substeps",
                               "restarts", "max_iter", "max_fail")}
        return cls(**_filter_fields(r, plant), **_jacobian_fields(r), **counts,
                   seed=r.read("seed", parse_integer, at_least=0),
                   input_range=r.read("input_range", _input_range, plant.m),
                   hold=r.read("hold", _hold),
                   noise_std=r.read("noise_std", parse_vector, plant.q, at_least=0.0),
                   target=r.read("target", parse_choice, ("ekf", "true")),
                   excitation=r.read("excitation", parse_choice, ("random", "designed")),
                   setpoint_range=r.read("setpoint_range", parse_vector, 2, at_least=0.0),
                   prbs_amplitude=r.read("prbs_amplitude", parse_number, at_least=0.0),
                   prbs_hold=r.read("prbs_hold", _hold))

    def memory_estimate(self, plant: Plant, ts: float | None) -> tuple[float, str]:
        """The Levenberg-Marquardt Jacobian (N n x P, built twice) with N = ``steps x runs``
        samples and P weights, its P x P normal matrix, and the data runs (bytes)."""
        n, q, m = plant.n, plant.q, plant.m
        nin = n + q + self.delays * n
        weights = self.hidden * (nin + 1) + n * (self.hidden + 1)
        samples = float(self.steps) * (self.runs + self.validation_runs)
        need = 8.0 * (3 * samples * n * weights + 2 * weights ** 2
                      + 12 * samples * (n + q + m) + 2 * samples * self.hidden * nin)
        ratios = {"steps": self.steps / 600, "runs": self.runs / 4, "hidden": self.hidden / 5,
                  "delays": self.delays / 2, "validation_runs": self.validation_runs}
        return need, max(ratios, key=lambda option: ratios[option])
