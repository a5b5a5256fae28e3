"""Verdict of ``ts_observer`` (Takagi-Sugeno observer LMI)."""

from __future__ import annotations

from typing import Any, Mapping

import casadi as ca
import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.analysis.linearize import discretize_zoh, linearize
from tanksynth.analysis.rank import observability_rank
from tanksynth.analysis.takagi_sugeno import Domain, PremiseBounds, TSModel, quasi_lpv, ts_model
from tanksynth.errors import TanksynthError
from tanksynth.plants.base import Plant
from tanksynth.spec import Spec
from tanksynth.verify.batch_call import BatchCall
from tanksynth.verify.common import (MODEL_TOLERANCE, artefact_matrix, complex_list, fmt, guard,
                                     operating_point, option, rank_check, relative_difference,
                                     stability_check)
from tanksynth.verify.numerics import observer_lmi_recheck
from tanksynth.verify.simulations import (eigen_time_constant, eigenvector_conditioning,
                                          observer_convergence, observer_period)
from tanksynth.verify.traces import TraceRecorder

__all__ = ["TSObserver", "recorded_ts_parts", "ts_observer_verdict"]


class TSObserver:
    """Multiple observer of seed 001 eq. (20), continuous time (a `BatchEstimator`).

    Same observer as `tanksynth.runtime.estimators.luenberger.TSMultiObserver`,
    integrated differently: that one uses explicit RK4, which is unstable for
    stiff LMI gains (an error eigenvalue near -1.3e5 1/s is met in practice)
    unless the step is below ``2.8 / |lambda|``; the exponential rule here is
    exact on the linear part at any step.

    ``dx_hat/dt = sum_i mu_i(x_hat) (A_i x_hat + B u) + d + L (y - C x_hat)``
    (the TS model `TSModel.rhs` at the estimate, premises unmeasured),
    integrated by the exponential Euler rule on the split ``(A0 - L C) x_hat
    + g(x_hat, u, y)``: exact for the (possibly very stiff) linear part,
    first order in the Lipschitz remainder; the measurement is held over
    each period.

    Parameters
    ----------
    model : tanksynth.analysis.takagi_sugeno.TSModel
    L : ndarray, shape (n, q)
    ts : float
        Sampling period (s).
    substeps : int
        Exponential-Euler steps per period.

    Notes
    -----
    A ``model`` with a ``casadi_rhs`` attribute (a CasADi function ``f(x, u)``, e.g. the plant's
    compiled vector field) has each period (all substeps of every run) evaluated as one compiled
    call of the same rule instead of ``substeps`` numpy evaluations.
    """

    def __init__(self, model: Any, L: np.ndarray, ts: float, substeps: int = 8):
        self.model = model
        self.L = np.asarray(L, dtype=float)
        self.A0 = np.asarray(model.A0, dtype=float)
        self.C = np.asarray(model.C, dtype=float)
        self.substeps = int(substeps)
        n = self.A0.shape[0]
        self._phi, self._gamma = discretize_zoh(self.A0 - self.L @ self.C, np.eye(n),
                                                float(ts) / self.substeps)
        self._x: np.ndarray = np.empty((0, n))    # set by reset
        self._y: np.ndarray | None = None
        f = getattr(model, "casadi_rhs", None)
        self._period = None if f is None else self._compiled_period(f)
        self._maps: dict = {}

    def _compiled_period(self, f: Any) -> Any:
        """``x_next = period(x_hat, u, y_prev)``: the substeps of `step` as one CasADi function."""
        n, m, q = self.A0.shape[0], f.size1_in(1), self.C.shape[0]
        xh, u, y0 = ca.SX.sym("x_hat", n), ca.SX.sym("u", m), ca.SX.sym("y_prev", q)
        A0, L, phi, gam = (ca.DM(v) for v in (self.A0, self.L, self._phi, self._gamma))
        x = xh
        for _ in range(self.substeps):
            g = f(x, u) - A0 @ x + L @ y0
            x = phi @ x + gam @ g
        return ca.Function("ts_observer_period", [xh, u, y0], [x], ["x_hat", "u", "y_prev"], ["x_hat_next"])

    def reset(self, x_hat0: np.ndarray) -> None:
        """Initial estimates (M, n).

        Parameters
        ----------
        x_hat0 : ndarray, shape (M, n)
            Initial estimates (state units, m).
        """
        self._x = np.asarray(x_hat0, dtype=float).copy()
        self._y = None

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Measurement (M, q), previous input (M, m) -> estimate (M, n).

        Parameters
        ----------
        y, u : ndarray (M, q), ndarray (M, m)
            Measurements (output units, m) and previous inputs (input units, m^3/s).
        """
        if self._y is not None and self._period is not None:
            M = self._x.shape[0]
            fn = self._maps.get(M)
            if fn is None:
                fn = self._maps[M] = BatchCall(self._period, M)
            x = fn(self._x, u, self._y.reshape(M, -1))
        elif self._y is not None:
            x = self._x
            for _ in range(self.substeps):
                g = self.model.rhs(x, u) - x @ self.A0.T + self._y @ self.L.T
                x = x @ self._phi.T + g @ self._gamma.T
        if self._y is not None:
            if not np.all(np.isfinite(x)):
                raise TanksynthError("the TS observer diverged: its estimate became non-finite "
                                     "(a premise denominator w . x_hat reached 0), so it does not "
                                     "converge on the plant from this start")
            self._x = x
        self._y = np.array(y, dtype=float)
        return self._x


def recorded_ts_parts(plant: Plant, record: Mapping[str, Any]
                      ) -> tuple[np.ndarray, Domain, PremiseBounds]:
    """The premise weights, domain and premise bounds a ``ts_observer`` design recorded.

    Parameters
    ----------
    plant : Plant
        The spec's plant (its state names and count).
    record : mapping
        ``diagnostics.ts_model``: ``premises[*].weights``, ``domain`` (``lower``, ``upper``,
        ``inequalities`` ``G x <= g``; state units) and ``bounds`` (``lower``, ``upper`` of the
        premises).

    Returns
    -------
    weights : ndarray, shape (k, n)
        One row per premise.
    domain : Domain
        The TS model's domain.
    bounds : PremiseBounds
        The recorded premise bounds (used as found and as given).

    Raises
    ------
    KeyError, TypeError, ValueError
        The record lacks a part or holds a malformed one.
    """
    W = np.array([p["weights"] for p in record["premises"]], dtype=float)
    dom, bounds = record["domain"], record["bounds"]
    ineq = dom.get("inequalities") or []
    G = np.array([r["G"] for r in ineq], dtype=float).reshape(len(ineq), plant.n)
    g = np.array([r["g"] for r in ineq], dtype=float)
    domain = Domain(np.array(dom["lower"], float), np.array(dom["upper"], float), G, g,
                    tuple(s.name for s in plant.states), str(dom.get("description", "")))
    lower, upper = np.array(bounds["lower"], float), np.array(bounds["upper"], float)
    pb = PremiseBounds(lower, upper, str(bounds.get("method", "recorded")),
                       float(bounds.get("margin", 0.0)), lower, upper, {})
    return W, domain, pb


def _ts_model_from_artefact(doc: Mapping[str, Any], spec: Spec) -> tuple[TSModel | None, list[Check]]:
    """Rebuild the TS multiple model from the plant and the recorded premises/bounds/domain."""
    plant = spec.plant
    diag = doc.get("diagnostics") or {}
    rec = diag.get("ts_model") if isinstance(diag, Mapping) else None
    missing = []
    if not isinstance(rec, Mapping):
        missing.append("diagnostics.ts_model")
        rec = {}
    prem = rec.get("premises")
    bounds = rec.get("bounds")
    dom = rec.get("domain")
    if not (isinstance(prem, list) and prem and all(isinstance(p, Mapping) and "weights" in p
                                                    for p in prem)):
        missing.append("ts_model.premises[*].weights")
    if not (isinstance(bounds, Mapping) and "lower" in bounds and "upper" in bounds):
        missing.append("ts_model.bounds.lower/upper")
    if not (isinstance(dom, Mapping) and "lower" in dom and "upper" in dom):
        missing.append("ts_model.domain.lower/upper")
    if missing:
        return None, [Check("ts_model_rebuilt", None,
                            "cannot rebuild the TS observer (eq. 20): the artefact's diagnostics lack "
                            + ", ".join(missing))]
    premises: list[Mapping[str, Any]] = prem if isinstance(prem, list) else []
    W, domain, pb = recorded_ts_parts(plant, rec)
    qlpv = quasi_lpv(plant, W)
    atoms_rec = [str(p.get("atom")) for p in premises]
    atoms_new = [str(a) for a in qlpv.atoms]
    inc_rec = np.array([p.get("incidence", [np.nan] * plant.n) for p in premises], dtype=float).T
    same = atoms_rec == atoms_new and inc_rec.shape == qlpv.incidence.shape and \
        bool(np.allclose(inc_rec, qlpv.incidence, rtol=0, atol=1e-12))
    lower, upper = pb.lower, pb.upper
    model = ts_model(qlpv, domain, bounds=pb)
    checks = [Check("ts_model_rebuilt", bool(same),
                    f"premises re-derived from the plant with the recorded weights {W.tolist()}: atoms "
                    + ("and incidence agree with the record" if same else
                       f"{atoms_new} differ from the record {atoms_rec}")
                    + f"; recorded premise bounds {fmt(lower)} .. {fmt(upper)} and domain "
                      f"({domain.description or 'box'}) used for the observer (its TS model at the estimate)",
                    {"weights": W.tolist(), "atoms": atoms_new})]
    return model, checks


def _local_error_check(spec: Spec, L: np.ndarray, C: np.ndarray) -> Check:
    """``eig(F(x_op) - L C)``: the observer error dynamics linearised at the operating point."""
    x0, u0 = operating_point(spec)
    F = linearize(spec.plant, x0, u0).F
    eig = np.linalg.eigvals(F - L @ C)
    worst = float(np.max(eig.real))
    return Check("local_error_dynamics", bool(worst < 0),
                 f"eigenvalues of F(x_op) - L C (F the Jacobian of the nonlinear plant at the operating "
                 f"point: the error dynamics of the TS observer for small errors there, whatever A0 and psi) "
                 f"{fmt(np.sort_complex(eig), 5)}: largest real part {worst:.4g} 1/s (must be < 0, a "
                 "necessary condition for convergence)",
                 {"eigenvalues": complex_list(eig), "max_real_part": worst})


def ts_observer_verdict(doc: Mapping[str, Any], spec: Spec, *,
                        trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``ts_observer`` artefact (seed 001).

    Checks: ``ts_model_rebuilt`` (premises re-derived, recorded bounds),
    ``model_recheck`` (stored ``A0``, ``B``, ``C`` vs the rebuilt multiple
    model), ``lmi_recheck`` (LMI 28 by `observer_lmi_recheck` from the
    stored ``P``, ``Q``, ``L`` and ``psi``), ``stability`` of ``A0 - L C``,
    ``local_error_dynamics`` (``F(x_op) - L C`` with the plant's Jacobian:
    the LMI certifies ``A0 - L C`` plus a Lipschitz bound, which need not
    hold), ``rank_observability`` of ``(A0, C)`` and of every vertex, and
    ``observer_convergence`` of the multiple observer (20) on the nonlinear
    plant, and ``observer_declared_start`` (the same run from the spec's
    ``x_start`` and ``x_hat_start``) when both are given.

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    plant = spec.plant
    n, q, m = plant.n, plant.q, plant.m
    L = artefact_matrix(doc, "L", (n, q))
    P = artefact_matrix(doc, "P", (n, n))
    Q = artefact_matrix(doc, "Q", (n, n))
    A0 = artefact_matrix(doc, "A0", (n, n))
    C = artefact_matrix(doc, "C", (q, n))
    B = artefact_matrix(doc, "B0", (n, m))
    eigs = np.linalg.eigvals(A0 - L @ C)
    what = "A0 - L C"
    checks: list[Check] = []
    model, rebuilt = _ts_model_from_artefact(doc, spec)
    checks += rebuilt
    if model is not None:
        diffs = {"A0": relative_difference(A0, model.A0), "B0": relative_difference(B, model.B),
                 "C": relative_difference(C, model.C)}
        worst = max(diffs.values())
        checks.append(Check("model_recheck", bool(worst <= MODEL_TOLERANCE),
                            f"stored A0, B0, C against the multiple model rebuilt from the plant "
                            f"(mean of the {model.r} vertices): largest relative difference "
                            f"{worst:.3g} (tolerance {MODEL_TOLERANCE:g})", diffs))
    diag = doc.get("diagnostics") or {}
    lmi = diag.get("lmi") if isinstance(diag, Mapping) else None
    psi_spec = option(doc, spec, "psi")
    psi_source = option(doc, spec, "psi_source", "given" if psi_spec is not None else "maximise")
    psi_rec = lmi.get("psi") if isinstance(lmi, Mapping) else None
    if psi_source == "given" and psi_spec is not None:
        psi, origin = float(psi_spec), "given in the spec"
    elif isinstance(psi_rec, (int, float)):
        psi, origin = float(psi_rec), f"{psi_source} (value from the diagnostics, re-checked here)"
    else:
        psi, origin = None, ""
    if psi is None:
        checks.append(Check("lmi_recheck", None, "psi is neither given in the spec nor recorded in "
                                                 "diagnostics.lmi.psi: the observer LMI cannot be re-checked"))
    else:
        margin = float(option(doc, spec, "margin", 1e-6))
        omega = float(np.linalg.norm(A0, 2)) or (psi if psi > 0 else 1.0)
        rc = observer_lmi_recheck(A0, C, L, P, Q, psi, margin=margin, omega=omega)
        checks.append(Check("lmi_recheck", rc.passed,
                            f"observer LMI [[G' P + P G + psi^2 Q, P], [P, -Q]] < 0 with G = A0 - L C "
                            f"(K = P L) recomputed in numpy from the stored P, Q and L with psi = "
                            f"{psi:.6g} 1/s ({origin}), margin {margin:g}, time scale |A0|_2 = "
                            f"{omega:.4g} 1/s: " + "; ".join(
                                f"{c.name}: {c.value:.4g} vs {c.limit:.4g} "
                                f"{'ok' if c.passed else 'FAILS'}" for c in rc.items),
                            {"items": [c.as_dict() for c in rc.items], "psi": psi,
                             "lmi_eigenvalues": rc.lmi_eigenvalues.tolist()}))
    checks.append(stability_check(eigs, "continuous", what))
    checks += guard("local_error_dynamics", lambda: [_local_error_check(spec, L, C)])
    checks.append(rank_check("rank_observability", observability_rank(A0, C), "(A0, C)"))
    if model is not None and model.enumerated and model.A is not None:
        ranks = [observability_rank(Ai, C) for Ai in model.A]
        bad = [i + 1 for i, r in enumerate(ranks) if not r.full]
        checks.append(Check("rank_observability_vertices", not bad,
                            f"(A_i, C) observable for {len(ranks) - len(bad)} of {len(ranks)} rebuilt "
                            "vertices" + (f"; not for vertices {bad} (Table I order)" if bad else ""),
                            {"ranks": [r.rank for r in ranks]}))

    def sim() -> list[Check]:
        if model is None:
            return [Check("observer_convergence", None, "the TS observer (20) cannot be rebuilt: see "
                                                        "ts_model_rebuilt")]
        if psi is not None and psi > 0:
            tau = 1.0 / psi
            rule = (f"(= 1 / psi: the observer LMI puts every eigenvalue of A0 - L C left of -psi = "
                    f"{-psi:.4g} 1/s, the decay the design claims)")
        else:
            tau, rule = eigen_time_constant(eigs, "continuous", None)
            rule = rule.replace("(", "(of the stored A0 - L C: ", 1)
        if not np.isfinite(tau):
            return [Check("observer_convergence", False, "A0 - L C is not stable")]
        # The exponential rule is exact on the (possibly stiff) linear part: the period only
        # has to resolve the designed decay.
        ts_sim = observer_period("continuous", spec.ts, tau)
        x0, u0 = operating_point(spec)
        kappa = eigenvector_conditioning(A0 - L @ C)
        rebuilt_model = model

        def run(name: str, start: tuple[np.ndarray, np.ndarray] | None) -> Check:
            return observer_convergence(plant, TSObserver(rebuilt_model, L, ts_sim), x0, u0, tau,
                                        ts_sim, conditioning=kappa,
                                        inside=lambda x: bool(rebuilt_model.domain.contains(x)[0]),
                                        outside=lambda X: ~rebuilt_model.domain.contains(X),
                                        rule=f"{rule}; multiple observer (20) with the premises "
                                             "evaluated at the estimate",
                                        trace=trace, name=name, start=start)

        out = [run("observer_convergence", None)]
        x_start, x_hat_start = option(doc, spec, "x_start"), option(doc, spec, "x_hat_start")
        if x_start is not None and x_hat_start is not None:
            out.append(run("observer_declared_start",
                           (np.asarray(x_start, dtype=float), np.asarray(x_hat_start, dtype=float))))
        return out

    return checks + guard("observer_convergence", sim)
