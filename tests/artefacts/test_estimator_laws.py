"""``--export law`` of the estimators built by `tanksynth.artefacts.estimator_laws`.

Each test designs from a (shrunk) example spec through the CLI, compiles the
exported C with gcc, and runs it beside the estimator the verdict runs (the
runtime filters of `tanksynth.runtime.estimators`, or the verdict's own
observers) on the same data: the compiled step must reproduce it to 1e-10.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts.export import compile_law, load_compiled_law
from tanksynth.artefacts.io import read_artefact
from tanksynth.cli import main

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is needed to compile laws")

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _designs(text: str, keep: set[str]) -> str:
    """The spec text with only the ``[[design]]`` entries named in ``keep``."""
    head, *blocks = re.split(r"(?m)^\[\[design\]\]\s*$", text)
    kept = [b for b in blocks if re.search(r'(?m)^name\s*=\s*"([^"]+)"', b).group(1) in keep]
    return head + "".join("[[design]]" + b for b in kept)


def _design(tmp: Path, text: str) -> Path:
    (tmp / "spec.toml").write_text(text, encoding="utf-8")
    assert main(["design", str(tmp / "spec.toml"), "-o", str(tmp / "out"), "--export", "law"]) == 0
    return tmp / "out"


def _compiled(out: Path, name: str):
    lib = compile_law(out / f"{name}_law.c", out / f"{name}_law.so")
    return load_compiled_law(lib, f"{name}_law")


def _gains(out: Path, name: str) -> dict[str, np.ndarray]:
    return {k: np.asarray(v, dtype=float) for k, v in read_artefact(out / f"{name}.json")["gains"].items()}


def _np(v) -> np.ndarray:
    return np.asarray(v, dtype=float)


def _close(actual, expected, what: str) -> None:
    expected = _np(expected)
    actual = _np(actual).reshape(expected.shape)
    scale = max(float(np.max(np.abs(expected))), 1e-300)
    np.testing.assert_allclose(actual, expected, rtol=1e-10, atol=1e-10 * scale, err_msg=what)


# ------------------------------------------------------------------ seed 004: linear hydraulic model
@pytest.fixture(scope="module")
def seed004(tmp_path_factory):
    from tanksynth.methods import load_spec

    text = (EXAMPLES / "seed004_fault_detection.toml").read_text(encoding="utf-8")
    out = _design(tmp_path_factory.mktemp("s4"), _designs(text, {"residual_fault_detector",
                                                                 "scaling_kalman",
                                                                 "sensor_consensus"}))
    return out, load_spec(out / "spec.toml")


def _data(rng, steps: int, y0, u0, dy: float, du: float):
    Y = np.asarray(y0, float) + dy * rng.standard_normal((steps, np.size(y0)))
    U = np.asarray(u0, float) + du * rng.standard_normal((steps, np.size(u0)))
    return Y, U


def test_adaptive_scaling_kalman_step_compiled_matches_the_runtime_filter(seed004):
    from tanksynth.runtime.estimators.adaptive import AdaptiveScalingKalmanFilter, AdaptiveScalingTuning

    out, spec = seed004
    g = _gains(out, "scaling_kalman")
    a, b, c = g["abc"]
    est = AdaptiveScalingKalmanFilter(spec.plant, AdaptiveScalingTuning(
        Q=g["Q"], R=g["R"], P0=g["P0"], x0=g["x_hat0"], ts=spec.ts, a=a, b=b, c=c, G=g["G"],
        phi0=float(g["phi0"][0]), operating_point=(g["x_op"], g["u_op"])))
    law = _compiled(out, "scaling_kalman")
    assert law.name_in() == ["x", "P", "phi", "y", "u"]
    x, P, phi = g["x_hat0"], g["P0"], float(g["phi0"][0])
    Y, U = _data(np.random.default_rng(1), 25, [2.0], [2.0], 0.05, 0.1)
    phis = []
    for y, u in zip(Y, U):
        x, P, phi = law(x, P, phi, y, u)
        expected = est.step(y, u)
        _close(x, expected, "x_next")
        _close(P, est.covariance, "P_next")
        _close(phi, est.phi, "phi_next")
        phis.append(float(phi))
    assert max(phis) > 10 * min(phis)      # the scaling adapted: the test exercised eq. 36-38


def test_consensus_step_compiled_matches_the_runtime_filter(seed004):
    from tanksynth.runtime.estimators.consensus import ConsensusFilter, ConsensusTuning

    out, spec = seed004
    g = _gains(out, "sensor_consensus")
    est = ConsensusFilter(spec.plant, ConsensusTuning(
        Q=g["Q"], R=(g["R0"], g["R1"]), P0=g["P0"], x0=g["x_hat0"], ts=spec.ts, G=g["G"],
        operating_point=(g["x_op"], g["u_op"])))
    law = _compiled(out, "sensor_consensus")
    assert law.size1_in(2) == 2 and law.name_out() == ["x_next", "M_next"]
    x, M = g["x_hat0"], g["P0"]
    Y, U = _data(np.random.default_rng(2), 20, [2.0, 2.0], [2.0], 0.01, 0.1)
    for y, u in zip(Y, U):
        x, M = law(x, M, y, u)
        _close(x, est.step(y, u), "x_next")
        _close(M, est.covariance, "M_next")
    # the network step is the centralised Kalman filter on the stacked sensors (independent check)
    mdl = est.model
    C2, R2 = np.vstack([mdl.C, mdl.C]), np.diag([g["R0"].item(), g["R1"].item()])
    Pp = mdl.Ad @ g["P0"] @ mdl.Ad.T + g["G"] @ g["Q"] @ g["G"].T
    K = Pp @ C2.T @ np.linalg.inv(C2 @ Pp @ C2.T + R2)
    xp = mdl.Ad @ g["x_hat0"] + mdl.Bd @ U[0] + mdl.cd
    x1, _ = law(g["x_hat0"], g["P0"], Y[0], U[0])
    _close(x1, xp + K @ (Y[0] - C2 @ xp - np.concatenate([mdl.dy, mdl.dy])), "centralised update")


def test_fault_detection_step_compiled_matches_the_verdicts_observer(seed004):
    from tanksynth.verify.fault.verdicts import ResidualObserver

    out, spec = seed004
    g = _gains(out, "residual_fault_detector")
    law = _compiled(out, "residual_fault_detector")
    assert law.name_out() == ["x_hat_next", "residual", "threshold", "alarm"]
    ts = float(spec.ts)
    obs = ResidualObserver(spec.plant, g["Psi"].reshape(3, 1), ts)
    x = np.full(3, 0.25)
    obs.reset(x[None])
    rng = np.random.default_rng(3)
    y_prev = np.array([2.0])
    obs.step(y_prev[None], np.array([[2.0]]))
    alarms = []
    for k in range(1, 40):
        y, u = y_prev + 0.02 * rng.standard_normal(1), np.array([2.0 + 0.1 * rng.standard_normal()])
        x, res, thr, alarm = law(x, u, y_prev, y, k * ts)
        expected = obs.step(y[None], u[None])[0]
        _close(x, expected, "x_hat_next")
        _close(res, obs.residuals[-1][0], "residual")
        thr_ref = np.sum(np.abs(g["threshold_coefficients"]) * np.exp(g["threshold_rates"] * k * ts))
        _close(thr, thr_ref, "threshold (eq. 55, conservative)")
        assert float(alarm) == float(abs(float(res)) > thr_ref)
        alarms.append(float(alarm))
        y_prev = y
    # a residual far above the threshold raises the alarm; the law is not constant
    _, res, thr, alarm = law(x, np.array([2.0]), y_prev, y_prev + 10.0, 40 * ts)
    assert float(alarm) == 1.0 and abs(float(res)) > float(thr)


# ------------------------------------------------------------------ seed 000: adaptive-Q Kalman filter
AKF_STEADY = """
[[design]]
name = "akf37"
method = "adaptive_kalman"
x0 = [0.9, 0.55, 0.5]
P0 = 10.0
Q0 = 1e-8
R = 1e-4
window = 3
q_floor = 1e-10
form = "steady_state"
"""


@pytest.mark.slow
@pytest.mark.parametrize("name, form", [("akf", "full"), ("akf37", "steady_state")])
def test_adaptive_kalman_step_compiled_matches_the_runtime_filter(tmp_path_factory, name, form):
    from tanksynth.methods import load_spec
    from tanksynth.runtime.estimators.adaptive import AdaptiveKalmanFilter, AdaptiveKalmanTuning

    text = _designs((EXAMPLES / "seed000_akf.toml").read_text(encoding="utf-8"), {"akf"})
    out = _design(tmp_path_factory.mktemp(name), text + (AKF_STEADY if name == "akf37" else ""))
    spec = load_spec(out / "spec.toml")
    g = _gains(out, name)
    W = int(g["window"][0])
    est = AdaptiveKalmanFilter(spec.plant, AdaptiveKalmanTuning(
        Q0=g["Q0"], R=g["R"], P0=g["P0"], x0=g["x_hat0"], ts=spec.ts, window=W,
        q_floor=float(g["q_floor"][0]), form=form, operating_point=(g["x_op"], g["u_op"])))
    law = _compiled(out, name)
    assert law.name_in() == ["x", "P", "Q", "V", "DX", "filled", "y", "u"]
    x, P, Q, V, DX, filled = g["x_hat0"], g["P0"], g["Q0"], np.zeros((W, 3)), np.zeros((W, 3)), 0.0
    Y, U = _data(np.random.default_rng(4), W + 8, [0.4, 0.2, 0.3], [3.5e-5, 3.75e-5], 0.01, 3e-6)
    for y, u in zip(Y, U):
        x, P, Q, V, DX, filled = law(x, P, Q, V, DX, filled, y, u)
        _close(x, est.step(y, u), "x_next")
        _close(P, est.covariance, "P_next")
        _close(Q, est.Q, "Q_next (adapted once the window is full)")
    assert float(filled) == W
    if name == "akf":      # eq. 36 gives Q below the floor there: the floor acts on every eigenvalue
        np.testing.assert_allclose(np.linalg.eigvalsh(_np(Q)), float(g["q_floor"][0]), rtol=1e-6)
    else:                  # eq. 37 adapted Q away from Q0 = 1e-8 I
        assert np.max(np.abs(_np(Q) - g["Q0"])) > 1e-7


def test_psd_floor_is_the_eigenvalue_clip():
    import casadi as ca

    from tanksynth.artefacts.estimator_laws import sx_psd_floor

    rng = np.random.default_rng(5)
    A = ca.SX.sym("A", 4, 4)
    fn = ca.Function("f", [A], [sx_psd_floor(A, 0.1)])
    for B in (rng.standard_normal((4, 4)), np.diag([1.0, 1.0, -2.0, 0.5]), np.ones((4, 4))):
        S = 0.5 * (B + B.T)
        w, V = np.linalg.eigh(S)
        _close(fn(S), (V * np.maximum(w, 0.1)) @ V.T, "V max(w, floor) V'")


# ------------------------------------------------------------------ seed 002: NARX
@pytest.mark.slow
def test_narx_step_compiled_matches_the_runtime_estimator(tmp_path_factory):
    from tanksynth.methods import load_spec
    from tanksynth.runtime.estimators.narx import NARXEstimator, NARXTuning

    text = _designs((EXAMPLES / "seed002_estimators.toml").read_text(encoding="utf-8"), {"narx"})
    for key, value in (("delays", "3"), ("runs", "2"), ("steps", "60"), ("restarts", "1"),
                       ("max_iter", "15")):
        text = re.sub(rf"(?m)^{key} = \d+", f"{key} = {value}", text)
    text += "substeps = 2\nclip = true\n"
    out = _design(tmp_path_factory.mktemp("narx"), text)
    spec = load_spec(out / "spec.toml")
    g = _gains(out, "narx")
    n, H, d = 3, g["W1"].shape[0], 3
    assert int(g["delays"][0]) == d
    est = NARXEstimator(spec.plant, NARXTuning(
        g["W1"], g["b1"], g["W2"], g["b2"], g["in_mean"], g["in_scale"], g["out_mean"],
        g["out_scale"], x0=g["x_hat0"], ts=spec.ts, delays=d, substeps=2, clip=True), backend="vm")
    law = _compiled(out, "narx")
    assert law.name_in() == ["x", "x_past", "y", "u"] and law.size1_in(1) == (d - 1) * n
    x, past = g["x_hat0"], np.tile(g["x_hat0"], d - 1)
    Y, U = _data(np.random.default_rng(6), 12, [0.31], [2.78e-5, 2.78e-5], 0.01, 5e-6)
    for y, u in zip(Y, U):
        x_prev = _np(x).ravel()
        x, past, x_pred, innov = law(x, past, y, u)
        _close(x, est.step(y, u), "x_next")
        _close(_np(past)[:n], x_prev, "the delay line shifts x(k-1) in")
        _close(_np(innov), y - spec.plant.compiled.output(_np(x_pred).reshape(1, n))[0], "innovation")
    assert H == 5


# ------------------------------------------------------------------ seed 001: TS multiple observer
@pytest.fixture(scope="module")
def seed001(tmp_path_factory):
    from tanksynth.methods import load_spec

    text = _designs((EXAMPLES / "seed001_ts_observer.toml").read_text(encoding="utf-8"),
                    {"ts_observer_paper"})
    text = text.replace("\n[[design]]", "\n[sampling]\nts = 0.5\n\n[[design]]", 1)
    out = _design(tmp_path_factory.mktemp("s1"), text)
    return out, load_spec(out / "spec.toml")


def test_ts_observer_step_compiled_matches_the_verdicts_observer(seed001):
    from tanksynth.verify.observer_lmi.verdicts import TSObserver, _ts_model_from_artefact

    out, spec = seed001
    doc = read_artefact(out / "ts_observer_paper.json")
    model, _ = _ts_model_from_artefact(doc, spec)
    L = _np(doc["gains"]["L"])
    obs = TSObserver(model, L, spec.ts)
    law = _compiled(out, "ts_observer_paper")
    assert law.name_in() == ["x_hat", "u", "y"] and law.name_out() == ["x_hat_next", "z", "mu"]
    x = np.array([0.45, 0.25, 0.35])
    obs.reset(x[None])
    rng = np.random.default_rng(7)
    y_prev = np.array([0.40, 0.20])
    obs.step(y_prev[None], np.zeros((1, 2)))
    for _ in range(10):
        u = np.array([3.5e-5, 3.75e-5]) * (1 + 0.1 * rng.standard_normal(2))
        x_start = _np(x).ravel()
        x, z, mu = law(x, u, y_prev)
        y = np.array([0.40, 0.20]) + 0.005 * rng.standard_normal(2)
        _close(x, obs.step(y[None], u[None])[0], "x_hat_next")
        # the memberships: those of the TS model at the estimate, summing to 1
        _close(mu, model.memberships(x_start[None])[0], "mu")
        _close(z, model.qlpv.premise_values(x_start[None])[0], "z")
        assert abs(float(np.sum(_np(mu))) - 1.0) < 1e-12
        y_prev = y


def test_ts_observer_measured_premises_variant(seed001):
    import casadi as ca

    from tanksynth.artefacts.observer_laws import ts_model_from_record, ts_observer_step

    out, spec = seed001
    doc = read_artefact(out / "ts_observer_paper.json")
    model = ts_model_from_record(spec.plant, doc["diagnostics"]["ts_model"])
    L = _np(doc["gains"]["L"])
    est = ts_observer_step("est", model, L, spec.ts, substeps=1)
    mea = ts_observer_step("mea", model, L, spec.ts, substeps=1, premises="measured")
    assert mea.name_in() == ["x_hat", "u", "y", "z"]
    x, u, y = np.array([0.45, 0.25, 0.35]), np.array([3.5e-5, 3.75e-5]), np.array([0.41, 0.19])
    z = _np(est(x, u, y)[1]).ravel()
    # with one substep and z the premises at the estimate, both variants are the same step
    _close(mea(x, u, y, z)[0], est(x, u, y)[0], "measured premises = estimated ones")
    # other premises give another step, and memberships that follow z (eq. 12-14)
    z2 = 0.5 * (_np(model.bounds.lower) + _np(model.bounds.upper))
    x2, mu2 = mea(x, u, y, z2)
    assert np.all(np.abs(_np(mu2) - 1.0 / model.r) < 1e-12)
    assert not np.allclose(_np(x2), _np(est(x, u, y)[0]), rtol=0, atol=1e-12)
    # the generated C of the measured variant compiles too
    from tanksynth.artefacts.export import export_law

    files = export_law(mea, out, name="ts_measured_law")
    lib = load_compiled_law(compile_law(files.c_source), "ts_measured_law")
    _close(lib(x, u, y, z2)[0], x2, "compiled measured variant")
    assert isinstance(mea, ca.Function)


def test_ts_observer_without_sampling_is_the_vector_field(seed001):
    from tanksynth.artefacts.observer_laws import ts_model_from_record, ts_observer_step

    out, spec = seed001
    doc = read_artefact(out / "ts_observer_paper.json")
    model = ts_model_from_record(spec.plant, doc["diagnostics"]["ts_model"])
    L = _np(doc["gains"]["L"])
    field = ts_observer_step("field", model, L, None)
    assert field.name_out() == ["x_hat_dot", "z", "mu"]
    x, u, y = np.array([0.45, 0.25, 0.35]), np.array([3.5e-5, 3.75e-5]), np.array([0.41, 0.19])
    # eq. (20) with the vertices: sum_i mu_i (A_i x + B u) + d + L (y - C x)
    mu = model.memberships(x[None])[0]
    expected = np.einsum("i,inj,j->n", mu, model.A, x) + model.B @ u + model.d + L @ (y - model.C @ x)
    _close(field(x, u, y)[0], expected, "x_hat_dot")


# ------------------------------------------------------------------ seed 003: decentralised Kalman
SEED003_SMALL = """
title = "seed 003 shrunk to 4 tanks"
[plant]
model = "tank_network"
N = 4
[operating_point]
x = [20.0, 20.0, 7.688, 4.9005]
u = [3.926125712679154, 3.6881786997895105]
[sampling]
ts = 1.0
[[design]]
name = "dkf"
method = "decentralized_kalman"
algorithm = "one_step"
window = 6
E = "own_tank"
process_noise = 0.01
process_noise_correlation = 0.5
measurement_noise = 4.0
initial_covariance = 10.0
input = [6.0, 6.0]
relinearize_every = 3
"""


@pytest.mark.slow
def test_decentralized_step_compiled_matches_the_verdicts_filter(tmp_path_factory):
    from tanksynth.methods import load_spec
    from tanksynth.verify.decentralized.verdicts import DecentralizedFilter

    base = (EXAMPLES / "seed003_tank_network.toml").read_text(encoding="utf-8")
    assert 'method = "decentralized_kalman"' in base and 'E = "own_tank"' in base
    out = _design(tmp_path_factory.mktemp("s3"), SEED003_SMALL)
    spec = load_spec(out / "spec.toml")
    g = _gains(out, "dkf")
    Ks = [g[f"K_{j}"] for j in range(6)]
    assert "K_6" not in g
    n, q = Ks[0].shape
    filt = DecentralizedFilter(spec.plant, Ks, spec.ts)
    law = _compiled(out, "dkf")
    assert law.name_in() == ["x_hat", "u", "y", "k"]
    x = np.array([21.0, 19.0, 8.0, 5.0])
    filt.reset(x[None])
    filt.step(np.zeros((1, q)), np.zeros((1, 2)))              # k = 0: the initial estimate
    rng = np.random.default_rng(8)
    for k in range(1, 10):                                     # window steps 1..6, then open loop
        u = np.array([6.0, 6.0]) + 0.2 * rng.standard_normal(2)
        y = np.array([20.0, 20.0, 7.7, 4.9])[:q] + rng.standard_normal(q)
        x_before = _np(x).ravel()
        x, crossed = law(x, u, y, float(k))
        _close(x, filt.step(y[None], u[None])[0], f"x_hat_next at k = {k}")
        assert float(crossed) == 0.0
        if k > 6:          # after the window: the prediction alone, whatever y
            _close(law(x_before, u, y + 5.0, float(k))[0], x, "no correction after the window")
        else:
            assert not np.allclose(_np(law(x_before, u, y + 5.0, float(k))[0]), _np(x))
