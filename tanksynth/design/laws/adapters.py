"""Spec design methods for control laws (issue 4).

==========================  ===================================================
``feedback_linearization``  exact feedback linearisation with decoupling (seed
                            000 II-C); gains ``K`` (outer-loop coefficients),
                            ``Lambda_op``, ``Lambda0_op``, ``u_op``, ``x_op``; the law
                            itself serialised in ``diagnostics.law``
``integral_tracking``       linear tracking with integral action, pump
                            saturation and anti-windup (seed 000 II-B); gains
                            ``K``, ``K1``, ``K2``, ``Kaw``, ``C1``, ``x_op``, ``u_op``
``inverse_dynamics``        estimator-based inverse-dynamics law (seed 002 eq.
                            46-47), ``C`` given or tuned by minimum ISE on the
                            servo scenario; gains ``C``, ``x_op``, ``u_op``
==========================  ===================================================

Every law is stored in the artefact's diagnostics as a serialised CasADi
Function (`tanksynth.design.laws.tracking.law_document`); `export_law` writes it as
``.casadi`` plus generated C.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import sympy as sp

from tanksynth.design.laws.tracking import ServoScenario, design_integral_tracking, tune_inverse_dynamics
from tanksynth.design.laws.feedback_linearization import feedback_linearization
from tanksynth.design.operating_point import (discrete_pair, equilibrium_at, linearized_at,
                                              sampling_period)
from tanksynth.design.result import DesignMethod, DesignResult, options_of, rekeyed
from tanksynth.design.placement.canonical import integral_augmentation
from tanksynth.design.placement.exact import robustness_report
from tanksynth.errors import DesignWarning, SpecError
from tanksynth.runtime.laws import inverse_dynamics_law, law_document, rename_law
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options import (FeedbackLinearizationOptions, IntegralTrackingOptions,
                                           InverseDynamicsOptions)

__all__ = ["run_feedback_linearization", "run_integral_tracking", "run_inverse_dynamics",
           "FEEDBACK_LINEARIZATION", "INTEGRAL_TRACKING", "INVERSE_DYNAMICS"]


# ------------------------------------------------------- feedback_linearization
def run_feedback_linearization(spec: Spec, design: DesignSpec) -> DesignResult:
    """Exact feedback linearisation with decoupling (seed 000 II-C).

    Gains: ``K`` (outer-loop coefficients ``c_ik``, m x max theta; for
    relative degree 1 the ``K_i`` of eq. 27, 1/s), ``Lambda_op`` and
    ``Lambda0_op`` (at the operating point), ``u_op`` (the law's input at
    the operating point ``x_op`` with ``y_r = y(x_op)``) and ``x_op``.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    o = options_of(design, spec, FeedbackLinearizationOptions)
    plant = spec.plant
    try:
        fl = feedback_linearization(
            plant, o.tracked, poles=o.poles,
            bandwidth=None if o.bandwidth is None else o.bandwidth.tolist(), saturate=o.saturate,
            allow_unstable_zero_dynamics=o.allow_unstable_zero_dynamics,
            per_axis=o.grid, samples=o.samples, seed=o.seed)
    except SpecError as exc:
        raise rekeyed(design, exc) from None
    dec = fl.decoupling
    vals = plant.parameter_values
    subs = dict(zip(plant.x, (sp.Float(v, 17) for v in spec.x0)))
    num = lambda M: np.array(M.xreplace(vals).xreplace(subs).evalf(17), dtype=float)  # noqa: E731
    Lam = num(dec.Lambda)
    Lam0 = num(dec.Lambda0).reshape(-1)
    alpha = num(dec.alpha).reshape(-1)
    y0 = num(dec.h).reshape(-1)
    u0 = np.asarray(fl.law(spec.x0, y0)[0], dtype=float).reshape(-1)
    eq = equilibrium_at(plant, spec.x0, spec.given_u0)
    diagnostics = dict(fl.diagnostics)
    diagnostics.update({
        "equilibrium": eq.as_dict(),
        "law_input_at_x0_matches_equilibrium": bool(np.allclose(u0, eq.u0, rtol=1e-9,
                                                                atol=1e-12 * max(1.0, np.abs(eq.u0).max()))),
        "law": law_document(rename_law(fl.law, design.name)),
        "law_signature": "u, zeta = law(x, y_r); y_r in output units; u saturated to the input range"
                         if fl.saturated else "u, zeta = law(x, y_r) (unsaturated)",
        "alpha_at_x0": alpha.tolist(),
    })
    gains = {"K": fl.outer.matrix, "Lambda_op": Lam, "Lambda0_op": Lam0, "u_op": u0,
             "x_op": spec.x0}
    return DesignResult(design.name, "feedback_linearization", plant.name, gains, diagnostics,
                        fl.latex())


