"""Spec design methods of the ``estimators`` family: state estimators and observers.

===========================  =========================================================
``kalman``                   CKF on the ZOH linearisation at the operating point (seed
                             000 eq. 29-34); gains ``Q, R, P0, x_hat0``, the model
                             ``Ad, Bd, C`` at ``x_op, u_op``, the steady-state gain
                             ``K_ss`` and Riccati solution ``P_ss``
``ekf``                      EKF on the nonlinear model (seed 002 eq. 13-22)
``ukf``                      UKF (seed 002 eq. 23-40)
``adaptive_kalman``          adaptive-Q CKF with window ``Psi`` (seed 000 eq. 35-37)
``adaptive_scaling_kalman``  adaptive-scaling KF (seed 004 eq. 30-41)
``consensus_filter``         information-form consensus filter (seed 004 eq. 42-51)
``narx``                     NARX estimator trained on EKF data (seed 002 section 3.3)
``luenberger``               Luenberger observer from a gain ``L`` or poles
===========================  =========================================================

Covariance options accept a number (``s I``), a list (diagonal) or a list
of rows (full matrix), in the squared state or output units. The initial
estimate (option ``x0``, gain ``x_hat0``) defaults to the operating point. Every method refuses an
unobservable linearisation (`UnobservableError` naming the modes) and lists
physically implausible tuning values (initial estimate outside the region,
noise or initial spread larger than the region) in the diagnostics.

Every method is made by one template, `estimator_method` (name, options class, linearisation,
build step): its design function checks the observability of the linearisation at the
operating point (`_observable_at_operating_point`), reads the validated options and returns
what the method's build step ``_build_<name>(spec, design, at, options)`` gives. A build step
states only what differs: its tuning (`_kalman_tuning` for the Kalman-type filters, else the
tuning class with its extra arguments), the runtime filter built once (its model is what the
diagnostics describe), its extra gains and diagnostics (the Kalman-type filters add them to the
common ones of `_filter_outcome`), its errata; its docstring is the method's summary.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import Any, Callable, NamedTuple

import numpy as np

from tanksynth.analysis.linearize import LinearModel
from tanksynth.analysis.rank import observability_rank, pbh_test
from tanksynth.design.estimators.narx_training import train_narx
from tanksynth.design.operating_point import (as_levels, discrete_pair, equilibrium_at, linearized_at,
                                              sampling_period)
from tanksynth.design.placement.canonical import place_observer
from tanksynth.design.result import DesignMethod, DesignResult, keyed_call, options_of
from tanksynth.errors import UnobservableError
from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.adaptive import (AdaptiveKalmanFilter, AdaptiveKalmanTuning,
                                                   AdaptiveScalingKalmanFilter, AdaptiveScalingTuning)
from tanksynth.runtime.estimators.base import DiscreteModel, discrete_model
from tanksynth.runtime.estimators.consensus import ConsensusFilter, ConsensusTuning
from tanksynth.runtime.estimators.kalman import (ExtendedKalmanFilter, KalmanFilter, KalmanTuning,
                                                 steady_state_gain)
from tanksynth.runtime.estimators.luenberger import LuenbergerObserver, LuenbergerTuning
from tanksynth.runtime.estimators.ukf import UKFTuning, UnscentedKalmanFilter
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options import (AdaptiveKalmanOptions, AdaptiveScalingKalmanOptions,
                                           ConsensusFilterOptions, EkfOptions, KalmanOptions,
                                           LuenbergerOptions, MethodOptions, NarxOptions,
                                           UkfOptions)

__all__ = [
    "estimator_method", "plausibility",
    "KALMAN", "EKF", "UKF", "ADAPTIVE_KALMAN", "ADAPTIVE_SCALING_KALMAN", "CONSENSUS_FILTER",
    "NARX", "LUENBERGER",
]

#: Option named in a `SpecError` a tuning raises, by the key it uses.
_OPTION_OF = {"a": "abc", "b": "abc", "c": "abc"}
#: What the observability refusal names: the linear model a linear filter runs on, or the
#: linearisation a nonlinear estimator is only checked on.
_LINEAR_MODEL = "(Ad, C) at the operating point"
_LINEARISATION = "the linearisation at the operating point"


def _x0(spec: Spec, o: Any) -> np.ndarray:
    """The initial estimate: the option, else the operating point (state units)."""
    return np.array(spec.x0 if o.x0 is None else o.x0, dtype=float)


# ------------------------------------------------------------------------------ checks
def plausibility(plant: Plant, x0: np.ndarray, R: np.ndarray | None = None,
                 P0: np.ndarray | None = None) -> list[str]:
    """Physically odd tuning values, as sentences for the report.

    Flags an initial estimate outside the plant's region (box or flow
    orderings), a measurement noise standard deviation or an initial
    estimate spread larger than the span of the region.

    Parameters
    ----------
    plant : Plant
        The plant model (its operating region).
    x0 : ndarray, shape (n,)
        Initial estimate (state units, m).
    R : ndarray, shape (q, q), optional
        Measurement noise covariance (output units squared).
    P0 : ndarray, shape (n, n), optional
        Initial estimate covariance (state units squared).
    """
    notes = [f"initial estimate outside the operating region: {v}"
             for v in plant.region.violations(as_levels(x0), plant.x)]
    span = float(np.max([hi - lo for lo, hi in plant.region.bounds]))
    unit = plant.states[0].unit
    if R is not None:
        std = float(np.sqrt(np.max(np.diag(R))))
        if std > span:
            notes.append(f"measurement noise standard deviation {std:g} {plant.outputs[0].unit} "
                         f"exceeds the span of the region ({span:g} {unit})")
    if P0 is not None:
        std = float(np.sqrt(np.max(np.diag(P0))))
        if std > span:
            notes.append(f"initial estimate standard deviation {std:g} {unit} exceeds the span of "
                         f"the region ({span:g} {unit})")
    return notes


@dataclass(frozen=True)
class _OperatingPoint:
    """The linearisation at the operating point (equilibrium input) and its observability."""

    lin: LinearModel
    x_op: np.ndarray
    u_op: np.ndarray
    rank: dict

    @property
    def point(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x_op, u_op)``: the point a linear filter's tuning is linearised at."""
        return self.x_op, self.u_op


