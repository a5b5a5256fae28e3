"""Write ``DIR/report.tex`` (and with ``pdf=True`` ``DIR/report.pdf``) from the files in DIR.

Files are replaced atomically: the figures and ``report.tex`` are written
to temporary names and renamed when complete; the PDF is built in a scratch
directory inside DIR and renamed into place only when LaTeX succeeded with
no error and no undefined reference. A failed build leaves no
``report.pdf`` (a stale one from an earlier run is removed, since it would
no longer match ``report.tex``) and keeps the LaTeX log as
``DIR/report.log``.
"""

from __future__ import annotations

import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

from tanksynth.artefacts.atomic import atomic_write, build_directory, commit
from tanksynth.errors import ArtefactError, ReportError
from tanksynth.reports.context import (build_context, draw_trace_figures, drawn_usable, trace_figures,
                                       trace_jobs)
from tanksynth.reports.figures import FigureFile, TraceFigure, eigenvalue_sets, figure_stem, pole_map
from tanksynth.reports.fit_figures import acf_figures
from tanksynth.reports.ts_figures import REGION_METHODS, region_figure, region_figures
from tanksynth.reports.linear_analysis import (LinearAnalysisView, linear_analysis_view,
                                               linear_analysis_views, linear_loops)
from tanksynth.reports.inputs import ReportInputs, read_report_inputs
from tanksynth.reports.comparison import PaperComparison
from tanksynth.reports.latex import Tex, environment
from tanksynth.reports.paper import compare_with_papers
from tanksynth.reports.pdf import compile_pdf, pdf_page_count
from tanksynth.reports.replay import replay_figures

__all__ = ["ReportResult", "render_report", "write_report", "draw_pole_maps", "figure_jobs",
           "draw_figure_jobs", "FIGURE_DIR"]

#: Sub-directory of DIR for the report's figures.
FIGURE_DIR = "report-figures"


@dataclass(frozen=True)
class ReportResult:
    """What `write_report` produced.

    Attributes
    ----------
    tex : Path
        ``DIR/report.tex``.
    pdf : Path or None
        ``DIR/report.pdf`` when built.
    log : Path or None
        ``DIR/report.log`` when LaTeX ran.
    figures : tuple of Path
    comparisons : tuple of PaperComparison
        The paper-vs-tool comparisons that applied.
    pages : int or None
        PDF page count.
    seconds : float
        Wall time of the whole call (s).
    latex_seconds : float or None
        Wall time of the LaTeX build (s).
    """

    tex: Path
    pdf: Path | None
    log: Path | None
    figures: tuple[Path, ...]
    comparisons: tuple[PaperComparison, ...]
    pages: int | None
    seconds: float
    latex_seconds: float | None


def _atomic_write_text(target: Path, text: str) -> None:
    atomic_write(target, text)


def draw_pole_maps(inputs: ReportInputs) -> dict[str, FigureFile | None]:
    """Draw the eigenvalue map of every artefact, ahead of `write_report` (its ``drawn``).

    Parameters
    ----------
    inputs : ReportInputs

    Returns
    -------
    dict
        File stem (``poles-NN-<name>``) -> FigureFile, or None for an
        artefact without eigenvalues.
    """
    figdir = inputs.directory / FIGURE_DIR
    out: dict[str, FigureFile | None] = {}
    for i, art in enumerate(inputs.artefacts):
        stem = figure_stem("poles", i, str(art.get("name", "")))
        out[stem] = pole_map(art, figdir, stem)
    return out


def figure_jobs(inputs: ReportInputs) -> list[tuple[str, int]]:
    """The figures of a report that need its verification, as jobs that processes can share.

    Time-domain figures (`tanksynth.reports.context.trace_jobs`: largest trace first),
    then certified-region figures (TS PDC artefacts) and linear analyses (artefacts with a
    linear loop, `tanksynth.reports.linear_analysis.linear_loops`: verified, passed); a
    region job may draw nothing (no certificate).

    Parameters
    ----------
    inputs : ReportInputs

    Returns
    -------
    list of (str, int)
        (kind ``"traces"``, ``"region"`` or ``"linear"``, artefact index).
    """
    arts = inputs.artefacts
    return ([("traces", i) for _, i in trace_jobs(inputs)]
            + [("region", i) for i, art in enumerate(arts) if str(art.get("method", "")) in REGION_METHODS]
            + [("linear", i) for i, art in enumerate(arts) if linear_loops(art, inputs.plant)])