# ------------------------------------------------------------ integral_tracking
def run_integral_tracking(spec: Spec, design: DesignSpec) -> DesignResult:
    """Linear tracking with integral action, saturation and anti-windup (seed 000 II-B).

    Gains: ``K = [K1 K2]``, ``K1``, ``K2``, ``Kaw`` (back-calculation),
    ``C1``, ``x_op``, ``u_op`` (operating point, equilibrium input), ``input_limits``.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    o = options_of(design, spec, IntegralTrackingOptions)
    plant = spec.plant
    if all(complex(p).imag == 0 and complex(p).real < 0 for p in o.poles):
        warnings.warn(f"every requested discrete pole is real and negative "
                      f"({[complex(p).real for p in o.poles]}): they are placed as z-plane poles (an "
                      "oscillating, near-deadbeat loop), but they look like s-plane poles (1/s); "
                      "z = exp(p ts) is the discrete pole of an s-plane pole p", DesignWarning,
                      stacklevel=2)
    try:
        it = design_integral_tracking(
            plant, spec.x0, list(o.poles), sampling_period(spec), tracked=list(o.tracked),
            method=o.algorithm,
            anti_windup=o.anti_windup, aw_gain=o.aw_gain, given_u0=spec.given_u0)
    except SpecError as exc:
        raise rekeyed(design, exc) from None
    diagnostics = dict(it.diagnostics)
    ts = sampling_period(spec)
    Ad, Bd = discrete_pair(linearized_at(plant, it.x0, it.u0, ts=ts))
    aug = integral_augmentation(Ad, Bd, it.C1, ts)
    rob = robustness_report(aug.A, aug.A - aug.B @ it.K, it.K, "discrete")
    diagnostics["robustness"] = rob
    if rob["fragile"]:
        warnings.warn(f"fragile design: a relative change of A of {rob['relative_stability_radius']:.3g} "
                      "destabilises the augmented closed loop (gain norm "
                      f"{rob['gain_norm']:.3g})", DesignWarning, stacklevel=2)
    if o.reference_gain is not None:
        ref = o.reference_gain
        diff = it.K - ref
        diagnostics["reference_gain"] = {
            "reference": ref.tolist(), "derived": it.K.tolist(), "difference": diff.tolist(),
            "relative_difference": float(np.linalg.norm(diff) / np.linalg.norm(ref)),
            "note": "with several inputs the placing gain is not unique; compare poles, not digits"}
    diagnostics["law"] = law_document(rename_law(it.law, design.name))
    diagnostics["law_signature"] = ("u, z_next = law(x, z, y_r): u = sat(u_op - K1 (x - x_op) - K2 z), "
                                    "z_next = z + ts (y_r - y0 - C1 (x - x_op)) + the anti-windup "
                                    "term, y0 = h(x_op) the tracked outputs at the operating point "
                                    "(diagnostics.y0); x in the state units, y_r in the tracked "
                                    "outputs' units, u in the input units, z the integrator state "
                                    "(starts at 0)")
    gains = {"K": it.K, "K1": it.K1, "K2": it.K2, "Kaw": it.Kaw, "C1": it.C1, "x_op": it.x0,
             "u_op": it.u0, "input_limits": it.input_limits}
    return DesignResult(design.name, "integral_tracking", plant.name, gains, diagnostics, it.latex())


# ------------------------------------------------------------- inverse_dynamics
def run_inverse_dynamics(spec: Spec, design: DesignSpec) -> DesignResult:
    """Inverse-dynamics law (seed 002 eq. 46-47), ``C`` given or tuned by minimum ISE.

    Without ``C`` (or with ``tune = true``) the rates are tuned on the servo
    scenario of seed 002 section 5.1 (set-point step ``step`` at
    ``step_time``, from the operating point, control period ``ts``) by a
    coarse grid and a 1-D refinement of each ``C_i`` over ``bounds``.

    Gains: ``C`` (1/s), ``x_op``, ``u_op`` (the law's input at ``x_op`` with
    the set points at ``x_op``), ``input_limits``.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    o = options_of(design, spec, InverseDynamicsOptions)
    plant = spec.plant
    controlled = None if o.controlled is None else list(o.controlled)
    diagnostics: dict[str, Any] = {}
    try:
        if o.tune:
            base = inverse_dynamics_law(plant, np.ones(plant.m), controlled, saturate=False)
            idx = [[s.name for s in plant.states].index(c) for c in base.controlled]
            scenario = ServoScenario(spec.x0.copy(), spec.x0[idx].copy(), np.array(o.step),
                                     o.step_time, o.horizon, float(sampling_period(spec)),
                                     o.substeps)
            law, tuning = tune_inverse_dynamics(plant, scenario, controlled=base.controlled,
                                                grid=np.array(o.grid),
                                                bounds=(float(o.bounds[0]), float(o.bounds[1])),
                                                saturate=o.saturate, name=design.name)
            diagnostics["tuning"] = tuning.as_dict()
        else:
            law = inverse_dynamics_law(plant, np.array(o.C), controlled, saturate=o.saturate,
                                       name=design.name)
    except SpecError as exc:
        raise rekeyed(design, exc) from None
    idx = [[s.name for s in plant.states].index(c) for c in law.controlled]
    u0 = np.asarray(law.law(spec.x0, spec.x0[idx]), dtype=float).reshape(-1)
    eq = equilibrium_at(plant, spec.x0, spec.given_u0)
    diagnostics.update(law.diagnostics)
    diagnostics.update({
        "equilibrium": eq.as_dict(),
        "law": law_document(rename_law(law.law, design.name)),
        "law_signature": "u = law(x_hat, h_sp): x_hat from any estimator (m), h_sp set points of "
                         f"{list(law.controlled)} (m), u in the input units, saturated",
        "design_simulates": o.tune,
        "assumptions": [a.text for a in plant.assumptions],
    })
    gains = {"C": law.C, "x_op": spec.x0, "u_op": u0, "input_limits": law.input_limits}
    return DesignResult(design.name, "inverse_dynamics", plant.name, gains, diagnostics, law.latex())


# ------------------------------------------------------------------ design methods
FEEDBACK_LINEARIZATION = DesignMethod("feedback_linearization", run_feedback_linearization,
                                      FeedbackLinearizationOptions)
INTEGRAL_TRACKING = DesignMethod("integral_tracking", run_integral_tracking, IntegralTrackingOptions)
INVERSE_DYNAMICS = DesignMethod("inverse_dynamics", run_inverse_dynamics, InverseDynamicsOptions)
