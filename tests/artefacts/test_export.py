"""Exports usable elsewhere: ``--export law`` for every linear controller, observer and the
KF/EKF step (generated C compiled with gcc and evaluated), and ``.h`` / ``.mat`` in one
orientation.

Each compiled law is compared with the same law written out here in numpy from the
artefact's gains (and, for the Kalman filter, a textbook predict/correct step).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts.export import compile_law, load_compiled_law
from tanksynth.artefacts.io import read_artefact
from tanksynth.cli import main

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is needed to compile laws")

SPEC = """
title = "law exports"
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "sf"
method = "pole_placement"
target = "state_feedback"
poles = [0.90, 0.92, 0.94]
[[design]]
name = "sfi"
method = "pole_placement"
target = "state_feedback"
integral = true
tracked = ["h1", "h2"]
poles = [0.92, 0.97, 0.90, 0.95, 0.94]
[[design]]
name = "lmi"
method = "lmi_placement"
target = "state_feedback"
integral = true
tracked = ["h1", "h2"]
region = [{type = "disk", center = 0.0, radius = 0.97}]
[[design]]
name = "obs"
method = "pole_placement"
target = "observer"
poles = [0.5, 0.6, 0.7]
[[design]]
name = "lue"
method = "luenberger"
form = "current"
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
x0 = [0.38, 0.21, 0.29]
[[design]]
name = "ukf"
method = "ukf"
Q = 1e-9
R = 1e-6
P0 = 1e-4
alpha = 1.0
x0 = [0.38, 0.21, 0.29]
"""

X = np.array([0.41, 0.195, 0.305])
Z = np.array([0.01, -0.02])
YR = np.array([0.42, 0.21])
U = np.array([3.6e-5, 3.1e-5])
Y = np.array([0.405, 0.198])


@pytest.fixture(scope="module")
def out(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("laws")
    (d / "spec.toml").write_text(SPEC, encoding="utf-8")
    assert main(["design", str(d / "spec.toml"), "-o", str(d / "out"), "--export", "law",
                 "--export", "h", "--export", "mat"]) == 0
    return d / "out"


def _compiled(out: Path, name: str):
    lib = compile_law(out / f"{name}_law.c", out / f"{name}_law.so")
    return load_compiled_law(lib, f"{name}_law")


def _np(v) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(-1)


def test_every_linear_design_exports_a_law(out):
    for name in ("sf", "sfi", "lmi", "obs", "lue", "kf", "ekf", "ukf"):
        for ext in (".casadi", ".c", ".h"):
            assert (out / f"{name}_law{ext}").is_file(), (name, ext)


@pytest.mark.parametrize("name", ["sf", "sfi", "lmi"])
def test_state_feedback_law_compiled(out, name):
    doc = read_artefact(out / f"{name}.json")
    g = {k: np.asarray(v) for k, v in doc["gains"].items()}
    x_op, u_op = np.array([0.40, 0.20, 0.30]), np.array(doc["diagnostics"]["equilibrium"]["u0"])
    law = _compiled(out, name)
    if name == "sf":
        np.testing.assert_allclose(_np(law(X)), u_op - g["K"] @ (X - x_op), rtol=1e-12, atol=1e-15)
        return
    u, z_next = law(X, Z, YR)
    expected_u = u_op - g["K"][:, :3] @ (X - x_op) - g["K"][:, 3:] @ Z
    np.testing.assert_allclose(_np(u), expected_u, rtol=1e-12, atol=1e-15)
    # discrete integrators of the design: z(k+1) = z(k) + (y_r - y), y = (h1, h2)
    np.testing.assert_allclose(_np(z_next), Z + (YR - X[:2]), rtol=1e-12, atol=1e-15)


def test_observer_steps_compiled(out):
    doc = read_artefact(out / "obs.json")
    L = np.asarray(doc["gains"]["L"])
    A, B, C = (np.asarray(doc["gains"][k]) for k in ("Ad", "Bd", "C"))
    step = _compiled(out, "obs")
    x_op = np.array([0.40, 0.20, 0.30])
    u_op = np.array(doc["diagnostics"]["equilibrium"]["u0"])
    got = _np(step(X, U, Y))
    dx = X - x_op
    expected = x_op + A @ dx + B @ (U - u_op) + L @ (Y - x_op[:2] - C @ dx)
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-14)
    # a fixed point: at the operating point with matching measurements the estimate stays
    np.testing.assert_allclose(_np(step(x_op, u_op, x_op[:2])), x_op, atol=1e-12)
    lue = _compiled(out, "lue")
    np.testing.assert_allclose(_np(lue(x_op, u_op, x_op[:2])), x_op, atol=1e-12)
    # the current form's error dynamics: e+ = (I - L C) Ad e, from the linear model of kf.json
    kf = read_artefact(out / "kf.json")
    Ad, C = np.asarray(kf["gains"]["Ad"]), np.asarray(kf["gains"]["C"])
    Llue = np.asarray(read_artefact(out / "lue.json")["gains"]["L"])
    e = np.array([0.01, -0.005, 0.002])
    got = _np(lue(x_op + e, u_op, x_op[:2])) - x_op
    np.testing.assert_allclose(got, (np.eye(3) - Llue @ C) @ Ad @ e, rtol=1e-6, atol=1e-13)


def test_kalman_step_compiled_is_the_textbook_filter(out):
    doc = read_artefact(out / "kf.json")
    g = {k: np.asarray(v) for k, v in doc["gains"].items()}
    Ad, Bd, C, Q, R = g["Ad"], g["Bd"], g["C"], g["Q"], g["R"]
    x_op, u_op = g["x_op"], g["u_op"]
    P = np.diag([1e-4, 2e-4, 3e-4])
    step = _compiled(out, "kf")
    x_next, P_next = step(X, P, Y, U)
    xp = x_op + Ad @ (X - x_op) + Bd @ (U - u_op)
    Pp = Ad @ P @ Ad.T + Q
    K = Pp @ C.T @ np.linalg.inv(C @ Pp @ C.T + R)
    y_pred = C @ xp          # outputs h1, h2 are states
    np.testing.assert_allclose(_np(x_next), xp + K @ (Y - y_pred), rtol=1e-9, atol=1e-13)
    np.testing.assert_allclose(np.asarray(P_next), (np.eye(3) - K @ C) @ Pp, rtol=1e-8, atol=1e-15)


def test_ekf_step_compiled_matches_the_runtime_filter(out):
    from tanksynth.methods import load_spec
    from tanksynth.runtime.estimators.kalman import ExtendedKalmanFilter, KalmanTuning

    spec = load_spec(out / "spec.toml")
    doc = read_artefact(out / "ekf.json")
    g = {k: np.asarray(v) for k, v in doc["gains"].items()}
    ekf = ExtendedKalmanFilter(spec.plant, KalmanTuning(Q=g["Q"], R=g["R"], P0=g["P0"], x0=g["x_hat0"],
                                                        ts=1.0), backend="vm")
    expected = ekf.step(Y, U)
    x_next, P_next = _compiled(out, "ekf")(g["x_hat0"], g["P0"], Y, U)
    np.testing.assert_allclose(_np(x_next), expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(P_next), ekf.covariance, rtol=1e-10, atol=1e-18)
    assert np.allclose(np.asarray(P_next), np.asarray(P_next).T)


def test_ukf_step_compiled_matches_the_runtime_filter(out):
    from tanksynth.methods import load_spec
    from tanksynth.runtime.estimators.ukf import UKFTuning, UnscentedKalmanFilter

    spec = load_spec(out / "spec.toml")
    g = {k: np.asarray(v) for k, v in read_artefact(out / "ukf.json")["gains"].items()}
    ukf = UnscentedKalmanFilter(spec.plant, UKFTuning(Q=g["Q"], R=g["R"], P0=g["P0"], x0=g["x_hat0"],
                                                      ts=1.0, alpha=1.0), backend="vm")
    x_next, P_next = _compiled(out, "ukf")(g["x_hat0"], g["P0"], Y, U)
    expected = ukf.step(Y, U)
    np.testing.assert_allclose(_np(x_next), expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(P_next), ukf.covariance, rtol=1e-10, atol=1e-18)
    # the estimate moved toward the measurement: the correction acted
    assert np.linalg.norm(_np(x_next)[:2] - Y) < np.linalg.norm(g["x_hat0"][:2] - Y)


def test_header_and_mat_agree_in_orientation(out, tmp_path):
    from scipy.io import loadmat

    header = (out / "ekf.h").read_text(encoding="utf-8")
    assert "#define EKF_X_HAT0_ROWS 3" in header and "#define EKF_X_HAT0_COLS 1" in header
    assert "#define EKF_TS 1.0" in header and "states: h1 [m], h2 [m], h3 [m]" in header
    mat = loadmat(out / "ekf.mat")
    assert mat["x_hat0"].shape == (3, 1) and mat["x_op"].shape == (3, 1)
    # x0, u0 (MATLAB's names, issue 30 item 5) are the operating point, never the initial estimate
    np.testing.assert_array_equal(mat["x0"], mat["x_op"])
    np.testing.assert_array_equal(mat["u0"], mat["u_op"])
    assert not np.array_equal(mat["x0"], mat["x_hat0"])
    values = re.search(r"ekf_x_op\[3\] = \{([^}]*)\}", header).group(1)
    np.testing.assert_allclose([float(v) for v in values.split(",")], mat["x_op"][:, 0])
    # the header compiles, and its arrays hold the .mat values
    src = tmp_path / "main.c"
    src.write_text(f'#include "{out / "sfi.h"}"\n#include <stdio.h>\nint main(void) {{\n'
                   "  for (int i = 0; i < SFI_K_ROWS * SFI_K_COLS; ++i) printf(\"%.17g\\n\", sfi_K[i]);\n"
                   "  printf(\"%.17g\\n\", SFI_TS);\n  return 0;\n}\n", encoding="utf-8")
    subprocess.run(["gcc", "-Wall", "-Werror", "-o", str(tmp_path / "main"), str(src), "-lm"], check=True)
    printed = np.array(subprocess.run([str(tmp_path / "main")], capture_output=True, text=True,
                                      check=True).stdout.split(), dtype=float)
    sfi = loadmat(out / "sfi.mat")
    np.testing.assert_array_equal(printed[:-1], sfi["K"].ravel())   # row-major, as in MATLAB rows
    assert printed[-1] == 1.0


def test_design_without_a_law_says_so(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC.split("[[design]]")[0] + '[[design]]\nname = "lin"\nmethod = "linearize"\n',
                    encoding="utf-8")
    assert main(["design", str(spec), "-o", str(tmp_path / "o"), "--export", "law"]) == 0
    assert "lin: no control law or estimator step to export" in capsys.readouterr().out
    assert not list((tmp_path / "o").glob("*_law.*"))


def test_every_controller_and_estimator_method_has_a_law():
    """No method of the table that designs a controller, observer, estimator or detector is
    left without `--export law` (models have nothing to export)."""
    from tanksynth.artefacts.estimator_laws import ESTIMATOR_LAW_METHODS
    from tanksynth.artefacts.export import DERIVED_LAW_METHODS
    from tanksynth.artefacts.synthesis_laws import SYNTHESIS_LAW_METHODS
    from tanksynth.methods import TABLE

    # these carry their law in `diagnostics.law` (written by the design itself)
    carried = {"feedback_linearization", "integral_tracking", "inverse_dynamics"}
    covered = set(DERIVED_LAW_METHODS) | set(ESTIMATOR_LAW_METHODS) | set(SYNTHESIS_LAW_METHODS)
    missing = [row.name for row in TABLE if set(row.kinds) != {"model"}
               and row.name not in covered | carried]
    assert missing == []


def spec_plant_limits(spec: Path) -> np.ndarray:
    from tanksynth.methods import load_spec

    return load_spec(spec).plant.input_limits


@pytest.mark.slow
def test_design_names_that_are_not_c_identifiers_export_their_law(tmp_path):
    """A design name may start with a digit or hold '.', '-' (the spec allows it): the law is
    still exported (it was an internal error), as ``<name>_law.*`` beside ``<name>.json``,
    with a C symbol made an identifier; compiled, it is u_op - K (x - x_op) with the stored K."""
    base = SPEC.split("[[design]]")[0]
    designs = "".join(f'[[design]]\nname = "{nm}"\nmethod = "pole_placement"\ntarget = "state_feedback"\n'
                      'poles = [0.90, 0.92, 0.94]\n' for nm in ("1a", "x-y", "int"))
    spec = tmp_path / "s.toml"
    spec.write_text(base + designs, encoding="utf-8")
    o = tmp_path / "o"
    assert main(["design", str(spec), "-o", str(o), "--export", "law", "--export", "h"]) == 0
    for name, symbol in (("1a", "law_1a_law"), ("x-y", "x_y_law"), ("int", "int_law")):
        assert {p.name for p in o.glob(f"{name}_law.*")} == {f"{name}_law.{e}" for e in ("c", "h", "casadi")}
        lib = compile_law(o / f"{name}_law.c", o / f"{name}_law.so", flags=("-O2", "-Wall", "-Werror"))
        law = load_compiled_law(lib, symbol)
        K = read_artefact(o / f"{name}.json")["gains"]["K"]
        x2 = X + np.array([0.001, -0.002, 0.0005])   # inside the pumps' range: linear
        du = _np(law(x2)) - _np(law(X))
        np.testing.assert_allclose(du, -K @ (x2 - X), rtol=1e-12, atol=1e-15)
        # far out: clipped to the pumps' range, as the plant the verdict simulates clips it
        lo, hi = np.asarray(spec_plant_limits(spec), dtype=float).T
        x3 = X + np.array([0.2, -0.15, 0.1])
        np.testing.assert_allclose(_np(law(x3)), np.clip(_np(law(X)) - K @ (x3 - X), lo, hi),
                                   rtol=1e-12, atol=1e-15)
        assert np.any(_np(law(x3)) != _np(law(X)) - K @ (x3 - X))   # the clip was active


def _three_tank_by_hand(h1=0.40, h2=0.20, h3=0.30):
    """Issue 30 item 5 reference: the three-tank linearised by hand (Torricelli, d/dd (k sqrt(d)) =
    k / (2 sqrt(d))), A = F (1/s), B (m/s per m^3/s), and the equilibrium pump flows."""
    g, area, Phi, mu13, mu32, mu20 = 9.81, 0.0154, 5e-5, 0.5, 0.5, 0.675
    k13, k32, k20 = (mu * Phi * np.sqrt(2 * g) for mu in (mu13, mu32, mu20))
    c13, c32, c20 = (k / (2 * np.sqrt(d)) / area for k, d in ((k13, h1 - h3), (k32, h3 - h2), (k20, h2)))
    A = np.array([[-c13, 0.0, c13], [0.0, -c32 - c20, c32], [c13, c32, -c13 - c32]])
    B = np.array([[1 / area, 0.0], [0.0, 1 / area], [0.0, 0.0]])
    u0 = np.array([k13 * np.sqrt(h1 - h3), k20 * np.sqrt(h2) - k32 * np.sqrt(h3 - h2)])
    return A, B, u0


def test_mat_export_loads_in_matlab_terms_without_the_readme(out):
    """Issue 30 item 5: A, B, C, D, x0, u0, the law as text, units and ts in the .mat."""
    from scipy.io import loadmat

    A, B, u0 = _three_tank_by_hand()
    for name in ("sf", "obs"):
        mat = loadmat(out / f"{name}.mat")
        np.testing.assert_allclose(mat["A"], A, rtol=1e-9)
        np.testing.assert_allclose(mat["B"], B, rtol=1e-12)
        np.testing.assert_array_equal(mat["C"], [[1, 0, 0], [0, 1, 0]])  # outputs h1, h2
        np.testing.assert_array_equal(mat["D"], np.zeros((2, 2)))
        np.testing.assert_allclose(mat["x0"].ravel(), [0.40, 0.20, 0.30])
        np.testing.assert_allclose(mat["u0"].ravel(), u0, rtol=1e-9)
        assert mat["ts"].item() == 1.0
        # the old names stay
        np.testing.assert_array_equal(mat["x_op"], mat["x0"])
        np.testing.assert_array_equal(mat["u_op"], mat["u0"])
        units = mat["units"][0, 0]
        assert units["A"].item() == "1/s" and units["ts"].item() == "s" and units["x0"].item() == "m"
        assert units["B"].item() == "m/(s m^3/s)" or "m^3/s" in units["B"].item()
    assert "u = u_op - K (x - x_op)" in loadmat(out / "sf.mat")["law"].item()
    obs_law = loadmat(out / "obs.mat")["law"].item()
    assert "x_hat_next" in obs_law and "L (y - y_op" in obs_law
    # every variable the law text names is in the file: y_op = h(x_op), here (h1, h2)
    obs = loadmat(out / "obs.mat")
    np.testing.assert_allclose(obs["y_op"].ravel(), [0.40, 0.20])
    np.testing.assert_array_equal(obs["y0"], obs["y_op"])
    assert obs["units"][0, 0]["y_op"].item() == "m"
    assert loadmat(out / "sf.mat")["units"][0, 0]["K"].item() == "(m^3/s)/m"


def test_law_header_states_the_law_units_and_sampling_period(out):
    header = (out / "sf_law.h").read_text(encoding="utf-8")
    comment = header[:header.index("*/")]
    assert "u = u_op - K (x - x_op)" in comment
    assert "h1 [m], h2 [m], h3 [m]" in comment and "q1 [m^3/s], q2 [m^3/s]" in comment
    assert "ts = 1.0 s" in comment and "x_op = [0.4, 0.2, 0.3]" in comment
    gains_header = (out / "sf.h").read_text(encoding="utf-8")
    assert "law: u = u_op - K (x - x_op)" in gains_header and "K [(m^3/s)/m]" in gains_header


@pytest.mark.slow
def test_every_exported_law_compiles_with_strict_warnings(out):
    """Issue 30 item 5: the generated C passes gcc -std=c99 -Wall -Wextra -Wpedantic -Werror."""
    sources = sorted(out.glob("*_law.c"))
    assert len(sources) >= 8
    for src in sources:
        proc = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-c",
                               str(src), "-o", str(src.with_suffix(".o"))],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, f"{src.name}: {proc.stderr[:2000]}"


def test_a_continuous_design_exports_no_sampling_period():
    """New-user pass: an ``lqr`` (continuous time) in a spec with ``ts = 1`` exported ``ts = 1``:
    the period of the spec is not the design's; a discrete design keeps it."""
    from tanksynth.artefacts.export import implementation_data

    record = {"ts": 1.0, "operating_point": {"x": [0.4, 0.2, 0.3], "u": [1e-5, 1e-5]}}
    assert np.isnan(implementation_data({"time_domain": "continuous"}, record)["ts"])
    assert implementation_data({"time_domain": "discrete"}, record)["ts"] == 1.0
    assert implementation_data({}, record)["ts"] == 1.0


