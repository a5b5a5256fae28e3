"""The template context: what each report section shows, formatted as LaTeX.

Every value a template inserts is built here, either escaped user text or
`Tex` generated from numbers, so the templates only lay things out. Any
artefact renders: known methods get a problem statement, every artefact
gets its solver/status, re-checks, margins, eigenvalues, gains (summarised
when large) and a bounded table of its remaining diagnostics.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.reports.figures import FigureFile, TraceFigure, eigenvalue_sets, is_pole_key, time_domain_figure
from tanksynth.reports.inputs import ReportInputs
from tanksynth.reports.latex import (Tex, escape_latex, expression_latex, format_eigenvalues,
                    format_number, format_unit, gain_latex, matrix_latex, split_equation,
                    symbol_latex, visual_length)
from tanksynth.reports.paper import PaperComparison

__all__ = ["DesignView", "build_context", "design_view", "diagnostic_rows", "fragment_lines",
           "trace_figures"]

_MAX_DIAG_ROWS = 30
_MAX_TEXT = 400


def _m(value: Any, digits: int = 5) -> Tex:
    return Tex("$" + format_number(value, digits) + "$")


def _label(prefix: str, name: str) -> str:
    """A LaTeX label from arbitrary text (ASCII letters, digits, '-')."""
    safe = re.sub(r"[^A-Za-z0-9]+", "-", name).strip("-") or "x"
    return f"{prefix}:{safe}"


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_complex_list(v: Any) -> bool:
    return (isinstance(v, list) and bool(v) and all(isinstance(x, list) and len(x) == 2
                                                   and all(_is_number(y) for y in x) for x in v))


def _is_matrix(v: Any) -> bool:
    return (isinstance(v, list) and bool(v) and all(isinstance(r, list) and r and
                                                   all(_is_number(x) for x in r) for r in v)
            and len({len(r) for r in v}) == 1)


def _value_tex(key: str, v: Any) -> Tex:
    """One diagnostics value as LaTeX (bounded size)."""
    if v is None:
        return Tex("--")
    if isinstance(v, bool) or _is_number(v):
        return _m(v)
    if isinstance(v, str):
        if v.lower() in ("inf", "-inf", "nan"):
            return _m(v)
        text = v if len(v) <= _MAX_TEXT else v[:_MAX_TEXT] + " ..."
        return escape_latex(text, breakable=True)
    if isinstance(v, list):
        if not v:
            return Tex(r"\emph{empty}")
        if ("eigenvalue" in key or is_pole_key(key)) and \
                (_is_complex_list(v) or all(_is_number(x) for x in v)):
            return Tex("$" + format_eigenvalues(v, 4, limit=12) + "$")
        if all(_is_number(x) for x in v):
            if len(v) <= 8:
                return Tex("$(" + ",\\; ".join(format_number(x, 4) for x in v) + ")$")
            arr = np.asarray(v, dtype=float)
            return Tex(f"{len(v)} numbers in $[{format_number(arr.min(), 4)},\\ "
                       f"{format_number(arr.max(), 4)}]$")
        if _is_matrix(v):
            r, c = len(v), len(v[0])
            if r * c <= 25:
                return Tex(r"$\scriptstyle " + matrix_latex(v, 4) + "$")
            return Tex(f"${r} \\times {c}$ matrix")
        if all(isinstance(x, str) for x in v):
            shown = [escape_latex(x if len(x) <= 120 else x[:120] + " ...", breakable=True)
                     for x in v[:6]]
            more = f" (+{len(v) - 6} more)" if len(v) > 6 else ""
            return Tex("; ".join(shown) + more)
        return Tex(f"list of {len(v)} entries")
    if isinstance(v, Mapping):
        return Tex(f"{len(v)} entries")
    return escape_latex(str(v)[:_MAX_TEXT])


def diagnostic_rows(diag: Mapping[str, Any], skip: Sequence[str] = (), limit: int = _MAX_DIAG_ROWS,
                    max_depth: int = 3) -> tuple[list[tuple[Tex, Tex]], int]:
    """Flatten diagnostics into (key path, value) rows, at most ``limit`` of them.

    Nested mappings are walked to ``max_depth``; lists of records and large
    matrices are summarised. Keys in ``skip`` (top level, or dotted paths)
    are left out (shown elsewhere).

    Returns
    -------
    rows : list of (Tex, Tex)
    omitted : int
        Rows not shown because of ``limit``.
    """
    rows: list[tuple[Tex, Tex]] = []
    omitted = 0

    def walk(node: Mapping[str, Any], prefix: str, depth: int) -> None:
        nonlocal omitted
        for k, v in node.items():
            path = f"{prefix}.{k}" if prefix else str(k)
            if path in skip or str(k).startswith(("_", "reference")):
                continue
            if isinstance(v, Mapping) and v and depth < max_depth:
                walk(v, path, depth + 1)
                continue
            if len(rows) >= limit:
                omitted += 1
                continue
            rows.append((escape_latex(path, breakable=True), _value_tex(str(k), v)))

    walk(diag, "", 1)
    return rows, omitted


def _find(diag: Mapping[str, Any], key: str, max_depth: int = 3) -> list[tuple[str, Any]]:
    """Every (path, value) whose last key is ``key``, breadth first."""
    out: list[tuple[str, Any]] = []
    frontier: list[tuple[str, Any, int]] = [("", diag, 0)]
    while frontier:
        prefix, node, depth = frontier.pop(0)
        if not isinstance(node, Mapping) or depth > max_depth:
            continue
        for k, v in node.items():
            path = f"{prefix}.{k}" if prefix else str(k)
            if k == key:
                out.append((path, v))
            if isinstance(v, Mapping):
                frontier.append((path, v, depth + 1))
    return out


# ------------------------------------------------------------ method problems


# ------------------------------------------------------------------ designs
@dataclass(frozen=True)
class DesignView:
    """One artefact as the design section shows it.

    Attributes
    ----------
    name, method, file : str
        Raw strings (escape when typesetting).
    label : str
        LaTeX label of its subsection.
    problem : Tex
    solver, status : Tex
    margins : list of (Tex, Tex)
    checks : list of dict
        Re-check rows: name, value, limit, passed (Tex each).
    eigenvalues : list of (Tex, Tex)
    gains : list of GainDisplay
    latex : list of (Tex, Tex)
        Symbolic fragments (name, math).
    notes : list of Tex
        Caveats and notes.
    diagnostics : list of (Tex, Tex)
    omitted : int
    verification : dict or None
    figure : FigureFile or None
    provenance : list of (Tex, Tex)
    trace_figure : TraceFigure or None
        Time-domain figure of the verdict simulation (`trace_figures`).
    trace_caption : Tex
        Its caption, escaped.
    """

    name: str
    method: str
    file: str
    label: str
    problem: Tex
    solver: Tex
    status: Tex
    margins: list = field(default_factory=list)
    checks: list = field(default_factory=list)
    eigenvalues: list = field(default_factory=list)
    gains: list = field(default_factory=list)
    latex: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    diagnostics: list = field(default_factory=list)
    omitted: int = 0
    verification: dict | None = None
    figure: FigureFile | None = None
    provenance: list = field(default_factory=list)
    trace_figure: TraceFigure | None = None
    trace_caption: Tex = Tex("")


_MARGIN_KEYS = ("margin", "achieved_margin", "min_region_margin", "max_pole_error", "condition_P",
                "gain_norm", "eigenvector_condition", "lmi_max_eigenvalue", "error_max_real_part")
_SHOWN = ("solver", "status", "checks", "assumptions", "caveats", "equilibrium", "rank")


def _verdict_tex(passed: Any, word_pass: str = "pass", word_fail: str = "FAIL") -> Tex:
    if passed is True:
        return Tex(r"\textcolor{passgreen}{" + word_pass + "}")
    if passed is False:
        return Tex(r"\textcolor{failred}{\textbf{" + word_fail + "}}")
    return Tex(r"\textcolor{infoblue}{info}")


def _checks_rows(value: Any) -> list[dict[str, Tex]]:
    """Rows of a list of check records (``name``/``check``, ``passed``, and ``value``,
    ``limit``, ``unit`` or ``detail``)."""
    rows = []
    if not isinstance(value, list):
        return rows
    for c in value:
        if not isinstance(c, Mapping):
            continue
        detail = c.get("detail")
        rows.append({
            "name": escape_latex(c.get("name", c.get("check", "")), breakable=True),
            "value": _m(c["value"], 4) if "value" in c else Tex("--"),
            "limit": _m(c["limit"], 4) if "limit" in c else Tex("--"),
            "unit": escape_latex(c.get("unit", "")),
            "detail": escape_latex(detail, breakable=True) if isinstance(detail, str) else Tex(""),
            "passed": _verdict_tex(c.get("passed")),
        })
    return rows


def _verification_view(ver: Any) -> dict | None:
    if ver is None:
        return None
    if not isinstance(ver, Mapping):
        return {"passed": Tex("--"), "checks": [], "rows": [(Tex("verification"), _value_tex("", ver))],
                "omitted": 0}
    passed = ver.get("passed")
    rows, omitted = diagnostic_rows(ver, skip=("passed", "checks"), limit=30)
    return {
        "passed": _verdict_tex(passed, "passed", "FAILED") if passed is not None
        else Tex(r"\textcolor{infoblue}{no verdict}"),
        "checks": _checks_rows(ver.get("checks")),
        "rows": rows,
        "omitted": omitted,
    }


def design_view(art: Mapping[str, Any], figure: FigureFile | None,
                statements: Mapping[str, Callable[[Mapping[str, Any]], Tex]]) -> DesignView:
    """Build the `DesignView` of one artefact (any method); ``statements`` maps a method to its
    problem statement (`tanksynth.methods.STATEMENTS`)."""
    diag = art.get("diagnostics") or {}
    method = str(art.get("method", ""))
    problem_fn = statements.get(method)
    problem = problem_fn(diag) if problem_fn else Tex(
        r"Method \texttt{" + escape_latex(method) + r"}: the report has no problem statement for "
        r"this method yet; its diagnostics are listed below.")
    solver_hits = _find(diag, "solver")
    status_hits = _find(diag, "status")
    prov = art.get("provenance") or {}
    solver = next((v for _, v in solver_hits if isinstance(v, str) and v), None) or prov.get("solver")
    status = next((v for _, v in status_hits if isinstance(v, str) and v), None)
    margins = []
    for key in _MARGIN_KEYS:
        for path, v in _find(diag, key):
            if _is_number(v) or (isinstance(v, str) and v.lower() in ("inf", "-inf", "nan")):
                margins.append((escape_latex(path, breakable=True), _m(v)))
    checks = []
    for path, v in _find(diag, "checks"):
        for row in _checks_rows(v):
            row = dict(row)
            row["where"] = escape_latex(path, breakable=True)
            checks.append(row)
    eig = []
    for s in eigenvalue_sets(art):
        eig.append((escape_latex(s.path, breakable=True),
                    Tex("$" + format_eigenvalues([[v.real, v.imag] for v in s.values], 5, limit=16)
                        + "$" + (r" \ ($z$)" if s.discrete else ""))))
    gains = [gain_latex(k, v) for k, v in (art.get("gains") or {}).items()]
    latex = [(symbol_latex(k), fragment_lines(symbol_latex(k), v))
             for k, v in (art.get("latex") or {}).items() if isinstance(v, str) and v.strip()]
    notes = []
    for key in ("caveats", "notes", "note", "warnings"):
        for _, v in _find(diag, key, max_depth=1):
            for item in (v if isinstance(v, list) else [v]):
                if isinstance(item, str) and item:
                    notes.append(escape_latex(item, breakable=True))
    skip = list(_SHOWN) + [s.path for s in eigenvalue_sets(art)]
    if method == "linearize":
        skip += ["eigenvalues_F", "eigenvalues_Ad", "ts", "smooth_form_valid"]
    rows, omitted = diagnostic_rows(diag, skip=skip)
    provenance = [(escape_latex(k), escape_latex(str(v), breakable=True))
                  for k, v in prov.items() if k in ("spec_sha256", "gains_sha256",
                                                     "tanksynth_version", "solver") and v]
    return DesignView(
        name=str(art.get("name", "")), method=method, file=str(art.get("_file", "")),
        label=_label("design", str(art.get("name", ""))), problem=problem,
        solver=escape_latex(solver) if solver else Tex("--"),
        status=escape_latex(status, breakable=True) if status else Tex("--"),
        margins=margins, checks=checks, eigenvalues=eig, gains=gains, latex=latex, notes=notes,
        diagnostics=rows, omitted=omitted, verification=_verification_view(art.get("verification")),
        figure=figure, provenance=provenance)


def fragment_lines(name_tex: str, fragment: str, width: int = 75) -> list[Tex]:
    """Display lines (``aligned`` rows) for a LaTeX fragment ``name = fragment``.

    A long sympy column vector is shown entry by entry (``name_{i} = ...``,
    each split at top-level sums) instead of one matrix shrunk to nothing;
    anything else is one line.
    """
    entries = _sympy_matrix_entries(fragment)
    if entries and all(len(r) == 1 for r in entries) and len(entries) > 1 \
            and visual_length(fragment) > width:
        lines: list[Tex] = []
        for i, (e,) in enumerate(entries):
            lines.extend(split_equation(f"{{{name_tex}}}_{{{i + 1}}} = {e}", width))
        return lines
    return [Tex(f"{name_tex} &= {fragment}")]


def _sympy_matrix_entries(tex: str) -> list[list[str]] | None:
    from tanksynth.reports.paper import _latex_matrix_entries

    return _latex_matrix_entries(tex)


# ------------------------------------------------------------------- plant
def _signal_rows(items: Sequence[Mapping[str, Any]]) -> list[dict[str, Tex]]:
    return [{"sym": Tex("$" + symbol_latex(s.get("name", "")) + "$"),
             "name": escape_latex(s.get("name", "")),
             "unit": format_unit(s.get("unit")),
             "desc": escape_latex(s.get("description", ""))} for s in items]


def _equation_blocks(lines: Sequence[str] | None) -> list[list[Tex]]:
    return [split_equation(str(e)) for e in (lines or [])]


def _plant_view(inputs: ReportInputs) -> dict[str, Any]:
    rec = inputs.plant
    p = rec.get("plant", {}) or {}
    units = {s.get("name"): s.get("unit") for s in p.get("states", [])}
    units.update({s.get("name"): s.get("unit") for s in p.get("inputs", [])})
    params = [{"sym": Tex("$" + symbol_latex(q.get("name", "")) + "$"),
               "name": escape_latex(q.get("name", "")),
               "value": _m(q.get("value")),
               "unit": format_unit(q.get("unit")),
               "desc": escape_latex(q.get("description", ""))} for q in p.get("parameters", [])]
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
                    "text": escape_latex(a.get("text", ""), breakable=True),
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
        "bounds": bounds,
        "input_bounds": ubounds,
        "orderings": orderings,
        "hybrid": hyb,
        "assumptions": assumptions,
        "general": _equation_blocks(general),
        "smooth": _equation_blocks(smooth) if smooth and smooth != general else [],
        "outputs_eq": _equation_blocks(eqs.get("outputs")),
    }


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
    diag = art.get("diagnostics") or {}
    gains = art.get("gains") or {}
    eq = diag.get("equilibrium") or {}
    shown = [gain_latex(k, gains[k]) for k in ("F", "B", "C", "Ad", "Bd") if k in gains]
    u0 = gains.get("u0")
    given = eq.get("given_u0")
    rows = []
    names, units = opv["input_names"], opv["input_units"]
    if u0 is not None:
        for k, v in enumerate(np.atleast_1d(np.asarray(u0, dtype=float))):
            nm = names[k] if k < len(names) else f"u{k + 1}"
            un = units[k] if k < len(units) else ""
            rows.append({"sym": Tex("$" + symbol_latex(nm) + "$"), "ours": _m(v),
                         "given": _m(given[k]) if isinstance(given, list) and k < len(given) else
                         Tex("--"), "unit": format_unit(un)})
    snames = opv["state_names"]

    def residual(vec):
        if not isinstance(vec, list):
            return []
        return [{"sym": Tex(r"$\dot{" + symbol_latex(snames[i] if i < len(snames) else f"x{i+1}")
                            + "}$"), "value": _m(v, 4)} for i, v in enumerate(vec)]

    latex = {k: Tex(v) for k, v in (art.get("latex") or {}).items() if isinstance(v, str)}
    return {
        "name": str(art.get("name", "")),
        "label": _label("lin", str(art.get("name", ""))),
        "gains": shown,
        "F_sym": latex.get("F"), "B_sym": latex.get("B"),
        "eig_F": Tex("$" + format_eigenvalues(diag["eigenvalues_F"], 5) + "$")
        if "eigenvalues_F" in diag else None,
        "eig_Ad": Tex("$" + format_eigenvalues(diag["eigenvalues_Ad"], 5) + "$")
        if "eigenvalues_Ad" in diag else None,
        "ts": _m(diag["ts"]) if _is_number(diag.get("ts")) else None,
        "u0": rows,
        "residual": residual(eq.get("residual")),
        "max_residual": _m(eq["max_abs_residual"], 3) if "max_abs_residual" in eq else None,
        "is_equilibrium": eq.get("is_equilibrium"),
        "given_residual": residual(eq.get("given_u0_residual")),
        "given_balances": eq.get("given_u0_balances"),
        "within_bounds": eq.get("within_input_bounds"),
        "smooth_valid": diag.get("smooth_form_valid"),
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
        if _is_number(data.get("condition_number")):
            facts.append(Tex(r"$\kappa = " + format_number(data["condition_number"], 3) + "$"))
        sv = data.get("singular_values")
        if isinstance(sv, list) and sv and all(_is_number(x) for x in sv):
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
        "name": escape_latex(c.get("check", ""), breakable=True),
        "passed": passed,
        "verdict": Tex(r"\textcolor{passgreen}{pass}" if passed is True else
                       r"\textcolor{failred}{\textbf{FAIL}}" if passed is False else
                       r"\textcolor{infoblue}{info}"),
        "detail": escape_latex(c.get("detail", ""), breakable=True),
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


def _trace_stem(index: int, name: str) -> str:
    safe = "".join(c if (c.isascii() and c.isalnum()) else "-" for c in name).strip("-")[:40]
    return f"traces-{index:02d}-{safe or 'design'}"


def trace_figures(inputs: ReportInputs) -> dict[str, TraceFigure]:
    """Draw the time-domain figure of every artefact that has a verdict trace.

    Figures go to ``DIR/report-figures/traces-NN-<name>.pdf`` (vector PDF,
    written atomically); figures of traces that are gone are removed. An
    artefact without ``DIR/<name>.traces.npz`` simply has none.

    Returns
    -------
    dict
        Artefact name -> TraceFigure.
    """
    figdir = inputs.directory / _FIGURE_DIR
    out: dict[str, TraceFigure] = {}
    for i, art in enumerate(inputs.artefacts):
        name = str(art.get("name", ""))
        fig = time_domain_figure(art, inputs.directory, figdir, _trace_stem(i, name))
        if fig is not None:
            out[name] = fig
    if figdir.is_dir():
        keep = {f.path.name for f in out.values()}
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


def build_context(inputs: ReportInputs, figures: Mapping[str, FigureFile],
                  paper: Sequence[PaperComparison],
                  traces: Mapping[str, TraceFigure] | None = None, *,
                  statements: Mapping[str, Callable[[Mapping[str, Any]], Tex]]) -> dict[str, Any]:
    """Everything the templates need, formatted (no file is written).

    Parameters
    ----------
    inputs : ReportInputs
    figures : mapping of artefact name to FigureFile
        Pole maps.
    paper : sequence of PaperComparison
    traces : mapping of artefact name to TraceFigure, optional
        Time-domain figures drawn by `trace_figures` (none when omitted).
    statements : mapping of method name to callable
        Problem statement of each method (`tanksynth.methods.STATEMENTS`).
    """
    rec = inputs.plant
    title = rec.get("title") or f"Design report: {rec.get('plant', {}).get('name', '')}"
    opv = _operating_view(inputs)
    lin = [_linearization_view(a, opv) for a in inputs.by_method("linearize")]
    designs = [design_view(a, figures.get(str(a.get("name"))), statements) for a in inputs.artefacts]
    traces = traces or {}
    designs = [dataclasses.replace(d, trace_figure=traces[d.name], trace_caption=escape_latex(
        traces[d.name].caption)) if d.name in traces else d for d in designs]
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
    return {
        "title": escape_latex(title),
        "pdf_title": escape_latex(" ".join(pdf_title.split())),
        "directory": escape_latex(inputs.directory.resolve().name, breakable=True),
        "spec_source": escape_latex(rec.get("spec_source", ""), breakable=True),
        "spec_sha": escape_latex(rec.get("spec_sha256", ""), breakable=True),
        "spec_lines": spec_lines,
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
        "figures": [designs_fig for designs_fig in designs if designs_fig.figure is not None],
        "trace_figures": [d for d in designs if d.trace_figure is not None],
        "paper": paper,
        "n_errata": n_err,
    }