def _observable_at_operating_point(spec: Spec, what: str, *, continuous: bool = False,
                                   sensors: int = 1) -> _OperatingPoint:
    """Linearise at the operating point and refuse an unobservable pair, naming the modes.

    ``continuous``: check ``(F, C)`` instead of ``(Ad, C)``; ``sensors``: ``C`` repeated for
    that many redundant sensors.
    """
    plant = spec.plant
    eq = equilibrium_at(plant, spec.x0, spec.given_u0)
    lin = linearized_at(plant, spec.x0, eq.u0, ts=spec.ts)
    A = lin.F if continuous else discrete_pair(lin)[0]
    C = lin.C if sensors == 1 else np.vstack([lin.C] * sensors)
    rank = observability_rank(A, C)
    if not rank.full:
        pbh = pbh_test(A, C=C, state_names=[s.name for s in plant.states])
        modes = "; ".join(f"eigenvalue {m.eigenvalue:.4g} in {', '.join(m.states)}"
                          for m in pbh.modes) or "rank deficient"
        raise UnobservableError(f"{what} is not observable (rank {rank.rank} < {rank.n}): "
                                f"unobservable modes: {modes}")
    return _OperatingPoint(lin, spec.x0, eq.u0, rank.as_dict())


def _kalman_tuning(spec: Spec, design: DesignSpec, o: Any, cls: type = KalmanTuning,
                   extra: dict[str, Any] | None = None, operating_point: Any = None) -> Any:
    """The tuning of a Kalman-type filter from its validated options."""
    kwargs = dict(Q=o.Q, R=o.R, P0=o.P0, x0=_x0(spec, o), ts=spec.ts, substeps=o.substeps,
                  clip=o.clip, operating_point=operating_point)
    if cls is KalmanTuning:
        kwargs.update(jacobian_eps=o.jacobian_eps, switch_tol=o.switch_tol)
    kwargs.update(extra or {})
    return keyed_call(design, cls, _OPTION_OF, **kwargs)


