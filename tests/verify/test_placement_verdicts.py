"""The placement verdicts judge repeated poles fairly (issue 12 item 1)."""

from __future__ import annotations

import numpy as np

from tanksynth.artefacts import write_artefact, write_plant_record
from tanksynth.methods import METHODS, parse_spec_text, verify_directory

SPEC = """
title = "triple pole"
[plant]
model = "hydraulic_fault"
[operating_point]
x = {x1 = 4.0, x2 = 1.3333333333333333, x3 = 4.0}
[[design]]
name = "pp"
method = "pole_placement"
target = "state_feedback"
poles = [-2, -2, -2]
[[design]]
name = "co"
method = "canonical_observer"
poles = [-2, -2, -2]
"""


def test_triple_pole_artefacts_pass_their_verdicts(tmp_path):
    spec = parse_spec_text(SPEC)
    write_plant_record(spec, tmp_path)
    for entry in spec.designs:
        write_artefact(METHODS[entry.method].design(spec, entry), tmp_path, spec.sha256)
    verdicts = {v.name: v for v in verify_directory(tmp_path)}
    for name in ("pp", "co"):
        poles = next(c for c in verdicts[name].checks if c.name == "poles")
        assert poles.passed, poles.detail
        assert poles.data["multiplicity"] == [3, 3, 3]
        assert poles.data["max_relative_error"] > 1e-6       # the naive test would have failed
        assert poles.data["polynomial_error"] < 1e-10
    # independent: (s + 2)^3 from the stored gains
    doc = __import__("json").loads((tmp_path / "pp.json").read_text())
    A, B, K = (np.array(doc["gains"][k]) for k in ("F", "B", "K"))   # no ts: continuous
    assert np.allclose(np.poly(A - B @ K), [1, 6, 12, 8], rtol=1e-10)
