"""Artefacts: design results on disk, with provenance, written atomically.

``DIR/<name>.json`` (schema ``tanksynth.artefact/1``) holds the gains as
nested lists, the diagnostics, the verification (once ``verify`` ran) and the
provenance: the spec's sha256, the package versions, a sha256 of the
gains (``gains_sha256``), of the ``.npz`` bytes as written (``npz_sha256``),
of the plant record written in the same run (``plant_record_sha256``, when
there is one) and of the whole content (``content_sha256``: name, method,
plant, gains, diagnostics, LaTeX and the provenance itself; not the
``verification``, which ``verify`` writes later), so that any file of an
artefact edited after design is detected. Beside it, ``<name>.npz`` holds
the same gains; ``.mat`` and a C header on request.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import platform
import stat
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping, cast

import numpy as np

from tanksynth.artefacts.atomic import (Payload, atomic_write, commit, discard, remove_stale, stage, staged_target,
                                       stale_temporaries)
from tanksynth.artefacts.jsontext import dumps
from tanksynth.artefacts.model import SCHEMA, Artefact, Gains, Provenance, check_document
from tanksynth.artefacts.npzfile import read_npz
from tanksynth.errors import ArtefactError, SpecError

if TYPE_CHECKING:  # the artefact only reads a result's fields; no import of the design stage
    from tanksynth.design.result import DesignResult
    from tanksynth.spec import Spec

__all__ = ["SCHEMA", "PLANT_SCHEMA", "EXPORT_FORMATS", "write_plant_record", "read_plant_record",
           "to_jsonable", "gains_digest", "artefact_document", "write_artefact", "read_artefact",
           "load_artefact", "content_digest", "file_sha256", "check_npz", "check_orphan_npz",
           "check_plant_record", "rehash", "other_spec_files", "read_limited", "MAX_FILE_BYTES",
           "remove_interrupted_writes"]

PLANT_SCHEMA = "tanksynth.plant/1"
#: Optional export formats besides .json and .npz.
EXPORT_FORMATS = ("mat", "h", "law")
_PACKAGES = ("tanksynth", "numpy", "scipy", "sympy", "casadi")


def to_jsonable(value: Any) -> Any:
    """Numpy arrays, numbers and complex values -> JSON-safe Python objects.

    Non-finite floats become the strings ``"inf"``, ``"-inf"``, ``"nan"``
    (strict JSON has no such numbers).

    Parameters
    ----------
    value : object
        A mapping, sequence, array, number, string or None (nested); any
        other object becomes its ``str``.
    """
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiu" and value.size \
            and (value.dtype.kind != "f" or np.all(np.isfinite(value))):
        return value.tolist()    # finite real numbers: nothing to convert one by one
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
    """sha256 over the gains' names, shapes and float64 bytes.

    Parameters
    ----------
    gains : mapping of str to array_like
        The design's gains (in the plant's units).

    Returns
    -------
    str
        The hex digest.
    """
    h = hashlib.sha256()
    for name in sorted(gains):
        arr = np.ascontiguousarray(np.asarray(gains[name], dtype=float))
        h.update(name.encode())
        h.update(str(arr.shape).encode())
        h.update(arr.tobytes())
    return h.hexdigest()


#: Largest file read from a result directory (bytes): artefacts are kilobytes to megabytes.
MAX_FILE_BYTES = 512 * 1024 ** 2


def read_limited(path: str | Path, limit: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes.

    A result directory is input: a file replaced by a FIFO, a device such as
    ``/dev/zero`` or a huge file must not hang or exhaust memory.

    Parameters
    ----------
    path : str or Path
        The file to read.
    limit : int, optional
        Largest size accepted (bytes; default `MAX_FILE_BYTES`).

    Raises
    ------
    ArtefactError
        Not a regular file, larger than ``limit``, or unreadable (naming it).
    """
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO must not block the open
        with os.fdopen(fd, "rb", buffering=0) as fh:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode):
                raise ArtefactError(f"{path}: not a regular file")
            if st.st_size > limit:
                raise ArtefactError(f"{path}: {st.st_size} bytes, more than the {limit} a result "
                                    "file may have")
            os.set_blocking(fd, True)
            data = fh.read(limit + 1)
    except OSError as exc:
        raise ArtefactError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise ArtefactError(f"{path}: more than the {limit} bytes a result file may have")
    return data


