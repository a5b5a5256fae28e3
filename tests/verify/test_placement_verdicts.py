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


SPLANE_SPEC = """
title = "s-plane poles of a discrete design (a new user's spec)"
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.50, h2 = 0.15, h3 = 0.325}
[sampling]
ts = 2.0
[[design]]
name = "pp_s"
method = "pole_placement"
target = "state_feedback"
integral = true
tracked = ["h1", "h2"]
poles = {values = [-0.02, -0.025, -0.03, -0.035, -0.04], domain = "s"}
[[design]]
name = "pp_z"
method = "pole_placement"
target = "state_feedback"
integral = true
tracked = ["h1", "h2"]
poles = {values = [%s], domain = "z"}
"""


def test_s_plane_poles_of_a_discrete_design_give_the_servo_horizon_of_their_time_constant(tmp_path):
    """Poles written in the s-plane for a discrete design are placed at z = exp(p ts); the servo
    verdict's time constant is that of the s-plane poles (slowest 1/0.02 = 50 s), not the raw
    values read as z-plane poles (which gave 0.62 s and failed a correct design)."""
    ts, s = 2.0, np.array([-0.02, -0.025, -0.03, -0.035, -0.04])
    z = ", ".join(repr(float(v)) for v in np.exp(s * ts))
    spec = parse_spec_text(SPLANE_SPEC % z)
    write_plant_record(spec, tmp_path)
    for entry in spec.designs:
        write_artefact(METHODS[entry.method].design(spec, entry), tmp_path, spec.sha256)
    verdicts = {v.name: v for v in verify_directory(tmp_path)}
    for name in ("pp_s", "pp_z"):
        assert verdicts[name].passed, [(c.name, c.detail) for c in verdicts[name].checks
                                       if c.passed is False]
    servo = {name: next(c for c in verdicts[name].checks if c.name == "servo_tracking")
             for name in ("pp_s", "pp_z")}
    assert "50 s" in servo["pp_s"].detail or "tau = 50" in servo["pp_s"].detail, servo["pp_s"].detail
    assert servo["pp_s"].detail == servo["pp_z"].detail
