"""Per-method verdicts on artefacts, and ``tanksynth verify DIR``.

`VERDICTS` maps a design method name to a function ``verdict(doc, spec)
-> list[Check]`` that re-checks one artefact against the plant it was
designed for (rebuilt from ``DIR/spec.toml``), by simulation and by
independent numerics. Methods without a verdict get one explicit check
``"no verification defined for method X"`` with ``passed = None``: not a
pass. Other modules plug their verdicts in with `register_verdict`.

``linearize``
    * ``jacobian_recheck``: F, B, C recomputed at (x0, u0) from the model;
    * ``zoh_consistency``: Ad, Bd equal the exact ZOH of (F, B) at ts;
    * ``equilibrium``: |f(x0, u0)| within the design's tolerance (an
      artefact designed away from an equilibrium fails it);
    * ``first_order_agreement``: the nonlinear plant and the discrete
      linear model, started from perturbations eps (dx0, du) of (x0, u0)
      for eps = e0, e0/2, e0/4, agree to first order: the relative error
      of the linear prediction shrinks at least like eps (a Taylor model
      has an O(eps) relative error);
    * ``rank_controllability``, ``rank_observability`` (continuous and
      discrete): Kalman ranks recomputed from the artefact's matrices,
      compared with the design's record.

Every other method's verdict lives in `tanksynth.verify.method_verdicts`
(imported at the end of this module, so that the registry is complete
whenever `verify_directory` can be called): observers, state feedback,
control laws, decentralised Kalman gains and a default estimator verdict.

`verify_directory` reads every artefact first (a tampered one, or one
designed from another spec than ``DIR/spec.toml``, is refused with an
`ArtefactError` before anything is written), runs the verdicts (in
process, or on a Dask cluster given its scheduler address), and writes
each artefact's ``verification`` field back atomically; gains are left
byte for byte as they were, so their provenance hash stays valid.

Beside each artefact it also stores a compact trace of the verdict's main
simulation (the first one the verdict runs that calls `record_trace`):
``DIR/<name>.traces.npz`` with ``t``, ``x`` (plant), ``x_hat`` (estimators
and observers), ``t_u``/``u`` (inputs), ``reference`` (if any) for the first
`TRACE_RUNS` runs, decimated to at most `TRACE_MAX_SAMPLES` samples, and a
JSON header (scenario, check and its verdict, state/input names and units).
It is written atomically and is not part of the artefact JSON (the
provenance hash is untouched); the report draws it as a time-domain figure.
A verdict that simulates nothing leaves no trace (a stale one is removed).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from contextvars import ContextVar
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.analysis.linearize import discretize_zoh, linearize
from tanksynth.errors import ArtefactError, TanksynthError
from tanksynth.analysis.checks import Check
from tanksynth.analysis.rank import controllability_rank, observability_rank
from tanksynth.sim.simulate import run_seeds, simulate

__all__ = [
    "Verdict",
    "VERDICTS",
    "register_verdict",
    "verdict_for",
    "artefact_gain",
    "linearize_verdict",
    "first_order_agreement",
    "load_directory",
    "verify_directory",
    "TRACE_SUFFIX",
    "TRACE_MAX_SAMPLES",
    "TRACE_RUNS",
    "record_trace",
    "verdict_with_trace",
    "trace_path",
    "write_trace",
    "read_trace",
]

#: File name suffix of an artefact's verdict trace: ``DIR/<name>.traces.npz``.
TRACE_SUFFIX = ".traces.npz"
#: Samples kept in a trace at most (decimated by a constant stride).
TRACE_MAX_SAMPLES = 2000
#: Runs of the verdict simulation batch kept in a trace (the first ones).
TRACE_RUNS = 2

#: The trace slot of the verdict running in this context (None: nothing is recorded).
_TRACE: ContextVar[dict | None] = ContextVar("tanksynth_verdict_trace", default=None)

VerdictFn = Callable[[Mapping[str, Any], Any], list]


@dataclass(frozen=True)
class Verdict:
    """The verification of one artefact.

    Attributes
    ----------
    name, method : str
    path : Path
        The artefact JSON.
    checks : tuple of Check
    """

    name: str
    method: str
    path: Path
    checks: tuple[Check, ...]

    @property
    def passed(self) -> bool | None:
        """False if any check failed; True if every decided check passed; None if none decided."""
        decided = [c.passed for c in self.checks if c.passed is not None]
        if any(p is False for p in decided):
            return False
        return True if decided else None

    def as_dict(self) -> dict:
        """The ``verification`` field of the artefact."""
        from tanksynth.artefacts.io import to_jsonable  # lazy: tanksynth.artefacts.io imports the design stage

        return {"passed": self.passed, "checks": [to_jsonable(c.as_dict()) for c in self.checks]}


#: Verdict functions by design method name.
VERDICTS: dict[str, VerdictFn] = {}
#: Methods whose verdict is a default (a later `register_verdict` replaces it).
_DEFAULTS: set[str] = set()


def register_verdict(method: str, fn: VerdictFn, *, default: bool = False) -> VerdictFn:
    """Register the verdict of a design method (one per method).

    Parameters
    ----------
    method : str
        Design method name.
    fn : callable
        ``fn(doc, spec) -> list[Check]``.
    default : bool
        A fallback verdict: it is replaced by a later (non-default)
        registration for the same method, and ignored when the method
        already has a verdict. This is how generic verdicts (e.g. the
        estimator verdict of `tanksynth.verify.method_verdicts`) leave room
        for a method's own.

    Returns
    -------
    callable
        ``fn`` (usable as a decorator body).

    Raises
    ------
    ValueError
        A second non-default verdict for the same method.
    """
    if method in VERDICTS:
        if default:
            return fn
        if method not in _DEFAULTS:
            raise ValueError(f"verdict for method {method!r} registered twice")
    VERDICTS[method] = fn
    if default:
        _DEFAULTS.add(method)
    else:
        _DEFAULTS.discard(method)
    return fn


def verdict_for(doc: Mapping[str, Any], spec: Any) -> list[Check]:
    """The checks of one artefact (``doc`` as returned by `read_artefact`)."""
    method = str(doc["method"])
    fn = VERDICTS.get(method)
    if fn is None:
        return [Check("verification", None, f"no verification defined for method {method}")]
    try:
        return list(fn(doc, spec))
    except TanksynthError as exc:
        return [Check("verification", False, f"verdict could not run: {' '.join(str(exc).split())}")]


# ------------------------------------------------------------------------- traces
def record_trace(result: Any, plant: Any, *, scenario: str, check: str, estimator: bool = False,
                 reference_names: Sequence[str] | None = None, runs: int = TRACE_RUNS) -> None:
    """Keep a compact trace of a verdict simulation (the first one of the verdict only).

    Does nothing unless the verdict runs under `verdict_with_trace`, or when
    that verdict already recorded a trace: the first simulation a verdict
    runs is its main one.

    Parameters
    ----------
    result : SimulationResult
    plant : Plant
        Gives the state, input and output names and units.
    scenario : str
        What the simulation does (plain text, for the figure caption).
    check : str
        Name of the check this simulation decides.
    estimator : bool
        The run has an estimator/observer (``x_hat`` is kept).
    reference_names : sequence of str, optional
        Names of the reference columns (states or outputs); default
        ``r1, r2, ...``.
    runs : int
        First runs of the batch kept.
    """
    slot = _TRACE.get()
    if slot is None or "trace" in slot:
        return
    t = np.asarray(result.t, dtype=float)
    stride = max(1, int(math.ceil(t.size / TRACE_MAX_SAMPLES)))
    keep = slice(None, None, stride)
    r = max(1, min(int(runs), int(result.x.shape[0])))
    ref = np.asarray(result.reference, dtype=float)
    names = [str(v) for v in reference_names] if reference_names is not None else \
        [f"r{i + 1}" for i in range(ref.shape[1])]
    arrays: dict[str, np.ndarray] = {
        "t": t[keep],
        "x": np.asarray(result.x[:r], dtype=float)[:, keep],
        "t_u": t[:-1][keep],
        "u": np.asarray(result.u[:r], dtype=float)[:, keep],
    }
    if estimator:
        arrays["x_hat"] = np.asarray(result.x_hat[:r], dtype=float)[:, keep]
    if ref.ndim == 2 and ref.shape[1] > 0:
        arrays["reference"] = ref[keep]
    header = {
        "schema": "tanksynth.traces/1",
        "scenario": str(scenario),
        "check": str(check),
        "runs": r,
        "stride": stride,
        "ts": float(result.ts),
        "plant": str(getattr(plant, "name", "")),
        "state_names": [q.name for q in plant.states],
        "state_units": [q.unit for q in plant.states],
        "input_names": [q.name for q in plant.inputs],
        "input_units": [q.unit for q in plant.inputs],
        "reference_names": names[:ref.shape[1]] if ref.ndim == 2 else [],
        "seeds": [int(v) for v in np.asarray(result.seeds)[:r]],
    }
    slot["trace"] = {"header": header, "arrays": arrays}


def verdict_with_trace(doc: Mapping[str, Any], spec: Any) -> tuple[list[Check], dict | None]:
    """`verdict_for`, with the trace of the verdict's main simulation.

    Returns
    -------
    checks : list of Check
    trace : dict or None
        ``{"header": dict, "arrays": dict of ndarray}`` (see `record_trace`),
        with the verdict of the check it decides (``check_passed``) and of
        the artefact (``verdict_passed``) added to the header; None when
        the verdict simulated nothing.
    """
    slot: dict = {}
    token = _TRACE.set(slot)
    try:
        checks = verdict_for(doc, spec)
    finally:
        _TRACE.reset(token)
    trace = slot.get("trace")
    if trace is not None:
        named = [c for c in checks if c.name == trace["header"]["check"]]
        decided = [c.passed for c in checks if c.passed is not None]
        trace["header"]["check_passed"] = named[0].passed if named else None
        trace["header"]["verdict_passed"] = (False if any(p is False for p in decided)
                                             else (True if decided else None))
        trace["header"]["artefact"] = str(doc.get("name", ""))
        trace["header"]["method"] = str(doc.get("method", ""))
    return checks, trace


def trace_path(artefact_path: str | Path, name: str) -> Path:
    """``DIR/<name>.traces.npz`` beside the artefact ``DIR/<name>.json``."""
    return Path(artefact_path).with_name(f"{name}{TRACE_SUFFIX}")


def write_trace(path: str | Path, trace: Mapping[str, Any]) -> Path:
    """Write a trace (`verdict_with_trace`) as ``.npz``, atomically (temp file + os.replace).

    The header is stored as a JSON string (``header``); no pickled object.
    """
    path = Path(path)
    arrays = {k: np.asarray(v, dtype=float) for k, v in trace["arrays"].items()}
    header = np.array(json.dumps(trace["header"], allow_nan=False, sort_keys=True))
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez_compressed(fh, header=header, **arrays)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def read_trace(path: str | Path) -> dict | None:
    """Read a trace file; None when it is missing or unreadable (no time-domain figure then).

    Returns
    -------
    dict or None
        ``{"header": dict, "arrays": dict of ndarray}``.
    """
    try:
        with np.load(Path(path), allow_pickle=False) as data:
            header = json.loads(str(data["header"][()]))
            arrays = {k: np.asarray(data[k]) for k in data.files if k != "header"}
    except (OSError, ValueError, KeyError, json.JSONDecodeError, EOFError):
        return None
    if not isinstance(header, dict) or "t" not in arrays or "x" not in arrays:
        return None
    return {"header": header, "arrays": arrays}


# ------------------------------------------------------------------------- linearize
def artefact_gain(doc: Mapping[str, Any], name: str) -> np.ndarray:
    """A gain of an artefact as a float array (at least 1-D).

    Raises
    ------
    ArtefactError
        The artefact has no gain of that name.
    """
    gains = doc["gains"]
    if name not in gains:
        raise ArtefactError(f"artefact '{doc['name']}' ({doc['method']}) has no gain {name!r}")
    return np.atleast_1d(np.asarray(gains[name], dtype=float))


_gain = artefact_gain


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def first_order_agreement(plant: Any, F: np.ndarray, B: np.ndarray, Ad: np.ndarray, Bd: np.ndarray,
                          x0: np.ndarray, u0: np.ndarray, ts: float, *, horizon: int = 20,
                          eps0: float = 5e-3, substeps: int = 10) -> dict[str, Any]:
    """Compare the nonlinear plant with its discrete linear model near (x0, u0).

    From ``x0 + eps dx`` with input ``u0 + eps du`` (``dx``, ``du`` fixed
    directions scaled by the region span and the input range), the
    nonlinear deviation from the unperturbed trajectory is compared with
    ``Ad^k dx + sum Ad^j Bd du`` over ``horizon`` samples, for ``eps =
    eps0, eps0/2, eps0/4``.

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
    record_trace(res, plant, check="first_order_agreement",
                 scenario=f"open loop from (x0, u0) and from (x0 + eps dx, u0 + eps du), eps = {eps0:g} "
                          f"(first-order agreement with the linear model)")
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


