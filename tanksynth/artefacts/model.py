"""The artefact document as typed, frozen objects (schema ``tanksynth.artefact/1``).

``DIR/<name>.json`` (DESIGN.md, "Artefact") is written once by design and
completed once by verify; every later stage only reads it. Who writes and who
reads each part:

`Artefact`
    Written by design (`tanksynth.artefacts.io.write_artefact`: ``tanksynth
    design`` and ``run``) from a `tanksynth.design.result.DesignResult`; read
    as an `Artefact` (`tanksynth.artefacts.io.load_artefact`) by
    ``tanksynth.load`` (`tanksynth.loading`) and the run summary
    (`tanksynth.messages.print_summary`), as its document
    (`tanksynth.artefacts.io.read_artefact`, the same checks) by verify
    (`tanksynth.verify.runner`) and the report (`tanksynth.reports.inputs`).
`Gains`
    Written by design (also as ``<name>.npz``); read by every stage after it
    (verify re-derives its checks from them).
`Provenance`
    Written by design (hashes of the spec, the gains, the ``.npz``, the plant
    record and the content; package versions); read by the integrity checks
    of every reader (`tanksynth.artefacts.io.read_artefact`,
    `tanksynth.verify.runner.read_directory`).
`Verification`, `VerificationCheck`
    Written by verify (``tanksynth verify`` and ``run``: the ``verification``
    field, None until then); read by the report, ``tanksynth.load`` and the
    run summary.

`Artefact.from_document` checks a document's form with the errors the
readers have always raised (`check_document`: schema, required keys, gains
as nested lists of numbers without NaN, the name of the file, a provenance
table), then the type of every field, naming the file and the key; the
integrity of the content (its hashes) is checked where files are read
(`tanksynth.artefacts.io.read_artefact`). `Artefact.to_document` gives the
document back: written with `tanksynth.artefacts.jsontext.dumps`, the text
of a document as tanksynth writes it is the same, byte for byte.

The ``verification`` field is not covered by the hashes (verify writes it
after design), so it is read leniently, as the run summary always read it:
a value that is not a table reads as not verified, entries of ``checks``
that are not tables are skipped, and a ``passed`` that is not true or false
reads as undecided (None) for a check, as not passed for the artefact.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np

from tanksynth.errors import ArtefactError

__all__ = ["SCHEMA", "Gains", "Provenance", "VerificationCheck", "Verification", "Artefact",
           "check_document"]

SCHEMA = "tanksynth.artefact/1"

#: Top-level keys every artefact has (``diagnostics``, ``latex`` and ``verification`` may be absent).
_REQUIRED = ("name", "method", "plant", "gains", "provenance")


class Gains(Mapping[str, np.ndarray]):
    """The gains of an artefact: a read-only mapping of name to read-only float64 array.

    Parameters
    ----------
    gains : mapping of str to array_like
        Every gain, in the plant's units (copied as float64 arrays, then made read-only).
    """

    def __init__(self, gains: Mapping[str, Any]) -> None:
        arrays: dict[str, np.ndarray] = {}
        for name, value in gains.items():
            arr = np.array(value, dtype=float)
            arr.flags.writeable = False
            arrays[str(name)] = arr
        self._arrays = arrays

    def __getitem__(self, name: str) -> np.ndarray:
        return self._arrays[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._arrays)

    def __len__(self) -> int:
        return len(self._arrays)

    def __reduce__(self) -> tuple[type[Gains], tuple[dict[str, np.ndarray]]]:
        return Gains, (self._arrays,)  # unpickled arrays would be writeable: made read-only again

    def __repr__(self) -> str:
        return "Gains(" + ", ".join(f"{k}: shape {v.shape}" for k, v in self._arrays.items()) + ")"

    def to_document(self) -> dict[str, Any]:
        """The ``gains`` field: every gain as nested lists of floats (a scalar as a float)."""
        return {name: arr.tolist() for name, arr in self._arrays.items()}


def _fail(path: Path | str | None, message: str) -> ArtefactError:
    return ArtefactError(f"{path}: {message}" if path is not None else message)


def _string(table: Mapping[str, Any], key: str, path: Path | str | None, prefix: str = "") -> str:
    """``table[key]``, refused unless a string (naming the key as ``prefix + key``)."""
    if key not in table:
        raise _fail(path, f"missing key {prefix + key!r}")
    value = table[key]
    if not isinstance(value, str):
        raise _fail(path, f"{prefix + key} must be a string, got {type(value).__name__}")
    return value


@dataclass(frozen=True)
class Provenance:
    """Where an artefact comes from, and the hashes that detect any later edit.

    Written by design (`tanksynth.artefacts.io.artefact_document`); checked by every
    reader of a result directory.

    Attributes
    ----------
    spec_sha256 : str
        sha256 (hex) of the spec text designed from (``spec.toml`` beside it).
    gains_sha256 : str
        sha256 of the gains' names, shapes and float64 bytes
        (`tanksynth.artefacts.io.gains_digest`).
    tanksynth_version : str
        The version of tanksynth that designed it.
    packages : mapping of str to str
        Versions of numpy, scipy, sympy, casadi and python.
    solver : str
        The solver used, if the caller named one (may be empty).
    npz_sha256 : str
        sha256 of the ``<name>.npz`` bytes written beside it.
    plant_record_sha256 : str or None
        sha256 of the ``plant.json`` written in the same run; None when designed without one.
    content_sha256 : str
        sha256 of everything design wrote (`tanksynth.artefacts.io.content_digest`).
    """

    spec_sha256: str
    gains_sha256: str
    tanksynth_version: str
    packages: Mapping[str, str]
    solver: str
    npz_sha256: str
    plant_record_sha256: str | None
    content_sha256: str

    @classmethod
    def from_document(cls, value: Any, path: Path | str | None = None) -> Provenance:
        """The ``provenance`` field of an artefact document, checked field by field.

        Parameters
        ----------
        value : mapping
            The field as read from the JSON.
        path : Path or str, optional
            The artefact file, named in errors.

        Raises
        ------
        ArtefactError
            Not a table, a key missing or unknown, or a value of another type
            (naming the file and ``provenance.<key>``).
        """
        if not isinstance(value, Mapping):
            raise _fail(path, "provenance must be a table")
        known = [f.name for f in fields(cls)]
        unknown = sorted(str(k) for k in value if k not in known)
        if unknown:
            raise _fail(path, f"provenance has unknown key(s) {unknown}; expected {known}")
        packages = value.get("packages")
        if not isinstance(packages, Mapping) or not all(
                isinstance(k, str) and isinstance(v, str) for k, v in packages.items()):
            raise _fail(path, "provenance.packages must be a table of version strings")

        def text(key: str) -> str:
            return _string(value, key, path, prefix="provenance.")

        # None: designed without a plant record (the key is written all the same)
        record = None if value.get("plant_record_sha256", "") is None else text("plant_record_sha256")
        return cls(text("spec_sha256"), text("gains_sha256"), text("tanksynth_version"),
                   dict(packages), text("solver"), text("npz_sha256"), record, text("content_sha256"))

    def to_document(self) -> dict[str, Any]:
        """The ``provenance`` field, its keys in the order the writer writes them."""
        return {f.name: (dict(self.packages) if f.name == "packages" else getattr(self, f.name))
                for f in fields(self)}


@dataclass(frozen=True)
class VerificationCheck:
    """One check recorded by verify: a condition, whether it held, why, and the numbers.

    Attributes
    ----------
    check : str
        The condition's name (``"stability"``, ``"observer_convergence"``...).
    passed : bool or None
        Whether it held; None when undecided (information only).
    detail : str
        One line saying why, with the numbers in the plant's units.
    data : mapping
        The numbers behind the verdict (JSON values, the plant's units).
    """

    check: str
    passed: bool | None
    detail: str
    data: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def from_document(cls, value: Mapping[str, Any]) -> VerificationCheck:
        """One entry of ``verification.checks`` (read leniently, see the module docstring).

        Parameters
        ----------
        value : mapping
            The entry as read from the JSON (``check``, ``passed``, ``detail``, ``data``).
        """
        passed = value.get("passed")
        data = value.get("data")
        detail = value.get("detail", "")
        return cls(str(value.get("check", "?")), passed if isinstance(passed, bool) else None,
                   detail if isinstance(detail, str) else str(detail),
                   data if isinstance(data, Mapping) else {})

    def to_document(self) -> dict[str, Any]:
        """The entry as verify writes it (the keys of `tanksynth.analysis.checks.Check.as_dict`)."""
        return {"check": self.check, "passed": self.passed, "detail": self.detail,
                "data": _plain(self.data)}


@dataclass(frozen=True)
class Verification:
    """What verify recorded for an artefact: the verdict and every check behind it.

    Attributes
    ----------
    passed : bool
        Every check that decides passed.
    checks : tuple of VerificationCheck
        In the order verify ran them.
    traces_sha256 : str or None
        sha256 of the ``<name>.traces.npz`` verify wrote beside the artefact; None when it
        wrote none (the key is then absent).
    """

    passed: bool
    checks: tuple[VerificationCheck, ...] = ()
    traces_sha256: str | None = None

    @classmethod
    def from_document(cls, value: Any) -> Verification | None:
        """The ``verification`` field (read leniently, see the module docstring).

        Parameters
        ----------
        value : mapping or None
            The field as read from the JSON (None until verify ran).

        Returns
        -------
        Verification or None
            None when not verified (or the field is not a table).
        """
        if not isinstance(value, Mapping):
            return None
        checks = value.get("checks")
        entries = checks if isinstance(checks, list) else []
        traces = value.get("traces_sha256")
        return cls(value.get("passed") is True,
                   tuple(VerificationCheck.from_document(c) for c in entries if isinstance(c, Mapping)),
                   traces if isinstance(traces, str) else None)

    def check(self, name: str) -> VerificationCheck | None:
        """The last check called ``name``, None when there is none.

        Parameters
        ----------
        name : str
            The check's name (``"stability"``...).
        """
        return next((c for c in reversed(self.checks) if c.check == name), None)

    def to_document(self) -> dict[str, Any]:
        """The ``verification`` field as verify writes it."""
        doc: dict[str, Any] = {"passed": self.passed, "checks": [c.to_document() for c in self.checks]}
        if self.traces_sha256 is not None:
            doc["traces_sha256"] = self.traces_sha256
        return doc


@dataclass(frozen=True, eq=False)
class Artefact:
    """One design artefact (``DIR/<name>.json``) as typed fields.

    Attributes
    ----------
    name : str
        The design's name (the file is ``<name>.json``).
    method : str
        Its method (a row of `tanksynth.methods.TABLE`).
    plant : str
        The plant model's name.
    gains : Gains
        Every gain, in the plant's units (read-only float arrays).
    diagnostics : mapping
        The design's evidence as JSON values (solver status, margins, eigenvalues...).
    latex : mapping of str to str
        LaTeX fragments for the report.
    verification : Verification or None
        What verify recorded; None until it ran.
    provenance : Provenance
        Hashes and versions.
    path : Path or None
        The file it was read from; None when built in memory.
    """

    name: str
    method: str
    plant: str
    gains: Gains
    diagnostics: Mapping[str, Any]
    latex: Mapping[str, str]
    verification: Verification | None
    provenance: Provenance
    path: Path | None = None

    @classmethod
    def from_document(cls, doc: Any, path: Path | str | None = None) -> Artefact:
        """An artefact document (as read from its JSON) as typed fields.

        The form is checked as every reader checks it (`check_document`), then
        each field's type; the hashes are not recomputed here (the readers of
        files do, `tanksynth.artefacts.io.read_artefact`). Keys other than the
        schema's are ignored.

        Parameters
        ----------
        doc : mapping
            The document (gains as nested lists or arrays).
        path : Path or str, optional
            The file it was read from: named in errors, and its stem must be the
            artefact's name.

        Raises
        ------
        ArtefactError
            Naming the file and the key (see `check_document`; also ``method``
            or ``plant`` not a string, ``diagnostics`` or ``latex`` not a table,
            a malformed `Provenance`).
        """
        gains = check_document(doc, path)
        method, plant = _string(doc, "method", path), _string(doc, "plant", path)
        diagnostics = doc.get("diagnostics")
        if diagnostics is None:
            diagnostics = {}
        if not isinstance(diagnostics, Mapping):
            raise _fail(path, f"diagnostics must be a table, got {type(diagnostics).__name__}")
        latex = doc.get("latex")
        if latex is None:
            latex = {}
        if not isinstance(latex, Mapping) or not all(isinstance(v, str) for v in latex.values()):
            raise _fail(path, "latex must be a table of strings")
        return cls(doc["name"], method, plant, Gains(gains), diagnostics, dict(latex),
                   Verification.from_document(doc.get("verification")),
                   Provenance.from_document(doc["provenance"], path),
                   None if path is None else Path(path))

    def to_document(self) -> dict[str, Any]:
        """The JSON document (gains as nested lists), keys in the order the writer writes them.

        Returns
        -------
        dict
            ``schema``, ``name``, ``method``, ``plant``, ``gains``, ``diagnostics``,
            ``latex``, ``verification``, ``provenance``.
        """
        return {
            "schema": SCHEMA,
            "name": self.name,
            "method": self.method,
            "plant": self.plant,
            "gains": self.gains.to_document(),
            "diagnostics": _plain(self.diagnostics),
            "latex": dict(self.latex),
            "verification": None if self.verification is None else self.verification.to_document(),
            "provenance": self.provenance.to_document(),
        }


def _plain(value: Any) -> Any:
    """A JSON value as plain dicts and lists (a copy: the caller may change it)."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def check_document(doc: Any, path: Path | str | None = None) -> dict[str, np.ndarray]:
    """Check the form of an artefact document; its gains as float arrays.

    The checks every reader of artefacts makes, in this order: the schema,
    the keys ``name``, ``method``, ``plant``, ``gains``, ``provenance``, the
    gains as nested lists of numbers without NaN (infinite entries mark
    unbounded limits), the name equal to the file's stem, a provenance table.

    Parameters
    ----------
    doc : mapping
        The document as read from the JSON (gains as nested lists or arrays).
    path : Path or str, optional
        The file it was read from (named in errors; its stem must be the name).

    Returns
    -------
    dict of str to ndarray
        The gains, float64 (the plant's units).

    Raises
    ------
    ArtefactError
        Naming the file: another schema, a missing key, gains that are not
        numbers, a NaN gain, a name other than the file's, a provenance that
        is not a table.
    """
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA:
        raise _fail(path, f"expected schema {SCHEMA!r}, got "
                          f"{doc.get('schema') if isinstance(doc, dict) else type(doc).__name__!r}")
    for key in _REQUIRED:
        if key not in doc:
            raise _fail(path, f"missing key {key!r}")
    if not isinstance(doc["gains"], Mapping):
        raise _fail(path, "gains must be nested lists of numbers")
    gains = {}
    for key, value in doc["gains"].items():
        try:
            gains[key] = np.asarray(value, dtype=float)
        except OverflowError:   # an integer beyond float64 (a 400-digit literal)
            raise _fail(path, f"gains.{key}: a number beyond the float64 range (|x| > 1.8e308)") from None
        except (TypeError, ValueError):
            raise _fail(path, f"gains.{key}: must be nested lists of numbers") from None
    bad = sorted(k for k, v in gains.items() if np.isnan(v).any())
    if bad:
        raise _fail(path, f"gain(s) {', '.join(bad)} hold NaN entries; a designed gain is a "
                          "number (infinite entries only mark unbounded limits)")
    if path is None and not isinstance(doc["name"], str):
        raise _fail(path, f"the artefact's name must be a string, got {doc['name']!r}")
    stem = None if path is None else Path(path).stem
    if stem is not None and (not isinstance(doc["name"], str) or doc["name"] != stem):
        raise _fail(path, f"the artefact's name {doc['name']!r} does not match its file "
                          f"name (expected {stem!r}); artefacts are written as <name>.json")
    if not isinstance(doc["provenance"], dict):
        raise _fail(path, "provenance must be a table")
    return gains
