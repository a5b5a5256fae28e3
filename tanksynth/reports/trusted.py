"""Which LaTeX from a result directory may be typeset as LaTeX: a small grammar of math.

Artefacts and the plant record carry math fragments (sympy's LaTeX of the Jacobians and
gains, the plant's equations). A result directory can be edited by anyone, so a fragment is
typeset only when it parses in this grammar (`latex_problem` says where it does not):

- tokens: letters, digits, the punctuation ``+ - * / = < > ( ) [ ] , . ; : ! ? |``, spaces;
  escaped characters (``\\{ \\} \\| \\_ \\# \\& \\$ \\%``) and spacing (``\\, \\; \\: \\! \\ ``);
  control words of an explicit allow-list (`MATH_COMMANDS`), each with its arguments
  (``\\frac`` two, ``\\sqrt`` one and an optional ``[...]``, ``\\text`` a text-mode group ...);
- ``^`` and ``_`` take one argument (a token or a group), at most one of each per base;
- braces balanced; ``\\left`` / ``\\right`` paired in the same group, each with a delimiter;
  ``\\begin{env}`` / ``\\end{env}`` paired for the environments of `MATH_ENVIRONMENTS`, with
  ``&`` and ``\\\\`` only directly inside one (columns within the environment's limit);
- in ``\\text{...}`` and the cells of a ``tabular`` (``\\hline`` at a row's start): text
  characters, escapes and balanced ``$...$`` math shifts;
- no trailing backslash, no ``%``, ``#``, ``~``, ``^^``, non-ASCII or control characters;
- at most `MAX_FRAGMENT_CHARS` characters (`MAX_DIRECTORY_CHARS` in a directory), `MAX_NESTING` nested groups and
  `MAX_STYLE_NESTING` nested ``\\text`` / ``\\boldsymbol`` / ``\\sqrt[n]``.

Everything accepted compiles with pdflatex in the report's preamble (a property test builds
samples). `check_result_latex` refuses a result directory whose LaTeX does not parse (exit 2,
naming the file and key) before a report is written; pdflatex also runs with
``openin_any = p`` / ``openout_any = p`` (`tanksynth.reports.pdf`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

from tanksynth.errors import ArtefactError
from tanksynth.reports.latex import Tex, escape_latex

__all__ = ["MATH_COMMANDS", "MATH_ENVIRONMENTS", "MAX_FRAGMENT_CHARS", "MAX_DIRECTORY_CHARS",
           "MAX_NESTING",
           "MAX_STYLE_NESTING", "MAX_TYPESET_CHARS",
           "latex_problem", "is_trusted_math", "math_or_text", "check_result_latex"]

#: Longest fragment (characters), and most characters of all fragments of a directory: the
#: longest the examples write has ~1,000; pdflatex's memory (5,000,000 words) ran out at
#: 50,000 characters of ``\frac`` typeset four times.
MAX_FRAGMENT_CHARS = 20_000
MAX_DIRECTORY_CHARS = 200_000
#: Deepest nesting of groups, arguments, ``\left`` and environments.
MAX_NESTING = 100
#: Deepest nesting of the commands that typeset their argument in all four math styles
#: (``\text``, ``\boldsymbol``, ``\sqrt[n]``: TeX's ``\mathchoice``): pdflatex's work grows
#: about 4x per level (11 nested ``\text{$`` took 53 s, 11 ``\boldsymbol`` over 300 s).
MAX_STYLE_NESTING = 4
#: Most characters pdflatex typesets for a fragment, each counted once per style it is set in
#: (4^k inside k of those commands).
MAX_TYPESET_CHARS = 100_000

_GREEK = ("alpha beta gamma delta epsilon varepsilon zeta eta theta vartheta iota kappa lambda mu "
          "nu xi pi varpi rho varrho sigma varsigma tau upsilon phi varphi chi psi omega "
          "Gamma Delta Theta Lambda Xi Pi Sigma Upsilon Phi Psi Omega")
_SYMBOLS = frozenset((_GREEK + " cdot cdots ldots vdots ddots times pm mp leq geq neq le ge ll gg "
                      "approx sim simeq equiv quad qquad sum prod int infty partial nabla vee wedge "
                      "cap cup in notin subset mid to rightarrow leftarrow Rightarrow mapsto prime "
                      "circ ast star sin cos tan sinh cosh tanh exp log ln max min sup inf lim det "
                      "arg displaystyle top hbar hslash ell aleph beth gimel daleth wp mho eth").split())
#: Control words that may stand alone as a script or macro argument (``x^\\alpha``).
_TOKEN_ARGUMENTS = frozenset((_GREEK + " infty partial nabla prime ast star circ top cdot times pm mp "
                              "hbar ell aleph").split())
_DELIMITER_WORDS = frozenset("lvert rvert lVert rVert langle rangle vert Vert".split())
_ONE_ARGUMENT = frozenset("sqrt dot ddot dddot ddddot hat widehat bar tilde widetilde vec check breve "
                          "acute grave mathring overline underline mathrm mathbf mathit mathcal "
                          "mathfrak boldsymbol operatorname".split())
_TWO_ARGUMENTS = frozenset("frac dfrac tfrac".split())
_TEXT_ARGUMENT = frozenset("text textrm".split())
_SIZED = frozenset("big Big bigg Bigg bigl bigr Bigl Bigr".split())
#: Control words a math fragment may use.
MATH_COMMANDS = (_SYMBOLS | _DELIMITER_WORDS | _ONE_ARGUMENT | _TWO_ARGUMENTS | _TEXT_ARGUMENT
                 | _SIZED | frozenset(("begin", "end", "left", "right")))
#: Environments a fragment may open, with their most columns (the report sets MaxMatrixCols 24;
#: an ``array`` has as many as its column letters).
MATH_ENVIRONMENTS: Mapping[str, int] = {
    **dict.fromkeys(("matrix", "bmatrix", "pmatrix", "Bmatrix", "vmatrix", "Vmatrix",
                     "smallmatrix"), 24),
    "array": 0, "tabular": 0, "aligned": 1_000, "cases": 2}

_MATH_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
                        "+-*/=<>()[],.;:!?|")
_TEXT_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
                        ".,;:!?()[]-+=/*' ")
_ESCAPES = frozenset("{}|_#&$%")
_SPACING = frozenset(",;:! ")
_DELIMITER_CHARS = frozenset("()[]|./")


class _Refused(Exception):
    """Where and why a fragment leaves the grammar."""

    def __init__(self, pos: int, why: str):
        super().__init__(f"{why} at character {pos + 1}")


class _Parser:
    """Recursive descent over one fragment; every method starts at ``self.pos``."""

    def __init__(self, text: str):
        self.text = text
        self.pos = 0
        self.depth = 0
        self.styles = 0          # enclosing \mathchoice-like commands
        self.extra = 0           # characters typeset again inside them

    def styled(self, word: str, start: int) -> None:
        """Enter one more command that typesets its argument in four styles."""
        self.styles += 1
        if self.styles > MAX_STYLE_NESTING:
            raise self.fail(f"\\{word} nested in more than {MAX_STYLE_NESTING} of \\text, "
                            "\\boldsymbol, \\sqrt[...]", start)

    def unstyled(self, start: int) -> None:
        """Leave it: its span is typeset 4x as often as at the level around it."""
        self.extra += 3 * 4 ** (self.styles - 1) * (self.pos - start)
        self.styles -= 1
        if len(self.text) + self.extra > MAX_TYPESET_CHARS:
            raise self.fail(f"more than {MAX_TYPESET_CHARS} characters to typeset, counting the "
                            "copies \\text, \\boldsymbol, \\sqrt[...] make")

    # ----------------------------------------------------------- helpers
    def peek(self, k: int = 0) -> str:
        i = self.pos + k
        return self.text[i] if i < len(self.text) else ""

    def fail(self, why: str, pos: int | None = None) -> _Refused:
        return _Refused(self.pos if pos is None else pos, why)

    def skip_spaces(self) -> None:
        while self.peek() == " ":
            self.pos += 1

    def enter(self) -> None:
        self.depth += 1
        if self.depth > MAX_NESTING:
            raise self.fail(f"nested deeper than {MAX_NESTING} levels")

    def control(self) -> str:
        """The control sequence at ``pos`` (a backslash): its name, ``pos`` after it."""
        start = self.pos
        self.pos += 1
        if self.pos >= len(self.text):
            raise self.fail("a trailing backslash", start)
        if self.peek().isascii() and self.peek().isalpha():
            while self.peek().isascii() and self.peek().isalpha():
                self.pos += 1
            return self.text[start + 1:self.pos]
        self.pos += 1
        return self.text[self.pos - 1]

    def name_group(self) -> str:
        """``{name}`` right after ``\\begin`` / ``\\end``."""
        if self.peek() != "{":
            raise self.fail("\\begin/\\end without {name}")
        end = self.text.find("}", self.pos)
        name = self.text[self.pos + 1:end] if end > 0 else ""
        if not name.isascii() or not name.isalpha():
            raise self.fail("an environment name that is not letters")
        self.pos = end + 1
        return name

    # ----------------------------------------------------------- math mode
    def math(self, stop: str, align: str | None = None, columns: int = 0) -> None:
        """Math material until ``stop``: ``""`` (end of text), ``"}"``, ``"]"`` (an optional
        argument), ``"$"`` (a math shift in text), ``"right"`` or ``"end"`` (left with ``pos``
        at the backslash). ``align``: the environment whose cells these are (``&``, ``\\\\``)."""
        self.enter()
        has_sup = has_sub = False
        column = 1
        while True:
            ch = self.peek()
            if ch == "":
                if stop:
                    raise self.fail(_UNCLOSED[stop])
                break
            if ch == " ":
                self.pos += 1
            elif ch in _MATH_CHARS:
                if ch == "]" and stop == "]":
                    break
                self.pos += 1
                has_sup = has_sub = False
            elif ch == "'":
                if has_sup:
                    raise self.fail("a prime after a superscript")
                self.pos += 1
                has_sup = True
            elif ch == "{":
                self.group()
                has_sup = has_sub = False
            elif ch == "}":
                if stop != "}":
                    raise self.fail("a '}' that closes no group")
                break
            elif ch == "$":
                if stop != "$":
                    raise self.fail("a math shift '$' in math")
                break
            elif ch in "^_":
                if (has_sup if ch == "^" else has_sub):
                    raise self.fail(f"a double {'superscript' if ch == '^' else 'subscript'}")
                self.pos += 1
                self.argument(f"'{ch}'")
                has_sup, has_sub = (True, has_sub) if ch == "^" else (has_sup, True)
            elif ch == "&":
                if align is None:
                    raise self.fail("'&' outside a matrix environment")
                column += 1
                if column > columns:
                    raise self.fail(f"more than {columns} columns in {align}")
                self.pos += 1
                has_sup = has_sub = False
            elif ch == "\\":
                start = self.pos
                word = self.control()
                if word in ("right", "end") and stop == word:
                    self.pos = start
                    break
                if word == "\\":
                    if align is None:
                        raise self.fail("'\\\\' outside a matrix environment", start)
                    self.skip_spaces()
                    if self.peek() in ("[", "*"):
                        raise self.fail("'\\\\' followed by '[' or '*'")
                    column = 1
                else:
                    self.command(word, start)
                has_sup = has_sub = False
            else:
                raise self.fail(f"the character {ch!r}")
        self.depth -= 1

    def group(self) -> None:
        """``{ math }`` at ``pos``."""
        self.pos += 1
        self.math("}")
        self.pos += 1

    def argument(self, of: str) -> None:
        """One macro argument: a group, or one letter/digit/symbol token."""
        self.skip_spaces()
        ch = self.peek()
        if ch == "{":
            self.group()
        elif ch.isascii() and ch.isalnum():
            self.pos += 1
        elif ch == "\\":
            start = self.pos
            word = self.control()
            if word not in _TOKEN_ARGUMENTS:
                raise self.fail(f"the argument of {of} is neither a group nor a symbol", start)
        else:
            raise self.fail(f"{of} without its argument")

    def delimiter(self, of: str) -> None:
        self.skip_spaces()
        ch = self.peek()
        if ch in _DELIMITER_CHARS and ch:
            self.pos += 1
            return
        if ch == "\\":
            start = self.pos
            word = self.control()
            if word in _DELIMITER_WORDS or word in ("{", "}", "|"):
                return
            raise self.fail(f"\\{of} followed by \\{word}, not a delimiter", start)
        raise self.fail(f"\\{of} without a delimiter")

    def command(self, word: str, start: int) -> None:
        """The rest of the control sequence ``word`` (name already read)."""
        if len(word) == 1 and not word.isalpha():
            if word in _ESCAPES or word in _SPACING:
                return
            raise self.fail(f"the control symbol \\{word}", start)
        if word not in MATH_COMMANDS:
            raise self.fail(f"the control word \\{word} (not in the allow-list)", start)
        if word in _SYMBOLS or word in _DELIMITER_WORDS:
            return
        if word in _SIZED:
            self.delimiter(word)
        elif word in _TWO_ARGUMENTS:
            self.argument(f"\\{word}")
            self.argument(f"\\{word}")
        elif word in _ONE_ARGUMENT:
            styled = word == "boldsymbol" or (word == "sqrt" and self.peek() == "[")
            if styled:
                self.styled(word, start)
            if word == "sqrt" and self.peek() == "[":
                self.pos += 1
                self.math("]")
                self.pos += 1
            self.argument(f"\\{word}")
            if styled:
                self.unstyled(start)
        elif word in _TEXT_ARGUMENT:
            self.styled(word, start)
            self.skip_spaces()
            if self.peek() != "{":
                raise self.fail(f"\\{word} without a {{text}} group")
            self.text_group()
            self.unstyled(start)
        elif word == "left":
            self.delimiter("left")
            self.math("right")
            self.control()                      # \right, stopped at by math()
            self.delimiter("right")
        elif word == "begin":
            self.environment()
        else:                                   # \right, \end without their opening
            raise self.fail(f"\\{word} without its \\{'left' if word == 'right' else 'begin'}",
                            start)

    def environment(self) -> None:
        at = self.pos
        name = self.name_group()
        if name not in MATH_ENVIRONMENTS:
            raise self.fail(f"the environment {name!r} (not in the allow-list)", at)
        columns = MATH_ENVIRONMENTS[name]
        if name in ("array", "tabular"):
            end = self.text.find("}", self.pos)
            spec = self.text[self.pos + 1:end] if self.peek() == "{" and end > 0 else ""
            if not spec.strip("|") or set(spec) - set("lcr|"):
                raise self.fail(f"{name} without its {{lcr...}} column letters")
            columns = sum(spec.count(c) for c in "lcr")
            self.pos = end + 1
        if name == "tabular":
            self.text_cells(name, columns)
        else:
            self.math("end", align=name, columns=columns)
        self.control()                          # \end, stopped at by math()
        at = self.pos
        if self.name_group() != name:
            raise self.fail(f"\\end of another environment than {name!r}", at)

    # ----------------------------------------------------------- text mode
    def text_cells(self, env: str, columns: int) -> None:
        """The body of a ``tabular`` until its ``\\end``: text cells, ``&``, ``\\\\`` and
        ``\\hline`` at the start of a row."""
        self.enter()
        column, row_start = 1, True
        while True:
            ch = self.peek()
            if ch == "":
                raise self.fail(_UNCLOSED["end"])
            if ch == " ":
                self.pos += 1
                continue
            if ch == "\\":
                start = self.pos
                word = self.control()
                if word == "end":
                    self.pos = start
                    break
                if word == "\\":
                    self.skip_spaces()
                    if self.peek() in ("[", "*"):
                        raise self.fail("'\\\\' followed by '[' or '*'")
                    column, row_start = 1, True
                    continue
                if word == "hline":
                    if not row_start:
                        raise self.fail("\\hline inside a row", start)
                    continue
                if not (word in _ESCAPES or word in _SPACING):
                    raise self.fail(f"\\{word} in a {env} cell", start)
            elif ch == "&":
                column += 1
                if column > columns:
                    raise self.fail(f"more than {columns} columns in {env}")
                self.pos += 1
            elif not self.text_item(ch):
                raise self.fail(f"the character {ch!r} in a {env} cell")
            row_start = False
        self.depth -= 1

    def text_group(self) -> None:
        """``{ text }`` at ``pos``: text characters, escapes, groups, ``$math$``."""
        self.enter()
        self.pos += 1
        while True:
            ch = self.peek()
            if ch == "":
                raise self.fail(_UNCLOSED["}"])
            if ch == "}":
                self.pos += 1
                break
            if ch == "\\":
                start = self.pos
                word = self.control()
                if not (word in _ESCAPES or word in _SPACING):
                    raise self.fail(f"\\{word} in text", start)
            elif not self.text_item(ch):
                raise self.fail(f"the character {ch!r} in text")
        self.depth -= 1

    def text_item(self, ch: str) -> bool:
        """Consume the text-mode item starting with ``ch`` (a text character, a ``{ group }``
        or ``$math$``); False, nothing consumed, for anything else."""
        if ch in _TEXT_CHARS:
            self.pos += 1
        elif ch == "{":
            self.text_group()
        elif ch == "$":
            self.pos += 1
            self.math("$")
            self.pos += 1
        else:
            return False
        return True


_UNCLOSED = {"}": "a '{' never closed (unbalanced braces)", "]": "an optional argument '[' never closed",
             "$": "a math shift '$' never closed", "right": "a \\left without its \\right",
             "end": "a \\begin without its \\end"}


def latex_problem(fragment: Any) -> str | None:
    """Why ``fragment`` is not in the math grammar (see the module notes), or None.

    Parameters
    ----------
    fragment : str
        Math-mode LaTeX (anything else is refused).

    Returns
    -------
    str or None
        The first problem (what, at which character), None when the fragment parses.
    """
    if not isinstance(fragment, str):
        return f"not a string ({type(fragment).__name__})"
    if len(fragment) > MAX_FRAGMENT_CHARS:
        return f"{len(fragment)} characters (at most {MAX_FRAGMENT_CHARS})"
    parser = _Parser(fragment)
    try:
        parser.math("")
    except _Refused as exc:
        return str(exc)
    return None


def is_trusted_math(fragment: Any) -> bool:
    """True when ``fragment`` parses in the math grammar (`latex_problem` is None).

    Parameters
    ----------
    fragment : str
        Math-mode LaTeX.
    """
    return latex_problem(fragment) is None


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


def _refuse(path: Path, key: str, value: Any, seen: list[int]) -> None:
    problem = latex_problem(value)
    if problem is None:
        seen[0] += len(value)
        if seen[0] > MAX_DIRECTORY_CHARS:
            problem = f"more than {MAX_DIRECTORY_CHARS} characters of LaTeX in the directory"
    if problem is not None:
        raise ArtefactError(f"{path}: key '{key}': LaTeX refused: {problem}; expected math of "
                            "the allowed commands, as tanksynth writes it")


def check_result_latex(directory: Path, plant: Mapping[str, Any],
                       artefacts: Sequence[Mapping[str, Any]],
                       checks: Sequence[Mapping[str, Any]] | None) -> None:
    """Refuse a result directory whose LaTeX a report would typeset does not parse.

    The fragments: ``plant.json`` ``equations`` (``general``, ``smooth``, ``outputs``), each
    artefact's ``latex`` table and a rank verdict's ``data.determinant_latex`` in
    ``checks.json``.

    Parameters
    ----------
    directory : Path
        The result directory.
    plant : mapping
        ``plant.json`` as read.
    artefacts : sequence of mapping
        The artefacts, each with its file name under ``"_file"``.
    checks : sequence of mapping or None
        ``checks.json`` as read.

    Raises
    ------
    ArtefactError
        Naming the file and the key of the first fragment outside the grammar (exit 2).
    """
    seen = [0]
    equations = plant.get("equations") or {}
    if isinstance(equations, Mapping):
        for kind in ("general", "smooth", "outputs"):
            lines = equations.get(kind) or []
            for i, line in enumerate(lines if isinstance(lines, list) else [lines]):
                _refuse(directory / "plant.json", f"equations.{kind}[{i}]", line, seen)
    for art in artefacts:
        for name, fragment in (art.get("latex") or {}).items():
            _refuse(directory / str(art.get("_file", "")), f"latex.{name}", fragment, seen)
    for i, check in enumerate(checks or ()):
        data = check.get("data")
        if isinstance(data, Mapping) and data.get("determinant_latex") is not None:
            _refuse(directory / "checks.json", f"[{i}].data.determinant_latex",
                    data["determinant_latex"], seen)
