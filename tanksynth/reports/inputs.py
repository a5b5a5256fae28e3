"""What a report reads: the plant record, the spec, the rank verdicts and the artefacts of DIR.

The report stage never designs or simulates; it only reads the files the
earlier stages wrote (see `tanksynth.artefacts.io`).
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from tanksynth.artefacts.io import (PLANT_SCHEMA, SCHEMA, check_npz, check_orphan_npz,
                                    check_plant_record, read_artefact, read_limited,
                                    read_plant_record)
from tanksynth.artefacts.traces import check_trace
from tanksynth.errors import ArtefactError
from tanksynth.reports.refused import REFUSED_FILE, read_refused
from tanksynth.reports.trusted import check_result_latex
from tanksynth.verify.replay import read_replay
from tanksynth.verify.runner import read_checks

__all__ = ["ReportInputs", "read_report_inputs"]


@dataclass(frozen=True)
class ReportInputs:
    """Everything a report is built from, as read from one directory.

    Attributes
    ----------
    directory : Path
    plant : dict
        ``plant.json`` (schema ``tanksynth.plant/1``).
    spec_text : str or None
        ``spec.toml`` when present.
    checks : tuple of dict or None
        ``checks.json`` (rank verdicts) when present.
    artefacts : tuple of dict
        Every ``*.json`` of schema ``tanksynth.artefact/1``, sorted by file
        name, read with `tanksynth.artefacts.io.read_artefact` (gains are numpy
        arrays). Each carries its file name under ``"_file"``.
    campaign : tuple of dict or None
        Rows of ``campaign.csv`` (Monte-Carlo campaign of ``tanksynth verify
        --runs``) when present, as strings.
    refused : tuple of dict
        Designs refused as infeasible (``refused.json``, see
        `tanksynth.reports.refused`).
    replay : dict or None
        ``replay.json`` of ``tanksynth replay`` (artefacts run on logged data) with each
        entry's trace when it matches its sha256 (`tanksynth.verify.replay.read_replay`);
        None when there is none.
    """

    directory: Path
    plant: Mapping[str, Any]
    spec_text: str | None
    checks: tuple[Mapping[str, Any], ...] | None
    artefacts: tuple[Mapping[str, Any], ...]
    campaign: tuple[Mapping[str, str], ...] | None = None
    refused: tuple[Mapping[str, Any], ...] = ()
    replay: Mapping[str, Any] | None = None

    @property
    def plant_name(self) -> str:
        """The plant model name (``three_tank`` ...)."""
        return str(self.plant.get("plant", {}).get("name", ""))

    @property
    def x0(self) -> np.ndarray | None:
        """The operating point of the plant record."""
        x = (self.plant.get("operating_point") or {}).get("x")
        return None if x is None else np.asarray(x, dtype=float)

    def parameters(self) -> dict[str, float]:
        """Parameter values of the plant record by name."""
        out = {}
        for p in self.plant.get("plant", {}).get("parameters", []):
            try:
                out[str(p["name"])] = float(p["value"])
            except (KeyError, TypeError, ValueError):
                continue
        return out

    def by_method(self, method: str) -> tuple[Mapping[str, Any], ...]:
        """Artefacts of one design method, in file order.

        Parameters
        ----------
        method : str
            Design method name.
        """
        return tuple(a for a in self.artefacts if a.get("method") == method)


def _schema_of(path: Path) -> str | None:
    # bounded like every result file: a FIFO or /dev/zero named *.json is refused (naming it)
    raw = read_limited(path)
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):
        return None
    return doc.get("schema") if isinstance(doc, dict) else None


def read_report_inputs(directory: str | Path) -> ReportInputs:
    """Read a result directory written by ``tanksynth run`` / ``tanksynth design``.

    Parameters
    ----------
    directory : str or Path

    Returns
    -------
    ReportInputs

    Raises
    ------
    ArtefactError
        The directory does not exist, has no ``plant.json``, has no design
        artefact, or a file of the artefact schema is malformed or fails
        its provenance check, or LaTeX in it that the report would typeset is outside the
        math grammar of `tanksynth.reports.trusted`. The message names the file (and key).
    """
    d = Path(directory)
    if not d.is_dir():
        raise ArtefactError(f"{d}: no such directory (expected the output of `tanksynth run` "
                            "or `tanksynth design`)")
    if not (d / "plant.json").exists():
        raise ArtefactError(f"{d}: no plant.json ({PLANT_SCHEMA}); this is not a tanksynth result "
                            "directory: run `tanksynth run SPEC -o DIR` or `tanksynth design SPEC "
                            "-o DIR` first")
    plant = read_plant_record(d)
    artefacts = []
    for path in sorted(d.glob("*.json")):
        if path.name in ("plant.json", "checks.json", REFUSED_FILE) or path.name.startswith("."):
            continue
        if _schema_of(path) != SCHEMA:
            continue
        doc = read_artefact(path)
        doc["_file"] = path.name
        artefacts.append(doc)
    if not artefacts:
        raise ArtefactError(f"{d}: no design artefact (*.json of schema {SCHEMA!r}) to report on; "
                            "the spec needs at least one [[design]] that succeeded")
    names = [a["name"] for a in artefacts]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ArtefactError(f"{d}: several artefacts are named {dupes}")
    # the same integrity checks as `verify`: every byte the report reads is covered
    for doc in artefacts:
        check_npz(d / doc["_file"], doc)
        check_trace(d / doc["_file"], doc)   # the verdict trace verify recorded, read bounded
    check_orphan_npz(d, names)
    check_plant_record(d, [(d / doc["_file"], doc) for doc in artefacts])
    spec_path = d / "spec.toml"
    spec_text = (read_limited(spec_path).decode("utf-8", errors="replace")
                 if spec_path.exists() else None)
    raw_checks = read_checks(d)  # the same reading (and refusal) as verify and load
    checks = None if raw_checks is None else tuple(raw_checks)
    check_result_latex(d, plant, artefacts, checks)   # LaTeX a report typesets: the grammar
    campaign = None
    campaign_path = d / "campaign.csv"
    if campaign_path.exists():
        try:
            text = read_limited(campaign_path).decode("utf-8")
            campaign = tuple(dict(r) for r in csv.DictReader(io.StringIO(text, newline="")))
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise ArtefactError(f"{campaign_path}: unreadable campaign table: {exc}") from None
    return ReportInputs(d, plant, spec_text, checks, tuple(artefacts), campaign, read_refused(d),
                        read_replay(d))
