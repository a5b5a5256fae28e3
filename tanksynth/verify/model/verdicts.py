"""Verdict of ``linearize``: the model artefact re-derived and compared with the nonlinear plant.

``linearize``
    * ``jacobian_recheck``: F, B, C recomputed at (x0, u0) from the model;
    * ``zoh_consistency``: Ad, Bd equal the exact ZOH of (F, B) at ts;
    * ``equilibrium``: ``|f(x0, u0)|`` within the design's tolerance (an
      artefact designed away from an equilibrium fails it), naming the
      unbalanced equation; and u0 within the actuator range;
    * ``first_order_agreement``: the nonlinear plant and the discrete
      linear model, started from perturbations eps (dx0, du) of (x0, u0)
      for eps = e0, e0/2, e0/4, agree to first order: the relative error
      of the linear prediction shrinks at least like eps (a Taylor model
      has an O(eps) relative error);
    * ``rank_controllability``, ``rank_observability`` (continuous and
      discrete): Kalman ranks recomputed from the artefact's matrices,
      compared with the design's record.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.analysis.linearize import discretize_zoh, linearize
from tanksynth.analysis.rank import controllability_rank, observability_rank
from tanksynth.errors import ArtefactError
from tanksynth.sim.simulate import run_seeds, simulate
from tanksynth.plants.base import Plant
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, relative_difference
from tanksynth.verify.traces import TraceRecorder

__all__ = ["first_order_agreement", "linearize_verdict"]


def first_order_agreement(plant: Plant, F: np.ndarray, B: np.ndarray, Ad: np.ndarray, Bd: np.ndarray,
                          x0: np.ndarray, u0: np.ndarray, ts: float, *, horizon: int = 20,
                          eps0: float = 5e-3, substeps: int = 10,
                          trace: TraceRecorder | None = None) -> dict[str, Any]:
    """Compare the nonlinear plant with its discrete linear model near (x0, u0).

    From ``x0 + eps dx`` with input ``u0 + eps du`` (``dx``, ``du`` fixed
    directions scaled by the region span and the input range), the
    nonlinear deviation from the unperturbed trajectory is compared with
    ``Ad^k dx + sum Ad^j Bd du`` over ``horizon`` samples, for ``eps =
    eps0, eps0/2, eps0/4``.

    Parameters
    ----------
    plant, F, B : Plant, ndarray (n, n), ndarray (n, m)
        The plant; continuous Jacobians [1/s] and (state units per input unit and s).
    Ad, Bd, x0, u0 : ndarray
        ZOH matrices, operating point (state units, m) and equilibrium input (input units, m^3/s).
    ts, horizon, eps0, substeps : float, int, float, int
        Sampling period [s], samples compared, largest perturbation (fraction of the span), RK4 steps.
    trace : TraceRecorder, optional
        Recorder of the simulated runs.

    Returns
    -------
    dict
        ``eps``, ``relative_errors`` (max over samples of the error norm
        over the max linear deviation norm), ``orders`` (``log2`` of
        successive error ratios: 1 for a correct Taylor model) and the
        directions used.
    """
    n, m = plant.n, plant.m
    span = np.array([hi - lo for lo, hi in plant.region.bounds], dtype=float)
    span = np.where(np.isfinite(span) & (span > 0), span, np.maximum(np.abs(x0), 1.0))
    lim = plant.input_limits
    urange = np.where(np.all(np.isfinite(lim), axis=1), lim[:, 1] - lim[:, 0], np.maximum(np.abs(u0), 1.0))
    # Fixed directions, alternating signs, unequal sizes (no symmetry hides an error).
    dx = span * np.array([(1.0 if i % 2 == 0 else -0.7) * (1 - 0.1 * i) for i in range(n)])
    du = urange * np.array([(0.5 if j % 2 == 0 else -0.35) for j in range(m)])
    eps_list = [eps0, eps0 / 2, eps0 / 4]
    starts = [x0] + [x0 + e * dx for e in eps_list]
    inputs = [u0] + [u0 + e * du for e in eps_list]
    X = np.array(starts)
    seeds = run_seeds(0, len(starts))
    # One batch: the unperturbed run and the three perturbed ones, open loop.
    res = simulate(plant, ts=ts, steps=horizon, x0=X, seeds=seeds, u_init=np.array(inputs),
                   substeps=substeps)
    if trace is not None:
        trace.record(res, plant, check="first_order_agreement",
                     scenario=f"open loop from (x0, u0) and from (x0 + eps dx, u0 + eps du), "
                              f"eps = {eps0:g} (first-order agreement with the linear model)")
    base = res.x[0]
    errors = []
    for i, e in enumerate(eps_list, start=1):
        d_nl = res.x[i] - base
        d_lin = np.empty_like(d_nl)
        z = e * dx
        for k in range(horizon + 1):
            d_lin[k] = z
            z = Ad @ z + Bd @ (e * du)
        scale = float(np.max(np.linalg.norm(d_lin, axis=1)))
        errors.append(float(np.max(np.linalg.norm(d_nl - d_lin, axis=1)) / max(scale, 1e-300)))
    orders = [float(np.log2(errors[i] / errors[i + 1])) if errors[i + 1] > 0 and errors[i] > 0
              else float("inf") for i in range(len(errors) - 1)]
    return {"eps": eps_list, "relative_errors": errors, "orders": orders, "horizon": horizon,
            "ts": ts, "dx": dx.tolist(), "du": du.tolist(), "clipped": res.clipped_low + res.clipped_high}



def linearize_verdict(doc: Mapping[str, Any], spec: Spec, *,
                      trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``linearize`` artefact (see the module docstring).

    Parameters
    ----------
    doc : mapping
        The artefact (gains as arrays).
    spec : tanksynth.spec.Spec
        The spec it was designed from (its plant).
    trace : TraceRecorder, optional
        Records the first-order agreement simulation.
    """
    plant = spec.plant
    F, B, C = (np.atleast_2d(artefact_gain(doc, k)) for k in ("F", "B", "C"))
    Ad, Bd = np.atleast_2d(artefact_gain(doc, "Ad")), np.atleast_2d(artefact_gain(doc, "Bd"))
    x0, u0 = artefact_gain(doc, "x_op"), artefact_gain(doc, "u_op")
    F, B, Ad, Bd = F.reshape(plant.n, plant.n), B.reshape(plant.n, plant.m), Ad.reshape(plant.n, plant.n), \
        Bd.reshape(plant.n, plant.m)
    C = C.reshape(plant.q, plant.n)
    diag = doc.get("diagnostics") or {}
    ts = diag.get("ts", spec.ts)
    if not isinstance(ts, (int, float)) or not ts > 0:
        raise ArtefactError(f"artefact '{doc['name']}': no sampling period in its diagnostics")
    ts = float(ts)
    checks = []
    lin = linearize(plant, x0, u0, ts=ts)
    worst = max(relative_difference(F, lin.F), relative_difference(B, lin.B), relative_difference(C, lin.C))
    checks.append(Check("jacobian_recheck", worst <= 1e-9,
                        f"F, B, C recomputed from the model at (x0, u0): largest relative difference "
                        f"{worst:.3g} (tolerance 1e-9)", {"relative_difference": worst}))
    Ad2, Bd2 = discretize_zoh(F, B, ts)
    zoh = max(relative_difference(Ad, Ad2), relative_difference(Bd, Bd2))
    checks.append(Check("zoh_consistency", zoh <= 1e-9,
                        f"Ad, Bd against the exact ZOH of (F, B) at ts = {ts:g} s: relative difference "
                        f"{zoh:.3g} (tolerance 1e-9)", {"relative_difference": zoh}))
    residual = plant.compiled.rhs(x0[None], u0[None])[0]
    eq = diag.get("equilibrium") or {}
    tol = float(eq.get("tolerance", 1e-12)) if isinstance(eq, Mapping) else 1e-12
    worst_res = float(np.max(np.abs(residual)))
    i = int(np.argmax(np.abs(residual)))
    st = plant.states[i]
    lim = plant.input_limits
    inside = [bool(lo - 1e-12 <= v <= hi + 1e-12) for v, (lo, hi) in zip(u0, lim)]
    balanced = worst_res <= tol
    detail = (f"max |f(x0, u0)| = {worst_res:.3g} {st.unit}/s (tolerance {tol:.3g})"
              + ("" if balanced else f"; unbalanced equation: d{st.name}/dt = {residual[i]:.3g} "
                                     f"{st.unit}/s")
              + "; u0 " + ", ".join(f"{q.name} = {v:.4g} {q.unit} "
                                    + ("in" if ok else "OUTSIDE") + f" [{lo:g}, {hi:g}]"
                                    for q, v, (lo, hi), ok in zip(plant.inputs, u0, lim, inside)))
    checks.append(Check("equilibrium", bool(balanced and all(inside)), detail,
                        {"residual": residual.tolist(), "tolerance": tol,
                         "unbalanced_state": None if balanced else st.name,
                         "u0_within_bounds": bool(all(inside))}))
    agreement = first_order_agreement(plant, F, B, Ad, Bd, x0, u0, ts, trace=trace)
    errs, orders = agreement["relative_errors"], agreement["orders"]
    exact = errs[-1] <= 1e-7  # a linear plant: agreement to rounding
    ok = exact or (all(o >= 0.7 for o in orders) and errs[-1] <= 0.2)
    checks.append(Check(
        "first_order_agreement", bool(ok),
        f"relative error of the linear model over {agreement['horizon']} samples for eps = "
        + ", ".join(f"{e:g}" for e in agreement["eps"]) + ": "
        + ", ".join(f"{e:.3g}" for e in errs)
        + ("" if exact else "; observed orders " + ", ".join(f"{o:.2f}" for o in orders)
           + " (>= 0.7 required: the error must shrink with eps)"),
        agreement))
    rank = diag.get("rank") or {}
    for key, result in (("controllability", controllability_rank(F, B)),
                        ("observability", observability_rank(F, C)),
                        ("controllability_discrete", controllability_rank(Ad, Bd)),
                        ("observability_discrete", observability_rank(Ad, C))):
        recorded = rank.get(key, {}).get("full") if isinstance(rank.get(key), Mapping) else None
        agrees = recorded is None or bool(recorded) == result.full
        detail = (f"rank {result.rank}/{result.n} recomputed from the artefact's matrices, condition "
                  f"number {result.condition_number:.3g}"
                  + ("" if recorded is None else ("; agrees with the design's record" if agrees
                                                  else f"; the design recorded full = {recorded}")))
        checks.append(Check(f"rank_{key}", bool(result.full and agrees), detail,
                            {**result.as_dict(), "recorded_full": recorded}))
    return checks
