"""`tanksynth.load`: gains, diagnostics, verdict and the linear system of a designed artefact.

Reference values are computed here independently: the poles requested in the spec text,
numpy eigenvalues of hand-built matrices and the Kalman gain of a Riccati recursion
iterated to convergence (not scipy's DARE, which the loader uses).
"""

from __future__ import annotations

import json
from pathlib import Path

import control
import numpy as np
import pytest

import tanksynth
from tanksynth.cli import main
from tanksynth.errors import ArtefactError

SPEC = """
title = "load() test: three-tank, every linear kind"
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0

[[design]]
name = "sf_integral"
method = "pole_placement"
target = "state_feedback"
integral = true
tracked = ["h1", "h2"]
poles = [0.92, 0.97, 0.90, 0.95, 0.94]

[[design]]
name = "sf_lmi"
method = "lmi_placement"
target = "state_feedback"
region = [{type = "disk", center = 0.0, radius = 0.97}]

[[design]]
name = "obs"
method = "pole_placement"
target = "observer"
poles = [0.5, 0.6, 0.7]

[[design]]
name = "kf"
method = "kalman"
Q = 1e-9
R = 1e-6
P0 = 1e-3

[[design]]
name = "ekf"
method = "ekf"
Q = 1e-9
R = 1e-6
P0 = 1e-3

[[design]]
name = "lue"
method = "luenberger"
form = "current"
poles = [0.5, 0.6, 0.7]

[[design]]
name = "it"
method = "integral_tracking"
tracked = ["h1", "h2"]
poles = [0.92, 0.97, 0.90, 0.95, 0.94]

[[design]]
name = "lin"
method = "linearize"
"""


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("load")
    (d / "spec.toml").write_text(SPEC, encoding="utf-8")
    out = d / "out"
    assert main(["design", str(d / "spec.toml"), "-o", str(out), "--export", "mat"]) == 0
    return out


def _sorted(values) -> np.ndarray:
    return np.sort_complex(np.asarray(values, dtype=complex))


def test_load_directory_and_file(results):
    res = tanksynth.load(results)
    assert set(res) == {"sf_integral", "sf_lmi", "obs", "kf", "ekf", "lue", "it", "lin"}
    assert res.verdict is None and all(d.verdict is None for d in res.values())
    one = tanksynth.load(results / "obs.json")
    assert isinstance(one, tanksynth.Design) and one.method == "pole_placement"
    doc = json.loads((results / "obs.json").read_text(encoding="utf-8"))
    np.testing.assert_array_equal(one.gains["L"], np.array(doc["gains"]["L"]))
    assert one.diagnostics["time_domain"] == "discrete" and one.ts == 1.0
    with pytest.raises(ValueError):
        one.gains["L"][0, 0] = 1.0   # read-only


def test_state_feedback_closed_loop_has_the_requested_poles(results):
    sys = tanksynth.load(results / "sf_integral.json").to_statespace()
    assert isinstance(sys, control.StateSpace) and sys.dt == 1.0
    assert sys.nstates == 5 and sys.ninputs == 2 and sys.noutputs == 2
    np.testing.assert_allclose(_sorted(sys.poles()), _sorted([0.90, 0.92, 0.94, 0.95, 0.97]), atol=1e-8)
    # integral action: unit DC gain from the references to the tracked outputs
    np.testing.assert_allclose(control.dcgain(sys), np.eye(2), atol=1e-8)
    lmi = tanksynth.load(results / "sf_lmi.json").to_statespace()
    assert np.all(np.abs(lmi.poles()) < 0.97)


def test_observer_error_system(results):
    d = tanksynth.load(results / "obs.json")
    sys = d.to_statespace()
    A, C = d.gains["Ad"], d.gains["C"]       # a discrete design: Ad (never A; issue 16)
    assert "A" not in d.gains and "B" not in d.gains
    np.testing.assert_allclose(_sorted(sys.poles()), _sorted([0.5, 0.6, 0.7]), atol=1e-8)
    np.testing.assert_allclose(sys.A, A - d.gains["L"] @ C)
    lue = tanksynth.load(results / "lue.json").to_statespace()
    np.testing.assert_allclose(_sorted(lue.poles()), _sorted([0.5, 0.6, 0.7]), atol=1e-8)


def _riccati_by_iteration(Ad, C, Q, R) -> np.ndarray:
    P = np.eye(Ad.shape[0]) * 1e-3
    for _ in range(200_000):
        S = C @ P @ C.T + R
        Pn = Ad @ (P - P @ C.T @ np.linalg.solve(S, C @ P)) @ Ad.T + Q
        if np.max(np.abs(Pn - P)) < 1e-22:
            break
        P = Pn
    return P @ C.T @ np.linalg.inv(C @ P @ C.T + R)


