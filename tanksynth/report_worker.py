"""The report stage of ``tanksynth run`` in a process forked before the design (issue 15).

The report needs matplotlib, jinja2 and the report modules (about 0.5-0.6 s of
imports), but only the files that design and verification write. So ``run``
forks a worker right after reading the spec: the worker imports the report
stack on the second core while the parent checks, designs and verifies, then
waits; when told to, it writes the report from the directory and sends back a
short summary. The report is the same as the one written in-process (it is
the same function reading the same files).

Two steps of the report are drawn ahead or in parallel (the figures are
most of its time): told that the designs are written (`ReportWorker.designed`),
the worker draws the eigenvalue maps while the parent verifies (they read
only the design artefacts); told to go, it forks once more and the two
processes share the figures that need the verification (time-domain figures,
largest trace first, then certified regions and linear analyses: every other
job each), so that none of them is left to one process after the other's
are done.

The worker is used only where forking is safe and cheap: Linux, a process
with no other thread running (a pytest-xdist worker or a notebook kernel has
some: the report is then written in-process), and unless
``TANKSYNTH_REPORT_WORKER=0``. Whatever goes wrong in the worker (it dies,
raises, sends nothing), the parent writes the report itself, so errors
surface exactly as without a worker.

The worker leads a process group of its own and dies with its parent (issue 31): a parent that
is interrupted ends the group (`ReportWorker.stop`: SIGTERM, then SIGKILL) and reaps it before it
releases the directory's lock; a parent that dies without a word (SIGKILL) sends the worker
SIGTERM all the same (`tanksynth.process.die_with_parent`). Either way the worker unwinds (its
LaTeX group ended, its staged files removed) and writes nothing into the directory after.
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterator

from tanksynth.process import die_with_parent, end_process_group

if TYPE_CHECKING:  # the report stack loads in the worker (or in write_report), not on import
    from tanksynth.reports.inputs import ReportInputs
    from tanksynth.reports.writer import ReportResult

__all__ = ["ReportSummary", "ReportWorker", "report_summary", "worker_usable"]


@dataclass(frozen=True)
class ReportSummary:
    """What ``run`` prints about a written report.

    Attributes
    ----------
    tex : Path
        The LaTeX source written.
    pdf : Path or None
        The PDF, when compiled.
    pages : int or None
        Pages of the PDF.
    latex_seconds : float
        Wall time of the LaTeX compilation (s); 0 without a PDF.
    errata : tuple of (str, int)
        Per paper comparison: its title and how many printed values differ
        from the derivation.
    """

    tex: Path
    pdf: Path | None
    pages: int | None
    latex_seconds: float
    errata: tuple[tuple[str, int], ...]


def report_summary(result: ReportResult) -> ReportSummary:
    """The summary of a `tanksynth.reports.writer.ReportResult`.

    Parameters
    ----------
    result : ReportResult

    Returns
    -------
    ReportSummary
    """
    return ReportSummary(Path(result.tex), None if result.pdf is None else Path(result.pdf),
                         result.pages, float(result.latex_seconds or 0.0),
                         tuple((str(c.title), len(c.errata)) for c in result.comparisons if c.errata))


def worker_usable() -> bool:
    """True where the report may be written by a forked worker (see the module docstring)."""
    return (sys.platform.startswith("linux") and hasattr(os, "fork")
            and os.environ.get("TANKSYNTH_REPORT_WORKER", "1") != "0"
            and threading.active_count() == 1)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def _read_all(fd: int) -> bytes:
    chunks: list[bytes] = []
    while True:
        chunk = os.read(fd, 1 << 16)
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)


class ReportWorker:
    """A forked process that writes the report of a result directory when told to.

    Use `start` (None where a worker is not usable), optionally `designed`,
    then exactly one of `finish` (write the report, get its summary),
    `cancel` (let it go) or `stop` (end it now: an interruption).

    Parameters
    ----------
    pid : int
        The worker's process id.
    go : int
        Write end of the pipe that tells the worker to start.
    result : int
        Read end of the pipe the worker answers on.
    """

    def __init__(self, pid: int, go: int, result: int):
        self._pid, self._go, self._result = pid, go, result
        self._done = False

    @classmethod
    def start(cls, directory: Path, pdf: bool) -> "ReportWorker | None":
        """Fork the worker (after importing the modules both processes need, `_SHARED`); it
        imports the report stack and waits.

        Parameters
        ----------
        directory : Path
            The result directory the report will be written from.
        pdf : bool
            Compile the PDF too.

        Returns
        -------
        ReportWorker or None
            None where forking is not usable (`worker_usable`).
        """
        if not worker_usable():
            return None
        for module in _SHARED:   # before the fork: imported once, not in both processes
            __import__(module)
        go_r, go_w = os.pipe()
        res_r, res_w = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        parent = os.getpid()
        pid = os.fork()
        if pid == 0:  # the worker: never returns
            try:
                die_with_parent(parent)
                os.close(go_w)
                os.close(res_r)
                _serve(Path(directory), bool(pdf), go_r, res_w)
            finally:
                os._exit(0)
        try:
            os.setpgid(pid, pid)  # also here: the group exists before `stop` may signal it
        except OSError:
            pass
        os.close(go_r)
        os.close(res_w)
        return cls(pid, go_w, res_r)

    def designed(self) -> None:
        """Tell the worker the design artefacts are written: it draws their eigenvalue maps
        meanwhile (nothing once `finish` or `cancel` ran)."""
        if not self._done:
            try:
                _write_all(self._go, _DESIGNED)
            except OSError:
                pass

    def finish(self) -> ReportSummary | None:
        """Tell the worker to write the report; its summary, or None if it did not manage
        (the caller then writes the report itself)."""
        self._done = True
        try:
            _write_all(self._go, _GO)
        except OSError:
            pass
        os.close(self._go)
        try:
            data = _read_all(self._result)
        except BaseException:  # interrupted while the worker writes: end it, nothing after
            os.close(self._result)
            end_process_group(self._pid)
            raise
        os.close(self._result)
        self._reap()
        try:
            status, payload = pickle.loads(data)
        except Exception:  # noqa: BLE001 - nothing or garbage: the worker died
            return None
        return payload if status == "ok" and isinstance(payload, ReportSummary) else None

    def cancel(self) -> None:
        """Let the worker go without writing anything (nothing once `finish` ran)."""
        if self._done:
            return
        self._done = True
        os.close(self._go)
        os.close(self._result)
        self._reap()

    def stop(self) -> None:
        """End the worker now (its process group: SIGTERM, then SIGKILL) and reap it; bounded
        (about 10 s at most). Nothing once `finish` or `cancel` ran."""
        if self._done:
            return
        self._done = True
        os.close(self._go)
        os.close(self._result)
        end_process_group(self._pid)

    def _reap(self) -> None:
        try:
            os.waitpid(self._pid, 0)
        except ChildProcessError:
            pass


#: What the report imports (lazily, inside its functions): imported by the worker up front.
_REPORT_STACK = ("tanksynth.reports.writer", "tanksynth.reports.figures", "tanksynth.reports.context",
                 "jinja2", "matplotlib.figure", "matplotlib.backends.backend_pdf",
                 "matplotlib.collections", "matplotlib.lines", "matplotlib.patches",
                 "matplotlib.ticker", "matplotlib.textpath", "matplotlib.transforms",
                 "matplotlib.font_manager")


#: What the report stack imports and ``run`` imports anyway (rank checks, verification: scipy.linalg,
#: scipy.optimize, the simulator): imported by `ReportWorker.start` before it forks, so that the
#: two processes do not both import them (0.4-0.5 s of CPU each run, which competes with the
#: parent's on a loaded machine; issue 29).
_SHARED = ("tanksynth.analysis.checks", "tanksynth.verify.runner", "tanksynth.verify.common",
           "tanksynth.sim.simulate")


#: Messages on the "go" pipe, one line each.
_DESIGNED, _GO = b"designed\n", b"go\n"


def _messages(fd: int) -> Iterator[bytes]:
    """The lines the parent sends, until it closes the pipe."""
    pending = b""
    while True:
        chunk = os.read(fd, 1 << 12)
        if not chunk:
            return
        pending += chunk
        while b"\n" in pending:
            line, pending = pending.split(b"\n", 1)
            yield line + b"\n"


def _serve(directory: Path, pdf: bool, go: int, result: int) -> None:
    """The worker's life: import, draw what it is told it can, write the report on "go",
    send the summary."""
    try:
        from tanksynth.methods import write_report

        for module in _REPORT_STACK:
            __import__(module)
        from matplotlib.font_manager import FontProperties, findfont

        findfont(FontProperties())  # the font cache, read once
    except Exception:  # noqa: BLE001 - the parent writes the report itself
        return
    drawn: dict[str, Any] = {}
    for message in _messages(go):
        if message == _DESIGNED:
            drawn.update(_ahead(_pole_maps, directory))
        elif message == _GO:
            break
    else:
        return  # cancelled
    drawn.update(_ahead(_figures_in_two, directory))
    try:
        payload: tuple[str, Any] = ("ok", report_summary(write_report(directory, pdf=pdf, drawn=drawn)))
    except BaseException as exc:  # noqa: BLE001 - reported by the parent's own attempt
        payload = ("failed", f"{type(exc).__name__}: {exc}")
    try:
        _write_all(result, pickle.dumps(payload))
    except OSError:
        pass


def _ahead(draw: Callable[[ReportInputs], dict[str, Any]], directory: Path) -> dict[str, Any]:
    """Figures drawn ahead of `write_report`; none when anything fails (`write_report` then
    draws them, or raises what is wrong)."""
    from tanksynth.reports.inputs import read_report_inputs

    try:
        return draw(read_report_inputs(directory))
    except Exception:  # noqa: BLE001
        return {}


def _pole_maps(inputs: ReportInputs) -> dict[str, Any]:
    from tanksynth.reports.writer import draw_pole_maps

    return draw_pole_maps(inputs)


def _figures_in_two(inputs: ReportInputs) -> dict[str, Any]:
    """Every figure that needs the verification (time-domain, certified-region, linear analysis;
    `tanksynth.reports.writer.figure_jobs`), every other job drawn in a forked process."""
    from tanksynth.reports.writer import draw_figure_jobs, figure_jobs

    jobs = figure_jobs(inputs)
    if len(jobs) < 2 or threading.active_count() != 1:
        return draw_figure_jobs(inputs, jobs)
    theirs, mine = jobs[0::2], jobs[1::2]  # the largest trace to the helper: this one renders after
    if any(kind == "linear" for kind, _ in jobs):
        __import__("control")  # the linear analyses' python-control (~0.5 s): once, before the fork
    read, write = os.pipe()
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:
        try:
            die_with_parent(parent, own_group=False)  # in the worker's group: ended with it
            os.close(read)
            _write_all(write, pickle.dumps(draw_figure_jobs(inputs, theirs)))
        finally:
            os._exit(0)
    os.close(write)
    try:
        out = draw_figure_jobs(inputs, mine)
        data = _read_all(read)
    except BaseException:  # interrupted: the helper stops drawing too (it unwinds, see start)
        os.kill(pid, signal.SIGTERM)
        raise
    finally:
        os.close(read)
        os.waitpid(pid, 0)
    try:
        helped = pickle.loads(data)
    except Exception:  # noqa: BLE001 - the helper died: its figures are drawn by write_report
        helped = {}
    return {**out, **(helped if isinstance(helped, dict) else {})}
