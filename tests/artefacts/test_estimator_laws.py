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
    actual, expected = _np(actual).reshape(np.shape(expected)), _np(expected)
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
        Q=g["Q"], R=g["R"], P0=g["P0"], x0=g["x0"], ts=spec.ts, a=a, b=b, c=c, G=g["G"],
        phi0=float(g["phi0"][0]), operating_point=(g["x_op"], g["u_op"])))
    law = _compiled(out, "scaling_kalman")
    assert law.name_in() == ["x", "P", "phi", "y", "u"]
    x, P, phi = g["x0"], g["P0"], float(g["phi0"][0])
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
        Q=g["Q"], R=(g["R0"], g["R1"]), P0=g["P0"], x0=g["x0"], ts=spec.ts, G=g["G"],
        operating_point=(g["x_op"], g["u_op"])))
    law = _compiled(out, "sensor_consensus")
    assert law.size1_in(2) == 2 and law.name_out() == ["x_next", "M_next"]
    x, M = g["x0"], g["P0"]
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
    xp = mdl.Ad @ g["x0"] + mdl.Bd @ U[0] + mdl.cd
    x1, _ = law(g["x0"], g["P0"], Y[0], U[0])
    _close(x1, xp + K @ (Y[0] - C2 @ xp - np.concatenate([mdl.dy, mdl.dy])), "centralised update")


def test_fault_detection_step_compiled_matches_the_verdicts_observer(seed004):
    from tanksynth.verify.fault import ResidualObserver

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
