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
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.design.estimators.narx_training import train_narx
from tanksynth.design.result import DesignMethod, DesignResult, options_of, rekeyed
from tanksynth.errors import SpecError, UnobservableError
from tanksynth.runtime.estimators.adaptive import (AdaptiveKalmanFilter, AdaptiveKalmanTuning,
                                                   AdaptiveScalingKalmanFilter, AdaptiveScalingTuning)
from tanksynth.runtime.estimators.base import DiscreteModel, discrete_model
from tanksynth.runtime.estimators.consensus import ConsensusFilter, ConsensusTuning
from tanksynth.runtime.estimators.kalman import (ExtendedKalmanFilter, KalmanFilter, KalmanTuning,
                                                 steady_state_gain)
from tanksynth.runtime.estimators.luenberger import LuenbergerObserver, LuenbergerTuning
from tanksynth.runtime.estimators.ukf import UKFTuning, UnscentedKalmanFilter
from tanksynth.spec.method_options import (AdaptiveKalmanOptions, AdaptiveScalingKalmanOptions,
                                           ConsensusFilterOptions, EkfOptions, KalmanOptions,
                                           LuenbergerOptions, NarxOptions, UkfOptions)

__all__ = [
    "run_kalman", "run_ekf", "run_ukf", "run_adaptive_kalman", "run_adaptive_scaling_kalman",
    "run_consensus_filter", "run_narx", "run_luenberger", "plausibility",
]

#: Option named in a `SpecError` a tuning or design step raises, by the key it uses.
_OPTION_OF = {"a": "abc", "b": "abc", "c": "abc", "gain": "poles", "input_schedule": "input"}


def _tuning(design: Any, cls: Any, **kwargs: Any) -> Any:
    """Build a tuning (or run a design step), re-keying its errors to the spec option."""
    try:
        return cls(**kwargs)
    except SpecError as exc:
        if exc.key and not exc.key.startswith("design["):
            raise rekeyed(design, exc, _OPTION_OF.get(exc.key, exc.key)) from None
        raise


def _x0(spec: Any, o: Any) -> np.ndarray:
    """The initial estimate: the option, else the operating point (state units)."""
    return np.array(spec.x0 if o.x0 is None else o.x0, dtype=float)


# ------------------------------------------------------------------------------ checks
def plausibility(plant: Any, x0: np.ndarray, R: np.ndarray | None = None,
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
             for v in plant.region.violations(x0, plant.x)]
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


def _linear_at_op(spec: Any) -> tuple[Any, np.ndarray, np.ndarray]:
    eq = equilibrium_input(spec.plant, spec.x0, spec.given_u0)
    lin = linearize(spec.plant, spec.x0, eq.u0, ts=spec.ts)
    return lin, spec.x0, eq.u0


def _require_observable(plant: Any, A: np.ndarray, C: np.ndarray, what: str) -> dict:
    from tanksynth.analysis.rank import observability_rank, pbh_test

    rank = observability_rank(A, C)
    if not rank.full:
        pbh = pbh_test(A, C=C, state_names=[s.name for s in plant.states])
        modes = "; ".join(f"eigenvalue {m.eigenvalue:.4g} in {', '.join(m.states)}"
                          for m in pbh.modes) or "rank deficient"
        raise UnobservableError(f"{what} is not observable (rank {rank.rank} < {rank.n}): "
                                f"unobservable modes: {modes}")
    return rank.as_dict()


def _kalman_tuning(spec: Any, design: Any, o: KalmanOptions | UkfOptions, cls: type = KalmanTuning,
                   extra: dict[str, Any] | None = None, operating_point: Any = None) -> Any:
    """The tuning of a Kalman-type filter from its validated options."""
    kwargs = dict(Q=o.Q, R=o.R, P0=o.P0, x0=_x0(spec, o), ts=spec.ts, substeps=o.substeps,
                  clip=o.clip, operating_point=operating_point)
    if cls is KalmanTuning:
        kwargs.update(jacobian_eps=o.jacobian_eps, switch_tol=o.switch_tol)
    kwargs.update(extra or {})
    return _tuning(design, cls, **kwargs)


