"""Exports beside an artefact: C header of the gains, control laws as CasADi files and generated C,
and the contents of the ``.mat`` file.

The ``.mat`` file and the C header carry what is needed to implement the design
elsewhere, besides the gains: the sampling period ``ts``, the operating point
``x_op``/``u_op`` (also as ``x0``/``u0`` unless a gain has that name, e.g. an
estimator's initial estimate) and the state, input and output names and units
(`implementation_data`). Vectors are columns in both (MATLAB's orientation).
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence, TypeVar

import casadi as ca
import numpy as np

from tanksynth.artefacts.atomic import commit
from tanksynth.errors import ArtefactError
from tanksynth.runtime.laws import c_identifier, rename_law
from tanksynth.spec.method_options.base import MethodOptions

if TYPE_CHECKING:  # annotations only: the runtime estimators load with the law that needs them
    from tanksynth.plants.base import Plant
    from tanksynth.runtime.estimators.base import KernelEstimator
    from tanksynth.runtime.estimators.kalman import KalmanTuning
    from tanksynth.spec import Spec

_Options = TypeVar("_Options", bound=MethodOptions)

__all__ = ['c_header', 'ExportedLaw', 'export_law', 'compile_law', 'load_compiled_law',
           'implementation_data', 'mat_contents', 'DERIVED_LAW_METHODS', 'state_feedback_law', 'saturate_input',
           'observer_law', 'kalman_step', 'estimator_step', 'derived_law', 'operating_point',
           'sampling_period']


#: File stems `export_law` keeps as given (else the C symbol is the stem).
_FILE_STEM = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")


@dataclass(frozen=True)
class ExportedLaw:
    """Files of an exported law.

    Attributes
    ----------
    function : str
        C symbol / CasADi Function name.
    casadi : Path
        ``<name>.casadi`` (``Function.save``; load with ``casadi.Function.load``).
    c_source, c_header : Path
        ``<name>.c`` and ``<name>.h`` (CasADi codegen; ``int <function>(const
        casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w,
        int mem)`` plus the work-size helpers).
    sha256 : dict
        sha256 of each file.
    """

    function: str
    casadi: Path
    c_source: Path
    c_header: Path
    sha256: dict



def export_law(law: ca.Function, directory: str | Path, name: str | None = None) -> ExportedLaw:
    """Write the law as ``<name>.casadi``, ``<name>.c`` and ``<name>.h``, atomically.

    Everything is generated in a temporary directory beside the targets and
    renamed only when all files exist; a failure leaves nothing behind.

    Parameters
    ----------
    law : casadi.Function
        An SX Function (as built by this module).
    directory : str or Path
        Created if missing.
    name : str, optional
        File stem (kept as given when it is a file name of letters, digits, ``_``, ``.``
        and ``-``, e.g. ``1a_law`` beside the artefact ``1a.json``) and C symbol (made a C
        identifier, `tanksynth.runtime.laws.c_identifier`: ``law_1a_law``); default the
        law's name.

    Returns
    -------
    ExportedLaw
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    fn = rename_law(law, name or law.name())
    stem = fn.name()
    file_stem = name if name is not None and _FILE_STEM.fullmatch(name) else stem
    final = {ext: directory / f"{file_stem}{ext}" for ext in (".casadi", ".c", ".h")}
    # CasADi's code generator refuses an output prefix that contains
    # "<stem>.c" (a guard for its old API); such a target directory is built
    # in the system temp directory, then copied beside the targets.
    tmpdir = Path(tempfile.mkdtemp(prefix=".law-build-", suffix=".tmp", dir=directory))
    build = tmpdir
    renamed: list[Path] = []
    try:
        if f"{stem}.c" in str(tmpdir) + os.sep:
            build = Path(tempfile.mkdtemp(prefix="tanksynth-law-"))
        fn.save(str(build / f"{stem}.casadi"))
        cg = ca.CodeGenerator(f"{stem}.c", {"with_header": True})
        cg.add(fn)
        cg.generate(str(build) + os.sep)
        for ext, target in final.items():
            built = build / f"{stem}{ext}"  # CasADi names its files after the C symbol
            if not built.is_file():
                raise ArtefactError(f"export of law '{stem}': {built.name} was not generated")
            if build != tmpdir:
                shutil.copyfile(built, tmpdir / target.name)
            elif built.name != target.name:
                built.rename(tmpdir / target.name)
        try:
            for ext in (".c", ".h", ".casadi"):
                renamed.append(commit(tmpdir / final[ext].name, final[ext]))
        except BaseException:
            for path in renamed:
                path.unlink(missing_ok=True)
            raise
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
        if build != tmpdir:
            shutil.rmtree(build, ignore_errors=True)
    digests = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in final.values()}
    return ExportedLaw(stem, final[".casadi"], final[".c"], final[".h"], digests)



