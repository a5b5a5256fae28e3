"""The fault-detection verdict records its faulty runs with the residual and the threshold.

`tanksynth run` on examples/seed004_fault_detection.toml stores ``residual_fault_detector.traces.npz``;
its arrays are checked here against values derived in the test from the spec (initial states,
observer start, output ``y = x3 / psi3``), the artefact's stored threshold (eq. 55: absolute
coefficients and rates) and the detection times of the verdict's own check.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact
from tanksynth.artefacts.traces import read_trace, trace_path
from tanksynth.cli import main
from tanksynth.methods import verify_directory

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "seed004_fault_detection.toml"
NAME = "residual_fault_detector"


pytestmark = pytest.mark.slow   # every test uses a verified fault-detection campaign


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("fault_trace") / "out"
    assert main(["run", str(EXAMPLE), "-o", str(d), "--no-pdf"]) == 0
    return d


@pytest.fixture(scope="module")
def design() -> dict:
    spec = tomllib.loads(EXAMPLE.read_text(encoding="utf-8"))
    out = next(d for d in spec["design"] if d["name"] == NAME)
    out["psi3"] = spec["plant"]["parameters"]["psi3"]
    return out


@pytest.fixture(scope="module")
def trace(run_dir) -> dict:
    tr = read_trace(trace_path(run_dir / f"{NAME}.json", NAME))
    assert tr is not None
    return tr


def test_the_trace_names_the_check_the_signals_and_the_fault(trace, design):
    head, arr = trace["header"], trace["arrays"]
    assert head["check"] == "fault_detected" and head["check_passed"] is True
    assert head["signal_names"] == [r"$|\varepsilon|$", "threshold"]   # figure labels (mathtext)
    assert head["signal_units"] == ["1", "1"]          # the plant's output y is dimensionless
    assert head["signal_styles"] == ["-", "--"] and "threshold" in head["signal_title"]
    assert [e[0] for e in head["events"]] == [design["t_fault"]]
    assert f"t_f = {design['t_fault']:g} s" in head["scenario"]
    runs = head["runs"]
    assert runs == 2 and arr["signals"].shape == (runs, arr["t"].size, 2)
    assert arr["x"].shape == arr["x_hat"].shape == (runs, arr["t"].size, 3)
    assert arr["t"].size <= 2000 and head["stride"] > 1       # decimated like the other traces


def test_the_runs_are_the_faulty_plant_from_the_first_starts(trace, design):
    arr = trace["arrays"]
    np.testing.assert_array_equal(arr["x"][:, 0, :], np.array(design["initial_states"][:2]))
    np.testing.assert_array_equal(arr["x_hat"][:, 0, :], np.full((2, 3), design["bounds"][0]))
    # the input schedule: 2 on [0, 1 s), then 1
    t_u, u = arr["t_u"], arr["u"][:, :, 0]
    assert np.all(u[:, t_u < 1.0] == 2.0) and np.all(u[:, t_u >= 1.0 + 1e-9] == 1.0)


def test_stored_residual_and_threshold_equal_independent_values(trace, design, run_dir):
    arr = trace["arrays"]
    t, sig = arr["t"], arr["signals"]
    # residual |y - h(x_hat)| with y = x3 / psi3 (no measurement noise in this scenario)
    residual = np.abs(arr["x"][:, :, 2] - arr["x_hat"][:, :, 2]) / design["psi3"]
    np.testing.assert_allclose(sig[:, :, 0], residual, rtol=1e-12, atol=1e-15)
    # eq. 55 (conservative = true): sum_i |c_i| exp(lambda_i t) from the stored coefficients and rates
    doc = read_artefact(run_dir / f"{NAME}.json")
    c = np.asarray(doc["gains"]["threshold_coefficients"], float).ravel()
    lam = np.asarray(doc["gains"]["threshold_rates"], float).ravel()
    assert design["conservative"] is True and np.all(lam < 0)
    threshold = np.sum(np.abs(c)[:, None] * np.exp(lam[:, None] * t[None, :]), axis=0)
    np.testing.assert_allclose(sig[0, :, 1], threshold, rtol=1e-12)
    np.testing.assert_array_equal(sig[1, :, 1], sig[0, :, 1])


def test_first_crossing_is_the_checks_detection_time_to_the_sampling(trace, design, run_dir):
    arr, head = trace["arrays"], trace["header"]
    t, sig = arr["t"], arr["signals"]
    verdict = {v.name: v for v in verify_directory(run_dir)}[NAME]
    check = {c.name: c for c in verdict.checks}["fault_detected"]
    assert check.passed is True
    step = head["stride"] * head["ts"]
    t_f = design["t_fault"]
    for run in range(2):
        above = np.flatnonzero((t > t_f) & (sig[run, :, 0] > sig[run, :, 1]))
        assert above.size, run
        j = int(above[0])
        t_detect = check.data["t_detect"][run]
        # the stored samples bracket the verdict's (interpolated, full-rate) detection time
        assert t[j - 1] < t_detect <= t[j] < t_detect + step + 1e-12, (run, t[j - 1], t[j], t_detect)
        # before the fault the residual stays under the threshold after the initial transient
        quiet = (t >= 0.02 * t_f) & (t < t_f)
        assert np.all(sig[run, quiet, 0] <= sig[run, quiet, 1] * (1 + 1e-6)), run
