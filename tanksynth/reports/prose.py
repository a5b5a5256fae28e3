"""Plain-text prose (check details, notes, solver messages) typeset as LaTeX.

The verdicts, rank checks and designs explain themselves in plain text meant
for a terminal as well (``|e|_inf <= 5 %``, ``X = P^-1``, ``[0.95-0.01j, ...]``,
``['h1', 'h2']``). `prose_latex` escapes such text and typesets the
fragments a reader would expect as mathematics: number lists as vectors (a
conjugate pair as ``a \\pm b j``), nested number lists as matrices, lists of
names as names, ``<=``/``>=``/``!=``/``->`` as relations, ``P^-1`` and
``L_f^k`` as super/subscripts, Greek names (``lambda_max``, ``psi``) as Greek
letters, ``(x)`` as the Kronecker product, ``M'`` as a transpose, numbers in
exponent notation as ``m \\times 10^{e}``, and the units ``m^3/s`` and ``m^2``.
Anything it does not recognise is escaped as text, so any string renders.
"""

from __future__ import annotations

import math
import re
from typing import Any

from tanksynth.reports.latex import (Tex, escape_latex, format_eigenvalues, format_number,
                                     format_unit, notation_symbol, symbol_latex)

__all__ = ["prose_latex", "list_latex", "distinct_digits"]

_GREEK = ("alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "kappa", "lambda",
          "mu", "nu", "xi", "rho", "sigma", "tau", "phi", "varphi", "chi", "psi", "omega",
          "Gamma", "Delta", "Theta", "Lambda", "Xi", "Sigma", "Phi", "Psi", "Omega")
_G = "|".join(sorted(_GREEK, key=len, reverse=True))
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_CPLX = rf"{_NUM}[-+](?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?j"
_BASE = rf"(?:{_G}|[A-Za-z]{{1,2}})"
_SCRIPT = r"(?:max|min|inf|[A-Za-z0-9]{1,3})"
_SUP = r"\^(?:\(-?[A-Za-z0-9.]{1,4}\)|-?[A-Za-z0-9.]{1,4})"   # ^(-1) with both brackets, or ^-1

_TOKEN = re.compile(
    r"(?P<list>\[(?:[^\[\]]|\[[^\[\]]*\])*\])"
    r"|(?P<norm>\|[^|\s][^|]{0,18}\|_(?:inf|2|F)\b)"
    r"|(?P<unit>\b(?:m|l|s)\^\d(?:/s(?:\^\d)?)?(?![\w^]))"
    r"|(?P<notation>(?<![\w.])(?:[xuy]_op2?|x_hat0?|y_hat)(?![\w]))"
    r"|(?P<hat>\b[A-Za-z]_hat\b)"
    rf"|(?P<sub>(?<![\w.-])-?{_BASE}_{_SCRIPT}(?:{_SUP})?(?![\w]))"
    rf"|(?P<sup>(?<![\w.-])-?{_BASE}{_SUP}(?![\w]))"
    rf"|(?P<trans>(?<![\w.'])(?:{_G}|[A-Z][A-Za-z0-9]?|[a-z])'(?=[\s,;.:)\]]|$)|\)'(?=[\s,;.:)\]]|$))"
    rf"|(?P<greek>(?<![\w.-])-?(?:{_G})(?![\w]))"
    r"|(?P<kron>(?<=\s)\(x\)(?=\s))"
    rf"|(?P<cplx>(?<![\w.]){_CPLX}(?![\w.]))"
    r"|(?P<sci>(?<![\w.])-?(?:\d+\.?\d*|\.\d+)[eE][-+]?\d+(?![\w.]))"
    r"|(?P<neg>(?<![\w.)\]])-(?:\d+\.?\d*|\.\d+)(?![\w.]))"
    r"|(?P<idx>(?<![\w.\-])[A-Za-z]\d{1,2}(?![\w.]))"
    r"|(?P<op><=|>=|!=|->|=>|\+-|(?<=\s)[<>](?=\s))"
)

_OPS = {"<=": r"\leq", ">=": r"\geq", "!=": r"\neq", "->": r"\to", "=>": r"\Rightarrow",
        "+-": r"\pm", "<": "<", ">": ">"}
_ITEM = re.compile(rf"\s*(?:(?P<c>{_CPLX})|(?P<n>{_NUM}|nan|inf|-inf)|'(?P<s>[^']*)'|\"(?P<d>[^\"]*)\")\s*")


def _base_tex(base: str) -> str:
    return "\\" + base if base in _GREEK else base


def _script_tex(script: str) -> str:
    return {"max": r"\max", "min": r"\min", "inf": r"\infty"}.get(script, script)


def _sup_tex(sup: str) -> str:
    return "^{" + sup.lstrip("^").strip("()") + "}"


