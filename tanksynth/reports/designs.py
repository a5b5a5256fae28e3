"""Design sections of the report: one `DesignView` per artefact, formatted as LaTeX.

Any artefact renders: known methods get their problem statement (from the
method table), every artefact gets its solver/status, re-checks, margins,
eigenvalues, gains (summarised when large), symbolic fragments, verification
and a bounded table of its remaining diagnostics.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.reports.check_names import check_title
from tanksynth.reports.comparison import latex_matrix_entries
from tanksynth.reports.diagnostics.common import is_number
from tanksynth.reports.equations import split_equation, visual_length
from tanksynth.reports.trusted import is_trusted_math, math_or_text
from tanksynth.reports.figures import (FigureFile, TraceFigure, eigenvalue_sets,
                                       is_pole_key)
from tanksynth.reports.gain_units import design_is_continuous, gain_unit
from tanksynth.reports.latex import (GainDisplay, Tex, escape_latex, format_eigenvalues,
                                     format_number, format_unit, gain_latex, gain_symbol,
                                     matrix_latex, symbol_latex)
from tanksynth.reports.prose import prose_latex

__all__ = ["DesignView", "design_view", "diagnostic_rows", "fragment_lines", "latex_label", "recheck_test_tex",
           "status_note", "INACCURATE_NOTE"]

_MAX_DIAG_ROWS = 30
_MAX_TEXT = 400


def _m(value: Any, digits: int = 5) -> Tex:
    return Tex("$" + format_number(value, digits) + "$")


def latex_label(prefix: str, name: str) -> str:
    """A LaTeX label from arbitrary text (ASCII letters, digits, '-').

    Parameters
    ----------
    prefix : str
        Label prefix (e.g. ``fig``).
    name : str
        Arbitrary text.
    """
    safe = re.sub(r"[^A-Za-z0-9]+", "-", name).strip("-") or "x"
    return f"{prefix}:{safe}"


def _is_complex_list(v: Any) -> bool:
    return (isinstance(v, list) and bool(v) and all(isinstance(x, list) and len(x) == 2
                                                   and all(is_number(y) for y in x) for x in v))


def _is_matrix(v: Any) -> bool:
    return (isinstance(v, list) and bool(v) and all(isinstance(r, list) and r and
                                                   all(is_number(x) for x in r) for r in v)
            and len({len(r) for r in v}) == 1)


def _value_tex(key: str, v: Any) -> Tex:
    """One diagnostics value as LaTeX (bounded size)."""
    if v is None:
        return Tex("--")
    if isinstance(v, bool) or is_number(v):
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
                (_is_complex_list(v) or all(is_number(x) for x in v)):
            return Tex("$" + format_eigenvalues(v, 4, limit=12) + "$")
        if all(is_number(x) for x in v):
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

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    skip : sequence of str, optional
        Keys left out (top level or dotted paths).
    limit : int, optional
        Largest number of rows.
    max_depth : int, optional
        Deepest nesting walked.

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
    region_figure : FigureFile or None
        Further figure: the certified region (TS PDC designs, `tanksynth.reports.ts_figures`)
        or the residual autocorrelation (fits, `tanksynth.reports.fit_figures`).
    status_note : Tex
        What a solver status short of ``optimal`` means and what the re-check then proves
        (`status_note`); empty otherwise.
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
    region_figure: FigureFile | None = None
    status_note: Tex = Tex("")

    @property
    def figure_caption(self) -> Tex:
        """The pole map's caption, typeset."""
        return (prose_latex(self.figure.caption, literal=(self.name,)) if self.figure is not None
                else Tex(""))

    @property
    def region_caption(self) -> Tex:
        """The certified-region figure's caption, typeset."""
        return (prose_latex(self.region_figure.caption, literal=(self.name,))
                if self.region_figure is not None else Tex(""))


_MARGIN_KEYS = ("margin", "achieved_margin", "min_region_margin", "min_boundary_distance", "max_pole_error", "condition_P",
                "gain_norm", "eigenvector_condition", "lmi_max_eigenvalue", "error_max_real_part")
