"""Interruption (issue 31, items 4 and 7): SIGINT, SIGTERM and SIGHUP end every command the same way
(exit 130, one line on stderr, the lock released, nothing partial) and no child process of the
command outlives it or writes into the result directory after it, even when it is SIGKILLed.

Signals are sent with ``os.kill`` to a real ``tanksynth`` process. LaTeX is replaced by a stand-in
``latexmk`` that says it started and then sleeps: the interruption lands while the report worker
waits for LaTeX, every time. Each process started is marked by an environment variable, so the test
finds the command's children (``/proc/<pid>/environ``) whoever their parent became.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from tanksynth.cli import main

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "examples" / "seed000_pole_placement.toml"

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="/proc and PR_SET_PDEATHSIG: Linux only")

#: Hang guard of every wait (s): generous for a loaded machine, never a timing assertion.
GUARD = 300
#: Hang guard for the children of a SIGKILLed command to end (s; see its test).
ORPHAN_GUARD = 120


def _marked(mark: str) -> list[int]:
    """Live (not zombie) processes whose environment holds ``mark``."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            env = Path(f"/proc/{entry}/environ").read_bytes()
            state = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if mark.encode() in env and state not in ("Z", "X"):
            found.append(int(entry))
    return found


def _kill_marked(mark: str) -> None:
    for pid in _marked(mark):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _fake_tex(bin_dir: Path) -> None:
    """``latexmk`` that touches ``$TANKSYNTH_TEST_LATEX_STARTED`` and sleeps; a ``pdflatex``."""
    bin_dir.mkdir()
    (bin_dir / "latexmk").write_text('#!/bin/sh\ntouch "$TANKSYNTH_TEST_LATEX_STARTED"\nexec sleep 600\n')
    (bin_dir / "pdflatex").write_text("#!/bin/sh\nexit 1\n")
    for tool in ("latexmk", "pdflatex"):
        (bin_dir / tool).chmod(0o755)


