"""Verdict of the H2 / H-infinity / multi-objective artefacts, its own norms, StateSpace interop."""

from __future__ import annotations

import copy
from pathlib import Path

import control
import numpy as np
import pytest

from tanksynth.artefacts.io import artefact_document
from tanksynth.methods import design, load_spec
from tanksynth.verify.statespace import artefact_statespace
from tanksynth.verify.synthesis.verdicts import disturbance_plant, h2_norm, hinf_norm, synthesis_verdict

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "three_tank_hinf.toml"


@pytest.fixture(scope="module")
def designed():
    spec = load_spec(EXAMPLE)
    docs = {d.name: artefact_document(design(spec, d), spec.sha256) for d in spec.designs}
    return spec, docs


def _checks(doc, spec):
    return {c.name: c for c in synthesis_verdict(doc, spec)}


@pytest.mark.parametrize("name", ["hinf_controller", "h2_observer", "multiobjective_disk"])
def test_example_artefacts_pass_their_verdict(designed, name):
    spec, docs = designed
    checks = _checks(docs[name], spec)
    failed = {k: c.detail for k, c in checks.items() if c.passed is not True}
    assert not failed
    assert {"model_recheck", "synthesis_data", "stability", "hinf_norm", "h2_norm",
            "disturbance_step"} <= set(checks)
    if name == "multiobjective_disk":
        assert {"region", "lmi_recheck"} <= set(checks)
    if name == "h2_observer":
        assert "h2_optimality" in checks


def test_a_wrong_gain_fails_the_norm_checks(designed):
    spec, docs = designed
    doc = copy.deepcopy(docs["h2_controller"])
    doc["gains"]["K"] = (0.5 * np.asarray(doc["gains"]["K"])).tolist()
    checks = _checks(doc, spec)
    assert checks["h2_norm"].passed is False and checks["h2_optimality"].passed is False
    doc = copy.deepcopy(docs["hinf_controller"])
    doc["gains"]["K"] = (1.5 * np.asarray(doc["gains"]["K"])).tolist()
    checks = _checks(doc, spec)
    assert checks["hinf_norm"].passed is False
    doc = copy.deepcopy(docs["hinf_controller"])
    doc["diagnostics"]["synthesis"]["gamma"] *= 0.99   # a claim the gain does not meet
    assert _checks(doc, spec)["hinf_norm"].passed is False


def test_own_norms_against_python_control():
    rng = np.random.default_rng(7)
    A = rng.standard_normal((5, 5))
    A = 0.95 * A / np.max(np.abs(np.linalg.eigvals(A)))
    B, C = rng.standard_normal((5, 2)), rng.standard_normal((2, 5))
    sys = control.ss(A, B, C, np.zeros((2, 2)), 1.0)
    lo, hi = hinf_norm(A, B, C, 1.0)
    ref = control.norm(sys, "inf", tol=1e-10, method="scipy", print_warning=False)
    assert lo <= ref * (1 + 1e-8) and hi >= ref * (1 - 1e-8)
    assert h2_norm(A, B, C, 1.0) == pytest.approx(control.norm(sys, 2), rel=1e-8)


def test_disturbance_plant_adds_bw_w():
    spec = load_spec(EXAMPLE)
    Bw = np.eye(3) / 0.0154
    dp = disturbance_plant(spec.plant, Bw)
    assert dp.m == spec.plant.m + 3
    x, u = np.array([[0.4, 0.2, 0.3]]), np.array([[3e-5, 3e-5]])
    w = np.array([[1e-5, -2e-5, 3e-5]])
    diff = dp.compiled.rhs(x, np.hstack([u, w]))[0] - spec.plant.compiled.rhs(x, u)[0]
    np.testing.assert_allclose(diff, Bw @ w[0], rtol=1e-12)


