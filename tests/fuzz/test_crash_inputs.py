"""One regression test per input of issue 19 that used to crash, hang or leak: each now ends in
exit 2 with one stderr line naming the spec file and key (or the path), within seconds."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time

import casadi as ca
import pytest

from fuzz_helpers import EXAMPLES, ROOT, assert_contract, run

CUSTOM = (EXAMPLES / "custom_two_tank.toml").read_text(encoding="utf-8")
FAULT_HEAD = (EXAMPLES / "seed004_fault_detection.toml").read_text(encoding="utf-8").split("[[design]]")[0]
EKF = 'method = "ekf"\nQ = 1e-9\nR = 1e-6\nP0 = 1e-3\n'


def nested(fn: str, depth: int, inner: str = "h2") -> str:
    for _ in range(depth):
        inner = f"{fn}({inner} + 1)" if fn == "sqrt" else f"{fn}({inner})"
    return inner


def fault_design(body: str) -> str:
    return FAULT_HEAD + "\n[[design]]\n" + body


CASES = {
    # item 8: orderings naming a parameter or an input
    "ordering_parameter": (CUSTOM.replace('orderings = ["h1 > h2"]', 'orderings = ["h1 > A"]'),
                           "plant.orderings[0]", "names A"),
    "ordering_input": (CUSTOM.replace('orderings = ["h1 > h2"]', 'orderings = ["h1 > q"]'),
                       "plant.orderings[0]", "names q"),
    "input_under_sqrt": (CUSTOM.replace('h1 = "(q - a1', 'h1 = "(sqrt(q) - a1'),
                         "plant.equations.h1", "square root"),
    "area_1e-300": (CUSTOM.replace("A = {value = 0.0154", "A = {value = 1e-300"),
                    "plant.equations.h1", "magnitude"),
    "ts_1e-300": (CUSTOM.replace("ts = 1.0", "ts = 1e-300"), "sampling.ts", "1e-06"),
    "toml_1000_brackets": (CUSTOM + "\nzz = " + "[" * 1000 + "]" * 1000 + "\n", None, "nested too deeply"),
    # item 5: symbolic blow-up
    "ordering_power_of_power": (CUSTOM.replace('orderings = ["h1 > h2"]',
                                               'orderings = ["((h1+h2+1)**64+1)**64 > h2"]'),
                                "plant.orderings[0]", "too complex for symbolic analysis"),
    "output_32_nested_sqrt": (CUSTOM.replace('y = {expr = "h2"', f'y = {{expr = "{nested("sqrt", 32)}"'),
                              "plant.outputs.y", "too complex for symbolic analysis"),
    "output_10_nested_exp": (CUSTOM.replace('y = {expr = "h2"', f'y = {{expr = "{nested("exp", 10)}"'),
                             "plant.outputs.y", "too complex for symbolic analysis"),
    # item 8: option values that reached numpy unvalidated
    "ragged_reference_gain": (fault_design('name = "c"\nmethod = "canonical_observer"\n'
                                           'poles = [-5.0, -8.0, -10.0]\n'
                                           'reference_gain = [[1.0], [2.0, 3.0], [4.0]]\n'),
                              "design[0].reference_gain", "different lengths"),
    "string_reference_gain": (fault_design('name = "c"\nmethod = "canonical_observer"\n'
                                           'poles = [-5.0, -8.0, -10.0]\nreference_gain = "abc"\n'),
                              "design[0].reference_gain", "got str"),
    "substeps_10_400": (fault_design('name = "e"\n' + EKF + "substeps = 1" + "0" * 400 + "\n"),
                        "design[0].substeps", "401 digits"),
    "seed_negative": (fault_design('name = "n"\nmethod = "narx"\nQ = 1e-9\nR = 1e-6\nP0 = 1e-3\n'
                                   "seed = -1\n"), "design[0].seed", ">= 0"),
    "seed_beyond_64_bits": (fault_design('name = "n"\nmethod = "narx"\nQ = 1e-9\nR = 1e-6\nP0 = 1e-3\n'
                                         f"seed = {2 ** 70}\n"), "design[0].seed", "64 bits"),
    "covariance_1e308": (fault_design('name = "e"\nmethod = "ekf"\nQ = 1e308\nR = 1e-6\nP0 = 1e-3\n'),
                         "design[0].Q", "at most 1e+100"),
    "ts_observer_on_linear_plant": (fault_design('name = "t"\nmethod = "ts_observer"\n'),
                                    "design[0].method", "linear in its states"),
    "horizon_inf": ((EXAMPLES / "seed002_inverse_dynamics.toml").read_text(encoding="utf-8")
                    .replace("horizon = 300.0", "horizon = inf"),
                    "design[0].horizon", "finite"),
    # item 4: sizes with a ceiling, and the memory estimate before allocation
    "narx_memory": (fault_design('name = "n"\nmethod = "narx"\nQ = 1e-9\nR = 1e-6\nP0 = 1e-3\n'
                                 "steps = 1000000\nruns = 1000\n"), "design[0].steps", "GiB of memory"),
    "ts_samples_ceiling": ((EXAMPLES / "seed001_ts_observer.toml").read_text(encoding="utf-8")
                           .replace('method = "ts_observer"', 'method = "ts_observer"\nsamples = 1000000000', 1),
                           "design[0].samples", "10000000"),
    # issue 16: did you mean
    "method_misspelt": (CUSTOM.replace('method = "linearize"', 'method = "linearise"'),
                        "design[0].method", "did you mean 'linearize'"),
    "plant_family_misspelt": ((EXAMPLES / "seed000_three_tank.toml").read_text(encoding="utf-8")
                              .replace('model = "three_tank"', 'model = "three_tanks"'),
                              "plant.model", "did you mean 'three_tank'"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_crash_input_is_exit_2_naming_the_key(case, tmp_path):
    text, key, match = CASES[case]
    spec = tmp_path / f"{case}.toml"
    spec.write_text(text, encoding="utf-8")
    code, _, err, seconds = run(["check", "--spec-only", spec])
    assert_contract(code, err, seconds, case)
    assert code == 2, err
    # refused by the spec checks and the static expression limits, never by running into the
    # symbolic time budget; the time of each case (< 10 s) is a floor of benchmarks/limits.py
    assert "did not finish within" not in err, err
    assert err.startswith(f"error: {spec}: "), err  # the file first ...
    if key is not None:
        assert f"key '{key}'" in err, err          # ... then the key
    assert match in err, err


def test_did_you_mean_does_not_list_everything_when_a_name_is_close(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(CUSTOM.replace('method = "linearize"', 'method = "pole_placment"'), encoding="utf-8")
    code, _, err, _ = run(["check", "--spec-only", spec])
    assert code == 2 and "did you mean 'pole_placement'" in err and "expected one of" not in err, err
    spec.write_text(CUSTOM.replace('method = "linearize"', 'method = "zzzz"'), encoding="utf-8")
    code, _, err, _ = run(["check", "--spec-only", spec])
    assert code == 2 and "expected one of" in err and "ekf" in err, err  # no close match: the list


def test_numbers_in_errors_are_cut(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(fault_design('name = "e"\n' + EKF + 'substeps = "' + "x" * 5000 + '"\n'), encoding="utf-8")
    code, _, err, _ = run(["check", "--spec-only", spec])
    assert code == 2 and len(err) < 400 and "..." in err, err


@pytest.mark.slow
def test_symbolic_step_past_its_budget_is_a_skipped_check(tmp_path, monkeypatch):
    """A polynomial output of degree 64 passes the parse limits; its determinant is refused by the
    time budget and reported as not attempted, not a hang."""
    monkeypatch.setenv("TANKSYNTH_SYMBOLIC_SECONDS", "2")
    spec = tmp_path / "s.toml"
    spec.write_text(CUSTOM.replace('y = {expr = "h2"', 'y = {expr = "(h1+h2+1)**64"'), encoding="utf-8")
    code, out, err, seconds = run(["check", "--json", spec])
    assert_contract(code, err, seconds)
    checks = {c["check"]: c for c in json.loads(out)}
    sym = checks["symbolic_observability"]
    assert sym["passed"] is None and "too complex for symbolic analysis" in sym["detail"], sym
    assert "did not finish within 2 s" in sym["detail"], sym     # cut off by the budget set
    assert seconds < 60                 # and not long after it (30x the budget: a loaded machine)


@pytest.mark.parametrize("name", ["inv-dyn", "it--2", "jac"])
def test_design_names_casadi_rejects_become_valid_law_names(name):
    """`rename_law` (the exported law of every controller) maps any design name to a CasADi name."""
    from tanksynth.runtime.laws import rename_law

    x = ca.SX.sym("x")
    law = rename_law(ca.Function("f", [x], [2 * x]), name)
    assert float(law(3.0)) == 6.0
    assert law.name() not in ("jac", "hess", "null") and "__" not in law.name()


def test_inverse_dynamics_law_accepts_any_design_name():
    from tanksynth.methods import load_spec
    from tanksynth.runtime.laws import inverse_dynamics_law

    spec = load_spec(EXAMPLES / "seed002_inverse_dynamics.toml")
    for name in ("inv-dyn", "it--2", "jac"):
        law = inverse_dynamics_law(spec.plant, [0.5] * spec.plant.m, name=name)
        assert law is not None


# ------------------------------------------------------------------ OS errors (item 8)
def test_unwritable_output_directory_is_exit_2_naming_it(tmp_path):
    out = "/proc/tanksynth-cannot-write-here"  # read-only even for root
    code, _, err, seconds = run(["design", EXAMPLES / "custom_two_tank.toml", "-o", out])
    assert_contract(code, err, seconds)
    assert code == 2 and out in err, err


def test_output_under_a_file_is_exit_2(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, _, err, seconds = run(["design", EXAMPLES / "custom_two_tank.toml", "-o", blocker / "out"])
    assert_contract(code, err, seconds)
    assert code == 2 and str(blocker) in err, err


@pytest.mark.parametrize("command", ["verify", "report"])
def test_missing_result_directory_is_exit_2(tmp_path, command):
    code, _, err, seconds = run([command, tmp_path / "missing"])
    assert_contract(code, err, seconds)
    assert code == 2 and "missing" in err, err


@pytest.mark.slow
def test_file_size_limit_is_exit_2_not_a_signal(tmp_path):
    """``ulimit -f``: the write fails with EFBIG (SIGXFSZ ignored), one line naming the file."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (1024, 1024))

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-m", "tanksynth.cli", "design", str(EXAMPLES / "custom_two_tank.toml"),
                           "-o", str(tmp_path / "out")], capture_output=True, text=True, env=env,
                          preexec_fn=limit, timeout=300)
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert len(proc.stderr.strip().splitlines()) == 1 and "File too large" in proc.stderr, proc.stderr


