"""Spec design methods of the ``placement`` family: pole placement, exact or in LMI regions.

======================  =========================================================
``lmi_placement``       state feedback ``K`` or observer ``L`` with eigenvalues in
                        an LMI region (half-plane, disk, sector, intersections),
                        continuous or discrete time, optional integral action
``pole_placement``      exact placement (python-control ``place``/``acker``),
                        optional integral action (seed 000 eq. 13-16)
``canonical_observer``  observer gain by the observer canonical form, exact
                        arithmetic (seed 004 eq. 27-29)
======================  =========================================================

Linear designs use the Jacobian linearisation at the spec's operating point
with the equilibrium input computed from the model (the spec's ``u`` is only
checked), ZOH-discretised with ``[sampling] ts`` in discrete time.
"""

from __future__ import annotations

import warnings
from typing import Any, Callable

import numpy as np
import sympy as sp

from tanksynth.analysis.linearize import Equilibrium, LinearModel, symbolic_jacobians
from tanksynth.analysis.lmi_region import region_from_parts
from tanksynth.analysis.statespace import model_names
from tanksynth.design.linear_gains import checked_robustness, reference_comparison
from tanksynth.design.matrices import complex_pairs
from tanksynth.design.operating_point import (discrete_pair, equilibrium_at, linearized_at,
                                              sampling_period, time_domain_of)
from tanksynth.design.placement.canonical import (canonical_observer, integral_augmentation,
                                                  place_observer, place_state_feedback, pole_errors)
from tanksynth.design.placement.exact import placement_accuracy
from tanksynth.design.placement.regions import lmi_observer, lmi_state_feedback
from tanksynth.design.result import DesignMethod, DesignResult, options_of, rekeyed
from tanksynth.errors import DesignWarning, InfeasibleDesign, SpecError
from tanksynth.plants.base import exact
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options import (CanonicalObserverOptions, LmiPlacementOptions,
                                           PolePlacementOptions)

__all__ = [
    "run_lmi_placement",
    "run_pole_placement",
    "run_canonical_observer",
    "LMI_PLACEMENT",
    "POLE_PLACEMENT",
    "CANONICAL_OBSERVER",
]


def _model(spec: Spec, time_domain: str) -> tuple[dict[str, np.ndarray], Equilibrium, LinearModel]:
    """Linear model at the operating point: matrices by name, equilibrium, LinearModel."""
    plant = spec.plant
    eq = equilibrium_at(plant, spec.x0, spec.given_u0)
    lin = linearized_at(plant, spec.x0, eq.u0, ts=spec.ts if time_domain == "discrete" else None)
    A, B = discrete_pair(lin) if time_domain == "discrete" else (lin.F, lin.B)
    return {"A": A, "B": B, "C": lin.C}, eq, lin


def _augment(model: dict[str, np.ndarray], C1: np.ndarray, time_domain: str,
             spec: Spec) -> dict[str, np.ndarray]:
    if time_domain == "discrete":
        aug = integral_augmentation(model["A"], model["B"], C1, sampling_period(spec))
        return {"A": aug.A, "B": aug.B, "Br": aug.Br}
    n, p = model["A"].shape[0], C1.shape[0]
    m = model["B"].shape[1]
    A = np.block([[model["A"], np.zeros((n, p))], [-C1, np.zeros((p, p))]])
    B = np.vstack([model["B"], np.zeros((p, m))])
    Br = np.vstack([np.zeros((n, p)), np.eye(p)])
    return {"A": A, "B": B, "Br": Br}


#: A placement route: ``(A, B or C, state names) -> result`` with its gain as ``K`` or ``L`` (`FeedbackGain`).
_GainRoute = Callable[[np.ndarray, np.ndarray, list[str]], Any]


def _assumptions(spec: Spec) -> list[str]:
    return [a.text for a in spec.plant.assumptions]


def _plane_of_poles(o: PolePlacementOptions, spec: Spec) -> tuple[list[complex], dict | None]:
    """The poles in the design's plane, and a note when they were converted or look mixed up.

    s-plane poles of a discrete design (``poles = {values, domain = "s"}``)
    are placed at ``z = exp(p ts)``. Without a plane, a discrete design whose
    poles are all real and negative warns: they look like s-plane poles
    (1/s) placed as z-plane ones (a near-deadbeat, oscillating gain).
    """
    poles = [complex(p) for p in o.poles]
    plane = getattr(o, "pole_domain", None)
    if o.time_domain == "discrete" and plane == "s":
        ts = sampling_period(spec)
        z = [complex(np.exp(p * ts)) for p in poles]
        return z, {"given": complex_pairs(poles), "domain": "s", "placed": complex_pairs(z),
                   "conversion": f"z = exp(p ts), ts = {ts:g} s"}
    if o.time_domain == "discrete" and plane is None and all(p.imag == 0 and p.real < 0 for p in poles):
        warnings.warn(
            f"every requested discrete pole is real and negative ({[p.real for p in poles]}): they "
            "are placed as z-plane poles (an oscillating, near-deadbeat loop), but they look like "
            "s-plane poles (1/s); if so write poles = {values = [...], domain = \"s\"} "
            "(placed at z = exp(p ts)), else domain = \"z\" to silence this", DesignWarning,
            stacklevel=3)
    return poles, None


