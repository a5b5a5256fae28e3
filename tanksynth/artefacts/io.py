"""Artefacts: design results on disk, with provenance, written atomically.

``DIR/<name>.json`` (schema ``tanksynth.artefact/1``) holds the gains as
nested lists, the diagnostics, the verification (once ``verify`` ran) and the
provenance: the spec's sha256, the package versions and a sha256 of the
gains, so that gains edited after design are detected. Beside it,
``<name>.npz`` holds the same gains; ``.mat`` and a C header on request.
"""

from __future__ import annotations

import hashlib
import json
import math
import platform
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

import numpy as np

from tanksynth.artefacts.atomic import atomic_write, commit, discard, stage
from tanksynth.artefacts.export import c_header
from tanksynth.errors import ArtefactError, SpecError

if TYPE_CHECKING:  # the artefact only reads a result's fields; no import of the design stage
    from tanksynth.design.result import DesignResult

__all__ = ["SCHEMA", "PLANT_SCHEMA", "EXPORT_FORMATS", "write_plant_record", "read_plant_record", "to_jsonable", "gains_digest", "artefact_document",
           "write_artefact", "read_artefact"]

SCHEMA = "tanksynth.artefact/1"
PLANT_SCHEMA = "tanksynth.plant/1"
#: Optional export formats besides .json and .npz.
EXPORT_FORMATS = ("mat", "h", "law")
_PACKAGES = ("tanksynth", "numpy", "scipy", "sympy", "casadi")


def to_jsonable(value: Any) -> Any:
    """Numpy arrays, numbers and complex values -> JSON-safe Python objects.

    Non-finite floats become the strings ``"inf"``, ``"-inf"``, ``"nan"``
    (strict JSON has no such numbers).
    """
    if isinstance(value, Mapping):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else ("nan" if v != v else ("inf" if v > 0 else "-inf"))
    if isinstance(value, (complex, np.complexfloating)):
        return [to_jsonable(value.real), to_jsonable(value.imag)]
    if value is None or isinstance(value, str):
        return value
    return str(value)


def gains_digest(gains: Mapping[str, Any]) -> str:
    """sha256 over the gains' names, shapes and float64 bytes."""
    h = hashlib.sha256()
    for name in sorted(gains):
        arr = np.ascontiguousarray(np.asarray(gains[name], dtype=float))
        h.update(name.encode())
        h.update(str(arr.shape).encode())
        h.update(arr.tobytes())
    return h.hexdigest()


def _versions() -> dict[str, str]:
    out = {}
    for pkg in _PACKAGES:
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "unknown"
    out["python"] = platform.python_version()
    return out


def artefact_document(result: DesignResult, spec_sha256: str, solver: str = "") -> dict:
    """The JSON document of an artefact (before verification)."""
    gains = {k: np.asarray(v, dtype=float) for k, v in result.gains.items()}
    for name, arr in gains.items():
        if not np.all(np.isfinite(arr)):
            raise ArtefactError(f"design '{result.name}': gain {name} has non-finite entries; "
                                "refusing to write it")
    versions = _versions()
    return {
        "schema": SCHEMA,
        "name": result.name,
        "method": result.method,
        "plant": result.plant,
        "gains": {k: v.tolist() for k, v in gains.items()},
        "diagnostics": to_jsonable(result.diagnostics),
        "latex": dict(result.latex),
        "verification": None,
        "provenance": {
            "spec_sha256": spec_sha256,
            "gains_sha256": gains_digest(gains),
            "tanksynth_version": versions.pop("tanksynth"),
            "packages": versions,
            "solver": solver,
        },
    }