def test_kalman_error_system_is_the_steady_state_filter(results):
    kf = tanksynth.load(results / "kf.json")
    Ad, C = kf.gains["Ad"], kf.gains["C"]
    K = _riccati_by_iteration(Ad, C, kf.gains["Q"], kf.gains["R"])
    expected = np.linalg.eigvals((np.eye(3) - K @ C) @ Ad)
    np.testing.assert_allclose(_sorted(kf.to_statespace().poles()), _sorted(expected), atol=1e-7)
    # the EKF (no linear model in its artefact) is linearised from spec.toml: same system
    ekf = tanksynth.load(results / "ekf.json").to_statespace()
    np.testing.assert_allclose(_sorted(ekf.poles()), _sorted(expected), atol=1e-7)


def test_integral_tracking_and_linearize(results):
    it = tanksynth.load(results / "it.json").to_statespace()
    np.testing.assert_allclose(_sorted(it.poles()), _sorted([0.90, 0.92, 0.94, 0.95, 0.97]), atol=1e-8)
    np.testing.assert_allclose(control.dcgain(it), np.eye(2), atol=1e-8)
    lin = tanksynth.load(results / "lin.json")
    sys = lin.to_statespace()
    np.testing.assert_allclose(sys.A, lin.gains["Ad"])
    assert sys.dt == 1.0 and sys.state_labels == ["h1", "h2", "h3"]


def test_verdict_after_verify(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.split("[[design]]")[0] + "[[design]]" + SPEC.split("[[design]]")[3],
                    encoding="utf-8")
    assert main(["design", str(spec), "-o", str(tmp_path / "out")]) == 0
    assert main(["verify", str(tmp_path / "out"), "--json"]) == 0
    res = tanksynth.load(tmp_path / "out")
    assert list(res) == ["obs"] and res.verdict is True
    assert res["obs"].verdict is True and res["obs"].checks and all("check" in c for c in res["obs"].checks)


def test_refusals(results, tmp_path):
    with pytest.raises(ArtefactError):
        tanksynth.load(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ArtefactError, match="no design artefact"):
        tanksynth.load(tmp_path / "empty")
    edited = tmp_path / "obs.json"
    doc = json.loads((results / "obs.json").read_text(encoding="utf-8"))
    doc["gains"]["L"][0][0] += 1.0
    edited.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(ArtefactError):
        tanksynth.load(edited)


def test_mat_export_matlab_orientation(results):
    from scipy.io import loadmat

    mat = loadmat(results / "ekf.mat")
    doc = json.loads((results / "ekf.json").read_text(encoding="utf-8"))
    assert mat["x_hat0"].shape == (3, 1)   # the initial estimate, a column
    np.testing.assert_allclose(mat["x_hat0"][:, 0], doc["gains"]["x_hat0"])
    np.testing.assert_array_equal(mat["x0"], mat["x_op"])   # MATLAB's name of the operating point
    np.testing.assert_allclose(mat["x_op"][:, 0], [0.40, 0.20, 0.30])
    assert mat["ts"].shape == (1, 1) and mat["ts"][0, 0] == 1.0
    assert [str(c[0]) for c in mat["state_names"][:, 0]] == ["h1", "h2", "h3"]
    assert [str(c[0]) for c in mat["state_units"][:, 0]] == ["m", "m", "m"]
    assert [str(c[0]) for c in mat["input_names"][:, 0]] == ["q1", "q2"]
    assert [str(c[0]) for c in mat["input_units"][:, 0]] == ["m^3/s", "m^3/s"]
    assert [str(c[0]) for c in mat["output_names"][:, 0]] == ["h1", "h2"]
    sf = loadmat(results / "sf_integral.mat")
    doc = json.loads((results / "sf_integral.json").read_text(encoding="utf-8"))
    np.testing.assert_allclose(sf["K"], doc["gains"]["K"])
    assert sf["x_op"].shape == (3, 1) and sf["u_op"].shape == (2, 1)
    np.testing.assert_allclose(sf["u_op"][:, 0], doc["diagnostics"]["equilibrium"]["u0"])


# ----------------------------------------------------------------- tampering (issue 19)
# `load` runs the integrity checks of `tanksynth verify` (one code path): every edit below
# makes both refuse, naming the file.
def _edit_json(name, fn):
    def edit(d: Path) -> None:
        doc = json.loads((d / name).read_text(encoding="utf-8"))
        fn(doc)
        (d / name).write_text(json.dumps(doc, indent=2), encoding="utf-8")
    return edit


def _rename_state(record):
    record["plant"]["states"][0]["name"] = "level1"


def _scale_npz(d: Path) -> None:
    with np.load(d / "obs.npz") as data:
        gains = {k: data[k] * 1.01 for k in data.files}
    np.savez(d / "obs.npz", **gains)


def _swap(a, b):
    def edit(d: Path) -> None:
        (d / a).rename(d / "tmp")
        (d / b).rename(d / a)
        (d / "tmp").rename(d / b)
    return edit


def _truncate(name, n):
    def edit(d: Path) -> None:
        (d / name).write_bytes((d / name).read_bytes()[:n])
    return edit


def _dir_over(name):
    def edit(d: Path) -> None:
        (d / name).unlink()
        (d / name).mkdir()
    return edit


def _unlink(name):
    return lambda d: (d / name).unlink()


def _write(name, text):
    return lambda d: (d / name).write_text(text, encoding="utf-8")


