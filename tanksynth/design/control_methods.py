"""Spec design methods for control laws (issue 4).

==========================  ===================================================
``feedback_linearization``  exact feedback linearisation with decoupling (seed
                            000 II-C); gains ``K`` (outer-loop coefficients),
                            ``Lambda_x0``, ``Lambda0_x0``, ``u0``, ``x0``; the law
                            itself serialised in ``diagnostics.law``
``integral_tracking``       linear tracking with integral action, pump
                            saturation and anti-windup (seed 000 II-B); gains
                            ``K``, ``K1``, ``K2``, ``Kaw``, ``C1``, ``x0``, ``u0``
``inverse_dynamics``        estimator-based inverse-dynamics law (seed 002 eq.
                            46-47), ``C`` given or tuned by minimum ISE on the
                            servo scenario; gains ``C``, ``x0``, ``u0``
==========================  ===================================================

Every law is stored in the artefact's diagnostics as a serialised CasADi
Function (`tanksynth.design.control.law_document`); `export_law` writes it as
``.casadi`` plus generated C.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import sympy as sp

from tanksynth.errors import SpecError
from tanksynth.design.control import ServoScenario, design_integral_tracking, tune_inverse_dynamics
from tanksynth.runtime.laws import inverse_dynamics_law, law_document, rename_law
from tanksynth.design.feedback_linearization import feedback_linearization
from tanksynth.analysis.linearize import equilibrium_input
from tanksynth.design.result import DesignMethod, DesignResult

__all__ = ["run_feedback_linearization", "run_integral_tracking", "run_inverse_dynamics",
           "seed000_law_erratum"]

_NUM = (int, float)


def _key(design, opt: str) -> str:
    return f"{design.key}.{opt}"


def _rekey(design, exc: SpecError) -> SpecError:
    if exc.key and exc.key.startswith(design.key):
        return exc
    return SpecError(exc.detail, key=_key(design, exc.key or "options"))


def _numbers(value: Any, key: str, length: int | None = None) -> np.ndarray:
    items = value if isinstance(value, list) else [value]
    out = []
    for v in items:
        if isinstance(v, bool) or not isinstance(v, _NUM):
            raise SpecError(f"expected numbers, got {v!r}", key=key)
        out.append(float(v))
    arr = np.asarray(out, dtype=float)
    if length is not None and arr.size == 1 and length > 1:
        arr = np.repeat(arr, length)
    if length is not None and arr.size != length:
        raise SpecError(f"expected {length} numbers, got {arr.size}", key=key)
    if not np.all(np.isfinite(arr)):
        raise SpecError("expected finite numbers", key=key)
    return arr


def _poles(value: Any, key: str) -> list[complex]:
    """Numbers, or ``[re, im]`` pairs for complex poles."""
    if not isinstance(value, list) or not value:
        raise SpecError("expected a list of poles (numbers or [re, im] pairs)", key=key)
    out = []
    for v in value:
        if isinstance(v, list) and len(v) == 2 and all(isinstance(c, _NUM) and not isinstance(c, bool)
                                                       for c in v):
            out.append(complex(float(v[0]), float(v[1])))
        elif isinstance(v, _NUM) and not isinstance(v, bool):
            out.append(complex(float(v)))
        else:
            raise SpecError(f"expected a number or [re, im], got {v!r}", key=key)
    return out


def _names(value: Any, key: str) -> list[str] | None:
    if value is None:
        return None
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise SpecError("expected a list of names", key=key)
    return list(value)


def seed000_law_erratum(plant, x0: np.ndarray, alpha_x0: np.ndarray) -> dict:
    """Seed 000 section IV prints ``u = (1/A) [-q13; q32 - q20] + A zeta``.

    Derived (eq. 24): ``alpha = -Lambda^-1 Lambda_0 = [q13; q20 - q32]`` (input
    units m^3/s); the printed ``alpha`` is ``Lambda_0`` itself (factor ``1/A``
    instead of ``A`` and the opposite sign). ``beta = diag(A, A)`` agrees.
    """
    vals = {p.name: p.value for p in plant.parameters}
    A = vals["A"]
    printed = -alpha_x0 / A
    return {"item": "seed 000 section IV, nonlinear control input u(t)",
            "printed": "u = (1/A) [-q13; q32 - q20] + [[A, 0], [0, A]] zeta",
            "derived": "u = [q13; q20 - q32] + [[A, 0], [0, A]] zeta  (alpha = -Lambda^-1 Lambda_0)",
            "printed_alpha_at_x0": printed.tolist(), "derived_alpha_at_x0": alpha_x0.tolist(),
            "x0": x0.tolist(),
            "note": "the printed alpha equals Lambda_0 (1/A instead of A, opposite sign); the "
                    "printed Lambda, Lambda_0 and beta agree with the derivation"}


# ------------------------------------------------------- feedback_linearization
def run_feedback_linearization(spec, design) -> DesignResult:
    """Exact feedback linearisation with decoupling (seed 000 II-C).

    Gains: ``K`` (outer-loop coefficients ``c_ik``, m x max theta; for
    relative degree 1 the ``K_i`` of eq. 27, 1/s), ``Lambda_x0`` and
    ``Lambda0_x0`` (at the operating point), ``u0`` (the law's input at
    ``x0`` with ``y_r = y(x0)``) and ``x0``.
    """
    o = design.options
    plant = spec.plant
    poles = _poles(o["poles"], _key(design, "poles")) if "poles" in o else None
    bandwidth = None
    if "bandwidth" in o:
        bandwidth = _numbers(o["bandwidth"], _key(design, "bandwidth")).tolist()
    try:
        fl = feedback_linearization(
            plant, _names(o.get("tracked"), _key(design, "tracked")), poles=poles,
            bandwidth=bandwidth, saturate=bool(o.get("saturate", True)),
            allow_unstable_zero_dynamics=bool(o.get("allow_unstable_zero_dynamics", False)),
            per_axis=int(o.get("grid", 11)), samples=int(o.get("samples", 400)),
            seed=int(o.get("seed", 0)))
    except SpecError as exc:
        raise _rekey(design, exc) from None
    dec = fl.decoupling
    vals = plant.parameter_values
    subs = dict(zip(plant.x, (sp.Float(v, 17) for v in spec.x0)))
    num = lambda M: np.array(M.xreplace(vals).xreplace(subs).evalf(17), dtype=float)  # noqa: E731
    Lam = num(dec.Lambda)
    Lam0 = num(dec.Lambda0).reshape(-1)
    alpha = num(dec.alpha).reshape(-1)
    y0 = num(dec.h).reshape(-1)
    u0 = np.asarray(fl.law(spec.x0, y0)[0], dtype=float).reshape(-1)
    eq = equilibrium_input(plant, spec.x0, spec.given_u0)
    diagnostics = dict(fl.diagnostics)
    diagnostics.update({
        "equilibrium": eq.as_dict(),
        "law_input_at_x0_matches_equilibrium": bool(np.allclose(u0, eq.u0, rtol=1e-9,
                                                                atol=1e-12 * max(1.0, np.abs(eq.u0).max()))),
        "law": law_document(rename_law(fl.law, design.name)),
        "law_signature": "u, zeta = law(x, y_r); y_r in output units; u saturated to the input range"
                         if fl.saturated else "u, zeta = law(x, y_r) (unsaturated)",
    })
    if plant.name == "three_tank" and tuple(dec.outputs) == ("h1", "h2"):
        diagnostics["errata"] = [seed000_law_erratum(plant, spec.x0, alpha)]
    gains = {"K": fl.outer.matrix, "Lambda_x0": Lam, "Lambda0_x0": Lam0, "u0": u0, "x0": spec.x0}
    return DesignResult(design.name, "feedback_linearization", plant.name, gains, diagnostics,
                        fl.latex())


# ------------------------------------------------------------ integral_tracking
def run_integral_tracking(spec, design) -> DesignResult:
    """Linear tracking with integral action, saturation and anti-windup (seed 000 II-B).

    Gains: ``K = [K1 K2]``, ``K1``, ``K2``, ``Kaw`` (back-calculation),
    ``C1``, ``x0``, ``u0`` (equilibrium input), ``input_limits``.
    """
    o = design.options
    plant = spec.plant
    try:
        it = design_integral_tracking(
            plant, spec.x0, _poles(o.get("poles"), _key(design, "poles")), spec.ts,
            tracked=_names(o.get("tracked"), _key(design, "tracked")),
            method=o.get("method", "auto"), anti_windup=o.get("anti_windup", "back_calculation"),
            aw_gain=float(o.get("aw_gain", 1.0)), given_u0=spec.given_u0)
    except SpecError as exc:
        raise _rekey(design, exc) from None
    diagnostics = dict(it.diagnostics)
    if "reference_gain" in o:
        ref = np.asarray(o["reference_gain"], dtype=float)
        if ref.shape != it.K.shape:
            raise SpecError(f"expected a {it.K.shape[0]} x {it.K.shape[1]} matrix, got shape "
                            f"{ref.shape}", key=_key(design, "reference_gain"))
        diff = it.K - ref
        diagnostics["reference_gain"] = {
            "reference": ref.tolist(), "derived": it.K.tolist(), "difference": diff.tolist(),
            "relative_difference": float(np.linalg.norm(diff) / np.linalg.norm(ref)),
            "note": "with several inputs the placing gain is not unique; compare poles, not digits"}
    diagnostics["law"] = law_document(rename_law(it.law, design.name))
    diagnostics["law_signature"] = ("u, z_next = law(x, z, y_r): levels and references in m, u in "
                                    "the input units, z the integrator state (starts at 0)")
    gains = {"K": it.K, "K1": it.K1, "K2": it.K2, "Kaw": it.Kaw, "C1": it.C1, "x0": it.x0,
             "u0": it.u0, "input_limits": it.input_limits}
    return DesignResult(design.name, "integral_tracking", plant.name, gains, diagnostics, it.latex())


# ------------------------------------------------------------- inverse_dynamics
def run_inverse_dynamics(spec, design) -> DesignResult:
    """Inverse-dynamics law (seed 002 eq. 46-47), ``C`` given or tuned by minimum ISE.

    Without ``C`` (or with ``tune = true``) the rates are tuned on the servo
    scenario of seed 002 section 5.1 (set-point step ``step`` at
    ``step_time``, from the operating point, control period ``ts``) by a
    coarse grid and a 1-D refinement of each ``C_i`` over ``bounds``.

    Gains: ``C`` (1/s), ``x0``, ``u0`` (the law's input at ``x0`` with the
    set points at ``x0``), ``input_limits``.
    """
    o = design.options
    plant = spec.plant
    controlled = _names(o.get("controlled"), _key(design, "controlled"))
    tune = bool(o.get("tune", "C" not in o))
    diagnostics: dict[str, Any] = {}
    try:
        if tune:
            if "C" in o:
                raise SpecError("give either C (fixed rates) or tune = true, not both",
                                key=_key(design, "C"))
            base = inverse_dynamics_law(plant, np.ones(plant.m), controlled, saturate=False)
            idx = [[s.name for s in plant.states].index(c) for c in base.controlled]
            bounds = _numbers(o.get("bounds", [0.0, 1.0]), _key(design, "bounds"), 2)
            grid = _numbers(o.get("grid", np.round(np.linspace(0.1, 1.0, 10), 10).tolist()),
                            _key(design, "grid"))
            scenario = ServoScenario(
                spec.x0.copy(), spec.x0[idx].copy(),
                _numbers(o.get("step", 0.04), _key(design, "step"), plant.m),
                float(o.get("step_time", 100.0)), float(o.get("horizon", 300.0)), float(spec.ts),
                int(o.get("substeps", 10)))
            if not 0 <= scenario.step_time < scenario.horizon or scenario.substeps < 1:
                raise SpecError("need 0 <= step_time < horizon and substeps >= 1",
                                key=_key(design, "step_time"))
            law, tuning = tune_inverse_dynamics(plant, scenario, controlled=base.controlled,
                                                grid=grid, bounds=(bounds[0], bounds[1]),
                                                saturate=bool(o.get("saturate", True)),
                                                name=design.name)
            diagnostics["tuning"] = tuning.as_dict()
        else:
            C = _numbers(o["C"], _key(design, "C"), plant.m)
            law = inverse_dynamics_law(plant, C, controlled, saturate=bool(o.get("saturate", True)),
                                       name=design.name)
    except SpecError as exc:
        raise _rekey(design, exc) from None
    idx = [[s.name for s in plant.states].index(c) for c in law.controlled]
    u0 = np.asarray(law.law(spec.x0, spec.x0[idx]), dtype=float).reshape(-1)
    eq = equilibrium_input(plant, spec.x0, spec.given_u0)
    diagnostics.update(law.diagnostics)
    diagnostics.update({
        "equilibrium": eq.as_dict(),
        "law": law_document(rename_law(law.law, design.name)),
        "law_signature": "u = law(x_hat, h_sp): x_hat from any estimator (m), h_sp set points of "
                         f"{list(law.controlled)} (m), u in the input units, saturated",
        "design_simulates": tune,
        "assumptions": [a.text for a in plant.assumptions],
    })
    gains = {"C": law.C, "x0": spec.x0, "u0": u0, "input_limits": law.input_limits}
    return DesignResult(design.name, "inverse_dynamics", plant.name, gains, diagnostics, law.latex())


# -------------------------------------------------------------------- registry
FEEDBACK_LINEARIZATION = DesignMethod("feedback_linearization", run_feedback_linearization, options={
    "tracked": (list, None), "poles": (list, None), "bandwidth": ((int, float, list), None),
    "saturate": (bool, True), "allow_unstable_zero_dynamics": (bool, False),
    "grid": (int, 11), "samples": (int, 400), "seed": (int, 0)})

INTEGRAL_TRACKING = DesignMethod("integral_tracking", run_integral_tracking, options={
    "poles": (list, None), "tracked": (list, None), "method": (str, "auto"),
    "anti_windup": (str, "back_calculation"), "aw_gain": (_NUM, 1.0),
    "reference_gain": (list, None)}, required=("poles",), needs_sampling=True)

INVERSE_DYNAMICS = DesignMethod("inverse_dynamics", run_inverse_dynamics, options={
    "controlled": (list, None), "C": ((int, float, list), None), "tune": (bool, None),
    "step": ((int, float, list), 0.04), "step_time": (_NUM, 100.0), "horizon": (_NUM, 300.0),
    "substeps": (int, 10), "grid": (list, None), "bounds": (list, [0.0, 1.0]),
    "saturate": (bool, True)}, needs_sampling=True)