def linearize_verdict(doc: Mapping[str, Any], spec: Any) -> list[Check]:
    """Verdict of a ``linearize`` artefact (see the module docstring).

    Parameters
    ----------
    doc : mapping
        The artefact (gains as arrays).
    spec : tanksynth.spec.Spec
        The spec it was designed from (its plant).
    """
    plant = spec.plant
    F, B, C = (np.atleast_2d(_gain(doc, k)) for k in ("F", "B", "C"))
    Ad, Bd = np.atleast_2d(_gain(doc, "Ad")), np.atleast_2d(_gain(doc, "Bd"))
    x0, u0 = _gain(doc, "x0"), _gain(doc, "u0")
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
    worst = max(_rel(F, lin.F), _rel(B, lin.B), _rel(C, lin.C))
    checks.append(Check("jacobian_recheck", worst <= 1e-9,
                        f"F, B, C recomputed from the model at (x0, u0): largest relative difference "
                        f"{worst:.3g} (tolerance 1e-9)", {"relative_difference": worst}))
    Ad2, Bd2 = discretize_zoh(F, B, ts)
    zoh = max(_rel(Ad, Ad2), _rel(Bd, Bd2))
    checks.append(Check("zoh_consistency", zoh <= 1e-9,
                        f"Ad, Bd against the exact ZOH of (F, B) at ts = {ts:g} s: relative difference "
                        f"{zoh:.3g} (tolerance 1e-9)", {"relative_difference": zoh}))
    residual = plant.compiled.rhs(x0[None], u0[None])[0]
    eq = diag.get("equilibrium") or {}
    tol = float(eq.get("tolerance", 1e-12)) if isinstance(eq, Mapping) else 1e-12
    worst_res = float(np.max(np.abs(residual)))
    checks.append(Check("equilibrium", worst_res <= tol,
                        f"max |f(x0, u0)| = {worst_res:.3g} state units/s (tolerance {tol:.3g})",
                        {"residual": residual.tolist(), "tolerance": tol}))
    agreement = first_order_agreement(plant, F, B, Ad, Bd, x0, u0, ts)
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


