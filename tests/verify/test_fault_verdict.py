"""The fault-detection verdict simulates the scenario the spec and artefact declare.

No initial state or input of a particular paper is built into the verdict: the starts come
from the design's ``initial_states``, else those recorded with the stored detection times,
else a documented rule on the operating point; the input from the design's ``input``, else
the equilibrium input.
"""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact, write_artefact
from tanksynth.cli import main
from tanksynth.design.result import DesignResult
from tanksynth.errors import ArtefactError
from tanksynth.methods import verify_directory
from tanksynth.plants import hydraulic_fault
from tanksynth.papers import seed004
from tanksynth.verify.fault.verdicts import (FAULT_START_OFFSET, fault_detection_verdict, fault_scenario,
                                    rule_initial_states)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

#: seed 004 section IV: its three initial states and its input (2, then 1)
PAPER_STARTS = [list(x) for x in seed004.INITIAL_STATES]
PAPER_INPUT = [[t, u] for t, u in seed004.INPUT]

#: appended to examples/seed004_fault_detection.toml: the example's plant and operating point,
#: the scenario of seed 004 section IV declared as the design's options
FAULT_DESIGN = f"""
[[design]]
name = "fd"
method = "fault_detection"
delta_bar = 1.0
initial_states = {PAPER_STARTS}
input = {PAPER_INPUT}
"""


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    root = tmp_path_factory.mktemp("fault")
    spec = root / "seed004_fd.toml"
    spec.write_text((EXAMPLES / "seed004_fault_detection.toml").read_text(encoding="utf-8")
                    + FAULT_DESIGN, encoding="utf-8")
    assert main(["design", str(spec), "-o", str(root / "out")]) == 0
    return root / "out"


