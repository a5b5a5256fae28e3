"""Trace recording is an explicit argument (`TraceRecorder`), passed by the runner."""

from __future__ import annotations

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.artefacts.traces import TRACE_MAX_SAMPLES
from tanksynth.plants import three_tank
from tanksynth.sim.simulate import run_seeds, simulate
from tanksynth.verify.runner import verdict_for, verdict_with_trace
from tanksynth.verify.traces import TraceRecorder


def _result(steps=4500):
    plant = three_tank()
    x0 = np.array([0.4, 0.2, 0.3])
    return plant, simulate(plant, ts=0.5, steps=steps, x0=x0, seeds=run_seeds(0, 3),
                           u_init=np.full(plant.m, 1e-5))


def test_recorder_keeps_the_first_simulation_decimated():
    plant, res = _result()
    rec = TraceRecorder()
    assert rec.trace is None
    rec.record(res, plant, scenario="s", check="c")
    rec.record(res, plant, scenario="second", check="c2")        # the first simulation only
    tr = rec.trace
    assert tr["header"]["scenario"] == "s" and tr["header"]["check"] == "c"
    assert tr["arrays"]["t"].size <= TRACE_MAX_SAMPLES and tr["arrays"]["x"].shape[0] == 2
    assert "x_hat" not in tr["arrays"]


def _simulating_verdict(doc, spec, *, trace=None):
    plant, res = _result(steps=10)
    if trace is not None:
        trace.record(res, plant, scenario="main run", check="main")
    return [Check("main", True, "ran"), Check("other", False, "failed")]


def test_runner_hands_a_recorder_to_a_verdict_that_takes_one():
    checks, trace = verdict_with_trace({"name": "a", "method": "m"}, None, _simulating_verdict)
    assert [c.name for c in checks] == ["main", "other"]
    header = trace["header"]
    assert header["check"] == "main" and header["check_passed"] is True
    assert header["verdict_passed"] is False and header["artefact"] == "a" and header["method"] == "m"


def test_a_verdict_without_the_keyword_runs_and_records_nothing():
    checks, trace = verdict_with_trace({"name": "a", "method": "m"}, None,
                                       lambda doc, spec: [Check("x", True, "")])
    assert [c.name for c in checks] == ["x"] and trace is None


def test_no_recorder_no_trace_and_no_global_state():
    # called without a recorder (the method-table signature), the verdict simulates untraced
    assert [c.name for c in verdict_for({}, None, _simulating_verdict)] == ["main", "other"]
    rec = TraceRecorder()
    verdict_for({}, None, _simulating_verdict, trace=rec)
    assert rec.trace["header"]["scenario"] == "main run"
    other = TraceRecorder()                                        # recorders are independent
    assert other.trace is None
