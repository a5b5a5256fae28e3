"""Verdicts of the estimators: kalman, ekf, ukf, adaptive_kalman, adaptive_scaling_kalman,
consensus_filter, luenberger; `ESTIMATOR_BUILDERS` rebuilds each from its artefact."""


from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.analysis.checks import Check
from tanksynth.analysis.rank import observability_rank
from tanksynth.sim.simulate import BatchEstimator, EstimatorAdapter
from tanksynth.verify.common import artefact_gain


from tanksynth.verify.common import _NUMERIC_ERRORS, _conditioning, _designed_tau, _equilibrium, _guard, _matrix, _model_recheck, _observer_tau, _one_line, _option, _pole_check, _rank_check, _rel, _stability_check, design_options, observer_convergence
from tanksynth.verify.runner import VerdictFn

__all__ = ["ESTIMATOR_BUILDERS", "estimator_verdict", "kalman_verdict", "ekf_verdict", "ukf_verdict",
           "adaptive_kalman_verdict", "adaptive_scaling_kalman_verdict", "consensus_filter_verdict",
           "luenberger_verdict"]

# ======================================================================= estimators
def _spec_kwargs(doc: Mapping[str, Any], spec: Any, names: Sequence[str]) -> dict:
    opts = design_options(doc, spec)
    return {k: opts[k] for k in names if k in opts}


def _operating_point_gains(doc: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray] | None:
    gains = doc["gains"]
    if "x_op" in gains and "u_op" in gains:
        return artefact_gain(doc, "x_op"), artefact_gain(doc, "u_op")
    return None