def compile_law(c_source: str | Path, output: str | Path | None = None, *, compiler: str = "gcc",
                flags: Sequence[str] = ("-O2",)) -> Path:
    """Compile generated C into a shared library.

    Parameters
    ----------
    c_source : str or Path
        ``<name>.c`` from `export_law`.
    output : str or Path, optional
        Library path (default ``<name>.so`` beside the source).
    compiler : str
        C compiler command.
    flags : sequence of str
        Extra flags (``-shared -fPIC`` are always added).

    Returns
    -------
    Path

    Raises
    ------
    ArtefactError
        Compiler missing or compilation failed (with its message).
    """
    src = Path(c_source)
    out = Path(output) if output is not None else src.with_suffix(".so")
    cmd = [compiler, "-shared", "-fPIC", *flags, "-o", str(out), str(src), "-lm"]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    except FileNotFoundError:
        raise ArtefactError(f"C compiler {compiler!r} not found; cannot compile {src}") from None
    if proc.returncode != 0:
        raise ArtefactError(f"compiling {src} failed ({' '.join(cmd)}): {proc.stderr.strip()[:2000]}")
    return out



def load_compiled_law(library: str | Path, function: str) -> ca.Function:
    """Load a compiled law (``casadi.external``) to evaluate the C code from Python.

    Parameters
    ----------
    library : str or Path
        The shared library of `compile_law`.
    function : str
        The C symbol (the law's name).
    """
    path = Path(library)
    if not path.is_file():
        raise ArtefactError(f"compiled law {path} not found")
    return ca.external(function, str(path.resolve()))


def implementation_data(diagnostics: Mapping[str, Any], plant_record: Mapping[str, Any] | None
                        ) -> dict[str, Any]:
    """Sampling period, operating point and signal names/units of a design, for exports.

    Parameters
    ----------
    diagnostics : mapping
        The design's diagnostics (``equilibrium`` gives ``x0``/``u0`` when the
        design computed it; ``ts`` or ``sampling_period`` the period).
    plant_record : mapping or None
        ``plant.json`` of the result directory (`tanksynth.artefacts.io.write_plant_record`):
        operating point, sampling period, signal names and units.

    Returns
    -------
    dict
        ``ts`` (s, NaN without sampling), ``x_op`` (state units), ``u_op`` (input
        units, NaN entries when unknown), and ``state_names``, ``state_units``,
        ``input_names``, ``input_units``, ``output_names``, ``output_units``
        (lists of str, empty when unknown).
    """
    record = plant_record or {}
    eq = diagnostics.get("equilibrium") if isinstance(diagnostics, Mapping) else None
    eq = eq if isinstance(eq, Mapping) else {}
    op = record.get("operating_point") or {}
    ts = record.get("ts", diagnostics.get("ts", diagnostics.get("sampling_period")))
    summary = record.get("plant") or {}
    out: dict[str, Any] = {"ts": float("nan") if ts is None else float(ts)}
    x_op = eq.get("x0", op.get("x"))
    u_op = eq.get("u0", op.get("u"))
    n_inputs = len(summary.get("inputs", ()))
    out["x_op"] = np.asarray(x_op if x_op is not None else [], dtype=float).reshape(-1)
    out["u_op"] = (np.asarray(u_op, dtype=float).reshape(-1) if u_op is not None
                   else np.full(n_inputs, np.nan))
    for what in ("state", "input", "output"):
        signals = summary.get(f"{what}s", ())
        out[f"{what}_names"] = [str(v["name"]) for v in signals]
        out[f"{what}_units"] = [str(v["unit"]) for v in signals]
    return out