def _pairs(values: np.ndarray) -> list[list[float]]:
    """Eigenvalues as ``[re, im]`` pairs, in the eigensolver's order."""
    return [[float(v.real), float(v.imag)] for v in values]


def _model_diag(model: DiscreteModel) -> dict:
    out = model.describe()
    if model.kind == "linear" and model.Ad is not None:
        out["Ad_eigenvalues"] = _pairs(np.linalg.eigvals(model.Ad))
    return out


def _linear_model_gains(model: DiscreteModel) -> dict[str, np.ndarray]:
    """``Ad``, ``Bd``, ``C`` of a linear filter's model (stored as gains)."""
    if model.Ad is None or model.Bd is None or model.C is None:
        raise TypeError(f"a {model.kind} model has no Ad, Bd, C")
    return {"Ad": model.Ad, "Bd": model.Bd, "C": model.C}


class _Outcome(NamedTuple):
    """What a method's build step returns: the gains and the diagnostics (in order) of its
    `DesignResult`."""

    gains: dict[str, np.ndarray]
    diagnostics: dict[str, Any]


def _filter_outcome(spec: Spec, at: _OperatingPoint, tuning: Any, model: DiscreteModel, *,
                    noise: np.ndarray | None = None, gains: dict[str, np.ndarray] | None = None,
                    **extra: Any) -> _Outcome:
    """The outcome of a Kalman-type filter: the tuning's gains (and ``gains``), the common
    diagnostics (model, observability, plausibility, assumptions, sampling period) and then
    ``extra``.

    ``noise``: the measurement noise covariance judged by `plausibility` (default the tuning's
    ``R``).
    """
    plant = spec.plant
    diag = {"model": _model_diag(model), "observability_at_operating_point": at.rank,
            "plausibility": plausibility(plant, tuning.x0, tuning.R if noise is None else noise,
                                         tuning.P0),
            "assumptions": [a.text for a in plant.assumptions],
            "sampling_period": spec.ts, **extra}
    return _Outcome({**tuning.gains(), **(gains or {})}, diag)


# ------------------------------------------------------------------------------ template
#: A method's build step: ``build(spec, design, at, options) -> _Outcome``.
_Build = Callable[[Spec, DesignSpec, _OperatingPoint, Any], _Outcome]
#: What a method is refused on: the description of the pair whose observability is checked
#: (before the options are read), or ``linearisation(spec, options) -> _OperatingPoint`` for a
#: pair that depends on the options (checked after reading them).
_Linearisation = str | Callable[[Spec, Any], _OperatingPoint]

_RUN_DOC = """{summary}

The design function of ``{name}`` (`estimator_method`): the observability of
the linearisation at the operating point, the validated options (`{options}`),
then the method's tuning, filter, gains and diagnostics (`{build}`).

Parameters
----------
spec : Spec
    The validated spec (plant, operating point, sampling).
design : DesignSpec
    This ``[[design]]`` entry (method ``{name}`` and its options).

Returns
-------
DesignResult
    The gains (SI units) and diagnostics of the ``{name}`` design.

Raises
------
UnobservableError
    The linearisation at the operating point is not observable (the modes are named).
SpecError
    Invalid options (validated again when ``design`` was copied with other
    options) or an option the tuning refuses, keyed ``design[i].<option>``.
"""


class _EstimatorDesign:
    """The design function of one estimator method (see `estimator_method`); its docstring is
    the method's (`_RUN_DOC`)."""

    def __init__(self, name: str, options: type[MethodOptions], linearisation: _Linearisation,
                 build: _Build) -> None:
        self.name, self.options = name, options
        self.linearisation, self.build = linearisation, build
        summary = inspect.getdoc(build)
        if not summary:
            raise TypeError(f"the build step of {name!r} has no docstring (the method's summary)")
        self.__doc__ = _RUN_DOC.format(summary=summary, name=name,
                                       options=options.__name__, build=build.__name__)

    def __call__(self, spec: Spec, design: DesignSpec) -> DesignResult:
        if isinstance(self.linearisation, str):   # refused before the options are read
            at = _observable_at_operating_point(spec, self.linearisation)
            o = options_of(design, spec, self.options)
        else:                                       # the checked pair depends on the options
            o = options_of(design, spec, self.options)
            at = self.linearisation(spec, o)
        gains, diagnostics = self.build(spec, design, at, o)
        return DesignResult(design.name, self.name, spec.plant.name, gains, diagnostics)

    def __repr__(self) -> str:
        return f"<design of {self.name!r}: {self.build.__name__}>"


