"""Campaigns run what each artefact ships: estimators, observers, detectors and models."""

from __future__ import annotations

import ast
import pickle
from pathlib import Path

import numpy as np
import pytest

from tanksynth.analysis.linearize import equilibrium_input
from tanksynth.artefacts import read_artefact
from tanksynth.cli import main
from tanksynth.methods import load_spec
from tanksynth.runtime.estimators.kalman import ExtendedKalmanFilter, KalmanTuning
from tanksynth.sim.simulate import EstimatorAdapter, run_seeds, simulate
from tanksynth.verify.campaign import campaign_tasks, run_campaign
from tanksynth.verify.model.campaign import linear_predictions

ROOT = Path(__file__).resolve().parents[2]
X_HYBRID = [0.31918677, 0.3209075, 0.30968861]

EKF_SPEC = """
title = "one EKF on the hybrid three-tank (only h3 measured)"
[plant]
model = "hybrid_three_tank"
[operating_point]
x = {h1 = 0.31918677, h2 = 0.3209075, h3 = 0.30968861}
u = {Q1in = 2.7777778e-5, Q2in = 2.7777778e-5}
[sampling]
ts = 1.0
[[design]]
name = "ekf"
method = "ekf"
x0 = [0.2, 0.2, 0.2]
Q = 1e-7
R = 1e-6
P0 = 1e-2
jacobian_eps = 1e-6
switch_tol = 0.0
"""

OBSERVER_SPEC = """
title = "a pole-placement observer on the three-tank (h1, h2, h3 measured)"
[plant]
model = "three_tank"
outputs = "all"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "observer"
method = "pole_placement"
target = "observer"
poles = [0.5, 0.55, 0.6]
"""

FAULT_SPEC = """
title = "detector, observer and model on the hydraulic fault plant"
[plant]
model = "hydraulic_fault"
[operating_point]
x = {x1 = 4.0, x2 = 1.3333333333, x3 = 4.0}
u = {u = 2.0}
[sampling]
ts = 0.01
[[design]]
name = "model"
method = "linearize"
[[design]]
name = "canonical"
method = "canonical_observer"
poles = [-5.0, -8.0, -10.0]
[[design]]
name = "detector"
method = "fault_detection"
delta_bar = 1.0
"""


def _design(tmp_path_factory, name, text):
    d = tmp_path_factory.mktemp(name)
    (d / "in.toml").write_text(text, encoding="utf-8")
    out = d / "out"
    assert main(["design", str(d / "in.toml"), "-o", str(out)]) == 0
    docs = {doc["name"]: doc for doc in (read_artefact(p) for p in sorted(out.glob("*.json"))
                                        if p.name not in ("plant.json", "checks.json"))}
    return (out / "spec.toml").read_text(encoding="utf-8"), docs, load_spec(out / "spec.toml")


def _by(rows, *keys):
    return {tuple(r[k] for k in keys): r for r in rows}


def test_every_method_has_a_runner(runners):
    from tanksynth import methods

    assert {row.name for row in methods.TABLE} <= set(runners)
    for runner in runners.values():
        assert pickle.loads(pickle.dumps(runner)) is runner      # tasks travel to Dask workers
    if hasattr(methods, "RUNNERS"):                             # once the table hands them over
        assert dict(methods.RUNNERS) == runners


