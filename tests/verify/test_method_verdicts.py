"""Verdicts of the observer, controller and filter methods (the `tanksynth.verify` verdict modules).

For every method: the artefact as designed passes ``tanksynth verify DIR`` (exit 0), and the
same artefact with a wrong gain, rewritten with `write_artefact` so that its provenance hash is
valid (a wrong design, not tampering), fails with exit 1 and names the checks that caught it.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact, write_artefact
from tanksynth.cli import main
from tanksynth.design.result import DesignResult

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

# One three-tank spec for the convex designs and the control laws (one verify run for all).
THREE_TANK = """
title = "verdict tests: three-tank designs"
[plant]
model = "three_tank"
outputs = "all"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0

[[design]]
name = "sf_integral_place"
method = "pole_placement"
target = "state_feedback"
integral = true
tracked = ["h1", "h2"]
poles = [0.92, 0.97, 0.90, 0.95, 0.94]

[[design]]
name = "sf_integral_lmi"
method = "lmi_placement"
target = "state_feedback"
integral = true
tracked = ["h1", "h2"]
region = [{type = "disk", center = 0.0, radius = 0.97}, {type = "disk", center = 0.9, radius = 0.08}]

[[design]]
name = "sf_place_continuous"
method = "pole_placement"
target = "state_feedback"
time_domain = "continuous"
poles = [-0.05, -0.06, -0.07]

[[design]]
name = "obs_place"
method = "pole_placement"
target = "observer"
poles = [0.8, 0.85, 0.9]

[[design]]
name = "obs_lmi_continuous"
method = "lmi_placement"
target = "observer"
time_domain = "continuous"
region = [{type = "half_plane", alpha = 0.05}, {type = "disk", center = 0.0, radius = 1.0}]

[[design]]
name = "decoupling"
method = "feedback_linearization"
tracked = ["h1", "h2"]
poles = [-0.05, -0.05]

