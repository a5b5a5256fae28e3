"""The `tanksynth` command: exit codes, JSON output, artefacts, one-line errors."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact
from tanksynth.cli import main

ROOT = Path(__file__).resolve().parents[1]
SEED000 = ROOT / "examples" / "seed000_three_tank.toml"
EXE = Path(sys.executable).parent / "tanksynth"

UNOBSERVABLE = """
title = "x2 is invisible"
[plant]
model = "custom"
[plant.states]
x1 = {unit = "m", min = 0.0, max = 1.0}
x2 = {unit = "m", min = 0.0, max = 1.0}
[plant.inputs]
u = {unit = "m/s", min = -1.0, max = 1.0}
[plant.equations]
x1 = "-x1 + u"
x2 = "-2*x2 + u"
[plant.outputs]
y = "x1"
[operating_point]
x = [0.5, 0.25]
[sampling]
ts = 1.0
[[design]]
name = "lin"
method = "linearize"
"""


def run_cli(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(err: str):
    lines = err.strip("\n").splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error:")
    assert "Traceback" not in err


@pytest.fixture(scope="module")
def check_json():
    """`check --json` on the seed 000 example, run once (the symbolic check takes seconds)."""
    import contextlib
    import io

    buf_out, buf_err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf_out), contextlib.redirect_stderr(buf_err):
        code = main(["check", str(SEED000), "--json"])
    return code, buf_out.getvalue(), buf_err.getvalue()


def test_plants(capsys):
    code, out, err = run_cli(capsys, "plants")
    assert code == 0 and err == ""
    assert "three_tank" in out and "mu13" in out


def test_plants_json(capsys):
    code, out, _ = run_cli(capsys, "plants", "--json")
    assert code == 0
    data = json.loads(out)
    names = [p["name"] for p in data]
    assert "three_tank" in names and "hydraulic_fault" in names
    tt = data[names.index("three_tank")]
    params = {p["name"]: (p["value"], p["unit"]) for p in tt["parameters"]}
    assert params["A"] == (0.0154, "m^2")
    assert params["Phi"] == (5e-5, "m^2")


def test_check_json(check_json):
    code, out, err = check_json
    assert code == 0, err
    checks = json.loads(out)
    by_name = {c["check"]: c for c in checks}
    assert by_name["observability"]["passed"] is True
    assert by_name["controllability"]["passed"] is True
    assert by_name["nonlinear_observability"]["passed"] is True
    assert by_name["observability"]["data"]["rank"] == 3
    # the printed u0 does not balance: reported, not a failure
    assert by_name["given_u0_balances"]["passed"] is None
    assert "does NOT balance" in by_name["given_u0_balances"]["detail"]
    assert all(c["passed"] in (True, None) for c in checks)


def test_design_writes_artefact(tmp_path, capsys):
    out_dir = tmp_path / "art"
    code, out, err = run_cli(capsys, "design", SEED000, "-o", out_dir, "--export", "h")
    assert code == 0, err
    assert (out_dir / "linear_model.json").exists()
    assert (out_dir / "linear_model.npz").exists()
    assert (out_dir / "linear_model.h").exists()
    doc = read_artefact(out_dir / "linear_model.json")
    assert doc["method"] == "linearize" and doc["plant"] == "three_tank"
    assert set(doc["gains"]) == {"F", "B", "Ad", "Bd", "C", "x_op", "u_op"}
    np.testing.assert_allclose(doc["gains"]["u_op"], [3.501785258978626e-05, 3.183782218805142e-05],
                               rtol=1e-10)
    np.testing.assert_allclose(doc["gains"]["F"][0, 0], -0.01136943265902151, rtol=1e-12)
    import hashlib

    assert doc["provenance"]["spec_sha256"] == hashlib.sha256(SEED000.read_bytes()).hexdigest()


def test_design_is_deterministic(tmp_path, capsys):
    for d in ("a", "b"):
        assert run_cli(capsys, "design", SEED000, "-o", tmp_path / d)[0] == 0
    ga = read_artefact(tmp_path / "a" / "linear_model.json")["gains"]
    gb = read_artefact(tmp_path / "b" / "linear_model.json")["gains"]
    for k in ga:
        assert ga[k].tobytes() == gb[k].tobytes()


@pytest.mark.slow
def test_run_default_demo(tmp_path, capsys, monkeypatch):
    """`make demo` as a user runs it: the built-in demo designs two controllers and two observers,
    verifies every one on the nonlinear plant, writes the report and prints the summary."""
    monkeypatch.chdir(tmp_path)
    out_dir = tmp_path / "demo"
    code, out, err = run_cli(capsys, "run", "-o", out_dir)
    assert code == 0, err
    checks = json.loads((out_dir / "checks.json").read_text())
    assert any(c["check"] == "observability" and c["passed"] is True for c in checks)
    assert any(c["check"] == "nonlinear_observability" and c["passed"] is True for c in checks)
    assert (out_dir / "plant.json").exists() and (out_dir / "spec.toml").exists()
    docs = {p.stem: read_artefact(p) for p in out_dir.glob("*.json")
            if p.name not in ("checks.json", "plant.json")}
    assert {d["method"] for d in docs.values()} == {"lmi_placement", "pole_placement", "ts_observer",
                                                    "ekf"}
    for name, doc in docs.items():
        assert doc["verification"]["passed"] is True, (name, doc["verification"])
    assert (out_dir / "report.tex").exists()
    have_tex = all(shutil.which(t) for t in ("pdflatex", "latexmk"))
    assert (out_dir / "report.pdf").exists() == have_tex          # PDF by default when TeX is there
    summary = out[out.index("Designs, verified on the nonlinear plant"):]
    for name in docs:
        assert name[:12] in summary
    assert "FAIL" not in summary.replace(str(tmp_path), ""), summary
    # the seed papers' errata are said to be the paper's, found by the derivation
    assert any(line.startswith("paper vs tool (") and line.endswith(
        "printed value(s) in the paper differ from the derivation (paper errata; not a failure of "
        "the designs: the report's section 'Paper vs tool')")
        for line in out.splitlines()), out                     # one line, even piped
    assert "erratum/errata" not in out
    assert "printed value(s) of the paper differ from the derivation (paper errata)" in (
        out_dir / "report.tex").read_text(encoding="utf-8")
    from tanksynth.summary import key_figure

    assert key_figure(docs["integral_pole_placement"]) == "poles 0.9, 0.92, 0.94, 0.95, 0.97"
    assert key_figure(docs["ts_observer_certified"]).startswith("psi = ")
    assert key_figure(docs["ekf"]).startswith("|e|inf ")
    assert key_figure(docs["integral_lmi_disk"]).startswith("spectral radius 0.9")


def test_check_fails_on_unobservable_plant(tmp_path, capsys):
    spec = tmp_path / "unobs.toml"
    spec.write_text(UNOBSERVABLE)
    code, out, err = run_cli(capsys, "check", spec, "--json")
    assert code == 1
    checks = {c["check"]: c for c in json.loads(out)}
    assert checks["observability"]["passed"] is False
    assert checks["observability"]["data"]["rank"] == 1
    assert checks["pbh_observability"]["passed"] is False
    assert checks["pbh_observability"]["data"]["modes"][0]["states"] == ["x2"]
    assert checks["nonlinear_observability"]["passed"] is False
    assert checks["controllability"]["passed"] is True
    assert err.strip().splitlines() == ["failed: some rank conditions fail"]


@pytest.mark.parametrize("case", ["missing", "malformed", "outside", "method", "no_design"])
def test_bad_input_exit_2_one_line(tmp_path, capsys, case):
    text = SEED000.read_text()
    spec = tmp_path / "spec.toml"
    if case == "missing":
        spec = tmp_path / "does_not_exist.toml"
    elif case == "malformed":
        spec.write_text("[plant\nmodel = 1\n")
    elif case == "outside":
        spec.write_text(text.replace("h1 = 0.40", "h1 = 0.25"))     # h1 > h3 violated
    elif case == "method":
        spec.write_text(text.replace('method = "linearize"', 'method = "magic"'))
    elif case == "no_design":
        spec.write_text(text.split("[[design]]")[0])
    command = "design" if case == "no_design" else "check"
    args = [command, spec] + (["-o", tmp_path / "o"] if command == "design" else [])
    code, out, err = run_cli(capsys, *args)
    assert code == 2
    assert_one_line_error(err)
    assert str(spec) in err
    expected = {"missing": "cannot read", "malformed": "invalid TOML",
                "outside": "operating_point.x", "method": "design[0].method",
                "no_design": "design"}[case]
    assert expected in err
    assert not (tmp_path / "o").exists()


def test_bad_arguments_exit_2(capsys):
    code, _, err = run_cli(capsys, "frobnicate")
    assert code == 2
    assert_one_line_error(err)
    code, _, err = run_cli(capsys, "design", str(SEED000))            # missing -o
    assert code == 2
    assert_one_line_error(err)


def test_help_exit_0(capsys):
    code, out, _ = run_cli(capsys, "--help")
    assert code == 0
    for command in ("plants", "check", "design", "run"):
        assert command in out


@pytest.mark.slow
@pytest.mark.skipif(not EXE.exists(), reason="console script not installed")
def test_console_script_bad_input(tmp_path):
    spec = tmp_path / "broken.toml"
    spec.write_text("[plant\n")
    proc = subprocess.run([str(EXE), "check", str(spec), "--json"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert len(proc.stderr.strip().splitlines()) == 1
    assert "Traceback" not in proc.stderr
    assert "broken.toml" in proc.stderr and "invalid TOML" in proc.stderr


@pytest.mark.slow
@pytest.mark.skipif(not EXE.exists(), reason="console script not installed")
def test_console_script_plants_json():
    proc = subprocess.run([str(EXE), "plants", "--json"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "three_tank" in [p["name"] for p in json.loads(proc.stdout)]


THREE_DESIGNS = """
[[design]]
name = "a_pp"
method = "pole_placement"
target = "state_feedback"
poles = [0.90, 0.91, 0.92]
[[design]]
name = "b_kf"
method = "kalman"
Q = 1e-8
R = 1e-6
P0 = 1e-3
[[design]]
name = "c_bad"
"""

# Third design: a value only the design used to catch (two artefacts were written before).
BAD_THIRD = {
    "pole_count": ('method = "pole_placement"\ntarget = "state_feedback"\npoles = [0.9, 0.8]\n', "design[2].poles",
                   "2 poles given, expected 3"),
    "not_psd": ('method = "ekf"\nQ = [[1e-8, 2e-8, 0.0], [2e-8, 1e-8, 0.0], [0.0, 0.0, 1e-8]]\n'
                'R = 1e-6\nP0 = 1e-3\n', "design[2].Q", "positive semidefinite"),
    "region": ('method = "lmi_placement"\ntarget = "observer"\nregion = [{type = "half_plane", alpha = 0.1}]\n',
               "design[2].region", "not inside the discrete-time stability domain"),
    "typo": ('method = "ukf"\nQ = 1e-8\nR = 1e-6\nP0 = 1e-3\nsubstep = 2\n', "design[2].substep",
             "did you mean 'substeps'"),
}


@pytest.mark.parametrize("command", ["design", "run"])
@pytest.mark.parametrize("case", sorted(BAD_THIRD))
def test_bad_third_design_exits_2_with_nothing_written(tmp_path, capsys, command, case):
    body, key, message = BAD_THIRD[case]
    spec = tmp_path / "spec.toml"
    head = SEED000.read_text().split("[[design]]")[0]
    spec.write_text(head + THREE_DESIGNS + body)
    out_dir = tmp_path / "out"
    code, out, err = run_cli(capsys, command, spec, "-o", out_dir)
    assert code == 2, err
    assert_one_line_error(err)
    assert key in err and message in err and str(spec) in err
    assert not out_dir.exists()
    # the same spec with a good third design writes all three
    spec.write_text(head + THREE_DESIGNS + 'method = "linearize"\n')
    assert run_cli(capsys, "design", spec, "-o", out_dir)[0] == 0
    assert {"a_pp.json", "b_kf.json", "c_bad.json"} <= {p.name for p in out_dir.glob("*.json")}


def test_design_time_refusal_is_infeasible_and_the_others_are_written(tmp_path, capsys):
    """Issue 12 item 8: an unobservable pair is a design refusal (exit 3, not 2); the remaining
    designs are still written and the summary lists the refused one with its reason."""
    spec = tmp_path / "unobs.toml"
    spec.write_text(UNOBSERVABLE + '[[design]]\nname = "obs"\nmethod = "pole_placement"\n'
                    'target = "observer"\npoles = [0.5, 0.6]\n'
                    '[[design]]\nname = "sf"\nmethod = "pole_placement"\n'
                    'target = "state_feedback"\npoles = [0.5, 0.6]\n')
    out_dir = tmp_path / "out"
    code, out, err = run_cli(capsys, "design", spec, "-o", out_dir)
    assert code == 3, err
    assert "refused obs: " in out and "not observable" in out and "x2" in out
    assert {p.name for p in out_dir.glob("*.json")} >= {"lin.json", "sf.json"}
    assert not (out_dir / "obs.json").exists()
    last = err.strip().splitlines()[-1]
    assert last.startswith("infeasible: ") and "1 of 3 design(s) refused" in last and "obs" in last
    # item 12: no message repeats its prefix
    assert "infeasible: infeasible" not in err and "error: error" not in err


def test_design_warnings_are_single_lines_and_recorded(tmp_path, capsys):
    """Issue 12 items 5-7: one line per problem on stderr, recorded in the artefact."""
    spec = tmp_path / "warn.toml"
    head = SEED000.read_text().split("[[design]]")[0].replace("A = 0.0154", "A = 154.0")
    spec.write_text(head + '[[design]]\nname = "pp"\nmethod = "pole_placement"\ntarget = "state_feedback"\n'
                    'poles = [-0.05, -0.06, -0.07]\n')
    out_dir = tmp_path / "out"
    code, out, err = run_cli(capsys, "design", spec, "-o", out_dir)
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if ln.startswith("warning: ")]
    assert any("A = 154 m^2" in ln and "plausible range" in ln for ln in lines)
    assert any("s-plane" in ln for ln in lines)
    assert "Traceback" not in err and "warnings.warn" not in err
    doc = read_artefact(out_dir / "pp.json")
    assert any("plausible range" in w for w in doc["diagnostics"]["warnings"])


def test_os_errors_and_internal_errors_keep_the_exit_code_contract(tmp_path, capsys, monkeypatch):
    """An unwritable output path is bad input (2, one line naming it); an unexpected exception
    is an internal error (4, one line naming the log that holds the traceback)."""
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, out, err = run_cli(capsys, "design", SEED000, "-o", blocker / "sub")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "file" in err, err

    def boom(*args, **kwargs):
        raise ZeroDivisionError("a bug")
    monkeypatch.setattr("tanksynth.analysis.checks.rank_conditions", boom)
    code, out, err = run_cli(capsys, "check", SEED000)
    assert code == 4 and len(err.strip().splitlines()) == 1, err
    log = err.split("traceback in ")[1].split(";")[0]
    assert "ZeroDivisionError: a bug" in Path(log).read_text()


def test_written_paths_are_printed_whole_on_one_line(tmp_path, capsys):
    """`design` prints each artefact path on one line as given: not wrapped at the console
    width when stdout is a pipe (a script reads ``artefact: <path>``), brackets not taken as rich
    markup (``[bold]`` used to vanish from the printed path)."""
    spec = tmp_path / "s.toml"
    spec.write_text(SEED000.read_text(encoding="utf-8"), encoding="utf-8")
    out_dir = tmp_path / ("a_directory_name_long_enough_to_pass_eighty_columns_" * 2) / "[bold]out"
    code, out, _ = run_cli(capsys, "design", spec, "-o", out_dir)
    assert code == 0
    assert f"artefact: {out_dir / 'linear_model.json'}\n" in out, out


def test_an_export_format_given_twice_is_written_once(tmp_path, capsys):
    """``--export law --export law`` (or h twice) exports once; it was exit 2 claiming the
    design "has no control law to export", after the plant record was written."""
    spec = tmp_path / "s.toml"
    spec.write_text(SEED000.read_text(encoding="utf-8").replace(
        'method = "linearize"', 'method = "pole_placement"\ntarget = "state_feedback"\npoles = [0.9, 0.91, 0.92]'),
        encoding="utf-8")
    code, _, err = run_cli(capsys, "design", spec, "-o", tmp_path / "o", "--export", "law",
                           "--export", "h", "--export", "law", "--export", "h")
    assert code == 0, err
    names = sorted(p.name for p in (tmp_path / "o").iterdir())
    assert names == ["linear_model.h", "linear_model.json", "linear_model.npz",
                     "linear_model_law.c", "linear_model_law.casadi", "linear_model_law.h",
                     "plant.json", "spec.toml"], names


@pytest.mark.slow
def test_export_law_prints_each_laws_files_and_signature(tmp_path, capsys):
    """``design --export law`` names, per law, its three files and its signature (inputs with
    sizes -> outputs): a law carried by the design (feedback linearisation, from the example)
    and one derived from the written gains (a pole-placement observer)."""
    import re

    spec = tmp_path / "s.toml"
    text = (ROOT / "examples" / "seed000_feedback_linearization.toml").read_text(encoding="utf-8")
    head = text[:text.index("[[design]]")]
    spec.write_text(head + '[[design]]\nname = "fl"\nmethod = "feedback_linearization"\n'
                    'tracked = ["h1", "h2"]\npoles = [-0.05, -0.05]\n'
                    '[[design]]\nname = "obs"\nmethod = "pole_placement"\ntarget = "observer"\n'
                    'poles = [0.5, 0.6, 0.7]\n', encoding="utf-8")
    out_dir = tmp_path / "o"
    code, out, err = run_cli(capsys, "design", spec, "-o", out_dir, "--export", "law")
    assert code == 0, err
    laws = [line for line in out.splitlines() if line.startswith("law: ")]
    assert len(laws) == 2, out
    # three tanks (n = 3), two pumps (m = 2), C = I3 (q = 3), two tracked levels
    expected = {"fl": "fl_law(x[3], y_r[2]) -> (u[2], zeta[2])",
                "obs": "obs_law(x_hat[3], u[2], y[3]) -> (x_hat_next[3])"}
    for line, (name, signature) in zip(laws, expected.items()):
        m = re.fullmatch(r"law: (.+)\.\{casadi,c,h\}: (.+)", line)
        assert m, line
        assert m.group(1) == str(out_dir / f"{name}_law")
        for ext in (".casadi", ".c", ".h"):
            assert Path(m.group(1) + ext).is_file(), ext
        assert m.group(2) == signature
    assert out.index("artefact: ") < out.index("law: ")