def _solve_gain(spec: Spec, design: DesignSpec, o: LmiPlacementOptions | PolePlacementOptions,
                observer: _GainRoute, feedback: _GainRoute, fallback_opt: str, augmented_B: bool
                ) -> tuple[Any, dict[str, np.ndarray], dict[str, Any],
                           tuple[np.ndarray, np.ndarray, np.ndarray], Callable[[np.ndarray], np.ndarray]]:
    """Shared body of `run_lmi_placement` and `run_pole_placement`.

    Builds the model, then calls ``observer(A, C, names)`` or
    ``feedback(A, B, names)`` (on the integral augmentation when the
    ``integral`` option ``o.integral`` is set). A `SpecError` from the solver without this
    design's key is re-raised under ``<design>.<fallback_opt>``.

    Returns ``(res, gains, diagnostics, (A, B, C), closed)`` where
    ``closed(G)`` is the closed-loop matrix a gain ``G`` gives.
    """
    plant = spec.plant
    time_domain = time_domain_of(o)
    model, eq, _ = _model(spec, time_domain)
    names = [s.name for s in plant.states]
    A, B, C = model["A"], model["B"], model["C"]
    diagnostics: dict[str, Any] = {"equilibrium": eq.as_dict(), "time_domain": time_domain,
                                   "ts": spec.ts, "assumptions": _assumptions(spec)}
    closed: Callable[[np.ndarray], np.ndarray]
    try:
        if o.target == "observer":
            res = observer(A, C, names)
            gains = {"L": res.L}
            closed = lambda G: A - G @ C  # noqa: E731
        else:
            if o.integral:
                outputs = [s.name for s in plant.outputs]
                tracked = list(o.tracked or ())
                C1 = C[[outputs.index(t) for t in tracked]]
                aug = _augment(model, C1, time_domain, spec)
                Aa, Ba = aug["A"], aug["B"]
                res = feedback(Aa, Ba, names + [f"z_{t}" for t in tracked])
                K = res.K
                gains = {"K": K, "K1": K[:, :plant.n], "K2": K[:, plant.n:], "Br": aug["Br"]}
                # the tracked outputs at the operating point, h(x0) with offsets and sensor gains:
                # the integrators integrate the measured outputs' error y_r - y_op - C1 (x - x_op)
                y_op = np.asarray(plant.compiled.output(np.asarray(spec.x0, dtype=float)[None]),
                                  dtype=float).reshape(-1)[[outputs.index(t) for t in tracked]]
                diagnostics["integral"] = {"tracked": tracked, "C1": C1.tolist(),
                                           "y_op": y_op.tolist(), "augmented_A": Aa.tolist()}
                if augmented_B:
                    diagnostics["integral"]["augmented_B"] = Ba.tolist()
                closed = lambda G: Aa - Ba @ G  # noqa: E731
            else:
                res = feedback(A, B, names)
                gains = {"K": res.K}
                closed = lambda G: A - B @ G  # noqa: E731
    except SpecError as exc:
        raise rekeyed(design, exc, fallback=fallback_opt) from None
    gains.update({"x_op": np.asarray(spec.x0, dtype=float), "u_op": np.asarray(eq.u0, dtype=float)})
    return res, gains, diagnostics, (A, B, C), closed


def _loop_name(o: LmiPlacementOptions | PolePlacementOptions) -> str:
    if o.target == "observer":
        return "the observer error matrix A - L C"
    return "the augmented closed loop Aa - Ba K" if o.integral else "the closed loop A - B K"