def write_artefact(result: DesignResult, directory: str | Path, spec_sha256: str,
                   export: Iterable[str] = (), solver: str = "") -> Path:
    """Write ``<name>.json`` and ``<name>.npz`` (and exports) atomically.

    All files are first written to temporary names in ``directory`` and
    renamed only when every one of them succeeded: a failure leaves no
    partial artefact behind.

    Parameters
    ----------
    result : DesignResult
    directory : str or Path
        Created if missing.
    spec_sha256 : str
        Provenance of the spec.
    export : iterable of str
        Extra formats among `EXPORT_FORMATS`: ``"mat"``, ``"h"`` (C header
        of the gains), ``"law"`` (the control law of a control design as
        ``<name>_law.casadi`` plus generated ``<name>_law.c``/``.h``).
    solver : str
        Solver used, for provenance.

    Returns
    -------
    Path
        The JSON file.
    """
    export = list(export)
    bad = [e for e in export if e not in EXPORT_FORMATS]
    if bad:
        raise SpecError(f"unknown export format(s) {bad}; expected some of {list(EXPORT_FORMATS)}",
                        key="export")
    law_doc = result.diagnostics.get("law") if "law" in export else None
    if "law" in export and not (isinstance(law_doc, Mapping) and "casadi_serialized" in law_doc):
        raise SpecError(f"design '{result.name}' (method {result.method}) has no control law "
                        "to export", key="export")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    doc = artefact_document(result, spec_sha256, solver)
    gains = {k: np.asarray(v, dtype=float) for k, v in result.gains.items()}
    payloads: dict[str, bytes] = {
        ".json": (json.dumps(doc, indent=2, allow_nan=False) + "\n").encode("utf-8"),
    }
    extensions = (".json", ".npz", *(f".{e}" for e in export if e != "law"))
    final = {ext: directory / f"{result.name}{ext}" for ext in extensions}
    temps: dict[str, Path] = {}
    try:
        for ext, target in final.items():
            if ext in payloads:
                payload = payloads[ext]
            elif ext == ".npz":
                payload = lambda fh: np.savez(fh, **gains)  # noqa: E731
            elif ext == ".mat":
                from scipy.io import savemat

                payload = lambda fh: savemat(fh, gains)  # noqa: E731
            else:
                payload = c_header(result.name, gains)
            temps[ext] = stage(target, payload)
        # The JSON (the artefact proper) is renamed last, and whatever was
        # renamed is removed again if a later rename fails: no partial artefact.
        renamed: list[Path] = []
        try:
            if law_doc is not None:
                from tanksynth.artefacts.export import export_law
                from tanksynth.runtime.laws import law_from_document

                exported = export_law(law_from_document(dict(law_doc)), directory,
                                      name=f"{result.name}_law")
                renamed += [exported.casadi, exported.c_source, exported.c_header]
            for ext in sorted(temps, key=lambda e: e == ".json"):
                renamed.append(commit(temps[ext], final[ext]))
        except BaseException:
            for path in renamed:
                path.unlink(missing_ok=True)
            raise
    finally:
        for tmp in temps.values():
            discard(tmp)
    return final[".json"]


def read_artefact(path: str | Path, check_gains: bool = True) -> dict:
    """Read an artefact JSON and check its schema and gain provenance.

    Parameters
    ----------
    path : str or Path
    check_gains : bool
        Recompute the gains' sha256 and refuse a mismatch (tampering).

    Raises
    ------
    ArtefactError
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ArtefactError(f"{path}: cannot read artefact: {exc.strerror}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ArtefactError(f"{path}: not a JSON artefact: {exc}") from None
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA:
        raise ArtefactError(f"{path}: expected schema {SCHEMA!r}, got "
                            f"{doc.get('schema') if isinstance(doc, dict) else type(doc).__name__!r}")
    for key in ("name", "method", "plant", "gains", "provenance"):
        if key not in doc:
            raise ArtefactError(f"{path}: missing key {key!r}")
    try:
        gains = {k: np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
    except (TypeError, ValueError, AttributeError):
        raise ArtefactError(f"{path}: gains must be nested lists of numbers") from None
    bad = sorted(k for k, v in gains.items() if np.isnan(v).any())
    if bad:
        raise ArtefactError(f"{path}: gain(s) {', '.join(bad)} hold NaN entries; a designed gain is a "
                            "number (infinite entries only mark unbounded limits)")
    if not isinstance(doc["name"], str) or doc["name"] != path.stem:
        raise ArtefactError(f"{path}: the artefact's name {doc['name']!r} does not match its file "
                            f"name (expected {path.stem!r}); artefacts are written as <name>.json")
    if check_gains and gains_digest(gains) != doc["provenance"].get("gains_sha256"):
        raise ArtefactError(f"{path}: gains do not match their provenance hash "
                            "(edited after design?)")
    doc["gains"] = gains
    return doc


def write_plant_record(spec, directory: str | Path) -> Path:
    """Write ``DIR/plant.json`` and ``DIR/spec.toml``: what reports need of the plant.

    ``plant.json`` (schema ``tanksynth.plant/1``) holds the plant summary
    (parameters with units, region, assumptions), its equations in LaTeX, the
    operating point and sampling period, and the spec's sha256; ``spec.toml``
    is the spec text itself. Both written atomically.

    Parameters
    ----------
    spec : tanksynth.spec.Spec
    directory : str or Path
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    plant = spec.plant
    doc = {
        "schema": PLANT_SCHEMA,
        "title": spec.title,
        "spec_sha256": spec.sha256,
        "spec_source": spec.source,
        "plant": plant.summary(),
        "equations": plant.latex_equations(),
        "operating_point": {"x": spec.x0.tolist(),
                            "u": None if spec.given_u0 is None else spec.given_u0.tolist()},
        "ts": spec.ts,
    }
    target = directory / "plant.json"
    if spec.text:
        atomic_write(directory / "spec.toml", spec.text.encode("utf-8"))
    atomic_write(target, (json.dumps(to_jsonable(doc), indent=2, allow_nan=False) + "\n").encode())
    return target


def read_plant_record(directory: str | Path) -> dict:
    """Read ``DIR/plant.json`` (see `write_plant_record`).

    Raises
    ------
    ArtefactError
        Missing, unreadable or of the wrong schema.
    """
    path = Path(directory) / "plant.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ArtefactError(f"{path}: cannot read plant record: {exc.strerror}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ArtefactError(f"{path}: not a JSON plant record: {exc}") from None
    if not isinstance(doc, dict) or doc.get("schema") != PLANT_SCHEMA:
        raise ArtefactError(f"{path}: expected schema {PLANT_SCHEMA!r}")
    return doc
