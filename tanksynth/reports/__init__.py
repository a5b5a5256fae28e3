"""Report stage: LaTeX design reports built only from the files of a result directory.

`write_report` reads ``plant.json``, ``spec.toml``, ``checks.json`` and every
artefact of DIR, renders ``DIR/report.tex`` from the Jinja2 templates in
``templates/`` and, on request, compiles ``DIR/report.pdf`` with
latexmk/pdflatex. The report covers the plant (equations, parameters,
region, assumptions), the linearisation and discretisation, every rank
condition, each design (problem, solver, re-check, margins, eigenvalues,
gains), verification (once run), pole-map figures and the paper-vs-tool
comparison of `tanksynth.reports.paper` (the printed values are in
`tanksynth.papers`). Each design's problem statement comes from
`tanksynth.reports.statements` (one module per method family); what the report
reads of a design's diagnostics, it reads through the named accessors of
`tanksynth.reports.diagnostics`.
"""

from __future__ import annotations

import logging

from tanksynth._lazy import lazy_exports as _lazy_exports

# matplotlib logs a font fallback ("findfont: Font family ['STIXGeneral'] not found", after a
# stale font cache) as a WARNING through logging's last-resort handler, i.e. on stderr, where
# the CLI prints one line at most: cosmetic for a figure, so only its errors are let through.
logging.getLogger("matplotlib").setLevel(logging.ERROR)

#: Re-exported name -> its module, imported on first use (PEP 562): importing the package
#: loads none of its modules' dependencies (issue 15).
_EXPORTS = {
    **dict.fromkeys(["ReportInputs", "read_report_inputs"], "tanksynth.reports.inputs"),
    "escape_latex": "tanksynth.reports.latex",
    **dict.fromkeys(["PaperComparison", "PaperRow"], "tanksynth.reports.comparison"),
    "compare_with_papers": "tanksynth.reports.paper",
    **dict.fromkeys(["ReportResult", "render_report", "write_report"], "tanksynth.reports.writer"),
}

__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)

__all__ = [
    "write_report",
    "render_report",
    "ReportResult",
    "ReportInputs",
    "read_report_inputs",
    "compare_with_papers",
    "PaperComparison",
    "PaperRow",
    "escape_latex",
]
