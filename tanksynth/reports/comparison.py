"""Paper-vs-tool rows: the data model and the helpers every seed reproduction uses.

A `Reproduction` says when it applies (plant, operating point, parameters,
which artefacts) and computes one `PaperRow` per compared quantity from the
plant record and the artefacts of a result directory. The printed values
themselves live in `tanksynth.papers`; the verdict of a row is computed here
by comparing numbers (or symbolic expressions).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from tanksynth.reports.inputs import ReportInputs
from tanksynth.reports.latex import Tex, format_number, matrix_latex

__all__ = [
    "AGREES", "ERRATUM", "DIFFERS",
    "PaperRow",
    "PaperComparison",
    "Reproduction",
    "cell_number",
    "cell_fit",
    "cell_matrix",
    "cell_terms",
    "close",
    "artefact_array",
    "artefact_arrays",
    "params_match",
    "first_artefact",
    "printed_precision",
    "latex_matrix_entries",
    "poly_latex",
    "verdict_check",
    "ratio_note",
]

AGREES, ERRATUM, DIFFERS = "agrees", "erratum", "differs"


@dataclass(frozen=True)
class PaperRow:
    """One compared quantity.

    Attributes
    ----------
    quantity : Tex
        What is compared (LaTeX, text mode).
    printed : Tex
        The printed value or formula (LaTeX, text mode, math in ``$``).
    ours : Tex
        tanksynth's value (LaTeX, text mode).
    verdict : str
        `AGREES`, `ERRATUM` (the printed value disagrees with its own
        equations or with the model) or `DIFFERS` (different, but not a
        mistake: non-unique gains, rounding beyond the printed digits, a
        value that depends on something the paper does not print).
    note : Tex
        What differs, or why an agreement is only numerical.
    entry : tuple of int, optional
        1-based matrix entry, for matrix rows.
    printed_value, ours_value : float, optional
        The numbers compared, when scalar.
    explanation : Tex, optional
        A derivation too long for a table cell: typeset as a paragraph under the table
        (the note then says so).
    """

    quantity: Tex
    printed: Tex
    ours: Tex
    verdict: str
    note: Tex = Tex("")
    entry: tuple[int, ...] | None = None
    printed_value: float | None = None
    ours_value: float | None = None
    explanation: Tex = Tex("")

    @property
    def is_erratum(self) -> bool:
        """True when the printed value is wrong."""
        return self.verdict == ERRATUM


@dataclass(frozen=True)
class PaperComparison:
    """The rows of one reproduction that applied to a result directory.

    Attributes
    ----------
    key : str
        Registry key.
    seed : str
        Seed paper number (``"000"``); empty for spec-given references.
    title : str
        Plain text.
    source : str
        Paper and section the printed values come from (plain text).
    rows : tuple of PaperRow
    intro : str, optional
        LaTeX shown between the source line and the table (the data every row refers to,
        such as the printed initial states); empty for none.
    """

    key: str
    seed: str
    title: str
    source: str
    rows: tuple[PaperRow, ...]
    intro: str = ""

    @property
    def errata(self) -> tuple[PaperRow, ...]:
        """The rows whose printed value is wrong."""
        return tuple(r for r in self.rows if r.is_erratum)


@dataclass(frozen=True)
class Reproduction:
    """A registered seed reproduction.

    Attributes
    ----------
    key, seed, title, source : str
        See `PaperComparison`.
    applies : callable
        ``applies(inputs) -> bool``.
    compute : callable
        ``compute(inputs) -> tuple of PaperRow``.
    intro : str, optional
        See `PaperComparison`.
    """

    key: str
    seed: str
    title: str
    source: str
    applies: Callable[[ReportInputs], bool]
    compute: Callable[[ReportInputs], tuple[PaperRow, ...]]
    intro: str = ""


def cell_number(x: Any, digits: int = 5) -> Tex:
    """A number as a table cell (inline math).

    Parameters
    ----------
    x : float or str
        The number (its own unit).
    digits : int, optional
        Significant digits.
    """
    return Tex("$" + format_number(x, digits) + "$")


def cell_fit(math_tex: str) -> Tex:
    """Math shrunk to the table column when wider (``\\fitcell`` of the template).

    Parameters
    ----------
    math_tex : str
        Math-mode LaTeX (without ``$``).
    """
    return Tex(r"\fitcell{$" + math_tex + "$}")


def cell_terms(expr: Any, per_line: int = 2) -> Tex:
    """A long sympy sum as a table cell broken over lines, ``per_line`` terms per line.

    A common factor is kept in front (``z_1^2 (...)``) when the factored form has one;
    the lines are typeset at text size and shrunk only if one is still wider than the column.

    Parameters
    ----------
    expr : sympy.Expr
        The sum.
    per_line : int, optional
        Terms per line.
    """
    expr = sp.factor(expr)
    head, body = sp.Integer(1), expr
    if isinstance(expr, sp.Mul):
        sums = [f for f in expr.args if isinstance(sp.expand(f), sp.Add)]
        if len(sums) == 1:
            body = sp.expand(sums[0])
            head = sp.Mul(*[f for f in expr.args if f is not sums[0]])
    terms = list(sp.Add.make_args(sp.expand(body)))
    if len(terms) <= per_line:
        return cell_fit(sp.latex(expr))
    lines = []
    for k in range(0, len(terms), per_line):
        chunk = sp.latex(sp.Add(*terms[k:k + per_line], evaluate=False))
        if k and not chunk.startswith("-"):
            chunk = "+ " + chunk
        lines.append(chunk)
    pre = "" if head == 1 else ("-" if head == -1 else sp.latex(head)) + r"\,\bigl("
    post = "" if head == 1 else r"\bigr)"
    rows = [(pre if i == 0 else r"\quad ") + line + (post if i == len(lines) - 1 else "")
            for i, line in enumerate(lines)]
    return Tex(r"\fitcell{$\begin{aligned}[t]" + r" \\ ".join("&" + r for r in rows)
               + r"\end{aligned}$}")


def cell_matrix(a: Any, digits: int = 4) -> Tex:
    """A matrix as a table cell, shrunk to the column when wider.

    Parameters
    ----------
    a : array_like
        The matrix (its own units).
    digits : int, optional
        Significant digits.
    """
    return cell_fit(matrix_latex(a, digits))


def close(a: Any, b: Any, rtol: float = 1e-9) -> bool:
    """Same shape and every entry within ``rtol`` times the largest absolute entry of either.

    Parameters
    ----------
    a, b : array_like
        The two arrays (same units).
    rtol : float, optional
        Relative tolerance (dimensionless).
    """
    a, b = np.asarray(a), np.asarray(b)
    kind = complex if (np.iscomplexobj(a) or np.iscomplexobj(b)) else float
    a, b = a.astype(kind), b.astype(kind)
    if a.shape != b.shape:
        return False
    scale = max(float(np.max(np.abs(a), initial=0.0)), float(np.max(np.abs(b), initial=0.0)), 1e-300)
    return bool(np.all(np.abs(a - b) <= rtol * scale))


def artefact_array(artefact: Mapping[str, Any], name: str) -> np.ndarray | None:
    """The gain ``name`` of an artefact as a float array (None when absent or not numeric).

    Parameters
    ----------
    artefact : mapping
        A loaded artefact.
    name : str
        Name of the gain.
    """
    g = (artefact.get("gains") or {}).get(name)
    if g is None:
        return None
    try:
        return np.asarray(g, dtype=float)
    except (TypeError, ValueError):
        return None


def artefact_arrays(artefact: Mapping[str, Any],
                    shapes: Mapping[str, tuple[int, ...]]) -> dict[str, np.ndarray] | None:
    """The gains named in ``shapes`` as float arrays, when every one is there with its shape.

    Parameters
    ----------
    artefact : mapping
        A loaded artefact.
    shapes : mapping of str to tuple of int
        Name of each gain and its required shape.

    Returns
    -------
    dict or None
        Name -> array (the gain's own units); None when one is absent, not numeric or of
        another shape.
    """
    arrays = {name: artefact_array(artefact, name) for name in shapes}
    found = {name: a for name, a in arrays.items() if a is not None and a.shape == shapes[name]}
    return found if len(found) == len(shapes) else None


def params_match(inputs: ReportInputs, expected: Mapping[str, float], rtol: float = 1e-12) -> bool:
    """True when the plant has every parameter of ``expected`` with that value.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (the plant's parameters).
    expected : mapping of str to float
        Parameter values (parameter units, SI).
    rtol : float, optional
        Relative tolerance (dimensionless).
    """
    have = inputs.parameters()
    return all(k in have and math.isclose(have[k], v, rel_tol=rtol, abs_tol=0.0)
               for k, v in expected.items())


def first_artefact(inputs: ReportInputs, method: str, x0: Sequence[float] | None = None,
                   shapes: Mapping[str, tuple[int, ...]] | None = None) -> Mapping[str, Any] | None:
    """The first artefact of ``method`` with gains of the given shapes (and operating point ``x_op``, if given).

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (artefacts of the output directory).
    method : str
        Design method name.
    x0 : sequence of float, optional
        Required operating point, gain ``x_op`` (state units, m); None: any.
    shapes : mapping of str to tuple of int, optional
        Required shape of each named gain; None: any.
    """
    for a in inputs.by_method(method):
        if shapes and artefact_arrays(a, shapes) is None:
            continue
        if x0 is not None:
            ax0 = artefact_array(a, "x_op")
            if ax0 is None or ax0.shape != (len(x0),) or not np.allclose(ax0, x0, rtol=0, atol=1e-9):
                continue
        return a
    return None


def printed_precision(text: str) -> float:
    """Half a unit of the last printed digit of a number written as text.

    Parameters
    ----------
    text : str
        The number as printed.
    """
    mant, _, exp = text.lower().partition("e")
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    return 0.5 * 10.0 ** (-decimals) * 10.0 ** (int(exp) if exp else 0)


def latex_matrix_entries(tex: str) -> list[list[str]] | None:
    """Entries of a sympy ``\\left[\\begin{matrix}..\\end{matrix}\\right]`` string.

    Parameters
    ----------
    tex : str
        LaTeX written by ``sympy.latex`` for a matrix.
    """
    head, tail = r"\left[\begin{matrix}", r"\end{matrix}\right]"
    if not (isinstance(tex, str) and tex.startswith(head) and tex.endswith(tail)):
        return None
    body = tex[len(head):-len(tail)]
    rows, cur, depth, i = [], [""], 0, 0
    while i < len(body):
        c = body[i]
        if body.startswith("\\\\", i) and depth == 0:
            rows.append(cur)
            cur = [""]
            i += 2
            continue
        if body.startswith("\\begin{", i) or body.startswith("\\end{", i):
            depth += 1 if body.startswith("\\begin{", i) else -1
            end = body.index("}", i) + 1
            cur[-1] += body[i:end]
            i = end
            continue
        if c == "\\" and i + 1 < len(body):
            cur[-1] += body[i:i + 2]
            i += 2
            continue
        if c == "{":
            depth += 1
        elif c == "}":
            depth -= 1
        if c == "&" and depth == 0:
            cur.append("")
        else:
            cur[-1] += c
        i += 1
    rows.append(cur)
    return [[e.strip() for e in r] for r in rows]


def poly_latex(coeffs: Sequence[float] | np.ndarray, var: str = "s") -> str:
    """Math-mode LaTeX of a polynomial given by its coefficients, highest power first.

    Parameters
    ----------
    coeffs : sequence of float or ndarray
        Coefficients, highest power first.
    var : str, optional
        Name of the variable.
    """
    n = len(coeffs) - 1
    parts = []
    for k, c in enumerate(coeffs):
        p = n - k
        if c == 0 and p < n:
            continue
        mag = format_number(abs(c), 5)
        term = ("" if (abs(c) == 1 and p > 0) else mag) + (f"{var}^{{{p}}}" if p > 1 else
                                                            (var if p == 1 else ""))
        parts.append(("-" if c < 0 else "+") + " " + term)
    text = " ".join(parts).lstrip("+ ").strip()
    return text if not text.startswith("- ") else "-" + text[2:]


def verdict_check(artefact: Mapping[str, Any], name: str) -> Mapping[str, Any] | None:
    """The check ``name`` of an artefact's stored verdict (None when absent).

    Parameters
    ----------
    artefact : mapping
        A loaded artefact.
    name : str
        The check's name (``"servo_scenario"`` ...).
    """
    for c in (artefact.get("verification") or {}).get("checks") or ():
        if isinstance(c, Mapping) and c.get("check") == name:
            return c
    return None


def ratio_note(ours: float, printed: float, factor: float = 2.0) -> tuple[bool, str]:
    """Whether ``ours`` is within a factor of ``printed``, and the ratio as a note.

    Parameters
    ----------
    ours, printed : float
        The two values (same units); ``ours`` may be inf or nan (never reached).
    factor : float, optional
        Largest accepted ratio either way (dimensionless).

    Returns
    -------
    tuple of (bool, str)
        True when ``printed / factor <= ours <= factor printed`` (both of one sign);
        LaTeX text of the ratio ("ours / printed = ...") or why there is none.
    """
    if not math.isfinite(ours):
        return False, "never reached in the simulation (paper: " + format_number(printed, 4) + ")"
    if printed == 0:
        return ours == 0, "printed value is 0"
    r = ours / printed
    ok = r > 0 and 1 / factor <= r <= factor
    return ok, (f"ours / printed $= {format_number(r, 3)}$"
                + ("" if ok else f" (outside the factor-{format_number(factor, 2)} band: not reproduced)"))
