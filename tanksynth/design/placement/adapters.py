"""Spec design methods for convex synthesis and pole placement.

======================  =========================================================
``ts_observer``         TS multiple model of the plant (seed 001) + observer LMI
                        (28); gains ``L``, ``P``, ``Q`` (and ``A0``, ``B0``, ``C``)
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
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp

from tanksynth.analysis.linearize import equilibrium_input, linearize, symbolic_jacobians
from tanksynth.analysis.lmi_region import region_from_parts
from tanksynth.analysis.statespace import model_names
from tanksynth.analysis.takagi_sugeno import (check_exactness, domain_from_plant, quasi_lpv,
                                              ts_model, vertex_observability)
from tanksynth.design.placement.canonical import (canonical_observer, integral_augmentation,
                                        place_observer, place_state_feedback, pole_errors)
from tanksynth.design.placement.exact import placement_accuracy, refuse_fragile, robustness_report
from tanksynth.design.result import DesignMethod, DesignResult, options_of, rekeyed
from tanksynth.design.observer_lmi.weighting import lipschitz_bound, search_weightings, selection_rules
from tanksynth.errors import DesignWarning, InfeasibleDesign, SpecError, UnobservableError
from tanksynth.plants.base import exact
from tanksynth.spec.method_options import (CanonicalObserverOptions, LmiPlacementOptions,
                                           PolePlacementOptions, TsObserverOptions)

if TYPE_CHECKING:  # pragma: no cover - typing only
    from tanksynth.spec import DesignSpec, Spec

__all__ = [
    "run_ts_observer",
    "run_lmi_placement",
    "run_pole_placement",
    "run_canonical_observer",
]


def _complex_list(values: Any) -> list[list[float]]:
    return [[float(v.real), float(v.imag)] for v in np.sort_complex(np.asarray(values, dtype=complex))]


def _model(spec, time_domain: str) -> tuple[dict, Any, Any]:
    """Linear model at the operating point: matrices by name, equilibrium, LinearModel."""
    plant = spec.plant
    eq = equilibrium_input(plant, spec.x0, spec.given_u0)
    lin = linearize(plant, spec.x0, eq.u0, ts=spec.ts if time_domain == "discrete" else None)
    A, B = (lin.Ad, lin.Bd) if time_domain == "discrete" else (lin.F, lin.B)
    return {"A": A, "B": B, "C": lin.C}, eq, lin


def _augment(model: dict, C1: np.ndarray, time_domain: str, ts: float | None) -> dict:
    if time_domain == "discrete":
        aug = integral_augmentation(model["A"], model["B"], C1, ts)
        return {"A": aug.A, "B": aug.B, "Br": aug.Br}
    n, p = model["A"].shape[0], C1.shape[0]
    m = model["B"].shape[1]
    A = np.block([[model["A"], np.zeros((n, p))], [-C1, np.zeros((p, p))]])
    B = np.vstack([model["B"], np.zeros((p, m))])
    Br = np.vstack([np.zeros((n, p)), np.eye(p)])
    return {"A": A, "B": B, "Br": Br}


def _compare(reference: np.ndarray, derived: np.ndarray, closed_loop_of) -> dict:
    diff = derived - reference
    out = {"reference": reference.tolist(), "derived": derived.tolist(),
           "difference": diff.tolist(), "max_abs_difference": float(np.max(np.abs(diff))),
           "relative_difference": float(np.linalg.norm(diff) / max(np.linalg.norm(reference), 1e-300))}
    if closed_loop_of is not None:
        eig = np.linalg.eigvals(closed_loop_of(reference))
        out["reference_closed_loop_eigenvalues"] = _complex_list(eig)
    return out


def _assumptions(spec) -> list[str]:
    return [a.text for a in spec.plant.assumptions]


def _robust(A: np.ndarray, closed: np.ndarray, gain: np.ndarray, domain: str, allow: bool,
            what: str) -> dict:
    """Robustness figures of a loop; refuse a fragile one unless ``allow_fragile``."""
    rob = robustness_report(A, closed, gain, domain)
    if rob["fragile"]:
        if not allow:
            refuse_fragile(rob, what)
        rob["accepted_because"] = "allow_fragile = true"
        warnings.warn(f"fragile design accepted (allow_fragile = true): a relative change of A of "
                      f"{rob['relative_stability_radius']:.3g} destabilises {what}", DesignWarning,
                      stacklevel=3)
    return rob


def _plane_of_poles(o, ts: float | None) -> tuple[list[complex], dict | None]:
    """The poles in the design's plane, and a note when they were converted or look mixed up.

    s-plane poles of a discrete design (``poles = {values, domain = "s"}``)
    are placed at ``z = exp(p ts)``. Without a plane, a discrete design whose
    poles are all real and negative warns: they look like s-plane poles
    (1/s) placed as z-plane ones (a near-deadbeat, oscillating gain).
    """
    poles = [complex(p) for p in o.poles]
    plane = getattr(o, "pole_domain", None)
    if o.time_domain == "discrete" and plane == "s":
        z = [complex(np.exp(p * ts)) for p in poles]
        return z, {"given": _complex_list(poles), "domain": "s", "placed": _complex_list(z),
                   "conversion": f"z = exp(p ts), ts = {ts:g} s"}
    if o.time_domain == "discrete" and plane is None and all(p.imag == 0 and p.real < 0 for p in poles):
        warnings.warn(
            f"every requested discrete pole is real and negative ({[p.real for p in poles]}): they "
            "are placed as z-plane poles (an oscillating, near-deadbeat loop), but they look like "
            "s-plane poles (1/s); if so write poles = {values = [...], domain = \"s\"} "
            "(placed at z = exp(p ts)), else domain = \"z\" to silence this", DesignWarning,
            stacklevel=3)
    return poles, None


# ------------------------------------------------------------------- ts_observer
def run_ts_observer(spec: "Spec", design: "DesignSpec") -> DesignResult:
    """TS multiple model + observer LMI (28) (seed 001).

    Gains: ``L`` (observer gain), ``P``, ``Q`` (LMI matrices), ``A0`` (mean
    vertex matrix), ``B0`` and ``C`` of the multiple model. The diagnostics
    hold the premises, their bounds and the method, the vertices, the
    exactness test, per-vertex observability, seed 001's selection rules, the
    Lipschitz analysis, the LMI solution and its re-check, and (with
    ``search = true``) the weightings searched.

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
    from tanksynth.design.observer_lmi.lmi import maximise_psi, observer_lmi  # cvxpy loads on first use

    o = options_of(design, spec, TsObserverOptions)
    plant = spec.plant
    variant, solver, margin, kappa = o.variant, o.solver, o.margin, o.kappa
    samples, seed, psi_source = o.samples, o.seed, o.psi_source
    names = [s.name for s in plant.states]
    box = list(plant.region.bounds)
    for nm, b in (o.domain or {}).items():
        box[names.index(nm)] = b
    try:
        domain = domain_from_plant(plant, box, o.orderings, o.ordering_gap)
    except SpecError as exc:
        raise rekeyed(design, exc, "domain") from None
    try:
        qlpv = quasi_lpv(plant, None if o.weights is None else dict(o.weights))
    except SpecError as exc:
        raise rekeyed(design, exc, fallback="weights") from None
    blocks = None if o.blocks is None else [[names.index(s) for s in b] for b in o.blocks]
    pattern = None if o.pattern is None else np.array(o.pattern)
    diagnostics: dict[str, Any] = {}
    if o.search:
        criterion = o.search_criterion
        found = search_weightings(qlpv, domain, values=list(o.search_values), include=[qlpv.weights],
                                  variant=variant, margin=margin, kappa=kappa, seed=seed,
                                  solver=solver)
        pick = found.best if criterion == "psi_max" else found.best_certified
        summary = found.as_dict()
        summary["criterion"] = criterion
        diagnostics["search"] = summary
        if pick is None:
            raise InfeasibleDesign(f"weighting search: no candidate meets the criterion '{criterion}' "
                                   f"(outcomes {summary['outcomes']})")
        qlpv = qlpv.with_weights(np.array(pick["weights"]))
    try:
        ts = ts_model(qlpv, domain, method=o.premise_bounds, samples=max(samples, 2000),
                      margin=o.premise_margin, seed=seed)
    except SpecError as exc:
        raise rekeyed(design, exc, fallback="weights") from None
    exactness = check_exactness(ts, plant, count=samples, seed=seed)
    if not exactness.passed:
        raise InfeasibleDesign(f"TS model is not exact on the domain: max relative error "
                               f"{exactness.max_relative_error:.3g}, min membership "
                               f"{exactness.min_membership:.3g}")
    obs = vertex_observability(ts)
    if not obs.all_observable:
        raise UnobservableError(f"TS vertices {list(obs.unobservable)} (Table I order) are not "
                                f"observable with C = {ts.C.tolist()}: choose other weights (seed 001 "
                                "section II-C)")
    A0, C = ts.A0, ts.C
    lip = None
    if psi_source == "lipschitz":
        lip = lipschitz_bound(ts, o.lipschitz,
                              o.lipschitz_method if o.lipschitz == "jacobian" else "sampling",
                              samples=samples, seed=seed)
        if not np.isfinite(lip.value):
            raise InfeasibleDesign(f"psi from the Lipschitz bound: {lip.detail.get('text')}")
    else:
        lip = lipschitz_bound(ts, "jacobian", "sampling", samples=samples, seed=seed)
    struct = dict(blocks=blocks, pattern=pattern, solver=solver)
    if psi_source == "maximise":
        search = maximise_psi(A0, C, variant=variant, margin=margin, kappa=kappa, **struct)
        res = search.result
        diagnostics["psi_search"] = search.as_dict()
        if search.kappa_active:
            warnings.warn(f"psi_max = {search.psi_max:.4g} 1/s is limited by the conditioning bound "
                          f"trace P <= kappa n (active at the optimum, kappa = {kappa:g}): a larger "
                          "kappa gives a larger psi", DesignWarning, stacklevel=2)
    else:
        psi = o.psi if psi_source == "given" else lip.value
        res = observer_lmi(A0, C, psi, variant=variant, margin=margin, kappa=kappa,
                           kappa_max=o.kappa_max, **struct)
    caveats = []
    if variant == "full":
        caveats.append("full Q (as printed in seed 001): the step Delta' Q Delta <= psi^2 e' Q e "
                       "needs a Lipschitz constant in the Q-weighted norm; the Euclidean bound "
                       "justifies only Q = q I (notes/plants.md 4.2)")
        try:
            safe = maximise_psi(A0, C, variant="qI", margin=margin, kappa=kappa, solver=solver)
            diagnostics["psi_max_qI"] = safe.psi_max
        except InfeasibleDesign as exc:
            diagnostics["psi_max_qI"] = f"refused: {exc}"
    if psi_source != "lipschitz":
        certified = bool(np.isfinite(lip.value) and res.psi >= lip.value)
        how = "given" if psi_source == "given" else "maximised"
        caveats.append(f"psi = {res.psi:.4g} 1/s was {how}, "
                       f"not derived from the region; sampled Lipschitz constant of Delta on the "
                       f"domain: {lip.value:.4g} 1/s ({'covered' if certified else 'NOT covered'})")
        if not certified:  # the LMI holds, but it certifies nothing on this plant and region
            bound = ("unbounded (the region reaches a point where a sqrt has infinite slope, e.g. "
                     "equal heads without orderings)" if not np.isfinite(lip.value)
                     else f"{lip.value:.4g} 1/s")
            warnings.warn(f"psi = {res.psi:.4g} 1/s ({how}) does not cover the Lipschitz constant "
                          f"of the TS remainder on the region, {bound}: the observer LMI holds but "
                          "certifies no convergence on the plant", DesignWarning, stacklevel=2)
    diagnostics.update({
        "psi_source": psi_source,
        "ts_model": ts.as_dict(),
        "exactness": exactness.as_dict(),
        "time_domain": "continuous",
        "vertex_observability": obs.as_dict(),
        "selection_rules": selection_rules(qlpv).as_dict(),
        "lipschitz": lip.as_dict(),
        "lmi": res.as_dict(),
        "solver": res.solver,
        "status": res.status,
        "robustness": _robust(A0, A0 - res.L @ C, res.L, "continuous", o.allow_fragile,
                              "the observer error matrix A0 - L C"),
        "caveats": caveats,
        "assumptions": _assumptions(spec),
    })
    if o.reference_L is not None:
        diagnostics["reference_L"] = _compare(o.reference_L, res.L, lambda Lr: A0 - Lr @ C)
        diagnostics["reference_L"]["note"] = ("LMI solutions are not unique: the comparison is "
                                              "informative, the re-check decides")
    gains = {"L": res.L, "P": res.P, "Q": res.Q, "A0": A0, "B0": ts.B0, "C": C}
    latex = {"L": _matrix_latex(np.round(res.L, 6)), "A0": _matrix_latex(np.round(A0, 8))}
    return DesignResult(design.name, "ts_observer", plant.name, gains, diagnostics, latex)


