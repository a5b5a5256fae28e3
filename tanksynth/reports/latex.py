"""LaTeX building blocks: escaping, number, unit and matrix formatting, the template engine.

Everything that ends up in ``report.tex`` passes through this module. User
strings (titles, names, assumption texts, solver messages) are escaped with
`escape_latex`; LaTeX we generate ourselves is marked as `Tex` so that the
template engine does not escape it a second time. The Jinja2 environment
escapes every value that is not `Tex`, so forgetting a filter in a template
gives ugly text, never a LaTeX error.

Long equations are split by `tanksynth.reports.equations`; the PDF is built by
`tanksynth.reports.pdf`.
"""

from __future__ import annotations

import math
import re
import unicodedata
from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np

from tanksynth.errors import ParseError

__all__ = [
    "Tex",
    "escape_latex",
    "format_number",
    "format_complex",
    "format_eigenvalues",
    "format_unit",
    "symbol_latex",
    "gain_symbol",
    "notation_symbol",
    "expression_latex",
    "matrix_latex",
    "round_relative",
    "gain_latex",
    "GainDisplay",
    "environment",
]


class Tex(str):
    """A string that already is LaTeX: the templates insert it unchanged."""

    __slots__ = ()


# ------------------------------------------------------------------ escaping
_SPECIAL = {
    "\\": r"\textbackslash{}",
    "{": r"\{",
    "}": r"\}",
    "$": r"\$",
    "&": r"\&",
    "#": r"\#",
    "%": r"\%",
    "_": r"\_",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
    "<": r"\textless{}",
    ">": r"\textgreater{}",
    "|": r"\textbar{}",
    '"': "''",
    "`": r"\textasciigrave{}",
}

# Non-ASCII characters the default (OT1) fonts can show, without extra packages.
_UNICODE = {
    "\u2013": "--", "\u2014": "---", "\u2018": "`", "\u2019": "'", "\u201c": "``",
    "\u201d": "''", "\u2026": r"\ldots{}", "\u00a0": r"\nobreakspace{}", "\u00b0": r"\textdegree{}",
    "\u00b5": r"\textmu{}", "\u00d7": r"\texttimes{}", "\u00b1": r"\textpm{}",
    "\u00b2": r"\texttwosuperior{}", "\u00b3": r"\textthreesuperior{}", "\u00a7": r"\S{}",
    "\u00df": r"\ss{}", "\u00e6": r"\ae{}", "\u00c6": r"\AE{}", "\u00f8": r"\o{}",
    "\u00d8": r"\O{}", "\u0153": r"\oe{}", "\u0152": r"\OE{}", "\u00e5": r"\aa{}",
    "\u00c5": r"\AA{}", "\u0142": r"\l{}", "\u0141": r"\L{}", "\u2212": "-{}",
    "\u2264": r"\ensuremath{\leq}", "\u2265": r"\ensuremath{\geq}",
    "\u2260": r"\ensuremath{\neq}", "\u2248": r"\ensuremath{\approx}",
    "\u2192": r"\ensuremath{\rightarrow}", "\u221e": r"\ensuremath{\infty}",
    "\u221a": r"\ensuremath{\surd}", "\u00b7": r"\ensuremath{\cdot}",
    "\u2202": r"\ensuremath{\partial}", "\u2211": r"\ensuremath{\sum}",
    "\u00ac": r"\ensuremath{\neg}", "\u00f7": r"\ensuremath{\div}",
    "\u20ac": "EUR", "\u00a9": r"\copyright{}", "\u2022": r"\textbullet{}",
}
_GREEK = {
    "alpha": "\u03b1", "beta": "\u03b2", "gamma": "\u03b3", "delta": "\u03b4",
    "epsilon": "\u03b5", "zeta": "\u03b6", "eta": "\u03b7", "theta": "\u03b8", "iota": "\u03b9",
    "kappa": "\u03ba", "lambda": "\u03bb", "mu": "\u03bc", "nu": "\u03bd", "xi": "\u03be",
    "pi": "\u03c0", "rho": "\u03c1", "sigma": "\u03c3", "tau": "\u03c4", "upsilon": "\u03c5",
    "phi": "\u03c6", "chi": "\u03c7", "psi": "\u03c8", "omega": "\u03c9",
    "Gamma": "\u0393", "Delta": "\u0394", "Theta": "\u0398", "Lambda": "\u039b", "Xi": "\u039e",
    "Pi": "\u03a0", "Sigma": "\u03a3", "Phi": "\u03a6", "Psi": "\u03a8", "Omega": "\u03a9",
}
for _name, _char in _GREEK.items():
    _UNICODE[_char] = rf"\ensuremath{{\{_name}}}"
