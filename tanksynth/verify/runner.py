"""``tanksynth verify DIR``: run each artefact's verdict and record it.

The verdict of each method comes from the method table (`tanksynth.methods`), passed in
as a mapping; an artefact whose method has no verdict is refused (exit 2), never passed.

`verify_directory` reads every artefact first (a tampered one, or one
designed from another spec than ``DIR/spec.toml``, is refused with an
`ArtefactError` before anything is written), runs the verdicts (in
process, or on a Dask cluster given its scheduler address), and writes
each artefact's ``verification`` field back atomically; gains are left
byte for byte as they were, so their provenance hash stays valid.
"""

from __future__ import annotations

import hashlib
import inspect
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Protocol

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.artefacts.atomic import atomic_write
from tanksynth.artefacts.io import (SCHEMA, check_npz, check_orphan_npz, check_plant_record, file_sha256,
                                    read_artefact, read_limited, to_jsonable)
from tanksynth.artefacts.jsontext import dumps
from tanksynth.artefacts.traces import TraceLimitError, trace_path, write_trace
from tanksynth.errors import ArtefactError, TanksynthError
from tanksynth.spec import Spec, parse_spec_text
from tanksynth.verify.cluster import CONNECT_TIMEOUT, WORKER_TIMEOUT, completed, connect
from tanksynth.verify.traces import TraceRecorder

__all__ = ["clear_cache", "VerdictFn", "Verdict", "verdict_for", "verdict_with_trace", "read_checks", "read_directory", "load_directory",
           "verify_directory"]


#: ``verdict(doc, spec, *, trace=None) -> list[Check]``: the verdict of one design method. The
#: keyword ``trace`` (a `TraceRecorder`) is optional: a verdict without it records no trace.
VerdictFn = Callable[..., list]

#: Errors a verdict may raise on bad data or failed numerics; they fail the artefact.
_VERDICT_ERRORS = (TanksynthError, np.linalg.LinAlgError, ValueError, RuntimeError, ArithmeticError,
                   KeyError, IndexError, TypeError)



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
    def passed(self) -> bool:
        """True if at least one check decided and every decided check passed.

        A verdict that decided nothing did not verify the artefact: it fails.
        """
        decided = [c.passed for c in self.checks if c.passed is not None]
        return bool(decided) and all(decided)

    def as_dict(self) -> dict:
        """The ``verification`` field of the artefact."""
        return {"passed": self.passed, "checks": [to_jsonable(c.as_dict()) for c in self.checks]}



def _takes_trace(verdict: VerdictFn) -> bool:
    """True if ``verdict`` accepts the keyword ``trace``."""
    try:
        params = inspect.signature(verdict).parameters
    except (TypeError, ValueError):
        return False
    return "trace" in params or any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())


def verdict_for(doc: Mapping[str, Any], spec: Spec, verdict: VerdictFn,
                trace: TraceRecorder | None = None) -> list[Check]:
    """The checks of one artefact (``doc`` as returned by `read_artefact`).

    A verdict that cannot run (bad artefact data, a numerical failure) gives
    one failed check ``verification`` with the reason, never a traceback.

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : tanksynth.spec.Spec
    verdict : callable
        ``verdict(doc, spec)``, with the keyword ``trace`` if it records.
    trace : TraceRecorder, optional
        Passed to the verdict when it accepts ``trace``.
    """
    try:
        if trace is not None and _takes_trace(verdict):
            return list(verdict(doc, spec, trace=trace))
        return list(verdict(doc, spec))
    except _VERDICT_ERRORS as exc:
        return [Check("verification", False, f"verdict could not run: {' '.join(str(exc).split())}")]


def verdict_with_trace(doc: Mapping[str, Any], spec: Spec,
                       verdict: VerdictFn) -> tuple[list[Check], dict | None]:
    """`verdict_for` with a fresh `TraceRecorder`: the checks and the recorded traces.

    Parameters
    ----------
    doc : mapping
        The artefact (as `read_artefact` returns it).
    spec : tanksynth.spec.Spec
        The spec the artefact was designed from.
    verdict : callable
        ``verdict(doc, spec)``, with the keyword ``trace`` if it records.

    Returns
    -------
    checks : list of Check
    trace : dict or None
        The main simulation's ``{"header": dict, "arrays": dict of ndarray}``
        (see `trace_of`) and ``more``, the list of the extra traces kept
        (`TraceRecorder.extras`, same form); each header gets the verdict of
        the check it decides (``check_passed``) and of the artefact
        (``verdict_passed``); None when the verdict recorded no simulation.
        Plain data: it crosses process boundaries (Dask) whole.
    """
    recorder = TraceRecorder()
    checks = verdict_for(doc, spec, verdict, trace=recorder)
    if recorder.trace is None:
        return checks, None
    decided = [c.passed for c in checks if c.passed is not None]
    for tr in [recorder.trace, *recorder.extras]:
        named = [c for c in checks if c.name == tr["header"]["check"]]
        tr["header"]["check_passed"] = named[0].passed if named else None
        tr["header"]["verdict_passed"] = bool(decided) and all(decided)
        tr["header"]["artefact"] = str(doc.get("name", ""))
        tr["header"]["method"] = str(doc.get("method", ""))
    return checks, {**recorder.trace, "more": list(recorder.extras)}