def _matrix_latex(M: np.ndarray) -> str:
    """``sympy.latex(sympy.Matrix(M))``, each distinct value converted and printed once.

    The same text as sympy's matrix printer (``\\left[\\begin{matrix}..`` up to
    10 columns, ``array`` with a column spec beyond), assembled here: a 256 x 256
    gain has 65,536 entries but a few distinct values, and printing every entry
    through sympy took seconds.
    """
    M = np.asarray(M)
    if M.ndim == 1:
        M = M.reshape(-1, 1)
    if M.ndim != 2 or not M.size:
        return sp.latex(sp.Matrix(M))
    kind = M.dtype.kind
    # a number, never text: the entries are floats or integers (anything else goes through Matrix)
    as_sympy = (lambda v: sp.Float(float(v))) if kind == "f" else \
        (lambda v: sp.Integer(int(v))) if kind in "iub" else (lambda v: sp.Matrix([[v]])[0, 0])
    text: dict = {}
    rows = []
    for row in M:
        cells = []
        for v in row:
            key = v.tobytes()
            if key not in text:
                text[key] = sp.latex(as_sympy(v))
            cells.append(text[key])
        rows.append(" & ".join(cells))
    env = "matrix" if M.shape[1] <= 10 else "array"
    spec = "" if env == "matrix" else "{" + "c" * M.shape[1] + "}"
    return rf"\left[\begin{{{env}}}{spec}" + r"\\".join(rows) + rf"\end{{{env}}}\right]"