def mat_contents(gains: Mapping[str, np.ndarray], data: Mapping[str, Any]) -> dict[str, Any]:
    """The variables of ``<name>.mat``: the gains and `implementation_data`, vectors as columns.

    Parameters
    ----------
    gains : mapping of str to ndarray
        The design's gains (a 1-D gain becomes an n x 1 column), in the plant's units.
    data : mapping
        `implementation_data` of the design.

    Returns
    -------
    dict
        For ``scipy.io.savemat``: arrays as columns or matrices, names and
        units as n x 1 cell arrays of strings, ``ts`` a 1 x 1 double; ``x_op``
        and ``u_op`` the operating point (the gains of that name when the
        design stores them). No ``x0``: an estimator's initial estimate is the
        gain ``x_hat0`` (the naming rule, `model_names`).
    """
    def column(value: Any) -> np.ndarray:
        arr = np.asarray(value, dtype=float)
        return arr.reshape(-1, 1) if arr.ndim <= 1 else arr

    out: dict[str, Any] = {k: column(v) for k, v in gains.items()}
    out["ts"] = np.array([[float(data["ts"])]])
    out.setdefault("x_op", column(data["x_op"]))
    out.setdefault("u_op", column(data["u_op"]))
    for key in ("state_names", "state_units", "input_names", "input_units", "output_names",
                "output_units"):
        cells = np.empty((len(data[key]), 1), dtype=object)
        for i, text in enumerate(data[key]):
            cells[i, 0] = text
        out[key] = cells
    return out


def c_header(name: str, gains: Mapping[str, np.ndarray], data: Mapping[str, Any] | None = None) -> str:
    """A C header with every gain as a ``static const double`` array (row-major).

    Each gain gets ``<NAME>_<GAIN>_NDIM`` and one ``_DIM<k>`` macro per axis
    (``_ROWS``/``_COLS`` too for 1-D and 2-D gains; a 1-D gain is a column).

    Parameters
    ----------
    name : str
        The design's name (prefix of every symbol).
    gains : mapping of str to ndarray
        The gains (in the plant's units, e.g. input units per state unit).
    data : mapping, optional
        `implementation_data`: adds ``<NAME>_TS`` (s), the arrays ``x_op`` and
        ``u_op`` (columns, as in the ``.mat`` file) and a comment listing the
        states, inputs and outputs with their units.

    Returns
    -------
    str
        The header text.
    """
    def ident(text: str) -> str:
        out = "".join(c if c.isalnum() else "_" for c in text)
        return out if out[:1].isalpha() else "d_" + out

    stem = ident(name)
    guard = "TANKSYNTH_" + stem.upper() + "_H"
    lines = [f"/* Gains of design '{name}', generated by tanksynth. Row-major. */",
             f"#ifndef {guard}", f"#define {guard}", ""]
    arrays = dict(gains)
    if data is not None:
        lines += ["#include <math.h> /* NAN: an entry of the operating point that is unknown */", ""]
        for what in ("state", "input", "output"):
            listed = ", ".join(f"{n} [{u}]" for n, u in zip(data[f"{what}_names"], data[f"{what}_units"]))
            lines.append(f"/* {what}s: {listed or 'unknown'} */")
        if np.isfinite(data["ts"]):
            lines.append(f"#define {stem.upper()}_TS {float(data['ts'])!r} /* sampling period, s */")
        lines.append("")
        arrays.setdefault("x_op", data["x_op"])
        arrays.setdefault("u_op", data["u_op"])
    for gname, value in arrays.items():
        arr = np.asarray(value, dtype=float)
        if arr.ndim == 0:
            arr = arr.reshape(1, 1)
        elif arr.ndim == 1:
            arr = arr.reshape(-1, 1)
        cname = f"{stem}_{ident(gname)}"
        macro = cname.upper()
        lines.append(f"#define {macro}_NDIM {arr.ndim}")
        for k, dim in enumerate(arr.shape):
            lines.append(f"#define {macro}_DIM{k} {dim}")
        if arr.ndim == 2:
            lines.append(f"#define {macro}_ROWS {arr.shape[0]}")
            lines.append(f"#define {macro}_COLS {arr.shape[1]}")
        values = ", ".join(repr(float(v)) if np.isfinite(v) else "NAN" for v in arr.ravel())
        lines.append(f"static const double {cname}[{max(arr.size, 1)}] = {{{values or '0.0'}}};")
        lines.append("")
    lines.append(f"#endif /* {guard} */")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ laws derived from gains
