"""Replay of estimator, observer and detector artefacts on logged experiments (issue 27, item 4).

The logs are simulated from the plant (`tanksynth.sim`) with seeded sensor noise of the level the
artefact declares (``R``), built as `Experiment` objects directly. References are independent of
the replay: the chi-square bands from `scipy.stats.chi2`, the innovation covariance from the
Kalman gain identity ``S = R (I - H K)^-1`` of the runtime filter stepped by hand (not from ``P``
as the replay computes it), a fully missing sample's estimate from the simulator's one-step
prediction, the trace digest from `hashlib`.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from tanksynth.cli import main
from tanksynth.errors import DataError
from tanksynth.measurements import Experiment
from tanksynth.methods import RUNNERS, load_directory
from tanksynth.sim.simulate import simulate_inputs
from tanksynth.verify.replay import (REPLAY_FILE, SCHEMA, TRACE_DIR, read_replay, replay_artefacts,
                                     replay_estimator, replay_line, write_replay)

#: The EKF's declared sensor noise (m): R = SIGMA^2 in replay_spec.toml.
SIGMA = 2e-3

#: The spec: an EKF with R = SIGMA^2 and a Luenberger observer on the three-tank (h1, h2).
SPEC = (Path(__file__).parent / "replay_spec.toml").read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    """A result directory designed from `SPEC`: its spec and artefact documents by name."""
    root = tmp_path_factory.mktemp("replay")
    spec_path = root / "spec.toml"
    spec_path.write_text(SPEC, encoding="utf-8")
    out = root / "out"
    assert main(["design", str(spec_path), "-o", str(out)]) == 0
    spec, docs = load_directory(out)
    return out, spec, {d["name"]: d for _, d in docs}


def logged(spec, *, noise: float = 1.0, samples: int = 600, seed: int = 1, period: float = 1.0,
           x_ref: bool = False) -> tuple[Experiment, np.ndarray]:
    """A log of the plant under piecewise-constant pump flows with sensor noise ``noise * SIGMA``;
    also the true states (N, n)."""
    rng = np.random.default_rng(seed)
    u0 = np.array([3.5e-5, 3.75e-5])
    U = u0 * np.repeat(rng.uniform(0.6, 1.4, size=(samples // 100 + 1, 2)), 100, axis=0)[:samples]
    res = simulate_inputs(spec.plant, spec.x0, U, 1.0, substeps=4)
    X = np.array(res.x[0, :samples])
    Y = np.array(res.y[0, :samples]) + noise * SIGMA * rng.standard_normal((samples, 2))
    flags = np.zeros(Y.shape, dtype=bool)
    exp = Experiment("log", "log.csv", np.arange(samples) * period, U, Y, ("q1", "q2"), ("h1", "h2"),
                     flags, flags.copy(), ((-np.inf, np.inf),) * 2, x_ref=X if x_ref else None)
    return exp, X


def with_y(exp: Experiment, y: np.ndarray, **kw) -> Experiment:
    fields = {k: getattr(exp, k) for k in ("name", "source", "t", "u", "y", "input_names", "output_names",
                                           "censored_low", "censored_high", "limits", "x_ref")}
    fields.update(y=y, **kw)
    return Experiment(**fields)


def run(result, name, exp):
    out, spec, docs = result
    return replay_estimator(docs[name], spec, RUNNERS[docs[name]["method"]](docs[name], spec), exp)


def check(r, name):
    return next(c for c in r.checks if c.name == name)


def test_ekf_innovations_consistent_on_data_of_its_noise_level(result):
    _, spec, _ = result
    exp, _ = logged(spec)
    r = run(result, "ekf", exp)
    assert r.kind == "estimator" and r.passed is True, replay_line(r)
    nis = check(r, "nis_mean")
    samples, dof = nis.data["samples"], nis.data["dof"]
    assert dof == 2 * samples  # two outputs per sample, none missing
    lo, hi = stats.chi2.ppf([0.025, 0.975], dof) / samples
    assert nis.data["band"] == pytest.approx([lo, hi], rel=1e-12)
    assert lo <= nis.data["value"] <= hi
    assert abs(check(r, "nis_exceedance").data["value"] - 0.05) < 0.03


def test_nis_equals_the_kalman_gain_identity(result):
    """NIS from S = R (I - H K)^-1 (the runtime filter's own gain, H = [I2 0]) and its innovation."""
    _, spec, docs = result
    exp, _ = logged(spec, samples=60)
    r = run(result, "ekf", exp)
    est = RUNNERS["ekf"](docs["ekf"], spec).estimator.template.batch(1)
    R = np.diag([SIGMA ** 2] * 2)
    H = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    est.reset(np.array([[0.40, 0.20, 0.30]]))
    ref, nus = [], []
    for k in range(exp.samples):
        est.step(exp.y[k][None], exp.u[max(k - 1, 0)][None])
        nu = est.innovation.reshape(2)
        nus.append(nu)
        S = R @ np.linalg.inv(np.eye(2) - H @ est.gain.reshape(3, 2))
        ref.append(nu @ np.linalg.solve(S, nu))
    start = 6  # warm-up: 10 % of 60 samples
    assert np.isnan(r.nis[:start]).all()
    np.testing.assert_allclose(r.nis[start:], ref[start:], rtol=1e-7)
    np.testing.assert_allclose(exp.y - r.y_pred, nus, rtol=1e-7, atol=1e-12)


def test_ten_times_the_sensor_noise_fails_the_nis_checks(result):
    _, spec, _ = result
    r = run(result, "ekf", logged(spec, noise=10.0)[0])
    assert r.passed is False
    assert check(r, "nis_mean").passed is False
    assert check(r, "nis_mean").data["value"] > check(r, "nis_mean").data["band"][1]
    assert check(r, "nis_exceedance").passed is False
    assert check(r, "prediction_rmse").passed is False


def test_missing_samples_are_predicted_and_counted(result):
    _, spec, _ = result
    exp, _ = logged(spec)
    y = exp.y.copy()
    y[100:105, :] = np.nan      # both outputs lost for 5 samples
    y[200:210, 1] = np.nan      # h2 lost for 10 samples
    r = run(result, "ekf", with_y(exp, y))
    assert r.summary["missing"] == 10 + 10
    assert r.summary["samples_not_updated"] == 5 + 10
    assert np.isnan(r.nis[100:105]).all() and np.isfinite(r.nis[200:210]).all()
    assert check(r, "nis_mean").data["dof"] == 2 * 540 - 10 - 2 * 5  # after the 60-sample warm-up
    # a sample with nothing measured: the estimate is the model's one-step prediction
    k = 102
    pred = simulate_inputs(spec.plant, r.x_hat[k - 1], exp.u[k - 1][None], 1.0, substeps=1)
    np.testing.assert_allclose(r.x_hat[k], pred.x[0, 1], rtol=1e-9, atol=1e-12)
    assert r.passed is True


def test_censored_samples_are_skipped_and_counted(result):
    _, spec, _ = result
    exp, _ = logged(spec)
    high = np.zeros(exp.y.shape, dtype=bool)
    high[300:320, 0] = True
    r = run(result, "ekf", with_y(exp, exp.y, censored_high=high))
    assert r.summary["censored"] == 20 and r.summary["missing"] == 0
    assert r.summary["samples_not_updated"] == 20
    assert "20 censored" in replay_line(r)


def test_nees_with_logged_reference_states(result):
    _, spec, _ = result
    exp, X = logged(spec, x_ref=True)
    r = run(result, "ekf", exp)
    nees = check(r, "nees_mean")
    n = 3
    lo, hi = stats.chi2.ppf([0.025, 0.975], nees.data["dof"]) / nees.data["samples"]
    assert nees.data["dof"] == n * nees.data["samples"]
    assert nees.data["band"] == pytest.approx([lo, hi], rel=1e-12)
    # P from Q = 1e-10 on a noise-free plant: the filter is pessimistic, NEES below the band
    assert nees.passed is False and nees.data["value"] < lo


def test_observer_without_covariance(result):
    _, spec, _ = result
    exp, _ = logged(spec)
    r = run(result, "obs", exp)
    assert r.kind == "observer" and r.passed is True, replay_line(r)
    assert {c.name for c in r.checks} == {"finite", "in_range", "prediction_fit"}
    fit = check(r, "prediction_fit").data
    for out in ("h1", "h2"):
        assert fit["value"][out] < fit["bound"][out]
        # bound: the output's spread about its mean after the warm-up
        assert fit["bound"][out] == pytest.approx(np.std(exp.y[60:, 0 if out == "h1" else 1]))


def test_a_log_without_an_output_is_refused_naming_it(result):
    _, spec, _ = result
    exp, _ = logged(spec)
    short = Experiment("log", "log.csv", exp.t, exp.u, exp.y[:, :1], ("q1", "q2"), ("h1",),
                       exp.censored_low[:, :1], exp.censored_high[:, :1], exp.limits[:1])
    with pytest.raises(DataError, match=r"needs the plant signal\(s\) h2"):
        run(result, "ekf", short)


def test_another_sampling_period_is_refused_naming_both(result):
    _, spec, _ = result
    exp, _ = logged(spec, period=2.0)
    with pytest.raises(DataError, match=r"sampled every 2 s, artefact 'ekf' runs every 1 s"):
        run(result, "ekf", exp)


def test_write_and_read_back(result, tmp_path):
    out, spec, docs = result
    exp, _ = logged(spec, samples=200)
    reps = replay_artefacts(spec, list(docs.values()), [exp], RUNNERS)
    assert [(r.artefact, r.kind) for r in reps] == [("ekf", "estimator"), ("obs", "observer")]
    path = write_replay(out, reps)
    assert path == out / REPLAY_FILE
    doc = read_replay(out)
    assert doc["schema"] == SCHEMA and len(doc["replays"]) == 2
    for entry in doc["replays"]:
        trace = out / entry["trace"]["file"]
        assert trace.parent == out / TRACE_DIR
        assert entry["trace"]["sha256"] == hashlib.sha256(trace.read_bytes()).hexdigest()
        assert entry["trace_data"] is not None
        assert entry["trace_data"]["arrays"]["y_pred"].shape == (200, 2)
        assert {c["check"] for c in entry["checks"]} >= ({"nis_mean"} if entry["kind"] == "estimator"
                                                         else {"finite"})
    # a trace that changed after the replay is not read (no figure from it)
    trace = out / doc["replays"][0]["trace"]["file"]
    data = bytearray(trace.read_bytes())
    data[len(data) // 2] ^= 0xFF
    trace.write_bytes(bytes(data))
    assert read_replay(out)["replays"][0]["trace_data"] is None
    # a replay on other logs removes the traces it did not write again
    reps = replay_artefacts(spec, [docs["ekf"]], [with_y(exp, exp.y, name="other")], RUNNERS)
    write_replay(out, reps)
    assert sorted(p.name for p in (out / TRACE_DIR).iterdir()) == ["ekf__other.npz"]


def test_no_artefact_to_replay(result):
    from tanksynth.errors import SpecError

    _, spec, docs = result
    with pytest.raises(SpecError, match="no estimator, observer or detector"):
        replay_artefacts(spec, [], [logged(spec, samples=20)[0]], RUNNERS)


@pytest.mark.slow
def test_detector_alarms_with_times(tmp_path):
    """Seed 004's residual detector: no alarm on a fault-free noise-free log from the operating
    point, alarms from just after a leak's onset (3 s), and alarms (info, not a failure) on noise
    its threshold (no noise margin: it decays to ~1e-13) was not designed for."""
    from tanksynth.sim.simulate import ParameterChange, simulate

    text = Path(__file__).parents[2].joinpath("examples", "seed004_fault_detection.toml").read_text()
    head = text[:text.index("[[design]]")]
    body = text[text.index('name = "residual_fault_detector"'):text.index("# Seed 004 eq. (30)")]
    (tmp_path / "spec.toml").write_text(head + "[[design]]\n" + body, encoding="utf-8")
    assert main(["design", str(tmp_path / "spec.toml"), "-o", str(tmp_path / "out")]) == 0
    spec, docs = load_directory(tmp_path / "out")

    def log(name, changes=(), std=0.0):
        res = simulate(spec.plant, ts=0.01, steps=599, x0=spec.x0, seeds=[3], u_init=np.array([2.0]),
                       measurement_std=std, changes=list(changes))
        U = np.vstack([res.u[0], res.u[0][-1:]])
        flags = np.zeros(res.y[0].shape, dtype=bool)
        return Experiment(name, f"{name}.csv", np.array(res.t), U, np.array(res.y[0]), ("u",), ("y",),
                          flags, flags.copy(), ((-np.inf, np.inf),))

    healthy, leak, noisy = (log("healthy"), log("leak", [ParameterChange(300, {"delta_bar": 1.0})]),
                            log("noisy", std=1e-3))
    reps = replay_artefacts(spec, [d for _, d in docs], [healthy, leak, noisy], RUNNERS)
    by = {r.experiment.name: r for r in reps}
    assert all(r.kind == "detector" and r.passed is None for r in reps)
    assert by["healthy"].summary["alarms"] == 0
    first = by["leak"].summary["first_alarm"]
    assert 3.0 < first <= 3.1
    assert all(t >= first for t in by["leak"].summary["alarm_times"])
    assert by["noisy"].summary["alarms"] > 0 and "false alarm" in by["noisy"].checks[0].detail
    write_replay(tmp_path / "out", reps)
    doc = read_replay(tmp_path / "out")
    assert doc["passed"] is None and doc["replays"][1]["summary"]["first_alarm"] == first


@pytest.mark.parametrize("gaps", [False, True])
def test_horizon_kernel_replay_equals_the_stepping_loop(result, monkeypatch, gaps):
    """The replay through the horizon kernel (`KernelEstimator.run_states`, with the observed
    mask where samples are missing) = the loop of one `step` / `step_observed` per sample
    (``TANKSYNTH_ESTIMATOR_BACKEND=step``): estimates, predictions, NIS and checks."""
    _, spec, _ = result
    exp, _ = logged(spec, x_ref=True)
    if gaps:
        y = exp.y.copy()
        y[100:105, :] = np.nan
        y[200:210, 1] = np.nan
        y[300:340:3, 0] = np.nan
        exp = with_y(exp, y)
    out = {}
    for mode in ("step", "horizon"):
        monkeypatch.setenv("TANKSYNTH_ESTIMATOR_BACKEND", mode)
        out[mode] = run(result, "ekf", exp)
    a, b = out["horizon"], out["step"]
    for name in ("x_hat", "y_pred", "nis"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=0)
    assert [(c.name, c.passed) for c in a.checks] == [(c.name, c.passed) for c in b.checks]
    assert a.summary["rmse"] == pytest.approx(b.summary["rmse"], rel=1e-12)