# ----------------------------------------------------------------- lmi_placement
def run_lmi_placement(spec: Spec, design: DesignSpec) -> DesignResult:
    """State feedback ``K`` or observer ``L`` with eigenvalues in an LMI region.

    Gains: ``K`` (state feedback, ``u = -K x``; with integral action also
    ``K1``, ``K2``) or ``L`` (observer), plus ``P`` (Lyapunov matrix of the
    closed loop), the model used (``F``, ``B``, ``C`` in continuous time,
    ``Ad``, ``Bd``, ``C`` in discrete time: `model_names`) and its operating
    point ``x_op``, ``u_op`` (the equilibrium input).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        The ``[[design]]`` entry; its options (``design.config``) were
        validated when the spec was parsed.

    Returns
    -------
    DesignResult

    Raises
    ------
    SpecError
        A value the design itself refuses (the key is named).
    InfeasibleDesign
        No gain passes the solve and the independent re-check.
    UnobservableError, UncontrollableError
        Refused before solving, naming the modes.
    """
    o = options_of(design, spec, LmiPlacementOptions)
    plant = spec.plant
    region = region_from_parts(o.region)
    time_domain, margin, kappa, solver = time_domain_of(o), o.margin, o.kappa, o.solver
    kmax = o.kappa_max
    res, gains, diagnostics, (A, B, C), closed = _solve_gain(
        spec, design, o,
        lambda A, C, names: lmi_observer(A, C, region, domain=time_domain, margin=margin,
                                         kappa=kappa, solver=solver, state_names=names,
                                         kappa_max=kmax),
        lambda A, B, names: lmi_state_feedback(A, B, region, domain=time_domain, margin=margin,
                                               kappa=kappa, solver=solver, state_names=names,
                                               kappa_max=kmax),
        fallback_opt="region", augmented_B=False)
    gain = gains["L"] if "L" in gains else gains["K"]
    open_loop = A if o.target == "observer" or not o.integral else \
        diagnostics["integral"]["augmented_A"]
    diagnostics["robustness"] = checked_robustness(np.asarray(open_loop, dtype=float), closed(gain),
                                                   gain, time_domain, o.allow_fragile, _loop_name(o))
    if res.scaling.get("kappa_relaxed"):
        warnings.warn(f"the conditioning bound was active: kappa relaxed from {kappa:g} to "
                      f"{res.scaling['kappa']:g} (ceiling kappa_max = {kmax:g})", DesignWarning,
                      stacklevel=2)
    names = model_names(time_domain)
    gains.update({"P": res.P, names["A"]: A, names["B"]: B, "C": C})
    diagnostics.update({"lmi": res.as_dict(), "solver": res.solver, "status": res.status})
    return DesignResult(design.name, "lmi_placement", plant.name, gains, diagnostics, {})


# ---------------------------------------------------------------- pole_placement
def run_pole_placement(spec: Spec, design: DesignSpec) -> DesignResult:
    """Exact pole placement (python-control), optionally with integral action.

    Gains: ``K`` (``u = -K x_e``; with integral action ``K1``, ``K2`` and the
    reference input matrix ``Br``) or ``L``, plus the model used (``F, B,
    C`` or ``Ad, Bd, C``: `model_names`) and its operating point ``x_op``,
    ``u_op``. With
    ``reference_gain`` the diagnostics put the paper's gain beside the
    derived one and give the eigenvalues the paper's gain produces on the
    derived model.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        The ``[[design]]`` entry; its options (``design.config``) were
        validated when the spec was parsed.

    Returns
    -------
    DesignResult

    Raises
    ------
    SpecError
        A value the design itself refuses (the key is named).
    InfeasibleDesign
        No gain passes the solve and the independent re-check.
    UnobservableError, UncontrollableError
        Refused before solving, naming the modes.
    """
    o = options_of(design, spec, PolePlacementOptions)
    plant = spec.plant
    method = o.algorithm
    poles, converted = _plane_of_poles(o, spec)
    res, gains, diagnostics, (A, B, C), closed = _solve_gain(
        spec, design, o,
        lambda A, C, names: place_observer(A, C, poles, method, state_names=names),
        lambda A, B, names: place_state_feedback(A, B, poles, method, state_names=names),
        fallback_opt="poles", augmented_B=True)
    gain = res.gain_matrix
    diagnostics["placement"] = res.as_dict()
    if converted is not None:
        diagnostics["poles_converted"] = converted
    open_loop = A if o.target == "observer" or not o.integral else \
        np.asarray(diagnostics["integral"]["augmented_A"], dtype=float)
    diagnostics["robustness"] = checked_robustness(open_loop, closed(gain), gain, time_domain_of(o),
                                                   o.allow_fragile, _loop_name(o))
    if o.reference_gain is not None:
        ref = o.reference_gain
        cmp_ = reference_comparison(ref, gain, closed)
        ach = np.linalg.eigvals(closed(ref))
        cmp_["reference_max_pole_error"] = pole_errors(poles, ach)[1]
        cmp_["note"] = ("with several inputs the gain placing given poles is not unique (place uses "
                        "Tits-Yang); compare the achieved poles, not the digits")
        diagnostics["reference_gain"] = cmp_
    names = model_names(time_domain_of(o))
    gains.update({names["A"]: A, names["B"]: B, "C": C})
    return DesignResult(design.name, "pole_placement", plant.name, gains, diagnostics, {})