#: What each margin key means, in words (keys not listed are shown with their name in words).
_MARGIN_WORDS = {
    "margin": "margin imposed on the strict LMI",
    "achieved_margin": "margin achieved by the LMI solution",
    "min_region_margin": r"smallest margin of the poles inside the region, $\min -\lambda_{\max}(f_D(z))$",
    "min_boundary_distance": ("smallest distance of the closed-loop eigenvalues to the region's boundary "
                              r"(units of the eigenvalues: 1/s, or the $z$-plane's)"),
    "max_pole_error": "largest error of the placed poles",
    "condition_P": r"condition number of the Lyapunov matrix $P$",
    "gain_norm": "norm of the gain",
    "eigenvector_condition": "condition number of the closed-loop eigenvectors",
    "lmi_max_eigenvalue": "largest eigenvalue of the LMI (must be negative)",
    "error_max_real_part": "largest real part of the error eigenvalues",
}


def words(key: str) -> str:
    """A diagnostics key in words (``min_region_margin`` -> ``min region margin``)."""
    return str(key).replace("_", " ").strip()


def _margin_label(path: str) -> Tex:
    parts = path.split(".")
    key = parts[-1]
    where = " ".join(words(p) for p in parts[:-1] if p not in ("lmi", "placement"))
    label = None if where else _MARGIN_WORDS.get(key)
    text = Tex(label) if label else prose_latex(words(key))
    return Tex(text + (f" ({escape_latex(where)})" if where else ""))


def _margin_where(path: str) -> int:
    """How many sub-record names a margin's label carries (0: the plain label of `_MARGIN_WORDS`)."""
    return sum(1 for p in path.split(".")[:-1] if p not in ("lmi", "placement"))


def _margin_rows(diag: Mapping[str, Any]) -> list[tuple[Tex, Tex]]:
    """The "Margins and conditioning" rows: every margin key found in ``diagnostics``, each
    quantity ONCE. A design records the same number under several sub-records (``placement.
    gain_norm`` and ``robustness.gain_norm``, ``placement.max_pole_error`` and ``placement.
    accuracy.max_pole_error``): hits with the same key and value are one quantity, shown in one
    row at the place of the first hit, labelled by the hit with the plainest label (fewest
    sub-record names, then the first)."""
    chosen: dict[tuple[str, str], str] = {}
    values: dict[tuple[str, str], Any] = {}
    for key in _MARGIN_KEYS:
        for path, v in _find(diag, key):
            if not (is_number(v) or (isinstance(v, str) and v.lower() in ("inf", "-inf", "nan"))):
                continue
            ident = (key, repr(float(v)))
            if ident not in chosen or _margin_where(path) < _margin_where(chosen[ident]):
                chosen[ident] = path      # (a dict keeps the first hit's place)
            values.setdefault(ident, v)
    return [(_margin_label(path), _m(values[ident])) for ident, path in chosen.items()]


_SHOWN = ("solver", "status", "checks", "assumptions", "caveats", "equilibrium", "rank")


#: What "optimal inaccurate" means, and what the independent re-check then proves.
INACCURATE_NOTE = (
    "Solver status optimal_inaccurate: the solver stopped before meeting its own accuracy tolerances "
    "(Clarabel: AlmostSolved), so its answer alone certifies nothing. The gain was kept only because "
    "the independent re-check below, computed in numpy from the returned matrices, passed: each "
    "constraint holds as its row states (direction, limit and the tolerance allowed). What is not "
    "proven is optimality: a larger margin or a smaller objective may exist.")


def status_note(status: Any) -> Tex:
    """The note on a solver status that reports an inaccurate solution (`INACCURATE_NOTE`, typeset);
    empty for any other status.

    Parameters
    ----------
    status : str or None
        The design's solver status (may join several solves, ``"optimal (phase 1), ..."``).
    """
    text = str(status or "").lower().replace("_", " ")
    return prose_latex(INACCURATE_NOTE) if "optimal inaccurate" in text else Tex("")


def _verdict_tex(passed: Any, word_pass: str = "pass", word_fail: str = "FAIL") -> Tex:
    if passed is True:
        return Tex(r"\textcolor{passgreen}{" + word_pass + "}")
    if passed is False:
        return Tex(r"\textcolor{failred}{\textbf{" + word_fail + "}}")
    return Tex(r"\textcolor{infoblue}{info}")