TAMPERING = {
    "plant_ts_edited": (_edit_json("plant.json", lambda r: r.__setitem__("ts", 5.0)), "plant.json"),
    "plant_state_renamed": (_edit_json("plant.json", _rename_state), "plant.json"),
    "plant_deleted": (_unlink("plant.json"), "plant.json"),
    "npz_edited": (_scale_npz, "obs.npz"),
    "npz_swapped": (_swap("obs.npz", "lue.npz"), "lue.npz|obs.npz"),
    "npz_truncated": (_truncate("obs.npz", 100), "obs.npz"),
    "npz_emptied": (_truncate("obs.npz", 0), "obs.npz"),
    "npz_is_a_directory": (_dir_over("obs.npz"), "obs.npz"),
    "npz_deleted": (_unlink("obs.npz"), "obs.npz"),
    "json_deleted_npz_orphan": (_unlink("obs.json"), "obs.npz"),
    "spec_edited": (lambda d: (d / "spec.toml").write_text(SPEC + "\n# edited\n", encoding="utf-8"),
                    "spec.toml"),
    "spec_deleted": (_unlink("spec.toml"), "spec.toml"),
    "checks_not_json": (_write("checks.json", "[{\"check\": "), "checks.json"),
    "checks_not_a_list": (_write("checks.json", "{\"check\": 1}"), "checks.json"),
}


@pytest.mark.parametrize("case", sorted(TAMPERING))
def test_load_refuses_what_verify_refuses(results, tmp_path, case):
    import shutil

    from tanksynth.methods import METHODS
    from tanksynth.verify.runner import load_directory

    edit, named = TAMPERING[case]
    d = tmp_path / "d"
    shutil.copytree(results, d)
    assert isinstance(tanksynth.load(d), tanksynth.Results)  # the copy loads before the edit
    edit(d)
    with pytest.raises(ArtefactError, match=named) as loaded:
        tanksynth.load(d)
    with pytest.raises(ArtefactError, match=named):
        load_directory(d, METHODS)
    assert len(str(loaded.value).splitlines()) == 1


SINGLE = {
    "own_npz_edited": (_scale_npz, "obs.npz"),
    "own_npz_deleted": (_unlink("obs.npz"), "obs.npz"),
    "plant_edited": (_edit_json("plant.json", lambda r: r.__setitem__("ts", 5.0)), "plant.json"),
    "plant_deleted": (_unlink("plant.json"), "plant.json"),
    "spec_edited": (lambda d: (d / "spec.toml").write_text(SPEC + "\n# edited\n", encoding="utf-8"),
                    "spec.toml"),
    "spec_deleted": (_unlink("spec.toml"), "spec.toml"),
}


@pytest.mark.parametrize("case", sorted(SINGLE))
def test_load_one_file_checks_its_files(results, tmp_path, case):
    import shutil

    edit, named = SINGLE[case]
    d = tmp_path / "d"
    shutil.copytree(results, d)
    edit(d)
    with pytest.raises(ArtefactError, match=named):
        tanksynth.load(d / "obs.json")


def test_load_one_file_ignores_other_artefacts(results, tmp_path):
    """One artefact loads when only another artefact's files were damaged."""
    import shutil

    d = tmp_path / "d"
    shutil.copytree(results, d)
    _scale_npz(d)
    (d / "kf.npz").unlink()
    one = tanksynth.load(d / "lue.json")
    assert one.name == "lue" and one.plant_record["ts"] == 1.0


def test_well_formed_checks_json_is_loaded(results, tmp_path):
    import shutil

    d = tmp_path / "d"
    shutil.copytree(results, d)
    verdicts = [{"check": "observability", "passed": True, "detail": "rank 3", "data": {}}]
    (d / "checks.json").write_text(json.dumps(verdicts), encoding="utf-8")
    assert tanksynth.load(d).checks == verdicts


def test_as_complex_reads_the_documented_json_form_of_eigenvalues():
    """Issue 30: eigenvalues are stored as [re, im] pairs; one documented reader."""
    import numpy as np

    import tanksynth
    from tanksynth.design.matrices import complex_pairs

    z = np.array([-0.5, -0.2 + 0.1j, -0.2 - 0.1j])
    pairs = complex_pairs(z)   # what a design writes
    assert pairs == [[-0.5, 0.0], [-0.2, -0.1], [-0.2, 0.1]]
    np.testing.assert_array_equal(tanksynth.as_complex(pairs), np.sort_complex(z))
    np.testing.assert_array_equal(tanksynth.as_complex([[-0.2, -0.1], [-0.2, 0.1], -0.5]),
                                  [-0.2 - 0.1j, -0.2 + 0.1j, -0.5])
    per_model = tanksynth.as_complex([pairs, pairs])
    assert per_model.shape == (2, 3)
    import pytest
    with pytest.raises(ValueError):
        tanksynth.as_complex([[1.0, 2.0, 3.0]])
    readme = (Path(tanksynth.__file__).resolve().parents[1] / "docs" / "artefacts.md").read_text(encoding="utf-8")
    assert "[re, im]` pair" in readme and "tanksynth.as_complex" in readme