def draw_figure_jobs(inputs: ReportInputs, jobs: list[tuple[str, int]]) -> dict[str, Any]:
    """Draw some `figure_jobs` ahead of `write_report` (its ``drawn``), e.g. in another process.

    Parameters
    ----------
    inputs : ReportInputs
    jobs : list of (str, int)
        Some of ``figure_jobs(inputs)``.

    Returns
    -------
    dict
        File stem -> what `write_report` takes for it: the main time-domain stem -> the
        artefact's figures (`tanksynth.reports.context.draw_trace_figures`), a region stem
        -> FigureFile, a linear stem -> LinearAnalysisView (none for a job that draws nothing).
    """
    traces = [i for kind, i in jobs if kind == "traces"]
    out: dict[str, Any] = dict(draw_trace_figures(inputs, traces)) if traces else {}
    figdir = inputs.directory / FIGURE_DIR
    for kind, i in jobs:
        art = inputs.artefacts[i]
        stem = figure_stem(kind, i, str(art.get("name", "")))
        fig: Any = None
        if kind == "region":
            fig = region_figure(art, inputs.directory, figdir, stem)
        elif kind == "linear":
            fig = linear_analysis_view(art, inputs.plant, figdir, stem)
        if fig is not None:
            out[stem] = fig
    return out


def render_report(inputs: ReportInputs, figures: dict[str, FigureFile] | None = None,
                  comparisons: tuple[PaperComparison, ...] | None = None,
                  traces: dict[str, tuple[TraceFigure, ...]] | None = None, *,
                  statements: Mapping[str, Callable[[Mapping[str, Any]], Tex]],
                  regions: dict[str, FigureFile] | None = None,
                  linear: dict[str, LinearAnalysisView] | None = None,
                  replay: dict[int, FigureFile] | None = None) -> str:
    """The LaTeX source of the report (no file is written).

    Parameters
    ----------
    inputs : ReportInputs
    figures : dict of artefact name to FigureFile, optional
        Pole maps to include (none when omitted).
    comparisons : tuple of PaperComparison, optional
        Computed with `compare_with_papers` when omitted.
    traces : dict of artefact name to tuple of TraceFigure, optional
        Time-domain figures to include, main first then the extra traces'
        (`tanksynth.reports.context.trace_figures`; none when omitted).
    statements : mapping of method name to callable
        Problem statement of each design method (`tanksynth.methods.STATEMENTS`).
    regions : dict of artefact name to FigureFile, optional
        Further figure of a design below its pole map: the certified region of a TS PDC
        design, the residual autocorrelation of a fit (`tanksynth.reports.fit_figures`); none
        when omitted.
    linear : dict of artefact name to LinearAnalysisView, optional
        Linear analysis (margins, step, Bode) of the verified loops
        (`tanksynth.reports.linear_analysis.linear_analysis_views`; none when omitted).
    replay : dict of int to FigureFile, optional
        Figures of the replay on measured data by entry (`tanksynth.reports.replay.replay_figures`;
        the section lists the checks without figures when omitted).
    """
    if comparisons is None:
        comparisons = compare_with_papers(inputs)
    ctx = build_context(inputs, figures or {}, comparisons, traces, statements=statements,
                        regions=regions, linear=linear, replay=replay)
    return environment().get_template("report.tex.j2").render(**ctx)