register_verdict("linearize", linearize_verdict)


# ------------------------------------------------------------------------- directory
@lru_cache(maxsize=8)
def _spec_from_text(text: str, source: str):
    from tanksynth.spec import parse_spec_text

    return parse_spec_text(text.encode("utf-8"), source=source)


def load_directory(directory: str | Path) -> tuple[Any, list[tuple[Path, dict]]]:
    """Read ``DIR/spec.toml`` and every artefact of a directory, refusing bad ones.

    Returns
    -------
    spec : tanksynth.spec.Spec
    artefacts : list of (Path, dict)
        Each artefact's path and document (gains as arrays), sorted by name.

    Raises
    ------
    ArtefactError
        No artefact, no ``spec.toml``, an unreadable or tampered artefact
        (gains changed after design), or one designed from another spec.
    """
    from tanksynth.artefacts.io import SCHEMA, read_artefact  # lazy: see Verdict.as_dict

    directory = Path(directory)
    if not directory.is_dir():
        raise ArtefactError(f"{directory}: not a directory")
    docs = []
    for path in sorted(directory.glob("*.json")):
        try:
            head = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError, UnicodeDecodeError):
            head = None
        if isinstance(head, dict) and isinstance(head.get("schema"), str) \
                and not head["schema"].startswith("tanksynth.artefact/"):
            continue  # plant record, campaign metadata, ...
        if not isinstance(head, dict) and path.name in ("checks.json",):
            continue
        docs.append((path, read_artefact(path)))
    if not docs:
        raise ArtefactError(f"{directory}: no artefact (*.json with schema {SCHEMA!r})")
    spec_path = directory / "spec.toml"
    try:
        raw = spec_path.read_bytes()
    except OSError:
        raise ArtefactError(f"{spec_path}: missing; verify needs the spec the artefacts were designed "
                            "from (written by `tanksynth design`)") from None
    import hashlib

    sha = hashlib.sha256(raw).hexdigest()
    for path, doc in docs:
        if doc["provenance"].get("spec_sha256") != sha:
            raise ArtefactError(f"{path}: designed from another spec than {spec_path} "
                                "(spec_sha256 differs)")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ArtefactError(f"{spec_path}: not UTF-8 text") from None
    return _spec_from_text(text, str(spec_path)), docs