_ACCENTS = {  # combining mark -> LaTeX accent command
    "\u0300": "`", "\u0301": "'", "\u0302": "^", "\u0303": "~", "\u0308": '"', "\u0304": "=",
    "\u0307": ".", "\u0327": "c", "\u030c": "v", "\u0306": "u", "\u030b": "H", "\u030a": "r",
}


def _escape_char(ch: str) -> str:
    if ch in _SPECIAL:
        return _SPECIAL[ch]
    code = ord(ch)
    if code < 128:
        if ch in "\n\r\t\f\v":
            return " "
        if code < 32 or code == 127:
            return ""
        return ch
    if ch in _UNICODE:
        return _UNICODE[ch]
    decomposed = unicodedata.normalize("NFD", ch)
    base, marks = decomposed[0], decomposed[1:]
    if len(marks) == 1 and marks in _ACCENTS and base.isascii() and base.isalpha():
        base_tex = {"i": r"\i", "j": r"\j"}.get(base, base)
        return rf"\{_ACCENTS[marks]}{{{base_tex}}}"
    # anything else: name the code point instead of failing the build
    return rf"\texttt{{[U+{code:04X}]}}"


def escape_latex(text: Any, breakable: bool = False) -> Tex:
    """Escape arbitrary text for LaTeX text mode.

    Parameters
    ----------
    text : object
        Converted with ``str``. ``None`` gives an empty string.
    breakable : bool
        Allow line breaks after ``/ _ - . :`` and every 16 characters of an
        unbroken run (paths, hashes, long identifiers in narrow columns).

    Returns
    -------
    Tex
        Safe to insert in text mode: every LaTeX special character, control
        character and non-ASCII character is replaced by a command that the
        default fonts can typeset.
    """
    if text is None:
        return Tex("")
    s = str(text)
    out: list[str] = []
    run = 0
    for i, ch in enumerate(s):
        if ch == "-" and i + 1 < len(s) and s[i + 1] == "-":
            out.append("-{}")  # no en/em-dash ligatures from user text
        else:
            out.append(_escape_char(ch))
        run = 0 if ch.isspace() else run + 1
        if breakable and i + 1 < len(s) and not s[i + 1].isspace() and (
                ch in "/_" or (ch in "-.:," and not s[i + 1].isdigit()) or run >= 20):
            out.append(r"\allowbreak{}")
            run = 0
    return Tex("".join(out))


# ----------------------------------------------------------------- numbers
def _exp_form(mantissa: str, exponent: int) -> str:
    if mantissa in ("1", "1.0"):
        return f"10^{{{exponent}}}"
    if mantissa in ("-1", "-1.0"):
        return f"-10^{{{exponent}}}"
    return rf"{mantissa} \times 10^{{{exponent}}}"


