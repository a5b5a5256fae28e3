"""Exports beside an artefact: C header of the gains, control laws as CasADi files and generated C,
and the contents of the ``.mat`` file.

The ``.mat`` file and the C header carry what is needed to implement the design
elsewhere, besides the gains: the sampling period ``ts``, the operating point
``x_op``/``u_op`` (also as ``x0``/``u0`` unless a gain has that name), the continuous
linearisation there ``A, B, C, D`` (``dx/dt = A (x - x0) + B (u - u0)``,
``y = y0 + C (x - x0) + D (u - u0)``, from ``plant.json``), the law as text, and the
state, input and output names and units with the unit of every matrix
(`implementation_data`). Vectors are columns in both (MATLAB's orientation).

The law files ``NAME_law.c``/``.h`` (`export_law`) open with a comment stating the law,
its arguments with their units, the sampling period and the operating point, and compile
cleanly with ``gcc -std=c99 -Wall -Wextra -Wpedantic -Werror`` (CasADi's generated code
leaves some work arguments unused: they are marked ``(void)`` here).
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

from tanksynth.artefacts.atomic import build_directory, commit
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
           'implementation_data', 'mat_contents', 'linearization_record', 'law_statement',
           'strict_c', 'law_preamble', 'matrix_units', 'DERIVED_LAW_METHODS', 'state_feedback_law', 'saturate_input',
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



def export_law(law: ca.Function, directory: str | Path, name: str | None = None, *,
               statement: str = "") -> ExportedLaw:
    """Write the law as ``<name>.casadi``, ``<name>.c`` and ``<name>.h``, atomically.

    Everything is generated in a temporary directory beside the targets and
    renamed only when all files exist; a failure leaves nothing behind. The C
    files open with `law_preamble` (the law, its arguments with units from the
    ``plant.json`` beside when there is one, ``ts``, the operating point) and
    are made warning-free under ``-std=c99 -Wall -Wextra -Wpedantic`` (`strict_c`).

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
    statement : str, optional
        The law in words and symbols (`law_statement`); default its signature.

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
    tmpdir = build_directory(directory, ".law-build-", ".tmp")
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
        preamble = law_preamble(fn, _plant_record_beside(directory), statement)
        for ext in (".c", ".h"):
            path = tmpdir / final[ext].name
            text = path.read_text(encoding="utf-8")
            path.write_text(preamble + (strict_c(text) if ext == ".c" else text), encoding="utf-8")
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



_C_FUNCTION = re.compile(r"^(?![ \t#/*])[^\n;{}()]*?\b(\w+)\(([^()]*)\)\s*\{", re.M)


def strict_c(source: str) -> str:
    """CasADi's generated C with each unused parameter of a function marked ``(void)name;``.

    The generated entry points take ``iw``, ``w`` and ``mem`` whether they use
    them or not, which ``-Wextra`` (``-Wunused-parameter``) rejects under
    ``-Werror``; nothing else is changed.

    Parameters
    ----------
    source : str
        The generated ``.c`` text.

    Returns
    -------
    str
    """
    out, last = [], 0
    for match in _C_FUNCTION.finditer(source):
        open_at = match.end() - 1
        depth, i = 0, open_at
        while i < len(source):
            depth += {"{": 1, "}": -1}.get(source[i], 0)
            if depth == 0:
                break
            i += 1
        body = source[open_at + 1:i]
        unused = []
        for param in match.group(2).split(","):
            words = re.findall(r"\w+", param)
            if words and words != ["void"] and not re.search(rf"\b{words[-1]}\b", body):
                unused.append(words[-1])
        if unused:
            out.append(source[last:open_at + 1])
            out.append("".join(f" (void){name};" for name in unused))
            last = open_at + 1
    out.append(source[last:])
    return "".join(out)


def _plant_record_beside(directory: Path) -> Mapping[str, Any] | None:
    """``DIR/plant.json`` as a mapping, None when absent or unreadable (a law exported alone)."""
    import json

    path = directory / "plant.json"
    try:
        if path.is_file() and path.stat().st_size <= 64 * 1024 ** 2:
            doc = json.loads(path.read_text(encoding="utf-8"))
            return doc if isinstance(doc, Mapping) else None
    except (OSError, ValueError):
        return None
    return None


