"""Spec design method ``ts_observer``: the Takagi-Sugeno observer of seed 001.

``ts_observer`` builds the TS multiple model of the plant (seed 001 section II: quasi-LPV
form, premise bounds, vertex matrices, exactness and vertex observability;
`tanksynth.analysis.takagi_sugeno`), optionally searches the weightings of the premises
(`tanksynth.design.observer_lmi.weighting`), and solves the observer LMI (28)
(`tanksynth.design.observer_lmi.lmi`) for a given, Lipschitz-derived or maximised ``psi``;
gains ``L``, ``P``, ``Q`` (and ``A0``, ``B0``, ``C`` of the multiple model).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from tanksynth.analysis.takagi_sugeno import (check_exactness, domain_from_plant, quasi_lpv,
                                              ts_model, vertex_observability)
from tanksynth.design.linear_gains import checked_robustness, matrix_latex, reference_comparison
from tanksynth.design.observer_lmi.lmi import maximise_psi, observer_lmi
from tanksynth.design.observer_lmi.weighting import lipschitz_bound, search_weightings, selection_rules
from tanksynth.design.result import DesignMethod, DesignResult, options_of, rekeyed
from tanksynth.errors import DesignWarning, InfeasibleDesign, SpecError, UnobservableError
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options import TsObserverOptions

__all__ = ["run_ts_observer", "TS_OBSERVER"]


def run_ts_observer(spec: Spec, design: DesignSpec) -> DesignResult:
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
                       "justifies only Q = q I")
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
        "robustness": checked_robustness(A0, A0 - res.L @ C, res.L, "continuous", o.allow_fragile,
                                         "the observer error matrix A0 - L C"),
        "caveats": caveats,
        "assumptions": [a.text for a in plant.assumptions],
    })
    if o.reference_L is not None:
        diagnostics["reference_L"] = reference_comparison(o.reference_L, res.L, lambda Lr: A0 - Lr @ C)
        diagnostics["reference_L"]["note"] = ("LMI solutions are not unique: the comparison is "
                                              "informative, the re-check decides")
    gains = {"L": res.L, "P": res.P, "Q": res.Q, "A0": A0, "B0": ts.B0, "C": C}
    latex = {"L": matrix_latex(np.round(res.L, 6)), "A0": matrix_latex(np.round(A0, 8))}
    return DesignResult(design.name, "ts_observer", plant.name, gains, diagnostics, latex)


TS_OBSERVER = DesignMethod("ts_observer", run_ts_observer, TsObserverOptions)
