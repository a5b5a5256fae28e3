"""Designs refused as infeasible: ``DIR/refused.json``, so that the report can show them.

A refused design writes no artefact (exit 3); ``tanksynth run``/``design``
record the refusal here (the design's name, method, the reason and, when the
`tanksynth.errors.InfeasibleDesign` carries one, its certificate) and the
report shows it in the design section with its problem statement.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterable, Mapping

from tanksynth.artefacts.atomic import atomic_write
from tanksynth.artefacts.io import read_limited, to_jsonable
from tanksynth.errors import ArtefactError

__all__ = ["REFUSED_FILE", "REFUSED_SCHEMA", "refusal", "write_refused", "read_refused"]

#: File name of the refusal record in a result directory.
REFUSED_FILE = "refused.json"
#: Its schema tag.
REFUSED_SCHEMA = "tanksynth.refused/1"


def refusal(name: str, method: str, exc: BaseException) -> dict[str, Any]:
    """One refusal record from the `InfeasibleDesign` a design raised.

    Parameters
    ----------
    name, method : str
        The design's name and method.
    exc : BaseException
        The exception; its message is the reason, its ``certificate``
        attribute (a mapping or text), when present, the certificate.
    """
    cert = getattr(exc, "certificate", None)
    return {"name": str(name), "method": str(method), "reason": " ".join(str(exc).split()),
            "certificate": to_jsonable(cert) if cert is not None else None}


def write_refused(directory: str | Path, records: Iterable[Mapping[str, Any]]) -> Path | None:
    """Write ``DIR/refused.json`` (atomically); with no record, remove a stale one.

    Parameters
    ----------
    directory : str or Path
        The output directory.
    records : iterable of mapping
        Refusal records (method, reason, certificate).

    Returns
    -------
    Path or None
        The file written, None when there was nothing to record.
    """
    d = Path(directory)
    path = d / REFUSED_FILE
    recs = [dict(r) for r in records]
    if not recs:
        path.unlink(missing_ok=True)
        return None
    d.mkdir(parents=True, exist_ok=True)
    atomic_write(path, json.dumps({"schema": REFUSED_SCHEMA, "refused": recs}, indent=2) + "\n")
    return path


def read_refused(directory: str | Path) -> tuple[dict[str, Any], ...]:
    """The refusal records of DIR (none when there is no ``refused.json``).

    Parameters
    ----------
    directory : str or Path
        The output directory.

    Raises
    ------
    ArtefactError
        The file is not a refusal record.
    """
    path = Path(directory) / REFUSED_FILE
    if not path.exists():
        return ()
    try:
        doc = json.loads(read_limited(path).decode("utf-8"))   # bounded: a FIFO must not hang
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ArtefactError(f"{path}: unreadable refusal record: {exc}") from None
    if not isinstance(doc, dict) or doc.get("schema") != REFUSED_SCHEMA or \
            not isinstance(doc.get("refused"), list) or \
            not all(isinstance(r, dict) and "name" in r and "reason" in r for r in doc["refused"]):
        raise ArtefactError(f"{path}: expected schema {REFUSED_SCHEMA!r} with a list 'refused' of "
                            "{name, method, reason, certificate}")
    return tuple(doc["refused"])
