"""Which LaTeX from a result directory may be typeset as LaTeX.

Artefacts and the plant record carry math fragments (sympy's LaTeX of the
Jacobians, the plant's equations). A result directory can be edited by anyone,
so a fragment is typeset only when every control sequence in it is a math
command of an allow-list (what sympy emits for these models) and every
environment is a matrix-like one; anything else (``\\input``, ``\\read``,
``\\catcode``, ``^^`` escapes, ``%`` ...) is shown escaped, as text. pdflatex
itself also runs with ``openin_any = p`` / ``openout_any = p``
(`tanksynth.reports.pdf`), so no absolute path or parent directory can be read.
"""

from __future__ import annotations

import re

from tanksynth.reports.latex import Tex, escape_latex

__all__ = ["MATH_COMMANDS", "MATH_ENVIRONMENTS", "is_trusted_math", "math_or_text"]

_GREEK = ("alpha beta gamma delta epsilon varepsilon zeta eta theta vartheta iota kappa lambda mu nu "
          "xi pi varpi rho varrho sigma varsigma tau upsilon phi varphi chi psi omega "
          "Gamma Delta Theta Lambda Xi Pi Sigma Upsilon Phi Psi Omega")
#: Control words a math fragment may use.
MATH_COMMANDS = frozenset((_GREEK + " frac dfrac tfrac sqrt left right big Big bigg Bigg bigl bigr "
                           "Bigl Bigr begin end cdot cdots ldots vdots ddots times pm mp leq geq neq "
                           "le ge lt gt ll gg approx sim simeq equiv quad qquad hline dot ddot hat "
                           "bar tilde vec overline underline sum prod int infty partial nabla vee "
                           "wedge cap cup in notin subset mid lvert rvert lVert rVert langle rangle "
                           "to rightarrow leftarrow Rightarrow mapsto prime circ ast star operatorname "
                           "mathrm mathbf mathit mathcal text textrm sin cos tan exp log ln max min "
                           "sup inf lim det sgn sign arg displaystyle boldsymbol").split())
#: Environments a math fragment may open.
MATH_ENVIRONMENTS = frozenset("matrix bmatrix pmatrix Bmatrix vmatrix smallmatrix array aligned "
                              "cases".split())
_TOKEN = re.compile(r"\\([A-Za-z]+|.)", re.S)
_ENV = re.compile(r"\s*\{([A-Za-z*]+)\}")
_SAFE_SYMBOLS = frozenset("\\,;:! {}|_#&$")


def is_trusted_math(fragment: str) -> bool:
    """True when ``fragment`` uses only allowed math commands and environments.

    Parameters
    ----------
    fragment : str
        Math-mode LaTeX.
    """
    if not isinstance(fragment, str) or "^^" in fragment or "%" in fragment:
        return False
    for m in _TOKEN.finditer(fragment):
        word = m.group(1)
        if word.isalpha():
            if word not in MATH_COMMANDS:
                return False
            if word in ("begin", "end"):
                env = _ENV.match(fragment, m.end())
                if env is None or env.group(1) not in MATH_ENVIRONMENTS:
                    return False
        elif word not in _SAFE_SYMBOLS:
            return False
    return True


def math_or_text(fragment: str) -> tuple[Tex, bool]:
    """``(fragment as LaTeX, True)`` when trusted, else ``(its escaped text, False)``.

    Parameters
    ----------
    fragment : str
        Math-mode LaTeX.
    """
    if is_trusted_math(fragment):
        return Tex(fragment), True
    return Tex(r"\text{\texttt{" + escape_latex(str(fragment), breakable=True)
               + r"} (not typeset: LaTeX outside the allowed math commands)}"), False
