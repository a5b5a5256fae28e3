"""The typed artefact (tanksynth.artefacts.model): the document as written, read back field by field."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

from tanksynth.analysis.checks import Check
from tanksynth.artefacts.io import load_artefact, read_artefact, rehash, to_jsonable, write_artefact
from tanksynth.artefacts.jsontext import dumps
from tanksynth.artefacts.model import (SCHEMA, Artefact, Gains, Provenance, Verification,
                                       VerificationCheck, check_document)
from tanksynth.design.result import DesignResult
from tanksynth.errors import ArtefactError

SHA = "ab" * 32


def _result(name: str = "obs") -> DesignResult:
    gains = {"L": np.array([[0.5, -1.25e-5], [3.0, 1e300], [0.1, 2.0]]), "s": np.array(2.0),
             "x_hat0": np.array([0.4, 0.2, 0.3])}
    diagnostics = {"status": "optimal", "eigenvalues": np.array([-1.0 + 0.5j, -1.0 - 0.5j]),
                   "margin": np.float64(1e-3), "nested": {"rank": np.int64(3), "bad": float("inf")}}
    return DesignResult(name, "luenberger", "three_tank", gains, diagnostics, {"F": r"\begin{bmatrix}\end{bmatrix}"})


def _verification() -> dict:
    checks = [Check("stability", True, "spectral radius 0.91 < 1", {"value": 0.91, "domain": "discrete"}),
              Check("observer_convergence", False, "|e| 0.1 m -> 0.02 m", {"e0": 0.1, "tail_max": 0.02}),
              Check("information", None, "not decided")]
    return {"passed": False, "checks": [to_jsonable(c.as_dict()) for c in checks]}


def test_a_written_artefact_round_trips_byte_for_byte(tmp_path):
    path = write_artefact(_result(), tmp_path, SHA, solver="clarabel", plant_record_sha256="cd" * 32)
    text = path.read_text(encoding="utf-8")
    artefact = Artefact.from_document(json.loads(text), path)
    assert dumps(artefact.to_document()) + "\n" == text
    # and once verify recorded its checks (the field as the runner writes it)
    doc = json.loads(text)
    doc["verification"] = _verification()
    verified = dumps(doc) + "\n"
    again = Artefact.from_document(json.loads(verified), path)
    assert dumps(again.to_document()) + "\n" == verified


def test_the_fields_are_typed_and_the_gains_read_only(tmp_path):
    path = write_artefact(_result(), tmp_path, SHA, solver="clarabel")
    doc = json.loads(path.read_text(encoding="utf-8"))
    doc["verification"] = _verification()
    path.write_text(dumps(doc) + "\n", encoding="utf-8")   # verification: not covered by the hashes
    artefact = load_artefact(path)
    assert (artefact.name, artefact.method, artefact.plant, artefact.path) == ("obs", "luenberger",
                                                                              "three_tank", path)
    assert isinstance(artefact.gains, Gains) and list(artefact.gains) == ["L", "s", "x_hat0"]
    assert artefact.gains["L"].dtype == np.float64 and artefact.gains["L"].shape == (3, 2)
    assert artefact.gains["s"].shape == ()
    with pytest.raises(ValueError):
        artefact.gains["L"][0, 0] = 1.0
    with pytest.raises(TypeError):
        artefact.gains["K"] = np.eye(2)  # type: ignore[index]
    np.testing.assert_array_equal(artefact.gains["L"], read_artefact(path)["gains"]["L"])
    prov = artefact.provenance
    assert isinstance(prov, Provenance)
    assert (prov.spec_sha256, prov.solver, prov.plant_record_sha256) == (SHA, "clarabel", None)
    assert prov.gains_sha256 == doc["provenance"]["gains_sha256"]
    assert {"numpy", "python"} <= set(prov.packages)
    assert artefact.diagnostics["nested"] == {"rank": 3, "bad": "inf"}
    assert artefact.latex == {"F": r"\begin{bmatrix}\end{bmatrix}"}
    ver = artefact.verification
    assert isinstance(ver, Verification) and ver.passed is False
    assert [c.check for c in ver.checks] == ["stability", "observer_convergence", "information"]
    assert [c.passed for c in ver.checks] == [True, False, None]
    assert ver.check("stability") == VerificationCheck("stability", True, "spectral radius 0.91 < 1",
                                                       {"value": 0.91, "domain": "discrete"})
    assert ver.check("missing") is None
    copy = pickle.loads(pickle.dumps(artefact))
    assert copy.gains["L"][1, 1] == 1e300 and not copy.gains["L"].flags.writeable


def test_an_unverified_artefact_has_no_verification(tmp_path):
    artefact = load_artefact(write_artefact(_result(), tmp_path, SHA))
    assert artefact.verification is None
    assert artefact.to_document()["verification"] is None


@pytest.mark.parametrize("content", [
    '{"schema": "other/1"}', "[1, 2]", '{"schema": "tanksynth.artefact/1", "name": "a"}',
    '{"schema": "tanksynth.artefact/1", "name": "a", "method": "m", "plant": "p", '
    '"gains": {"K": "abc"}, "provenance": {}}',
    '{"schema": "tanksynth.artefact/1", "name": "a", "method": "m", "plant": "p", '
    '"gains": {"K": [[NaN]]}, "provenance": {}}',
    '{"schema": "tanksynth.artefact/1", "name": "b", "method": "m", "plant": "p", '
    '"gains": {}, "provenance": {}}',
    '{"schema": "tanksynth.artefact/1", "name": "a", "method": "m", "plant": "p", '
    '"gains": {}, "provenance": []}',
])
def test_the_form_is_refused_with_the_readers_errors(tmp_path, content):
    """`Artefact.from_document` and `read_artefact` raise the same error for the same document."""
    path = tmp_path / "a.json"
    path.write_text(content)
    with pytest.raises(ArtefactError) as by_reader:
        read_artefact(path)
    with pytest.raises(ArtefactError) as by_model:
        Artefact.from_document(json.loads(content), path)
    assert str(by_model.value) == str(by_reader.value)
    assert str(by_model.value).startswith(f"{path}: ")


@pytest.mark.parametrize("edit, match", [
    (lambda doc: doc["provenance"].pop("solver"), r"missing key 'provenance\.solver'"),
    (lambda doc: doc["provenance"].update(tanksynth_version=1), r"provenance\.tanksynth_version must be a string"),
    (lambda doc: doc["provenance"].update(packages=["numpy"]), r"provenance\.packages must be a table"),
    (lambda doc: doc["provenance"].update(extra="x"), r"unknown key\(s\) \['extra'\]"),
    (lambda doc: doc.update(method=3), "method must be a string"),
    (lambda doc: doc.update(diagnostics=[1]), "diagnostics must be a table"),
    (lambda doc: doc.update(latex={"F": 1}), "latex must be a table of strings"),
])
def test_a_field_of_another_type_is_refused_naming_the_file_and_key(tmp_path, edit, match):
    """Written consistently (`rehash`), so only the field's type is wrong."""
    path = write_artefact(_result(), tmp_path, SHA)
    doc = json.loads(path.read_text(encoding="utf-8"))
    edit(doc)
    path.write_text(json.dumps(doc), encoding="utf-8")
    rehash(path)
    read_artefact(path)   # the untyped reader checks the form and the hashes only
    with pytest.raises(ArtefactError, match=f"{path.name}: .*{match}"):
        load_artefact(path)


def test_the_verification_is_read_leniently():
    """Not covered by the hashes: what is not of the written form reads as not verified/undecided."""
    assert Verification.from_document(None) is None
    assert Verification.from_document("x") is None
    assert Verification.from_document({"passed": "true"}) == Verification(False, ())
    ver = Verification.from_document({"passed": True, "checks": [1, None, {"check": "a", "passed": "no",
                                                                           "detail": 3, "data": "x"}]})
    assert ver == Verification(True, (VerificationCheck("a", None, "3", {}),))


def test_check_document_returns_float_gains_and_needs_no_file():
    doc = {"schema": SCHEMA, "name": "a", "method": "m", "plant": "p", "gains": {"K": [[1, 2]]},
           "provenance": {}}
    gains = check_document(doc)
    assert gains["K"].dtype == np.float64 and gains["K"].tolist() == [[1.0, 2.0]]
    with pytest.raises(ArtefactError, match="name must be a string"):
        check_document({**doc, "name": 5})