def _solve_gain(spec, design, o, observer, feedback, fallback_opt: str, augmented_B: bool):
    """Shared body of `run_lmi_placement` and `run_pole_placement`.

    Builds the model, then calls ``observer(A, C, names)`` or
    ``feedback(A, B, names)`` (on the integral augmentation when the
    ``integral`` option ``o.integral`` is set). A `SpecError` from the solver without this
    design's key is re-raised under ``<design>.<fallback_opt>``.

    Returns ``(res, gains, diagnostics, (A, B, C), closed)`` where
    ``closed(G)`` is the closed-loop matrix a gain ``G`` gives.
    """
    plant = spec.plant
    time_domain = o.time_domain
    model, eq, _ = _model(spec, time_domain)
    names = [s.name for s in plant.states]
    A, B, C = model["A"], model["B"], model["C"]
    diagnostics: dict[str, Any] = {"equilibrium": eq.as_dict(), "time_domain": time_domain,
                                   "ts": spec.ts, "assumptions": _assumptions(spec)}
    try:
        if o.target == "observer":
            res = observer(A, C, names)
            gains = {"L": res.gain}
            closed = lambda G: A - G @ C  # noqa: E731
        else:
            if o.integral:
                outputs = [s.name for s in plant.outputs]
                tracked = list(o.tracked)
                C1 = C[[outputs.index(t) for t in tracked]]
                aug = _augment(model, C1, time_domain, spec.ts)
                Aa, Ba = aug["A"], aug["B"]
                res = feedback(Aa, Ba, names + [f"z_{t}" for t in tracked])
                K = res.gain
                gains = {"K": K, "K1": K[:, :plant.n], "K2": K[:, plant.n:], "Br": aug["Br"]}
                diagnostics["integral"] = {"tracked": tracked, "C1": C1.tolist(),
                                           "augmented_A": Aa.tolist()}
                if augmented_B:
                    diagnostics["integral"]["augmented_B"] = Ba.tolist()
                closed = lambda G: Aa - Ba @ G  # noqa: E731
            else:
                res = feedback(A, B, names)
                gains = {"K": res.gain}
                closed = lambda G: A - B @ G  # noqa: E731
    except SpecError as exc:
        raise rekeyed(design, exc, fallback=fallback_opt) from None
    gains.update({"x_op": np.asarray(spec.x0, dtype=float), "u_op": np.asarray(eq.u0, dtype=float)})
    return res, gains, diagnostics, (A, B, C), closed