#: Units of a law's arguments, by name (``{s}``: the states with their units, ``{u}`` the
#: inputs', ``{y}`` the outputs'; ``{y1}`` the outputs' one unit, or "output units").
_ARGUMENT_UNITS = {"x": "{s}", "x_hat": "{s}", "x_next": "{s}", "x_hat_next": "{s}",
                   "x_hat_dot": "{s}/s", "x_pred": "{s}", "u": "{u}", "u_applied": "{u}",
                   "y": "{y}", "y_prev": "{y}", "y_r": "references of the tracked outputs, {y1}",
                   "P": "({s})^2", "P_next": "({s})^2",
                   "z": "integrated tracking error, {y1} s", "z_next": "integrated tracking error, {y1} s",
                   "z_dot": "tracking error, {y1}", "t": "s"}


def _unit_list(names: Sequence[str], units: Sequence[str]) -> str:
    """``"h1 [m], h2 [m]"``."""
    return ", ".join(f"{n} [{u}]" for n, u in zip(names, units))


def law_preamble(law: ca.Function, plant_record: Mapping[str, Any] | None, statement: str = "") -> str:
    """The comment at the top of an exported law's C files.

    Parameters
    ----------
    law : casadi.Function
        The law (its name and arguments).
    plant_record : mapping or None
        ``plant.json`` (`tanksynth.artefacts.io.write_plant_record`): signal names
        and units, operating point, sampling period. None: units unknown.
    statement : str, optional
        The law (`law_statement`); default its signature.

    Returns
    -------
    str
        A C comment block (``/* ... */``), lines of at most about 100 characters.
    """
    data = implementation_data({}, plant_record)
    units = {"s": _unit_list(data["state_names"], data["state_units"]) or "state units",
             "u": _unit_list(data["input_names"], data["input_units"]) or "input units",
             "y": _unit_list(data["output_names"], data["output_units"]) or "output units",
             "y1": _uniform_unit(data["output_units"], "output units")}

    def described(i: int, out: bool) -> str:
        name = law.name_out(i) if out else law.name_in(i)
        size = int(law.nnz_out(i) if out else law.nnz_in(i))
        unit = _ARGUMENT_UNITS.get(name, "see the design's artefact").format(**units)
        return f" *   {name}[{size}]: {unit}"

    signature = (f"{law.name()}({', '.join(law.name_in())}) -> ({', '.join(law.name_out())})")
    lines = ["/*", f" * Exported by tanksynth: {signature}.",
             f" * Law: {' '.join((statement or signature).split())}",
             " * Values are absolute, in the plant's units (the operating point is inside the law).",
             " * Inputs:"]
    lines += [described(i, False) for i in range(law.n_in())]
    lines.append(" * Outputs:")
    lines += [described(i, True) for i in range(law.n_out())]
    ts = data["ts"]
    lines.append(f" * Sampling period ts = {ts!r} s." if np.isfinite(ts)
                 else " * Continuous time (a continuous-time design, or no sampling period in the spec).")
    if data["x_op"].size:
        lines.append(" * Operating point x_op = [" + ", ".join(repr(float(v)) for v in data["x_op"])
                     + "], u_op = [" + ", ".join(repr(float(v)) for v in data["u_op"]) + "].")
    lines.append(" */")
    return "\n".join(line.replace("*/", "* /") if 0 < k < len(lines) - 1 else line
                     for k, line in enumerate(lines)) + "\n"


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
        ``ts`` (s, NaN without sampling or for a continuous-time design), ``x_op`` (state units), ``u_op`` (input
        units, NaN entries when unknown), and ``state_names``, ``state_units``,
        ``input_names``, ``input_units``, ``output_names``, ``output_units``
        (lists of str, empty when unknown); ``y_op`` (output units, the outputs at
        ``x_op``; empty when the record has no linearisation); ``linearization``: ``A, B, C, D`` at the
        operating point (`linearization_record`, from ``plant.json``; empty when the
        record has none); ``law_context``: the diagnostics `law_statement` reads;
        ``weights``: the design's cost weights ``Q``, ``R`` (an LQR-type design's
        ``diagnostics.weights``; empty when it has none).
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
    lin = record.get("linearization")
    out["linearization"] = ({k: np.asarray(lin[k], dtype=float) for k in ("A", "B", "C", "D")}
                            if isinstance(lin, Mapping) and all(k in lin for k in ("A", "B", "C", "D"))
                            else {})
    # the outputs at the operating point: the observers' laws read y - y_op
    out["y_op"] = np.asarray(lin["y0"] if isinstance(lin, Mapping) and "y0" in lin else [],
                             dtype=float).reshape(-1)
    weights = diagnostics.get("weights") if isinstance(diagnostics, Mapping) else None
    out["weights"] = ({k: np.asarray(v, dtype=float) for k, v in weights.items() if k in ("Q", "R")}
                      if isinstance(weights, Mapping) else {})
    out["law_context"] = {k: diagnostics.get(k)
                          for k in ("law_signature", "time_domain", "form", "integral")
                          if isinstance(diagnostics, Mapping) and k in diagnostics}
    if out["law_context"].get("time_domain") == "continuous":
        out["ts"] = float("nan")   # a continuous-time design: the spec's period is not its own
    return out


