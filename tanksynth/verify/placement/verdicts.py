"""Verdicts of ``pole_placement``, ``lmi_placement`` and ``canonical_observer``."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.analysis.lmi_region import region_from_parts
from tanksynth.analysis.rank import controllability_rank, observability_rank
from tanksynth.spec import Spec
from tanksynth.spec.options import parse_region
from tanksynth.verify.common import (POLE_TOLERANCE, artefact_matrix, complex_list, fmt, guard,
                                     model_recheck, operating_point, option, output_at, output_rows,
                                     rank_check, region_check, region_lmi_check, required_ts,
                                     stability_check, time_domain, tracked_outputs)
from tanksynth.verify.numerics import integral_augmentation, pole_agreement
from tanksynth.verify.simulations import (IntegralStateFeedback, designed_time_constant, requested_poles,
                                          eigenvector_conditioning, fastest_rate,
                                          luenberger_estimator, observer_convergence,
                                          observer_period, regulation_check, servo_check)
from tanksynth.verify.traces import TraceRecorder

__all__ = ["pole_placement_verdict", "lmi_placement_verdict", "canonical_observer_verdict"]

# =================================================================== convex designs
def _pole_check(matrix: np.ndarray, requested: Any, what: str) -> Check:
    """``poles``: the eigenvalues of ``matrix`` against the requested poles (`pole_agreement`).

    Repeated poles are judged by the characteristic polynomial and a
    multiplicity-scaled pole tolerance (a k-fold eigenvalue is computable
    only to ``eps^(1/k)``), simple poles by their matched error.
    """
    p = np.asarray(requested, dtype=complex).reshape(-1)
    eigs = np.linalg.eigvals(matrix)
    if p.size != eigs.size:
        return Check("poles", False, f"{p.size} poles requested in the spec, {eigs.size} eigenvalues "
                                     f"of {what}", {"requested": complex_list(p)})
    ag = pole_agreement(p, matrix, POLE_TOLERANCE)
    m = ag.match
    detail = (f"eigenvalues of {what} recomputed from the artefact: {fmt(np.sort_complex(eigs), 6)}; "
              f"requested in the spec: {fmt(np.sort_complex(p), 6)}; largest error after the optimal "
              f"one-to-one matching {m.max_error:.3g}, relative to max(1, |p|) "
              f"{m.max_relative_error:.3g}")
    if np.any(ag.multiplicity > 1):
        detail += (f" (allowed {float(np.min(ag.allowed)):.3g} for a pole of multiplicity "
                   f"{int(ag.multiplicity.max())}); characteristic polynomial relative error "
                   f"{ag.polynomial_error:.3g} (tolerance {POLE_TOLERANCE:g})")
    else:
        detail += f" (tolerance {POLE_TOLERANCE:g})"
    return Check("poles", ag.passed, detail,
                 {"achieved": complex_list(eigs), "requested": complex_list(p),
                  "max_error": m.max_error, "max_relative_error": m.max_relative_error,
                  "multiplicity": ag.multiplicity.tolist(), "polynomial_error": ag.polynomial_error,
                  "measure": ag.measure, "tolerance": POLE_TOLERANCE})


def _placement_common(doc: Mapping[str, Any], spec: Spec) -> dict:
    plant = spec.plant
    n, m, q = plant.n, plant.m, plant.q
    domain = time_domain(doc, spec)
    ts = spec.ts
    A = artefact_matrix(doc, "A", (n, n), domain)
    B = artefact_matrix(doc, "B", (n, m), domain)
    C = artefact_matrix(doc, "C", (q, n))
    x0, u0 = operating_point(spec)
    gains = doc["gains"]
    target = "observer" if "L" in gains else "state_feedback"
    integral = "K1" in gains and "K2" in gains
    out: dict[str, Any] = dict(plant=plant, domain=domain, ts=ts, A=A, B=B, C=C, x0=x0, u0=u0, target=target,
               integral=integral)
    if target == "observer":
        L = artefact_matrix(doc, "L", (n, q))
        out.update(L=L, Acl=A - L @ C, what="the observer error matrix A - L C")
    elif integral:
        names = tracked_outputs(doc, spec)
        rows = output_rows(plant, names)
        C1 = C[rows]
        K = artefact_matrix(doc, "K", (m, n + len(rows)))
        Aa, Ba = integral_augmentation(A, B, C1, required_ts(ts) if domain == "discrete" else None)
        out.update(K=K, C1=C1, rows=rows, tracked=names, Aa=Aa, Ba=Ba, Acl=Aa - Ba @ K,
                   y0=output_at(plant, x0)[rows],   # the measured outputs at x0, offsets included
                   what="the augmented closed loop Aa - Ba K")
    else:
        K = artefact_matrix(doc, "K", (m, n))
        out.update(K=K, Acl=A - B @ K, what="the closed loop A - B K")
    out["eigs"] = np.linalg.eigvals(out["Acl"])
    return out


def _placement_rank(c: dict) -> list[Check]:
    if c["target"] == "observer":
        return [rank_check("rank_observability", observability_rank(c["A"], c["C"]), "(A, C)")]
    checks = [rank_check("rank_controllability", controllability_rank(c["A"], c["B"]), "(A, B)")]
    if c["integral"]:
        checks.append(rank_check("rank_controllability_augmented",
                                 controllability_rank(c["Aa"], c["Ba"]), "the augmented (Aa, Ba)"))
    return checks


def _placement_simulation(doc: Mapping[str, Any], spec: Spec, c: dict,
                          trace: TraceRecorder | None) -> list[Check]:
    plant, domain, ts = c["plant"], c["domain"], c["ts"]
    tau, rule = designed_time_constant(doc, spec, c["eigs"], domain, ts)
    if c["target"] == "observer":
        if not np.isfinite(tau):
            return [Check("observer_convergence", False, "the designed error dynamics are not "
                                                         "stable: nothing to converge")]
        ts_sim = observer_period(domain, ts, tau)
        form = "predictor" if domain == "discrete" else "continuous"
        est = luenberger_estimator(plant, c["L"], c["x0"], c["u0"], ts_sim, form)
        return [observer_convergence(plant, est, c["x0"], c["u0"], tau, ts_sim,
                                     conditioning=eigenvector_conditioning(c["Acl"]),
                                     rule=f"{rule}; Luenberger observer, {form} form (error matrix "
                                          f"{'A - L C' if form == 'predictor' else 'F - L C'}), on the "
                                          "plant linearised at the operating point",
                                     trace=trace)]
    if domain == "discrete":
        ts_sim = float(ts)
    else:
        fast = fastest_rate(c["eigs"], domain, ts)
        ts_sim = 0.05 / fast if fast > 0 else tau / 20
        ts_sim = min(ts_sim, ts) if ts else ts_sim
    if c["integral"]:
        law = IntegralStateFeedback(c["K"][:, :plant.n], c["K"][:, plant.n:], c["C1"], c["x0"],
                                    c["u0"], ts_sim, y0=c["y0"])
        return servo_check(plant, law, c["x0"], c["u0"], c["rows"], tau, ts_sim, rule=rule,
                           trace=trace)
    return [regulation_check(plant, c["K"], c["x0"], c["u0"], tau, ts_sim,
                             eigenvector_conditioning(c["Acl"]), rule=rule, trace=trace)]


def pole_placement_verdict(doc: Mapping[str, Any], spec: Spec, *,
                           trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``pole_placement`` artefact (state feedback, integral action or observer).

    Checks: ``model_recheck``, ``poles`` (vs the spec's ``poles``),
    ``stability``, ``rank_*``, then ``observer_convergence``,
    ``servo_tracking`` + ``bounded_inputs`` (integral action) or
    ``regulation`` on the nonlinear plant.

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    c = _placement_common(doc, spec)
    checks = [model_recheck(c["plant"], c["x0"], c["u0"], c["domain"], c["ts"],
                            {"A": c["A"], "B": c["B"], "C": c["C"]})]
    poles = requested_poles(doc, spec, c["domain"])
    if poles is None:
        checks.append(Check("poles", None, "the spec entry of this artefact gives no poles"))
    else:
        checks.append(_pole_check(c["Acl"], poles, c["what"]))
    checks.append(stability_check(c["eigs"], c["domain"], c["what"]))
    checks += _placement_rank(c)
    checks += guard("simulation", lambda: _placement_simulation(doc, spec, c, trace))
    return checks


def lmi_placement_verdict(doc: Mapping[str, Any], spec: Spec, *,
                          trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of an ``lmi_placement`` artefact.

    Checks: ``model_recheck``, ``region`` (eigenvalues in the spec's
    region), ``lmi_recheck`` (region LMI from the stored ``P``),
    ``stability``, ``rank_*`` and the simulation checks of
    `pole_placement_verdict`.

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    c = _placement_common(doc, spec)
    size = c["Acl"].shape[0]
    checks = [model_recheck(c["plant"], c["x0"], c["u0"], c["domain"], c["ts"],
                            {"A": c["A"], "B": c["B"], "C": c["C"]})]
    raw = option(doc, spec, "region")
    if raw is None:
        checks.append(Check("region", None, "the spec entry of this artefact gives no region"))
    else:
        region = region_from_parts(parse_region(raw, "region"))
        checks.append(region_check(c["eigs"], region, c["what"]))
        P = artefact_matrix(doc, "P", (size, size))
        if c["target"] == "observer":
            # dual problem: X = P for (A', C'), closed loop (A - L C)'
            checks.append(region_lmi_check(region, c["Acl"].T, P, "(A - L C)' with X = P"))
        else:
            checks.append(region_lmi_check(region, c["Acl"], np.linalg.inv(P),
                                           c["what"] + " with X = P^-1"))
    checks.append(stability_check(c["eigs"], c["domain"], c["what"]))
    checks += _placement_rank(c)
    checks += guard("simulation", lambda: _placement_simulation(doc, spec, c, trace))
    return checks


def canonical_observer_verdict(doc: Mapping[str, Any], spec: Spec, *,
                               trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``canonical_observer`` artefact (seed 004 eq. 27-29).

    Checks: ``model_recheck`` (stored ``A``, ``C`` vs the continuous
    Jacobians), ``poles`` of ``A - L C`` vs the spec's poles,
    ``stability``, ``rank_observability`` and ``observer_convergence`` of
    the continuous Luenberger observer on the nonlinear plant.

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    plant = spec.plant
    n, q = plant.n, plant.q
    A = artefact_matrix(doc, "F", (n, n))
    C = artefact_matrix(doc, "C", (q, n))
    L = artefact_matrix(doc, "L", (n, q))
    x0, u0 = operating_point(spec)
    eigs = np.linalg.eigvals(A - L @ C)
    what = "the observer error matrix A - L C"
    checks = [model_recheck(plant, x0, u0, "continuous", None, {"A": A, "C": C})]
    poles = requested_poles(doc, spec, "continuous")
    if poles is None:
        checks.append(Check("poles", None, "the spec entry of this artefact gives no poles"))
    else:
        checks.append(_pole_check(A - L @ C, poles, what))
    checks.append(stability_check(eigs, "continuous", what))
    checks.append(rank_check("rank_observability", observability_rank(A, C), "(A, C)"))

    def sim() -> list[Check]:
        tau, rule = designed_time_constant(doc, spec, eigs, "continuous", None)
        if not np.isfinite(tau):
            return [Check("observer_convergence", False, "error dynamics not stable")]
        ts_sim = observer_period("continuous", spec.ts, tau)
        est = luenberger_estimator(plant, L, x0, u0, ts_sim, "continuous")
        return [observer_convergence(plant, est, x0, u0, tau, ts_sim,
                                     conditioning=eigenvector_conditioning(A - L @ C),
                                     rule=f"{rule}; continuous Luenberger observer on the plant "
                                          "linearised at the operating point",
                                     trace=trace)]

    return checks + guard("observer_convergence", sim)
