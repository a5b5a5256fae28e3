"""Robust verdicts record their Monte-Carlo runs (tanksynth.verify.robust.traces)."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.artefacts.io import read_artefact, write_artefact
from tanksynth.artefacts.traces import trace_path, write_trace
from tanksynth.methods import METHODS, load_spec
from tanksynth.reports.figures import time_domain_figure
from tanksynth.verify.robust.traces import PeakRecordingLaw, record_monte_carlo
from tanksynth.verify.runner import verdict_with_trace

EXAMPLE = "examples/three_tank_robust.toml"


@pytest.mark.slow
@pytest.mark.parametrize("name,observer", [("robust_integral", False), ("robust_observer", True)])
def test_monte_carlo_runs_are_the_trace_and_are_drawn(name, observer, tmp_path):
    spec = load_spec(EXAMPLE)
    design = next(d for d in spec.designs if d.name == name)
    doc = read_artefact(write_artefact(METHODS[design.method].design(spec, design), tmp_path,
                                       spec.sha256))
    checks, trace = verdict_with_trace(doc, spec, METHODS[doc["method"]].verdict)
    assert trace is not None
    head, arr = trace["header"], trace["arrays"]
    mc = next(c for c in checks if c.name == "monte_carlo")
    assert head["check"] == "monte_carlo" and head["check_passed"] is mc.passed
    runs = int(dict(design.options).get("mc_runs", 16))
    assert arr["x"].shape[0] == runs
    assert ("x_hat" in arr) is observer
    # each run is its own plant (parameters drawn in the box): the runs differ
    assert np.ptp(arr["x"][:, -1, :], axis=0).max() > 1e-6
    write_trace(trace_path(tmp_path / f"{name}.json", name), trace)
    fig = time_domain_figure(doc, tmp_path, tmp_path / "figs", f"traces-00-{name}")
    assert fig is not None and fig.check == "monte_carlo" and fig.estimator is observer
    assert f"{runs} runs shown" in fig.caption


def test_no_recorder_records_nothing_and_peak_law_tracks_the_excursion():
    record_monte_carlo(None, object(), object(), observer=False)   # no recorder: nothing to do
    law = PeakRecordingLaw(lambda x, r, t: x[:, :1] * 2.0, np.zeros(1), np.array([4.0]))
    law.reset(2)
    law(np.array([[1.0], [-3.0]]), None, 0.0)
    law(np.array([[0.5], [1.0]]), None, 1.0)
    assert np.allclose(law.peak, [0.5, 1.5])