def _parse_items(body: str) -> list[Any] | None:
    """Items of a flat Python/numpy list body: numbers, complex numbers or quoted strings."""
    body = body.strip()
    if not body:
        return []
    parts = [p for p in re.split(r",|\s+(?=[-+\d.'\"n])", body) if p.strip()]
    out: list[Any] = []
    for p in parts:
        m = _ITEM.fullmatch(p)
        if not m:
            return None
        if m.group("c"):
            out.append(complex(m.group("c")))
        elif m.group("n"):
            out.append(float(m.group("n")))
        else:
            out.append(m.group("s") if m.group("s") is not None else m.group("d"))
    return out


def list_latex(values: list[Any], digits: int = 4) -> Tex | None:
    """Math (with ``$``) for a list of numbers (a vector), complex numbers or names; None otherwise.

    Parameters
    ----------
    values : list
        Numbers, ``[re, im]`` pairs or names.
    digits : int, optional
        Significant digits.
    """
    if not values:
        return Tex(r"$[\,]$")
    if all(isinstance(v, str) for v in values):
        return Tex(", ".join("$" + symbol_latex(v) + "$" if re.fullmatch(r"[A-Za-z]\w*", v)
                             else escape_latex(v) for v in values))
    if all(isinstance(v, complex) for v in values) or (
            all(isinstance(v, (float, complex)) for v in values)
            and any(isinstance(v, complex) for v in values)):
        pairs = [[complex(v).real, complex(v).imag] for v in values]
        return Tex(r"$[" + format_eigenvalues(pairs, digits) + "]$")
    if all(isinstance(v, float) for v in values):
        digits = distinct_digits(values, digits)
        return Tex(r"$[" + r",\allowbreak\ ".join(format_number(v, digits) for v in values) + "]$")
    return None


def distinct_digits(values: list[float], digits: int = 4, most: int = 12) -> int:
    """The fewest significant digits, at least ``digits``, that print different values
    differently (a bisection bracket ``[0.066572611, 0.066572617]`` must not read
    ``[0.06657, 0.06657]``); at most ``most``.

    Parameters
    ----------
    values : list of float
        The numbers of one list (their own units).
    digits : int, optional
        Fewest significant digits.
    most : int, optional
        Most significant digits.
    """
    distinct = sorted({float(v) for v in values if math.isfinite(float(v))})
    if len(distinct) < 2:
        return digits
    for d in range(digits, most + 1):
        if len({f"{v:.{d}g}" for v in distinct}) == len(distinct):
            return d
    return most


def _list_tex(text: str) -> Tex:
    inner = text[1:-1]
    if "[" in inner:  # nested: a matrix of numbers, or of expressions
        rows = re.findall(r"\[([^\[\]]*)\]", inner)
        rest = re.sub(r"\[[^\[\]]*\]", "", inner)
        if rows and not rest.strip(" ,"):
            parsed = [_parse_items(r) for r in rows]
            numeric = [p for p in parsed if p and all(isinstance(v, float) for v in p)]
            if len(numeric) == len(parsed):
                body = r" \\ ".join(" & ".join(format_number(v, 4) for v in p) for p in numeric)
                return Tex(r"$\left[\begin{smallmatrix}" + body + r"\end{smallmatrix}\right]$")
            cells = [[c.strip() for c in r.split(",")] for r in rows]
            body = r" \\ ".join(" & ".join(_math_cell(c) for c in row) for row in cells)
            return Tex(r"$\left[\begin{smallmatrix}" + body + r"\end{smallmatrix}\right]$")
        return escape_latex(text, breakable=True)
    items = _parse_items(inner)
    if items is not None:
        tex = list_latex(items)
        if tex is not None:
            return tex
    return Tex("[" + prose_latex(inner) + "]")


def _math_cell(text: str) -> str:
    """An expression cell (``G' P + P G + psi^2 Q``) as math-mode LaTeX."""
    out = []
    for tok in re.findall(r"[A-Za-z]\w*(?:\^\(?-?\w+\)?)?'?|[-+*/=()]|\d+\.?\d*", text):
        trans = tok.endswith("'")
        tok = tok.rstrip("'")
        m = re.fullmatch(r"([A-Za-z]\w*)(\^\(?-?\w+\)?)?", tok)
        if m:
            base = m.group(1)
            t = _base_tex(base) if base in _GREEK else (base if len(base) <= 2 else
                                                        r"\mathrm{" + escape_latex(base) + "}")
            if m.group(2):
                t += _sup_tex(m.group(2))
            if trans:
                t += r"^{\top}"
            out.append(t)
        else:
            out.append(tok)
    return " ".join(out)