[[design]]
name = "tracking"
method = "integral_tracking"
tracked = ["h1", "h2"]
poles = [0.92, 0.97, 0.90, 0.95, 0.94]
"""

TS = """
title = "verdict tests: TS observer (sampled premise bounds, given psi)"
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[[design]]
name = "ts"
method = "ts_observer"
weights = {z1 = [-1.0, 0.0, 1.0], z3 = [0.0, -1.0, 1.0]}
psi = 0.03
variant = "qI"
orderings = true
ordering_gap = 0.1
premise_bounds = "sampling"
samples = 500
domain = {h1 = [0.05, 0.62], h2 = [0.05, 0.62], h3 = [0.05, 0.62]}
"""

INVERSE = """
title = "verdict tests: inverse dynamics with fixed rates"
[plant]
model = "hybrid_three_tank"
[operating_point]
x = {h1 = 0.31918677, h2 = 0.3209075, h3 = 0.30968861}
[sampling]
ts = 1.0
[[design]]
name = "inverse"
method = "inverse_dynamics"
C = [0.05, 0.05]
"""

NETWORK = """
title = "verdict tests: decentralised gains, 8 tanks"
[plant]
model = "tank_network"
N = 8
[operating_point]
x = [21.70591608, 22.54471524, 21.70591608, 22.54471524, 9.04293578, 5.08665138, 9.04293578, 5.08665138]
[sampling]
ts = 1.0
[[design]]
name = "dkf_a"
method = "decentralized_kalman"
algorithm = "one_step"
window = 12
process_noise = 0.01
process_noise_correlation = 0.5
measurement_noise = 4.0
[[design]]
name = "dkf_b"
method = "decentralized_kalman"
algorithm = "one_step"
window = 12
process_noise = 0.01
process_noise_correlation = 0.5
measurement_noise = 4.0
"""

ESTIMATORS = """
title = "verdict tests: estimators"
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "ckf"
method = "kalman"
Q = 1e-8
R = 1e-6
P0 = 1e-3
[[design]]
name = "luenberger"
method = "luenberger"
poles = [0.8, 0.85, 0.9]
"""

SPECS = {"three_tank": THREE_TANK, "ts": TS, "inverse": INVERSE, "network": NETWORK,
         "estimators": ESTIMATORS}


def _scale(*names, factor):
    def mutate(gains):
        for n in names:
            gains[n] = np.asarray(gains[n]) * factor
    return mutate


def _mask_entry(gains):
    K = np.array(gains["K_0"], dtype=float)
    E = np.asarray(gains["E"])
    i, j = np.argwhere(E == 0)[0]
    K[i, j] = 1e-3
    gains["K_0"] = K


def _negate_all_k(gains):
    for name in [k for k in gains if k.startswith("K_")]:
        gains[name] = -np.asarray(gains[name])


#: directory -> artefact -> (wrong gain, checks that must fail)
TAMPER = {
    "three_tank": {
        "sf_integral_place": (_scale("K", "K1", "K2", factor=-1.0), {"poles", "stability", "servo_tracking"}),
        "sf_integral_lmi": (_scale("K", "K1", "K2", factor=-1.0), {"region", "lmi_recheck",
                                                                   "servo_tracking"}),
        "sf_place_continuous": (_scale("K", factor=-1.0), {"poles", "regulation"}),
        "obs_place": (_scale("L", factor=0.01), {"poles", "observer_convergence"}),
        "obs_lmi_continuous": (_scale("L", factor=0.01), {"region", "lmi_recheck",
                                                         "observer_convergence"}),
        "decoupling": (_scale("K", factor=2.0), {"law_matches_gains", "time_constant_h1",
                                                 "time_constant_h2"}),
        "tracking": (_scale("K", "K1", "K2", factor=-1.0), {"law_matches_gains", "anti_windup_gain",
                                                            "poles", "servo_tracking"}),
    },
    "ts": {"ts": (_scale("L", factor=0.01), {"lmi_recheck", "observer_convergence"})},
    "inverse": {"inverse": (_scale("C", factor=0.01), {"law_matches_gains", "servo_scenario"})},
    "network": {"dkf_a": (_mask_entry, {"sparsity"}),
                "dkf_b": (_negate_all_k, {"filter_vs_open_loop", "filter_error_bounded"})},
    "estimators": {"ckf": (_scale("K_ss", factor=0.01), {"riccati_recheck"}),
                   "luenberger": (_scale("L", factor=0.01), {"poles", "estimator_convergence"})},
}

#: checks that must be present (and pass) on the good artefacts
EXPECTED = {
    "sf_integral_place": {"model_recheck", "poles", "stability", "rank_controllability_augmented",
                          "servo_tracking", "bounded_inputs"},
    "sf_integral_lmi": {"model_recheck", "region", "lmi_recheck", "servo_tracking"},
    "sf_place_continuous": {"poles", "regulation"},
    "obs_place": {"poles", "rank_observability", "observer_convergence"},
    "obs_lmi_continuous": {"region", "lmi_recheck", "observer_convergence"},
    "decoupling": {"rank_decoupling", "law_matches_gains", "time_constant_h1", "decoupling_h1",
                   "time_constant_h2", "decoupling_h2"},
    "tracking": {"law_matches_gains", "anti_windup_gain", "poles", "servo_tracking",
                 "bounded_inputs"},
    "ts": {"ts_model_rebuilt", "model_recheck", "lmi_recheck", "local_error_dynamics",
           "rank_observability_vertices", "observer_convergence"},
    "inverse": {"rank_input_matrix", "law_matches_gains", "servo_scenario"},
    "dkf_a": {"sparsity", "covariances", "filter_vs_open_loop", "filter_error_bounded"},
    "luenberger_canonical": {"model_recheck", "poles", "observer_convergence"},
    "ckf": {"model_recheck", "riccati_recheck", "estimator_convergence"},
    "luenberger": {"poles", "estimator_convergence"},
}


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    root = tmp_path_factory.mktemp("method_verdicts")
    out = {}
    for key, text in SPECS.items():
        spec = root / f"{key}.toml"
        spec.write_text(text, encoding="utf-8")
        assert main(["design", str(spec), "-o", str(root / key)]) == 0
        out[key] = root / key
    assert main(["design", str(EXAMPLES / "seed004_fault_detection.toml"), "-o",
                 str(root / "canonical")]) == 0
    out["canonical"] = root / "canonical"
    return out


def _verify_json(directory, capsys):
    code = main(["verify", str(directory), "--json"])
    report = json.loads(capsys.readouterr().out)
    return code, {a["name"]: a for a in report["artefacts"]}


def _rewrite(path: Path, mutate) -> None:
    """Change gains and write the artefact again with `write_artefact` (valid provenance hash)."""
    doc = read_artefact(path)
    gains = {k: np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
    mutate(gains)
    result = DesignResult(doc["name"], doc["method"], doc["plant"], gains, doc["diagnostics"], {})
    write_artefact(result, path.parent, doc["provenance"]["spec_sha256"])


@pytest.mark.slow
@pytest.mark.parametrize("key", ["three_tank", "ts", "inverse", "network", "canonical"])
def test_designed_artefacts_pass(designed, key, tmp_path, capsys):
    d = Path(shutil.copytree(designed[key], tmp_path / key))
    code, arts = _verify_json(d, capsys)
    assert code == 0, {n: [c["check"] for c in a["checks"] if c["passed"] is False]
                       for n, a in arts.items()}
    for name, art in arts.items():
        assert art["passed"] is True, name
        checks = {c["check"]: c for c in art["checks"]}
        assert EXPECTED.get(name, set()) <= set(checks), (name, sorted(checks))
        for c in checks.values():
            assert c["passed"] in (True, None) and c["detail"], (name, c)
        assert read_artefact(d / f"{name}.json")["verification"]["passed"] is True


@pytest.mark.slow
@pytest.mark.parametrize("key", ["three_tank", "ts", "inverse", "network"])
def test_wrong_gains_fail_with_exit_1(designed, key, tmp_path, capsys):
    d = Path(shutil.copytree(designed[key], tmp_path / key))
    for name, (mutate, _) in TAMPER[key].items():
        _rewrite(d / f"{name}.json", mutate)
    code, arts = _verify_json(d, capsys)
    assert code == 1
    for name, (_, must_fail) in TAMPER[key].items():
        failed = {c["check"] for c in arts[name]["checks"] if c["passed"] is False}
        assert arts[name]["passed"] is False
        assert must_fail <= failed, (name, sorted(failed))


@pytest.mark.slow
def test_canonical_observer_with_a_wrong_gain_fails(designed, tmp_path, capsys):
    d = Path(shutil.copytree(designed["canonical"], tmp_path / "canonical"))
    _rewrite(d / "luenberger_canonical.json", _scale("L", factor=0.01))
    assert main(["verify", str(d)]) == 1
    doc = read_artefact(d / "luenberger_canonical.json")
    failed = {c["check"] for c in doc["verification"]["checks"] if c["passed"] is False}
    assert {"poles", "observer_convergence"} <= failed
    assert doc["verification"]["passed"] is False


@pytest.mark.slow
def test_estimator_verdicts(designed, tmp_path, capsys):
    d = Path(shutil.copytree(designed["estimators"], tmp_path / "good"))
    code, arts = _verify_json(d, capsys)
    assert code == 0
    for name in ("ckf", "luenberger"):
        assert arts[name]["passed"] is True
        assert EXPECTED[name] <= {c["check"] for c in arts[name]["checks"]}
    bad = Path(shutil.copytree(designed["estimators"], tmp_path / "bad"))
    for name, (mutate, _) in TAMPER["estimators"].items():
        _rewrite(bad / f"{name}.json", mutate)
    code, arts = _verify_json(bad, capsys)
    assert code == 1
    for name, (_, must_fail) in TAMPER["estimators"].items():
        assert must_fail <= {c["check"] for c in arts[name]["checks"] if c["passed"] is False}


@pytest.mark.slow
def test_observer_rule_and_numbers_are_stated(designed, tmp_path, capsys):
    d = Path(shutil.copytree(designed["three_tank"], tmp_path / "tt"))
    _, arts = _verify_json(d, capsys)
    conv = next(c for c in arts["obs_place"]["checks"] if c["check"] == "observer_convergence")
    assert "H = tau (5 + ln kappa)" in conv["detail"] and "tolerance" in conv["detail"]
    data = conv["data"]
    assert data["tail_max"] <= data["tolerance"] == pytest.approx(0.05 * data["e0"])
    # tau from the slowest designed pole 0.9 at ts = 1 s
    assert data["tau_s"] == pytest.approx(-1.0 / np.log(0.9))


# ------------------------------------------------------------ seed 004 / seed 002 estimators
SEED004_FILTERS = """
title = "verdict tests: adaptive-scaling and consensus filters"
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "askf"
method = "adaptive_scaling_kalman"
Q = 1e-8
R = 1e-6
P0 = 1e-3
abc = [0.1, 0.6, 0.3]
[[design]]
name = "cf"
method = "consensus_filter"
Q = 1e-8
R = [1e-6, 2e-6]
P0 = 1e-3
"""

FAULT = """
title = "verdict tests: fault detection (seed 004)"
[plant]
model = "hydraulic_fault"
[operating_point]
x = {x1 = 4.0, x2 = 1.3333333333, x3 = 4.0}
u = {u = 2.0}
[sampling]
ts = 0.01
[[design]]
name = "fd"
method = "fault_detection"
delta_bar = 1.0
initial_states = [[0.26, 0.26, 0.26], [4.0, 4.0, 4.0], [2.4, 3.6, 1.8]]
input = [[0.0, 2.0], [1.0, 1.0]]
"""

NARX = """
title = "verdict tests: a small NARX estimator"
[plant]
model = "hybrid_three_tank"
[operating_point]
x = {h1 = 0.31918677, h2 = 0.3209075, h3 = 0.30968861}
u = {Q1in = 2.7777778e-5, Q2in = 2.7777778e-5}
[sampling]
ts = 1.0
[[design]]
name = "narx"
method = "narx"
x0 = [0.2, 0.2, 0.2]
Q = 1e-7
R = 1e-6
P0 = 1e-2
hidden = 3
delays = 2
runs = 2
validation_runs = 1
steps = 200
seed = 0
restarts = 1
max_iter = 40
input_range = [[8.333333e-06, 3.6111111e-05], [8.333333e-06, 3.6111111e-05]]
"""

#: artefact -> (spec, wrong gain, checks present and passing when good, checks failing when wrong)
MORE = {
    "askf": (SEED004_FILTERS, _scale("R", factor=1e4), {"estimator_convergence", "covariance"},
             {"estimator_convergence"}),
    "cf": (SEED004_FILTERS, _scale("R0", "R1", factor=1e4), {"estimator_convergence", "covariance"},
           {"estimator_convergence"}),
    "fd": (FAULT, _scale("Psi", factor=0.01), {"threshold_recheck", "no_false_alarm",
                                               "fault_detected"},
           {"threshold_recheck", "no_false_alarm", "fault_detected"}),
    "narx": (NARX, _scale("W2", factor=-1.0), {"training_fit_recheck", "one_step_fit",
                                               "closed_loop_bounded"},
             {"training_fit_recheck", "one_step_fit"}),
}


@pytest.fixture(scope="module")
def designed_more(tmp_path_factory):
    root = tmp_path_factory.mktemp("method_verdicts_more")
    out = {}
    for key, text in (("filters", SEED004_FILTERS), ("fault", FAULT), ("narx", NARX)):
        spec = root / f"{key}.toml"
        spec.write_text(text, encoding="utf-8")
        assert main(["design", str(spec), "-o", str(root / key)]) == 0
        out[key] = root / key
    return out


def _dir_of(name):
    return {"askf": "filters", "cf": "filters", "fd": "fault", "narx": "narx"}[name]


@pytest.mark.slow
@pytest.mark.parametrize("key", ["filters", "fault", "narx"])
def test_more_estimator_verdicts_good_and_wrong(designed_more, key, tmp_path, capsys):
    names = [n for n in MORE if _dir_of(n) == key]
    good = Path(shutil.copytree(designed_more[key], tmp_path / "good"))
    code, arts = _verify_json(good, capsys)
    assert code == 0, {n: [(c["check"], c["detail"]) for c in a["checks"] if c["passed"] is not True]
                       for n, a in arts.items()}
    for name in names:
        checks = {c["check"]: c for c in arts[name]["checks"]}
        assert MORE[name][2] <= {k for k, c in checks.items() if c["passed"] is True}, \
            (name, {k: c["detail"] for k, c in checks.items()})
        for c in checks.values():
            assert c["detail"] and ("tolerance" in c["detail"] or "must" in c["detail"]), c
    bad = Path(shutil.copytree(designed_more[key], tmp_path / "bad"))
    for name in names:
        _rewrite(bad / f"{name}.json", MORE[name][1])
    assert main(["verify", str(bad)]) == 1
    capsys.readouterr()
    for name in names:
        doc = read_artefact(bad / f"{name}.json")
        failed = {c["check"] for c in doc["verification"]["checks"] if c["passed"] is False}
        assert MORE[name][3] <= failed, (name, sorted(failed))
        assert doc["verification"]["passed"] is False


@pytest.mark.slow
def test_fault_detection_reports_detection_times(designed_more, tmp_path, capsys):
    d = Path(shutil.copytree(designed_more["fault"], tmp_path / "fd"))
    _, arts = _verify_json(d, capsys)
    det = next(c for c in arts["fd"]["checks"] if c["check"] == "fault_detected")
    data = det["data"]
    assert all(data["t_fault"] < t <= data["t_fault"] + data["horizon_s"] for t in data["t_detect"])
    # the design's exact detection times (matrix exponentials, Brent) within the stated tolerance
    assert max(data["differences"]) <= data["tolerance_s"]
    assert "t_d = " in det["detail"]


@pytest.mark.parametrize("model, x, u", [
    ("tank_network", None, None),
    ("hybrid_three_tank", [0.31918677, 0.3209075, 0.30968861], [2.7777778e-5, 2.7777778e-5]),
])
def test_decentralized_filter_prediction_equals_one_simulator_step(model, x, u):
    """`DecentralizedFilter.predict` (one direct integrator call) equals `simulate(steps=1)`."""
    from tanksynth.plants import hybrid_three_tank, tank_network
    from tanksynth.verify.decentralized.verdicts import DecentralizedFilter
    from tanksynth.sim.simulate import simulate

    plant = tank_network(N=8) if model == "tank_network" else hybrid_three_tank()
    rng = np.random.default_rng(3)
    lo = np.array([b[0] for b in plant.region.bounds], float)
    hi = np.array([b[1] for b in plant.region.bounds], float)
    hi = np.where(np.isfinite(hi), hi, lo + 30.0)
    X = lo + (hi - lo) * rng.uniform(0.02, 0.98, (6, plant.n))
    X[0] = lo                                    # on the lower bound (clipping)
    if x is not None:
        X[1] = x
    U = rng.uniform(0.0, 1.0, (6, plant.m)) * (1e-4 if model != "tank_network" else 2.0)
    U[2] = -1.0                                  # saturated input
    filt = DecentralizedFilter(plant, [], ts=1.0, substeps=4)
    ref = simulate(plant, ts=1.0, steps=1, x0=X, seeds=np.zeros(6, dtype=np.uint64), u_init=U,
                   substeps=4).x[:, 1]
    np.testing.assert_allclose(filt.predict(X, U), ref, rtol=0, atol=1e-12)


@pytest.mark.slow
def test_narx_closed_loop_bound_comes_from_the_scenario(designed_more, tmp_path, capsys):
    """Issue 28: the NARX's closed-loop bound is the measurement-free prediction's RMSE (the
    model run open loop from the same initial estimate), not a multiple of the EKF's; a network
    whose estimate is biased by ~0.3 m (output bias b2 + 3 in standardised units) does worse than
    no correction and fails it. The recorded noise floor is the steady-state Kalman posterior,
    recomputed here by iterating the Riccati recursion (no scipy DARE)."""
    import scipy.linalg

    from tanksynth.methods import load_spec

    good = Path(shutil.copytree(designed_more["narx"], tmp_path / "good"))
    _, arts = _verify_json(good, capsys)
    chk = next(c for c in arts["narx"]["checks"] if c["check"] == "closed_loop_bounded")
    data = chk["data"]
    assert chk["passed"] is True and data["rmse"] <= data["bound"] == data["open_loop_rmse"]
    spec = load_spec(good / "spec.toml")
    plant, x = spec.plant, np.asarray(spec.x0, dtype=float)
    from tanksynth.analysis.linearize import equilibrium_input

    u = equilibrium_input(plant, x).u0
    Ad = scipy.linalg.expm(np.asarray(plant.compiled.jacobians(x[None], u[None])[0])[0] * spec.ts)
    C, Q, R = np.array([[0.0, 0.0, 1.0]]), 1e-7 * np.eye(3), np.array([[1e-6]])
    P = 1e-2 * np.eye(3)
    for _ in range(20000):
        Pm = Ad @ P @ Ad.T + Q
        P = Pm - Pm @ C.T @ np.linalg.inv(C @ Pm @ C.T + R) @ C @ Pm
    assert data["noise_floor"] == pytest.approx(float(np.sqrt(np.mean(np.diag(P)))), rel=1e-6)

    def bias(gains):
        gains["b2"] = np.asarray(gains["b2"]) + 3.0

    bad = Path(shutil.copytree(designed_more["narx"], tmp_path / "bad"))
    _rewrite(bad / "narx.json", bias)
    assert main(["verify", str(bad)]) == 1
    capsys.readouterr()
    doc = read_artefact(bad / "narx.json")
    chk = next(c for c in doc["verification"]["checks"] if c["check"] == "closed_loop_bounded")
    assert chk["passed"] is False and chk["data"]["rmse"] > chk["data"]["bound"]