def linearization_record(spec: Spec) -> dict[str, Any] | None:
    """The continuous linearisation at the spec's operating point, for ``plant.json``.

    ``dx/dt = A (x - x0) + B (u - u0)``, ``y = y0 + C (x - x0) + D (u - u0)``
    (``D = 0``: the outputs do not depend on the inputs), about the operating
    levels ``x0`` and their equilibrium input ``u0`` (`operating_point`).

    Parameters
    ----------
    spec : Spec
        The validated spec.

    Returns
    -------
    dict or None
        ``A`` (1/s), ``B`` (state units/s per input unit), ``C`` (output units per
        state unit), ``D`` (output per input units), ``x0``, ``u0``, ``y0`` as nested
        lists; None when the model cannot be linearised there (non-finite Jacobians).
    """
    from tanksynth.analysis.linearize import linearize

    x_op, u_op = operating_point(spec)
    try:
        lin = linearize(spec.plant, x_op.tolist(), u_op.tolist())
    except (ValueError, ArithmeticError, ArtefactError):
        return None
    A, B, C = (np.asarray(m, dtype=float) for m in (lin.F, lin.B, lin.C))
    if not all(np.all(np.isfinite(m)) for m in (A, B, C)):
        return None
    y0 = _output_at(spec.plant, x_op)
    return {"A": A.tolist(), "B": B.tolist(), "C": C.tolist(),
            "D": np.zeros((C.shape[0], B.shape[1])).tolist(),
            "x0": x_op.tolist(), "u0": u_op.tolist(), "y0": y0.tolist()}