_RELATION_TEX = {"<=": r"\le", "<": "<", ">=": r"\ge", ">": ">"}


def _beyond_limit(c: Mapping[str, Any]) -> bool:
    """A tested value on the wrong side of its limit (passed only by the test's tolerance)."""
    value, limit, rel = c.get("value"), c.get("limit"), c.get("relation")
    if not (is_number(value) and is_number(limit)) or rel not in _RELATION_TEX:
        return False
    v, lim = float(value), float(limit)
    return (v > lim if rel == "<=" else v >= lim if rel == "<" else v < lim if rel == ">=" else v <= lim)


def _value_digits(c: Mapping[str, Any]) -> int:
    """Significant digits of a check's value: 12 past its limit; else at least 4, more until the
    printed value and the printed limit (6 digits) compare as the true ones do (0.0397369 under
    0.0397369x must not print as 0.03974)."""
    if _beyond_limit(c):
        return 12
    value, limit = c.get("value"), c.get("limit")
    if c.get("relation") not in _RELATION_TEX or not (is_number(value) and is_number(limit)):
        return 4
    v, lim = float(value), float(limit)
    shown_limit = float(f"{lim:.6g}")
    for digits in range(4, 13):
        shown = float(f"{v:.{digits}g}")
        if (shown < shown_limit) == (v < lim) and (shown > shown_limit) == (v > lim):
            return digits
    return 12


def recheck_test_tex(c: Mapping[str, Any]) -> Tex:
    """The test of a re-check record as it was made: direction, limit and the tolerance given to the
    value (``<= 1 + 10^{-6}`` (tolerance)), or the bare limit for a record without its direction.

    Parameters
    ----------
    c : mapping
        A check record (``limit``, optional ``relation`` and ``tolerance``).
    """
    if "limit" not in c:
        return Tex("--")
    rel = c.get("relation")
    if rel not in _RELATION_TEX:
        return _m(c["limit"], 4)
    tol = c.get("tolerance")
    text = "$" + _RELATION_TEX[str(rel)] + " " + format_number(c["limit"], 6)
    if is_number(tol) and float(tol) > 0:
        text += (" + " if rel in ("<=", "<") else " - ") + format_number(tol, 2) + r"$ \mbox{(tolerance)}"
    else:
        text += "$"
    return Tex(text)


