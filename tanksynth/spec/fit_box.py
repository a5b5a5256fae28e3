"""The parameter box of a fit result: a robust design's ``uncertain = "fit"`` with ``fit = "PATH"``.

``PATH`` (relative to the spec file) is a fit result directory (its ``fit.json`` is read) or a
fit artefact JSON file. The box is the fit's intervals (``diagnostics.parameters.<name>.ci95``,
at the fit's confidence level) of its free parameters. The file is read bounded and checked
(schema, method, every interval finite and inside the parameter's admissible range); any
problem is a `SpecError` naming the file (exit 2).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tanksynth.errors import SpecError

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["FitBox", "MAX_FIT_BYTES", "MAX_DIRECTORY_FILES", "fit_file", "read_fit_box"]

#: Largest fit file read (bytes).
MAX_FIT_BYTES = 32 * 1024 * 1024


@dataclass(frozen=True)
class FitBox:
    """The intervals of a fit's free parameters, and where they came from.

    Attributes
    ----------
    box : tuple of (str, float, float)
        Parameter name, lower and upper bound (the parameter's unit), in the fit's order.
    file : str
        The fit file read.
    sha256 : str
        Its sha256.
    level : float
        The intervals' confidence level (dimensionless).
    """

    box: tuple[tuple[str, float, float], ...]
    file: str
    sha256: str
    level: float

    def source(self) -> dict[str, Any]:
        """``{file, sha256, level}`` (a design's ``diagnostics.uncertain_source``)."""
        return {"file": self.file, "sha256": self.sha256, "level": self.level}


#: Most JSON files of a result directory looked at for its fit artefact.
MAX_DIRECTORY_FILES = 64


def fit_file(path: str | Path, key: str = "fit") -> Path:
    """The fit JSON named by ``path``: the file itself, or the fit artefact of a directory.

    In a directory, ``fit.json`` when it exists, else the one artefact whose ``method`` is
    ``"fit"`` (a fit design named ``myfit`` writes ``myfit.json``).

    Parameters
    ----------
    path : str or Path
        A fit result directory or a fit artefact JSON file.
    key : str
        Spec key, for messages.

    Returns
    -------
    Path

    Raises
    ------
    SpecError
        A directory with no fit artefact, or with several (naming them).
    """
    p = Path(path)
    if not p.is_dir():
        return p
    if (p / "fit.json").is_file():
        return p / "fit.json"
    candidates = sorted(p.glob("*.json"))[:MAX_DIRECTORY_FILES]
    found = []
    for file in candidates:
        try:
            doc = json.loads(_read(file, key))
        except (SpecError, ValueError):
            continue
        if isinstance(doc, dict) and doc.get("method") == "fit":
            found.append(file)
    if len(found) == 1:
        return found[0]
    if not found:
        raise SpecError(f"{p}: no fit artefact (a JSON file with method \"fit\") in this directory; "
                        "name the fit's JSON file instead", key=key)
    raise SpecError(f"{p}: {len(found)} fit artefacts ({', '.join(f.name for f in found)}); name one "
                    "of them", key=key)


def _read(path: Path, key: str) -> bytes:
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise SpecError(f"{path}: cannot read the fit result: {exc.strerror}", key=key) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise SpecError(f"{path}: not a regular file (expected a fit result's fit.json)", key=key)
        if st.st_size > MAX_FIT_BYTES:
            raise SpecError(f"{path}: {st.st_size} bytes, more than the {MAX_FIT_BYTES} a fit file "
                            "may have", key=key)
        with os.fdopen(fd, "rb", closefd=False) as fh:
            raw = fh.read(MAX_FIT_BYTES + 1)
    finally:
        os.close(fd)
    if len(raw) > MAX_FIT_BYTES:
        raise SpecError(f"{path}: more than the {MAX_FIT_BYTES} bytes a fit file may have", key=key)
    return raw


def read_fit_box(path: str | Path, key: str, plant: Plant) -> FitBox:
    """Read the box of a fit result (see the module docstring).

    Parameters
    ----------
    path : str or Path
        The fit result directory or its JSON file (already resolved against the spec file).
    key : str
        Spec key (``design[i].fit``), for messages.
    plant : Plant
        The spec's plant: every fitted parameter must be one of its parameters and each interval
        inside its admissible range.

    Returns
    -------
    FitBox

    Raises
    ------
    SpecError
        Naming the file: unreadable, too large, not JSON, not a fit artefact, a malformed or
        non-finite interval, an unknown parameter, an interval outside the admissible range.
    """
    file = fit_file(path, key)
    raw = _read(file, key)
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise SpecError(f"{file}: not a fit result (not JSON: {str(exc)[:80]})", key=key) from None
    if not isinstance(doc, dict) or not str(doc.get("schema", "")).startswith("tanksynth.artefact/") \
            or doc.get("method") != "fit":
        raise SpecError(f"{file}: not a fit result (expected an artefact of method 'fit' written by "
                        "tanksynth fit)", key=key)
    if doc.get("plant") != plant.name:
        raise SpecError(f"{file}: a fit of plant {str(doc.get('plant'))[:80]!r}, not of this spec's "
                        f"plant {plant.name!r}: its intervals are another model's", key=key)
    diag = doc.get("diagnostics")
    if not isinstance(diag, dict):
        diag = {}
    params = diag.get("parameters")
    if not isinstance(params, dict) or not params:
        raise SpecError(f"{file}: no diagnostics.parameters (the fitted intervals)", key=key)
    level = diag.get("level", 0.95)
    if not isinstance(level, (int, float)) or not 0 < float(level) < 1:
        raise SpecError(f"{file}: diagnostics.level must be in (0, 1), got {level!r}", key=key)
    known = {prm.name: prm for prm in plant.parameters}
    box = []
    for name, entry in params.items():
        where = f"{file}: diagnostics.parameters.{name}"
        if name not in known:
            raise SpecError(f"{where}: not a parameter of plant '{plant.name}'", key=key)
        ci = entry.get("ci95") if isinstance(entry, dict) else None
        if not (isinstance(ci, list) and len(ci) == 2 and all(isinstance(v, (int, float))
                                                             and not isinstance(v, bool) for v in ci)):
            raise SpecError(f"{where}.ci95: expected [low, high], got {ci!r}"[:200], key=key)
        lo, hi = float(ci[0]), float(ci[1])
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise SpecError(f"{where}.ci95: expected finite low <= high, got [{lo!r}, {hi!r}]", key=key)
        try:
            known[name].check(lo, key)
            known[name].check(hi, key)
        except SpecError as exc:
            raise SpecError(f"{where}.ci95: {exc.detail}", key=key) from None
        box.append((str(name), lo, hi))
    return FitBox(tuple(box), str(file), hashlib.sha256(raw).hexdigest(), float(level))