# ------------------------------------------------------------ consistency (item 10)
def test_second_run_on_a_locked_directory_says_who_holds_it(result_dir, tmp_path):
    import shutil

    d = tmp_path / "d"
    shutil.copytree(result_dir, d)
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])   # killed below
    try:
        (d / ".tanksynth.lock").write_text(json.dumps({"pid": holder.pid, "host": socket.gethostname(),
                                                       "command": "design", "started": "2026-12-01T10:00"}))
        code, _, err, _ = run(["verify", d, "--json"])
        assert code == 2 and f"pid {holder.pid}" in err and socket.gethostname() in err \
            and "2026-12-01T10:00" in err, err
    finally:
        holder.kill()
        holder.wait()
    # the holder is dead now: its lock is stale and taken over
    code, _, err, _ = run(["verify", d, "--json"])
    assert code == 0, err
    assert not (d / ".tanksynth.lock").exists()


def test_design_refuses_a_directory_of_another_spec_unless_forced(tmp_path):
    out = tmp_path / "out"
    code, _, err, _ = run(["design", EXAMPLES / "custom_two_tank.toml", "-o", out])
    assert code == 0, err
    other = tmp_path / "other.toml"
    other.write_text(CUSTOM.replace('name = "cascade_linear_model"', 'name = "other_model"')
                     .replace("Custom two-tank cascade", "another spec"), encoding="utf-8")
    code, _, err, _ = run(["design", other, "-o", out])
    assert code == 2 and "another spec" in err and "--force" in err, err
    assert (out / "cascade_linear_model.json").exists()
    code, _, err, _ = run(["design", other, "-o", out, "--force"])
    assert code == 0, err
    assert not (out / "cascade_linear_model.json").exists() and not (out / "cascade_linear_model.npz").exists()
    code, _, err, _ = run(["verify", out, "--json"])
    assert code == 0, err
    # the same spec again needs no --force
    code, _, err, _ = run(["design", other, "-o", out])
    assert code == 0, err