def _token_tex(kind: str, text: str) -> Tex:
    if kind == "list":
        return _list_tex(text)
    if kind == "norm":
        inner, sub = text[1:].rsplit("|_", 1)
        return Tex(r"$\|" + prose_math(inner) + r"\|_{" + _script_tex(sub) + "}$")
    if kind == "unit":
        return format_unit(text)
    if kind == "notation":
        return Tex("$" + (notation_symbol(text) or escape_latex(text)) + "$")
    if kind == "hat":
        return Tex(r"$\hat{" + text[0] + "}$")
    neg = "-" if text.startswith("-") and kind in ("sub", "sup", "greek") else ""
    text = text[len(neg):]
    if kind == "sub":
        m = re.fullmatch(rf"({_BASE})_({_SCRIPT})({_SUP})?", text)
        if m is None:  # pragma: no cover - the token regex matched it
            return escape_latex(text)
        t = _base_tex(m.group(1)) + "_{" + _script_tex(m.group(2)) + "}"
        return Tex("$" + neg + t + (_sup_tex(m.group(3)) if m.group(3) else "") + "$")
    if kind == "sup":
        m = re.fullmatch(rf"({_BASE})({_SUP})", text)
        if m is None:  # pragma: no cover
            return escape_latex(text)
        return Tex("$" + neg + _base_tex(m.group(1)) + _sup_tex(m.group(2)) + "$")
    if kind == "greek":
        return Tex("$" + neg + _base_tex(text) + "$")
    if kind == "trans":
        return Tex("$" + _base_tex(text[:-1]) + r"^{\top}$")
    if kind == "kron":
        return Tex(r"$\otimes$")
    if kind == "cplx":
        return Tex("$" + format_number(complex(text), 5) + "$")
    if kind in ("sci", "neg"):
        return Tex("$" + format_number(float(text), 4) + "$")
    if kind == "idx":
        return Tex("$" + text[0] + "_{" + text[1:] + "}$")
    if kind == "op":
        return Tex("$" + _OPS[text] + "$")
    return escape_latex(text)  # pragma: no cover


def prose_math(text: str) -> str:
    """A short plain-text expression (``e(0)``, ``x - x0``) in math mode (without ``$``)."""
    tex = prose_latex(text)
    return re.sub(r"\$", "", tex).replace(r"\textless{}", "<").replace(r"\textgreater{}", ">")


def prose_latex(text: Any, breakable: bool = True, literal: tuple[str, ...] = ()) -> Tex:
    """Plain-text prose as LaTeX text mode, with its mathematical fragments typeset.

    Parameters
    ----------
    text : object
        Converted with ``str``; None gives an empty string.
    breakable : bool
        Allow line breaks inside long runs of plain text (narrow table columns).
    literal : tuple of str
        Words set verbatim (escaped, never read as mathematics): names the
        user chose, such as a design called ``my_pp``, which would otherwise
        read as ``my`` with subscript ``pp``.

    Returns
    -------
    Tex
    """
    if text is None:
        return Tex("")
    s = " ".join(str(text).split())
    words = sorted({w for w in literal if w}, key=len, reverse=True)
    if words:
        pattern = re.compile("|".join(rf"(?<![\w.]){re.escape(w)}(?![\w])" for w in words))
        out, pos = [], 0
        for m in pattern.finditer(s):
            out.append(_typeset(s[pos:m.start()], breakable))
            out.append(escape_latex(m.group(0), breakable=breakable))
            pos = m.end()
        out.append(_typeset(s[pos:], breakable))
        return Tex("".join(out))
    return Tex(_typeset(s, breakable))


#: A quoted phrase: ``'every state settled (to the run's own equilibrium)'``; the opening quote
#: starts a word after a space, apostrophes inside sit between letters, there are several words
#: (a Python list of names ``['h1', 'h2']`` is not prose), the closing quote ends a word or a
#: bracket (not a transpose ``(A - L C)'``, which no opening quote precedes).
_QUOTED = re.compile(r"(?<![^\s(])'(?=\w)((?:[^']|(?<=\w)'(?=\w))*?\s(?:[^']|(?<=\w)'(?=\w))*?)'(?!\w)")


def _typeset(s: str, breakable: bool) -> str:
    """Escape ``s`` as text, its quoted phrases in typographic quotes, its recognised fragments
    as mathematics."""
    quoted = list(_QUOTED.finditer(s))
    if quoted:
        out, pos = [], 0
        for m in quoted:
            out += [_fragments(s[pos:m.start()], breakable), "`", _fragments(m.group(1), breakable), "'"]
            pos = m.end()
        return "".join(out + [_fragments(s[pos:], breakable)])
    return _fragments(s, breakable)


def _fragments(s: str, breakable: bool) -> str:
    """Escape ``s`` as text, its recognised fragments as mathematics."""
    out, pos = [], 0
    for m in _TOKEN.finditer(s):
        out.append(escape_latex(s[pos:m.start()], breakable=breakable))
        out.append(_token_tex(m.lastgroup or "", m.group(0)))
        pos = m.end()
    out.append(escape_latex(s[pos:], breakable=breakable))
    return "".join(out)