def format_number(value: Any, digits: int = 5) -> Tex:
    """Math-mode LaTeX (without ``$``) for a number, ``digits`` significant digits.

    Uses fixed notation between 1e-4 and 10**digits, otherwise
    ``m \\times 10^{e}``. Accepts the strings ``"inf"``, ``"-inf"``, ``"nan"``
    written by `tanksynth.artefacts.io.to_jsonable`, booleans and ``None``.

    Parameters
    ----------
    value : float, int, bool, str or None
        The number (its own unit).
    digits : int, optional
        Significant digits.
    """
    if value is None:
        return Tex(r"\text{--}")
    if isinstance(value, (bool, np.bool_)):
        return Tex(r"\text{yes}" if value else r"\text{no}")
    if isinstance(value, str):
        low = value.strip().lower()
        if low in ("inf", "+inf", "infinity"):
            return Tex(r"\infty")
        if low in ("-inf", "-infinity"):
            return Tex(r"-\infty")
        if low == "nan":
            return Tex(r"\text{NaN}")
        return Tex(r"\text{" + escape_latex(value) + "}")
    if isinstance(value, (int, np.integer)):
        return Tex(str(int(value)))
    if isinstance(value, (complex, np.complexfloating)):
        return format_complex(float(value.real), float(value.imag), digits)
    x = float(value)
    if math.isnan(x):
        return Tex(r"\text{NaN}")
    if math.isinf(x):
        return Tex(r"\infty" if x > 0 else r"-\infty")
    if x == 0.0:
        return Tex("0")
    s = f"{x:.{digits}g}"
    if "e" in s:
        mantissa, exp = s.split("e")
        return Tex(_exp_form(mantissa, int(exp)))
    return Tex(s)


def format_complex(re_: float, im: float, digits: int = 5) -> Tex:
    """Math-mode LaTeX of ``re + j im`` (``re`` alone when ``im == 0``).

    Parameters
    ----------
    re_ : float
        Real part (its own unit, e.g. 1/s for an eigenvalue).
    im : float
        Imaginary part (same unit).
    digits : int, optional
        Significant digits.
    """
    re_, im = float(re_), float(im)
    if im == 0.0:
        return format_number(re_, digits)
    mag = format_number(abs(im), digits)
    sign = "-" if im < 0 else "+"
    if re_ == 0.0:
        return Tex(("-" if im < 0 else "") + mag + r"\,\mathrm{j}")
    return Tex(f"{format_number(re_, digits)} {sign} {mag}" + r"\,\mathrm{j}")


def _as_complex_list(values: Any) -> list[complex]:
    arr = values if isinstance(values, list) else list(np.asarray(values).tolist())
    out = []
    for v in arr:
        if isinstance(v, (list, tuple)) and len(v) == 2:
            out.append(complex(float(v[0]), float(v[1])))
        elif isinstance(v, (list, tuple)):
            raise ValueError("not an eigenvalue list")
        else:
            out.append(complex(float(v), 0.0))
    return out


def format_eigenvalues(values: Any, digits: int = 5, limit: int = 24) -> Tex:
    """Math-mode list of eigenvalues; conjugate pairs are written ``a \\pm b j``.

    ``values`` is a list of numbers or of ``[re, im]`` pairs (the artefact
    convention for complex numbers). At most ``limit`` entries are shown.

    Parameters
    ----------
    values : sequence
        Numbers or ``[re, im]`` pairs (1/s in continuous time, dimensionless in discrete time).
    digits : int, optional
        Significant digits.
    limit : int, optional
        Largest number of entries shown.
    """
    vals = _as_complex_list(values)
    used = [False] * len(vals)
    parts: list[str] = []
    for i, v in enumerate(vals):
        if used[i]:
            continue
        used[i] = True
        if v.imag != 0.0:
            for j in range(i + 1, len(vals)):
                w = vals[j]
                if not used[j] and abs(w.real - v.real) <= 1e-12 * max(1.0, abs(v.real)) \
                        and abs(w.imag + v.imag) <= 1e-12 * max(1.0, abs(v.imag)):
                    used[j] = True
                    parts.append(f"{format_number(v.real, digits)} \\pm "
                                 f"{format_number(abs(v.imag), digits)}\\,\\mathrm{{j}}")
                    break
            else:
                parts.append(format_complex(v.real, v.imag, digits))
        else:
            parts.append(format_number(v.real, digits))
    shown = parts[:limit]
    text = ",\\allowbreak\\; ".join(shown)
    if len(parts) > limit:
        text += rf",\;\ldots\ (\text{{{len(parts) - limit} more}})"
    return Tex(text)


