"""Shared by the verdicts: tolerances, option and gain readers, re-checks, simulation adapters.

Every verdict reads the gains of the artefact (the
part its provenance hash protects) and the spec it was designed from; the
diagnostics are evidence to compare with, never an input that a check
trusts. The simulator never designs: gains are read, laws rebuilt from
gains or deserialised, and simulated on the NONLINEAR plant.

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
        one with the poles requested in the spec; error relative to
        ``max(1, |p|)`` <= `POLE_TOLERANCE`.
    ``stability`` / ``region``
        those eigenvalues inside the stability domain (``Re < 0`` or
        ``|z| < 1``), or inside the LMI region requested in the spec.
    ``lmi_recheck``
        LMI blocks recomputed in numpy from the stored ``P``: the region LMI
        ``L (x) X + M (x) (Acl X) + M' (x) (Acl X)' < 0`` (Chilali-Gahinet;
        ``X = P^-1`` for state feedback, ``X = P`` for observers) or the
        observer LMI (28) of seed 001 by
        `tanksynth.design.lmi.check_observer_lmi` (with ``K = P L``).
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
        inverse dynamics: seed 002 servo scenario (`scenario("servo")`);
        ISE finite and tracking time within the horizon.
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
"
"""


import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError, TanksynthError
from tanksynth.analysis.checks import Check
from tanksynth.sim.simulate import BatchEstimator, EstimatorAdapter, run_seeds, simulate
from tanksynth.verify.traces import record_trace


__all__ = ["artefact_gain", "MODEL_TOLERANCE", "POLE_TOLERANCE", "OBSERVER_TIME_CONSTANTS", "OBSERVER_TOLERANCE", "SERVO_TIME_CONSTANTS", "SERVO_TOLERANCE", "PERTURBATION", "MAX_STEPS", "design_options", "CasadiControlLaw", "CasadiIntegralLaw", "luenberger_estimator", "TSObserver", "observer_convergence"]

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

_NUMERIC_ERRORS = (TanksynthError, np.linalg.LinAlgError, ValueError, RuntimeError,
                   FloatingPointError, ZeroDivisionError)


# =============================================================================== helpers
def _one_line(exc: BaseException) -> str:
    return " ".join(f"{type(exc).__name__}: {exc}".split())


def _guard(name: str, fn: Callable[[], list[Check]]) -> list[Check]:
    """Run a group of checks; an error becomes one failed check naming it."""
    try:
        return list(fn())
    except _NUMERIC_ERRORS as exc:
        return [Check(name, False, f"could not be checked: {_one_line(exc)}")]


def design_options(doc: Mapping[str, Any], spec: Any) -> Mapping[str, Any]:
    """The options of the spec's ``[[design]]`` entry that produced an artefact.

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : tanksynth.spec.Spec

    Returns
    -------
    mapping
        Empty when the spec has no entry of that name and method.
    """
    for d in getattr(spec, "designs", ()):
        if d.name == doc["name"] and d.method == doc["method"]:
            return d.options
    return {}


def _option(doc: Mapping[str, Any], spec: Any, name: str, default: Any = None) -> Any:
    """An option of the artefact's design as validated (spec value, else the method's default)."""
    for d in getattr(spec, "designs", ()):
        if d.name == doc["name"] and d.method == doc["method"]:
            config = d.config if d.config is not None else d.options
            value = config.get(name) if hasattr(config, "get") else getattr(config, name, None)
            return default if value is None else value
    return default