def _loop_name(o) -> str:
    if o.target == "observer":
        return "the observer error matrix A - L C"
    return "the augmented closed loop Aa - Ba K" if o.integral else "the closed loop A - B K"


# ----------------------------------------------------------------- lmi_placement
def run_lmi_placement(spec: "Spec", design: "DesignSpec") -> DesignResult:
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
    from tanksynth.design.placement.regions import lmi_observer, lmi_state_feedback  # loads cvxpy

    o = options_of(design, spec, LmiPlacementOptions)
    plant = spec.plant
    region = region_from_parts(o.region)
    time_domain, margin, kappa, solver = o.time_domain, o.margin, o.kappa, o.solver
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
    gain = gains.get("L", gains.get("K"))
    open_loop = A if o.target == "observer" or not o.integral else \
        diagnostics["integral"]["augmented_A"]
    diagnostics["robustness"] = _robust(np.asarray(open_loop, dtype=float), closed(gain), gain,
                                        time_domain, o.allow_fragile, _loop_name(o))
    if res.scaling.get("kappa_relaxed"):
        warnings.warn(f"the conditioning bound was active: kappa relaxed from {kappa:g} to "
                      f"{res.scaling['kappa']:g} (ceiling kappa_max = {kmax:g})", DesignWarning,
                      stacklevel=2)
    names = model_names(time_domain)
    gains.update({"P": res.P, names["A"]: A, names["B"]: B, "C": C})
    diagnostics.update({"lmi": res.as_dict(), "solver": res.solver, "status": res.status})
    return DesignResult(design.name, "lmi_placement", plant.name, gains, diagnostics, {})