#: Methods whose law `derived_law` builds from the artefact's gains (the others either carry
#: their law in the diagnostics or have none to export).
DERIVED_LAW_METHODS = ("pole_placement", "lmi_placement", "canonical_observer", "luenberger",
                       "kalman", "ekf", "ukf")


def _output_at(plant: Plant, x: np.ndarray) -> np.ndarray:
    values = dict(zip(plant.x, (float(v) for v in x)))
    return np.array(plant.h_numeric.subs(values), dtype=float).reshape(-1)


def saturate_input(u: Any, limits: Any | None) -> Any:
    """``u`` clipped to the actuator range, element by element (infinite bounds leave it free).

    Parameters
    ----------
    u : casadi.SX, shape (m, 1)
        The law's input (input units).
    limits : array_like, shape (m, 2), or None
        ``(lower, upper)`` per input (input units); None: ``u`` unchanged.
    """
    if limits is None:
        return u
    lim = np.asarray(limits, dtype=float).reshape(-1, 2)
    parts = []
    for j in range(lim.shape[0]):
        v = u[j]
        if np.isfinite(lim[j, 0]):
            v = ca.fmax(v, float(lim[j, 0]))
        if np.isfinite(lim[j, 1]):
            v = ca.fmin(v, float(lim[j, 1]))
        parts.append(v)
    return ca.vertcat(*parts)


def state_feedback_law(name: str, K: np.ndarray, x_op: np.ndarray, u_op: np.ndarray,
                       integral: Mapping[str, Any] | None = None, Br: np.ndarray | None = None,
                       continuous: bool = False, input_limits: Any | None = None) -> ca.Function:
    """The state feedback ``u = u_op - K (x - x_op)`` of a linear design, with integral action.

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    K : ndarray
        The gain, m x n, or m x (n + p) with integral action (input units per
        state unit).
    x_op, u_op : ndarray
        Operating point (state and input units).
    integral : mapping, optional
        The design's ``integral`` diagnostics (``C1``, ``augmented_A``) when
        the gain has integral action.
    Br : ndarray, optional
        Reference input matrix of the augmented system ((n + p) x p).
    continuous : bool
        Continuous-time design: the integrator output is ``z_dot``, not ``z_next``.
    input_limits : array_like, shape (m, 2), optional
        Actuator range (input units): ``u`` is clipped to it, as the plant the
        verdict simulates clips it (the integrators are not: that loop has no
        anti-windup either). None: unclipped.

    Returns
    -------
    casadi.Function
        ``u = law(x)``; with integral action ``u, z_next = law(x, z, y_r)``
        (``z_dot`` in continuous time), ``u = u_op - K1 (x - x_op) - K2 z`` and
        the integrators as designed (``z_next = z + (y_r - C1 x)`` on the ZOH
        model; ``y_r`` the references of the tracked outputs).
    """
    K = np.asarray(K, dtype=float)
    x_op, u_op = np.asarray(x_op, dtype=float), np.asarray(u_op, dtype=float)
    n = x_op.size
    x = ca.SX.sym("x", n)
    if integral is None:
        u = saturate_input(ca.DM(u_op) - ca.DM(K) @ (x - ca.DM(x_op)), input_limits)
        return ca.Function(name, [x], [u], ["x"], ["u"])
    Aa, C1 = np.asarray(integral["augmented_A"], dtype=float), np.asarray(integral["C1"], dtype=float)
    p = C1.shape[0]
    Br = np.vstack([np.zeros((n, p)), np.eye(p)]) if Br is None else np.asarray(Br, dtype=float)
    z, r = ca.SX.sym("z", p), ca.SX.sym("y_r", p)
    dx = x - ca.DM(x_op)
    u = saturate_input(ca.DM(u_op) - ca.DM(K[:, :n]) @ dx - ca.DM(K[:, n:]) @ z, input_limits)
    z_new = ca.DM(Aa[n:, :n]) @ dx + ca.DM(Aa[n:, n:]) @ z + ca.DM(Br[n:]) @ (r - ca.DM(C1 @ x_op))
    out = "z_dot" if continuous else "z_next"
    return ca.Function(name, [x, z, r], [u, z_new], ["x", "z", "y_r"], ["u", out])