def _rewrite(path: Path, gains=None, diagnostics=None) -> None:
    doc = read_artefact(path)
    g = {k: np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
    d = dict(doc["diagnostics"])
    if gains:
        gains(g)
    if diagnostics:
        diagnostics(d)
    write_artefact(DesignResult(doc["name"], doc["method"], doc["plant"], g, d, {}), path.parent,
                   doc["provenance"]["spec_sha256"])


def _checks(d: Path, name="fd"):
    verdicts = {v.name: v for v in verify_directory(d)}
    return verdicts[name], {c.name: c for c in verdicts[name].checks}


# ----------------------------------------------------------------------------- rules
def test_rule_initial_states_by_hand():
    # x_op = (4, 4/3, 4), bounds (0.25, 4]: a quarter of hi - lo is 0.9375; +0.9375 would leave
    # the bounds in x1 and x3, so those move down: (3.0625, 4/3 - 0.9375, 3.0625)
    starts = rule_initial_states(np.array([4.0, 4.0 / 3.0, 4.0]), 0.25, 4.0)
    assert FAULT_START_OFFSET == 0.25
    np.testing.assert_allclose(starts, [[4.0, 4.0 / 3.0, 4.0],
                                        [3.0625, 4.0 / 3.0 - 0.9375, 3.0625],
                                        [4.0, 4.0, 4.0]])


def test_rule_initial_states_stay_inside_the_bounds():
    starts = rule_initial_states(np.array([0.25, 10.0]), 0.25, 4.0)   # on and beyond the bounds
    assert np.all(starts > 0.25) and np.all(starts <= 4.0)
    assert len({tuple(x) for x in starts}) == len(starts)             # no duplicate


def _fake_spec(**options):
    design = SimpleNamespace(name="fd", method="fault_detection", options=options, config=None)
    return SimpleNamespace(plant=hydraulic_fault(), x0=np.array([4.0, 4.0 / 3.0, 4.0]),
                           given_u0=np.array([2.0]), ts=0.01, designs=(design,))


DOC = {"name": "fd", "method": "fault_detection", "gains": {}, "diagnostics": {}}


def test_scenario_reads_the_declared_options():
    spec = _fake_spec(bounds=[0.25, 4.0], delta_bar=0.5, t_fault=1.5, conservative=False,
                      initial_states=[[1.0, 2.0, 3.0], [0.5, 0.5, 0.5]], input=[[0.0, 2.0], [1.0, 1.0]])
    sc = fault_scenario(DOC, spec)
    np.testing.assert_array_equal(sc.starts, [[1.0, 2.0, 3.0], [0.5, 0.5, 0.5]])
    assert "initial_states" in sc.starts_source and "schedule" in sc.inputs_source
    assert [(t, u.tolist()) for t, u in sc.inputs] == [(0.0, [2.0]), (1.0, [1.0])]
    assert (sc.lo, sc.hi, sc.delta_bar, sc.t_fault, sc.conservative) == (0.25, 4.0, 0.5, 1.5, False)


def test_scenario_defaults_to_the_rule_and_the_equilibrium_input():
    sc = fault_scenario(DOC, _fake_spec(bounds=[0.25, 4.0], delta_bar=1.0, t_fault=2.0))
    np.testing.assert_allclose(sc.starts, rule_initial_states(np.array([4.0, 4.0 / 3.0, 4.0]),
                                                              0.25, 4.0))
    assert len(sc.inputs) == 1 and sc.inputs[0][1].tolist() == pytest.approx([2.0])
    assert "equilibrium" in sc.inputs_source and sc.conservative is True


@pytest.mark.parametrize("options, match", [
    (dict(bounds=[0.25, 4.0], delta_bar=1.0, t_fault=2.0, initial_states=[[0.1, 1.0, 1.0]]),
     "outside the threshold's bounds"),
    (dict(bounds=[0.25, 4.0], delta_bar=1.0, t_fault=2.0, initial_states=[[1.0, 1.0]]),
     "not vectors of 3 states"),
    (dict(delta_bar=1.0, t_fault=2.0), "no bounds"),
    (dict(bounds=[0.25, 4.0], t_fault=2.0), "delta_bar"),
    (dict(bounds=[0.25, 4.0], delta_bar=1.0, t_fault=2.0, input=[[1.0, 2.0]]), "start at t = 0"),
])
def test_scenario_refuses_what_it_cannot_simulate(options, match):
    with pytest.raises(ArtefactError, match=match):
        fault_scenario(DOC, _fake_spec(**options))


# ----------------------------------------------------------------- on the example spec
@pytest.mark.slow
def test_verdict_passes_on_the_example_spec(designed, tmp_path):
    d = Path(shutil.copytree(designed, tmp_path / "good"))
    verdict, checks = _checks(d)
    assert verdict.passed is True
    assert {"threshold_recheck", "no_false_alarm", "fault_detected"} <= set(checks)
    det = checks["fault_detected"].data
    # the design's detection times are compared where it records their initial states
    assert all(x is not None for x in det["differences"])
    assert max(det["differences"]) <= det["tolerance_s"]


@pytest.mark.slow
def test_wrong_threshold_fails(designed, tmp_path):
    d = Path(shutil.copytree(designed, tmp_path / "thr"))
    _rewrite(d / "fd.json", gains=lambda g: g.update(threshold_coefficients=0.5 *
                                                      g["threshold_coefficients"]))
    verdict, checks = _checks(d)
    assert verdict.passed is False
    assert checks["threshold_recheck"].passed is False and checks["no_false_alarm"].passed is False


@pytest.mark.slow
def test_wrong_gain_fails(designed, tmp_path):
    d = Path(shutil.copytree(designed, tmp_path / "gain"))
    _rewrite(d / "fd.json", gains=lambda g: g.update(Psi=0.01 * g["Psi"]))
    verdict, checks = _checks(d)
    assert verdict.passed is False
    assert checks["threshold_recheck"].passed is False and checks["no_false_alarm"].passed is False


def _exact_healthy_margin(doc, starts, lo, t):
    """max over t of |C exp(Gamma_d t) (x0 - lo)| - threshold (55), by matrix exponentials."""
    import scipy.linalg as sla

    G = np.asarray(doc["gains"]["Gamma_d"], dtype=float)
    C = np.array([[0.0, 0.0, 0.5]])                   # y = x3 / psi3, psi3 = 2 in the example
    coef = np.abs(np.asarray(doc["gains"]["threshold_coefficients"], dtype=float))
    rates = np.asarray(doc["gains"]["threshold_rates"], dtype=float)
    thr = (coef[:, None] * np.exp(rates[:, None] * t[None, :])).sum(axis=0)
    step = sla.expm(G * (t[1] - t[0]))
    worst = -np.inf
    for x0 in starts:
        e = sla.expm(G * t[0]) @ (np.asarray(x0) - lo)
        for k in range(t.size):
            worst = max(worst, abs(float((C @ e)[0])) - thr[k])
            e = step @ e
    return worst


def test_without_recorded_starts_the_rule_is_simulated(designed, tmp_path):
    """The rule's starts are simulated, and the verdict agrees with exact arithmetic.

    The threshold is derived from the largest initial error ``e_hat = (hi - lo) 1``; from other
    starts in the box (the operating point among them) the healthy residual need not stay below
    it: the verdict must say so exactly when the exact residual exceeds it.
    """
    from tanksynth.methods import METHODS
    from tanksynth.verify.runner import load_directory

    d = Path(shutil.copytree(designed, tmp_path / "rule"))
    _rewrite(d / "fd.json", diagnostics=lambda diag: diag.pop("detections"))
    spec, docs = load_directory(d, METHODS)
    doc = next(doc for _, doc in docs if doc["name"] == "fd")
    entry = next(e for e in spec.designs if e.name == "fd")
    undeclared = replace(entry, options={k: v for k, v in entry.options.items()
                                         if k not in ("initial_states", "input")}, config=None)
    checks = {c.name: c for c in fault_detection_verdict(doc, replace(spec, designs=(undeclared,)))}
    det, quiet = checks["fault_detected"], checks["no_false_alarm"]
    starts = rule_initial_states(np.array([4.0, 1.3333333333, 4.0]), 0.25, 4.0)
    np.testing.assert_allclose(det.data["starts"], starts)
    assert all(x is None for x in det.data["differences"]) and "rule" in det.detail
    exact = _exact_healthy_margin(doc, starts, 0.25, np.arange(0.04, 5.0, 1e-3))
    assert quiet.passed is bool(exact <= quiet.data["slack"])
    assert quiet.data["healthy_margin"] == pytest.approx(exact, rel=0.05, abs=1e-6)


def test_declared_scenario_reproduces_the_design_times_tightly(designed):
    """With the design's own starts and input declared, the simulated times agree to 0.2 ms."""
    from tanksynth.methods import METHODS
    from tanksynth.verify.runner import load_directory

    spec, docs = load_directory(designed, METHODS)
    doc = next(doc for _, doc in docs if doc["name"] == "fd")
    entry = next(e for e in spec.designs if e.name == "fd")
    declared = replace(entry, options={**entry.options, "initial_states": PAPER_STARTS,
                                       "input": PAPER_INPUT}, config=None)
    checks = {c.name: c for c in fault_detection_verdict(doc, replace(spec, designs=(declared,)))}
    det = checks["fault_detected"]
    assert det.passed is True and "initial_states" in det.detail and "schedule" in det.detail
    assert max(det.data["differences"]) < 2e-4


def test_observer_period_is_the_rk4_of_the_numpy_model():
    """One compiled period = 4 RK4 substeps of f(x, u) + Psi (y(t) - h(x)) written here in numpy."""
    from tanksynth.sim.integrate import param_arrays
    from tanksynth.sim.tape import numpy_model
    from tanksynth.verify.fault.verdicts import ResidualObserver

    plant = hydraulic_fault()
    Psi = np.array([[1.2], [0.4], [-0.3]])
    ts, M = 1e-3, 3
    model, p = numpy_model(plant), param_arrays(plant, {"delta_bar": 0.0}, 1)
    obs = ResidualObserver(plant, Psi, ts)
    rng = np.random.default_rng(2)
    x = 0.5 + rng.random((M, 3))
    obs.reset(x)
    y_prev = None
    for _ in range(20):
        y = 1.0 + 0.1 * rng.standard_normal((M, 1))
        u = 1.0 + 0.1 * rng.random((M, 1))
        got = obs.step(y, u).copy()
        if y_prev is not None:
            h = ts / 4

            def f(v, t, u=u, y0=y_prev, y1=y):
                yt = y0 + (y1 - y0) * t / ts
                return np.asarray(model.rhs(v, u, p)) + (yt - np.asarray(model.output(v, p)).reshape(M, 1)) @ Psi.T

            for j in range(4):
                t0 = j * h
                k1 = f(x, t0)
                k2 = f(x + 0.5 * h * k1, t0 + 0.5 * h)
                k3 = f(x + 0.5 * h * k2, t0 + 0.5 * h)
                k4 = f(x + h * k3, t0 + h)
                x = x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        np.testing.assert_allclose(got, x, rtol=1e-13, atol=0)
        y_prev = y
