"""Compiling ``report.tex`` into a PDF with latexmk or pdflatex.

`compile_pdf` runs latexmk (or pdflatex directly when latexmk is missing)
in a scratch directory and checks the log for errors and undefined
references.
"""

from __future__ import annotations

import os
import signal
import re
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from tanksynth.errors import ReportError

__all__ = ["CompileResult", "compile_pdf", "find_latex", "pdf_page_count"]


@dataclass(frozen=True)
class CompileResult:
    """Outcome of a successful LaTeX build.

    Attributes
    ----------
    pdf : Path
        The PDF inside the build directory.
    log : Path
        The LaTeX log inside the build directory.
    engine : str
        ``"latexmk"`` or ``"pdflatex"``.
    seconds : float
        Wall time of the build (s).
    passes : int
        pdflatex runs (1 for latexmk: it decides itself).
    """

    pdf: Path
    log: Path
    engine: str
    seconds: float
    passes: int


def find_latex() -> tuple[str | None, str | None]:
    """Paths of ``latexmk`` and ``pdflatex`` on PATH (None when missing)."""
    return shutil.which("latexmk"), shutil.which("pdflatex")


_ERROR_LINE = re.compile(r"^(?:! .*|.*:\d+: .*)$", re.M)
_UNDEFINED = re.compile(r"(?:Reference|Citation) `[^']*' on page \d+ undefined|"
                        r"There were undefined references", re.M)


def _needs_rerun(log: Path) -> bool:
    text = log.read_text(encoding="latin-1", errors="replace") if log.exists() else ""
    return "Rerun to get" in text or "Label(s) may have changed" in text or \
        "Rerun LaTeX" in text


def _first_error(log: str) -> str:
    m = _ERROR_LINE.search(log)
    return " ".join(m.group(0).split()) if m else ""


def _run_group(cmd: list[str], cwd: Path, env: dict, timeout: float) -> subprocess.CompletedProcess:
    """Run a LaTeX command in its own process group; on timeout (or an interruption: SIGINT,
    SIGTERM, SIGHUP) end the whole group.

    latexmk starts pdflatex as a child: killing latexmk alone would leave pdflatex running
    after tanksynth has given up.
    """
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
    except BaseException:  # the timeout, or an interruption: nothing of LaTeX runs on after it
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.communicate()
        raise
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


def compile_pdf(tex_file: Path, timeout: float = 180.0) -> CompileResult:
    """Build ``tex_file`` into a PDF in its own directory.

    Uses ``latexmk -pdf`` when installed, else pdflatex up to four passes
    (until no "Rerun" request). Shell escape is off, interaction is
    non-stop, the first error halts the run.

    Parameters
    ----------
    tex_file : Path
        A ``.tex`` file in a scratch directory (auxiliary files land beside
        it).
    timeout : float
        Seconds before the build is abandoned.

    Returns
    -------
    CompileResult

    Raises
    ------
    ReportError
        No LaTeX installed, the build failed or timed out, or the log still
        reports undefined references. ``log_path`` is the log in the build
        directory (the caller keeps a copy).
    """
    tex_file = Path(tex_file)
    workdir = tex_file.parent
    stem = tex_file.stem
    log = workdir / f"{stem}.log"
    latexmk, pdflatex = find_latex()
    if pdflatex is None:
        raise ReportError("pdflatex is not installed: run `make tex` (Debian packages "
                          "texlive-latex-base texlive-latex-recommended latexmk) or omit --pdf")
    flags = ["-interaction=nonstopmode", "-halt-on-error", "-file-line-error", "-no-shell-escape"]
    # Paranoid file access for this run only: no absolute paths, no parent directories, no
    # dot files (kpathsea's openin_any/openout_any), and no shell escape (flags above).
    env = {**os.environ, "openin_any": "p", "openout_any": "p"}
    start = time.perf_counter()
    passes = 0
    try:
        if latexmk is not None:
            cmd = [latexmk, "-pdf", "-silent", f"-pdflatex=pdflatex {' '.join(flags)} %O %S",
                   tex_file.name]
            proc = _run_group(cmd, workdir, env, timeout)
            engine, passes, ok = "latexmk", 1, proc.returncode == 0
            # latexmk may stop while the log still asks for a rerun (labels moved by
            # the table of contents): finish with plain pdflatex runs.
            for _ in range(2):
                if not ok or not _needs_rerun(log):
                    break
                proc = _run_group([pdflatex, *flags, tex_file.name], workdir, env, timeout)
                passes += 1
                ok = proc.returncode == 0
        else:
            engine, ok = "pdflatex", True
            for passes in range(1, 5):
                proc = _run_group([pdflatex, *flags, tex_file.name], workdir, env, timeout)
                if proc.returncode != 0:
                    ok = False
                    break
                if passes >= 2 and not _needs_rerun(log):
                    break
    except subprocess.TimeoutExpired:
        raise ReportError(f"LaTeX did not finish within {timeout:.0f} s", log_path=log) from None
    seconds = time.perf_counter() - start
    text = log.read_text(encoding="latin-1", errors="replace") if log.exists() else ""
    pdf = workdir / f"{stem}.pdf"
    if not ok or not pdf.exists():
        first = _first_error(text) or "no PDF produced"
        raise ReportError(f"LaTeX failed: {first}", log_path=log)
    if _UNDEFINED.search(text):
        raise ReportError("LaTeX left undefined references", log_path=log)
    return CompileResult(pdf, log, engine, seconds, passes)


def pdf_page_count(pdf: Path) -> int | None:
    """Number of pages of a PDF (``pdfinfo`` when installed, else a byte scan).

    Parameters
    ----------
    pdf : Path
        The PDF file.
    """
    pdfinfo = shutil.which("pdfinfo")
    if pdfinfo:
        proc = subprocess.run([pdfinfo, str(pdf)], capture_output=True, text=True,
                              stdin=subprocess.DEVNULL)
        m = re.search(r"^Pages:\s+(\d+)", proc.stdout, re.M)
        if m:
            return int(m.group(1))
    data = Path(pdf).read_bytes()
    n = len(re.findall(rb"/Type\s*/Page[^s]", data))
    return n or None
