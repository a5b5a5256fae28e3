"""Messages of the command line on one line: exceptions cut to a readable length, library
warnings translated into what they mean for the user, design-table indices explained."""

from __future__ import annotations

import re
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator

from tanksynth.errors import TanksynthError

if TYPE_CHECKING:  # read when the summary is printed
    from tanksynth.artefacts.model import VerificationCheck

__all__ = ["print_summary", "MAX_MESSAGE", "KNOWN_WARNINGS", "one_line", "meaning", "origin", "warning_line",
           "design_index_note", "note_warnings", "law_line", "StageClock"]

#: Longest message printed (characters); longer ones are cut.
MAX_MESSAGE = 600


def one_line(exc: BaseException | str) -> str:
    """The message on one line, its long runs of digits and its total length cut.

    Parameters
    ----------
    exc : BaseException or str
        The error (or warning message) to print.

    Returns
    -------
    str
        At most `MAX_MESSAGE` characters; runs of 40+ digits shown as ``<n digits>``.
    """
    text = " ".join(str(exc).split())
    text = re.sub(r"\d{40,}", lambda m: f"<{len(m.group(0))} digits>", text)
    return text if len(text) <= MAX_MESSAGE else text[:MAX_MESSAGE - 12] + " ... (cut)"


#: Library warnings whose meaning is known: (category name, text fragment, what it means).
KNOWN_WARNINGS = (
    ("UserWarning", "Tight layout not applied",
     "a figure's layout could not be tightened (cosmetic: labels may overlap)"),
    ("UserWarning", "Solution may be inaccurate",
     "a convex solver reported an inaccurate solution (the design's checks re-verify it)"),
)


def meaning(message: Any, category: type, filename: str) -> str:
    """What a library warning means for the user, on one short line: a known one (see
    `KNOWN_WARNINGS`), a numerical one with where it came from, else a generic line.

    Parameters
    ----------
    message : Warning or str
        The warning's message.
    category : type
        Its class (a `Warning` subclass).
    filename : str
        The file that issued it.
    """
    text = str(message)
    for kind, fragment, meaning in KNOWN_WARNINGS:
        if category.__name__ == kind and fragment in text:
            return meaning
    if issubclass(category, RuntimeWarning):
        return warning_line(message, category, filename)
    return (f"a {category.__name__} from {origin(filename)} (not known to affect the results; "
            "tanksynth --verbose COMMAND prints its text)")


def origin(filename: str) -> str:
    """The top-level package a warning came from (its file's path), else the file's name.

    Parameters
    ----------
    filename : str
        The file that issued the warning.
    """
    parts = Path(str(filename)).parts
    if "site-packages" in parts and parts.index("site-packages") + 1 < len(parts):
        return parts[parts.index("site-packages") + 1].removesuffix(".py")
    return Path(str(filename)).name


def warning_line(message: Any, category: type, filename: str) -> str:
    """One line for a warning: a tanksynth warning as it is, a numerical library warning with
    where it came from and what it means.

    Parameters
    ----------
    message : Warning or str
        The warning's message.
    category : type
        Its class (a `Warning` subclass).
    filename : str
        The file that issued it.
    """
    text = one_line(message)
    if issubclass(category, RuntimeWarning) and "lambdify" in str(filename):
        return (f"numerical: {text} (in generated model code): a model or premise was evaluated "
                "outside its domain (e.g. a negative level), giving NaN there")
    if issubclass(category, RuntimeWarning):
        return f"numerical: {text} (in {Path(str(filename)).name})"
    return text


def design_index_note(text: str, limit: int = MAX_MESSAGE) -> str:
    """``text`` with, when it names ``design[i]``, which ``[[design]]`` table that is (the
    index counts from 0: ``design[1]`` is the second table), still on one line.

    Parameters
    ----------
    text : str
        A one-line message.
    limit : int
        Longest result (characters): the message is cut to leave room for the note.

    Returns
    -------
    str
        The message and the note, at most ``limit`` characters.
    """
    found = list(dict.fromkeys(int(i) for i in re.findall(r"\bdesign\[(\d+)\]", text)))
    if not found:
        return text
    where = ", ".join(f"design[{i}] = [[design]] table {i + 1}" for i in found[:4])
    note = f" ({where}; indices count from 0)"
    if len(text) + len(note) > limit:
        text = text[:max(0, limit - len(note) - 10)].rstrip() + " ... (cut)"
    return text + note


def note_warnings(caught: list, console: Any, quiet: bool, code: int = 0,
                  verbose: bool = False) -> None:
    """Tanksynth warnings (a meaning for the user): one line each on stderr, unless the exit
    code is 2 or 4 (their contract is one stderr line). Library warnings: one note on stdout
    saying what they mean (`meaning`); their raw text only with ``verbose``.
    Nothing with ``--json``.

    Parameters
    ----------
    caught : list of warnings.WarningMessage
        The warnings a command recorded.
    console : rich.console.Console
        Where the library-warning note goes (stdout).
    quiet : bool
        Print nothing (``--json``).
    code : int
        The command's exit code (no warning lines on 2 or 4).
    verbose : bool
        Also print the library warnings' raw text.
    """
    from tanksynth.errors import DesignWarning, TanksynthWarning

    if not caught or quiet:
        return
    ours = [w for w in caught if issubclass(w.category, TanksynthWarning)
            and not issubclass(w.category, DesignWarning)]  # design warnings: printed per design
    library = [w for w in caught if not issubclass(w.category, TanksynthWarning)]
    try:
        if code not in (2, 4):
            for line in dict.fromkeys(warning_line(w.message, w.category, w.filename) for w in ours):
                print(f"warning: {line}", file=sys.stderr)
        if library:
            kinds = sorted({w.category.__name__ for w in library})
            meanings = list(dict.fromkeys(meaning(w.message, w.category, w.filename)
                                          for w in library))
            shown = "; ".join(m[:200] for m in meanings[:3]) + (
                f"; and {len(meanings) - 3} more" if len(meanings) > 3 else "")
            console.print(f"note: {len(library)} library warning(s) ({', '.join(kinds)}) were handled: "
                       f"{shown}", markup=False, highlight=False, soft_wrap=True)
            if verbose:
                raw = dict.fromkeys(f"{w.category.__name__}: {one_line(w.message)[:300]} "
                                    f"({w.filename}:{w.lineno})" for w in library)
                for line in raw:
                    console.print(f"  raw: {line}", markup=False, highlight=False, soft_wrap=True)
    except OSError:  # stdout/stderr closed: nothing more to say
        pass