def _write_verification(path: Path, verification: Mapping[str, Any]) -> None:
    """Set the ``verification`` field of an artefact JSON, atomically, gains untouched."""
    raw = json.loads(path.read_text(encoding="utf-8"))
    raw["verification"] = verification
    data = (json.dumps(raw, indent=2, allow_nan=False) + "\n").encode("utf-8")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _remote_verdict(method: str, doc: dict, spec_text: str, source: str) -> tuple[list[dict], dict | None]:
    """Run one verdict on a Dask worker (plain data in, plain data out), with its trace."""
    spec = _spec_from_text(spec_text, source)
    doc = dict(doc)
    doc["gains"] = {k: np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
    checks, trace = verdict_with_trace(doc, spec)
    return [c.as_dict() for c in checks], trace


def verify_directory(directory: str | Path, scheduler: str | None = None,
                     progress: Callable[[int, int], None] | None = None) -> list[Verdict]:
    """Verify every artefact of a directory and record the verdicts in them.

    Beside each artefact ``DIR/<name>.json`` the trace of its verdict's main
    simulation is written to ``DIR/<name>.traces.npz`` (`write_trace`,
    atomic); an artefact whose verdict simulates nothing has its stale
    trace removed. The artefact JSON gets only its ``verification`` field.

    Parameters
    ----------
    directory : str or Path
        Holds the artefacts and ``spec.toml``.
    scheduler : str, optional
        Address of a Dask scheduler: the verdicts run there (one task per
        artefact). Default: in this process.
    progress : callable, optional
        ``progress(done, total)`` after each artefact.

    Returns
    -------
    list of Verdict

    Raises
    ------
    ArtefactError
        See `load_directory`; nothing is written then.
    """
    spec, docs = load_directory(directory)
    total = len(docs)
    checks: dict[Path, list[Check]] = {}
    traces: dict[Path, dict | None] = {}
    if scheduler is None:
        for i, (path, doc) in enumerate(docs):
            checks[path], traces[path] = verdict_with_trace(doc, spec)
            if progress is not None:
                progress(i + 1, total)
    else:
        from distributed import Client, as_completed

        text = (Path(directory) / "spec.toml").read_text(encoding="utf-8")
        source = str(Path(directory) / "spec.toml")
        with Client(scheduler) as client:
            futures = {}
            for path, doc in docs:
                plain = {**doc, "gains": {k: v.tolist() for k, v in doc["gains"].items()}}
                fut = client.submit(_remote_verdict, doc["method"], plain, text, source, pure=False,
                                    retries=2)
                futures[fut] = path
            for i, fut in enumerate(as_completed(futures)):
                found, traces[futures[fut]] = fut.result()
                checks[futures[fut]] = [Check(c["check"], c["passed"], c["detail"], c["data"])
                                        for c in found]
                if progress is not None:
                    progress(i + 1, total)
    verdicts = []
    for path, doc in docs:
        v = Verdict(str(doc["name"]), str(doc["method"]), path, tuple(checks[path]))
        _write_verification(path, v.as_dict())
        trace = traces.get(path)
        target = trace_path(path, str(doc["name"]))
        if trace is not None:
            write_trace(target, trace)
        else:
            target.unlink(missing_ok=True)  # a stale trace of an earlier verdict
        verdicts.append(v)
    return verdicts


# Registers the verdicts of the other design methods (imported last: it uses this module).
from tanksynth.verify import method_verdicts as _method_verdicts  # noqa: E402,F401