def test_artefact_statespace_for_python_control_users(designed):
    spec, docs = designed
    perf = artefact_statespace(docs["hinf_controller"], spec=spec)
    assert perf.dt == 1.0 and perf.state_labels == ["h1", "h2", "h3"]
    gamma = docs["hinf_controller"]["diagnostics"]["synthesis"]["gamma"]
    assert hinf_norm(perf.A, perf.B, perf.C, 1.0)[1] <= gamma * (1 + 1e-6)
    ref = artefact_statespace(docs["hinf_controller"], "reference", spec)
    resp = control.step_response(ref, T=np.arange(0, 400.0))
    assert np.all(np.isfinite(resp.outputs))
    loop = artefact_statespace(docs["hinf_controller"], "loop")
    assert loop.ninputs == 2 and loop.noutputs == 2
    err = artefact_statespace(docs["h2_observer"], spec=spec)
    h2 = docs["h2_observer"]["diagnostics"]["synthesis"]["h2_bound"]
    assert control.norm(err, 2) == pytest.approx(h2, rel=1e-6)
    obs = artefact_statespace(docs["h2_observer"], "observer", spec)
    assert obs.ninputs == 2 + 2 and obs.output_labels == ["h1_hat", "h2_hat", "h3_hat"]


@pytest.mark.parametrize("name", ["h2_controller", "hinf_controller", "h2_observer", "hinf_observer",
                                  "multiobjective_disk"])
def test_the_disturbance_step_is_recorded_beside_the_main_run(designed, name, monkeypatch):
    """The recorder keeps the regulation / observer run (main) and the disturbance step (extra): its
    arrays are the simulated runs (decimated by the stated stride), its inputs the pumps then the
    declared disturbances, stepped to the check's w and removed at the check's phase."""
    import tanksynth.verify.synthesis.verdicts as synthesis
    from tanksynth.artefacts.traces import TRACE_MAX_SAMPLES
    from tanksynth.verify.traces import TraceRecorder

    spec, docs = designed
    runs = []

    def simulate_and_keep(*args, **kwargs):
        runs.append(synthesis.simulate.__wrapped__(*args, **kwargs))
        return runs[-1]

    simulate_and_keep.__wrapped__ = synthesis.simulate
    monkeypatch.setattr(synthesis, "simulate", simulate_and_keep)
    rec = TraceRecorder()
    checks = {c.name: c for c in synthesis_verdict(docs[name], spec, trace=rec)}
    observer = "observer" in name
    assert rec.trace["header"]["check"] == ("observer_convergence" if observer else "regulation")
    (extra,) = rec.extras
    head, arr = extra["header"], extra["arrays"]
    assert head["check"] == "disturbance_step" and checks["disturbance_step"].passed is True
    (res,) = runs                                    # the one simulation of this module: the step
    stride = int(np.ceil(res.t.size / TRACE_MAX_SAMPLES))
    assert head["stride"] == stride and head["runs"] == 1
    np.testing.assert_array_equal(arr["t"], res.t[::stride])
    np.testing.assert_array_equal(arr["x"], res.x[:1, ::stride])
    np.testing.assert_array_equal(arr["u"], res.u[:1, ::stride])
    assert ("x_hat" in arr) is observer
    m = 2                                           # the three-tank's pumps q1, q2, then w
    assert head["input_names"] == ["q1", "q2", "w1", "w2", "w3"]
    assert head["disturbance_names"] == ["w1", "w2", "w3"]
    data = checks["disturbance_step"].data
    t_off = data["phase_samples"] * data["ts"]
    w = arr["u"][0, :, m:]
    on = arr["t_u"] < t_off - 1e-9
    np.testing.assert_allclose(w[on], np.tile(data["w"], (int(on.sum()), 1)), rtol=0, atol=0)
    assert np.all(w[~on] == 0.0) and on.any() and (~on).any()


@pytest.mark.parametrize("name", ["h2_observer", "hinf_observer"])
def test_observer_bias_and_its_linear_prediction_have_one_sign_convention(designed, name):
    """The disturbance step's estimation bias is x_hat - x; its linear prediction is printed with
    the same convention (it was printed as x - x_hat: opposite signs in one sentence)."""
    import re

    spec, docs = designed
    detail = _checks(docs[name], spec)["disturbance_step"].detail
    bias, pred = (np.array([float(v) for v in re.findall(r"-?[0-9.]+(?:e-?\d+)?", group)])
                  for group in re.search(r"bias \[([^\]]*)\] \(linear prediction \[([^\]]*)\]", detail).groups())
    big = np.abs(bias) > 0.2 * np.max(np.abs(bias))
    assert big.any() and np.all(np.sign(bias[big]) == np.sign(pred[big]))
