"""`tanksynth run` writes the report in a forked worker (issue 15): the same files as in-process,
and a worker that fails or is cancelled changes nothing."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CLI = str(Path(sys.executable).with_name("tanksynth"))

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork worker: Linux only")


def _run(tmp: Path, worker: str) -> Path:
    out = tmp / f"worker{worker}" / "out"   # same directory name: the report names it
    env = dict(os.environ, TANKSYNTH_REPORT_WORKER=worker)
    proc = subprocess.run([CLI, "run", str(ROOT / "examples" / "tank_network_n8.toml"), "-o", str(out)],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "times:" in proc.stdout and "report:" in proc.stdout
    return out


def _digests(directory: Path) -> dict[str, str]:
    files = [directory / "report.tex", *sorted((directory / "report-figures").glob("*"))]
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def test_report_by_the_worker_is_the_in_process_report(tmp_path):
    by_worker, in_process = _run(tmp_path, "1"), _run(tmp_path, "0")
    a, b = _digests(by_worker), _digests(in_process)
    assert len(a) > 1 and a == b


SCRIPT = """
import os, signal, sys, threading
from pathlib import Path
from tanksynth.report_worker import ReportWorker, worker_usable
d = Path(sys.argv[1]); what = sys.argv[2]
if what == "thread":
    threading.Thread(target=threading.Event().wait, daemon=True).start()
    print(worker_usable(), ReportWorker.start(d, False))
    sys.exit(0)
w = ReportWorker.start(d, False)
assert w is not None
if what == "kill":
    os.kill(w._pid, signal.SIGKILL)
    print(w.finish())
elif what == "cancel":
    w.cancel(); w.cancel()
    print("cancelled", (d / "report.tex").exists())
elif what == "empty":
    print(w.finish())
"""


@pytest.mark.parametrize("what, expected", [
    ("kill", "None"),                 # the worker died: finish says so; run writes the report itself
    ("cancel", "cancelled False"),    # cancelled (twice): nothing written
    ("thread", "False None"),         # another thread running: no fork
    ("empty", "None"),                # a directory without artefacts: the report fails in the worker
])
def test_worker_failure_or_cancel_leaves_the_report_to_the_parent(tmp_path, what, expected):
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path), what], capture_output=True,
                          text=True, timeout=300, env=dict(os.environ, TANKSYNTH_REPORT_WORKER="1"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == expected


def test_worker_can_be_switched_off(monkeypatch):
    from tanksynth.report_worker import worker_usable

    monkeypatch.setenv("TANKSYNTH_REPORT_WORKER", "0")
    assert worker_usable() is False