@pytest.mark.slow
def test_verify_and_report_keep_file_modes_and_new_files_share_one(result_dir, tmp_path):
    import shutil
    import stat

    d = tmp_path / "d"
    shutil.copytree(result_dir, d)
    art = d / "cascade_linear_model.json"
    os.chmod(art, 0o640)
    code, _, err, _ = run(["verify", d, "--json"])
    assert code == 0, err
    assert stat.S_IMODE(art.stat().st_mode) == 0o640
    code, _, err, _ = run(["report", d])
    assert code == 0, err
    assert stat.S_IMODE(art.stat().st_mode) == 0o640
    umask = os.umask(0o022)
    os.umask(umask)
    fresh = tmp_path / "fresh"
    code, _, err, _ = run(["design", EXAMPLES / "custom_two_tank.toml", "-o", fresh])
    assert code == 0, err
    modes = {p.name: stat.S_IMODE(p.stat().st_mode) for p in fresh.iterdir() if p.is_file()}
    assert set(modes.values()) == {0o666 & ~umask}, modes


def test_new_npz_beside_old_json_is_detected(result_dir, tmp_path):
    """A kill between the NPZ rename and the JSON rename leaves a new NPZ with the old JSON:
    the NPZ is renamed first and the JSON holds its hash, so verify refuses the pair."""
    import shutil

    import numpy as np

    d = tmp_path / "d"
    shutil.copytree(result_dir, d)
    npz = d / "cascade_linear_model.npz"
    with np.load(npz) as data:
        gains = {k: data[k] * 1.01 for k in data.files}
    np.savez(npz, **gains)
    code, _, err, _ = run(["verify", d, "--json"])
    assert code == 2 and "cascade_linear_model.npz" in err, err


