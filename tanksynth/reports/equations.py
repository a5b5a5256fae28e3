"""Long display equations: a rough typeset width and splitting at top-level sums.

sympy prints a plant's equations on one line; `split_equation` breaks the
right-hand side of a long one into ``aligned`` rows so that it fits the page.
"""

from __future__ import annotations

from tanksynth.reports.latex import Tex

__all__ = ["visual_length", "split_equation"]


def _top_level_splits(s: str) -> list[int]:
    """Indices of top-level `` + `` / `` - `` in a LaTeX string (outside braces,
    ``\\left..\\right`` and environments)."""
    depth = 0
    out = []
    i = 0
    n = len(s)
    while i < n:
        c = s[i]
        if c == "\\":
            for word, delta in (("\\left", 1), ("\\right", -1), ("\\begin", 1), ("\\end", -1)):
                if s.startswith(word, i) and not (i + len(word) < n and s[i + len(word)].isalpha()):
                    depth += delta
                    i += len(word)
                    break
            else:
                i += 2
            continue
        if c == "{":
            depth += 1
        elif c == "}":
            depth -= 1
        elif depth == 0 and c in "+-" and i > 0 and s[i - 1] == " " and i + 1 < n and s[i + 1] == " ":
            out.append(i)
        i += 1
    return out


def _brace_group(s: str, start: int) -> int:
    """Index just past the brace group opening at ``s[start] == '{'``."""
    depth = 0
    for i in range(start, len(s)):
        if s[i] == "\\":
            continue
        if s[i] == "{" and (i == 0 or s[i - 1] != "\\"):
            depth += 1
        elif s[i] == "}" and s[i - 1] != "\\":
            depth -= 1
            if depth == 0:
                return i + 1
    return -1


_STRUCTURAL = {"frac", "tfrac", "dfrac", "sqrt", "left", "right", "operatorname", "mathrm", "text",
               "begin", "end", "dot", "bar", "hat", "tilde", "mathbf", "mathcal", "quad", "qquad"}


def visual_length(tex: str) -> int:
    """Rough typeset width of math LaTeX, in characters.

    Structural commands (``\\frac``, ``\\sqrt``, ``\\left`` ...) and braces count
    nothing, other commands (Greek letters, operators) one character,
    subscripts and superscripts half; a fraction counts the wider of its
    numerator and denominator.

    Parameters
    ----------
    tex : str
        Math-mode LaTeX.
    """
    total = 0.0
    i, n = 0, len(tex)
    while i < n:
        c = tex[i]
        if c == "\\":
            j = i + 1
            while j < n and tex[j].isalpha():
                j += 1
            word = tex[i + 1:j]
            if word in ("frac", "tfrac", "dfrac") and j < n and tex[j] == "{":
                end_num = _brace_group(tex, j)
                if end_num > 0 and end_num < n and tex[end_num] == "{":
                    end_den = _brace_group(tex, end_num)
                    if end_den > 0:
                        total += max(visual_length(tex[j + 1:end_num - 1]),
                                     visual_length(tex[end_num + 1:end_den - 1]))
                        i = end_den
                        continue
            if word == "begin" or word == "end":
                k = _brace_group(tex, j) if j < n and tex[j] == "{" else j
                i = k if k > 0 else j
                continue
            total += 0 if word in _STRUCTURAL else 1
            i = max(j, i + 2)
            continue
        if c in "_^":
            if i + 1 < n and tex[i + 1] == "{":
                end = _brace_group(tex, i + 1)
                if end > 0:
                    total += 0.6 * visual_length(tex[i + 2:end - 1])
                    i = end
                    continue
            total += 0.6
            i += 2
            continue
        if c not in "{} ":
            total += 1
        elif c == " ":
            total += 0.15
        i += 1
    return int(round(total))


def split_equation(equation: str, width: int = 75) -> list[Tex]:
    """Split a long sympy-LaTeX equation ``lhs = rhs`` into display lines.

    The right-hand side is broken at top-level ``+``/``-``; a right-hand
    side that is one fraction ``\\frac{N}{D}`` is first rewritten as
    ``\\frac{1}{D}\\bigl(N\\bigr)`` so that its numerator can be broken.
    ``width`` is a budget per line in the units of `visual_length`. Returns
    one line when nothing can be split.

    Parameters
    ----------
    equation : str
        Sympy LaTeX of ``lhs = rhs``.
    width : int, optional
        Budget per line (characters, see `visual_length`).

    Returns
    -------
    list of Tex
        Lines for an ``aligned`` environment; the first holds ``lhs &= ...``,
        the others start with ``&\\quad``.
    """
    if visual_length(equation) <= width or " = " not in equation:
        return [Tex(equation.replace(" = ", " &= ", 1))] if " = " in equation else [Tex(equation)]
    lhs, rhs = equation.split(" = ", 1)
    rhs = rhs.strip()
    prefix, suffix = "", ""
    if rhs.startswith(r"\frac{"):
        end_num = _brace_group(rhs, len(r"\frac"))
        if end_num > 0 and end_num < len(rhs) and rhs[end_num] == "{":
            end_den = _brace_group(rhs, end_num)
            if end_den == len(rhs):
                num, den = rhs[len(r"\frac") + 1:end_num - 1], rhs[end_num + 1:end_den - 1]
                if _top_level_splits(num):
                    prefix, suffix = rf"\frac{{1}}{{{den}}}\Bigl(", r"\Bigr)"
                    rhs = num
    cuts = _top_level_splits(rhs)
    if not cuts:
        return [Tex(equation.replace(" = ", " &= ", 1))]
    terms, last = [], 0
    for c in cuts:
        terms.append(rhs[last:c].strip())
        last = c
    terms.append(rhs[last:].strip())
    lines: list[str] = []
    current = ""
    for t in terms:
        if current and visual_length(current) + visual_length(t) > width:
            lines.append(current)
            current = t
        else:
            current = (current + " " + t).strip()
    lines.append(current)
    lines[0] = f"{lhs} &= {prefix}{lines[0]}"
    lines[1:] = [r"&\quad " + ln for ln in lines[1:]]
    lines[-1] += suffix
    return [Tex(ln) for ln in lines]