def law_statement(diagnostics: Mapping[str, Any], gains: Mapping[str, Any]) -> str:
    """The design's law in one line of text (what the exported law computes).

    Parameters
    ----------
    diagnostics : mapping
        The design's diagnostics (``law_signature``, the statement of a design that
        builds its own law; else ``time_domain``, ``form``, ``integral``).
    gains : mapping
        Its gains (names only are read).

    Returns
    -------
    str
        E.g. ``"u = u_op - K (x - x_op), u clipped to the actuator range"``; ``""`` for
        a design without a state feedback or observer gain.
    """
    signature = diagnostics.get("law_signature")
    if isinstance(signature, str) and signature:  # a design that builds its own law states it
        return signature
    names = set(gains)
    discrete = diagnostics.get("time_domain", "discrete") == "discrete"
    if "K" in names:
        if isinstance(diagnostics.get("integral"), Mapping):
            e = "y_r - y_op - C1 (x - x_op)"
            z = (f"z_next = z + ts ({e})" if discrete else f"dz/dt = {e}")
            return (f"u = u_op - K1 (x - x_op) - K2 z with K = [K1 K2], {z} (integrators of the "
                    "tracked outputs' error, y_op = h(x_op) the tracked outputs at the operating "
                    "point), u clipped to the actuator range")
        return "u = u_op - K (x - x_op), u clipped to the actuator range"
    if "L" in names:
        form = diagnostics.get("form") or ("predictor" if discrete else "continuous")
        if form == "continuous":
            return "dx_hat/dt = A (x_hat - x_op) + B (u - u_op) + L (y - y_op - C (x_hat - x_op))"
        if form == "current":
            return ("x_p = x_op + Ad (x_hat - x_op) + Bd (u - u_op); "
                    "x_hat_next = x_p + L (y - y_op - C (x_p - x_op)) (current form, y the new measurement)")
        return ("x_hat_next = x_op + Ad (x_hat - x_op) + Bd (u - u_op) + L (y - y_op - C (x_hat - x_op)) "
                "(predictor form)")
    return ""


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
        units as n x 1 cell arrays of strings, ``ts`` a 1 x 1 double (s; NaN
        in continuous time); ``x_op``, ``u_op`` and ``y_op`` the operating point (the
        gains of that name when the design stores them), also as ``x0``, ``u0`` and
        ``y0`` (MATLAB's names); ``A, B, C, D`` the continuous linearisation
        there (when ``data`` has it); ``Q``, ``R`` the cost weights of an LQR-type
        design; ``law`` the law as text (`law_statement`);
        ``units`` a struct giving the unit of every variable. A gain of one of
        these names keeps its value.
    """
    def column(value: Any) -> np.ndarray:
        arr = np.asarray(value, dtype=float)
        return arr.reshape(-1, 1) if arr.ndim <= 1 else arr

    out: dict[str, Any] = {k: column(v) for k, v in gains.items()}
    out["ts"] = np.array([[float(data["ts"])]])
    out.setdefault("x_op", column(data["x_op"]))
    out.setdefault("u_op", column(data["u_op"]))
    out.setdefault("x0", out["x_op"])
    out.setdefault("u0", out["u_op"])
    if np.size(data.get("y_op", ())):
        out.setdefault("y_op", column(data["y_op"]))
        out.setdefault("y0", out["y_op"])
    for key, value in (data.get("linearization") or {}).items():
        out.setdefault(key, np.atleast_2d(np.asarray(value, dtype=float)))
    for key, value in (data.get("weights") or {}).items():   # the LQR weights the gain minimises
        out.setdefault(key, np.atleast_2d(np.asarray(value, dtype=float)))
    law = law_statement(data.get("law_context") or {}, gains)
    if law:
        out.setdefault("law", law)
    for key in ("state_names", "state_units", "input_names", "input_units", "output_names",
                "output_units"):
        cells = np.empty((len(data[key]), 1), dtype=object)
        for i, text in enumerate(data[key]):
            cells[i, 0] = text
        out[key] = cells
    units = matrix_units(data)
    K = out.get("K")
    n = len(data.get("state_units", ()))
    if K is not None and K.ndim == 2 and n and K.shape[1] > n:
        # integral action, K = [K1 K2]: K2 acts on z, the integrated output error (output unit s)
        y = _uniform_unit(data.get("output_units", ()), "output units")
        u, x = units["u_op"], units["x_op"]
        wrap = (lambda t: f"({t})" if re.search(r"[ /*]", t) else t)
        units["K"] = (f"{wrap(u)}/{wrap(x)} in columns 1-{n} (on x - x_op); {wrap(u)}/({wrap(y)} s) in "
                      f"columns {n + 1}-{K.shape[1]} (on z, the integrated output error)")
    out["units"] = {k: v for k, v in units.items() if k in out}
    return out


def matrix_units(data: Mapping[str, Any]) -> dict[str, str]:
    """The unit of each variable of the exports, in the plant's units where they are uniform.

    Parameters
    ----------
    data : mapping
        `implementation_data` (the state, input and output units).

    Returns
    -------
    dict of str to str
        ``ts``, ``x_op``/``x0``, ``u_op``/``u0``, ``y_op``/``y0``, ``A``, ``B``, ``C``, ``D``, ``F``,
        ``Ad``, ``Bd``, ``K``, ``L`` (``"cm/(s V)"`` when every state is in cm and
        every input in V; ``"(state units)/s per (input units)"`` when mixed).
    """
    s, u, y = (_uniform_unit(data.get(f"{what}_units", ()), f"{what} units")
               for what in ("state", "input", "output"))

    def per(num: str, den: str) -> str:
        wrap = (lambda t: f"({t})" if re.search(r"[ /*]", t) else t)
        return f"{wrap(num)}/{wrap(den)}"

    return {"ts": "s", "x_op": s, "x0": s, "u_op": u, "u0": u, "y_op": y, "y0": y, "A": "1/s", "F": "1/s",
            "B": per(s, f"s {u}" if " " not in u else f"s ({u})"), "C": per(y, s), "D": per(y, u),
            "Ad": "1 (dimensionless)", "Bd": per(s, u), "K": per(u, s), "L": per(s, y),
            "state_names": "-", "input_names": "-", "output_names": "-", "law": "-"}


def _uniform_unit(units: Sequence[str], generic: str) -> str:
    """The one unit of a group of signals (``"m"``), else ``generic``."""
    distinct = set(units)
    return next(iter(distinct)) if len(distinct) == 1 else generic


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
        law = law_statement(data.get("law_context") or {}, gains)
        if law:
            lines.append(f"/* law: {law} */".replace("*/ */", "*/"))
        for what in ("state", "input", "output"):
            listed = ", ".join(f"{n} [{u}]" for n, u in zip(data[f"{what}_names"], data[f"{what}_units"]))
            lines.append(f"/* {what}s: {listed or 'unknown'} */")
        units = matrix_units(data)
        listed = ", ".join(f"{k} [{units[k]}]" for k in dict.fromkeys((*gains, "x_op", "u_op"))
                           if k in units)
        if listed:
            lines.append(f"/* units: {listed} */")
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
        The design's ``integral`` diagnostics (``C1``, ``augmented_A``, ``y_op``
        the tracked outputs at ``x_op``, output units; ``C1 x_op`` when it is not
        recorded) when the gain has integral action.
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
        the integrators as designed (``z_next = z + ts (y_r - y_op - C1 (x - x_op))``
        on the ZOH model, the measured outputs' error; ``y_r`` the references of
        the tracked outputs).
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
    y_op = np.asarray(integral.get("y_op", C1 @ x_op), dtype=float).reshape(-1)
    if y_op.shape != (p,):
        raise ArtefactError(f"diagnostics.integral.y_op has {y_op.size} values, expected {p} (one "
                            "per tracked output)")
    # Aa[n:, :n] = -ts C1 (discrete) or -C1: z_next = z + ts (y_r - y_op - C1 (x - x_op))
    z_new = ca.DM(Aa[n:, :n]) @ dx + ca.DM(Aa[n:, n:]) @ z + ca.DM(Br[n:]) @ (r - ca.DM(y_op))
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
        outputs = [s.name for s in plant.outputs]
        if isinstance(integral, Mapping) and "y_op" not in integral and \
                all(t in outputs for t in integral.get("tracked") or ()):
            # an artefact from before y_op was recorded: the tracked outputs at x_op from the plant
            rows = [outputs.index(t) for t in integral.get("tracked") or ()]
            if len(rows) == len(integral.get("C1") or ()):
                integral = {**integral, "y_op": _output_at(plant, x_op)[rows].tolist()}
        return state_feedback_law(name, gains["K"], x_op, u_op,
                                  integral if isinstance(integral, Mapping) else None,
                                  gains.get("Br"), continuous, plant.input_limits)
    if "L" not in gains:
        return None
    form = "continuous" if continuous else (diagnostics.get("form") or "predictor")
    return observer_law(name, A, B, lin.C, gains["L"], x_op, u_op, _output_at(plant, x_op), form)