# ------------------------------------------------------------ canonical_observer
def run_canonical_observer(spec: Spec, design: DesignSpec) -> DesignResult:
    """Observer gain ``L = Psi`` by the observer canonical form (seed 004).

    The continuous-time Jacobians at the operating point are taken in exact
    arithmetic (parameters as exact rationals), so ``Psi`` comes out exact
    (reported as strings); it is cross-checked against python-control's
    placement. ``reference_gain`` (the printed ``Psi``) and
    ``reference_closed_loop`` (the printed ``Gamma_d``) are compared with the
    derived values.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        The ``[[design]]`` entry; its options (``design.config``) were
        validated when the spec was parsed.

    Returns
    -------
    DesignResult

    Raises
    ------
    SpecError
        A value the design itself refuses (the key is named).
    InfeasibleDesign
        No gain passes the solve and the independent re-check.
    UnobservableError, UncontrollableError
        Refused before solving, naming the modes.
    """
    o = options_of(design, spec, CanonicalObserverOptions)
    plant = spec.plant
    poles = list(o.poles)
    F_sym, _, H_sym = symbolic_jacobians(plant)
    subs = dict(plant.parameter_values)
    subs.update({s: exact(v) for s, v in zip(plant.x, spec.x0)})
    A = sp.Matrix(F_sym.xreplace(subs)).applyfunc(sp.nsimplify)
    C = sp.Matrix(H_sym.xreplace(subs)).applyfunc(sp.nsimplify)
    if A.free_symbols or C.free_symbols:
        raise SpecError("the linearisation depends on the inputs; the canonical-form route needs a "
                        "model affine in u", key=f"{design.key}.method")
    exact_poles = [exact(p.real) + (sp.I * exact(p.imag) if p.imag else 0) for p in poles]
    co = canonical_observer(A, C, exact_poles)
    if not co.exact:
        raise InfeasibleDesign("canonical observer: det(sI - (A - Psi C)) differs from the requested "
                               "polynomial in exact arithmetic")
    L = co.L
    An, Cn = np.array(A.evalf(), dtype=float), np.array(C.evalf(), dtype=float)
    pl = place_observer(An, Cn, poles, state_names=[s.name for s in plant.states])
    ach = np.linalg.eigvals(An - L @ Cn)
    acc = placement_accuracy(poles, An - L @ Cn)
    diagnostics: dict[str, Any] = {
        "time_domain": "continuous",
        "canonical_form": co.as_dict(),
        "achieved_poles": complex_pairs(ach),
        "max_pole_error": pole_errors(poles, ach)[1],
        "accuracy": {"measure": "characteristic polynomial in exact arithmetic (sympy)",
                     "exact": co.exact, "float_gain": acc},
        "robustness": checked_robustness(An, An - L @ Cn, L, "continuous", o.allow_fragile,
                                         "the observer error matrix F - L C"),
        "place_cross_check": {"L_place": pl.L.tolist(),
                              "max_abs_difference": float(np.max(np.abs(pl.L - L))),
                              "place_report": pl.as_dict()},
        "assumptions": _assumptions(spec),
    }
    if o.reference_gain is not None:
        diagnostics["reference_gain"] = reference_comparison(o.reference_gain, L, lambda G: An - G @ Cn)
    if o.reference_closed_loop is not None:
        ref = o.reference_closed_loop
        eig = np.linalg.eigvals(ref)
        derived = np.array(co.Gamma_d.evalf(), dtype=float)
        diagnostics["reference_closed_loop"] = {
            "reference": ref.tolist(), "derived": derived.tolist(),
            "reference_eigenvalues": complex_pairs(eig),
            "reference_max_pole_error": pole_errors(poles, eig)[1],
            "max_abs_difference": float(np.max(np.abs(ref - derived)))}
    latex = {"Psi": sp.latex(co.Psi), "Delta": sp.latex(co.Delta), "Gamma_d": sp.latex(co.Gamma_d)}
    return DesignResult(design.name, "canonical_observer", plant.name,
                        {"L": L, "F": An, "C": Cn}, diagnostics, latex)


# ------------------------------------------------------------------ design methods
LMI_PLACEMENT = DesignMethod("lmi_placement", run_lmi_placement, LmiPlacementOptions)
POLE_PLACEMENT = DesignMethod("pole_placement", run_pole_placement, PolePlacementOptions)
CANONICAL_OBSERVER = DesignMethod("canonical_observer", run_canonical_observer,
                                  CanonicalObserverOptions)