def estimator_method(name: str, options: type[MethodOptions], linearisation: _Linearisation,
                     build: _Build) -> DesignMethod:
    """The `DesignMethod` of an estimator: the family's steps around the method's build step.

    Its design function ``run(spec, design)`` checks the observability of the linearisation at
    the operating point (refusing an unobservable one with `UnobservableError`, the modes
    named), reads the validated options (`options_of`), calls ``build(spec, design, at,
    options)`` and returns the ``(gains, diagnostics)`` it gives as the `DesignResult` of
    ``name``. Its docstring is the build step's, with the parameters of ``run``.

    Parameters
    ----------
    name : str
        The spec's ``method`` value.
    options : type of MethodOptions
        The method's Options class (its ``method_name`` is ``name``).
    linearisation : str or callable
        The description of the pair whose observability is checked before the options are read
        (``"(Ad, C) at the operating point"`` for a filter on the linear model, ``"the
        linearisation at the operating point"`` for one on the nonlinear model), or
        ``linearisation(spec, options)`` returning the checked linearisation when the pair
        depends on the options (checked after reading them).
    build : callable
        ``build(spec, design, at, options) -> (gains, diagnostics)``: the method's tuning,
        filter, gains and diagnostics; ``at`` is the linearisation at the operating point.

    Returns
    -------
    DesignMethod
        ``DesignMethod(name, run, options)``.
    """
    return DesignMethod(name, _EstimatorDesign(name, options, linearisation, build), options)


# ------------------------------------------------------------------------------ methods
def _build_kalman(spec: Spec, design: DesignSpec, at: _OperatingPoint,
                  o: KalmanOptions) -> _Outcome:
    """Kalman filter (CKF) on the ZOH linearisation at the operating point (seed 000)."""
    tuning = _kalman_tuning(spec, design, o, operating_point=at.point)
    model = KalmanFilter(spec.plant, tuning, backend="vm").model
    matrices = _linear_model_gains(model)
    K, P = steady_state_gain(model, tuning.Q, tuning.R)
    Acl = (np.eye(spec.plant.n) - K @ model.C) @ matrices["Ad"]
    return _filter_outcome(
        spec, at, tuning, model, gains={**matrices, "K_ss": K, "P_ss": P},
        time_domain="discrete",   # the model is stored as Ad, Bd (`model_names`)
        steady_state={"error_dynamics_eigenvalues": _pairs(np.linalg.eigvals(Acl)),
                      "source": "scipy.linalg.solve_discrete_are"})


def _build_ekf(spec: Spec, design: DesignSpec, at: _OperatingPoint, o: EkfOptions) -> _Outcome:
    """Extended Kalman filter on the nonlinear model (seed 002 eq. 13-22)."""
    tuning = _kalman_tuning(spec, design, o)
    ekf = ExtendedKalmanFilter(spec.plant, tuning, backend="vm")
    return _filter_outcome(spec, at, tuning, ekf.model, kernel_instructions=ekf.instructions)


def _build_ukf(spec: Spec, design: DesignSpec, at: _OperatingPoint, o: UkfOptions) -> _Outcome:
    """Unscented Kalman filter (seed 002 eq. 23-40)."""
    tuning = _kalman_tuning(spec, design, o, UKFTuning,
                            {"alpha": o.alpha, "beta": o.beta, "kappa": o.kappa, "redraw": o.redraw})
    ukf = UnscentedKalmanFilter(spec.plant, tuning, backend="vm")
    return _filter_outcome(spec, at, tuning, ukf.model, kernel_instructions=ukf.instructions)