def _steady_kalman_error(spec: Any, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``(I - K C) Ad`` of the steady-state Kalman filter of the linearisation at the operating point."""
    from tanksynth.runtime.estimators.base import discrete_model
    from tanksynth.runtime.estimators.kalman import steady_state_gain

    x0, u0 = _equilibrium(spec)
    model = discrete_model(spec.plant, float(spec.ts), operating_point=(x0, u0))
    K, _ = steady_state_gain(model, Q, R)
    return (np.eye(spec.plant.n) - K @ model.C) @ model.Ad


def _kalman_builder(doc: Mapping[str, Any], spec: Any) -> tuple[BatchEstimator, np.ndarray, str]:
    from tanksynth.runtime.estimators.kalman import ExtendedKalmanFilter, KalmanFilter, KalmanTuning

    plant = spec.plant
    n, q = plant.n, plant.q
    Q, R = _matrix(doc, "Q", (n, n)), _matrix(doc, "R", (q, q))
    tuning = KalmanTuning(Q=Q, R=R, P0=_matrix(doc, "P0", (n, n)), x0=artefact_gain(doc, "x0"),
                          ts=float(spec.ts), operating_point=_operating_point_gains(doc),
                          **_spec_kwargs(doc, spec, ("substeps", "clip", "jacobian_eps", "switch_tol")))
    linear = doc["method"] == "kalman"
    est = (KalmanFilter if linear else ExtendedKalmanFilter)(plant, tuning, backend="vm")
    what = ("linear Kalman filter (CKF) on the linearisation at the operating point" if linear else
            "extended Kalman filter on the nonlinear model")
    return EstimatorAdapter(est), _steady_kalman_error(spec, Q, R), what


def _ukf_builder(doc: Mapping[str, Any], spec: Any) -> tuple[BatchEstimator, np.ndarray, str]:
    from tanksynth.runtime.estimators.ukf import UKFTuning, UnscentedKalmanFilter

    plant = spec.plant
    n, q = plant.n, plant.q
    Q, R = _matrix(doc, "Q", (n, n)), _matrix(doc, "R", (q, q))
    tuning = UKFTuning(Q=Q, R=R, P0=_matrix(doc, "P0", (n, n)), x0=artefact_gain(doc, "x0"),
                       ts=float(spec.ts), operating_point=_operating_point_gains(doc),
                       **_spec_kwargs(doc, spec, ("alpha", "beta", "kappa", "redraw", "substeps",
                                                  "clip")))
    est = UnscentedKalmanFilter(plant, tuning, backend="vm")
    return EstimatorAdapter(est), _steady_kalman_error(spec, Q, R), "unscented Kalman filter"


def _adaptive_kalman_builder(doc: Mapping[str, Any], spec: Any
                             ) -> tuple[BatchEstimator, np.ndarray, str]:
    from tanksynth.runtime.estimators.adaptive import AdaptiveKalmanFilter, AdaptiveKalmanTuning

    plant = spec.plant
    n, q = plant.n, plant.q
    Q0, R = _matrix(doc, "Q0", (n, n)), _matrix(doc, "R", (q, q))
    tuning = AdaptiveKalmanTuning(Q0=Q0, R=R, P0=_matrix(doc, "P0", (n, n)),
                                  x0=artefact_gain(doc, "x0"), ts=float(spec.ts),
                                  window=int(round(float(artefact_gain(doc, "window")[0]))),
                                  q_floor=float(artefact_gain(doc, "q_floor")[0]),
                                  operating_point=_operating_point_gains(doc),
                                  **_spec_kwargs(doc, spec, ("form",)))
    est = AdaptiveKalmanFilter(plant, tuning)
    return EstimatorAdapter(est), _steady_kalman_error(spec, Q0, R), \
        "adaptive-Q Kalman filter (horizon from the steady-state filter with Q0)"


def _dare_error(spec: Any, op: tuple[np.ndarray, np.ndarray] | None, Q: np.ndarray,
                R: np.ndarray, sensors: int = 1) -> np.ndarray:
    """``(I - K C) Ad`` of the steady-state Kalman filter on the linearisation at ``op``.

    ``Q`` is the process noise covariance in state coordinates (``G Q G'``);
    with ``sensors = N`` the output matrix is ``C`` stacked N times and ``R``
    the block-diagonal covariance of the N sensors (the centralised filter
    the consensus filter reproduces).
    """
    import scipy.linalg as sla

    from tanksynth.analysis.linearize import linearize

    x_op, u_op = op if op is not None else _equilibrium(spec)
    lin = linearize(spec.plant, x_op, u_op, ts=float(spec.ts))
    Ad, C = lin.Ad, np.vstack([lin.C] * sensors)
    P = sla.solve_discrete_are(Ad.T, C.T, 0.5 * (Q + Q.T), R)
    K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    return (np.eye(spec.plant.n) - K @ C) @ Ad


def _spec_design(doc: Mapping[str, Any], spec: Any) -> Any:
    for d in getattr(spec, "designs", ()):
        if d.name == doc["name"] and d.method == doc["method"]:
            return d
    return None


def _claimed(doc: Mapping[str, Any], spec: Any, opt: str, stored: np.ndarray) -> tuple[np.ndarray, str]:
    """The covariance the spec declares for ``opt`` (the design's claim), else the stored one."""
    from tanksynth.spec.options import parse_covariance as _covariance

    design = _spec_design(doc, spec)
    if design is None or opt not in design.options:
        return stored, "stored"
    value = design.options[opt]
    size = stored.shape[0]
    if opt == "R" and doc["method"] == "consensus_filter":
        import scipy.linalg as sla

        return sla.block_diag(*[_covariance(v, f"{opt}[{i}]", size // len(value))
                                for i, v in enumerate(value)]), "spec"
    return _covariance(value, opt, size, semidefinite=(opt == "Q")), "spec"


def _adaptive_scaling_builder(doc: Mapping[str, Any], spec: Any
                              ) -> tuple[BatchEstimator, np.ndarray, str]:
    from tanksynth.runtime.estimators.adaptive import AdaptiveScalingKalmanFilter, AdaptiveScalingTuning

    plant = spec.plant
    n, q = plant.n, plant.q
    Q = np.atleast_2d(artefact_gain(doc, "Q"))
    r = Q.shape[0]
    G = _matrix(doc, "G", (n, r))
    R = _matrix(doc, "R", (q, q))
    a, b, c = (float(v) for v in np.asarray(artefact_gain(doc, "abc"), float).reshape(3))
    op = _operating_point_gains(doc)
    tuning = AdaptiveScalingTuning(Q=Q, R=R, P0=_matrix(doc, "P0", (n, n)),
                                   x0=artefact_gain(doc, "x0"), ts=float(spec.ts), a=a, b=b, c=c,
                                   G=G, phi0=float(np.ravel(artefact_gain(doc, "phi0"))[0]),
                                   operating_point=op)
    est = AdaptiveScalingKalmanFilter(plant, tuning)
    Qc, src_q = _claimed(doc, spec, "Q", Q)
    Rc, src_r = _claimed(doc, spec, "R", R)
    return EstimatorAdapter(est), _dare_error(spec, op, G @ Qc @ G.T, Rc), \
        (f"adaptive-scaling Kalman filter (horizon from the steady-state filter with phi = 1, "
         f"Q of the {src_q}, R of the {src_r})")


class _StackedSensors(EstimatorAdapter):
    """`EstimatorAdapter` feeding the plant's measurement to each of N redundant sensors."""

    def __init__(self, template: Any, sensors: int):
        super().__init__(template)
        self.sensors = int(sensors)

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        return self._est.step(np.tile(y, (1, self.sensors)), u)


def _consensus_builder(doc: Mapping[str, Any], spec: Any) -> tuple[BatchEstimator, np.ndarray, str]:
    from tanksynth.runtime.estimators.consensus import ConsensusFilter, ConsensusTuning

    plant = spec.plant
    n, q = plant.n, plant.q
    gains = doc["gains"]
    N = 0
    while f"R{N}" in gains:
        N += 1
    if N == 0:
        raise ArtefactError(f"artefact '{doc['name']}' has no sensor covariance R0")
    if "C0" in gains:
        raise ArtefactError(f"artefact '{doc['name']}': sensors with their own C_i are not "
                            "verified on the plant's output")
    Rs = [_matrix(doc, f"R{i}", (q, q)) for i in range(N)]
    Q = np.atleast_2d(artefact_gain(doc, "Q"))
    G = _matrix(doc, "G", (n, Q.shape[0]))
    op = _operating_point_gains(doc)
    tuning = ConsensusTuning(Q=Q, R=tuple(Rs), P0=_matrix(doc, "P0", (n, n)),
                             x0=artefact_gain(doc, "x0"), ts=float(spec.ts), G=G,
                             operating_point=op)
    import scipy.linalg as sla

    Qc, src_q = _claimed(doc, spec, "Q", Q)
    Rc, src_r = _claimed(doc, spec, "R", sla.block_diag(*Rs))
    err = _dare_error(spec, op, G @ Qc @ G.T, Rc, sensors=N)
    return _StackedSensors(ConsensusFilter(plant, tuning), N), err, \
        (f"consensus filter with {N} sensors, each fed the plant's measurement (horizon from the "
         f"equivalent centralised steady-state filter, Q of the {src_q}, R of the {src_r})")


def _covariance_check(est: Any) -> Check:
    """Final covariance of a filter run: symmetric positive definite (every run)."""
    inner = getattr(est, "_est", None)
    P = np.asarray(getattr(inner, "covariance"), dtype=float)
    P = P.reshape(-1, P.shape[-2], P.shape[-1])
    scale = max(float(np.max(np.abs(P))), 1e-300)
    asym = float(np.max(np.abs(P - np.swapaxes(P, -1, -2)))) / scale
    lam = np.linalg.eigvalsh(0.5 * (P + np.swapaxes(P, -1, -2)))
    pmin, pmax = float(np.min(lam)), float(np.max(lam))
    ok = bool(np.all(np.isfinite(P)) and asym <= 1e-9 and pmin > 0)
    return Check("covariance", ok,
                 f"filter covariance at the end of the estimator_convergence run: asymmetry "
                 f"max|P - P'| / max|P| = {asym:.3g} (tolerance 1e-09), eigenvalues in "
                 f"[{pmin:.3g}, {pmax:.3g}] (smallest must be > 0)",
                 {"asymmetry": asym, "min_eigenvalue": pmin, "max_eigenvalue": pmax})


def _luenberger_error_matrix(spec: Any, L: np.ndarray, form: str,
                             op: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    from tanksynth.analysis.linearize import linearize

    x_op, u_op = op if op is not None else _equilibrium(spec)
    lin = linearize(spec.plant, x_op, u_op, ts=spec.ts)
    if form == "current":
        return (np.eye(spec.plant.n) - L @ lin.C) @ lin.Ad
    if form == "predictor":
        return lin.Ad - L @ lin.C
    return lin.F - L @ lin.C


def _luenberger_builder(doc: Mapping[str, Any], spec: Any) -> tuple[BatchEstimator, np.ndarray, str]:
    from tanksynth.runtime.estimators.luenberger import LuenbergerObserver, LuenbergerTuning

    plant = spec.plant
    L = _matrix(doc, "L", (plant.n, plant.q))
    form = str(_option(doc, spec, "form", "current"))
    op = _operating_point_gains(doc)
    tuning = LuenbergerTuning(L=L, x0=artefact_gain(doc, "x0"), ts=float(spec.ts), form=form,
                              operating_point=op, **_spec_kwargs(doc, spec, ("substeps",)))
    err = _luenberger_error_matrix(spec, L, form, op)
    if form == "continuous":
        err = _expm(err * float(spec.ts))
    where = "the linearisation at the operating point" if op is not None else "the nonlinear model"
    return EstimatorAdapter(LuenbergerObserver(plant, tuning)), err, \
        f"Luenberger observer, {form} form, on {where}"


def _expm(M: np.ndarray) -> np.ndarray:
    import scipy.linalg as sla

    return sla.expm(M)


#: Builders of batch estimators from estimator artefacts: method -> ``builder(doc, spec)``
#: returning ``(BatchEstimator, E, description)`` with ``E`` the discrete error matrix whose
#: eigenvalues set the horizon (steady-state gain at the operating point). The estimator stage may
#: add entries, or register a verdict of its own (which replaces `estimator_verdict`).
ESTIMATOR_BUILDERS: dict[str, Callable[[Mapping[str, Any], Any],
                                       tuple[BatchEstimator, np.ndarray, str]]] = {
    "kalman": _kalman_builder,
    "ekf": _kalman_builder,
    "ukf": _ukf_builder,
    "luenberger": _luenberger_builder,
    "adaptive_kalman": _adaptive_kalman_builder,
    "adaptive_scaling_kalman": _adaptive_scaling_builder,
    "consensus_filter": _consensus_builder,
}

#: Methods whose filter covariance is checked (symmetric positive definite) after the run.
_COVARIANCE_METHODS = ("adaptive_scaling_kalman", "consensus_filter")


def _kalman_rechecks(doc: Mapping[str, Any], spec: Any) -> list[Check]:
    """CKF artefact: stored model, Riccati solution and steady-state gain re-checked."""
    plant = spec.plant
    n, m, q = plant.n, plant.m, plant.q
    Ad, Bd, C = _matrix(doc, "Ad", (n, n)), _matrix(doc, "Bd", (n, m)), _matrix(doc, "C", (q, n))
    Q, R = _matrix(doc, "Q", (n, n)), _matrix(doc, "R", (q, q))
    K, P = _matrix(doc, "K_ss", (n, q)), _matrix(doc, "P_ss", (n, n))
    op = _operating_point_gains(doc)
    x_op, u_op = op if op is not None else _equilibrium(spec)
    checks = [_model_recheck(plant, x_op, u_op, "discrete", float(spec.ts),
                             {"A": Ad, "B": Bd, "C": C})]
    S = C @ P @ C.T + R
    res = Ad @ P @ Ad.T - Ad @ P @ C.T @ np.linalg.solve(S, C @ P @ Ad.T) + Q - P
    rr = float(np.linalg.norm(res) / max(np.linalg.norm(P), 1e-300))
    kk = _rel(K, P @ C.T @ np.linalg.inv(S))
    pmin = float(np.min(np.linalg.eigvalsh(0.5 * (P + P.T))))
    checks.append(Check("riccati_recheck", bool(rr <= 1e-8 and kk <= 1e-8 and pmin > 0),
                        f"stored P_ss in the discrete Riccati equation P = Ad P Ad' - Ad P C' (C P C' + "
                        f"R)^-1 C P Ad' + Q: relative residual {rr:.3g}; stored K_ss against P C' (C P C' "
                        f"+ R)^-1: {kk:.3g} (tolerance 1e-08); smallest eigenvalue of P_ss {pmin:.3g} "
                        "(must be > 0)", {"residual": rr, "gain_difference": kk}))
    err = (np.eye(n) - K @ C) @ Ad
    checks.append(_stability_check(np.linalg.eigvals(err), "discrete",
                                   "the steady-state error matrix (I - K_ss C) Ad"))
    checks.append(_rank_check("rank_observability", observability_rank(Ad, C), "(Ad, C)"))
    return checks


def estimator_verdict(doc: Mapping[str, Any], spec: Any) -> list[Check]:
    """Default verdict of an estimator artefact.

    ``kalman`` artefacts first get `_kalman_rechecks` (stored model, Riccati
    residual of ``P_ss``, ``K_ss``, stability, rank). Then the estimator
    built by ``ESTIMATOR_BUILDERS[method]`` from the gains (and the spec's
    options) runs through `EstimatorAdapter` in `observer_convergence`: the
    nonlinear plant starts at ``x0 + delta``, the estimate at ``x0``, no
    noise; the horizon comes from the discrete error matrix the builder
    gives (the steady-state Kalman error dynamics at the operating point,
    or the observer's error matrix). Methods without a builder get one
    undecided check.
    """
    method = str(doc["method"])
    builder = ESTIMATOR_BUILDERS.get(method)
    if builder is None:
        return [Check("verification", None, f"no estimator builder for method {method}: the verify "
                                            "stage cannot rebuild it from the artefact")]
    checks: list[Check] = []
    if method == "kalman":
        checks += _guard("riccati_recheck", lambda: _kalman_rechecks(doc, spec))
    if method == "luenberger":
        from tanksynth.spec.options import parse_poles

        def poles() -> list[Check]:
            plant = spec.plant
            L = _matrix(doc, "L", (plant.n, plant.q))
            form = str(_option(doc, spec, "form", "current"))
            err = _luenberger_error_matrix(spec, L, form, _operating_point_gains(doc))
            what = {"current": "(I - L C) Ad", "predictor": "Ad - L C"}.get(form, "F - L C")
            domain = "continuous" if form == "continuous" else "discrete"
            out = [_stability_check(np.linalg.eigvals(err), domain, what)]
            requested = _option(doc, spec, "poles")
            if requested is not None:
                out.insert(0, _pole_check(np.linalg.eigvals(err), parse_poles(requested, "poles"),
                                          what))
            return out

        checks += _guard("poles", poles)
    try:
        est, err, what = builder(doc, spec)
    except (TypeError, AttributeError, KeyError) as exc:
        return checks + [Check("estimator_convergence", None,
                               f"the estimator could not be rebuilt from the artefact ({_one_line(exc)})")]
    except _NUMERIC_ERRORS as exc:
        return checks + [Check("estimator_convergence", False,
                               f"the estimator could not be rebuilt: {_one_line(exc)}")]

    def run() -> list[Check]:
        plant = spec.plant
        x0, u0 = _equilibrium(spec)
        eigs = np.linalg.eigvals(err)
        ts = float(spec.ts)
        tau, rule = _observer_tau(eigs, "discrete", ts)
        if method == "luenberger" and _option(doc, spec, "poles") is not None:
            form = str(_option(doc, spec, "form", "current"))
            tau, rule = _designed_tau(doc, spec, eigs, "continuous" if form == "continuous"
                                      else "discrete", ts)
        out = [observer_convergence(plant, est, x0, u0, tau, ts, conditioning=_conditioning(err),
                                    rule=f"{rule}; {what}", name="estimator_convergence")]
        if method in _COVARIANCE_METHODS and out[0].passed is not None:
            out += _guard("covariance", lambda: [_covariance_check(est)])
        return out

    return checks + _guard("estimator_convergence", run)


def _estimator_verdict_for(method: str) -> VerdictFn:
    def verdict(doc: Mapping[str, Any], spec: Any) -> list[Check]:
        if str(doc["method"]) != method:
            raise ArtefactError(f"artefact '{doc['name']}' is a {doc['method']!r} artefact, not {method!r}")
        return estimator_verdict(doc, spec)

    verdict.__name__ = verdict.__qualname__ = f"{method}_verdict"
    verdict.__doc__ = f"Verdict of ``{method}`` artefacts (see `estimator_verdict`)."
    return verdict


kalman_verdict = _estimator_verdict_for("kalman")
ekf_verdict = _estimator_verdict_for("ekf")
ukf_verdict = _estimator_verdict_for("ukf")
adaptive_kalman_verdict = _estimator_verdict_for("adaptive_kalman")
adaptive_scaling_kalman_verdict = _estimator_verdict_for("adaptive_scaling_kalman")
consensus_filter_verdict = _estimator_verdict_for("consensus_filter")
luenberger_verdict = _estimator_verdict_for("luenberger")