def _matrix(doc: Mapping[str, Any], name: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    arr = np.atleast_2d(artefact_gain(doc, name))
    if shape is not None:
        if arr.size != shape[0] * shape[1]:
            raise ArtefactError(f"artefact '{doc['name']}': gain {name} has shape {arr.shape}, "
                                f"expected {shape}")
        arr = arr.reshape(shape)
    return arr


def _equilibrium(spec: Any) -> tuple[np.ndarray, np.ndarray]:
    from tanksynth.analysis.linearize import equilibrium_input

    eq = equilibrium_input(spec.plant, spec.x0, spec.given_u0)
    return np.asarray(spec.x0, dtype=float).copy(), np.asarray(eq.u0, dtype=float)


def _time_domain(doc: Mapping[str, Any], spec: Any) -> str:
    value = _option(doc, spec, "time_domain")
    if value in ("continuous", "discrete"):
        return str(value)
    return "discrete" if spec.ts is not None else "continuous"


def _fmt(values: Any, digits: int = 4) -> str:
    arr = np.asarray(values)
    if np.iscomplexobj(arr):
        return "[" + ", ".join(f"{complex(v).real:.{digits}g}{complex(v).imag:+.{digits}g}j"
                               if abs(complex(v).imag) > 0 else f"{complex(v).real:.{digits}g}"
                               for v in arr.ravel()) + "]"
    if arr.ndim > 1:
        return "[" + ", ".join(_fmt(row, digits) for row in arr) + "]"
    return np.array2string(arr, precision=digits, separator=", ", max_line_width=10_000)


def _complex_list(values: Any) -> list[list[float]]:
    return [[float(v.real), float(v.imag)] for v in np.sort_complex(np.asarray(values, dtype=complex))]


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def _output_rows(plant: Any, names: Sequence[str]) -> list[int]:
    outputs = [s.name for s in plant.outputs]
    missing = [n for n in names if n not in outputs]
    if missing:
        raise ArtefactError(f"tracked output(s) {missing} are not outputs of plant '{plant.name}' "
                            f"({outputs})")
    return [outputs.index(n) for n in names]


def _tracked_outputs(doc: Mapping[str, Any], spec: Any, option: str = "tracked") -> list[str]:
    chosen = _option(doc, spec, option)
    if isinstance(chosen, list) and chosen:
        return [str(c) for c in chosen]
    return [s.name for s in spec.plant.outputs][: spec.plant.m]


def _output_at(plant: Any, x: np.ndarray) -> np.ndarray:
    return np.asarray(plant.compiled.output(np.asarray(x, float)[None]), dtype=float).reshape(-1)


def _slowest_time_constant(eigs: np.ndarray, domain: str, ts: float | None) -> float:
    """Slowest time constant (s) of stable eigenvalues; inf if not stable."""
    eigs = np.asarray(eigs, dtype=complex)
    if domain == "discrete":
        rho = float(np.max(np.abs(eigs)))
        if not rho < 1:
            return math.inf
        if rho == 0:
            return float(ts)
        return float(-ts / math.log(rho))
    slow = float(np.min(-eigs.real))
    return 1.0 / slow if slow > 0 else math.inf


def _fastest_rate(eigs: np.ndarray, domain: str, ts: float | None) -> float:
    eigs = np.asarray(eigs, dtype=complex)
    if domain == "discrete":
        return 1.0 / float(ts)
    return float(np.max(np.abs(eigs)))


# ------------------------------------------------------------------------- re-checks
def _model_recheck(plant: Any, x0: np.ndarray, u0: np.ndarray, domain: str, ts: float | None,
                   stored: Mapping[str, np.ndarray]) -> Check:
    from tanksynth.analysis.linearize import linearize

    lin = linearize(plant, x0, u0, ts=ts if domain == "discrete" else None)
    ref = {"A": lin.Ad if domain == "discrete" else lin.F,
           "B": lin.Bd if domain == "discrete" else lin.B, "C": lin.C}
    diffs = {}
    for name, mat in stored.items():
        r = ref[name]
        diffs[name] = math.inf if mat.shape != r.shape else _rel(mat, r)
    worst = max(diffs.values())
    ok = bool(worst <= MODEL_TOLERANCE)
    what = f"exact ZOH at ts = {ts:g} s" if domain == "discrete" else "continuous Jacobians"
    return Check("model_recheck", ok,
                 f"stored {', '.join(stored)} against the plant linearised at the spec's operating "
                 f"point with the equilibrium input ({what}): largest relative difference "
                 f"{worst:.3g} (tolerance {MODEL_TOLERANCE:g})",
                 {"relative_differences": diffs, "tolerance": MODEL_TOLERANCE, "domain": domain})


def _pole_check(achieved: np.ndarray, requested: Sequence[complex], what: str) -> Check:
    from tanksynth.design.placement import pole_errors

    p = np.asarray(requested, dtype=complex)
    a = np.asarray(achieved, dtype=complex)
    if p.size != a.size:
        return Check("poles", False, f"{p.size} poles requested in the spec, {a.size} eigenvalues "
                                     f"of {what}", {"requested": _complex_list(p)})
    err, emax = pole_errors(p, a)
    rel = float(np.max(err / np.maximum(1.0, np.abs(p)))) if err.size else 0.0
    ok = bool(rel <= POLE_TOLERANCE)
    return Check("poles", ok,
                 f"eigenvalues of {what} recomputed from the artefact: {_fmt(np.sort_complex(a), 6)}; "
                 f"requested in the spec: {_fmt(np.sort_complex(p), 6)}; largest matched error "
                 f"{emax:.3g}, relative to max(1, |p|) {rel:.3g} (tolerance {POLE_TOLERANCE:g})",
                 {"achieved": _complex_list(a), "requested": _complex_list(p), "max_error": emax,
                  "max_relative_error": rel, "tolerance": POLE_TOLERANCE})


def _stability_check(eigs: np.ndarray, domain: str, what: str) -> Check:
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


def _region_check(eigs: np.ndarray, region: Any, what: str) -> Check:
    margins = np.array([region.margin(complex(z)) for z in np.asarray(eigs, dtype=complex)])
    worst = float(np.min(margins))
    return Check("region", bool(worst > 0),
                 f"eigenvalues of {what} {_fmt(np.sort_complex(eigs), 6)} against the spec's region "
                 f"{region.describe()}: smallest margin -lambda_max(f_D(z)) = {worst:.3g} (must be > 0)",
                 {"margins": margins.tolist(), "region": region.describe()})


def _region_lmi_check(region: Any, Acl: np.ndarray, X: np.ndarray, what: str) -> Check:
    # placement._d_lmi is the design's own block builder (no second implementation here).
    from tanksynth.design.placement import _d_lmi

    M = _d_lmi(region, Acl @ X, X, np.kron)
    M = 0.5 * (M + M.T)
    eig = np.linalg.eigvalsh(M)
    lam = float(eig.max())
    scale = float(np.max(np.abs(eig))) or 1.0
    xmin = float(np.min(np.linalg.eigvalsh(0.5 * (X + X.T))))
    ok = bool(lam < 0 and xmin > 0)
    return Check("lmi_recheck", ok,
                 f"region LMI of {what} recomputed in numpy from the stored P: largest eigenvalue "
                 f"{lam:.4g} (relative {lam / scale:.3g}; must be < 0), smallest eigenvalue of X "
                 f"{xmin:.4g} (must be > 0)",
                 {"lmi_max_eigenvalue": lam, "relative": lam / scale, "X_min_eigenvalue": xmin})


def _rank_check(name: str, result: Any, pair: str) -> Check:
    return Check(name, bool(result.full),
                 f"rank {result.rank}/{result.n} of {pair} stored in the artefact, condition number "
                 f"{result.condition_number:.3g}", result.as_dict())


# ====================================================================== law adapters
class CasadiControlLaw:
    """A `ControlLaw` from a CasADi Function ``(x_hat, reference) -> u`` (batch over runs).

    The Function is evaluated on the M runs at once (``Function.map``);
    only its first output is used (feedback-linearisation laws also return
    ``zeta``).

    Parameters
    ----------
    function : casadi.Function
        Inputs ``x_hat`` (n) and the reference (r), first output ``u`` (m).
    """

    def __init__(self, function: Any):
        self.function = function
        self._mapped: dict[int, Any] = {}

    def evaluate(self, *args: np.ndarray) -> list[np.ndarray]:
        """Every output of the Function at M points: inputs (M, k_i) -> outputs (M, k_j)."""
        count = int(args[0].shape[0])
        fn = self._mapped.get(count)
        if fn is None:
            fn = self.function.map(count, "serial") if count > 1 else self.function
            self._mapped[count] = fn
        outs = fn(*[np.asarray(a, dtype=float).T for a in args])
        outs = outs if isinstance(outs, (list, tuple)) else [outs]
        return [np.asarray(o, dtype=float).reshape(-1, count).T for o in outs]

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m) for the estimate (M, n) and the reference (M, r)."""
        return self.evaluate(x_hat, reference)[0]


class CasadiIntegralLaw(CasadiControlLaw):
    """A stateful `ControlLaw` from ``(x, z, y_r) -> (u, z_next)`` (integral tracking).

    Parameters
    ----------
    function : casadi.Function
        `tanksynth.design.control.integral_tracking_law` signature.
    """

    def __init__(self, function: Any):
        super().__init__(function)
        self.z = np.zeros((0, int(function.nnz_in(1))))

    def reset(self, runs: int) -> None:
        """Zero the integrators of ``runs`` runs."""
        self.z = np.zeros((int(runs), int(self.function.nnz_in(1))))

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m); advances the integrator state."""
        u, z_next = self.evaluate(x_hat, self.z, reference)[:2]
        self.z = z_next
        return u


