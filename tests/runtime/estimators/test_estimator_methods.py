"""Spec methods of the estimators and fault detection: options, errors, artefacts."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact, write_artefact
from tanksynth.methods import METHODS
from tanksynth.errors import SpecError, UnobservableError
from tanksynth.methods import parse_spec

FAULT_PLANT = {"model": "hydraulic_fault"}
FAULT_OP = {"x": {"x1": 4.0, "x2": 4.0 / 3.0, "x3": 4.0}}


def _spec(designs, plant=None, op=None, ts=0.01):
    table = {"plant": plant or FAULT_PLANT, "operating_point": op or FAULT_OP,
             "sampling": {"ts": ts}, "design": designs}
    return parse_spec(table)


def _run(spec, tmp_path):
    out = {}
    for d in spec.designs:
        result = METHODS[d.method].design(spec, d)
        doc = read_artefact(write_artefact(result, tmp_path, spec.sha256))
        assert doc["method"] == d.method
        out[d.name] = result
    return out


def test_seed004_methods_design_and_write_artefacts(tmp_path):
    spec = _spec([
        {"name": "askf", "method": "adaptive_scaling_kalman", "Q": 1e-4, "R": 1e-4, "P0": 1.0,
         "abc": [0.1, 0.6, 0.3], "x0": [0.25, 0.25, 0.25]},
        {"name": "cf", "method": "consensus_filter", "Q": [1e-4, 1e-4, 1e-4], "R": [1e-4, 2e-4],
         "P0": 1.0},
        {"name": "obs", "method": "luenberger", "poles": [-5.0, -8.0, -10.0], "form": "continuous"},
        {"name": "obs_d", "method": "luenberger", "poles": [0.9, 0.92, 0.95]},
        {"name": "fd", "method": "fault_detection", "delta_bar": 1.0,
         "initial_states": [[0.26, 0.26, 0.26], {"x1": 4.0, "x2": 4.0, "x3": 4.0},
                            [2.4, 3.6, 1.8]], "input": [[0.0, 2.0], [1.0, 1.0]]},
        {"name": "fd_op", "method": "fault_detection"},
        {"name": "kf", "method": "kalman", "Q": 1e-4, "R": 1e-4, "P0": 1.0},
    ])
    res = _run(spec, tmp_path)
    np.testing.assert_allclose(res["obs"].gains["L"].ravel(), [855, 509 / 3, 41], rtol=1e-9)
    np.testing.assert_allclose(sorted(np.array(res["obs_d"].diagnostics[
        "error_dynamics_eigenvalues"])[:, 0]), [0.9, 0.92, 0.95], atol=1e-9)
    fd = res["fd"]
    np.testing.assert_allclose(fd.gains["threshold_coefficients"], [78 / 64, -765 / 64, 807 / 64])
    # detection times are diagnostics of the given starts, not gains (nor seed values)
    assert set(fd.gains) == {"Psi", "Gamma_d", "threshold_coefficients", "threshold_rates"}
    np.testing.assert_allclose(fd.diagnostics["detection_times"],
                               [2.0169779247665742, 2.01522566408112, 2.012684041049772], atol=1e-6)
    assert fd.diagnostics["initial_states"][1] == [4.0, 4.0, 4.0]
    assert [d["x0"] for d in fd.diagnostics["detections"]] == fd.diagnostics["initial_states"]
    assert all(d["false_alarm_before_fault"] is None for d in fd.diagnostics["detections"])
    # default: the operating point alone
    assert fd.diagnostics["input"] == [[0.0, 2.0], [1.0, 1.0]]
    op = res["fd_op"].diagnostics
    assert op["initial_states"] == [[4.0, 4.0 / 3.0, 4.0]] and len(op["detection_times"]) == 1
    assert op["input"] == [[0.0, pytest.approx(2.0, rel=1e-9)]]     # equilibrium input, held
    assert 2.0 <= op["detection_times"][0] <= 5.0
    assert not any("paper" in k for k in {**fd.diagnostics, **fd.gains})
    assert "78" in fd.latex["threshold"] or "39" in fd.latex["threshold"]
    assert res["cf"].diagnostics["sensors"] == 2
    assert res["kf"].gains["K_ss"].shape == (3, 1)


@pytest.mark.parametrize("design, key, match", [
    ({"method": "kalman", "R": 1e-4, "P0": 1.0}, "design[0].Q", "missing option 'Q'"),
    ({"method": "kalman", "Q": -1.0, "R": 1e-4, "P0": 1.0}, "design[0].Q", "semidefinite"),
    ({"method": "kalman", "Q": 1e-4, "R": [[1.0, 2.0]], "P0": 1.0}, "design[0].R",
     "1 x 1"),
    ({"method": "ekf", "Q": 1e-4, "R": 1e-4, "P0": [1.0, 0.0, 1.0]}, "design[0].P0",
     "positive definite"),
    ({"method": "ekf", "Q": 1e-4, "R": 1e-4, "P0": 1.0, "x0": [1.0, 2.0]}, "design[0].x0",
     "expected 3 values"),
    ({"method": "ekf", "Q": 1e-4, "R": 1e-4, "P0": 1.0, "substep": 2}, "design[0].substep",
     "did you mean 'substeps'"),
    ({"method": "luenberger", "poles": [-5.0, -8.0]}, "design[0].poles", "2 poles given, expected 3"),
    ({"method": "luenberger", "poles": [[-5.0, 1.0], -8.0, -9.0]}, "design[0].poles",
     "conjugate pairs"),
    ({"method": "luenberger", "poles": [-5.0, -8.0, -9.0], "nonlinear": True}, "design[0].nonlinear",
     "form = 'continuous'"),
    ({"method": "consensus_filter", "Q": 1e-4, "R": 1e-4, "P0": 1.0}, "design[0].R",
     "one covariance per sensor"),
    ({"method": "narx", "Q": 1e-4, "R": 1e-4, "P0": 1.0, "hold": [5, 2]}, "design[0].hold",
     "min <= max"),
    ({"method": "narx", "Q": 1e-4, "R": 1e-4, "P0": 1.0, "target": "tru"}, "design[0].target",
     "did you mean 'true'"),
    ({"method": "ukf", "Q": 1e-4, "R": 1e-4, "P0": 1.0, "kappa": -3.0}, "design[0].kappa", "> -3"),
    ({"method": "fault_detection", "initial_states": [[5.0, 1.0, 1.0]]},
     "design[0].initial_states", r"not inside the bounds \(0.25, 4\]"),
    ({"method": "fault_detection", "initial_states": [[1.0, 1.0]]}, "design[0].initial_states[0]",
     "expected 3 values"),
    ({"method": "fault_detection", "bounds": [4.0, 0.25]}, "design[0].bounds", "lower < upper"),
    ({"method": "fault_detection", "input": [[1.0, 2.0], [2.0, 1.0]]}, "design[0].input",
     "starting at t = 0"),
    ({"method": "fault_detection", "input": [[0.0, 2.0, 1.0]]}, "design[0].input[0]",
     "expected a list of 2 numbers"),
    ({"method": "adaptive_scaling_kalman", "Q": 1e-4, "R": 1e-4, "P0": 1.0,
      "abc": [0.5, 0.5, 0.5]}, "design[0].abc", "a \\+ b \\+ c must equal 1"),
    ({"method": "adaptive_kalman", "Q0": 1e-4, "R": 1e-4, "P0": 1.0, "window": 0},
     "design[0].window", r"integer in \[1, "),
    ({"method": "ukf", "Q": 1e-4, "R": 1e-4, "P0": 1.0, "speed": 3}, "design[0].speed",
     "unknown option"),
    ({"method": "luenberger"}, "design[0].L", "exactly one of L"),
    ({"method": "fault_detection", "poles": [-5.0, -5.0, -10.0]}, "design[0].poles",
     "distinct real"),
])
def test_bad_options_are_spec_errors_with_keys(design, key, match, tmp_path):
    """Every one is refused when the spec is parsed, before any design runs."""
    with pytest.raises(SpecError, match=match) as info:
        _spec([{"name": "bad", **design}])
    assert info.value.key == key


def test_options_are_validated_once_with_their_defaults():
    from tanksynth.spec.method_options import FaultDetectionOptions, KalmanOptions

    spec = _spec([{"name": "kf", "method": "kalman", "Q": 1e-4, "R": 1e-4, "P0": [1.0, 2.0, 3.0],
                   "x0": {"x1": 1.0, "x2": 2.0, "x3": 3.0}},
                  {"name": "fd", "method": "fault_detection"}])
    kf, fd = (d.config for d in spec.designs)
    assert isinstance(kf, KalmanOptions) and isinstance(fd, FaultDetectionOptions)
    np.testing.assert_array_equal(kf.P0, np.diag([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(kf.x0, [1.0, 2.0, 3.0])
    assert kf.substeps == KalmanOptions.default("substeps") == 1 and kf.clip is False
    assert fd.poles == (-5.0, -8.0, -10.0) and fd.bounds == (0.25, 4.0)
    assert fd.initial_states is None
    with pytest.raises(ValueError):  # validated arrays are read-only
        kf.Q[0, 0] = 1.0
    assert not hasattr(kf, "get")


def test_unobservable_plant_is_refused_naming_the_mode(tmp_path):
    plant = {
        "model": "custom", "name": "two_separate_tanks",
        "states": {"h1": {"unit": "m", "min": 0.0, "max": 0.6},
                   "h2": {"unit": "m", "min": 0.0, "max": 0.6}},
        "inputs": {"q1": {"unit": "m^3/s", "min": 0.0, "max": 1e-4},
                   "q2": {"unit": "m^3/s", "min": 0.0, "max": 1e-4}},
        "parameters": {"A": {"value": 0.0154, "unit": "m^2", "min": 0.0},
                       "a": {"value": 2.5e-5, "unit": "m^2", "min": 0.0},
                       "g": {"value": 9.81, "unit": "m/s^2", "min": 0.0}},
        "equations": {"h1": "(q1 - a*sqrt(2*g*h1))/A", "h2": "(q2 - a*sqrt(2*g*h2))/A"},
        "outputs": {"y": {"expr": "h1", "unit": "m"}},
    }
    spec = _spec([{"name": "ekf", "method": "ekf", "Q": 1e-8, "R": 1e-6, "P0": 1e-2}],
                 plant=plant, op={"x": {"h1": 0.2, "h2": 0.3}}, ts=1.0)
    with pytest.raises(UnobservableError, match="h2"):
        _run(spec, tmp_path)


def test_a_copied_entry_with_other_options_is_validated_again(tmp_path):
    """`DesignSpec` copied with other options: the design reads those, not the stale config."""
    from dataclasses import replace

    spec = _spec([{"name": "obs", "method": "luenberger", "poles": [-5.0, -8.0, -10.0],
                   "form": "continuous"}])
    d = spec.designs[0]
    other = replace(d, options={**d.options, "poles": [-2.0, -3.0, -4.0]})
    res = METHODS["luenberger"].design(spec, other)
    np.testing.assert_allclose(sorted(np.array(res.diagnostics["error_dynamics_eigenvalues"])[:, 0]),
                               [-4.0, -3.0, -2.0], atol=1e-9)
    assert d.config.read_from(d.options) and not d.config.read_from(other.options)
    with pytest.raises(SpecError, match="2 poles given") as info:
        METHODS["luenberger"].design(spec, replace(d, options={**d.options, "poles": [-1.0, -2.0]}))
    assert info.value.key == "design[0].poles"
