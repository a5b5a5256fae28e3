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


def test_recorder_keeps_the_main_trace_and_the_first_of_two_other_checks():
    from tanksynth.artefacts.traces import TRACE_EXTRAS

    plant, res = _result(steps=20)
    rec = TraceRecorder()
    assert rec.extras == []
    for scenario, check in [("main", "a"), ("again a", "a"), ("first b", "b"), ("second b", "b"),
                            ("first c", "c"), ("first d", "d"), ("first e", "e"), ("first f", "f")]:
        rec.record(res, plant, scenario=scenario, check=check)
    assert TRACE_EXTRAS == 4
    assert rec.trace["header"]["scenario"] == "main"                 # the main trace is unchanged
    assert [(e["header"]["scenario"], e["header"]["check"]) for e in rec.extras] == \
        [("first b", "b"), ("first c", "c"), ("first d", "d"), ("first e", "e")]   # f: over the limit
    assert "disturbance_names" not in rec.trace["header"]


def _two_check_verdict(doc, spec, *, trace=None):
    plant, res = _result(steps=10)
    trace.record(res, plant, scenario="main run", check="main")
    trace.record(res, plant, scenario="step", check="step", disturbances=["q2"])
    return [Check("main", True, "ran"), Check("step", False, "failed")]


def test_runner_returns_the_extras_with_their_own_verdicts():
    checks, trace = verdict_with_trace({"name": "a", "method": "m"}, None, _two_check_verdict)
    assert trace["header"]["check"] == "main" and trace["header"]["check_passed"] is True
    (extra,) = trace["more"]
    head = extra["header"]
    assert head["check"] == "step" and head["check_passed"] is False
    assert head["verdict_passed"] is False and head["artefact"] == "a" and head["method"] == "m"
    assert head["disturbance_names"] == ["q2"]
    # no extra recorded: an empty list
    assert verdict_with_trace({"name": "a", "method": "m"}, None, _simulating_verdict)[1]["more"] == []


# ----------------------------------------------------------------------------- named signals
def test_signals_follow_the_kept_runs_and_the_decimation():
    from tanksynth.verify.traces import Signal, trace_of

    plant, res = _result()
    M, N = res.x.shape[0], res.t.size
    level_sum = np.asarray(res.x, float).sum(axis=2)                   # (M, N): one value per run and sample
    flat = np.broadcast_to(np.linspace(1.0, 2.0, N), (M, N))
    tr = trace_of(res, plant, scenario="s", check="c", rows=[2, 0],
                  signals=(Signal("sum", "m", level_sum), Signal("limit", "m", flat, "--")),
                  signal_title="sum of levels", events=[(100.0, "event")])
    head, arr = tr["header"], tr["arrays"]
    stride = head["stride"]
    assert stride == int(np.ceil(N / TRACE_MAX_SAMPLES)) and head["runs"] == 2
    np.testing.assert_array_equal(arr["x"], np.asarray(res.x)[[2, 0]][:, ::stride])
    np.testing.assert_array_equal(arr["signals"][:, :, 0], level_sum[[2, 0]][:, ::stride])
    np.testing.assert_array_equal(arr["signals"][:, :, 1], flat[[2, 0]][:, ::stride])
    assert head["seeds"] == [int(v) for v in np.asarray(res.seeds)[[2, 0]]]
    assert head["signal_names"] == ["sum", "limit"] and head["signal_units"] == ["m", "m"]
    assert head["signal_styles"] == ["-", "--"] and head["signal_title"] == "sum of levels"
    assert head["events"] == [[100.0, "event"]]


def test_without_signals_the_trace_is_the_one_written_before_they_existed():
    from tanksynth.verify.traces import trace_of

    plant, res = _result()
    tr = trace_of(res, plant, scenario="s", check="c")
    assert set(tr["arrays"]) == {"t", "x", "t_u", "u"}
    assert set(tr["header"]) == {"schema", "scenario", "check", "runs", "stride", "ts", "plant", "state_names",
                                 "state_units", "input_names", "input_units", "reference_names", "seeds"}
    np.testing.assert_array_equal(tr["arrays"]["x"], np.asarray(res.x)[:2, ::tr["header"]["stride"]])
    first = trace_of(res, plant, scenario="s", check="c", rows=[0, 1])     # the same runs, named
    assert first["header"] == tr["header"]
    for key, value in tr["arrays"].items():
        np.testing.assert_array_equal(first["arrays"][key], value)


def test_a_signal_of_the_wrong_shape_or_a_run_outside_the_batch_is_refused():
    import pytest

    from tanksynth.verify.traces import Signal, trace_of

    plant, res = _result(steps=10)
    with pytest.raises(ValueError, match="signal 'r'"):
        trace_of(res, plant, scenario="s", check="c", signals=(Signal("r", "m", np.zeros((3, 10))),))
    with pytest.raises(ValueError, match="runs"):
        trace_of(res, plant, scenario="s", check="c", rows=[3])


def test_the_recorder_passes_signals_on():
    from tanksynth.verify.traces import Signal

    plant, res = _result(steps=10)
    rec = TraceRecorder()
    rec.record(res, plant, scenario="s", check="c", signals=(Signal("r", "1", np.ones((3, 11))),), rows=[1])
    assert rec.trace["arrays"]["signals"].shape == (1, 11, 1) and rec.trace["header"]["events"] == []