# ========================================================================= observers
def luenberger_estimator(plant: Any, L: np.ndarray, x0: np.ndarray, u0: np.ndarray, ts: float,
                         form: str) -> EstimatorAdapter:
    """The estimator stage's Luenberger observer on the model linearised at ``(x0, u0)``.

    `tanksynth.runtime.estimators.luenberger.LuenbergerObserver` (the one
    implementation), wrapped by `EstimatorAdapter`: ``form = "predictor"``
    (error matrix ``Ad - L C``, discrete designs), ``"current"`` (``(I - L
    C) Ad``) or ``"continuous"`` (``F - L C``, integrated exactly over each
    period with the input and the sampled measurement held).

    Parameters
    ----------
    plant : Plant
    L : ndarray, shape (n, q)
    x0, u0 : ndarray
        Operating point and its equilibrium input.
    ts : float
        Sampling period (s).
    form : {"predictor", "current", "continuous"}

    Returns
    -------
    EstimatorAdapter
    """
    from tanksynth.runtime.estimators.luenberger import LuenbergerObserver, LuenbergerTuning

    tuning = LuenbergerTuning(L=np.asarray(L, dtype=float), x0=np.asarray(x0, dtype=float),
                              ts=float(ts), form=form, operating_point=(x0, u0))
    return EstimatorAdapter(LuenbergerObserver(plant, tuning))