@pytest.mark.slow
def test_ekf_campaign_rmse_equals_the_ekf_run_by_hand(tmp_path_factory, runners):
    text, docs, spec = _design(tmp_path_factory, "ekf", EKF_SPEC)
    runs, seed = 3, 7
    table = run_campaign(campaign_tasks(text, [docs["ekf"]], ["servo", "mismatch"], runs, seed=seed,
                                        chunk=2, runners=runners), local=True)
    rows = _by(table.rows, "scenario", "run", "metric")
    assert {r["kind"] for r in table.rows} == {"estimator"}
    assert {r["metric"] for r in table.rows} == {"rmse_h1", "rmse_h2", "rmse_h3", "estimator_time"}
    assert all("open loop" not in r["loop"] and "extended Kalman" in r["loop"] for r in table.rows)
    # The same EKF built by hand from the spec's numbers, on the same seeded noise.
    plant = spec.plant
    u_eq = equilibrium_input(plant, X_HYBRID, [2.7777778e-5, 2.7777778e-5]).u0
    tuning = KalmanTuning(Q=1e-7 * np.eye(3), R=1e-6 * np.eye(1), P0=1e-2 * np.eye(3), x0=[0.2] * 3,
                          ts=1.0, jacobian_eps=1e-6, switch_tol=0.0)
    cases = {"servo": (300, X_HYBRID, [0.2, 0.2, 0.2]),            # the artefact's initial estimate
             "mismatch": (400, [0.28, 0.28, 0.23], [0.0, 0.0, 0.23])}  # the scenario's
    for name, (steps, x0, x_hat0) in cases.items():
        res = simulate(plant, ts=1.0, steps=steps, x0=x0, seeds=run_seeds(seed, runs),
                       estimator=EstimatorAdapter(ExtendedKalmanFilter(plant, tuning)),
                       x_hat0=x_hat0, u_init=u_eq, process_std=1e-5, measurement_std=5e-4, substeps=4)
        start = steps // 10                                     # the documented 10 % warm-up
        rmse = np.sqrt(np.mean((res.x_hat[:, start:] - res.x[:, start:]) ** 2, axis=1))
        for r in range(runs):
            for i, state in enumerate(("h1", "h2", "h3")):
                row = rows[(name, r, f"rmse_{state}")]
                assert row["seed"] == int(run_seeds(seed, runs)[r])
                assert row["value"] == pytest.approx(rmse[r, i], rel=1e-9, abs=1e-15), (name, r, state)
                assert row["value"] > 1e-5                      # noise and a wrong start: never 0


@pytest.mark.slow
def test_observer_runs_on_noisy_measurements(tmp_path_factory, runners):
    text, docs, spec = _design(tmp_path_factory, "observer", OBSERVER_SPEC)
    table = run_campaign(campaign_tasks(text, [docs["observer"]], ["servo", "regulatory"], 2,
                                        runners=runners), local=True)
    assert {r["kind"] for r in table.rows} == {"estimator"}
    assert all("open loop" not in r["loop"] and "Luenberger observer, predictor form" in r["loop"]
               for r in table.rows)
    summary = table.summary()
    for sc in ("servo", "regulatory"):
        metrics = {k[2] for k in summary if k[1] == sc}
        assert metrics == {"rmse_h1", "rmse_h2", "rmse_h3", "estimator_time"}
        for state in ("h1", "h2", "h3"):
            assert 1e-6 < summary[("observer", sc, f"rmse_{state}")] < 5e-3   # noise, not 0


@pytest.fixture(scope="module")
def fault_table(tmp_path_factory, runners):
    text, docs, spec = _design(tmp_path_factory, "fault", FAULT_SPEC)
    return run_campaign(campaign_tasks(text, list(docs.values()), ["additive_fault", "servo"], 2,
                                       runners=runners), local=True)


@pytest.mark.slow
def test_detector_rows(fault_table):
    rows = [r for r in fault_table.rows if r["artefact"] == "detector"]
    assert {r["kind"] for r in rows} == {"detector"}
    summary = fault_table.summary()
    # the leak of 0.5 from t_f = 2 s is detected within a few samples of 0.01 s
    assert 0 <= summary[("detector", "additive_fault", "detection_delay")] <= 0.05
    assert {k[2] for k in summary if k[:2] == ("detector", "servo")} == {
        "false_alarm_rate", "first_false_alarm", "estimator_time"}     # no fault: no delay
    for sc in ("additive_fault", "servo"):
        assert 0 <= summary[("detector", sc, "false_alarm_rate")] <= 1
    assert all("Psi" in r["loop"] and "without them" in r["loop"] for r in rows)


@pytest.mark.slow
def test_canonical_observer_and_model_rows(fault_table):
    summary = fault_table.summary()
    kinds = {(r["artefact"], r["kind"]) for r in fault_table.rows}
    assert kinds == {("detector", "detector"), ("canonical", "estimator"), ("model", "model")}
    assert not any("open loop at" in r["loop"] for r in fault_table.rows)
    assert summary[("canonical", "servo", "rmse_x1")] > 1e-6
    # The plant is linear: the model predicts x1 exactly one step ahead (the leak is in tank 2),
    # and its free run drifts from the faulty plant's x2.
    assert summary[("model", "additive_fault", "one_step_rmse_x1")] < 1e-12
    assert summary[("model", "additive_fault", "prediction_rmse_x2")] > 1e-2
    assert {k[2] for k in summary if k[:2] == ("model", "servo")} == {
        f"{kind}_rmse_x{i}" for kind in ("prediction", "one_step") for i in (1, 2, 3)}


