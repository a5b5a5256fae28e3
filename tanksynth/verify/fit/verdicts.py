"""Verdict of the ``fit`` family: the fitted model re-simulated on the copied data.

The verdict never imports the design code. It reads the data files from the result directory
(``DIR/data/``, each one's sha256 checked against the artefact), simulates the plant with the
artefact's parameter values and initial states with `tanksynth.sim` (the toolbox's one
integrator and clipping rule, the same RK4 substeps as the fit) and checks:

``data_files``
    every copied data file is present and unedited (sha256 as recorded);
``converged``
    IPOPT reported convergence;
``rmse_reproduced``
    the RMSE of every output on the estimation data, re-simulated, equals the recorded one
    (relative tolerance `RMSE_RTOL`): the recorded fit is the model's, on these data;
``parameters_inside_bounds``
    no fitted value lies at a bound of its search box (within `BOUND_TOL` of the box width):
    at a bound the optimum may lie outside the box and the intervals mean nothing;
``parameters_consistent``
    the artefact's report of the parameters is its gains' and its spec's: the parameter names
    and search boxes (start, min, max) are the spec's free parameters, each
    ``parameters.<name>.value`` is the entry of ``theta``, the ``covariance`` gain is finite,
    symmetric and positive semidefinite, each ``stderr`` is the square root of its diagonal
    entry and each ``ci95`` is a finite interval holding the value (a parameter the data do not
    determine: stderr ``"inf"`` and its box as interval) (an edited and rehashed
    ``fit.json`` whose table says one thing and whose gains another fails here);
``residual_whiteness``
    information only (never fails): the Ljung-Box statistic of the residuals' autocorrelation
    (20 lags, pooled over the estimation files) against its chi-square 95 % bound (31.4), the
    same statistic and bound as the fit's diagnostics. An output-error fit stays consistent
    when the noise is coloured, and a lab log always has some unmodelled dynamics (an offset,
    a leak), so correlated residuals are a finding to read, not a refusal;
``validation_fit``
    on each validation file (simulated from the recorded initial state, estimated on its
    first ``init_samples`` samples only, which are left out of the score), the fit % of every
    output is at least the floor
    ``max(0, 100 (1 - 2 rmse_est / s_val))``, ``s_val`` the RMS deviation of the validation
    output from its mean: the validation RMSE is at most twice the estimation RMSE (the model
    predicts new data about as well as it fits the old; twice allows for the short initial-state
    estimate) and in every case the model beats the data's mean; the re-simulated fit % also
    equals the recorded one.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.artefacts.datafiles import read_data_copy
from tanksynth.errors import ArtefactError, TanksynthError
from tanksynth.measurements import read_experiments
from tanksynth.measurements.experiment import Experiment
from tanksynth.measurements.scores import (WHITENESS_LAGS, WHITENESS_LEVEL, fit_percent,
                                            ljung_box, rmse)
from tanksynth.plants.base import Plant
from tanksynth.sim.simulate import simulate_inputs
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain
from tanksynth.verify.traces import Signal

__all__ = ["RMSE_RTOL", "BOUND_TOL", "STDERR_RTOL", "consistency_check", "WHITENESS_LAGS", "fit_verdict", "simulated_outputs",
           "fitted_plant", "whiteness", "validation_floor", "read_fit_data"]

#: Relative tolerance of the re-simulated RMSE against the recorded one.
RMSE_RTOL = 1e-6
#: A fitted value within this fraction of its box width of a bound is at the bound.
BOUND_TOL = 1e-6


#: Relative tolerance of the reported standard errors against the covariance gain's diagonal.
STDERR_RTOL = 1e-9


def consistency_check(doc: Mapping[str, Any], spec: Spec) -> Check:
    """``parameters_consistent``: the reported parameters are the gains' and the spec's.

    Parameters
    ----------
    doc : mapping
        The ``fit`` artefact (gains as arrays).
    spec : Spec
        The validated spec of its result directory (its free parameters and their boxes).

    Returns
    -------
    Check
        Failed, naming every disagreement, when the parameter table, ``theta``, the
        ``covariance`` gain and the spec's free parameters do not agree.
    """
    diag = doc.get("diagnostics") or {}
    found = diag.get("parameters")
    params: Mapping[str, Any] = found if isinstance(found, Mapping) else {}
    theta = artefact_gain(doc, "theta").reshape(-1)
    cov = artefact_gain(doc, "covariance")
    free = {fp.name: fp for fp in spec.free_parameters}
    names = [str(n) for n in diag.get("names") or []]
    bad = []
    if names != list(free):
        bad.append(f"names {names} are not the spec's free parameters {list(free)}")
    if set(params) != set(names):
        bad.append(f"the parameter table names {sorted(params)}, theta holds {names}")
    k = theta.size
    if cov.shape != (k, k) or not np.all(np.isfinite(cov)):
        bad.append(f"covariance is not a finite {k} x {k} matrix")
    else:
        scale = float(np.max(np.abs(cov))) or 1.0
        if not np.allclose(cov, cov.T, rtol=1e-12, atol=1e-15 * scale):
            bad.append("covariance is not symmetric")
        elif float(np.min(np.linalg.eigvalsh(0.5 * (cov + cov.T)))) < -1e-9 * scale:
            bad.append("covariance is not positive semidefinite")
    found = diag.get("uncertainty")
    unc: Mapping[str, Any] = found if isinstance(found, Mapping) else {}
    found = unc.get("interval_method")
    methods: Mapping[str, Any] = found if isinstance(found, Mapping) else {}
    for i, nm in enumerate(names[:k]):
        p = params.get(nm)
        if not isinstance(p, Mapping):
            continue
        if methods.get(nm) == "unidentifiable":
            # the data do not determine it: no standard error, the interval is the whole box
            if p.get("stderr") != "inf" or p.get("ci95") != [p.get("lower"), p.get("upper")]:
                bad.append(f"{nm}: undetermined by the data, but stderr {p.get('stderr')!r} and ci95 "
                           f"{p.get('ci95')!r} are not 'inf' and its box")
            if float(p.get("value", np.nan)) != float(theta[i]):
                bad.append(f"{nm}: value {p.get('value')!r} is not theta[{i}] = {theta[i]!r}")
            continue
        value, fp = p.get("value"), free.get(nm)
        if not isinstance(value, (int, float)) or float(value) != float(theta[i]):
            bad.append(f"{nm}: value {value!r} is not theta[{i}] = {theta[i]!r}")
        if fp is not None and (p.get("start"), p.get("lower"), p.get("upper")) != (fp.start, fp.lower, fp.upper):
            bad.append(f"{nm}: box (start, min, max) = ({p.get('start')}, {p.get('lower')}, {p.get('upper')}) "
                       f"is not the spec's ({fp.start:g}, {fp.lower:g}, {fp.upper:g})")
        se = p.get("stderr")
        if cov.shape == (k, k) and np.isfinite(cov[i, i]) and cov[i, i] >= 0:
            expected = float(np.sqrt(cov[i, i]))
            if not isinstance(se, (int, float)) or not np.isclose(float(se), expected, rtol=STDERR_RTOL,
                                                                  atol=0.0):
                bad.append(f"{nm}: stderr {se!r} is not sqrt(covariance[{i},{i}]) = {expected:.6g}")
        ci = p.get("ci95")
        if not (isinstance(ci, list) and len(ci) == 2 and all(isinstance(v, (int, float)) for v in ci)
                and np.all(np.isfinite(ci)) and float(ci[0]) <= float(theta[i]) <= float(ci[1])):
            bad.append(f"{nm}: ci95 {ci!r} is not a finite interval holding the value")
    return Check("parameters_consistent", not bad,
                 f"the parameter table of {k} parameter(s) is theta's, the covariance gain's (finite, "
                 "symmetric, positive semidefinite, stderr its diagonal's square roots) and the "
                 "spec's boxes" if not bad else "; ".join(bad))


def fitted_plant(doc: Mapping[str, Any], spec: Spec) -> tuple[Plant, dict[str, float]]:
    """The spec's plant with the artefact's fitted parameter values.

    Parameters
    ----------
    doc : mapping
        The ``fit`` artefact.
    spec : Spec
        The validated spec of its result directory.

    Returns
    -------
    plant : Plant
    values : dict of str to float
        Parameter name -> fitted value (the parameter's unit).
    """
    diag = doc.get("diagnostics") or {}
    names = diag.get("names")
    theta = artefact_gain(doc, "theta").reshape(-1)
    if not isinstance(names, list) or len(names) != theta.size:
        raise ArtefactError(f"artefact '{doc['name']}': diagnostics.names does not name the "
                            f"{theta.size} entries of theta")
    values = {str(n): float(v) for n, v in zip(names, theta)}
    return spec.plant.with_parameters(values), values


def simulated_outputs(plant: Plant, experiment: Experiment, x0: np.ndarray,
                      substeps: int) -> np.ndarray:
    """The plant's outputs of the experiment's logged columns, simulated with `tanksynth.sim`
    from ``x0`` under the logged inputs (held between samples).

    Parameters
    ----------
    plant : Plant
        With the fitted values.
    experiment : Experiment
        The logged run.
    x0 : ndarray, shape (n,)
        Initial state at the first sample (state units).
    substeps : int
        RK4 steps per sampling interval (the fit's).

    Returns
    -------
    ndarray, shape (N, p)
        Output units, at the experiment's sample times.
    """
    return _simulation(plant, experiment, x0, substeps)[0]


def _simulation(plant: Plant, experiment: Experiment, x0: np.ndarray,
                substeps: int) -> tuple[np.ndarray, Any]:
    """`simulated_outputs` and the `SimulationResult` behind it (None for non-uniform samples)."""
    names = [s.name for s in plant.outputs]
    cols = [names.index(nm) for nm in experiment.output_names]
    period = experiment.uniform_period
    if period is not None:
        res = simulate_inputs(plant, np.asarray(x0, float), experiment.u[:-1], period,
                              substeps=substeps)
        return np.asarray(res.y)[0][:, cols], res
    out = np.empty((experiment.samples, len(cols)))  # non-uniform sampling: one interval at a time
    x = np.asarray(x0, float)
    for k in range(experiment.samples - 1):
        res = simulate_inputs(plant, x, experiment.u[k:k + 1], float(experiment.t[k + 1] - experiment.t[k]),
                              substeps=substeps)
        out[k] = np.asarray(res.y)[0, 0, cols]
        x = np.asarray(res.x)[0, 1]
    res = simulate_inputs(plant, x, experiment.u[-1:], 1.0, substeps=substeps)
    out[-1] = np.asarray(res.y)[0, 0, cols]
    return out, None


def _record(trace: Any, res: Any, plant: Plant, experiment: Experiment, y_hat: np.ndarray, *,
            check: str, what: str, residuals: bool = False) -> None:
    """Keep a figure's trace: the simulated states and inputs, and per output the measured and
    the simulated values (or the residuals)."""
    if trace is None or res is None:
        return
    units = {q.name: str(q.unit) for q in plant.outputs}
    unit = units.get(experiment.output_names[0], "") if experiment.output_names else ""
    signals = []
    for j, nm in enumerate(experiment.output_names):
        y = np.where(experiment.observed[:, j], experiment.y[:, j], np.nan)
        if residuals:
            signals.append(Signal(f"{nm} residual", unit, (y - y_hat[:, j])[None, :], "-"))
        else:
            signals.append(Signal(f"{nm} measured", unit, y[None, :], "-"))
            signals.append(Signal(f"{nm} simulated", unit, y_hat[:, j][None, :], "--"))
    title = ("residuals, measured minus simulated" if residuals
             else "measured (solid) and simulated (dashed) outputs")
    trace.record(res, plant, scenario=f"{what} '{experiment.name}' re-simulated at the fitted values",
                 check=check, signals=signals, signal_title=title)


def whiteness(residuals: Sequence[np.ndarray], lags: int = WHITENESS_LAGS) -> tuple[float, float, int]:
    """Ljung-Box test of the residuals of one output, one sequence per experiment: the fit's
    own statistic (`tanksynth.measurements.scores.ljung_box`), against the 95 % quantile of
    chi-square with ``lags`` degrees of freedom (white residuals stay below).

    Parameters
    ----------
    residuals : sequence of ndarray, shape (N_e,)
        Residuals in time order per experiment (output units); NaN entries are left out.
    lags : int
        Most lags L (at most N / 4).

    Returns
    -------
    statistic, bound : float
    lags : int
        The lags used (0 when too few samples: statistic and bound NaN).
    """
    _, q, bound, used, _ = ljung_box(residuals, lags, WHITENESS_LEVEL)
    return q, bound, used


def validation_floor(rmse_est: float, y: np.ndarray) -> float:
    """The least validation fit % the verdict accepts for one output (see the module docstring).

    Parameters
    ----------
    rmse_est : float
        The output's RMSE on the estimation data (output units).
    y : ndarray
        The output's validation samples that count (output units).

    Returns
    -------
    float
        Percent, at least 0.
    """
    spread = float(np.sqrt(np.mean((y - y.mean()) ** 2))) if y.size else 0.0
    if not spread > 0 or not np.isfinite(rmse_est):
        return 0.0
    return max(0.0, 100.0 * (1.0 - 2.0 * float(rmse_est) / spread))


def read_fit_data(doc: Mapping[str, Any], spec: Spec, part: str) -> list[tuple[Experiment, dict]]:
    """The experiments of one part (``"estimation"`` or ``"validation"``) of a fit artefact, read
    from the copies in the result directory (sha256 checked), with their records.

    Parameters
    ----------
    doc : mapping
        The ``fit`` artefact.
    spec : Spec
        The spec of its result directory (``spec.source`` is ``DIR/spec.toml``).
    part : str
        ``"estimation"`` or ``"validation"``.

    Returns
    -------
    list of (Experiment, dict)

    Raises
    ------
    ArtefactError
        A copy missing or edited, a malformed record.
    """
    directory = Path(str(spec.source)).parent
    diag = doc.get("diagnostics") or {}
    records = (diag.get(part) or {}).get("experiments") or []
    if not isinstance(records, list):
        raise ArtefactError(f"artefact '{doc['name']}': diagnostics.{part}.experiments is not a list")
    out = []
    for rec in records:
        path = read_data_copy(directory, rec.get("file"), rec.get("sha256"))
        (exp,) = read_experiments([str(path)], spec.plant, getattr(spec, "data", None))
        out.append((exp, rec))
    return out


def _close(a: float, b: float, rtol: float = RMSE_RTOL) -> bool:
    return bool(np.isfinite(a) and np.isfinite(b) and abs(a - b) <= rtol * max(abs(a), abs(b), 1e-300))


def _pooled(pairs: Sequence[tuple[Experiment, np.ndarray]]) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Output name -> (y, y_hat, mask) over the experiments that log it."""
    out: dict[str, list] = {}
    for exp, y_hat in pairs:
        for j, nm in enumerate(exp.output_names):
            out.setdefault(nm, []).append((exp.y[:, j], y_hat[:, j], exp.observed[:, j]))
    return {nm: tuple(np.concatenate([p[i] for p in parts]) for i in range(3))  # type: ignore[misc]
            for nm, parts in out.items()}


def fit_verdict(doc: Mapping[str, Any], spec: Spec, trace: Any = None) -> list[Check]:
    """Verdict of ``fit``: the checks of the module docstring.

    Parameters
    ----------
    doc : mapping
        The artefact (gains as arrays).
    spec : Spec
        The validated spec of its result directory.
    trace : TraceRecorder, optional
        Keeps the figures' simulations: measured and simulated outputs of the first estimation
        and validation files, and the estimation residuals.

    Returns
    -------
    list of Check
    """
    diag = doc.get("diagnostics") or {}
    checks = []
    try:
        est = read_fit_data(doc, spec, "estimation")
        val = read_fit_data(doc, spec, "validation")
    except (ArtefactError, TanksynthError) as exc:
        return [Check("data_files", False, f"the data the fit was made on cannot be read back: {exc}")]
    checks.append(Check("data_files", True, f"{len(est) + len(val)} data file(s) in data/ with the "
                        "recorded sha256"))
    converged = diag.get("converged") is True
    checks.append(Check("converged", converged, f"IPOPT status {diag.get('status')!r}"
                        + ("" if converged else ": the optimum was not reached")))

    checks.append(consistency_check(doc, spec))
    plant, values = fitted_plant(doc, spec)
    substeps = int(diag.get("substeps", 4))
    x0 = artefact_gain(doc, "x_init").reshape(len(est), plant.n) if est else np.zeros((0, plant.n))
    pairs = []
    for e, (exp, _) in enumerate(est):
        y_hat, res = _simulation(plant, exp, x0[e], substeps)
        pairs.append((exp, y_hat))
        if e == 0:
            _record(trace, res, plant, exp, y_hat, check="rmse_reproduced", what="estimation data")
            _record(trace, res, plant, exp, y_hat, check="residual_whiteness", what="estimation data",
                    residuals=True)
    pooled = _pooled(pairs)
    recorded = (diag.get("estimation") or {}).get("rmse") or {}
    rows, bad = {}, []
    for nm, (y, y_hat, mask) in pooled.items():
        value = float(rmse(y[:, None], y_hat[:, None], mask[:, None])[0])
        rec = recorded.get(nm)
        rec = float(rec) if isinstance(rec, (int, float)) else float("nan")
        rows[nm] = {"resimulated": value, "recorded": rec}
        if not _close(value, rec):
            bad.append(f"{nm}: {value:.10g} re-simulated vs {rec:.10g} recorded")
    checks.append(Check("rmse_reproduced", not bad and bool(rows),
                        ("RMSE re-simulated with tanksynth.sim at the fitted values equals the "
                         f"recorded one (rtol {RMSE_RTOL:g}): " + ", ".join(
                             f"{nm} {r['resimulated']:.6g}" for nm, r in rows.items()))
                        if not bad else "re-simulated RMSE differs from the artefact's: " + "; ".join(bad),
                        {"rmse": rows, "rtol": RMSE_RTOL}))

    params = diag.get("parameters") or {}
    at = []
    for nm, v in values.items():
        p = params.get(nm) or {}
        lo, hi = float(p.get("lower", -np.inf)), float(p.get("upper", np.inf))
        tol = BOUND_TOL * (hi - lo) if np.isfinite(hi - lo) else 0.0
        if v <= lo + tol or v >= hi - tol:
            at.append(f"{nm} = {v:.6g} in [{lo:g}, {hi:g}]")
    checks.append(Check("parameters_inside_bounds", not at,
                        "every fitted value inside its search box" if not at else
                        "at a bound (the optimum may lie outside the box; widen min/max): " + "; ".join(at)))

    white = {}
    per_output: dict[str, list[np.ndarray]] = {}
    for exp, y_hat in pairs:
        for j, nm in enumerate(exp.output_names):
            per_output.setdefault(nm, []).append(np.where(exp.observed[:, j], exp.y[:, j] - y_hat[:, j],
                                                          np.nan))
    for nm, series in per_output.items():
        q, bound, lags = whiteness(series)
        white[nm] = {"statistic": q, "bound": bound, "lags": lags, "white": bool(q <= bound)}
    checks.append(Check("residual_whiteness", None,
                        "information (an output-error fit needs no white residuals): " + ", ".join(
                            f"{nm} Q = {w['statistic']:.3g} {'<=' if w['white'] else '>'} {w['bound']:.3g}"
                            + ("" if w["white"] else " (correlated: unmodelled dynamics or coloured noise)")
                            for nm, w in white.items()), {"whiteness": white}))

    if val:
        init = int((diag.get("validation") or {}).get("init_samples", 0))
        bad = []
        rows_v: dict[str, dict[str, Any]] = {}
        for exp, rec in val:
            xv = np.asarray(rec.get("x0"), dtype=float).reshape(plant.n)
            y_hat, res = _simulation(plant, exp, xv, substeps)
            if not rows_v:
                _record(trace, res, plant, exp, y_hat, check="validation_fit", what="validation data")
            scored = exp.observed.copy()
            scored[:init] = False  # the samples its initial state was estimated on do not score
            fp = fit_percent(exp.y, y_hat, scored)
            for j, nm in enumerate(exp.output_names):
                mask = scored[:, j]
                floor = validation_floor(float(recorded.get(nm, np.nan)), exp.y[mask, j])
                given = (rec.get("fit_percent") or {}).get(nm)
                rows_v[f"{exp.name}.{nm}"] = {"fit_percent": float(fp[j]), "floor": floor,
                                              "recorded": given}
                if not fp[j] >= floor:
                    bad.append(f"{exp.name} {nm}: {fp[j]:.2f} % < floor {floor:.2f} %")
                elif not (isinstance(given, (int, float)) and _close(float(fp[j]), float(given), 1e-6)):
                    bad.append(f"{exp.name} {nm}: re-simulated {fp[j]:.6g} % vs recorded {given!r}")
        checks.append(Check("validation_fit", not bad,
                            ("validation fit % at least its floor max(0, 100 (1 - 2 e_est / s_val)), e_est the "
                             "output's RMSE on the estimation data, s_val its RMS deviation from its "
                             "mean on the validation file: "
                             + ", ".join(f"{' '.join(k.rsplit('.', 1))} {r['fit_percent']:.1f} % >= "
                                         f"{r['floor']:.1f} %" for k, r in rows_v.items()))
                            if not bad else "; ".join(bad), {"validation": rows_v}))
    else:
        checks.append(Check("validation_fit", None, "no validation file: the model is not checked "
                            "on data it was not fitted to"))
    return checks