def test_lqr_weights_are_exported_with_the_gain():
    """An LQR-type design's .mat holds the Q and R its gain minimises (issue 30: lqr.mat had K
    without Q, R), so that a MATLAB user can check ``K = lqr(A, B, Q, R)`` without the artefact."""
    from tanksynth.artefacts.export import implementation_data, mat_contents

    record = {"ts": 1.0, "plant": {"states": [{"name": "h1", "unit": "m"}],
                                   "inputs": [{"name": "q1", "unit": "m^3/s"}], "outputs": []}}
    data = implementation_data({"weights": {"Q": [[2.0]], "R": [[3.0]]}, "equilibrium": {"x0": [0.1], "u0": [1e-5]}},
                               record)
    mat = mat_contents({"K": np.array([[0.5]])}, data)
    np.testing.assert_array_equal(mat["Q"], [[2.0]])
    np.testing.assert_array_equal(mat["R"], [[3.0]])
    assert "Q" not in mat_contents({"K": np.array([[0.5]])}, implementation_data({}, record))


def test_integral_gain_units_name_each_block(out):
    """Issue 30 (new-user pass): the .mat gave K = [K1 K2] one unit (input per state unit),
    but K2 multiplies z, the integrated output error: (m^3/s)/(m s) here, by hand."""
    from scipy.io import loadmat

    mat = loadmat(out / "sfi.mat")
    K = mat["K"]
    assert K.shape[1] > 3
    unit = mat["units"][0, 0]["K"].item()
    assert unit.startswith("(m^3/s)/m in columns 1-3")
    assert f"(m^3/s)/(m s) in columns 4-{K.shape[1]}" in unit
    header = (out / "sfi_law.h").read_text(encoding="utf-8")
    assert "integrated tracking error, m s" in header