def observer_law(name: str, A: np.ndarray, B: np.ndarray, C: np.ndarray, L: np.ndarray,
                 x_op: np.ndarray, u_op: np.ndarray, y_op: np.ndarray, form: str = "predictor"
                 ) -> ca.Function:
    """One step of a linear (Luenberger) observer about the operating point.

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    A, B, C : ndarray
        The model (``Ad, Bd`` in discrete time, ``F, B`` in continuous time), in the
        plant's units (``F`` in 1/s, ``Ad`` dimensionless).
    L : ndarray
        Observer gain (n x q, state per output units).
    x_op, u_op, y_op : ndarray
        Operating point and the output there (state, input, output units).
    form : str
        ``"predictor"``: ``x_next = x_op + A dx + B du + L (dy - C dx)``;
        ``"current"``: predict with ``A, B``, then correct with the new ``y``;
        ``"continuous"``: ``x_hat_dot = A dx + B du + L (dy - C dx)``.

    Returns
    -------
    casadi.Function
        ``x_hat_next = step(x_hat, u, y)`` (``x_hat_dot`` in continuous time):
        in the current form ``u`` is the input applied over the last period
        and ``y`` the new measurement.
    """
    A, B, C, L = (np.asarray(v, dtype=float) for v in (A, B, C, L))
    x_op, u_op, y_op = (np.asarray(v, dtype=float) for v in (x_op, u_op, y_op))
    xh, u, y = ca.SX.sym("x_hat", A.shape[0]), ca.SX.sym("u", B.shape[1]), ca.SX.sym("y", C.shape[0])
    dx, du, dy = xh - ca.DM(x_op), u - ca.DM(u_op), y - ca.DM(y_op)
    if form == "current":
        xp = ca.DM(A) @ dx + ca.DM(B) @ du
        new = ca.DM(x_op) + xp + ca.DM(L) @ (dy - ca.DM(C) @ xp)
    else:
        new = ca.DM(A) @ dx + ca.DM(B) @ du + ca.DM(L) @ (dy - ca.DM(C) @ dx)
        new = new if form == "continuous" else ca.DM(x_op) + new
    out = "x_hat_dot" if form == "continuous" else "x_hat_next"
    return ca.Function(name, [xh, u, y], [new], ["x_hat", "u", "y"], [out])


def kalman_step(name: str, plant: Plant, tuning: KalmanTuning, linear: bool) -> ca.Function:
    """The (extended) Kalman filter step the runtime runs, as a standalone Function.

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    plant : Plant
        The spec's plant.
    tuning : KalmanTuning
        ``Q, R, P0, x0``, sampling and model options (`tanksynth.runtime.estimators.kalman`).
    linear : bool
        Kalman filter on the ZOH linearisation (``tuning.operating_point``) instead of the EKF.

    Returns
    -------
    casadi.Function
        ``x_next, P_next = step(x, P, y, u)``: from ``x(k-1|k-1)``, ``P(k-1|k-1)``,
        the input held over the period and the new measurement, ``x(k|k)`` and
        ``P(k|k)`` (``Q`` and ``R`` built in). A hybrid plant adds the input
        and output ``memory`` (the kept Jacobian across a switching surface;
        start with zeros).
    """
    from tanksynth.runtime.estimators.kalman import ExtendedKalmanFilter, KalmanFilter

    return estimator_step(name, (KalmanFilter if linear else ExtendedKalmanFilter)(plant, tuning,
                                                                                   backend="vm"))