def test_a_fifo_or_device_in_a_result_directory_does_not_hang(result_dir, tmp_path):
    import shutil

    d = tmp_path / "d"
    shutil.copytree(result_dir, d)
    (d / "plant.json").unlink()
    os.mkfifo(d / "plant.json")
    t0 = time.perf_counter()
    code, _, err, _ = run(["verify", d, "--json"])
    # not a hang (a blocking open never returns): a bound generous for a loaded machine; the
    # time itself (< 10 s) is a floor of benchmarks/limits.py
    assert code == 2 and "plant.json" in err and time.perf_counter() - t0 < 60, err
    (d / "plant.json").unlink()
    (d / "plant.json").symlink_to("/dev/zero")
    code, _, err, _ = run(["verify", d, "--json"])
    assert code == 2 and "not a regular file" in err, err


def test_a_fifo_as_the_lock_file_does_not_hang(result_dir, tmp_path):
    import shutil

    d = tmp_path / "d"
    shutil.copytree(result_dir, d)
    os.mkfifo(d / ".tanksynth.lock")
    t0 = time.perf_counter()
    code, _, err, _ = run(["verify", d, "--json"])
    # not a hang, as above (the time itself: benchmarks/limits.py)
    assert code == 2 and ".tanksynth.lock" in err and time.perf_counter() - t0 < 60, err


# ---------------------------------------------- lock holders that are not a process (item 10)
@pytest.mark.parametrize("pid", [99999999999999999999, 2 ** 31, 0, -5, True, "123", None, 1.5])
def test_a_lock_naming_no_valid_pid_is_unreadable_never_a_crash(result_dir, tmp_path, pid):
    """A pid that cannot be a process is refused as an unreadable lock (exit 2, naming it),
    never taken over (pid <= 0 included) and never exit 4 (OverflowError in os.kill)."""
    import shutil

    d = tmp_path / "d"
    shutil.copytree(result_dir, d)
    lock = d / ".tanksynth.lock"
    lock.write_text(json.dumps({"pid": pid, "host": socket.gethostname(), "command": "design",
                                "started": "2026-12-01T10:00"}))
    code, _, err, seconds = run(["verify", d, "--json"])
    assert_contract(code, err, seconds)
    assert code == 2 and "unreadable lock file" in err and str(lock) in err and "remove it" in err, err
    assert lock.exists()  # not taken over


def test_an_old_empty_lock_is_unreadable(result_dir, tmp_path):
    import shutil

    d = tmp_path / "d"
    shutil.copytree(result_dir, d)
    lock = d / ".tanksynth.lock"
    lock.write_text("")
    os.utime(lock, (time.time() - 60, time.time() - 60))
    code, _, err, seconds = run(["verify", d, "--json"])
    assert_contract(code, err, seconds)
    assert code == 2 and "unreadable lock file" in err, err


def test_verify_refuses_a_malformed_checks_json(result_dir, tmp_path):
    import shutil

    d = tmp_path / "d"
    shutil.copytree(result_dir, d)
    (d / "checks.json").write_text('[{"check": ', encoding="utf-8")
    code, _, err, seconds = run(["verify", d, "--json"])
    assert_contract(code, err, seconds)
    assert code == 2 and "checks.json" in err, err
