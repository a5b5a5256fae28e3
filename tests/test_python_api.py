"""Issue 30 item 6: ``tanksynth.design(plant, method, ...)`` designs from Python objects.

References: the CLI's artefact of the same problem written as TOML (``tanksynth design``), the
closed-loop eigenvalues by numpy against the region's definition (``|z - c| < r``,
``Re s < -alpha``), python-control's ``lqr`` on the same ``StateSpace``.
"""

from __future__ import annotations

import json
import warnings

import control
import numpy as np
import pytest

import tanksynth
from tanksynth.cli import main
from tanksynth.errors import SpecError
from tanksynth.plants import three_tank

X0 = [0.40, 0.20, 0.30]
DISK = [{"type": "disk", "center": 0.9, "radius": 0.08}]
TOML = """
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = [0.40, 0.20, 0.30]
[sampling]
ts = 1.0
[[design]]
name = "k"
method = "lmi_placement"
target = "state_feedback"
region = [{type = "disk", center = 0.9, radius = 0.08}]
"""
SYSTEM = control.ss([[0.0, 1.0], [-2.0, -3.0]], [[0.0], [1.0]], [[1.0, 0.0]], 0.0)


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


def test_design_from_python_objects_equals_the_cli_artefact(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(TOML)
    assert main(["design", str(spec), "-o", str(tmp_path / "cli")]) == 0
    K_cli = np.array(json.loads((tmp_path / "cli" / "k.json").read_text())["gains"]["K"])

    k = tanksynth.design(three_tank(outputs="h1h2"), "lmi_placement", target="state_feedback",
                         region=DISK, x0=np.array(X0), ts=1.0, name="k", directory=tmp_path / "api")
    assert isinstance(k, tanksynth.Design) and k.method == "lmi_placement"
    np.testing.assert_allclose(k.gains["K"], K_cli, rtol=1e-6, atol=1e-12)
    # the same object `tanksynth.load` gives for the file
    assert tanksynth.load(tmp_path / "api" / "k.json").gains["K"].tolist() == k.gains["K"].tolist()
    # eigenvalues of Ad - Bd K (the stored ZOH model) inside |z - 0.9| < 0.08, by numpy
    eig = np.linalg.eigvals(k.gains["Ad"] - k.gains["Bd"] @ k.gains["K"])
    assert np.all(np.abs(eig - 0.9) < 0.08)


@pytest.mark.slow
def test_one_call_verifies_it(tmp_path):
    k = tanksynth.design("three_tank", "lmi_placement", target="state_feedback", region=DISK,
                         x0=X0, ts=1.0, name="k", directory=tmp_path / "out")
    verdict = k.verify()
    assert type(verdict).__name__ == "Verdict" and verdict.passed is True
    assert tanksynth.load(tmp_path / "out" / "k.json").verdict is True


def test_design_works_after_the_design_package_was_imported():
    import tanksynth.design.placement  # noqa: F401  (sets the package attribute)

    assert callable(tanksynth.design)
    k = tanksynth.design(SYSTEM, "lmi_placement", target="state_feedback",
                         region=[{"type": "half_plane", "alpha": 2.5}])
    eig = np.linalg.eigvals(SYSTEM.A - SYSTEM.B @ k.gains["K"])
    assert np.all(eig.real < -2.5)


def test_a_statespace_is_a_linear_plant_lqr_as_python_control():
    k = tanksynth.design(SYSTEM, "lqr", Q=np.eye(2), R=[[0.5]])
    K_ref, _, _ = control.lqr(SYSTEM, np.eye(2), 0.5 * np.eye(1))
    np.testing.assert_allclose(k.gains["K"], K_ref, rtol=1e-8)
    assert k.diagnostics["method_alias"] == "lqr" and k.method == "h2_state_feedback"
    # lqe with G = B, as python-control's lqe(sys, QN, RN)
    L = tanksynth.design(SYSTEM, "lqe", disturbance_std=[2.0], measurement_std=[0.1])
    L_ref, _, _ = control.lqe(SYSTEM, 4.0 * np.eye(1), 0.01 * np.eye(1))
    np.testing.assert_allclose(L.gains["L"], L_ref, rtol=1e-7)


def test_bad_input_is_the_clis_spec_error_naming_the_key():
    with pytest.raises(SpecError) as info:
        tanksynth.design("three_tank", "lmi_placement", target="observr", region=DISK, x0=X0, ts=1.0)
    assert info.value.key == "design[0].target" and "did you mean 'observer'" in str(info.value)
    with pytest.raises(SpecError) as info:
        tanksynth.design("three_tank", "pole_placement", target="state_feedback", poles=[0.9, 0.8],
                         x0=X0, ts=1.0)
    assert info.value.key == "design[0].poles"


def test_a_statespace_for_a_nonlinear_method_is_a_type_error_naming_the_linear_ones():
    with pytest.raises(TypeError, match="needs a nonlinear plant") as info:
        tanksynth.design(SYSTEM, "ekf", Q=1e-3, R=1e-3, P0=1.0)
    assert "lmi_placement" in str(info.value) and "lqr" in str(info.value)
    with pytest.raises(TypeError, match="discrete-time StateSpace"):
        tanksynth.design(control.c2d(SYSTEM, 0.1), "lqr")
    with pytest.raises(tanksynth.DimensionError, match="D must be zero"):
        tanksynth.design(control.ss(SYSTEM.A, SYSTEM.B, SYSTEM.C, 1.0), "lqr")


def test_the_spec_text_reparses_to_its_document():
    import tomllib

    doc = tanksynth.spec_document(three_tank(outputs="h1h2").with_parameters({"A": 0.02}),
                                  "pole_placement", target="observer", poles=[0.5 + 0.1j, 0.5 - 0.1j, 0.6],
                                  x0=X0, ts=2.0, title='a "quoted" title')
    assert tomllib.loads(tanksynth.spec_text(doc)) == doc
    assert doc["plant"] == {"model": "three_tank", "outputs": "h1h2", "parameters": {"A": 0.02}}
    assert doc["design"][0]["poles"] == [[0.5, 0.1], [0.5, -0.1], 0.6]


def test_a_refused_design_leaves_nothing(tmp_path):
    with pytest.raises(tanksynth.UncontrollableError):  # u1 moves only x1's derivative; x2 free
        tanksynth.design(control.ss([[-1.0, 0.0], [0.0, 1.0]], [[1.0], [0.0]], [[1.0, 1.0]], 0.0),
                         "lmi_placement", target="state_feedback",
                         region=[{"type": "half_plane", "alpha": 0.5}], directory=tmp_path / "out")
    assert not (tmp_path / "out").exists() and list(tmp_path.iterdir()) == []



def test_the_api_asks_for_a_trim_as_the_spec_does():
    """``trim="states"`` with ``u0`` solves the levels, as ``[operating_point] trim`` does: the
    design's operating point balances the plant's own model, f(x0, u0) = 0."""
    import tanksynth
    from tanksynth.api import spec_document, spec_text
    from tanksynth.methods import parse_spec_text
    from tanksynth.plants import three_tank

    plant = three_tank(outputs="h1h2")
    u0 = [3.5e-5, 2.0e-5]
    doc = spec_document(plant, "lqr", u0=u0, trim="states")
    assert doc["operating_point"] == {"u": u0, "trim": "states"}
    spec = parse_spec_text(spec_text(doc))
    assert spec.trim is not None
    # level rates in m/s; the inflows alone move the levels at about 2e-3 m/s
    assert np.max(np.abs(plant.compiled.rhs(spec.x0, np.asarray(u0)))) < 1e-12
    d = tanksynth.design(plant, "lqr", u0=u0, trim="states")
    assert np.asarray(d.gains["K"]).shape == (2, 3)


def test_an_estimators_initial_estimate_is_x_hat0(tmp_path):
    """Issue 30: `x0` of tanksynth.design is the operating point, so an estimator's own option
    x0 (its initial estimate) could not be given from Python; it is `x_hat0`, as stored."""
    x_hat0 = [0.38, 0.22, 0.29]
    k = tanksynth.design(three_tank(outputs="h1h2"), "kalman", x0=X0, ts=1.0, x_hat0=x_hat0,
                         Q=1e-12, R=4e-6, P0=1e-4, directory=tmp_path / "kf")
    np.testing.assert_array_equal(k.gains["x_hat0"].ravel(), x_hat0)
    np.testing.assert_array_equal(k.gains["x_op"].ravel(), X0)
    doc = tanksynth.spec_document("three_tank", "kalman", x0=X0, ts=1.0, x_hat0=x_hat0)
    assert doc["design"][0]["x0"] == x_hat0 and doc["operating_point"]["x"] == X0