def _model_diag(model: DiscreteModel) -> dict:
    out = model.describe()
    if model.kind == "linear":
        out["Ad_eigenvalues"] = [[float(v.real), float(v.imag)]
                                 for v in np.linalg.eigvals(model.Ad)]
    return out


def _common_diag(spec: Any, tuning: Any, R: Any, P0: Any, rank: dict, model: DiscreteModel) -> dict:
    return {"model": _model_diag(model), "observability_at_operating_point": rank,
            "plausibility": plausibility(spec.plant, tuning.x0, R, P0),
            "assumptions": [a.text for a in spec.plant.assumptions],
            "sampling_period": spec.ts}


# ------------------------------------------------------------------------------ methods
def run_kalman(spec: Any, design: Any) -> DesignResult:
    """Kalman filter (CKF) on the ZOH linearisation at the operating point (seed 000).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    lin, x_op, u_op = _linear_at_op(spec)
    rank = _require_observable(spec.plant, lin.Ad, lin.C, "(Ad, C) at the operating point")
    tuning = _kalman_tuning(spec, design, options_of(design, spec, KalmanOptions),
                            operating_point=(x_op, u_op))
    kf = KalmanFilter(spec.plant, tuning, backend="vm")
    K, P = steady_state_gain(kf.model, tuning.Q, tuning.R)
    Acl = (np.eye(spec.plant.n) - K @ kf.model.C) @ kf.model.Ad
    gains = {**tuning.gains(), "Ad": kf.model.Ad, "Bd": kf.model.Bd, "C": kf.model.C,
             "K_ss": K, "P_ss": P}
    diag = _common_diag(spec, tuning, tuning.R, tuning.P0, rank, kf.model)
    diag["time_domain"] = "discrete"   # the model is stored as Ad, Bd (`model_names`)
    diag["steady_state"] = {"error_dynamics_eigenvalues": [[float(v.real), float(v.imag)]
                                                           for v in np.linalg.eigvals(Acl)],
                            "source": "scipy.linalg.solve_discrete_are"}
    return DesignResult(design.name, "kalman", spec.plant.name, gains, diag)


def run_ekf(spec: Any, design: Any) -> DesignResult:
    """Extended Kalman filter on the nonlinear model (seed 002 eq. 13-22).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    lin, _, _ = _linear_at_op(spec)
    rank = _require_observable(spec.plant, lin.Ad, lin.C, "the linearisation at the operating point")
    tuning = _kalman_tuning(spec, design, options_of(design, spec, EkfOptions))
    ekf = ExtendedKalmanFilter(spec.plant, tuning, backend="vm")
    diag = _common_diag(spec, tuning, tuning.R, tuning.P0, rank, ekf.model)
    diag["kernel_instructions"] = ekf.instructions
    return DesignResult(design.name, "ekf", spec.plant.name, tuning.gains(), diag)


def run_ukf(spec: Any, design: Any) -> DesignResult:
    """Unscented Kalman filter (seed 002 eq. 23-40).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    lin, _, _ = _linear_at_op(spec)
    rank = _require_observable(spec.plant, lin.Ad, lin.C, "the linearisation at the operating point")
    o = options_of(design, spec, UkfOptions)
    tuning = _kalman_tuning(spec, design, o, UKFTuning,
                            {"alpha": o.alpha, "beta": o.beta, "kappa": o.kappa, "redraw": o.redraw})
    ukf = UnscentedKalmanFilter(spec.plant, tuning, backend="vm")
    diag = _common_diag(spec, tuning, tuning.R, tuning.P0, rank, ukf.model)
    diag["kernel_instructions"] = ukf.instructions
    return DesignResult(design.name, "ukf", spec.plant.name, tuning.gains(), diag)


def run_adaptive_kalman(spec: Any, design: Any) -> DesignResult:
    """Adaptive-Q Kalman filter (seed 000 eq. 29-37) on the linearisation.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    plant = spec.plant
    lin, x_op, u_op = _linear_at_op(spec)
    rank = _require_observable(plant, lin.Ad, lin.C, "(Ad, C) at the operating point")
    o = options_of(design, spec, AdaptiveKalmanOptions)
    tuning = _tuning(design, AdaptiveKalmanTuning, Q0=o.Q0, R=o.R, P0=o.P0, x0=_x0(spec, o),
                     ts=spec.ts, window=o.window, form=o.form, q_floor=o.q_floor,
                     operating_point=(x_op, u_op))
    akf = AdaptiveKalmanFilter(plant, tuning)
    diag = _common_diag(spec, tuning, tuning.R, tuning.P0, rank, akf.model)
    diag["time_domain"] = "discrete"   # the model is stored as Ad, Bd (`model_names`)
    diag["errata"] = ["seed 000 eq. 35 uses the updated estimate in v_k (a residual); the innovation "
                      "y_k - H x_k^+ (prediction) is used, as in Mohamed & Schwarz (1999)"]
    return DesignResult(design.name, "adaptive_kalman", plant.name,
                        {**tuning.gains(), "Ad": akf.model.Ad, "Bd": akf.model.Bd,
                         "C": akf.model.C}, diag)


