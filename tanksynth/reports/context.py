"""The template context: what each report section shows, formatted as LaTeX.

Every value a template inserts is built here (the design sections in
`tanksynth.reports.designs`), either escaped user text or `Tex` generated from
numbers, so the templates only lay things out: the plant, the operating point,
the linearisations, the rank checks, the campaign summary, the figures and the
paper-vs-tool comparisons.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.artefacts.traces import trace_path
from tanksynth.plants import BUILTIN_PLANTS
from tanksynth.reports.check_names import check_title
from tanksynth.reports.comparison import PaperComparison
from tanksynth.reports.diagnostics.common import is_number
from tanksynth.reports.diagnostics.model import linearization_of
from tanksynth.reports.designs import design_view, latex_label
from tanksynth.reports.equations import split_equation
from tanksynth.reports.prose import prose_latex
from tanksynth.reports.replay import replay_view
from tanksynth.reports.trusted import math_or_text
from tanksynth.reports.figure_layout import TraceCanvas
from tanksynth.reports.figures import (FigureFile, TraceFigure, drawn_file_is, figure_stem,
                                       time_domain_figures)
from tanksynth.reports.inputs import ReportInputs
from tanksynth.reports.latex import (Tex, escape_latex, expression_latex, format_eigenvalues,
                                     format_number, format_unit, gain_latex, symbol_latex)

__all__ = ["build_context", "trace_figures", "trace_jobs", "draw_trace_figures", "drawn_usable"]


def _m(value: Any, digits: int = 5) -> Tex:
    return Tex("$" + format_number(value, digits) + "$")


# ------------------------------------------------------------------- plant
def _signal_rows(items: Sequence[Mapping[str, Any]]) -> list[dict[str, Tex]]:
    return [{"sym": Tex("$" + symbol_latex(s.get("name", "")) + "$"),
             "name": escape_latex(s.get("name", "")),
             "unit": format_unit(s.get("unit")),
             "desc": escape_latex(s.get("description", ""))} for s in items]


def _equation_blocks(lines: Sequence[str] | None) -> list[list[Tex]]:
    out = []
    for e in lines or []:
        tex, trusted = math_or_text(str(e))
        out.append(split_equation(str(e)) if trusted else [tex])
    return out


def _fitted_parameters(inputs: ReportInputs) -> dict[str, dict[str, Any]]:
    """The free parameters of the directory's fit artefacts: name -> ``{"value", "design"}``
    (the fitted value, typeset, and the fit's design name); the plant record holds their start
    values, which section 1.2 then labels as such."""
    out: dict[str, dict[str, Any]] = {}
    for art in inputs.artefacts:
        diag = art.get("diagnostics")
        table = diag.get("parameters") if art.get("method") == "fit" and isinstance(diag, Mapping) else None
        if not isinstance(table, Mapping):
            continue
        for name, row in table.items():
            if isinstance(row, Mapping) and is_number(row.get("value")):
                out.setdefault(str(name), {"value": _m(row["value"]),
                                           "design": escape_latex(str(art.get("name", "")))})
    return out


def _plant_view(inputs: ReportInputs) -> dict[str, Any]:
    rec = inputs.plant
    p = rec.get("plant", {}) or {}
    units = {s.get("name"): s.get("unit") for s in p.get("states", [])}
    units.update({s.get("name"): s.get("unit") for s in p.get("inputs", [])})
    fitted = _fitted_parameters(inputs)
    params = [{"sym": Tex("$" + symbol_latex(q.get("name", "")) + "$"),
               "name": escape_latex(q.get("name", "")),
               "value": _m(q.get("value")),
               "fitted": fitted.get(str(q.get("name", ""))),
               "unit": format_unit(q.get("unit")),
               "desc": prose_latex(q.get("description", ""))} for q in p.get("parameters", [])]
    region = p.get("region", {}) or {}
    bounds = [{"sym": Tex("$" + symbol_latex(k) + "$"), "lo": _m(v[0]), "hi": _m(v[1]),
               "unit": format_unit(units.get(k))}
              for k, v in (region.get("bounds") or {}).items() if isinstance(v, list) and len(v) == 2]
    ubounds = [{"sym": Tex("$" + symbol_latex(k) + "$"), "lo": _m(v[0]), "hi": _m(v[1]),
                "unit": format_unit(units.get(k))}
               for k, v in (p.get("input_bounds") or {}).items() if isinstance(v, list) and len(v) == 2]
    orderings = []
    for o in region.get("orderings") or []:
        tex = _ordering_tex(str(o))
        orderings.append(tex)
    hybrid = p.get("hybrid")
    hyb = None
    if isinstance(hybrid, Mapping):
        sw = []
        for s in hybrid.get("switching") or []:
            t = expression_latex(str(s))
            sw.append(Tex("$" + t + " = 0$") if t else escape_latex(s))
        hyb = {"bits": Tex(", ".join(escape_latex(b) for b in hybrid.get("bits") or [])),
               "switching": sw}
    assumptions = [{"kind": escape_latex(a.get("kind", "")),
                    "text": prose_latex(a.get("text", "")),
                    "source": escape_latex(a.get("source", ""), breakable=True)}
                   for a in p.get("assumptions", []) if isinstance(a, Mapping)]
    eqs = rec.get("equations", {}) or {}
    general = list(eqs.get("general") or [])
    smooth = list(eqs.get("smooth") or [])
    return {
        "name": escape_latex(p.get("name", "")),
        "description": escape_latex(p.get("description", "")),
        "source": escape_latex(p.get("source", ""), breakable=True),
        "states": _signal_rows(p.get("states", [])),
        "inputs": _signal_rows(p.get("inputs", [])),
        "outputs": _signal_rows(p.get("outputs", [])),
        "parameters": params,
        "fitted": sorted({f["design"] for f in fitted.values()}),
        "bounds": bounds,
        "input_bounds": ubounds,
        "orderings": orderings,
        "hybrid": hyb,
        "assumptions": assumptions,
        "general": _equation_blocks(general),
        "smooth": _equation_blocks(smooth) if smooth and smooth != general else [],
        "outputs_eq": _outputs_blocks(eqs.get("outputs"), p.get("outputs", [])),
    }


def _outputs_blocks(lines: Sequence[str] | None, outputs: Sequence[Mapping[str, Any]]) -> list[list[Tex]]:
    """The output equations; measured states (``h_{1} = h_{1}``) as one vector ``y = [h_1, h_2]^T``."""
    lines = [str(e) for e in lines or []]
    sides = [[part.strip() for part in e.split("=", 1)] for e in lines]
    if lines and all(len(sd) == 2 and sd[0] == sd[1] for sd in sides):
        return [[Tex(r"y &= \begin{bmatrix}" + r" & ".join(sd[0] for sd in sides)
                     + r"\end{bmatrix}^{\top}")]]
    return _equation_blocks(lines)


def _ordering_tex(text: str) -> Tex:
    m = re.fullmatch(r"\s*(.+?)\s*(>=|<=|>|<)\s*(.+?)\s*", text)
    if m:
        lhs, op, rhs = (expression_latex(m.group(1)), m.group(2), expression_latex(m.group(3)))
        if lhs and rhs:
            rel = {">": ">", "<": "<", ">=": r"\geq", "<=": r"\leq"}[op]
            return Tex(f"${lhs} {rel} {rhs}$")
    return escape_latex(text)


def _operating_view(inputs: ReportInputs) -> dict[str, Any]:
    rec = inputs.plant
    p = rec.get("plant", {}) or {}
    op = rec.get("operating_point", {}) or {}
    states = [s.get("name", "") for s in p.get("states", [])]
    ins = [s.get("name", "") for s in p.get("inputs", [])]
    sunits = [s.get("unit") for s in p.get("states", [])]
    iunits = [s.get("unit") for s in p.get("inputs", [])]

    def pairs(names, values, units):
        if values is None:
            return []
        return [{"sym": Tex("$" + symbol_latex(n) + "$"), "value": _m(v),
                 "unit": format_unit(u)} for n, v, u in zip(names, values, units)]

    ts = rec.get("ts")
    return {"x": pairs(states, op.get("x"), sunits), "u": pairs(ins, op.get("u"), iunits),
            "ts": _m(ts) if ts is not None else None,
            "input_names": ins, "input_units": iunits, "state_names": states, "state_units": sunits}


def _linearization_view(art: Mapping[str, Any], opv: Mapping[str, Any]) -> dict[str, Any]:
    lin = linearization_of(art.get("diagnostics") or {})
    eq = lin.equilibrium
    gains = art.get("gains") or {}
    shown = [gain_latex(k, gains[k]) for k in ("F", "B", "C", "Ad", "Bd") if k in gains]
    u0 = gains.get("u_op")
    rows = []
    names, units = opv["input_names"], opv["input_units"]
    if u0 is not None:
        for k, v in enumerate(np.atleast_1d(np.asarray(u0, dtype=float))):
            nm = names[k] if k < len(names) else f"u{k + 1}"
            un = units[k] if k < len(units) else ""
            rows.append({"sym": Tex("$" + symbol_latex(nm) + "$"), "ours": _m(v),
                         "given": _m(eq.given_u0[k]) if eq.given_u0 is not None and k < len(eq.given_u0)
                         else Tex("--"), "unit": format_unit(un)})
    snames = opv["state_names"]

    def residual(vec: Sequence[Any] | None) -> list[dict[str, Tex]]:
        if vec is None:
            return []
        return [{"sym": Tex(r"$\dot{" + symbol_latex(snames[i] if i < len(snames) else f"x{i+1}")
                            + "}$"), "value": _m(v, 4)} for i, v in enumerate(vec)]

    def eigenvalues(pairs: Sequence[tuple[float, float]] | None) -> Tex | None:
        return None if pairs is None else Tex("$" + format_eigenvalues([list(p) for p in pairs], 5) + "$")

    latex = {k: math_or_text(v)[0] for k, v in (art.get("latex") or {}).items() if isinstance(v, str)}
    return {
        "name": str(art.get("name", "")),
        "label": latex_label("lin", str(art.get("name", ""))),
        "gains": shown,
        "F_sym": latex.get("F"), "B_sym": latex.get("B"),
        "eig_F": eigenvalues(lin.eigenvalues_F),
        "eig_Ad": eigenvalues(lin.eigenvalues_Ad),
        "ts": _m(lin.ts) if lin.ts is not None else None,
        "u0": rows,
        "residual": residual(eq.residual),
        "max_residual": _m(eq.max_abs_residual, 3) if eq.max_abs_residual is not None else None,
        "is_equilibrium": eq.is_equilibrium,
        "given_residual": residual(eq.given_u0_residual),
        "given_balances": eq.given_u0_balances,
        "within_bounds": eq.within_input_bounds,
        "smooth_valid": lin.smooth_form_valid,
    }


# -------------------------------------------------------------------- checks
def _check_view(c: Mapping[str, Any]) -> dict[str, Any]:
    passed = c.get("passed")
    data = c.get("data") or {}
    facts: list[Tex] = []
    if isinstance(data, Mapping):
        if "rank" in data and "n" in data:
            facts.append(Tex(f"rank ${data['rank']}/{data['n']}$"))
        if "min_rank" in data and "n" in data:
            facts.append(Tex(f"min.\\ rank ${data['min_rank']}/{data['n']}$ over "
                             f"{data.get('points', '?')} points"))
        if is_number(data.get("condition_number")):
            facts.append(Tex(r"$\kappa = " + format_number(data["condition_number"], 3) + "$"))
        sv = data.get("singular_values")
        if isinstance(sv, list) and sv and all(is_number(x) for x in sv):
            facts.append(Tex(r"$\sigma_{\min} = " + format_number(min(sv), 3) + "$"))
        if isinstance(data.get("modes"), list) and data["modes"]:
            facts.append(Tex(f"{len(data['modes'])} failing mode(s)"))
    symbolic = None
    if isinstance(data, Mapping) and "determinant" in data:
        det = data.get("determinant")
        det_tex = data.get("determinant_latex") or expression_latex(str(det))
        factors = []
        for f in data.get("factors") or []:
            t = expression_latex(str(f))
            factors.append(Tex("$" + t + "$") if t else escape_latex(f))
        degenerate = []
        for d in data.get("degenerate_parameters") or []:
            if isinstance(d, Mapping):
                degenerate.append(Tex("$" + ",\\ ".join(f"{symbol_latex(k)} = {format_number(v)}"
                                                        for k, v in d.items()) + "$"))
            else:
                degenerate.append(escape_latex(d))
        symbolic = {
            "det": Tex("$" + det_tex + "$") if det_tex else
            Tex(r"\texttt{" + escape_latex(det, breakable=True) + "}"),
            "factors": factors,
            "degenerate": degenerate,
            "variables": Tex(", ".join("$" + symbol_latex(v) + "$" for v in data.get("variables") or [])),
            "blocks": data.get("blocks_used"),
        }
    return {
        "name": prose_latex(check_title(c.get("check", ""))),
        "passed": passed,
        "verdict": Tex(r"\textcolor{passgreen}{pass}" if passed is True else
                       r"\textcolor{failred}{\textbf{FAIL}}" if passed is False else
                       r"\textcolor{infoblue}{info}"),
        "detail": prose_latex(c.get("detail", "")),
        "facts": Tex("; ".join(facts)),
        "symbolic": symbolic,
    }


# ----------------------------------------------------------------- campaign
def _campaign_view(rows: Sequence[Mapping[str, str]] | None, limit: int = 60) -> dict | None:
    """Summary of a tidy campaign table: runs, mean, min, max per (artefact, scenario, metric)."""
    if not rows:
        return None
    keys = ("artefact", "scenario", "metric", "value")
    if not all(k in rows[0] for k in keys):
        return {"summary": [], "omitted": 0, "runs": len(rows), "generic": True}
    groups: dict[tuple[str, str, str], list[float]] = {}
    units: dict[tuple[str, str, str], str] = {}
    for r in rows:
        key = (r["artefact"], r["scenario"], r["metric"])
        try:
            groups.setdefault(key, []).append(float(r["value"]))
        except (TypeError, ValueError):
            continue
        units[key] = r.get("unit", "")
    out = []
    for key in sorted(groups)[:limit]:
        v = np.asarray(groups[key], dtype=float)
        fin = v[np.isfinite(v)]
        out.append({"artefact": escape_latex(key[0], breakable=True),
                    "scenario": escape_latex(key[1], breakable=True),
                    "metric": escape_latex(key[2], breakable=True),
                    "unit": format_unit(units.get(key)),
                    "n": len(v),
                    "mean": _m(float(fin.mean()), 4) if fin.size else Tex("--"),
                    "min": _m(float(fin.min()), 4) if fin.size else Tex("--"),
                    "max": _m(float(fin.max()), 4) if fin.size else Tex("--")})
    return {"summary": out, "omitted": max(0, len(groups) - limit), "runs": len(rows),
            "generic": False}


# ------------------------------------------------------------------ context
#: Sub-directory of DIR holding the report's figures (as in `tanksynth.reports.writer`).
_FIGURE_DIR = "report-figures"


def drawn_usable(drawn: Mapping[str, Any], stem: str, target: Path, kind: type[FigureFile] | type[TraceFigure],
                 none_ok: Callable[[], bool]) -> bool:
    """Whether ``drawn[stem]`` (a figure drawn ahead) can stand for the one drawn here.

    It can when it is None and ``none_ok()`` (this artefact has no such figure),
    or a ``kind`` instance whose file is ``target`` and exists; anything else
    (another directory's or another artefact's figure, a missing file, a wrong
    type) is drawn again.

    Parameters
    ----------
    drawn : mapping
        File stem -> figure or None.
    stem : str
        File stem of the figure wanted.
    target : Path
        ``DIR/report-figures/<stem>.pdf``.
    kind : type
        `FigureFile` or `TraceFigure`.
    none_ok : callable
        True when the artefact has no figure of this kind.

    Returns
    -------
    bool
    """
    if stem not in drawn:
        return False
    fig = drawn[stem]
    return bool(none_ok()) if fig is None else _is_file(fig, kind, target)


def _is_file(fig: Any, kind: type[FigureFile] | type[TraceFigure], target: Path) -> bool:
    """``fig`` is a ``kind`` whose file is ``target`` and exists."""
    return drawn_file_is(fig, target, kind)


def _as_figures(value: Any) -> tuple[TraceFigure, ...]:
    """An artefact's drawn time-domain figures as a tuple (a lone figure or None also accepted)."""
    if value is None:
        return ()
    return (value,) if isinstance(value, TraceFigure) else tuple(value)


def trace_jobs(inputs: ReportInputs) -> list[tuple[str, int]]:
    """The time-domain figures a report draws: (file stem, artefact index) of every artefact
    with a verdict trace file, largest trace file first (what `draw_trace_figures` takes).
    An artefact's extra traces are drawn with its main one (one job).

    Parameters
    ----------
    inputs : ReportInputs

    Returns
    -------
    list of (str, int)
    """
    jobs = []
    for i, art in enumerate(inputs.artefacts):
        name = str(art.get("name", ""))
        path = trace_path(inputs.directory / f"{name}.json", name)
        if path.is_file():
            jobs.append((path.stat().st_size, figure_stem("traces", i, name), i))
    return [(stem, i) for _, stem, i in sorted(jobs, key=lambda j: (-j[0], j[2]))]


def draw_trace_figures(inputs: ReportInputs, indices: Sequence[int] | None = None
                       ) -> dict[str, tuple[TraceFigure, ...]]:
    """Draw the time-domain figures of some artefacts (all by default), ahead of `trace_figures`.

    Parameters
    ----------
    inputs : ReportInputs
    indices : sequence of int, optional
        Artefact indices in ``inputs.artefacts``.

    Returns
    -------
    dict
        File stem of the main figure (``traces-NN-<name>``) -> the artefact's figures: the
        main one, then one per extra trace (``traces-NN-<name>-K``); empty when the artefact
        has no (readable) trace.
    """
    figdir = inputs.directory / _FIGURE_DIR
    canvas = TraceCanvas()    # figures with the same panel count reuse one figure's axes
    out: dict[str, tuple[TraceFigure, ...]] = {}
    for i in range(len(inputs.artefacts)) if indices is None else indices:
        art = inputs.artefacts[i]
        stem = figure_stem("traces", i, str(art.get("name", "")))
        out[stem] = time_domain_figures(art, inputs.directory, figdir, stem, canvas=canvas)
    return out


def trace_figures(inputs: ReportInputs, drawn: Mapping[str, Any] | None = None
                  ) -> dict[str, tuple[TraceFigure, ...]]:
    """Draw the time-domain figures of every artefact that has a verdict trace.

    Figures go to ``DIR/report-figures/traces-NN-<name>.pdf`` (the main
    trace) and ``traces-NN-<name>-K.pdf`` (its K-th extra trace), vector PDF
    written atomically; figures of traces that are gone are removed. An
    artefact without ``DIR/<name>.traces.npz`` simply has none.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (artefacts of the output directory).
    drawn : mapping, optional
        Figures already drawn from these inputs (`draw_trace_figures`, main
        file stem -> tuple of figures; a lone figure is read as a tuple of it):
        used as they are when they are this directory's files of that artefact
        (`drawn_usable`; none only for an artefact without a trace file); the
        others are drawn here.

    Returns
    -------
    dict
        Artefact name -> its figures (main first), for the artefacts that have one.
    """
    figdir = inputs.directory / _FIGURE_DIR
    drawn = drawn or {}

    def ahead(i: int, name: str) -> bool:
        """The figures drawn ahead for this artefact are its own (`drawn_usable` on the main
        figure; the extras this directory's existing files)."""
        stem = figure_stem("traces", i, name)
        if stem not in drawn:
            return False
        try:
            figs = _as_figures(drawn[stem])
        except TypeError:
            return False
        if not figs:
            return not trace_path(inputs.directory / f"{name}.json", name).is_file()
        if not all(isinstance(f, TraceFigure) for f in figs):
            return False
        return (_is_file(figs[0], TraceFigure, figdir / f"{stem}.pdf")
                and all(Path(f.path).stem.startswith(stem + "-")
                        and _is_file(f, TraceFigure, figdir / Path(f.path).name) for f in figs[1:]))

    missing = [i for i, art in enumerate(inputs.artefacts) if not ahead(i, str(art.get("name", "")))]
    fresh = draw_trace_figures(inputs, missing) if missing else {}
    out: dict[str, tuple[TraceFigure, ...]] = {}
    for i, art in enumerate(inputs.artefacts):
        name = str(art.get("name", ""))
        stem = figure_stem("traces", i, name)
        figs = _as_figures(fresh[stem] if stem in fresh else drawn[stem])
        if figs:
            out[name] = figs
    if figdir.is_dir():
        keep = {f.path.name for figs in out.values() for f in figs}
        for stale in figdir.glob("traces-*.pdf"):
            if stale.name not in keep:
                stale.unlink(missing_ok=True)
    return out


def _code_line(line: str) -> Tex:
    """One line of the spec for a typewriter block (indentation kept, escaped)."""
    stripped = line.lstrip(" ")
    indent = len(line) - len(stripped)
    body = escape_latex(stripped.expandtabs(4), breakable=True)
    return Tex((rf"\hspace*{{{indent * 0.5:.1f}em}}" if indent else "") + (body or r"\mbox{}"))


def _refused_view(rec: Mapping[str, Any],
                  statements: Mapping[str, Callable[[Mapping[str, Any]], Tex]]) -> dict[str, Any]:
    """A design refused as infeasible (``refused.json``): problem, reason, certificate."""
    method = str(rec.get("method", ""))
    fn = statements.get(method)
    try:
        problem = fn({}) if fn else escape_latex(f"method {method}")
    except (KeyError, TypeError, ValueError, AttributeError):
        problem = escape_latex(f"method {method}")
    cert = rec.get("certificate")
    cert_rows = []
    if isinstance(cert, Mapping):
        for k, v in cert.items():
            value = _m(v) if is_number(v) else prose_latex(v if isinstance(v, str) else str(v))
            cert_rows.append((prose_latex(str(k).replace("_", " ")), value))
    elif cert:
        cert_rows.append((Tex("certificate"), prose_latex(str(cert))))
    name = str(rec.get("name", ""))
    return {"name": name, "method": method, "label": latex_label("refused", name),
            "problem": problem, "reason": prose_latex(rec.get("reason", "")), "certificate": cert_rows}


def _spec_verbatim(text: str | None, limit: int = 600) -> Tex:
    """The spec for a ``verbatim`` environment: ASCII only (others named), no ``\\end{verbatim}``."""
    out = []
    for line in (text or "").splitlines()[:limit]:
        line = line.expandtabs(4).rstrip()
        line = "".join(c if (32 <= ord(c) < 127) else f"[U+{ord(c):04X}]" for c in line)
        out.append(line.replace("\\end{verbatim}", "\\end {verbatim}"))
    return Tex("\n".join(out))


def _is_builtin(name: str) -> bool:
    return name in BUILTIN_PLANTS


def build_context(inputs: ReportInputs, figures: Mapping[str, FigureFile],
                  paper: Sequence[PaperComparison],
                  traces: Mapping[str, tuple[TraceFigure, ...] | TraceFigure | None] | None = None, *,
                  statements: Mapping[str, Callable[[Mapping[str, Any]], Tex]],
                  regions: Mapping[str, FigureFile] | None = None,
                  linear: Mapping[str, Any] | None = None,
                  replay: Mapping[int, FigureFile] | None = None) -> dict[str, Any]:
    """Everything the templates need, formatted (no file is written).

    Parameters
    ----------
    inputs : ReportInputs
    figures : mapping of artefact name to FigureFile
        Pole maps.
    paper : sequence of PaperComparison
    traces : mapping of artefact name to tuple of TraceFigure, optional
        Time-domain figures drawn by `trace_figures`, main first (none when omitted; a lone
        TraceFigure is its artefact's main figure).
    statements : mapping of method name to callable
        Problem statement of each method (`tanksynth.methods.STATEMENTS`).
    regions : mapping of artefact name to FigureFile, optional
        Further figure of a design: certified regions (`tanksynth.reports.ts_figures.region_figures`),
        residual autocorrelation of fits (`tanksynth.reports.fit_figures.acf_figures`).
    linear : mapping of artefact name to LinearAnalysisView, optional
        Linear analysis of the verified loops (`tanksynth.reports.linear_analysis`).
    replay : mapping of int to FigureFile, optional
        Figures of the replay on measured data (`tanksynth.reports.replay.replay_figures`).
    """
    rec = inputs.plant
    title = rec.get("title") or f"Design report: {rec.get('plant', {}).get('name', '')}"
    opv = _operating_view(inputs)
    lin = [_linearization_view(a, opv) for a in inputs.by_method("linearize")]
    designs = [design_view(a, figures.get(str(a.get("name"))), statements,
                           rec.get("plant")) for a in inputs.artefacts]
    drawn = {k: v for k, v in ((k, _as_figures(v)) for k, v in (traces or {}).items()) if v}
    designs = [dataclasses.replace(d, trace_figure=drawn[d.name][0], trace_caption=prose_latex(
        drawn[d.name][0].caption, literal=(d.name,))) if d.name in drawn else d for d in designs]
    trace_extras = {d.name: [{"figure": f, "caption": prose_latex(f.caption, literal=(d.name,)),
                              "k": f.path.stem.rsplit("-", 1)[-1]}
                             for f in drawn[d.name][1:]] for d in designs if d.name in drawn}
    designs = [dataclasses.replace(d, region_figure=(regions or {})[d.name])
               if d.name in (regions or {}) else d for d in designs]
    checks = [_check_view(c) for c in inputs.checks] if inputs.checks is not None else None
    first = inputs.artefacts[0].get("provenance", {}) if inputs.artefacts else {}
    eq_check = None
    if inputs.checks:
        for c in inputs.checks:
            if c.get("check") == "equilibrium" and isinstance(c.get("data"), Mapping):
                eq_check = c["data"]
    eq_rows = []
    if not lin and eq_check:
        for k, v in enumerate(eq_check.get("u0") or []):
            nm = opv["input_names"][k] if k < len(opv["input_names"]) else f"u{k + 1}"
            un = opv["input_units"][k] if k < len(opv["input_units"]) else ""
            eq_rows.append({"sym": Tex("$" + symbol_latex(nm) + "$"), "value": _m(v),
                            "unit": format_unit(un)})
    n_fail = sum(1 for c in (inputs.checks or []) if c.get("passed") is False)
    n_err = sum(len(pc.errata) for pc in paper)
    verified = [d for d in designs if d.verification is not None]
    pdf_title = re.sub(r"[^A-Za-z0-9 .,:;()=+-]", " ", str(title))
    spec_lines = [_code_line(line) for line in (inputs.spec_text or "").splitlines()[:400]]
    refused = [_refused_view(r, statements) for r in inputs.refused]
    show_paper = _is_builtin(inputs.plant_name)
    return {
        "title": escape_latex(title),
        "pdf_title": escape_latex(" ".join(pdf_title.split())),
        "directory": escape_latex(inputs.directory.resolve().name, breakable=True),
        "spec_source": escape_latex(rec.get("spec_source", ""), breakable=True),
        "spec_sha": escape_latex(rec.get("spec_sha256", ""), breakable=True),
        "spec_lines": spec_lines,
        "spec_verbatim": _spec_verbatim(inputs.spec_text),
        "refused": refused,
        "show_paper": show_paper,
        "version": escape_latex(first.get("tanksynth_version", "")),
        "plant": _plant_view(inputs),
        "op": opv,
        "linearizations": lin,
        "eq_rows": eq_rows,
        "eq_max": _m(eq_check["max_abs_residual"], 3) if eq_check and "max_abs_residual" in eq_check
        else None,
        "checks": checks,
        "n_checks_failed": n_fail,
        "designs": designs,
        "other_designs": [d for d in designs if d.method != "linearize"],
        "verified": verified,
        "campaign": _campaign_view(inputs.campaign),
        "replay": replay_view(inputs.replay, replay or {},
                              {str(a.get("name")): str((a.get("provenance") or {}).get("content_sha256", ""))
                               for a in inputs.artefacts}),
        "figures": [designs_fig for designs_fig in designs if designs_fig.figure is not None],
        "trace_figures": [d for d in designs if d.trace_figure is not None],
        "trace_extras": trace_extras,
        "paper": paper,
        "n_errata": n_err,
        "linear": {name: {"view": v, "caption": prose_latex(v.figure.caption, literal=(name,))}
                   for name, v in (linear or {}).items()},
    }