def _start(args: list[str], tmp_path: Path, mark: str, **env: str) -> subprocess.Popen:
    environ = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONUNBUFFERED": "1",
               "TANKSYNTH_TEST_MARK": mark, "TANKSYNTH_REPORT_WORKER": "1", **env}
    return subprocess.Popen([sys.executable, "-m", "tanksynth", *args], env=environ, cwd=tmp_path,
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def _wait_for(path: Path, proc: subprocess.Popen) -> None:
    deadline = time.monotonic() + GUARD
    while not path.exists():
        assert proc.poll() is None, f"ended before LaTeX started: {proc.communicate()}"
        assert time.monotonic() < deadline, "LaTeX never started"
        time.sleep(0.1)


def _leftovers(out: Path) -> list[str]:
    return sorted(p.name for p in [*out.glob(".*"), *out.glob("*/.*")]
                  if p.name.endswith(".tmp") or p.name.startswith((".report-build-", ".tanksynth.lock")))


def _run_pdf_until_latex(tmp_path: Path, mark: str) -> tuple[subprocess.Popen, Path]:
    _fake_tex(tmp_path / "bin")
    started = tmp_path / "latex-started"
    out = tmp_path / "out"
    proc = _start(["run", str(SPEC), "--pdf", "-o", str(out)], tmp_path, mark,
                  PATH=f"{tmp_path / 'bin'}{os.pathsep}{os.environ['PATH']}",
                  TANKSYNTH_TEST_LATEX_STARTED=str(started))
    _wait_for(started, proc)   # the report worker is now waiting for LaTeX
    return proc, out


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_signal_during_run_pdf_ends_the_report_worker_and_latex(tmp_path, signum):
    mark = uuid.uuid4().hex
    proc, out = _run_pdf_until_latex(tmp_path, mark)
    try:
        os.kill(proc.pid, signum)
        _, err = proc.communicate(timeout=GUARD)  # a worker holding stderr would hang this
        alive = _marked(mark)
    finally:
        proc.kill()
        _kill_marked(mark)
    assert proc.returncode == 130, err
    assert err.strip().splitlines() == [err.strip()] and err.startswith(
        f"interrupted ({signal.Signals(signum).name})"), err
    assert alive == [], "children of the command outlived it"
    assert not (out / "report.pdf").exists()
    assert _leftovers(out) == []   # no lock, no staged file, no LaTeX build directory


@pytest.mark.slow
def test_the_report_worker_dies_with_a_sigkilled_parent(tmp_path):
    mark = uuid.uuid4().hex
    proc, out = _run_pdf_until_latex(tmp_path, mark)
    try:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=GUARD)        # not communicate: an orphaned worker holds the pipes
        # hang guard, generous, yet below the report's LaTeX timeout (180 s), after which an
        # orphaned worker would give up by itself and hide the bug
        deadline = time.monotonic() + ORPHAN_GUARD
        while _marked(mark) and time.monotonic() < deadline:  # the worker unwinds, then exits
            time.sleep(0.1)
        alive = _marked(mark)
    finally:
        _kill_marked(mark)
    assert proc.returncode == -signal.SIGKILL
    assert alive == [], "the report worker (or LaTeX) outlived its SIGKILLed parent"
    assert not (out / "report.pdf").exists()
    assert not [p for p in out.glob(".report-build-*")]


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_design_is_exit_130_and_one_line(tmp_path, signum):
    mark = uuid.uuid4().hex
    out = tmp_path / "out"
    proc = _start(["design", str(ROOT / "examples" / "three_tank_robust.toml"), "-o", str(out)],
                  tmp_path, mark)
    try:
        assert proc.stdout is not None
        for line in proc.stdout:       # the first design is being computed
            if line.startswith("- designing"):
                break
        os.kill(proc.pid, signum)
        _, err = proc.communicate(timeout=GUARD)
    finally:
        proc.kill()
        _kill_marked(mark)
    assert proc.returncode == 130, err
    assert len(err.strip().splitlines()) == 1 and err.startswith(
        f"interrupted ({signal.Signals(signum).name})"), err
    assert not out.exists() or _leftovers(out) == []


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "-1", "0"])
def test_a_non_finite_or_negative_connect_timeout_is_bad_input(tmp_path, capsys, value):
    code = main(["verify", str(tmp_path), "--connect-timeout", value])
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "--connect-timeout" in err, err


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_during_the_fits_ipopt_solve_stops_it(tmp_path, signum):
    """IPOPT calls the fit's derivatives as Python callbacks and CasADi swallows their
    exceptions: the interruption must still stop the solve and the remaining starts (exit 130,
    one line, no fit.json, no data copies, no lock), not run the fit to its end (exit 0)."""
    mark = uuid.uuid4().hex
    example = ROOT / "examples" / "three_tank_fit.toml"
    csv = (ROOT / "examples" / "data" / "three_tank_estimation.csv").read_text()
    names = []
    for i in range(6):     # six logs, eight starts: a fit of tens of seconds
        (tmp_path / f"log{i}.csv").write_text(csv)
        names.append(f"log{i}.csv")
    text = example.read_text()
    text = text.replace('data = ["data/three_tank_estimation.csv"]', f"data = {names!r}".replace("'", '"'))
    text = text.replace('validate = ["data/three_tank_validation.csv"]', "").replace("starts = 4", "starts = 8")
    spec = tmp_path / "fit.toml"
    spec.write_text(text)
    out = tmp_path / "out"
    proc = _start(["fit", str(spec), "-o", str(out)], tmp_path, mark)
    try:
        assert proc.stdout is not None
        for line in proc.stdout:       # the fit is being computed
            if line.startswith("- designing"):
                break
        time.sleep(2.0)                # into IPOPT's iterations
        os.kill(proc.pid, signum)
        sent = time.monotonic()
        _, err = proc.communicate(timeout=GUARD)
        took = time.monotonic() - sent
    finally:
        proc.kill()
        _kill_marked(mark)
    assert proc.returncode == 130, err
    assert len(err.strip().splitlines()) == 1 and err.startswith(
        f"interrupted ({signal.Signals(signum).name})"), err
    assert not (out / "fit.json").exists() and not (out / "data").exists()
    assert _leftovers(out) == []
    assert took < 60, f"the fit took {took:.0f} s to stop"   # hang guard (it stops within ~1 s)