class VerifiableMethod(Protocol):
    """What the runner needs of a method-table row (`tanksynth.methods.Method`)."""

    verdict: VerdictFn
    adapter: Any  # ``adapter.validate(options, key, plant, ts) -> config``


#: Specs of result directories parsed in this process (at most 8; `clear_cache` empties it).
_SPECS: dict[tuple[str, str, tuple[str, ...]], Any] = {}


def clear_cache() -> int:
    """Forget the specs of result directories parsed in this process; returns how many."""
    count = len(_SPECS)
    _SPECS.clear()
    return count


def _spec_from_text(text: str, source: str, table: Mapping[str, VerifiableMethod]):
    """The spec of a result directory, every design's options validated (cached per process)."""
    key = (text, source, tuple(sorted(table)))
    if key not in _SPECS:
        if len(_SPECS) >= 8:
            _SPECS.pop(next(iter(_SPECS)))
        _SPECS[key] = parse_spec_text(text.encode("utf-8"), source=source,
                                      methods={name: row.adapter for name, row in table.items()})
    return _SPECS[key]



def read_checks(directory: str | Path) -> list[dict] | None:
    """Read the rank verdicts ``DIR/checks.json`` (written by ``tanksynth check -o DIR``).

    Parameters
    ----------
    directory : str or Path
        The result directory.

    Returns
    -------
    list of dict or None
        The verdicts (``check``, ``passed``, ``detail``, ``data``); None when
        the directory has no ``checks.json``.

    Raises
    ------
    ArtefactError
        Naming ``checks.json``: unreadable, not JSON, or not a list of
        verdicts (each an object with a ``check`` key).
    """
    path = Path(directory) / "checks.json"
    if not path.exists() and not path.is_symlink():
        return None
    try:
        raw = json.loads(read_limited(path).decode("utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise ArtefactError(f"{path}: not a JSON list of rank verdicts: {exc}") from None
    if not isinstance(raw, list) or not all(isinstance(c, dict) and "check" in c for c in raw):
        raise ArtefactError(f"{path}: expected a list of {{check, passed, detail, data}} (the rank "
                            "verdicts written by `tanksynth check -o DIR`)")
    return raw


def read_directory(directory: str | Path,
                   artefact: str | Path | None = None) -> tuple[bytes, list[tuple[Path, dict]]]:
    """Every integrity check of a result directory, or of one artefact in it.

    THE one code path behind ``tanksynth verify`` (`load_directory`) and
    ``tanksynth.load``: each artefact JSON is read with its content hash
    (`read_artefact`), its ``<name>.npz`` checked (`check_npz`), ``plant.json``
    checked against the artefacts (`check_plant_record`) and ``spec.toml``
    against their ``spec_sha256``. For a whole directory also: no ``.npz``
    without its artefact (`check_orphan_npz`) and a well-formed
    ``checks.json`` when present (`read_checks`). The spec is not parsed.

    Parameters
    ----------
    directory : str or Path
        The result directory (holds the artefacts, ``plant.json``, ``spec.toml``).
    artefact : str or Path, optional
        Check only this artefact JSON of ``directory`` (with its ``.npz``, the
        plant record and the spec) instead of every artefact.

    Returns
    -------
    spec_bytes : bytes
        The bytes of ``DIR/spec.toml`` (their sha256 matches every artefact's).
    artefacts : list of (Path, dict)
        Each artefact's path and document (gains as arrays), sorted by name.

    Raises
    ------
    ArtefactError
        Naming the file: no artefact, no ``spec.toml``, an unreadable or
        tampered artefact (any of its content changed after design), a
        missing, edited or swapped ``<name>.npz``, an ``.npz`` with no
        artefact, a ``plant.json`` other than the one designed with, an
        artefact designed from another spec, a malformed ``checks.json``.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise ArtefactError(f"{directory}: not a directory")
    docs = []
    if artefact is not None:
        path = Path(artefact)
        doc = read_artefact(path)
        check_npz(path, doc)
        docs.append((path, doc))
    else:
        for path in sorted(directory.glob("*.json")):
            if path.name == "checks.json":
                read_checks(directory)
                continue
            try:
                head = json.loads(read_limited(path).decode("utf-8"))
            except (OSError, ArtefactError, json.JSONDecodeError, UnicodeDecodeError, RecursionError):
                head = None
            if isinstance(head, dict) and isinstance(head.get("schema"), str) \
                    and not head["schema"].startswith("tanksynth.artefact/"):
                continue  # plant record, campaign metadata, ...
            doc = read_artefact(path)
            check_npz(path, doc)
            docs.append((path, doc))
        check_orphan_npz(directory, (path.stem for path, _ in docs))
    if not docs:
        raise ArtefactError(f"{directory}: no design artefact (<name>.json of schema {SCHEMA!r}) in it")
    check_plant_record(directory, docs)
    spec_path = directory / "spec.toml"
    try:
        raw = read_limited(spec_path)
    except ArtefactError:
        raise ArtefactError(f"{spec_path}: missing; the artefacts are checked against the spec they "
                            "were designed from (written by `tanksynth design`)") from None
    sha = hashlib.sha256(raw).hexdigest()
    for path, doc in docs:
        if doc["provenance"].get("spec_sha256") != sha:
            raise ArtefactError(f"{path}: designed from another spec than {spec_path} "
                                "(spec_sha256 differs)")
    return raw, docs


def load_directory(directory: str | Path,
                   table: Mapping[str, VerifiableMethod]) -> tuple[Any, list[tuple[Path, dict]]]:
    """Read ``DIR/spec.toml`` and every artefact of a directory, refusing bad ones.

    Parameters
    ----------
    directory : str or Path
        The result directory.
    table : mapping of method name to row
        The method table: each row's ``adapter`` validates the spec's options.

    Returns
    -------
    spec : tanksynth.spec.Spec
    artefacts : list of (Path, dict)
        Each artefact's path and document (gains as arrays), sorted by name.

    Raises
    ------
    ArtefactError
        Any integrity check of `read_directory` fails, or ``spec.toml`` is
        not UTF-8 text.
    """
    raw, docs = read_directory(directory)
    spec_path = Path(directory) / "spec.toml"
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ArtefactError(f"{spec_path}: not UTF-8 text") from None
    return _spec_from_text(text, str(spec_path), table), docs



def _write_verification(path: Path, verification: Mapping[str, Any]) -> None:
    """Set the ``verification`` field of an artefact JSON, atomically, gains untouched.

    The text is ``json.dumps(doc, indent=2)`` byte for byte (`tanksynth.artefacts.jsontext`):
    only the field's value is encoded and put in place of the old one (re-encoding a 1 MB
    artefact took 0.05-0.4 s); the result must parse back to the document with the new
    field, else the whole document is encoded again.
    """
    text = path.read_text(encoding="utf-8")
    raw = json.loads(text)
    raw["verification"] = verification
    out = _splice_top_level(text, "verification", dumps(verification).replace("\n", "\n  "))
    if out is None or json.loads(out) != raw:
        out = dumps(raw) + "\n"
    atomic_write(path, out)


def _splice_top_level(text: str, key: str, value: str) -> str | None:
    """``text`` (a JSON object indented by 2) with the value of its top-level ``key`` replaced.

    A top-level key is the only thing starting a line with exactly two spaces and a quote
    (JSON strings hold no raw newline); None when ``key`` is not found that way.
    """
    head = f"\n  {json.dumps(key)}: "
    i = text.find(head)
    if i < 0:
        return None
    start = i + len(head)
    nxt = text.find('\n  "', start)
    end = nxt if nxt >= 0 else text.rfind("\n}")
    if end < start:
        return None
    comma = "," if text[start:end].rstrip().endswith(",") else ""
    return text[:start] + value + comma + text[end:]



def _remote_verdict(table: Mapping[str, VerifiableMethod], doc: dict, spec_text: str,
                    source: str) -> tuple[list[dict], dict | None]:
    """Run one verdict on a Dask worker (plain data in, plain data out), with its traces (main and
    extras, `verdict_with_trace`)."""
    spec = _spec_from_text(spec_text, source, table)
    verdict = table[str(doc["method"])].verdict
    doc = dict(doc)
    doc["gains"] = {k: np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
    checks, trace = verdict_with_trace(doc, spec, verdict)
    return [c.as_dict() for c in checks], trace



def verify_directory(directory: str | Path, table: Mapping[str, VerifiableMethod],
                     scheduler: str | None = None,
                     progress: Callable[[int, int], None] | None = None,
                     connect_timeout: float = CONNECT_TIMEOUT,
                     started: Callable[[int, int, str, str], None] | None = None,
                     worker_timeout: float = WORKER_TIMEOUT,
                     waiting: Callable[[str], None] | None = None) -> list[Verdict]:
    """Verify every artefact of a directory and record the verdicts in them.

    Beside each artefact ``DIR/<name>.json`` the trace of its verdict's main
    simulation (and its extra traces, `TraceRecorder`) is written to
    ``DIR/<name>.traces.npz`` (`write_trace`, atomic); an artefact whose
    verdict simulates nothing has its stale trace removed. The artefact JSON gets only its ``verification`` field.

    Parameters
    ----------
    directory : str or Path
        Holds the artefacts and ``spec.toml``.
    table : mapping of method name to row
        The method table (`tanksynth.methods.METHODS`): each row's ``verdict``
        and its ``adapter`` (which validates the spec's options).
    scheduler : str, optional
        Address of a Dask scheduler: the verdicts run there (one task per
        artefact). Default: in this process.
    progress : callable, optional
        ``progress(done, total)`` after each artefact.
    connect_timeout : float
        Seconds to wait for the scheduler (`tanksynth.verify.cluster.connect`).
    started : callable, optional
        ``started(done, total, name, method)`` as an artefact's verdict starts (in process
        only: on a cluster they run at once), so a display can name the artefact whose
        checks run.
    worker_timeout : float
        On a cluster: seconds to wait while it has no worker before giving up (s).
    waiting : callable, optional
        On a cluster: ``waiting(text)``, one line when it has no worker.

    Returns
    -------
    list of Verdict

    Raises
    ------
    ArtefactError
        See `load_directory`; nothing is written then.
    SchedulerError
        The cluster had no worker for ``worker_timeout`` seconds; nothing is written then.
    """
    spec, docs = load_directory(directory, table)
    for path, doc in docs:
        if str(doc["method"]) not in table:
            raise ArtefactError(f"{path}: unknown design method {doc['method']!r}; expected one of: "
                                + ", ".join(sorted(table)))
    total = len(docs)
    checks: dict[Path, list[Check]] = {}
    traces: dict[Path, dict | None] = {}
    if scheduler is None:
        for i, (path, doc) in enumerate(docs):
            if started is not None:
                started(i, total, str(doc["name"]), str(doc["method"]))
            checks[path], traces[path] = verdict_with_trace(doc, spec, table[str(doc["method"])].verdict)
            if progress is not None:
                progress(i + 1, total)
    else:
        text = (Path(directory) / "spec.toml").read_text(encoding="utf-8")
        source = str(Path(directory) / "spec.toml")
        with connect(scheduler, connect_timeout) as client:
            futures = {}
            for path, doc in docs:
                plain = {**doc, "gains": {k: v.tolist() for k, v in doc["gains"].items()}}
                fut = client.submit(_remote_verdict, dict(table), plain, text, source,
                                    pure=False,
                                    retries=2)
                futures[fut] = path
            for i, fut in enumerate(completed(client, futures, worker_timeout=worker_timeout,
                                              waiting=waiting)):
                found, traces[futures[fut]] = fut.result()
                checks[futures[fut]] = [Check(c["check"], c["passed"], c["detail"], c["data"])
                                        for c in found]
                if progress is not None:
                    progress(i + 1, total)
    verdicts = []
    for path, doc in docs:
        v = Verdict(str(doc["name"]), str(doc["method"]), path, tuple(checks[path]))
        trace = traces.get(path)
        target = trace_path(path, str(doc["name"]))
        written = None
        if trace is not None:
            try:
                written = write_trace(target, trace)
            except TraceLimitError:  # beyond the limits every reader applies: no figure rather than a refusal
                written = None
        if written is None:
            target.unlink(missing_ok=True)  # a stale trace of an earlier verdict
        # the trace first, then the verification that records its hash (the report checks it)
        record = v.as_dict() if written is None else {**v.as_dict(), "traces_sha256": file_sha256(written)}
        _write_verification(path, record)
        verdicts.append(v)
    return verdicts