def _checks_rows(value: Any) -> list[dict[str, Tex]]:
    """Rows of a list of check records (``name``/``check``, ``passed``, and ``value``,
    ``limit``, ``unit`` or ``detail``; ``relation`` and ``tolerance`` when the test recorded its
    direction: the limit column then states the test, and a value past its limit, passed by the
    tolerance alone, is printed with the digits that show it)."""
    rows: list[dict[str, Tex]] = []
    if not isinstance(value, list):
        return rows
    for c in value:
        if not isinstance(c, Mapping):
            continue
        detail = c.get("detail")
        rows.append({
            "name": prose_latex(c["name"] if c.get("name") else check_title(c.get("check", ""))),
            "value": (_m(c["value"], _value_digits(c)) if "value" in c else Tex("--")),
            "limit": recheck_test_tex(c),
            "unit": prose_latex(c.get("unit", "")),
            "detail": prose_latex(detail) if isinstance(detail, str) else Tex(""),
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


def _columns(value: Any) -> int | None:
    """Columns of a numeric gain matrix, None for anything else."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    return int(arr.shape[1]) if arr.ndim == 2 else None


def _with_unit(display: GainDisplay, unit: str | None) -> GainDisplay:
    """``display`` with its unit typeset (none for an unknown or dimensionless unit)."""
    if unit is None or unit == "1":
        return display
    return replace(display, unit=format_unit(unit))


def design_view(art: Mapping[str, Any], figure: FigureFile | None,
                statements: Mapping[str, Callable[[Mapping[str, Any]], Tex]],
                plant: Mapping[str, Any] | None = None) -> DesignView:
    """Build the `DesignView` of one artefact (any method); ``statements`` maps a method to its
    problem statement (`tanksynth.methods.STATEMENTS`).

    Parameters
    ----------
    art : mapping
        The artefact.
    figure : FigureFile or None
        Its eigenvalue figure, if drawn.
    statements : mapping of str to callable
        Method name -> problem statement.
    plant : mapping or None, optional
        The plant record's ``plant`` table (signal units, for the units of ``K`` and ``L``).
    """
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
    margins = _margin_rows(diag)
    checks = []
    for path, v in _find(diag, "checks"):
        for row in _checks_rows(v):
            row = dict(row)
            row["where"] = escape_latex(path, breakable=True)
            checks.append(row)
    eig = []
    for s in eigenvalue_sets(art):
        eig.append((escape_latex(s.label),
                    Tex("$" + format_eigenvalues([[v.real, v.imag] for v in s.values], 5, limit=16)
                        + "$" + (r" \ ($z$)" if s.discrete else ""))))
    continuous = design_is_continuous(diag)
    gains = [_with_unit(gain_latex(k, v), gain_unit(k, plant, continuous, _columns(v)))
             for k, v in (art.get("gains") or {}).items()]
    latex = [(gain_symbol(k), fragment_lines(gain_symbol(k), v) if is_trusted_math(v)
              else [Tex(gain_symbol(k) + " &= " + math_or_text(v)[0])])
             for k, v in (art.get("latex") or {}).items() if isinstance(v, str) and v.strip()
             and not (k in (art.get("gains") or {}) and _is_numeric_fragment(v))]
    notes = []
    for key in ("caveats", "notes", "note", "warnings"):
        for _, v in _find(diag, key, max_depth=1):
            for item in (v if isinstance(v, list) else [v]):
                if isinstance(item, str) and item and prose_latex(item) not in notes:
                    notes.append(prose_latex(item))  # a caveat repeated in a sub-record: once
    skip = list(_SHOWN) + [s.path for s in eigenvalue_sets(art)]
    if method == "linearize":
        skip += ["eigenvalues_F", "eigenvalues_Ad", "ts", "smooth_form_valid"]
    rows, omitted = diagnostic_rows(diag, skip=skip)
    provenance = [(escape_latex(k), escape_latex(str(v), breakable=True))
                  for k, v in prov.items() if k in ("spec_sha256", "gains_sha256",
                                                     "tanksynth_version", "solver") and v]
    return DesignView(
        name=str(art.get("name", "")), method=method, file=str(art.get("_file", "")),
        label=latex_label("design", str(art.get("name", ""))), problem=problem,
        solver=escape_latex(solver) if solver else Tex("--"),
        status=escape_latex(status, breakable=True) if status else Tex("--"),
        margins=margins, checks=checks, eigenvalues=eig, gains=gains, latex=latex, notes=notes,
        diagnostics=rows, omitted=omitted, verification=_verification_view(art.get("verification")),
        figure=figure, provenance=provenance,
        status_note=status_note(" ".join(str(v) for _, v in status_hits if isinstance(v, str))))


def _is_numeric_fragment(fragment: str) -> bool:
    """True for a LaTeX matrix/number holding numbers only (the gain printed again)."""
    body = re.sub(r"\\(begin|end)\{[a-z]*matrix\}|\\left|\\right|\\\\|&|[\[\]()\s]", " ", fragment)
    return bool(re.fullmatch(r"[\s0-9.eE+\-]*", body))


def fragment_lines(name_tex: str, fragment: str, width: int = 75) -> list[Tex]:
    """Display lines (``aligned`` rows) for a LaTeX fragment ``name = fragment``.

    A long sympy column vector is shown entry by entry (``name_{i} = ...``,
    each split at top-level sums) instead of one matrix shrunk to nothing;
    anything else is one line.

    Parameters
    ----------
    name_tex : str
        LaTeX of the left-hand side.
    fragment : str
        LaTeX of the right-hand side.
    width : int, optional
        Budget per line (characters, see `visual_length`).
    """
    entries = latex_matrix_entries(fragment)
    if entries and all(len(r) == 1 for r in entries) and len(entries) > 1 \
            and visual_length(fragment) > width:
        lines: list[Tex] = []
        for i, (e,) in enumerate(entries):
            lines.extend(split_equation(f"{{{name_tex}}}_{{{i + 1}}} = {e}", width))
        return lines
    return [Tex(f"{name_tex} &= {fragment}")]