def estimator_step(name: str, est: KernelEstimator) -> ca.Function:
    """The step of a kernel estimator whose state is ``x`` then ``P`` (KF, EKF, UKF), standalone.

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    est : KernelEstimator
        The runtime estimator (`tanksynth.runtime.estimators`): its CasADi kernel
        and its tuning vector (``Q``, ``R``) are built into the Function.

    Returns
    -------
    casadi.Function
        ``x_next, P_next = step(x, P, y, u)`` (``memory`` in and out too when the
        kernel keeps more state, e.g. on a hybrid plant), as in `kalman_step`.
    """
    plant = est.plant
    kernel = est.step_kernel
    n = plant.n
    x, P = ca.SX.sym("x", n), ca.SX.sym("P", n, n)
    y, u = ca.SX.sym("y", plant.q), ca.SX.sym("u", plant.m)
    extra = kernel.size1_in(0) - n - n * n
    mem = ca.SX.sym("memory", extra)
    params = ca.DM(est.kernel_parameters)
    state = ca.vertcat(x, ca.reshape(P, n * n, 1), mem)
    new = kernel(state, y, u, params)[0]
    outs = [new[:n], ca.reshape(new[n:n + n * n], n, n)]
    ins, names_in, names_out = [x, P, y, u], ["x", "P", "y", "u"], ["x_next", "P_next"]
    if extra:
        ins.append(mem)
        names_in.append("memory")
        outs.append(new[n + n * n:])
        names_out.append("memory_next")
    return ca.Function(name, ins, outs, names_in, names_out)


def operating_point(spec: Spec) -> tuple[np.ndarray, np.ndarray]:
    """The spec's operating point and its equilibrium input, as the designs linearise there.

    Parameters
    ----------
    spec : Spec
        The spec a design was made from.

    Returns
    -------
    x_op : ndarray, shape (n,)
        Operating levels (state units, m).
    u_op : ndarray, shape (m,)
        Equilibrium input at ``x_op`` (input units, m^3/s; the spec's ``u`` when given and
        checked, see `tanksynth.analysis.linearize.equilibrium_input`).
    """
    from tanksynth.analysis.linearize import equilibrium_input

    given = None if spec.given_u0 is None else spec.given_u0.tolist()
    eq = equilibrium_input(spec.plant, spec.x0.tolist(), given)
    return np.asarray(spec.x0, dtype=float), np.asarray(eq.u0, dtype=float)


def sampling_period(spec: Spec, method: str) -> float:
    """The spec's sampling period (s), which a discrete-time law of ``method`` needs.

    Parameters
    ----------
    spec : Spec
        The spec a design was made from.
    method : str
        The design's method, named in the error.

    Raises
    ------
    ArtefactError
        The spec has no ``[sampling] ts``.
    """
    if spec.ts is None:
        raise ArtefactError(f"the law of a discrete-time {method} design needs the spec's [sampling] ts")
    return float(spec.ts)


def _options_of(options: MethodOptions | None, cls: type[_Options]) -> _Options:
    """The validated options of the design, of the method's Options class."""
    if not isinstance(options, cls):  # a caller's bug: the spec's designs are validated on parsing
        raise TypeError(f"expected the design's validated {cls.__name__}, got {type(options).__name__}")
    return options