_UNIT_TOKEN = re.compile(r"([A-Za-z]+|\d+(?:\.\d+)?)(?:\^(\(?-?\d+(?:\.\d+)?\)?))?")


def format_unit(unit: Any) -> Tex:
    """LaTeX (text mode) for a unit string such as ``m^3/s`` or ``m/s^2``.

    ``"1"`` or ``""`` (dimensionless) gives a dash. Strings outside the
    simple ``name^exp`` grammar are escaped as plain text.

    Parameters
    ----------
    unit : str
        The unit, e.g. ``m^3/s``.
    """
    if unit is None:
        return Tex("--")
    u = str(unit).strip()
    if u in ("", "1", "-"):
        return Tex("--")
    if not re.fullmatch(r"[A-Za-z0-9^/*.() \-]+", u):
        return escape_latex(u)
    out: list[str] = []
    pos = 0
    for m in _UNIT_TOKEN.finditer(u):
        between = u[pos:m.start()]
        out.append(_unit_sep(between))
        base, exp = m.group(1), m.group(2)
        piece = rf"\mathrm{{{base}}}"
        if exp:
            piece += "^{" + exp.strip("()") + "}"
        out.append(piece)
        pos = m.end()
    tail = u[pos:]
    if tail.strip(" ()"):
        return escape_latex(u)
    out.append(_unit_sep(tail))
    return Tex("$" + "".join(out) + "$")


def _unit_sep(text: str) -> str:
    """The separator between two unit tokens, character by character (``/(`` stays ``/(``)."""
    t = text.strip()
    if not t:
        return r"\," if text else ""
    marks = {"/": "/", "*": r"\,", ".": r"\,", "(": "(", ")": ")", "-": "-", "^": "^"}
    return "".join(marks.get(ch, "") for ch in t if not ch.isspace())


_IDENT = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")


def symbol_latex(name: Any) -> Tex:
    """Math-mode LaTeX of a symbol name, as sympy prints it (``mu13`` -> ``\\mu_{13}``).

    Names that are not plain identifiers are escaped and set upright.

    Parameters
    ----------
    name : str
        Name of the symbol.
    """
    s = str(name)
    if _IDENT.match(s):
        import sympy as sp  # here, not at the top: see `expression_latex`

        return Tex(sp.latex(sp.Symbol(s)))
    return Tex(r"\text{" + escape_latex(s) + "}")


#: The report's one notation for the operating point, a second (set-point) one and the estimate:
#: artefact keys and plain-text names -> math-mode LaTeX (also valid matplotlib mathtext).
NOTATION = {"x_op": "x_0", "u_op": "u_0", "y_op": "y_0", "x0": "x_0", "u0": "u_0",
            "x_op2": r"x_0^{\prime}", "u_op2": r"u_0^{\prime}", "x_hat": r"\hat{x}",
            "x_hat0": r"\hat{x}_0", "y_hat": r"\hat{y}",
            "sp_x_op": r"x_0^{\prime}", "sp_u_op": r"u_0^{\prime}"}   # the set-point design's gains


def notation_symbol(key: Any) -> Tex | None:
    """Math-mode LaTeX (without ``$``) of an operating-point or estimate name, None for others.

    ``x_op`` and ``x0`` are both :math:`x_0`, ``x_op2`` is :math:`x_0'`, ``x_hat0`` is
    :math:`\\hat x_0`: the notation of the report's statements. The same string is valid
    matplotlib mathtext (figure legends and axis labels).

    Parameters
    ----------
    key : str
        The name (an artefact gain key or a word of plain text).
    """
    tex = NOTATION.get(str(key))
    return Tex(tex) if tex is not None else None


