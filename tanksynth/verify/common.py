"""Shared by the verdicts: tolerances, option and gain readers, re-checks.

Every verdict reads the gains of the artefact (the part its provenance hash
protects) and the spec it was designed from; the diagnostics are evidence to
compare with, never an input that a check trusts. Nothing here designs:
gains are read, laws rebuilt from gains or deserialised, eigenvalues and LMI
residuals recomputed with the verdicts' own numerics
(`tanksynth.verify.numerics`); the simulations on the NONLINEAR plant live in
`tanksynth.verify.simulations`.

Re-checks from the artefact alone
    ``model_recheck``
        the ``(A, B, C)`` stored with a gain equal the linearisation of the
        plant at the spec's operating point with its equilibrium input
        (exact ZOH at ``ts`` for discrete-time designs); largest relative
        difference <= `MODEL_TOLERANCE`.
    ``poles``
        eigenvalues of the closed loop (``A - B K``, or the augmented
        ``Aa - Ba K`` with integral action) or of the observer error matrix
        (``A - L C``), recomputed from the stored matrices, matched one to
        one with the poles requested in the spec (`match_poles`); error
        relative to ``max(1, |p|)`` <= `POLE_TOLERANCE`.
    ``stability`` / ``region``
        those eigenvalues inside the stability domain (``Re < 0`` or
        ``|z| < 1``), or inside the LMI region requested in the spec.
    ``lmi_recheck``
        LMI blocks recomputed in numpy from the stored ``P``: the region LMI
        ``L (x) X + M (x) (Acl X) + M' (x) (Acl X)' < 0`` (Chilali-Gahinet;
        ``X = P^-1`` for state feedback, ``X = P`` for observers,
        `region_lmi_matrix`) or the observer LMI (28) of seed 001
        (`observer_lmi_recheck`, with ``K = P L``).
    ``rank_*``
        Kalman ranks of the stored pairs.
    ``law_matches_gains``
        a law serialised in the diagnostics agrees with the law built from
        (or the quantities stored as) gains, at the operating point and at
        points of the region.

Simulations on the nonlinear plant (rules stated in each check's detail)
    ``tau``, the designed time constant
        the slowest time constant the DESIGN asks for: of the poles requested
        in the spec (``1 / min |Re p|``, or ``-ts / ln max |p|`` in discrete
        time), of the decay an LMI region guarantees (half-plane ``alpha``,
        disk ``|c| + r``), ``1 / psi`` for the observer LMI (28); otherwise
        of the stored gain's matrix. A wrong gain is thus simulated against
        the design's claim, not against its own (slower) dynamics.
    ``observer_convergence`` (and ``estimator_convergence``)
        the plant starts at ``x0 + delta`` (``delta`` 5 % of the region
        span, alternating signs, scaled down until it lies in the region and
        in the TS domain) under the equilibrium input, the observer at
        ``x0``; horizon ``H = tau (5 + ln kappa)``, ``kappa`` the condition
        number of the eigenvectors of the stored error matrix (the linear
        bound ``|e(t)| <= kappa exp(-t / tau) |e(0)|``: a peaking high-gain
        observer gets the time its transient needs); pass if ``|e(t)|_inf
        <= 5 %`` of ``|e(0)|_inf`` at every sample of ``[H, 1.2 H]``.
    ``servo_tracking`` / ``bounded_inputs``
        state feedback with integral action: set-points of the tracked
        outputs step by 5 % of their operating values, the simulator
        saturates the pumps; horizon ``8 tau``; pass if the tracking error
        over the last 10 % of the samples is <= 2 % of the step and the
        inputs settle strictly inside the actuator range.
    ``regulation``
        state feedback without integral action: from ``x0 + delta``,
        ``|x - x0|_inf <= 5 %`` of ``|delta|_inf`` on ``[H, 1.2 H]``, ``H``
        as for observers.
    ``time_constant_*`` / ``decoupling_*``
        feedback linearisation: a step of 5 % on one output, the law sampled
        with ``K ts <= 0.005``; the 63.2 % rise time within 2 % of ``1/K``
        and the other outputs within 1 % of the step.
    ``servo_scenario``
        inverse dynamics: the servo scenario (`scenario("servo")`); ISE
        finite and tracking time within the horizon.
    ``filter_vs_open_loop`` / ``filter_error_bounded``
        decentralised Kalman gains on the nonlinear network over the window.
    ``estimator_convergence``
        estimators: the initial-state mismatch run of `estimator_verdict`
        (``adaptive_scaling_kalman`` and ``consensus_filter`` included, their
        horizon from the steady-state filter with the spec's ``Q`` and ``R``).
    ``covariance``
        adaptive-scaling and consensus filters: the covariance at the end of
        that run symmetric (to 1e-9 relative) and positive definite.
    ``training_fit_recheck`` / ``one_step_fit`` / ``closed_loop_bounded``
        NARX, on fresh EKF data: see `narx_verdict`.
    ``threshold_recheck`` / ``no_false_alarm`` / ``fault_detected``
        fault detection, healthy and faulty plant with the stored ``Psi`` and
        threshold: see `fault_detection_verdict`.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.analysis.lmi_region import LMIRegion
from tanksynth.analysis.rank import RankResult
from tanksynth.analysis.statespace import model_names
from tanksynth.errors import ArtefactError, TanksynthError
from tanksynth.plants.base import Plant
from tanksynth.spec import DesignSpec, Spec
from tanksynth.verify.numerics import match_poles, region_lmi_matrix, symmetric

__all__ = [
    "MODEL_TOLERANCE", "POLE_TOLERANCE", "OBSERVER_TIME_CONSTANTS", "OBSERVER_TOLERANCE",
    "SERVO_TIME_CONSTANTS", "SERVO_TOLERANCE", "PERTURBATION", "MAX_STEPS", "NUMERIC_ERRORS",
    "CONTINUOUS_TS", "artefact_gain", "artefact_matrix", "design_options", "option",
    "operating_point", "stored_operating_point", "sampling_period", "discrete_ts", "required_ts",
    "time_domain", "tracked_outputs", "output_rows", "output_at",
    "one_line", "guard", "fmt", "fmt_signals", "complex_list", "relative_difference",
    "model_recheck", "pole_check", "stability_check", "region_check", "region_lmi_check",
    "rank_check",
]

#: Largest relative difference between a stored model matrix and the re-linearisation.
MODEL_TOLERANCE = 1e-9
#: Largest pole error, relative to ``max(1, |p|)``.
POLE_TOLERANCE = 1e-6
#: Observer horizon in slowest error time constants.
OBSERVER_TIME_CONSTANTS = 5.0
#: Observer error at the horizon, as a fraction of the initial error.
OBSERVER_TOLERANCE = 0.05
#: Servo horizon in slowest closed-loop time constants.
SERVO_TIME_CONSTANTS = 8.0
#: Steady tracking error, as a fraction of the set-point step.
SERVO_TOLERANCE = 0.02
#: Initial perturbation, as a fraction of each state's region span.
PERTURBATION = 0.05
#: Most samples a verification simulation may take (else the check is not decided).
MAX_STEPS = 20000
#: Sampling period of campaigns on a spec without one (continuous-time designs), s: the
#: scenarios count samples with ts = 1 s in mind.
CONTINUOUS_TS = 1.0
#: Errors a group of checks may raise on bad data or failed numerics (`guard` turns them
#: into one failed check).
NUMERIC_ERRORS = (TanksynthError, np.linalg.LinAlgError, ValueError, RuntimeError,
                  FloatingPointError, ZeroDivisionError)


# ============================================================================ readers
def artefact_gain(doc: Mapping[str, Any], name: str) -> np.ndarray:
    """A gain of an artefact as a float array (at least 1-D, the gain's units).

    Parameters
    ----------
    doc, name : mapping, str
        The artefact and the gain's name.

    Raises
    ------
    ArtefactError
        The artefact has no gain of that name (naming the old name when the
        artefact predates the naming rule, `model_names`).
    """
    gains = doc["gains"]
    if name not in gains:
        old = _OLD_NAMES.get(name)
        hint = f" but {old!r}: written before gains were renamed (docs/artefacts.md); design again" \
            if old in gains else ""
        raise ArtefactError(f"artefact '{doc['name']}' ({doc['method']}) has no gain {name!r}{hint}")
    return np.atleast_1d(np.asarray(gains[name], dtype=float))


#: New gain name -> the name artefacts written before the naming rule used.
_OLD_NAMES = {"F": "A", "Ad": "A", "Bd": "B", "Bwd": "Bw", "B0": "B", "x_op": "x0", "u_op": "u0",
              "x_hat0": "x0", "Lambda_op": "Lambda_x0", "Lambda0_op": "Lambda0_x0"}


def artefact_matrix(doc: Mapping[str, Any], name: str, shape: tuple[int, int] | None = None,
                    domain: str | None = None) -> np.ndarray:
    """A gain of an artefact as a 2-D float array, reshaped to ``shape`` if given.

    Parameters
    ----------
    doc, name, shape : mapping, str, (int, int) or None
        The artefact, the gain's name and its expected shape.
    domain : {"continuous", "discrete"}, optional
        Given: ``name`` is a model role (``"A"``, ``"B"``, ``"Bw"``, ``"C"``) read under its
        name in that time domain (``F``/``Ad``, ``B``/``Bd``, ...: `model_names`).

    Raises
    ------
    ArtefactError
        No gain of that name, or its size does not fit ``shape``.
    """
    if domain is not None:
        name = model_names(domain)[name]
    arr = np.atleast_2d(artefact_gain(doc, name))
    if shape is not None:
        if arr.size != shape[0] * shape[1]:
            raise ArtefactError(f"artefact '{doc['name']}': gain {name} has shape {arr.shape}, "
                                f"expected {shape}")
        arr = arr.reshape(shape)
    return arr


def _design_entry(doc: Mapping[str, Any], spec: Spec) -> DesignSpec | None:
    # a spec parsed without the method table keeps an alias as written (``method = "lqr"``);
    # the artefact records it beside the method it ran
    methods = {doc["method"], (doc.get("diagnostics") or {}).get("method_alias")}
    for d in getattr(spec, "designs", ()):
        if d.name == doc["name"] and d.method in methods:
            return d
    return None


def design_options(doc: Mapping[str, Any], spec: Spec) -> Mapping[str, Any]:
    """The options of the spec's ``[[design]]`` entry that produced an artefact.

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : tanksynth.spec.Spec

    Returns
    -------
    mapping
        As written in the spec; empty when the spec has no entry of that
        name and method.
    """
    entry = _design_entry(doc, spec)
    return entry.options if entry is not None else {}


def option(doc: Mapping[str, Any], spec: Spec, name: str, default: Any = None) -> Any:
    """An option of the artefact's design as validated (spec value, else the method's default).

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : tanksynth.spec.Spec
    name : str
        Option name.
    default : optional
        Returned when the option is absent (or None).
    """
    entry = _design_entry(doc, spec)
    if entry is None:
        return default
    config = entry.config if getattr(entry, "config", None) is not None else entry.options
    if config is None:
        return default
    value = config.get(name) if isinstance(config, Mapping) else getattr(config, name, None)
    return default if value is None else value


def operating_point(spec: Spec) -> tuple[np.ndarray, np.ndarray]:
    """The spec's operating point ``x0`` (state units) and its equilibrium input (input units).

    Parameters
    ----------
    spec : Spec
        The validated spec.
    """
    eq = equilibrium_input(spec.plant, spec.x0, spec.given_u0)
    return np.asarray(spec.x0, dtype=float).copy(), np.asarray(eq.u0, dtype=float)


def stored_operating_point(doc: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray] | None:
    """The operating point an artefact ships (gains ``x_op``, ``u_op``; state and input units).

    Parameters
    ----------
    doc : mapping
        The artefact.

    Returns
    -------
    tuple of ndarray, or None
        ``(x_op, u_op)``: levels (state units, m) and inputs (input units, m^3/s); None when
        the artefact ships no operating point (its design used the spec's).
    """
    gains = doc["gains"]
    if "x_op" in gains and "u_op" in gains:
        return artefact_gain(doc, "x_op").reshape(-1), artefact_gain(doc, "u_op").reshape(-1)
    return None


def sampling_period(spec: Spec) -> float:
    """The campaign's sampling period (s): the spec's ``ts``, else `CONTINUOUS_TS`.

    Parameters
    ----------
    spec : Spec
        The validated spec.
    """
    return float(spec.ts) if spec.ts else CONTINUOUS_TS


def discrete_ts(spec: Spec) -> float:
    """The spec's sampling period ``ts`` (s): the period a discrete-time artefact was designed at.

    Parameters
    ----------
    spec : Spec
        The validated spec.

    Raises
    ------
    ArtefactError
        The spec has no sampling period (no discrete-time design can come from it).
    """
    return required_ts(spec.ts)


def required_ts(ts: float | None) -> float:
    """A sampling period that a discrete-time computation needs (s).

    Parameters
    ----------
    ts : float or None
        The sampling period [s]; None where the spec gives none.

    Raises
    ------
    ArtefactError
        ``ts`` is None: no discrete-time model (or design) exists without it.
    """
    if ts is None:
        raise ArtefactError("the spec has no sampling period [sampling] ts: a discrete-time "
                            "artefact cannot be verified against it")
    return float(ts)


def time_domain(doc: Mapping[str, Any], spec: Spec) -> str:
    """``"continuous"`` or ``"discrete"``: the design's option, else discrete iff the spec has ``ts``.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    value = option(doc, spec, "time_domain")
    if value in ("continuous", "discrete"):
        return str(value)
    return "discrete" if spec.ts is not None else "continuous"


def output_rows(plant: Plant, names: Sequence[str]) -> list[int]:
    """Indices of the named outputs of the plant.

    Parameters
    ----------
    plant, names : Plant, sequence of str
        The plant model and output names.

    Raises
    ------
    ArtefactError
        A name is not an output of the plant.
    """
    outputs = [s.name for s in plant.outputs]
    missing = [n for n in names if n not in outputs]
    if missing:
        raise ArtefactError(f"tracked output(s) {missing} are not outputs of plant '{plant.name}' "
                            f"({outputs})")
    return [outputs.index(n) for n in names]


def tracked_outputs(doc: Mapping[str, Any], spec: Spec, name: str = "tracked") -> list[str]:
    """The tracked outputs the design declares (option ``name``), else the first ``m`` outputs.

    Parameters
    ----------
    doc, spec, name : mapping, Spec, str
        The artefact, the validated spec and the option naming the tracked outputs.
    """
    chosen = option(doc, spec, name)
    if isinstance(chosen, list) and chosen:
        return [str(c) for c in chosen]
    return [s.name for s in spec.plant.outputs][: spec.plant.m]


def output_at(plant: Plant, x: np.ndarray) -> np.ndarray:
    """The plant's output ``h(x)`` at one state (output units).

    Parameters
    ----------
    plant, x : Plant, ndarray (n,)
        The plant model and one state (state units, m).
    """
    return np.asarray(plant.compiled.output(np.asarray(x, float)[None]), dtype=float).reshape(-1)


# ========================================================================= formatting
def one_line(exc: BaseException) -> str:
    """``"Type: message"`` of an exception on one line.

    Parameters
    ----------
    exc : BaseException
        The exception.
    """
    return " ".join(f"{type(exc).__name__}: {exc}".split())


def guard(name: str, fn: Callable[[], list[Check]]) -> list[Check]:
    """Run a group of checks; a numerical error becomes one failed check ``name`` naming it.

    Parameters
    ----------
    name, fn : str, callable
        Name of the failed check on an error; runs the group and returns its checks.
    """
    try:
        return list(fn())
    except NUMERIC_ERRORS as exc:
        return [Check(name, False, f"could not be checked: {one_line(exc)}")]


def fmt(values: Any, digits: int = 4) -> str:
    """Compact text of a number, vector or matrix (complex entries as ``a+bj``).

    Parameters
    ----------
    values, digits : float or array_like, int
        Number, vector or matrix (its own units); significant digits.
    """
    arr = np.asarray(values)
    if np.iscomplexobj(arr):
        return "[" + ", ".join(f"{complex(v).real:.{digits}g}{complex(v).imag:+.{digits}g}j"
                               if abs(complex(v).imag) > 0 else f"{complex(v).real:.{digits}g}"
                               for v in arr.ravel()) + "]"
    if arr.ndim > 1:
        return "[" + ", ".join(fmt(row, digits) for row in arr) + "]"
    # significant digits, never fixed-point (array2string(precision=4) prints 1.2e-4 as 0.0001)
    return "[" + ", ".join(f"{float(v):.{digits}g}" for v in np.atleast_1d(arr).ravel()) + "]"


def fmt_signals(values: Any, signals: Sequence[Any], digits: int = 4) -> str:
    """``name = value unit`` per signal (``q1 = 3.5e-05 m^3/s, ...``); ranges as ``[lo, hi]``.

    ``values`` is a vector (one number per signal) or an ``(n, 2)`` array of
    ranges; ``signals`` have ``name`` and ``unit`` (plant states, inputs, outputs).

    Parameters
    ----------
    values, signals, digits : array_like (n,) or (n, 2), sequence, int
        One value or range per signal (its unit); signals with ``name`` and ``unit``; significant digits.
    """
    arr = np.asarray(values, dtype=float)
    parts = []
    for i, sig in enumerate(signals):
        if i >= arr.shape[0]:
            break
        name, unit = str(getattr(sig, "name", f"#{i + 1}")), str(getattr(sig, "unit", "") or "")
        v = arr[i]
        text = (f"{name} in [{float(v[0]):.{digits}g}, {float(v[1]):.{digits}g}]" if np.ndim(v) == 1
                else f"{name} = {float(v):.{digits}g}")
        parts.append(text + (f" {unit}" if unit and unit != "1" else ""))
    return ", ".join(parts)


def complex_list(values: Any) -> list[list[float]]:
    """Sorted complex values as ``[[re, im], ...]`` (JSON-friendly).

    Parameters
    ----------
    values : array_like of complex
        The values (their own unit, e.g. 1/s).
    """
    return [[float(v.real), float(v.imag)] for v in np.sort_complex(np.asarray(values, dtype=complex))]


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """``|a - b| / |b|`` in the Frobenius norm (``|b|`` floored at 1e-300).

    Parameters
    ----------
    a, b : ndarray
        Arrays of the same shape and units.
    """
    return float(np.linalg.norm(a - b) / max(float(np.linalg.norm(b)), 1e-300))


# ========================================================================== re-checks
def model_recheck(plant: Plant, x0: np.ndarray, u0: np.ndarray, domain: str, ts: float | None,
                  stored: Mapping[str, np.ndarray]) -> Check:
    """``model_recheck``: stored ``A``/``B``/``C`` against the plant linearised at ``(x0, u0)``.

    ``domain = "discrete"`` compares with the exact ZOH at ``ts`` (s).

    Parameters
    ----------
    plant, x0, u0 : Plant, ndarray (n,), ndarray (m,)
        The plant, operating point (state units, m) and equilibrium input (input units, m^3/s).
    domain, ts, stored : str, float or None, mapping of str to ndarray
        ``"continuous"``/``"discrete"``, sampling period [s], the artefact's model by role
        (``"A"``, ``"B"``, ``"C"``; stored as ``F, B, C`` or ``Ad, Bd, C``: `model_names`).
    """
    lin = linearize(plant, x0, u0, ts=required_ts(ts) if domain == "discrete" else None)
    A, B = (lin.Ad, lin.Bd) if domain == "discrete" else (lin.F, lin.B)
    if A is None or B is None:  # linearize discretises whenever it is given ts
        raise ArtefactError(f"no {domain}-time model of the plant at the operating point (ts = {ts})")
    ref = {"A": A, "B": B, "C": lin.C}
    diffs = {}
    for name, mat in stored.items():
        r = ref[name]
        diffs[name] = math.inf if mat.shape != r.shape else relative_difference(mat, r)
    worst = max(diffs.values())
    ok = bool(worst <= MODEL_TOLERANCE)
    what = f"exact ZOH at ts = {ts:g} s" if domain == "discrete" else "continuous Jacobians"
    return Check("model_recheck", ok,
                 f"stored {', '.join(model_names(domain).get(k, k) for k in stored)} against the plant linearised at the spec's operating "
                 f"point with the equilibrium input ({what}): largest relative difference "
                 f"{worst:.3g} (tolerance {MODEL_TOLERANCE:g})",
                 {"relative_differences": diffs, "tolerance": MODEL_TOLERANCE, "domain": domain})


def pole_check(achieved: np.ndarray, requested: Sequence[complex], what: str) -> Check:
    """``poles``: eigenvalues matched one to one with the requested poles (`match_poles`).

    Parameters
    ----------
    achieved, requested, what : ndarray, sequence of complex, str
        Rebuilt eigenvalues and requested poles (1/s; discrete: dimensionless); the system's name.
    """
    p = np.asarray(requested, dtype=complex)
    a = np.asarray(achieved, dtype=complex)
    if p.size != a.size:
        return Check("poles", False, f"{p.size} poles requested in the spec, {a.size} eigenvalues "
                                     f"of {what}", {"requested": complex_list(p)})
    match = match_poles(p, a)
    emax, rel = match.max_error, match.max_relative_error
    ok = bool(rel <= POLE_TOLERANCE)
    return Check("poles", ok,
                 f"eigenvalues of {what} recomputed from the artefact: {fmt(np.sort_complex(a), 6)}; "
                 f"requested in the spec: {fmt(np.sort_complex(p), 6)}; largest error after the "
                 f"optimal one-to-one matching {emax:.3g}, relative to max(1, |p|) {rel:.3g} "
                 f"(tolerance {POLE_TOLERANCE:g})",
                 {"achieved": complex_list(a), "requested": complex_list(p), "max_error": emax,
                  "max_relative_error": rel, "tolerance": POLE_TOLERANCE})


def stability_check(eigs: np.ndarray, domain: str, what: str) -> Check:
    """``stability``: every eigenvalue in ``Re < 0`` (continuous) or ``|z| < 1`` (discrete).

    Parameters
    ----------
    eigs, domain, what : ndarray of complex, str, str
        Eigenvalues (1/s; discrete: dimensionless), ``"continuous"``/``"discrete"``, the system's name.
    """
    eigs = np.asarray(eigs, dtype=complex)
    if domain == "discrete":
        value = float(np.max(np.abs(eigs)))
        ok = value < 1.0
        detail = f"spectral radius of {what}: {value:.6g} (must be < 1)"
    else:
        value = float(np.max(eigs.real))
        ok = value < 0.0
        detail = f"largest real part of the eigenvalues of {what}: {value:.6g} 1/s (must be < 0)"
    return Check("stability", bool(ok), detail, {"value": value, "domain": domain})


def region_check(eigs: np.ndarray, region: LMIRegion, what: str) -> Check:
    """``region``: every eigenvalue inside the LMI region (``-lambda_max(f_D(z)) > 0``).

    Parameters
    ----------
    eigs, region, what : ndarray of complex, LMIRegion, str
        Eigenvalues (1/s; discrete: dimensionless), the region, the system's name.
    """
    margins = np.array([region.margin(complex(z)) for z in np.asarray(eigs, dtype=complex)])
    worst = float(np.min(margins))
    return Check("region", bool(worst > 0),
                 f"eigenvalues of {what} {fmt(np.sort_complex(eigs), 6)} against the spec's region "
                 f"{region.describe()}: smallest margin -lambda_max(f_D(z)) = {worst:.3g} (must be > 0)",
                 {"margins": margins.tolist(), "region": region.describe()})


def region_lmi_check(region: LMIRegion, Acl: np.ndarray, X: np.ndarray, what: str) -> Check:
    """``lmi_recheck``: the region LMI of ``Acl`` with the stored Lyapunov matrix ``X``.

    Parameters
    ----------
    region, Acl, X, what : LMIRegion, ndarray (n, n), ndarray (n, n), str
        The region, closed-loop (or error) matrix, stored Lyapunov matrix, the system's name.
    """
    M = region_lmi_matrix(region.L, region.M, Acl, X)
    eig = np.linalg.eigvalsh(M)
    lam = float(eig.max())
    scale = float(np.max(np.abs(eig))) or 1.0
    xmin = float(np.min(np.linalg.eigvalsh(symmetric(X))))
    ok = bool(lam < 0 and xmin > 0)
    return Check("lmi_recheck", ok,
                 f"region LMI L (x) X + M (x) (A X) + M' (x) (A X)' of {what} recomputed in numpy "
                 f"from the stored P: largest eigenvalue {lam:.4g} (relative {lam / scale:.3g}; "
                 f"must be < 0), smallest eigenvalue of X {xmin:.4g} (must be > 0)",
                 {"lmi_max_eigenvalue": lam, "relative": lam / scale, "X_min_eigenvalue": xmin})


def rank_check(name: str, result: RankResult, pair: str) -> Check:
    """A Kalman rank test (`tanksynth.analysis.rank`) as a check: full rank passes.

    Parameters
    ----------
    name, result, pair : str, RankResult, str
        Name of the check, the rank test's result, the pair tested (e.g. ``(A, C)``).
    """
    return Check(name, bool(result.full),
                 f"rank {result.rank}/{result.n} of {pair} stored in the artefact, condition number "
                 f"{result.condition_number:.3g}", result.as_dict())
