"""verify/runner.py: the verification field written back into an artefact, byte for byte what
encoding the whole document gives, whatever the position of the field."""

import json

import pytest

from tanksynth.artefacts.jsontext import dumps
from tanksynth.verify.runner import _splice_top_level, _write_verification

VERDICT = {"passed": False, "checks": [{"check": "x", "passed": None, "detail": "a \"quoted\"\nline",
                                        "data": {"e": [1.0, 2.5e-17, -3.0], "empty": [], "n": None}}]}


@pytest.mark.parametrize("order", ["middle", "last", "absent", "first"])
def test_written_field_equals_the_whole_document_encoded(tmp_path, order):
    doc = {"schema": "tanksynth.artefact/1", "name": "a",
           "gains": {"K": [[1.5, -2.0], [0.1, 3e-300]]}, "diagnostics": {"note": "  \"verification\": x"}}
    if order == "middle":
        doc = {**doc, "verification": None, "provenance": {"spec_sha256": "0" * 64}}
    elif order == "last":
        doc = {**doc, "provenance": {}, "verification": {"passed": True, "checks": []}}
    elif order == "first":
        doc = {"verification": None, **doc}
    path = tmp_path / "a.json"
    path.write_text(dumps(doc) + "\n", encoding="utf-8")
    _write_verification(path, VERDICT)
    expected = dict(doc)
    expected["verification"] = VERDICT
    assert path.read_text(encoding="utf-8") == dumps(expected) + "\n"
    assert json.loads(path.read_text(encoding="utf-8")) == expected


def test_splice_needs_a_top_level_key():
    text = dumps({"a": {"verification": 1}}) + "\n"
    assert _splice_top_level(text, "verification", "2") is None      # nested only: not spliced
    assert json.loads(_splice_top_level(text, "a", "3")) == {"a": 3}
