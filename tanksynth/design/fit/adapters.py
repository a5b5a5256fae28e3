"""Design adapter of the ``fit`` family: ``fit`` (grey-box estimation from logged data).

The estimation itself is `tanksynth.design.fit.estimation.fit_parameters` (CasADi + IPOPT,
multiple shooting, multi-start); this adapter reads the data files the design names, runs it,
refuses a fit that did not converge (`InfeasibleDesign`, exit 3, naming IPOPT's status), warns
(`DesignWarning`) of a parameter at a bound, of a rank-deficient information matrix and of
residuals that are not white (the intervals are then the autocorrelation-consistent ones,
recorded with the white-noise ones under ``uncertainty``), scores
the validation files and records what the verdict re-derives: the fitted values and initial
states, and each data file's sha256 and the name of its copy in the result directory
(``data/<file>``; the design writer copies them beside the artefact,
`tanksynth.artefacts.datafiles`).
"""

from __future__ import annotations

import hashlib
import warnings
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.design.result import DesignMethod, DesignResult, options_of
from tanksynth.errors import DesignWarning, InfeasibleDesign, SpecError
from tanksynth.measurements.scores import pooled_scores
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.context import resolve
from tanksynth.spec.memory import refuse_oversized_fit
from tanksynth.spec.method_options.fit import FitOptions

__all__ = ["run_fit", "FIT", "copy_names", "free_parameters_of"]


def free_parameters_of(spec: Spec) -> tuple[Any, ...]:
    """The spec's free parameters (``Spec.free_parameters``); `SpecError` (exit 2) when there is
    none, saying how to mark one.

    Parameters
    ----------
    spec : Spec
        The validated spec.

    Returns
    -------
    tuple of FreeParameter
    """
    free = tuple(getattr(spec, "free_parameters", ()) or ())
    if not free:
        names = [p.name for p in spec.plant.parameters]
        example = names[0] if names else "p"
        raise SpecError("the plant has no free parameter to fit: mark one in [plant.parameters] as "
                        f"{example} = {{value = <start>, min = <lower>, max = <upper>, fit = true}}",
                        key="plant.parameters", source=spec.source)
    return free


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def copy_names(paths: Sequence[str]) -> list[str]:
    """The names of the copies of data files in a result directory, ``data/<file name>``
    (``data/<stem>-2<suffix>`` for a second file of the same name).

    Parameters
    ----------
    paths : sequence of str
        The files, as given.

    Returns
    -------
    list of str
        One relative path per file, in order, all different.
    """
    out: list[str] = []
    for p in paths:
        base = Path(p)
        name, k = f"data/{base.name}", 1
        while name in out:
            k += 1
            name = f"data/{base.stem}-{k}{base.suffix}"
        out.append(name)
    return out


def _outputs(plant: Any, experiment: Any, y_hat: np.ndarray) -> np.ndarray:
    """The simulated outputs of the experiment's logged columns."""
    y_hat = np.asarray(y_hat, dtype=float)
    p = len(experiment.output_names)
    if y_hat.shape[1] == p:
        return y_hat
    names = [s.name for s in plant.outputs]
    return y_hat[:, [names.index(nm) for nm in experiment.output_names]]


def _by_output(names: Sequence[str], values: np.ndarray) -> dict[str, float]:
    return {str(nm): float(v) for nm, v in zip(names, np.asarray(values, dtype=float).reshape(-1))}


