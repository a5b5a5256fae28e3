"""Helpers for the report tests (not a test module)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tanksynth.artefacts import write_artefact, write_plant_record
from tanksynth.methods import METHODS
from tanksynth.methods import parse_spec_text

HAVE_LATEX = all(shutil.which(t) for t in ("pdflatex", "pdftotext", "pdftoppm"))
needs_latex = pytest.mark.skipif(not HAVE_LATEX, reason="pdflatex/pdftotext/pdftoppm not installed "
                                                        "(make tex)")


def copy_dir(src: Path, dst: Path) -> Path:
    """A private copy of a result directory (tests may edit it)."""
    shutil.copytree(src, dst)
    return dst


def design_dir(directory: Path, spec_text: str) -> Path:
    """Write the plant record and every design of ``spec_text`` into ``directory`` (no rank checks)."""
    spec = parse_spec_text(spec_text.encode(), source="<test>")
    write_plant_record(spec, directory)
    for design in spec.designs:
        write_artefact(METHODS[design.method].design(spec, design), directory, spec.sha256)
    return directory


def edit_json(path: Path, **changes) -> None:
    """Change top-level keys of an artefact JSON and re-hash it (a consistently written design)."""
    from tanksynth.artefacts.io import rehash

    doc = json.loads(path.read_text(encoding="utf-8"))
    doc.update(changes)
    path.write_text(json.dumps(doc, indent=2), encoding="utf-8")
    rehash(path)


def replace_plant_record(directory: Path, record: dict) -> None:
    """Replace ``plant.json`` and re-hash every artefact against it (an edit, not tampering)."""
    from tanksynth.artefacts.io import rehash

    (directory / "plant.json").write_text(json.dumps(record), encoding="utf-8")
    for path in directory.glob("*.json"):
        if path.name not in ("plant.json", "checks.json") and "gains" in json.loads(path.read_text()):
            rehash(path)