def _size(shape: tuple[int, int]) -> str:
    """``3`` for a column of 3, ``1x3`` / ``3x3`` otherwise (a CasADi argument's shape)."""
    rows, cols = shape
    return str(rows) if cols == 1 else f"{rows}x{cols}"


def law_line(casadi_file: str | Path) -> str:
    """One line naming an exported law's files and its signature, read from the written file.

    Parameters
    ----------
    casadi_file : str or Path
        ``<dir>/<name>_law.casadi`` written by `tanksynth.artefacts.export.export_law`
        (``<name>_law.c`` and ``<name>_law.h`` beside it).

    Returns
    -------
    str
        ``law: <dir>/<name>_law.{casadi,c,h}: <function>(x[3], y[2]) -> (u[2])``: the C
        function / CasADi Function name, each input and output name with its size (``n``
        for a column of n entries, ``rxc`` otherwise).
    """
    import casadi

    path = Path(casadi_file)
    fn = casadi.Function.load(str(path))
    ins = ", ".join(f"{fn.name_in(i)}[{_size(fn.size_in(i))}]" for i in range(fn.n_in()))
    outs = ", ".join(f"{fn.name_out(i)}[{_size(fn.size_out(i))}]" for i in range(fn.n_out()))
    return f"law: {path.with_suffix('')}.{{casadi,c,h}}: {fn.name()}({ins}) -> ({outs})"


class StageClock:
    """Wall time of the stages of a command, summed per stage name, for one summary line.

    Use ``with clock("design"): ...`` around a stage (repeatable: the times add up),
    `part` to note a share of a stage timed elsewhere (the LaTeX run of the report) and
    `line` for the summary.
    """

    def __init__(self) -> None:
        self._seconds: dict[str, float] = {}
        self._parts: dict[str, list[tuple[str, float]]] = {}
        self._start = time.perf_counter()

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        """Time the block as (part of) ``stage``; the time counts even if the block raises."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self._seconds[stage] = self._seconds.get(stage, 0.0) + time.perf_counter() - t0

    def part(self, stage: str, name: str, seconds: float) -> None:
        """Note that ``seconds`` (s) of ``stage`` were spent in ``name`` (shown in brackets).

        Parameters
        ----------
        stage : str
            A stage timed by the clock.
        name : str
            The part (e.g. ``"LaTeX"``).
        seconds : float
            Its wall time (s).
        """
        self._parts.setdefault(stage, []).append((name, float(seconds)))

    @property
    def seconds(self) -> dict[str, float]:
        """Wall time per stage (s), in the order the stages first ran."""
        return dict(self._seconds)

    def line(self) -> str:
        """``times: rank checks 0.4 s, design 1.2 s, ... (LaTeX 3.1 s); total 9.8 s`` (wall, s)."""
        items = []
        for stage, sec in self._seconds.items():
            parts = "".join(f" ({name} {s:.1f} s)" for name, s in self._parts.get(stage, []))
            items.append(f"{stage} {sec:.1f} s{parts}")
        total = time.perf_counter() - self._start
        return "times: " + ", ".join(items) + f"; total {total:.1f} s"


def print_summary(paths: list[Path], console: Any) -> None:
    """The table ``run`` ends with: design, method, key figure, verdict; then each failed
    check's reason and where the artefacts are.

    Parameters
    ----------
    paths : list of Path
        The artefacts written (non-empty), all in one directory.
    console : rich.console.Console
        Where to print.
    """
    from rich.table import Table

    from tanksynth.artefacts.io import load_artefact
    from tanksynth.summary import summary_row

    table = Table(title="Designs, verified on the nonlinear plant")
    for col in ("design", "method", "key figure", "verdict"):   # names never broken mid-word
        table.add_column(col, overflow="fold", no_wrap=col in ("design", "method"))
    failures: list[tuple[str, VerificationCheck]] = []
    try:
        from tanksynth.artefacts.io import read_plant_record

        units = [s.get("unit", "") for s in read_plant_record(paths[0].parent)["plant"]["states"]]
    except (TanksynthError, KeyError, TypeError, OSError):
        units = None
    for path in paths:
        artefact = load_artefact(path)
        row = summary_row(artefact, units)
        table.add_row(row.name, row.method, row.figure, "[green]pass[/]" if row.passed else "[red]FAIL[/]")
        if artefact.verification is not None:   # an edited verification reads leniently: no crash
            failures += [(row.name, c) for c in artefact.verification.checks if c.passed is False]
    console.print(table)
    for name, c in failures:  # why, without opening the artefact
        console.print(f"{name}: {c.check} FAILED: {one_line(c.detail)}", markup=False,
                   highlight=False)
    console.print(f"artefacts: {paths[0].parent}/<design>.json (.npz beside)", markup=False,
               highlight=False)
