"""`tanksynth run` writes the report in a forked worker (issue 15): the same files as in-process
(eigenvalue maps drawn while verification runs, time-domain figures drawn by two processes), and a
worker that fails or is cancelled changes nothing."""

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


#: Five designs with eigenvalue maps and time-domain figures of different sizes.
EXAMPLE = ROOT / "examples" / "seed004_fault_detection.toml"
#: Five designs whose verdicts store an extra trace each (the disturbance step): two figures each.
EXTRAS = ROOT / "examples" / "three_tank_hinf.toml"


def _run(tmp: Path, worker: str, example: Path = EXAMPLE) -> Path:
    out = tmp / f"worker{worker}" / "out"   # same directory name: the report names it
    env = dict(os.environ, TANKSYNTH_REPORT_WORKER=worker)
    proc = subprocess.run([CLI, "run", str(example), "-o", str(out)],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "times:" in proc.stdout and "report:" in proc.stdout
    return out


def _digests(directory: Path) -> dict[str, str]:
    files = [directory / "report.tex", *sorted((directory / "report-figures").glob("*"))]
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


@pytest.mark.slow
def test_report_by_the_worker_is_the_in_process_report(tmp_path):
    by_worker, in_process = _run(tmp_path, "1"), _run(tmp_path, "0")
    a, b = _digests(by_worker), _digests(in_process)
    assert sum(k.startswith("traces-") for k in a) >= 4 and sum(k.startswith("poles-") for k in a) >= 4
    assert a == b


@pytest.mark.slow
def test_extra_trace_figures_by_the_worker_are_the_in_process_ones(tmp_path):
    by_worker, in_process = _run(tmp_path, "1", EXTRAS), _run(tmp_path, "0", EXTRAS)
    a, b = _digests(by_worker), _digests(in_process)
    assert sum(k.startswith("traces-") and k.endswith("-1.pdf") for k in a) == 5
    assert sum(k.startswith("traces-") for k in a) == 10
    assert a == b


@pytest.mark.slow
def test_figures_drawn_ahead_are_used_and_the_rest_drawn(tmp_path):
    """`write_report(drawn=...)`: figures drawn ahead (all maps, half the traces) are taken as
    they are, the others drawn in place; the files are those of a report drawn all at once."""
    import shutil

    from tanksynth.methods import write_report
    from tanksynth.reports.context import draw_trace_figures, trace_jobs
    from tanksynth.reports.inputs import read_report_inputs
    from tanksynth.reports.writer import draw_pole_maps

    whole = _run(tmp_path, "0")
    ahead = tmp_path / "ahead" / "out"
    shutil.copytree(whole, ahead)
    shutil.rmtree(ahead / "report-figures")
    (ahead / "report.tex").unlink()
    inputs = read_report_inputs(ahead)
    jobs = trace_jobs(inputs)
    sizes = [(ahead / f"{inputs.artefacts[i]['name']}.traces.npz").stat().st_size for _, i in jobs]
    assert len(jobs) >= 4 and sizes == sorted(sizes, reverse=True)
    drawn = {**draw_pole_maps(inputs), **draw_trace_figures(inputs, [i for _, i in jobs[0::2]])}
    drawn_files = {p.name: p.stat().st_mtime_ns for p in (ahead / "report-figures").glob("*.pdf")}
    assert {f"{stem}.pdf" for stem, _ in jobs[1::2]}.isdisjoint(drawn_files)
    res = write_report(ahead, drawn=drawn)
    assert {name: (ahead / "report-figures" / name).stat().st_mtime_ns  # not drawn again
            for name in drawn_files} == drawn_files
    assert {p.name for p in res.figures} == {p.name for p in (whole / "report-figures").glob("*.pdf")}
    assert _digests(ahead) == _digests(whole)



@pytest.mark.slow
def test_figures_drawn_ahead_that_do_not_fit_are_drawn_again(tmp_path):
    """`write_report(drawn=...)` with entries that are not this directory's figures of those stems
    (another directory's, another artefact's, None for an artefact with eigenvalues, a wrong type):
    drawn again, the report is the one drawn all at once (no figure reused under a wrong name)."""
    import shutil

    from tanksynth.methods import write_report
    from tanksynth.reports.context import draw_trace_figures
    from tanksynth.reports.inputs import read_report_inputs
    from tanksynth.reports.writer import draw_pole_maps

    whole = _run(tmp_path, "0")
    want = _digests(whole)
    other = tmp_path / "other" / "out"
    shutil.copytree(whole, other)
    inputs = read_report_inputs(other)
    elsewhere = {**draw_pole_maps(inputs), **draw_trace_figures(inputs)}
    poles = sorted(k for k in elsewhere if k.startswith("poles-") and elsewhere[k] is not None)
    traces = sorted(k for k in elsewhere if k.startswith("traces-") and elsewhere[k] is not None)
    assert len(poles) >= 2 and len(traces) >= 2
    shutil.rmtree(whole / "report-figures")
    write_report(whole, drawn=elsewhere)                   # another directory's files
    assert _digests(whole) == want
    here = {**draw_pole_maps(read_report_inputs(whole)), **draw_trace_figures(read_report_inputs(whole))}
    wrong = {poles[0]: here[poles[1]], traces[0]: here[traces[1]],   # another artefact's figure
             poles[1]: None, traces[1]: None,                      # "no figure" where there is one
             poles[2] if len(poles) > 2 else "poles-99-x": "not a figure"}
    write_report(whole, drawn=wrong)
    assert _digests(whole) == want


#: Two TS PDC designs: a time-domain, a certified-region figure each and a linear analysis.
REGIONS = ROOT / "examples" / "three_tank_ts_control.toml"


@pytest.mark.slow
def test_region_and_linear_figures_shared_by_two_processes_are_the_in_process_ones(tmp_path):
    """Issue 29: the worker's two processes share every figure that needs the verification
    (`figure_jobs`: time-domain, certified region, linear analysis), not the time-domain ones
    only; `write_report(drawn=...)` takes the region figures and linear views drawn ahead as they
    are, draws the others, and redraws entries that are not this directory's of that stem."""
    import shutil

    from tanksynth.methods import write_report
    from tanksynth.reports.inputs import read_report_inputs
    from tanksynth.reports.writer import draw_figure_jobs, figure_jobs

    by_worker, whole = _run(tmp_path, "1", REGIONS), _run(tmp_path, "0", REGIONS)
    want = _digests(whole)
    assert _digests(by_worker) == want
    assert sum(k.startswith("region-") for k in want) == 2 and any(k.startswith("linear-") for k in want)
    ahead = tmp_path / "ahead" / "out"
    shutil.copytree(whole, ahead)
    shutil.rmtree(ahead / "report-figures")
    (ahead / "report.tex").unlink()
    inputs = read_report_inputs(ahead)
    jobs = figure_jobs(inputs)
    assert {kind for kind, _ in jobs} == {"traces", "region", "linear"}
    mine = [job for job in jobs if job[0] != "traces"]
    drawn = draw_figure_jobs(inputs, mine)
    assert {k.split("-")[0] for k in drawn} == {"region", "linear"}
    drawn_files = {p.name: p.stat().st_mtime_ns for p in (ahead / "report-figures").glob("*.pdf")}
    res = write_report(ahead, drawn=drawn)
    assert {name: (ahead / "report-figures" / name).stat().st_mtime_ns  # not drawn again
            for name in drawn_files} == drawn_files
    assert {p.name for p in res.figures} >= {n for n in drawn_files if n.startswith("linear-")}
    assert _digests(ahead) == want
    # another directory's views and figures, and a region figure under a linear stem: drawn again
    region = sorted(k for k in drawn if k.startswith("region-"))
    linear = sorted(k for k in drawn if k.startswith("linear-"))
    shutil.rmtree(whole / "report-figures")
    write_report(whole, drawn={**drawn, linear[0]: drawn[region[0]]})
    assert _digests(whole) == want



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


@pytest.mark.slow
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


SHARED_SCRIPT = """
import sys
from pathlib import Path
from tanksynth.report_worker import ReportWorker
shared = ("tanksynth.analysis.checks", "tanksynth.verify.runner", "scipy.optimize")
before = [m in sys.modules for m in shared]
w = ReportWorker.start(Path(sys.argv[1]), False)
print(before, [m in sys.modules for m in shared], w is not None)
w.cancel()
"""


@pytest.mark.slow
def test_modules_both_processes_need_are_imported_once_before_the_fork(tmp_path):
    """Issue 29: the report stack and the parent's rank checks and verification share scipy.linalg,
    scipy.optimize and the simulator: the parent imports them before it forks the worker, which
    inherits them instead of importing them a second time."""
    proc = subprocess.run([sys.executable, "-c", SHARED_SCRIPT, str(tmp_path)], capture_output=True,
                          text=True, timeout=300, env=dict(os.environ, TANKSYNTH_REPORT_WORKER="1"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "[False, False, False] [True, True, True] True"