def _plain(value: Any) -> Any:
    """A result attribute as JSON-friendly data (dataclasses and arrays unpacked)."""
    import dataclasses

    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def run_fit(spec: Spec, design: DesignSpec) -> DesignResult:
    """Fit the spec's free parameters and each experiment's initial state to the data files.

    Gains: ``theta`` (k, the fitted values in the parameters' units, spec order),
    ``covariance`` (k x k, from the Fisher information) and ``x0`` (E x n, the fitted initial
    state of each estimation experiment, state units).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant with the free parameters marked, ``[data]`` table).
    design : DesignSpec
        This ``[[design]]`` entry: the data files (relative to the spec file, or absolute).

    Returns
    -------
    DesignResult

    Raises
    ------
    SpecError
        No free parameter, no data file, bad data (`DataError`, naming file, column and row).
    InfeasibleDesign
        The fit did not converge (IPOPT's status named), or ran out of its time (``max_time``).
    DesignTooLarge
        The data would need more memory than the budget (`tanksynth.spec.memory.fit_bytes`).
    """
    from tanksynth.design.fit.estimation import fit_parameters
    from tanksynth.design.fit.validation import simulate_outputs, validate_experiment
    from tanksynth.measurements import read_experiments

    o = options_of(design, spec, FitOptions)
    free = free_parameters_of(spec)
    plant = spec.plant
    if not o.data:
        raise SpecError("no estimation data: give data = [\"file.csv\", ...] (relative to the spec "
                        "file) or run tanksynth fit SPEC --data FILE...", key=f"{design.key}.data")
    base = Path(spec.source).parent if spec.source and not spec.source.startswith("<") else None
    est_paths = [resolve(p, base) for p in o.data]
    val_paths = [resolve(p, base) for p in o.validate]
    table = getattr(spec, "data", None)
    estimation = read_experiments([str(p) for p in est_paths], plant, table)
    validation = read_experiments([str(p) for p in val_paths], plant, table) if val_paths else ()
    # refused before the NLP is built when its memory would exceed the budget
    refuse_oversized_fit(design.name, sum(len(e.t) for e in [*estimation, *validation]),
                         len(plant.states))
    hashes = [_sha256(p) for p in [*est_paths, *val_paths]]
    copies = copy_names([str(p) for p in [*est_paths, *val_paths]])

    result = fit_parameters(plant, free, estimation, starts=o.starts, seed=o.seed, mode=o.mode,
                            shooting=o.shooting, level=o.level, max_iter=o.max_iter,
                            max_time=o.max_time)
    if not result.converged:
        raise InfeasibleDesign(f"the fit did not converge (IPOPT status {result.status!r} after "
                               f"{result.iterations} iterations, {result.starts_tried} start(s)); "
                               "widen the parameter bounds, give better start values or more "
                               "informative data")
    substeps = int(result.substeps)
    names = tuple(str(n) for n in result.names)
    values = np.asarray(result.values, dtype=float)
    fitted = dict(zip(names, map(float, values)))
    plant_fit = plant.with_parameters(fitted)
    stderr = np.asarray(result.stderr, dtype=float)
    ci = np.asarray(result.ci95, dtype=float)
    at_bound = tuple(str(n) for n in result.at_bound)
    for nm in at_bound:
        p = next(f for f in free if f.name == nm)
        warnings.warn(f"fitted {nm} = {fitted[nm]:.6g} lies at a bound of its search box "
                      f"[{p.lower:g}, {p.upper:g}]: the optimum may lie outside; widen min/max",
                      DesignWarning, stacklevel=2)
    if not result.identifiable:
        warnings.warn("the data do not determine every free parameter (the Fisher information "
                      "is rank deficient): " + str(result.unidentifiable_note), DesignWarning,
                      stacklevel=2)

    if result.covariance_method == "hac":
        failed = [f"{nm}, Q = {w.statistic:.4g} > {w.bound:.4g}" for nm, w in result.whiteness.items()
                  if not w.passed]
        warnings.warn(f"residuals not white ({'; '.join(failed)}): the model misses dynamics or "
                      "the noise is coloured; intervals widened by the autocorrelation-consistent "
                      "covariance; they cover noise, not model error: extend the model (see "
                      "examples/three_tank_fit_leak.toml)", DesignWarning, stacklevel=2)
    x0 = np.asarray(result.x0, dtype=float).reshape(len(estimation), plant.n)
    ys, hats, masks, experiments = [], [], [], []
    for e, (exp, path, sha, copy) in enumerate(zip(estimation, est_paths, hashes, copies)):
        y_hat = _outputs(plant, exp, simulate_outputs(plant_fit, fitted, exp, x0[e], substeps=substeps))
        ys.append(exp.y)
        hats.append(y_hat)
        masks.append(exp.observed)
        r1, f1 = pooled_scores([exp.y], [y_hat], [exp.observed])
        experiments.append({"name": exp.name, "file": copy, "source": str(path), "sha256": sha,
                            "samples": exp.samples, "outputs": list(exp.output_names),
                            "rmse": _by_output(exp.output_names, r1),
                            "fit_percent": _by_output(exp.output_names, f1)})
    outputs = list(dict.fromkeys(nm for exp in estimation for nm in exp.output_names))
    est_rmse, est_fit = _pooled(estimation, ys, hats, masks, outputs)

    val_records = []
    val_y, val_hat, val_mask = [], [], []
    for exp, path, sha, copy in zip(validation, val_paths, hashes[len(est_paths):],
                                     copies[len(est_paths):]):
        v = validate_experiment(plant_fit, fitted, exp, init_samples=o.init_samples,
                                substeps=substeps)
        xv = np.asarray(v.x0, dtype=float).reshape(plant.n)
        y_hat = _outputs(plant, exp, simulate_outputs(plant_fit, fitted, exp, xv, substeps=substeps))
        scored = exp.observed.copy()
        scored[:o.init_samples] = False  # the samples x0 was estimated on do not score
        val_y.append(exp.y)
        val_hat.append(y_hat)
        val_mask.append(scored)
        r1, f1 = pooled_scores([exp.y], [y_hat], [scored])
        val_records.append({"name": exp.name, "file": copy, "source": str(path), "sha256": sha,
                            "samples": exp.samples, "outputs": list(exp.output_names),
                            "x0": xv.tolist(), "rmse": _by_output(exp.output_names, r1),
                            "fit_percent": _by_output(exp.output_names, f1)})
    val_outputs = list(dict.fromkeys(nm for exp in validation for nm in exp.output_names))
    val_rmse, val_fit = (_pooled(validation, val_y, val_hat, val_mask, val_outputs)
                         if validation else ({}, {}))

    parameters = {}
    for i, nm in enumerate(names):
        p = next(f for f in free if f.name == nm)
        parameters[nm] = {"value": float(values[i]), "stderr": float(stderr[i]),
                          "ci95": [float(ci[i, 0]), float(ci[i, 1])], "unit": str(p.unit),
                          "start": float(p.start), "lower": float(p.lower), "upper": float(p.upper),
                          "at_bound": nm in at_bound}
    diagnostics = {
        "parameters": parameters,
        "names": list(names),
        "level": float(o.level),
        "mode": o.mode,
        "substeps": substeps,
        "estimation": {"rmse": est_rmse, "fit_percent": est_fit,
                       "whiteness": _plain(result.whiteness), "experiments": experiments,
                       "outputs": outputs},
        "validation": {"rmse": val_rmse, "fit_percent": val_fit, "experiments": val_records,
                       "outputs": val_outputs, "init_samples": int(o.init_samples)},
        "solver": "IPOPT (CasADi nlpsol)",
        "converged": bool(result.converged),
        "status": str(result.status),
        "iterations": int(result.iterations),
        "starts_tried": int(result.starts_tried),
        "cost": float(result.cost),
        "identifiability": {"identifiable": bool(result.identifiable),
                            "note": str(result.unidentifiable_note or "")},
        "correlation": np.asarray(result.correlation, dtype=float).tolist(),
        "uncertainty": {
            "used": str(result.covariance_method),
            "why": str(result.covariance_note),
            "white": {nm: {"stderr": float(result.stderr_white[i]),
                           "ci95": [float(result.ci95_white[i, 0]), float(result.ci95_white[i, 1])]}
                      for i, nm in enumerate(names)},
            "hac": {"stderr": {nm: float(result.stderr_hac[i]) for i, nm in enumerate(names)},
                    "kernel": "Bartlett (Newey-West)",
                    "lags": [int(v) for v in result.hac_lags],
                    "lag_rule": "Andrews AR(1) plug-in, at least floor(4 (N/100)^(2/9)), at most N/4"},
            "interval_method": {nm: str(m) for nm, m in zip(names, result.interval_method)},
        },
        "data_files": [{"file": c, "source": str(p), "sha256": h}
                       for c, p, h in zip(copies, [*est_paths, *val_paths], hashes)],
        "states": [s.name for s in plant.states],
        "output_units": {q.name: str(q.unit) for q in plant.outputs},
    }
    gains = {"theta": values, "covariance": np.asarray(result.covariance, dtype=float),
             "x_init": x0}
    return DesignResult(design.name, "fit", plant.name, gains, diagnostics)


def _pooled(experiments: Sequence[Any], ys: list, hats: list, masks: list,
            outputs: list[str]) -> tuple[dict[str, float], dict[str, float]]:
    """RMSE and fit % per output name over experiments whose logged outputs may differ."""
    rm, fp = {}, {}
    for nm in outputs:
        cols = [(exp.output_names.index(nm), k) for k, exp in enumerate(experiments)
                if nm in exp.output_names]
        r, f = pooled_scores([ys[k][:, [j]] for j, k in cols], [hats[k][:, [j]] for j, k in cols],
                             [masks[k][:, [j]] for j, k in cols])
        rm[nm], fp[nm] = float(r[0]), float(f[0])
    return rm, fp


FIT = DesignMethod("fit", run_fit, FitOptions)