_GREEK_NAMES = {"alpha", "beta", "gamma", "delta", "epsilon", "kappa", "lambda", "mu", "nu", "rho",
                "sigma", "tau", "phi", "psi", "omega", "theta", "eta", "xi", "zeta", "chi",
                "Gamma", "Delta", "Lambda", "Phi", "Psi", "Omega", "Theta", "Sigma", "Xi"}

#: Gains whose key is a description rather than a symbol: the words of the report.
_GAIN_WORDS = {"covariance": r"\operatorname{Cov}(\hat{\theta})"}


def gain_symbol(name: Any) -> Tex:
    """Math-mode LaTeX of a gain name: short symbols as symbols (``K1`` -> ``K_{1}``, ``alpha``),
    longer identifiers upright and whole (``training_inputs``, ``ekf_P0``).

    Parameters
    ----------
    name : str
        Name of the gain.
    """
    s = str(name)
    notation = notation_symbol(s)
    if notation is not None:
        return notation
    if s in _GAIN_WORDS:
        return Tex(_GAIN_WORDS[s])
    greek = "|".join(sorted(_GREEK_NAMES, key=len, reverse=True))
    short = re.fullmatch(r"[A-Za-z]{1,2}\d{0,2}|[A-Za-z][A-Za-z0-9]?_[A-Za-z0-9]{1,3}", s)
    if short or s in _GREEK_NAMES or re.fullmatch(r"(%s)\d{0,2}" % greek, s) \
            or re.fullmatch(r"(%s)_[A-Za-z0-9]{1,3}" % greek, s):
        return symbol_latex(s)
    sub = re.fullmatch(r"([A-Za-z])_([a-z]{4,12})", s)
    if sub:   # x_init: a symbol with a word as its index
        return Tex(f"{symbol_latex(sub.group(1))}_{{\\mathrm{{{sub.group(2)}}}}}")
    # a longer identifier (training_inputs): its words, upright, never a raw key with underscores
    return Tex(r"\text{" + escape_latex(s.replace("_", " ")) + "}")


def expression_latex(text: Any) -> Tex | None:
    """Math-mode LaTeX of an expression string written by sympy (``str(expr)``).

    The text goes through the whitelist parser of `tanksynth.plants.parser`
    (never ``eval``/``sympify``); every identifier becomes a symbol. Returns
    None when the text is outside that grammar (the caller then shows it
    verbatim).

    Parameters
    ----------
    text : str
        The expression as ``str(expr)`` writes it (any other value gives None).
    """
    if not isinstance(text, str) or not text.strip() or len(text) > 4000:
        return None
    # sympy (with the parser, about 0.5 s) is imported where symbols are typeset, not at the top:
    # every problem statement (`tanksynth.reports.statements`) builds on this module and needs none
    import sympy as sp

    from tanksynth.plants.parser import FUNCTIONS, parse_expression

    names = {n: sp.Symbol(n) for n in set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", text))
             if n not in FUNCTIONS}
    try:
        expr = parse_expression(text, names, key="report")
    except (ParseError, ValueError, TypeError, RecursionError):
        return None
    return Tex(sp.latex(expr))


# ----------------------------------------------------------------- matrices
#: Full display limits: larger gains are summarised.
MAX_ROWS, MAX_COLS, MAX_VECTOR = 16, 12, 16


#: Entries below this fraction of a matrix's largest entry print as 0 (round-off of a product
#: such as ``A - B K``: ``1e-19`` beside entries of order 1 is no information).
RELATIVE_ZERO = 1e-12