def _build_adaptive_kalman(spec: Spec, design: DesignSpec, at: _OperatingPoint,
                           o: AdaptiveKalmanOptions) -> _Outcome:
    """Adaptive-Q Kalman filter (seed 000 eq. 29-37) on the linearisation."""
    tuning = keyed_call(design, AdaptiveKalmanTuning, _OPTION_OF, Q0=o.Q0, R=o.R, P0=o.P0,
                        x0=_x0(spec, o), ts=spec.ts, window=o.window, form=o.form,
                        q_floor=o.q_floor, operating_point=at.point)
    model = AdaptiveKalmanFilter(spec.plant, tuning).model
    return _filter_outcome(
        spec, at, tuning, model, gains=_linear_model_gains(model),
        time_domain="discrete",   # the model is stored as Ad, Bd (`model_names`)
        errata=["seed 000 eq. 35 uses the updated estimate in v_k (a residual); the innovation "
                "y_k - H x_k^+ (prediction) is used, as in Mohamed & Schwarz (1999)"])


def _build_adaptive_scaling_kalman(spec: Spec, design: DesignSpec, at: _OperatingPoint,
                                   o: AdaptiveScalingKalmanOptions) -> _Outcome:
    """Adaptive-scaling Kalman filter (seed 004 eq. 30-41)."""
    a, b, c = o.abc
    tuning = keyed_call(design, AdaptiveScalingTuning, _OPTION_OF, Q=o.Q, R=o.R, P0=o.P0,
                        x0=_x0(spec, o), ts=spec.ts, a=a, b=b, c=c, G=o.G, phi0=o.phi0,
                        operating_point=at.point)
    model = AdaptiveScalingKalmanFilter(spec.plant, tuning).model
    return _filter_outcome(
        spec, at, tuning, model,
        errata=["seed 004 eq. 36 is read as the trace equation v'v = tr(beta) + phi "
                "tr(C G Q G' C') solved for phi (the printed form divides a vector by a "
                "matrix that itself contains phi)"])


def _consensus_linearisation(spec: Spec, o: ConsensusFilterOptions) -> _OperatingPoint:
    """``(Ad, C)`` at the operating point, ``C`` repeated for each redundant sensor."""
    return _observable_at_operating_point(spec, _LINEAR_MODEL, sensors=len(o.R))


def _build_consensus_filter(spec: Spec, design: DesignSpec, at: _OperatingPoint,
                            o: ConsensusFilterOptions) -> _Outcome:
    """Consensus (information-form) filter with N redundant sensors (seed 004 eq. 42-51)."""
    R = tuple(o.R)
    tuning = keyed_call(design, ConsensusTuning, _OPTION_OF, Q=o.Q, R=R, P0=o.P0,
                        x0=_x0(spec, o), ts=spec.ts, operating_point=at.point)
    model = ConsensusFilter(spec.plant, tuning).model
    return _filter_outcome(
        spec, at, tuning, model, noise=R[0], sensors=len(R),
        errata=["seed 004 eq. 50 propagates Pcal = N (P^-1 + sum H_i)^-1; for N > 1 the "
                "central covariance Pcal / N is propagated (identical for N = 1)"])


def _build_narx(spec: Spec, design: DesignSpec, at: _OperatingPoint, o: NarxOptions) -> _Outcome:
    """NARX estimator trained by Levenberg-Marquardt on EKF data (seed 002 section 3.3)."""
    plant = spec.plant
    ekf_tuning = _kalman_tuning(spec, design, o)
    training = keyed_call(
        design, train_narx, _OPTION_OF, plant=plant, ekf_tuning=ekf_tuning, hidden=o.hidden,
        delays=o.delays, runs=o.runs, validation_runs=o.validation_runs, steps=o.steps, seed=o.seed,
        input_range=None if o.input_range is None else np.array(o.input_range), hold=o.hold,
        noise_std=None if o.noise_std is None else np.array(o.noise_std),
        sim_substeps=o.sim_substeps, target=o.target, restarts=o.restarts, max_iter=o.max_iter,
        max_fail=o.max_fail, clip=ekf_tuning.clip, excitation=o.excitation,
        setpoint_range=None if o.setpoint_range is None else np.array(o.setpoint_range),
        prbs_amplitude=o.prbs_amplitude, prbs_hold=o.prbs_hold)
    gains = {**training.tuning.gains(), "ekf_Q": ekf_tuning.Q, "ekf_R": ekf_tuning.R,
             "ekf_P0": ekf_tuning.P0, "training_inputs": training.inputs,
             "training_targets": training.targets}
    # the trained network runs on no model of its own: the diagnostics describe the EKF's
    diag = {"model": _model_diag(discrete_model(plant, sampling_period(spec),
                                                substeps=ekf_tuning.substeps)),
            "observability_at_operating_point": at.rank, **training.diagnostics,
            "plausibility": plausibility(plant, ekf_tuning.x0, ekf_tuning.R, ekf_tuning.P0),
            "sampling_period": spec.ts}
    return _Outcome(gains, diag)