def file_sha256(path: str | Path) -> str:
    """sha256 (hex) of a file's bytes.

    Parameters
    ----------
    path : str or Path
        The file.

    Raises
    ------
    ArtefactError
        The file cannot be read (or is not a regular file, see `read_limited`).
    """
    return hashlib.sha256(read_limited(path)).hexdigest()


def content_digest(doc: Mapping[str, Any]) -> str:
    """sha256 over everything design wrote into an artefact that verify and report read.

    A canonical JSON serialisation (sorted keys, no whitespace, no NaN) of
    the name, method, plant, the gains (as `gains_digest`), the diagnostics,
    the LaTeX fragments and the provenance without ``content_sha256``; the
    ``verification`` field (written later by ``verify``) is not covered.

    Parameters
    ----------
    doc : mapping
        The artefact document (gains as nested lists or arrays).

    Raises
    ------
    ArtefactError
        Content that has no canonical JSON form (NaN, non-string keys, ...).
    """
    prov = doc.get("provenance")
    prov = {k: v for k, v in prov.items() if k != "content_sha256"} if isinstance(prov, Mapping) else prov
    try:
        gains = {k: np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
        canonical = json.dumps({"name": doc.get("name"), "method": doc.get("method"),
                                "plant": doc.get("plant"), "gains_sha256": gains_digest(gains),
                                "diagnostics": doc.get("diagnostics"), "latex": doc.get("latex"),
                                "provenance": prov},
                               sort_keys=True, separators=(",", ":"), allow_nan=False)
    except (TypeError, ValueError, AttributeError, KeyError) as exc:
        raise ArtefactError(f"artefact {doc.get('name')!r}: content has no canonical JSON form "
                            f"({' '.join(str(exc).split())[:120]})") from None
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def _npz_bytes(gains: Mapping[str, np.ndarray]) -> bytes:
    """The ``.npz`` file of the gains, in memory (zip timestamps make it differ run to run)."""
    buf = io.BytesIO()
    # Any: numpy's stub types allow_pickle as a keyword too, which no gain's name can be
    np.savez(buf, **cast(Mapping[str, Any], gains))
    return buf.getvalue()


def _versions() -> dict[str, str]:
    out = {}
    for pkg in _PACKAGES:
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "unknown"
    out["python"] = platform.python_version()
    return out


def artefact_document(result: DesignResult, spec_sha256: str, solver: str = "",
                      npz_sha256: str | None = None, plant_record_sha256: str | None = None) -> dict:
    """The JSON document of an artefact (before verification).

    Parameters
    ----------
    result : DesignResult
    spec_sha256 : str
    solver : str
    npz_sha256 : str, optional
        sha256 of the ``.npz`` bytes written beside it; computed from a fresh
        ``.npz`` of the gains when omitted.
    plant_record_sha256 : str, optional
        sha256 of ``plant.json`` written in the same run (`file_sha256`).
    """
    gains = {k: np.asarray(v, dtype=float) for k, v in result.gains.items()}
    for name, arr in gains.items():
        if not np.all(np.isfinite(arr)):
            raise ArtefactError(f"design '{result.name}': gain {name} has non-finite entries; "
                                "refusing to write it")
    versions = _versions()
    if npz_sha256 is None:
        npz_sha256 = hashlib.sha256(_npz_bytes(gains)).hexdigest()
    provenance = Provenance(spec_sha256, gains_digest(gains), versions.pop("tanksynth"), versions, solver,
                            npz_sha256, plant_record_sha256, content_sha256="")  # set below: covers the rest
    doc = Artefact(result.name, result.method, result.plant, Gains(gains), to_jsonable(result.diagnostics),
                   dict(result.latex), None, provenance).to_document()
    doc["provenance"]["content_sha256"] = content_digest(doc)
    return doc


def write_artefact(result: DesignResult, directory: str | Path, spec_sha256: str,
                   export: Iterable[str] = (), solver: str = "",
                   plant_record_sha256: str | None = None) -> Path:
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
    plant_record_sha256 : str, optional
        sha256 of the ``plant.json`` written in the same run (`file_sha256` of
        `write_plant_record`'s path); ``verify`` then refuses another plant record.

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
    gains = {k: np.asarray(v, dtype=float) for k, v in result.gains.items()}
    npz = _npz_bytes(gains)
    doc = artefact_document(result, spec_sha256, solver, npz_sha256=hashlib.sha256(npz).hexdigest(),
                            plant_record_sha256=plant_record_sha256)
    payloads: dict[str, bytes] = {
        ".json": (dumps(doc) + "\n").encode("utf-8"),
        ".npz": npz,
    }
    extensions = (".json", ".npz", *(f".{e}" for e in export if e != "law"))
    final = {ext: directory / f"{result.name}{ext}" for ext in extensions}
    temps: dict[str, Path] = {}
    if ".mat" in final or ".h" in final:  # ts, operating point, names and units beside the gains
        from tanksynth.artefacts.export import implementation_data, mat_contents

        record = read_plant_record(directory) if (directory / "plant.json").is_file() else None
        data = implementation_data(result.diagnostics, record)
    try:
        for ext, target in final.items():
            payload: Payload
            if ext in payloads:
                payload = payloads[ext]
            elif ext == ".mat":
                from scipy.io import savemat

                contents = mat_contents(gains, data)
                payload = lambda fh: savemat(fh, contents, oned_as="column")  # noqa: E731
            else:
                from tanksynth.artefacts.export import c_header  # deferred: loads CasADi, the laws

                payload = c_header(result.name, gains, data)
            temps[ext] = stage(target, payload)
        # The JSON (the artefact proper) is renamed last, and whatever was
        # renamed is removed again if a later rename fails: no partial artefact.
        renamed: list[Path] = []
        try:
            if law_doc is not None:
                from tanksynth.artefacts.export import export_law, law_statement
                from tanksynth.runtime.laws import law_from_document

                exported = export_law(law_from_document(dict(law_doc)), directory,
                                      name=f"{result.name}_law",
                                      statement=law_statement(result.diagnostics, result.gains))
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
    # the verdict trace of the artefact this one replaces judged other gains (a fresh artefact
    # is not verified; `verify` writes its trace)
    (directory / f"{result.name}.traces.npz").unlink(missing_ok=True)
    return final[".json"]


def _json_document(path: Path) -> Any:
    """The JSON value of an artefact file (errors name the file)."""
    try:
        return json.loads(read_limited(path).decode("utf-8"))
    except OSError as exc:
        raise ArtefactError(f"{path}: cannot read artefact: {exc.strerror}") from None
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise ArtefactError(f"{path}: not a JSON artefact: {exc}") from None


def read_artefact(path: str | Path, check_gains: bool = True) -> dict[str, Any]:
    """Read an artefact JSON and check its schema and gain provenance.

    Parameters
    ----------
    path : str or Path
        The artefact (``DIR/<name>.json``).
    check_gains : bool
        Recompute the gains' sha256 and the content's sha256 (`content_digest`)
        and refuse a mismatch (tampering).

    Returns
    -------
    dict
        The document, its gains as float arrays (`load_artefact`: as an `Artefact`).

    Raises
    ------
    ArtefactError
        Naming the file: unreadable, not JSON, not of the form of an artefact
        (`tanksynth.artefacts.model.check_document`), or edited after design.
    """
    path = Path(path)
    doc = _json_document(path)
    gains = check_document(doc, path)
    if check_gains and gains_digest(gains) != doc["provenance"].get("gains_sha256"):
        raise ArtefactError(f"{path}: gains do not match their provenance hash "
                            "(edited after design?)")
    if check_gains:
        stored = doc["provenance"].get("content_sha256")
        if not isinstance(stored, str):
            raise ArtefactError(f"{path}: provenance has no content_sha256; name, method, plant, "
                                "diagnostics and LaTeX are not covered (rewrite it with `tanksynth design`)")
        try:
            actual = content_digest(doc)
        except ArtefactError as exc:
            raise ArtefactError(f"{path}: {exc}") from None
        if actual != stored:
            raise ArtefactError(f"{path}: name, method, plant, diagnostics, LaTeX or provenance do not "
                                "match content_sha256 (content edited after design)")
    doc["gains"] = gains
    return doc


def load_artefact(path: str | Path) -> Artefact:
    """Read an artefact JSON as an `Artefact`, with every check of `read_artefact`.

    Parameters
    ----------
    path : str or Path
        The artefact (``DIR/<name>.json``).

    Raises
    ------
    ArtefactError
        As `read_artefact` (hashes checked), or a field of another type
        (`Artefact.from_document`).
    """
    return Artefact.from_document(read_artefact(path), path)


def write_plant_record(spec: Spec, directory: str | Path) -> Path:
    """Write ``DIR/plant.json`` and ``DIR/spec.toml``: what reports need of the plant.

    ``plant.json`` (schema ``tanksynth.plant/1``) holds the plant summary
    (parameters with units, region, assumptions), its equations in LaTeX, the
    operating point, the continuous linearisation there (``linearization``:
    ``A, B, C, D, x0, u0, y0``, or null) and sampling period, and the spec's sha256; ``spec.toml``
    is the spec text itself. Both written atomically.

    Parameters
    ----------
    spec : tanksynth.spec.Spec
    directory : str or Path
    """
    from tanksynth.artefacts.export import linearization_record  # deferred: loads CasADi

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
        "linearization": linearization_record(spec),  # A, B, C, D there, for the .mat export
    }
    target = directory / "plant.json"
    if spec.text:
        atomic_write(directory / "spec.toml", spec.text.encode("utf-8"))
    atomic_write(target, (json.dumps(to_jsonable(doc), indent=2, allow_nan=False) + "\n").encode())
    return target


def read_plant_record(directory: str | Path) -> dict[str, Any]:
    """Read ``DIR/plant.json`` (see `write_plant_record`).

    Parameters
    ----------
    directory : str or Path
        The result directory.

    Raises
    ------
    ArtefactError
        Missing, unreadable or of the wrong schema.
    """
    path = Path(directory) / "plant.json"
    try:
        doc = json.loads(read_limited(path).decode("utf-8"))
    except OSError as exc:
        raise ArtefactError(f"{path}: cannot read plant record: {exc.strerror}") from None
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise ArtefactError(f"{path}: not a JSON plant record: {exc}") from None
    if not isinstance(doc, dict) or doc.get("schema") != PLANT_SCHEMA:
        raise ArtefactError(f"{path}: expected schema {PLANT_SCHEMA!r}")
    return doc


#: Room for an ``.npy`` member's header (bytes) in the size a gain implies: numpy writes 128.
_NPY_HEADER_ROOM = 4096
#: Room for the zip's own records (bytes): per member (local and central headers, zip64
#: extras, the name twice) and once for the archive.
_ZIP_MEMBER_ROOM, _ZIP_ROOM = 512, 4096


def check_npz(path: str | Path, doc: Mapping[str, Any]) -> Path:
    """Refuse an artefact whose ``<name>.npz`` is missing, not the one design wrote, or not its gains.

    The ``.npz`` is read with a cap (`read_limited`) of the size the JSON's gains
    imply; its bytes must match ``npz_sha256``, and (even with every hash recomputed)
    it must hold exactly the JSON's gains: the same names and shapes and, as float64,
    the same values bit for bit. Each member's declared size and ``.npy`` header are
    checked before anything is decompressed or allocated (`tanksynth.artefacts.npzfile`).

    Parameters
    ----------
    path : str or Path
        The artefact JSON (``DIR/<name>.json``).
    doc : mapping
        Its document (`read_artefact`), whose provenance holds ``npz_sha256`` and whose
        gains are float arrays.

    Returns
    -------
    Path
        The checked ``.npz``.

    Raises
    ------
    ArtefactError
        Naming the ``.npz``: missing, not a regular file, larger than its gains imply,
        unreadable, its bytes differ from ``npz_sha256`` (edited, replaced or swapped
        after design), or its gains differ from the JSON's (names, shapes, values).
    """
    npz = Path(path).with_suffix(".npz")
    if not npz.is_file():
        raise ArtefactError(f"{npz}: missing; every artefact's gains are written as <name>.json "
                            "and <name>.npz")
    stored = doc["provenance"].get("npz_sha256")
    if not isinstance(stored, str):
        raise ArtefactError(f"{path}: provenance has no npz_sha256; {npz} is not covered")
    gains = {str(k): np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
    implied = {f"{k}": v.nbytes + _NPY_HEADER_ROOM for k, v in gains.items()}
    cap = sum(implied.values()) + sum(_ZIP_MEMBER_ROOM + 2 * len(k.encode()) for k in gains) + _ZIP_ROOM
    data = read_limited(npz, cap)
    if hashlib.sha256(data).hexdigest() != stored:
        raise ArtefactError(f"{npz}: does not match npz_sha256 in {Path(path).name} "
                            "(gains edited, replaced or swapped after design)")

    def same_form(key: str, shape: tuple[int, ...], dtype: np.dtype) -> str | None:
        want = gains[key]
        if dtype != np.dtype(float) or shape != want.shape:
            return (f"holds a {dtype} array of shape {shape}, but gain {key} of {Path(path).name} "
                    f"is float64 of shape {want.shape}")
        return None

    stored_gains = read_npz(data, npz, max_members=len(gains), max_total=sum(implied.values()),
                            member_limit=lambda key: implied.get(key, 0), check=same_form)
    missing = sorted(set(gains) - set(stored_gains))
    if missing:
        raise ArtefactError(f"{npz}: gain(s) {', '.join(missing)} of {Path(path).name} missing")
    for key, want in gains.items():
        if stored_gains[key].tobytes() != want.tobytes():   # C-order bytes of both
            raise ArtefactError(f"{npz}: gain {key} differs from the one in {Path(path).name} "
                                "(the NPZ is not the verified gains)")
    return npz


def check_orphan_npz(directory: str | Path, names: Iterable[str]) -> None:
    """Refuse a ``<name>.npz`` in ``directory`` with no artefact ``<name>.json``.

    Verdict traces (``<name>.traces.npz``) are not gains files and are skipped.

    Parameters
    ----------
    directory : str or Path
    names : iterable of str
        The names of the artefacts read from ``directory``.

    Raises
    ------
    ArtefactError
        Naming the orphan ``.npz``.
    """
    from tanksynth.artefacts.traces import TRACE_SUFFIX

    known = set(names)
    for npz in sorted(Path(directory).glob("*.npz")):
        if npz.name.endswith(TRACE_SUFFIX) or npz.stem in known:
            continue
        raise ArtefactError(f"{npz}: gains file with no artefact {npz.stem}.json beside it "
                            "(artefact deleted after design, or its design interrupted: design again)")


def remove_interrupted_writes(directory: str | Path) -> list[Path]:
    """Remove what a run killed mid-write left in ``directory`` (call it under `directory_lock`).

    `write_artefact` stages every file of an artefact, then renames them, the JSON
    last. A kill in between leaves temporary files (``.<file>.tanksynth-<8 characters>.tmp``)
    that no rename will claim, and possibly ``<name>.npz`` with no ``<name>.json``
    (which `check_orphan_npz` refuses). Removed: every temporary file and build
    directory of the tool's own naming (`tanksynth.artefacts.atomic.stale_temporaries`),
    and an orphan ``<name>.npz`` exactly when a staged ``<name>.json`` left beside it
    records its sha256 (the interrupted write's own NPZ). No other file is touched: an
    orphan NPZ without that evidence is still refused by the readers.

    Parameters
    ----------
    directory : str or Path
        A result directory.

    Returns
    -------
    list of Path
        The files and directories removed, sorted.
    """
    directory = Path(directory)
    stale = stale_temporaries(directory)
    orphans = []
    for tmp in stale:
        target = staged_target(tmp)
        if target is None or not target.endswith(".json"):
            continue
        json_file, npz = directory / target, directory / f"{target[:-len('.json')]}.npz"
        if json_file.exists() or json_file.is_symlink() or not npz.is_file() or npz.is_symlink():
            continue
        try:
            staged = json.loads(read_limited(tmp).decode("utf-8"))
            recorded = staged["provenance"]["npz_sha256"]
            if isinstance(recorded, str) and recorded == file_sha256(npz):
                orphans.append(npz)
        except (ArtefactError, ValueError, TypeError, KeyError, RecursionError):
            continue   # a partial or foreign temporary file: no evidence about the NPZ
    remove_stale(stale)
    for npz in orphans:
        npz.unlink(missing_ok=True)
    return sorted(stale + orphans)


def check_plant_record(directory: str | Path, artefacts: Iterable[tuple[Path, Mapping[str, Any]]]) -> None:
    """Refuse a ``plant.json`` other than the one written with the artefacts.

    Artefacts whose provenance records a ``plant_record_sha256`` (written by
    ``tanksynth design``) need ``DIR/plant.json`` with exactly that sha256.

    Parameters
    ----------
    directory : str or Path
    artefacts : iterable of (Path, mapping)
        The artefacts read (`read_artefact`).

    Raises
    ------
    ArtefactError
        Naming ``plant.json``: missing or edited after design.
    """
    record = Path(directory) / "plant.json"
    actual: str | None = None
    for path, doc in artefacts:
        stored = doc["provenance"].get("plant_record_sha256")
        if stored is None:
            continue
        if not record.is_file():
            raise ArtefactError(f"{record}: missing; {path.name} was designed with a plant record")
        if actual is None:
            actual = file_sha256(record)
        if actual != stored:
            raise ArtefactError(f"{record}: does not match plant_record_sha256 in {path.name} "
                                "(plant record edited after design)")


def rehash(path: str | Path, keep_npz: bool = False) -> Path:
    """Make an artefact consistent again after its JSON was edited (tests, tools).

    Rewrites ``<name>.npz`` from the JSON's gains and recomputes every digest
    of the provenance (``gains_sha256``, ``npz_sha256``, ``plant_record_sha256``
    from the ``plant.json`` beside it when the field is set, ``content_sha256``)
    and, for a verified artefact with a ``<name>.traces.npz`` beside it, the
    verification's ``traces_sha256``: the result reads as a (possibly wrong)
    design written consistently, not as tampering.

    Parameters
    ----------
    path : str or Path
        The artefact JSON.
    keep_npz : bool
        Keep ``<name>.npz`` as it is and record its hash instead of rewriting it
        (what a tool that edits the NPZ alone would do; the readers then still
        compare it with the JSON's gains, `check_npz`).

    Returns
    -------
    Path
        The JSON file.
    """
    path = Path(path)
    doc = json.loads(read_limited(path).decode("utf-8"))
    gains = {k: np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
    npz = read_limited(path.with_suffix(".npz")) if keep_npz else _npz_bytes(gains)
    prov = doc.setdefault("provenance", {})
    prov["gains_sha256"] = gains_digest(gains)
    prov["npz_sha256"] = hashlib.sha256(npz).hexdigest()
    record = path.parent / "plant.json"
    if prov.get("plant_record_sha256") is not None and record.is_file():
        prov["plant_record_sha256"] = file_sha256(record)
    prov["content_sha256"] = content_digest(doc)
    trace = path.with_name(f"{doc.get('name', path.stem)}.traces.npz")
    if isinstance(doc.get("verification"), dict) and trace.is_file():
        doc["verification"]["traces_sha256"] = file_sha256(trace)
    if not keep_npz:
        atomic_write(path.with_suffix(".npz"), npz)
    atomic_write(path, dumps(doc) + "\n")
    return path


#: Files of a result directory that belong to the run as a whole (not to one design).
_RUN_FILES = ("plant.json", "spec.toml", "checks.json", "refused.json", "campaign.csv", "campaign.json",
              "report.tex", "report.pdf", "report.log")
#: Files written beside an artefact ``<name>.json``.
_SIBLING_SUFFIXES = (".npz", ".traces.npz", ".mat", ".h", "_law.c", "_law.h", "_law.casadi")


def other_spec_files(directory: str | Path, spec_sha256: str) -> tuple[str, list[Path]]:
    """What in ``directory`` was written from another spec than ``spec_sha256``.

    Parameters
    ----------
    directory : str or Path
    spec_sha256 : str
        sha256 of the spec about to be designed into ``directory``.

    Returns
    -------
    reason : str
        Empty when nothing was written from another spec; else which file
        says so (the plant record or an artefact's provenance).
    files : list of Path
        The files of that other run (its artefacts with their ``.npz``,
        traces and exports, and its checks, campaign and report), which
        ``design --force`` removes before writing.
    """
    directory = Path(directory)
    if not directory.is_dir():
        return "", []
    reason, files = "", []
    record = directory / "plant.json"
    if record.is_file():
        try:
            other = json.loads(read_limited(record).decode("utf-8")).get("spec_sha256")
        except (OSError, ValueError, AttributeError):
            other = None
        if other != spec_sha256:
            reason = f"{record} was written from another spec (spec_sha256 {str(other)[:12]}...)"
            files += [directory / f for f in _RUN_FILES[2:] if (directory / f).is_file()]
    for path in sorted(directory.glob("*.json")):
        if path.name in _RUN_FILES:
            continue
        try:
            doc = json.loads(read_limited(path).decode("utf-8"))
        except (OSError, ValueError):
            continue
        if not isinstance(doc, dict) or doc.get("schema") != SCHEMA:
            continue
        other = (doc.get("provenance") or {}).get("spec_sha256") if isinstance(
            doc.get("provenance"), dict) else None
        if other != spec_sha256:
            reason = reason or f"{path} was designed from another spec (spec_sha256 {str(other)[:12]}...)"
            stem = path.name[:-len(".json")]
            files += [path] + [directory / f"{stem}{sfx}" for sfx in _SIBLING_SUFFIXES
                               if (directory / f"{stem}{sfx}").is_file()]
    return reason, files