def round_relative(arr: Any, relative: float = RELATIVE_ZERO) -> np.ndarray:
    """A float copy of ``arr`` with entries below ``relative`` times its largest finite
    magnitude set to 0.

    Parameters
    ----------
    arr : array_like
        The matrix or vector (its own units).
    relative : float, optional
        Threshold as a fraction of the largest finite ``|entry|`` (dimensionless).

    Returns
    -------
    numpy.ndarray
        Same shape; nonfinite entries are kept.
    """
    a = np.array(arr, dtype=float)
    finite = np.isfinite(a)
    if not finite.any():
        return a
    scale = float(np.max(np.abs(a[finite])))
    a[finite & (np.abs(a) < relative * scale)] = 0.0
    return a


def _common_exponent(arr: np.ndarray) -> int:
    finite = np.abs(arr[np.isfinite(arr)])
    nz = finite[finite > 0]
    if nz.size == 0:
        return 0
    e = int(math.floor(math.log10(float(nz.max()))))
    return e if (e <= -3 or e >= 5) else 0


def matrix_latex(arr: Any, digits: int = 5, factor: bool = True) -> Tex:
    """Math-mode ``bmatrix`` of a 1-D or 2-D array (1-D shown as a column).

    Parameters
    ----------
    arr : array_like
    digits : int
        Significant digits per entry.
    factor : bool
        Pull a common power of ten out when the largest entry is below 1e-2
        or at least 1e5 (``10^{-4} [ ... ]``, as papers print gains).

    Entries below `RELATIVE_ZERO` times the largest ``|entry|`` print as 0 (`round_relative`).
    """
    a = np.asarray(arr, dtype=float)
    if a.ndim == 0:
        return format_number(float(a), digits)
    a = round_relative(a)
    if a.ndim == 1:
        a = a.reshape(-1, 1)
    e = _common_exponent(a) if factor else 0
    scaled = a / 10.0**e if e else a
    rows = [" & ".join(format_number(v, digits) for v in row) for row in scaled]
    body = r"\begin{bmatrix}" + r" \\ ".join(rows) + r"\end{bmatrix}"
    return Tex((f"10^{{{e}}}\\," if e else "") + body)


@dataclass(frozen=True)
class GainDisplay:
    """How one gain is shown: a full matrix or a summary of a large array.

    Attributes
    ----------
    name : str
        Gain name (raw; escape when typesetting).
    shape : tuple of int
    full : bool
        True when ``latex`` holds every entry.
    latex : Tex
        Math-mode matrix when ``full``; otherwise empty.
    summary : tuple of (str, Tex)
        Label (plain text) and math-mode value rows for large gains.
    unit : Tex
        The gain's unit, text mode (`format_unit`); empty when not known.
    """

    name: str
    shape: tuple[int, ...]
    full: bool
    latex: Tex
    summary: tuple[tuple[str, Tex], ...]
    unit: Tex = Tex("")

    @property
    def shape_latex(self) -> Tex:
        """The shape as ``n \\times m`` (math mode)."""
        if not self.shape:
            return Tex(r"\text{scalar}")
        return Tex(r" \times ".join(str(s) for s in self.shape))


def _index(idx: tuple[int | np.integer, ...]) -> str:
    return "(" + ",".join(str(i + 1) for i in idx) + ")"


