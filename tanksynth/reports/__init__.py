"""Report stage: LaTeX design reports built only from the files of a result directory.

`write_report` reads ``plant.json``, ``spec.toml``, ``checks.json`` and every
artefact of DIR, renders ``DIR/report.tex`` from the Jinja2 templates in
``templates/`` and, on request, compiles ``DIR/report.pdf`` with
latexmk/pdflatex. The report covers the plant (equations, parameters,
region, assumptions), the linearisation and discretisation, every rank
condition, each design (problem, solver, re-check, margins, eigenvalues,
gains), verification (once run), pole-map figures and the paper-vs-tool
comparison of `tanksynth.reports.paper` (the printed values are in
`tanksynth.papers`).
"""

from tanksynth.reports.inputs import ReportInputs, read_report_inputs
from tanksynth.reports.latex import escape_latex
from tanksynth.reports.comparison import PaperComparison, PaperRow
from tanksynth.reports.paper import compare_with_papers
from tanksynth.reports.writer import ReportResult, render_report, write_report

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