def write_report(directory: str | Path, pdf: bool = False, timeout: float = 180.0, *,
                 statements: Mapping[str, Callable[[Mapping[str, Any]], Tex]],
                 drawn: Mapping[str, Any] | None = None) -> ReportResult:
    """Write ``DIR/report.tex`` and its figures; with ``pdf`` also ``DIR/report.pdf``.

    Parameters
    ----------
    directory : str or Path
        A result directory (``plant.json``, artefacts, optionally
        ``checks.json`` and ``spec.toml``).
    pdf : bool
        Compile with latexmk/pdflatex.
    timeout : float
        Seconds allowed for the LaTeX build.
    statements : mapping of method name to callable
        Problem statement of each design method (`tanksynth.methods.STATEMENTS`).
    drawn : mapping, optional
        Figures already drawn from this directory's current files (file stem ->
        figure or None, `draw_pole_maps`; main trace stem -> tuple of figures,
        `tanksynth.reports.context.draw_trace_figures`; region stem -> FigureFile and
        linear stem -> LinearAnalysisView, `draw_figure_jobs`), e.g. by another process
        while verification ran or beside this one: used as they are when they are this directory's
        files of those stems (`drawn_usable`; None only for an artefact without
        such a figure), the others are drawn here.

    Returns
    -------
    ReportResult

    Raises
    ------
    ArtefactError
        The directory is not a result directory, has no artefact, or holds
        a malformed artefact.
    ReportError
        LaTeX is missing or failed; the message names ``DIR/report.log``.
    """
    start = time.perf_counter()
    inputs = read_report_inputs(directory)
    unknown = sorted({str(a.get("method")) for a in inputs.artefacts} - set(statements))
    if unknown:
        raise ArtefactError(f"{inputs.directory}: unknown design method(s) {unknown} in the artefacts; "
                            "expected one of: " + ", ".join(sorted(statements)))
    d = inputs.directory
    comparisons = compare_with_papers(inputs)
    figdir = d / FIGURE_DIR
    drawn = drawn or {}
    figures: dict[str, FigureFile] = {}
    for i, art in enumerate(inputs.artefacts):
        stem = figure_stem("poles", i, str(art.get("name", "")))
        ahead = drawn_usable(drawn, stem, figdir / f"{stem}.pdf", FigureFile,
                             lambda: not eigenvalue_sets(art))  # noqa: B023 - called right here
        fig = drawn[stem] if ahead else pole_map(art, figdir, stem)
        if fig is not None:
            figures[str(art["name"])] = fig
    replay = replay_figures(inputs.replay, d, FIGURE_DIR)
    if figdir.is_dir():  # figures of artefacts (and replays) that are gone
        keep = {f.path.name for f in figures.values()} | {f.path.name for f in replay.values()}
        for stale in [*figdir.glob("poles-*.pdf"), *figdir.glob("replay-*.pdf")]:
            if stale.name not in keep:
                stale.unlink(missing_ok=True)
    traces = trace_figures(inputs, drawn)
    regions = {**region_figures(inputs, drawn), **acf_figures(inputs)}   # a fit has no TS region
    linear = linear_analysis_views(inputs, drawn)
    tex = render_report(inputs, figures, comparisons, traces, statements=statements, regions=regions,
                        linear=linear, replay=replay)
    tex_path = d / "report.tex"
    pdf_path = d / "report.pdf"
    log_path = d / "report.log"
    out_pdf: Path | None = None
    out_log: Path | None = None
    pages = None
    latex_seconds = None
    if pdf:
        build = build_directory(d, ".report-build-")
        try:
            (build / "report.tex").write_text(tex, encoding="utf-8")
            if figdir.is_dir():
                shutil.copytree(figdir, build / FIGURE_DIR)
            try:
                res = compile_pdf(build / "report.tex", timeout=timeout)
            except ReportError as exc:
                kept = _keep_log(getattr(exc, "log_path", None), log_path)
                pdf_path.unlink(missing_ok=True)
                _atomic_write_text(tex_path, tex)
                where = f"; see {log_path}" if kept else ""
                raise ReportError(f"{d}: report.pdf not built: {exc}{where}",
                                  log_path=log_path if kept else None) from None
            _keep_log(res.log, log_path)
            pages = pdf_page_count(res.pdf)
            latex_seconds = res.seconds
            _atomic_write_text(tex_path, tex)
            commit(res.pdf, pdf_path)
            out_pdf, out_log = pdf_path, log_path
        finally:
            shutil.rmtree(build, ignore_errors=True)
    else:
        _atomic_write_text(tex_path, tex)
    drawn_files = [f.path for f in figures.values()] + [f.path for figs in traces.values() for f in figs] \
        + [v.figure.path for v in linear.values()] + [f.path for f in replay.values()]
    return ReportResult(tex_path, out_pdf, out_log, tuple(drawn_files),
                        comparisons, pages, time.perf_counter() - start, latex_seconds)


def _keep_log(src: Path | None, target: Path) -> bool:
    if src is None or not Path(src).exists():
        return False
    atomic_write(target, Path(src).read_bytes())
    return True