def _luenberger_linearisation(spec: Spec, o: LuenbergerOptions) -> _OperatingPoint:
    """The linearisation at the operating point: ``(F, C)`` for the continuous form, else
    ``(Ad, C)``."""
    return _observable_at_operating_point(spec, _LINEARISATION, continuous=o.form == "continuous")


def _build_luenberger(spec: Spec, design: DesignSpec, at: _OperatingPoint,
                      o: LuenbergerOptions) -> _Outcome:
    """Luenberger observer from a given gain ``L`` or from observer ``poles``.

    Poles are placed (`tanksynth.design.placement.canonical.place_observer`) on the
    linearisation at the operating point: ``eig(F - L C)`` (continuous),
    ``eig(Ad - L C)`` (predictor) or ``eig((I - L C) Ad)`` (current form).
    ``nonlinear = true`` runs the continuous form on the plant's own vector
    field instead of the linearisation.
    """
    plant = spec.plant
    form = o.form
    lin = at.lin
    A_design = lin.F if form == "continuous" else discrete_pair(lin)[0]
    placement = None
    if o.L is not None:
        L = np.array(o.L)
    else:
        placement = keyed_call(design, place_observer, _OPTION_OF, A=A_design, C=lin.C,
                               poles=list(o.poles))
        L = placement.L
        if form == "current":
            L = np.linalg.solve(discrete_pair(lin)[0], L)   # eig((I - L C) Ad) = eig(Ad - (Ad L) C)
    tuning = keyed_call(design, LuenbergerTuning, _OPTION_OF, L=L, x0=_x0(spec, o), ts=spec.ts,
                        form=form, substeps=o.substeps,
                        operating_point=None if o.nonlinear else at.point)
    obs = LuenbergerObserver(plant, tuning)
    diag = {"model": _model_diag(obs.model), "form": form,
            "observability_at_operating_point": at.rank,
            "plausibility": plausibility(plant, tuning.x0),
            "error_dynamics_eigenvalues": None if obs.error_eigenvalues is None else
            _pairs(obs.error_eigenvalues)}
    if placement is not None:
        diag["placement"] = placement.as_dict()
    return _Outcome(tuning.gains(), diag)


# ------------------------------------------------------------------ design methods
KALMAN = estimator_method("kalman", KalmanOptions, _LINEAR_MODEL, _build_kalman)
EKF = estimator_method("ekf", EkfOptions, _LINEARISATION, _build_ekf)
UKF = estimator_method("ukf", UkfOptions, _LINEARISATION, _build_ukf)
ADAPTIVE_KALMAN = estimator_method("adaptive_kalman", AdaptiveKalmanOptions, _LINEAR_MODEL,
                                   _build_adaptive_kalman)
ADAPTIVE_SCALING_KALMAN = estimator_method("adaptive_scaling_kalman", AdaptiveScalingKalmanOptions,
                                           _LINEAR_MODEL, _build_adaptive_scaling_kalman)
CONSENSUS_FILTER = estimator_method("consensus_filter", ConsensusFilterOptions,
                                    _consensus_linearisation, _build_consensus_filter)
NARX = estimator_method("narx", NarxOptions, _LINEARISATION, _build_narx)
LUENBERGER = estimator_method("luenberger", LuenbergerOptions, _luenberger_linearisation,
                              _build_luenberger)