def gain_latex(name: str, arr: Any, digits: int = 5) -> GainDisplay:
    """Full matrix for small gains, a summary (shape, norms, first/last entries) for large ones.

    Vectors up to 16 entries and matrices up to 16 x 12 are shown in full;
    larger arrays and every array of three or more dimensions (gain
    sequences) are summarised.

    Parameters
    ----------
    name : str
        Name of the gain.
    arr : array_like
        Its value (the gain's own units).
    digits : int, optional
        Significant digits.
    """
    a = np.asarray(arr, dtype=float)
    shape = tuple(int(s) for s in a.shape)
    small = (a.ndim <= 1 and a.size <= MAX_VECTOR) or \
        (a.ndim == 2 and shape[0] <= MAX_ROWS and shape[1] <= MAX_COLS)
    if a.size == 1:  # a scalar is a scalar, not [20]^T
        return GainDisplay(name, shape, True, format_number(float(a.ravel()[0]), digits), ())
    if small:
        if a.ndim == 1:
            a = round_relative(a)
            e = _common_exponent(a)
            scaled = a / 10.0**e if e else a
            body = r"\begin{bmatrix}" + " & ".join(format_number(v, digits) for v in scaled) \
                + r"\end{bmatrix}^{\top}"
            tex = Tex((f"10^{{{e}}}\\," if e else "") + body)
        else:
            tex = matrix_latex(a, digits)
        return GainDisplay(name, shape, True, tex, ())
    flat = a.ravel()
    finite = flat[np.isfinite(flat)]
    rows: list[tuple[str, Tex]] = [
        ("Frobenius norm", format_number(float(np.linalg.norm(finite)), digits)),
        ("largest |entry|", format_number(float(np.max(np.abs(finite))) if finite.size else 0.0,
                                          digits)),
        ("nonzero entries", Tex(f"{int(np.count_nonzero(flat))} / {flat.size}")),
    ]
    if a.ndim == 2 and shape[0] == shape[1]:
        try:
            rho = float(np.max(np.abs(np.linalg.eigvals(a))))
            rows.append(("spectral radius", format_number(rho, digits)))
        except np.linalg.LinAlgError:  # pragma: no cover - eigvals of a finite matrix
            pass
    if a.ndim >= 3:
        first, last = a[0], a[-1]
        rows.append((f"norm of slice 1 (of {shape[0]})", format_number(float(np.linalg.norm(first)),
                                                                         digits)))
        rows.append((f"norm of slice {shape[0]}", format_number(float(np.linalg.norm(last)), digits)))
    k = min(4, flat.size)
    idx_first = [np.unravel_index(i, shape) for i in range(k)]
    idx_last = [np.unravel_index(i, shape) for i in range(flat.size - k, flat.size)]
    rows.append(("first entries", Tex(r",\; ".join(
        f"{_index(ix)}: {format_number(a[ix], digits)}" for ix in idx_first))))
    rows.append(("last entries", Tex(r",\; ".join(
        f"{_index(ix)}: {format_number(a[ix], digits)}" for ix in idx_last))))
    return GainDisplay(name, shape, False, Tex(""), tuple(rows))


# ------------------------------------------------------------------ Jinja2
def _finalize(value: Any) -> Any:
    if isinstance(value, Tex):
        return value
    if value is None:
        return ""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, float, np.integer, np.floating)):
        return Tex("$" + format_number(value) + "$")
    return escape_latex(value)


def _math(value: Any, digits: int = 5) -> Tex:
    return Tex("$" + format_number(value, digits) + "$")


def _texjoin(items: Iterable[Any], sep: str = ", ") -> Tex:
    return Tex(sep.join(_finalize(i) for i in items))


def environment():
    """The Jinja2 environment for the report templates.

    Delimiters are chosen not to clash with LaTeX braces: ``((* block *))``,
    ``((( expression )))``, ``((= comment =))``. Every expression that is not
    `Tex` is escaped; numbers are formatted with `format_number`.
    """
    import jinja2  # only to render a report: the statements and figures that use this module do not

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("tanksynth.reports", "templates"),
        block_start_string="((*", block_end_string="*))",
        variable_start_string="(((", variable_end_string=")))",
        comment_start_string="((=", comment_end_string="=))",
        trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
        autoescape=False, undefined=jinja2.StrictUndefined, finalize=_finalize,
    )
    env.filters.update({
        "e": escape_latex,
        "tex": lambda s: Tex(s),
        "num": _math,
        "unit": format_unit,
        "sym": lambda s: Tex("$" + symbol_latex(s) + "$"),
        "symm": symbol_latex,
        "gsym": gain_symbol,
        "texjoin": _texjoin,
        "breakable": lambda s: escape_latex(s, breakable=True),
    })
    return env