# ---------------------------------------------------------------- pole_placement
def run_pole_placement(spec: "Spec", design: "DesignSpec") -> DesignResult:
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
    poles, converted = _plane_of_poles(o, spec.ts)
    res, gains, diagnostics, (A, B, C), closed = _solve_gain(
        spec, design, o,
        lambda A, C, names: place_observer(A, C, poles, method, state_names=names),
        lambda A, B, names: place_state_feedback(A, B, poles, method, state_names=names),
        fallback_opt="poles", augmented_B=True)
    gain = res.gain
    diagnostics["placement"] = res.as_dict()
    if converted is not None:
        diagnostics["poles_converted"] = converted
    open_loop = A if o.target == "observer" or not o.integral else \
        np.asarray(diagnostics["integral"]["augmented_A"], dtype=float)
    diagnostics["robustness"] = _robust(open_loop, closed(gain), gain, o.time_domain,
                                        o.allow_fragile, _loop_name(o))
    if o.reference_gain is not None:
        ref = o.reference_gain
        cmp_ = _compare(ref, gain, closed)
        ach = np.linalg.eigvals(closed(ref))
        cmp_["reference_max_pole_error"] = pole_errors(poles, ach)[1]
        cmp_["note"] = ("with several inputs the gain placing given poles is not unique (place uses "
                        "Tits-Yang); compare the achieved poles, not the digits")
        diagnostics["reference_gain"] = cmp_
    names = model_names(o.time_domain)
    gains.update({names["A"]: A, names["B"]: B, "C": C})
    return DesignResult(design.name, "pole_placement", plant.name, gains, diagnostics, {})


# ------------------------------------------------------------ canonical_observer
def run_canonical_observer(spec: "Spec", design: "DesignSpec") -> DesignResult:
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
    L = co.gain
    An, Cn = np.array(A.evalf(), dtype=float), np.array(C.evalf(), dtype=float)
    pl = place_observer(An, Cn, poles, state_names=[s.name for s in plant.states])
    ach = np.linalg.eigvals(An - L @ Cn)
    acc = placement_accuracy(poles, An - L @ Cn)
    diagnostics: dict[str, Any] = {
        "time_domain": "continuous",
        "canonical_form": co.as_dict(),
        "achieved_poles": _complex_list(ach),
        "max_pole_error": pole_errors(poles, ach)[1],
        "accuracy": {"measure": "characteristic polynomial in exact arithmetic (sympy)",
                     "exact": co.exact, "float_gain": acc},
        "robustness": _robust(An, An - L @ Cn, L, "continuous", o.allow_fragile,
                              "the observer error matrix F - L C"),
        "place_cross_check": {"L_place": pl.gain.tolist(),
                              "max_abs_difference": float(np.max(np.abs(pl.gain - L))),
                              "place_report": pl.as_dict()},
        "assumptions": _assumptions(spec),
    }
    if o.reference_gain is not None:
        diagnostics["reference_gain"] = _compare(o.reference_gain, L, lambda G: An - G @ Cn)
    if o.reference_closed_loop is not None:
        ref = o.reference_closed_loop
        eig = np.linalg.eigvals(ref)
        derived = np.array(co.Gamma_d.evalf(), dtype=float)
        diagnostics["reference_closed_loop"] = {
            "reference": ref.tolist(), "derived": derived.tolist(),
            "reference_eigenvalues": _complex_list(eig),
            "reference_max_pole_error": pole_errors(poles, eig)[1],
            "max_abs_difference": float(np.max(np.abs(ref - derived)))}
    latex = {"Psi": sp.latex(co.Psi), "Delta": sp.latex(co.Delta), "Gamma_d": sp.latex(co.Gamma_d)}
    return DesignResult(design.name, "canonical_observer", plant.name,
                        {"L": L, "F": An, "C": Cn}, diagnostics, latex)


# ------------------------------------------------------------------ design methods
TS_OBSERVER = DesignMethod("ts_observer", run_ts_observer, TsObserverOptions)
LMI_PLACEMENT = DesignMethod("lmi_placement", run_lmi_placement, LmiPlacementOptions)
POLE_PLACEMENT = DesignMethod("pole_placement", run_pole_placement, PolePlacementOptions)
CANONICAL_OBSERVER = DesignMethod("canonical_observer", run_canonical_observer,
                                  CanonicalObserverOptions)