def run_adaptive_scaling_kalman(spec: Any, design: Any) -> DesignResult:
    """Adaptive-scaling Kalman filter (seed 004 eq. 30-41).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    plant = spec.plant
    lin, x_op, u_op = _linear_at_op(spec)
    rank = _require_observable(plant, lin.Ad, lin.C, "(Ad, C) at the operating point")
    o = options_of(design, spec, AdaptiveScalingKalmanOptions)
    a, b, c = o.abc
    tuning = _tuning(design, AdaptiveScalingTuning, Q=o.Q, R=o.R, P0=o.P0, x0=_x0(spec, o),
                     ts=spec.ts, a=a, b=b, c=c, G=o.G, phi0=o.phi0, operating_point=(x_op, u_op))
    filt = AdaptiveScalingKalmanFilter(plant, tuning)
    diag = _common_diag(spec, tuning, tuning.R, tuning.P0, rank, filt.model)
    diag["errata"] = ["seed 004 eq. 36 is read as the trace equation v'v = tr(beta) + phi "
                      "tr(C G Q G' C') solved for phi (the printed form divides a vector by a "
                      "matrix that itself contains phi)"]
    return DesignResult(design.name, "adaptive_scaling_kalman", plant.name, tuning.gains(), diag)


def run_consensus_filter(spec: Any, design: Any) -> DesignResult:
    """Consensus (information-form) filter with N redundant sensors (seed 004 eq. 42-51).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    plant = spec.plant
    lin, x_op, u_op = _linear_at_op(spec)
    o = options_of(design, spec, ConsensusFilterOptions)
    R = list(o.R)
    C_stack = np.vstack([lin.C] * len(R))
    rank = _require_observable(plant, lin.Ad, C_stack, "(Ad, C) at the operating point")
    tuning = _tuning(design, ConsensusTuning, Q=o.Q, R=tuple(R), P0=o.P0, x0=_x0(spec, o),
                     ts=spec.ts, operating_point=(x_op, u_op))
    filt = ConsensusFilter(plant, tuning)
    diag = _common_diag(spec, tuning, R[0], tuning.P0, rank, filt.model)
    diag["sensors"] = len(R)
    diag["errata"] = ["seed 004 eq. 50 propagates Pcal = N (P^-1 + sum H_i)^-1; for N > 1 the "
                      "central covariance Pcal / N is propagated (identical for N = 1)"]
    return DesignResult(design.name, "consensus_filter", plant.name, tuning.gains(), diag)