def derived_law(gains: Mapping[str, np.ndarray], diagnostics: Mapping[str, Any], method: str,
                spec: Spec, options: MethodOptions | None, name: str) -> ca.Function | None:
    """The law or estimator step of a design whose artefact does not carry one, from its gains.

    Parameters
    ----------
    gains : mapping of str to ndarray
        The design's gains (in the plant's units).
    diagnostics : mapping
        Its diagnostics (equilibrium, time domain, integral action, form).
    method : str
        Its method.
    spec : Spec
        The spec it was designed from (plant, operating point, sampling).
    options : MethodOptions
        Its validated options.
    name : str
        Function name (made a C identifier, `tanksynth.runtime.laws.c_identifier`).

    Returns
    -------
    casadi.Function or None
        `state_feedback_law`, `observer_law`, `kalman_step` or `estimator_step`, or the
        step of `tanksynth.artefacts.estimator_laws.ESTIMATOR_LAW_METHODS`
        (`tanksynth.artefacts.synthesis_laws.synthesis_law` for its methods); None for
        another method (or a linear design without a gain).
    """
    from tanksynth.artefacts.estimator_laws import ESTIMATOR_LAW_METHODS, estimator_law
    from tanksynth.artefacts.synthesis_laws import SYNTHESIS_LAW_METHODS, synthesis_law

    name = c_identifier(name)  # a design name may start with a digit or hold '.', '-'
    if method in ESTIMATOR_LAW_METHODS:
        return estimator_law(gains, diagnostics, method, spec, options, name)
    if method in SYNTHESIS_LAW_METHODS:
        return synthesis_law(gains, diagnostics, method, spec, options, name)
    if method not in DERIVED_LAW_METHODS or getattr(options, "nonlinear", False):
        return None
    from tanksynth.analysis.linearize import linearize

    plant = spec.plant
    x_op, u_op = operating_point(spec)
    if method in ("kalman", "ekf"):
        from tanksynth.runtime.estimators.kalman import KalmanTuning
        from tanksynth.spec.method_options.estimators import KalmanOptions

        kalman = _options_of(options, KalmanOptions)
        tuning = KalmanTuning(Q=gains["Q"], R=gains["R"], P0=gains["P0"], x0=gains["x_hat0"],
                              ts=sampling_period(spec, method),
                              substeps=kalman.substeps, jacobian_eps=kalman.jacobian_eps,
                              switch_tol=kalman.switch_tol, clip=kalman.clip,
                              operating_point=(x_op, u_op) if method == "kalman" else None)
        return kalman_step(name, plant, tuning, linear=method == "kalman")
    if method == "ukf":
        from tanksynth.runtime.estimators.ukf import UKFTuning, UnscentedKalmanFilter
        from tanksynth.spec.method_options.estimators import UkfOptions

        ukf = _options_of(options, UkfOptions)
        ukf_tuning = UKFTuning(Q=gains["Q"], R=gains["R"], P0=gains["P0"], x0=gains["x_hat0"],
                               ts=sampling_period(spec, method),
                               alpha=ukf.alpha, beta=ukf.beta, kappa=ukf.kappa,
                               redraw=ukf.redraw, substeps=ukf.substeps, clip=ukf.clip)
        return estimator_step(name, UnscentedKalmanFilter(plant, ukf_tuning, backend="vm"))
    lin = linearize(plant, x_op.tolist(), u_op.tolist(), ts=spec.ts)
    time_domain = diagnostics.get("time_domain", "continuous" if method == "canonical_observer"
                                  else "discrete")
    if method == "luenberger":
        time_domain = "continuous" if diagnostics.get("form") == "continuous" else "discrete"
    continuous = time_domain == "continuous"
    A, B = (lin.F, lin.B) if continuous else (lin.Ad, lin.Bd)
    if A is None or B is None:
        raise ArtefactError(f"design of method {method} in discrete time needs the spec's [sampling] ts")
    if "K" in gains:
        integral = diagnostics.get("integral")
        return state_feedback_law(name, gains["K"], x_op, u_op,
                                  integral if isinstance(integral, Mapping) else None,
                                  gains.get("Br"), continuous, plant.input_limits)
    if "L" not in gains:
        return None
    form = "continuous" if continuous else (diagnostics.get("form") or "predictor")
    return observer_law(name, A, B, lin.C, gains["L"], x_op, u_op, _output_at(plant, x_op), form)