def test_linear_predictions_by_hand():
    Ad, Bd = np.array([[0.9, 0.1], [0.0, 0.8]]), np.array([[0.0], [0.5]])
    x0, u0 = np.array([1.0, 2.0]), np.array([0.5])
    u = np.array([[[0.5], [1.5], [0.5]]])
    jumps = np.zeros((4, 2))
    jumps[2] = [0.1, 0.0]
    z, xs = np.zeros(2), [x0.copy()]
    for k in range(3):
        z = Ad @ z + Bd @ (u[0, k] - u0) + jumps[k + 1]
        xs.append(x0 + z)
    x = np.array([xs])
    free, one = linear_predictions(Ad, Bd, x0, u0, x, u, jumps)
    assert np.allclose(free, x) and np.allclose(one, x[:, 1:])


def test_no_seed_identifiers_in_sim_and_campaign_modules():
    files = list((ROOT / "tanksynth" / "sim").glob("*.py"))
    files += [ROOT / "tanksynth" / "verify" / f"{m}.py" for m in ("campaign", "estimation")]
    files += sorted((ROOT / "tanksynth" / "verify").glob("*/campaign.py"))  # each family's runners
    assert len(files) > 12
    files += [ROOT / "tanksynth" / "comparison.py"]
    bad = []
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.Name):
                names = [node.id]
            elif isinstance(node, ast.Attribute):
                names = [node.attr]
            elif isinstance(node, (ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)):
                names = [node.name]
            elif isinstance(node, ast.arg):
                names = [node.arg]
            elif isinstance(node, ast.alias):
                names = [node.name, node.asname or ""]
            for name in names:
                if "seed0" in name.lower() or "SEED" in name or "paper" in name.lower() \
                        or "printed" in name.lower():
                    bad.append(f"{path.name}: {name}")
    assert not bad, bad


@pytest.mark.slow
@pytest.mark.parametrize("example", ["seed001_ts_observer", "seed003_tank_network", "seed002_estimators"])
def test_example_estimators_and_observers_run(example, tmp_path, runners):
    """TS observers, decentralised filters, EKF/UKF/NARX of the examples: their estimate, or why not."""
    assert main(["design", str(ROOT / "examples" / f"{example}.toml"), "-o", str(tmp_path)]) == 0
    docs = [read_artefact(p) for p in sorted(tmp_path.glob("*.json"))
            if p.name not in ("plant.json", "checks.json")]
    text = (tmp_path / "spec.toml").read_text(encoding="utf-8")
    plant = load_spec(tmp_path / "spec.toml").plant
    table = run_campaign(campaign_tasks(text, docs, ["servo"], 1, runners=runners), local=True)
    expected = {f"rmse_{s.name}" for s in plant.states} | {"estimator_time"}
    ran = 0
    for doc in docs:
        rows = [r for r in table.rows if r["artefact"] == doc["name"]]
        assert rows and {r["kind"] for r in rows} == {"estimator"}, doc["name"]
        assert not any("open loop at" in r["loop"] for r in rows)
        metrics = {r["metric"]: r["value"] for r in rows}
        if set(metrics) == {"failed"}:                      # a diverging observer says so
            assert "the simulation failed" in rows[0]["loop"]
            continue
        assert set(metrics) == expected, doc["name"]
        assert all(np.isfinite(metrics[m]) and metrics[m] > 0 for m in expected), doc["name"]
        ran += 1
    assert ran >= 2


EXACT_START_EKF = """
title = "an EKF on the three-tank starting at the true state"
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "ekf"
method = "ekf"
Q = 1e-9
R = 1e-6
P0 = 1e-3
"""


@pytest.mark.slow
def test_noise_free_scenario_gives_no_rmse_for_an_exact_start(tmp_path_factory, runners):
    """dynamic_steps (no noise, no disturbance for an estimator) with the estimate at the true state:
    the error is zero by construction, so the row says not_applicable instead of rmse = 0.0;
    the noisy servo scenario gives real (non-zero) RMSEs."""
    text, docs, _ = _design(tmp_path_factory, "exact_ekf", EXACT_START_EKF)
    table = run_campaign(campaign_tasks(text, [docs["ekf"]], ["dynamic_steps", "servo"], 1,
                                        runners=runners), local=True)
    quiet = [r for r in table.rows if r["scenario"] == "dynamic_steps"]
    assert [r["metric"] for r in quiet] == ["not_applicable"] and quiet[0]["value"] == 1.0
    noisy = {r["metric"]: r["value"] for r in table.rows if r["scenario"] == "servo"}
    assert all(noisy[f"rmse_{s}"] > 1e-7 for s in ("h1", "h2", "h3"))