class TSObserver:
    """Multiple observer of seed 001 eq. (20), continuous time (a `BatchEstimator`).

    Same observer as `tanksynth.runtime.estimators.luenberger.TSMultiObserver`,
    integrated differently: that one uses explicit RK4, which is unstable for
    stiff LMI gains (``ts_observer_paper_safe`` has an error eigenvalue of
    about -1.3e5 1/s) unless the step is below ``2.8 / |lambda|``; the
    exponential rule here is exact on the linear part at any step.

    ``dx_hat/dt = sum_i mu_i(x_hat) (A_i x_hat + B u) + d + L (y - C x_hat)``
    (the TS model `TSModel.rhs` at the estimate, premises unmeasured),
    integrated by the exponential Euler rule on the split ``(A0 - L C) x_hat
    + g(x_hat, u, y)``: exact for the (possibly very stiff) linear part,
    first order in the Lipschitz remainder; the measurement is held over
    each period.

    Parameters
    ----------
    model : tanksynth.design.takagi_sugeno.TSModel
    L : ndarray, shape (n, q)
    ts : float
        Sampling period (s).
    substeps : int
        Exponential-Euler steps per period.
    """

    def __init__(self, model: Any, L: np.ndarray, ts: float, substeps: int = 8):
        from tanksynth.analysis.linearize import discretize_zoh

        self.model = model
        self.L = np.asarray(L, dtype=float)
        self.A0 = np.asarray(model.A0, dtype=float)
        self.C = np.asarray(model.C, dtype=float)
        self.substeps = int(substeps)
        n = self.A0.shape[0]
        self._phi, self._gamma = discretize_zoh(self.A0 - self.L @ self.C, np.eye(n),
                                                float(ts) / self.substeps)
        self._x: np.ndarray | None = None
        self._y: np.ndarray | None = None

    def reset(self, x_hat0: np.ndarray) -> None:
        """Initial estimates (M, n)."""
        self._x = np.asarray(x_hat0, dtype=float).copy()
        self._y = None

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Measurement (M, q), previous input (M, m) -> estimate (M, n)."""
        if self._y is not None:
            x = self._x
            for _ in range(self.substeps):
                g = self.model.rhs(x, u) - x @ self.A0.T + self._y @ self.L.T
                x = x @ self._phi.T + g @ self._gamma.T
            if not np.all(np.isfinite(x)):
                raise TanksynthError("the TS observer's estimate became non-finite (premise "
                                     "denominator w . x_hat = 0?)")
            self._x = x
        self._y = np.array(y, dtype=float)
        return self._x


def _perturbed_start(plant: Any, x0: np.ndarray, inside: Callable[[np.ndarray], bool] | None = None
                     ) -> tuple[np.ndarray, float]:
    """``x0 + delta`` in the region (and ``inside``), delta = 5 % of the span, alternating signs."""
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    span = hi - lo
    span = np.where(np.isfinite(span) & (span > 0), span, np.maximum(np.abs(x0), 1.0))
    n = x0.size
    base = PERTURBATION * span
    patterns = [np.array([1.0 if (i + k) % 2 == 0 else -1.0 for i in range(n)]) for k in range(2)]
    patterns += [np.ones(n), -np.ones(n)]
    patterns += [np.array([1.0 if i == j else 0.0 for i in range(n)]) for j in range(min(n, 8))]
    for scale in (1.0, 0.5, 0.25, 0.1):
        for sgn in patterns:
            x = x0 + scale * base * sgn
            if np.all(x >= lo) and np.all(x <= hi) and not plant.region.violations(x, plant.x) \
                    and (inside is None or inside(x)):
                return x, scale * PERTURBATION
    raise TanksynthError("no perturbed start x0 + delta (delta up to 5 % of the region span) lies in "
                         "the operating region" + (" and the TS domain" if inside else ""))


def observer_convergence(plant: Any, estimator: BatchEstimator, x0: np.ndarray, u0: np.ndarray,
                         tau: float, ts: float, *, conditioning: float = 1.0,
                         inside: Callable[[np.ndarray], bool] | None = None,
                         rule: str = "", substeps: int = 4, name: str = "observer_convergence",
                         outside: Callable[[np.ndarray], np.ndarray] | None = None) -> Check:
    """Estimation error of an observer on the nonlinear plant, started away from it.

    The plant starts at ``x0 + delta`` (see `PERTURBATION`) and holds the
    input ``u0``; the estimate starts at ``x0``. With ``H = tau (5 + ln
    kappa)`` (``kappa`` the condition number of the error matrix's
    eigenvectors: ``|e(t)| <= kappa exp(-t / tau) |e(0)|`` for the linear
    error dynamics, so a non-normal, peaking observer gets the time its
    transient needs) the check passes if ``|x_hat - x|_inf <= 5 %`` of the
    initial error at every sample of ``[H, 1.2 H]``.

    Parameters
    ----------
    plant : Plant
    estimator : BatchEstimator
    x0, u0 : ndarray
        Operating point and input.
    tau : float
        Slowest designed error time constant (s).
    ts : float
        Sampling period of the simulation (s).
    conditioning : float
        Condition number ``kappa`` of the eigenvector matrix of the designed
        error dynamics (>= 1; capped at 1e8).
    inside : callable, optional
        Extra condition on the plant's start (e.g. the TS domain).
    rule : str
        How ``tau`` was obtained (for the detail).
    substeps : int
        RK4 steps per period for the plant.
    name : str
        Name of the check.
    outside : callable, optional
        ``outside(X) -> bool array`` on estimates (N, n): samples reported
        as outside the observer's validity domain (e.g. the TS domain).

    Returns
    -------
    Check
    """
    if not np.isfinite(tau) or tau <= 0:
        return Check(name, False, f"no finite error time constant (tau = {tau}): the designed error "
                                  "dynamics are not stable, nothing to converge")
    kappa = float(min(max(conditioning, 1.0), 1e8)) if np.isfinite(conditioning) else 1e8
    factor = OBSERVER_TIME_CONSTANTS + math.log(kappa)
    horizon = factor * tau
    k_h = max(int(math.ceil(horizon / ts)), 1)
    steps = max(int(math.ceil(1.2 * horizon / ts)), k_h + 1)
    if steps > MAX_STEPS:
        return Check(name, None, f"not simulated: the horizon {horizon:.3g} s needs {steps} samples "
                                 f"of {ts:.3g} s (> {MAX_STEPS})")
    x_start, frac = _perturbed_start(plant, x0, inside)
    res = simulate(plant, ts=ts, steps=steps, x0=x_start, seeds=run_seeds(0, 1), estimator=estimator,
                   x_hat0=x0, u_init=u0, substeps=substeps)
    record_trace(res, plant, check=name, estimator=True,
                 scenario="initial-state mismatch: plant from x0 + delta, estimate from x0, "
                          "equilibrium input held")
    err = np.max(np.abs(res.x_hat[0] - res.x[0]), axis=1)
    e0 = float(err[0])
    tail = float(np.max(err[k_h:]))
    tol = OBSERVER_TOLERANCE * e0
    ok = bool(np.all(np.isfinite(err)) and tail <= tol)
    where = ""
    if outside is not None:
        out = np.asarray(outside(res.x_hat[0]), dtype=bool)
        where = (f"; the estimate is outside the domain at {int(out.sum())} of {out.size} samples"
                 + (f" (first at t = {float(res.t[np.argmax(out)]):.4g} s)" if out.any() else ""))
    return Check(name, ok,
                 f"plant from x0 + delta ({100 * frac:g} % of the region span), estimate from x0, "
                 f"equilibrium input held, nonlinear plant sampled every {ts:.4g} s: |e|_inf = "
                 f"{e0:.3g} at t = 0, largest on [H, 1.2 H] = {tail:.3g} (tolerance {tol:.3g} = "
                 f"{100 * OBSERVER_TOLERANCE:g} % of |e(0)|); rule H = tau ({OBSERVER_TIME_CONSTANTS:g} "
                 f"+ ln kappa) = {factor:.3g} tau = {horizon:.4g} s with kappa = {kappa:.3g} (eigenvector "
                 f"conditioning of the error matrix), tau = {tau:.4g} s {rule}".rstrip() + where,
                 {"e0": e0, "tail_max": tail, "tolerance": tol, "horizon_s": horizon, "tau_s": tau,
                  "kappa": kappa, "ts": ts, "x_start": x_start.tolist(), "error_inf": err.tolist()})


def _conditioning(M: np.ndarray) -> float:
    """Condition number of the eigenvector matrix of ``M`` (inf if defective)."""
    _, V = np.linalg.eig(M)
    with np.errstate(all="ignore"):
        value = float(np.linalg.cond(V))
    return value if np.isfinite(value) else math.inf


def _observer_ts(domain: str, spec_ts: float | None, tau: float) -> float:
    if domain == "discrete":
        return float(spec_ts)
    step = tau / 20.0
    return float(min(spec_ts, step)) if spec_ts else float(step)


def _region_tau(region: Any, domain: str, ts: float | None) -> float:
    """Slowest time constant an LMI region guarantees (inf when it bounds no decay)."""
    best = math.inf
    for part in region.parts:
        if domain == "continuous":
            rate = part[1] if part[0] == "half_plane" else (-(part[1] + part[2]) if part[0] == "disk"
                                                            else 0.0)
            if rate > 0:
                best = min(best, 1.0 / rate)
        elif part[0] == "disk" and abs(part[1]) + part[2] < 1:
            rho = abs(part[1]) + part[2]
            best = min(best, float(ts) if rho == 0 else -float(ts) / math.log(rho))
    return best


def _designed_tau(doc: Mapping[str, Any], spec: Any, eigs: np.ndarray, domain: str,
                  ts: float | None) -> tuple[float, str]:
    """Slowest time constant the DESIGN asks for (spec poles or region), else of the stored gain."""
    from tanksynth.analysis.lmi_region import region_from_parts
    from tanksynth.spec.options import parse_poles, parse_region

    poles = _option(doc, spec, "poles")
    if poles is not None:
        p = np.asarray(parse_poles(poles, "poles"), dtype=complex)
        tau, rule = _observer_tau(p, domain, ts)
        return tau, rule.replace("(", "(of the poles requested in the spec: ", 1)
    raw = _option(doc, spec, "region")
    if raw is not None:
        region = region_from_parts(parse_region(raw, "region"))
        tau = _region_tau(region, domain, ts)
        if np.isfinite(tau):
            return tau, f"(the decay guaranteed by the spec's region {region.describe()})"
    tau, rule = _observer_tau(eigs, domain, ts)
    return tau, rule.replace("(", "(of the stored gain's matrix: ", 1)


def _observer_tau(eigs: np.ndarray, domain: str, ts: float | None) -> tuple[float, str]:
    tau = _slowest_time_constant(eigs, domain, ts)
    if domain == "discrete":
        rule = f"(-ts / ln max|lambda|, max|lambda| = {np.max(np.abs(eigs)):.6g})"
    else:
        rule = f"(1 / min|Re lambda|, min|Re lambda| = {np.min(-np.asarray(eigs).real):.6g} 1/s)"
    return tau, rule


# ====================================================================== control loops
def _servo_check(plant: Any, controller: Callable, x0: np.ndarray, u0: np.ndarray,
                 out_idx: Sequence[int], tau: float, ts: float, substeps: int = 4,
                 rule: str = "") -> list[Check]:
    """Step the tracked set-points by 5 % and check steady tracking and bounded inputs."""
    if not np.isfinite(tau) or tau <= 0:
        return [Check("servo_tracking", False, f"the closed loop has no finite time constant "
                                               f"(tau = {tau}): not stable")]
    y0 = _output_at(plant, x0)[list(out_idx)]
    step = PERTURBATION * np.where(np.abs(y0) > 0, np.abs(y0), 1.0)
    k_step = 5
    steps = k_step + max(int(math.ceil(SERVO_TIME_CONSTANTS * tau / ts)), 10)
    if steps > MAX_STEPS:
        return [Check("servo_tracking", None, f"not simulated: {steps} samples of {ts:g} s needed "
                                              f"(> {MAX_STEPS})")]
    ref = np.tile(y0, (steps + 1, 1))
    ref[k_step:] += step
    res = simulate(plant, ts=ts, steps=steps, x0=x0, seeds=run_seeds(0, 1), controller=controller,
                   reference=ref, u_init=u0, substeps=substeps)
    record_trace(res, plant, check="servo_tracking",
                 reference_names=[plant.outputs[i].name for i in out_idx],
                 scenario=f"set-point step of 5 % at t = {k_step * ts:g} s (servo)")
    y = res.y[0][:, list(out_idx)]
    err = ref - y
    window = max(1, (steps + 1) // 10)
    final = float(np.max(np.abs(err[-window:]) / step))
    lim = plant.input_limits
    u = res.u[0]
    lo, hi = lim[:, 0], lim[:, 1]
    tail_u = u[-window:]
    inside = bool(np.all(np.isfinite(u)) and np.all(tail_u > lo) and np.all(tail_u < hi))
    saturated = int(np.sum(np.any((u <= lo) | (u >= hi), axis=1)))
    names = [plant.outputs[i].name for i in out_idx]
    ok = bool(np.all(np.isfinite(err)) and final <= SERVO_TOLERANCE)
    checks = [Check("servo_tracking", ok,
                    f"set-points of {names} step by {_fmt(step)} (5 % of their operating values) at "
                    f"t = {k_step * ts:g} s, nonlinear plant with pump saturation, sampled every "
                    f"{ts:g} s; largest tracking error over the last {window} samples "
                    f"{100 * final:.3g} % of the step (tolerance {100 * SERVO_TOLERANCE:g} %); "
                    f"horizon {SERVO_TIME_CONSTANTS:g} tau = {steps * ts:.4g} s with tau = {tau:.4g} s "
                    f"{rule or '(slowest closed-loop pole)'}",
                    {"step": step.tolist(), "final_relative_error": final, "tau_s": tau, "ts": ts,
                     "steps": steps, "tolerance": SERVO_TOLERANCE}),
              Check("bounded_inputs", inside,
                    f"inputs finite, {saturated} of {steps} samples at an actuator limit, and strictly "
                    f"inside the range {_fmt(lim)} over the last {window} samples "
                    f"(final input {_fmt(u[-1])})",
                    {"saturated_samples": saturated, "final_input": u[-1].tolist()})]
    return checks


@dataclass
class _StateFeedback:
    """``u = u0 - K (x - x0)`` (regulation check)."""

    K: np.ndarray
    x0: np.ndarray
    u0: np.ndarray

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        return self.u0 - (x_hat - self.x0) @ self.K.T


def _regulation_check(plant: Any, K: np.ndarray, x0: np.ndarray, u0: np.ndarray, tau: float,
                      ts: float, conditioning: float = 1.0, rule: str = "") -> Check:
    if not np.isfinite(tau) or tau <= 0:
        return Check("regulation", False, f"the closed loop has no finite time constant (tau = {tau})")
    kappa = float(min(max(conditioning, 1.0), 1e8)) if np.isfinite(conditioning) else 1e8
    factor = OBSERVER_TIME_CONSTANTS + math.log(kappa)
    horizon = factor * tau
    k_h = max(int(math.ceil(horizon / ts)), 1)
    steps = max(int(math.ceil(1.2 * horizon / ts)), k_h + 1)
    if steps > MAX_STEPS:
        return Check("regulation", None, f"not simulated: {steps} samples needed (> {MAX_STEPS})")
    x_start, frac = _perturbed_start(plant, x0)
    res = simulate(plant, ts=ts, steps=steps, x0=x_start, seeds=run_seeds(0, 1),
                   controller=_StateFeedback(K, x0, u0), u_init=u0)
    record_trace(res, plant, check="regulation",
                 scenario="regulation to x0 from x0 + delta, u = u0 - K (x - x0)")
    dev = np.max(np.abs(res.x[0] - x0), axis=1)
    tail = float(np.max(dev[k_h:]))
    tol = OBSERVER_TOLERANCE * float(dev[0])
    return Check("regulation", bool(np.all(np.isfinite(dev)) and tail <= tol),
                 f"u = u0 - K (x - x0) on the nonlinear plant from x0 + delta ({100 * frac:g} % of the "
                 f"region span), sampled every {ts:.4g} s: |x - x0|_inf = {dev[0]:.3g} at t = 0, "
                 f"largest on [H, 1.2 H] = {tail:.3g} (tolerance {tol:.3g} = "
                 f"{100 * OBSERVER_TOLERANCE:g} %); rule H = tau ({OBSERVER_TIME_CONSTANTS:g} + ln kappa) "
                 f"= {factor:.3g} tau = {horizon:.4g} s, kappa = {kappa:.3g} (eigenvector conditioning of "
                 f"the closed loop), tau = {tau:.4g} s {rule or '(slowest closed-loop pole)'}",
                 {"tail_max": tail, "tolerance": tol, "tau_s": tau, "kappa": kappa, "ts": ts})


def _augment_continuous(A: np.ndarray, B: np.ndarray, C1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``[x; z]' = [[A, 0], [-C1, 0]] [x; z] + [B; 0] u`` (integral of ``r - C1 x``)."""
    n, p, m = A.shape[0], C1.shape[0], B.shape[1]
    Aa = np.block([[A, np.zeros((n, p))], [-C1, np.zeros((p, p))]])
    Ba = np.vstack([B, np.zeros((p, m))])
    return Aa, Ba




def _safe(fn: Callable[[Mapping[str, Any], Any], list[Check]]) -> Callable[[Mapping[str, Any], Any],
                                                                       list[Check]]:
    """A verdict whose numerical errors become one failed check (never a traceback in `verify`)."""

    def verdict(doc: Mapping[str, Any], spec: Any) -> list[Check]:
        return _guard("verification", lambda: fn(doc, spec))

    verdict.__name__ = getattr(fn, "__name__", "verdict")
    verdict.__doc__ = fn.__doc__
    return verdict