def run_narx(spec: Any, design: Any) -> DesignResult:
    """NARX estimator trained by Levenberg-Marquardt on EKF data (seed 002 section 3.3).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    plant = spec.plant
    lin, _, _ = _linear_at_op(spec)
    rank = _require_observable(plant, lin.Ad, lin.C, "the linearisation at the operating point")
    o = options_of(design, spec, NarxOptions)
    ekf_tuning = _kalman_tuning(spec, design, o)
    training = _tuning(
        design, train_narx, plant=plant, ekf_tuning=ekf_tuning, hidden=o.hidden, delays=o.delays,
        runs=o.runs, validation_runs=o.validation_runs, steps=o.steps, seed=o.seed,
        input_range=None if o.input_range is None else np.array(o.input_range), hold=o.hold,
        noise_std=None if o.noise_std is None else np.array(o.noise_std),
        sim_substeps=o.sim_substeps, target=o.target, restarts=o.restarts, max_iter=o.max_iter,
        max_fail=o.max_fail, clip=ekf_tuning.clip)
    gains = {**training.tuning.gains(), "ekf_Q": ekf_tuning.Q, "ekf_R": ekf_tuning.R,
             "ekf_P0": ekf_tuning.P0, "training_inputs": training.inputs,
             "training_targets": training.targets}
    diag = {"model": _model_diag(discrete_model(plant, spec.ts, substeps=ekf_tuning.substeps)),
            "observability_at_operating_point": rank, **training.diagnostics,
            "plausibility": plausibility(plant, ekf_tuning.x0, ekf_tuning.R, ekf_tuning.P0),
            "sampling_period": spec.ts}
    return DesignResult(design.name, "narx", plant.name, gains, diag)


def run_luenberger(spec: Any, design: Any) -> DesignResult:
    """Luenberger observer from a given gain ``L`` or from observer ``poles``.

    Poles are placed (`tanksynth.design.placement.canonical.place_observer`) on the
    linearisation at the operating point: ``eig(F - L C)`` (continuous),
    ``eig(Ad - L C)`` (predictor) or ``eig((I - L C) Ad)`` (current form).
    ``nonlinear = true`` runs the continuous form on the plant's own vector
    field instead of the linearisation.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    from tanksynth.design.placement.canonical import place_observer

    o = options_of(design, spec, LuenbergerOptions)
    plant = spec.plant
    form = o.form
    lin, x_op, u_op = _linear_at_op(spec)
    A_design = lin.F if form == "continuous" else lin.Ad
    rank = _require_observable(plant, A_design, lin.C, "the linearisation at the operating point")
    placement = None
    if o.L is not None:
        L = np.array(o.L)
    else:
        placement = _tuning(design, place_observer, A=A_design, C=lin.C, poles=list(o.poles))
        L = placement.gain
        if form == "current":
            L = np.linalg.solve(lin.Ad, L)            # eig((I - L C) Ad) = eig(Ad - (Ad L) C)
    tuning = _tuning(design, LuenbergerTuning, L=L, x0=_x0(spec, o), ts=spec.ts, form=form,
                     substeps=o.substeps, operating_point=None if o.nonlinear else (x_op, u_op))
    obs = LuenbergerObserver(plant, tuning)
    diag = {"model": _model_diag(obs.model), "form": form,
            "observability_at_operating_point": rank,
            "plausibility": plausibility(plant, tuning.x0),
            "error_dynamics_eigenvalues": None if obs.error_eigenvalues is None else
            [[float(v.real), float(v.imag)] for v in obs.error_eigenvalues]}
    if placement is not None:
        diag["placement"] = placement.as_dict()
    return DesignResult(design.name, "luenberger", plant.name, tuning.gains(), diag)


# ------------------------------------------------------------------ design methods
KALMAN = DesignMethod("kalman", run_kalman, KalmanOptions)
EKF = DesignMethod("ekf", run_ekf, EkfOptions)
UKF = DesignMethod("ukf", run_ukf, UkfOptions)
ADAPTIVE_KALMAN = DesignMethod("adaptive_kalman", run_adaptive_kalman, AdaptiveKalmanOptions)
ADAPTIVE_SCALING_KALMAN = DesignMethod("adaptive_scaling_kalman", run_adaptive_scaling_kalman,
                                       AdaptiveScalingKalmanOptions)
CONSENSUS_FILTER = DesignMethod("consensus_filter", run_consensus_filter, ConsensusFilterOptions)
NARX = DesignMethod("narx", run_narx, NarxOptions)
LUENBERGER = DesignMethod("luenberger", run_luenberger, LuenbergerOptions)
