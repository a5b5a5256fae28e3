"""The ``tanksynth`` command.

Exit codes: 0 success, 1 a verification (rank) check failed, 2 bad input
(one line on stderr, no traceback; also an operating-system error on a named
path, a result directory in use by another run or written from another spec,
a problem too large for the memory budget), 3 a design was infeasible (no
artefact written for it), 4 an internal error (a bug: one line on stderr
naming a log file that holds the traceback), 130 interrupted (SIGINT, SIGTERM
or SIGHUP: child processes ended, nothing partial left, the lock released,
one line ``interrupted (SIGTERM): ...`` on stderr). Library warnings never
reach stderr: they are counted in one note on stdout.
"""

from __future__ import annotations

import json
import shutil
import signal
import sys
import warnings
from contextlib import contextmanager
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Iterator

import click
from rich.console import Console
from rich.table import Table

from tanksynth.errors import InfeasibleDesign, SpecError, TanksynthError
from tanksynth.messages import KNOWN_WARNINGS, MAX_MESSAGE  # noqa: F401 (the CLI's surface)
from tanksynth.messages import StageClock, law_line, print_summary
from tanksynth.messages import design_index_note as _design_index_note
from tanksynth.messages import note_warnings
from tanksynth.messages import one_line as _one_line
from tanksynth.process import EXIT_INTERRUPTED, Interrupted, interruptible
from tanksynth.process import ignore_file_size_signal as _ignore_file_size_signal
from tanksynth.process import internal_error_log as _internal_error_log
from tanksynth.process import one_blas_thread as _one_blas_thread
from tanksynth.report_worker import ReportSummary, ReportWorker, report_summary
from tanksynth.verify.cluster import MAX_WORKERS, WORKER_TIMEOUT

if TYPE_CHECKING:  # annotations only: each command imports what it needs when it runs
    import casadi
    from rich.progress import Progress, TaskID

    from tanksynth.analysis.checks import Check
    from tanksynth.design.result import DesignResult
    from tanksynth.spec import DesignSpec, Spec

__all__ = ["main", "cli"]

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INFEASIBLE, EXIT_INTERNAL = 0, 1, 2, 3, 4

_out = Console()

#: Columns of the console used for tables when stdout is not a terminal (piped, redirected).
_PIPED_WIDTH = 400


class _Seconds(click.FloatRange):
    """A finite number of seconds in a range (``nan`` and ``inf`` are refused naming the option)."""

    name = "seconds"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        import math

        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number of seconds", param, ctx)
        return number


class _Fail(Exception):
    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


#: Longest message line printed (characters): an echoed value in an error is cut, not dumped.




def _live() -> bool:
    """Live displays (spinner, bars) work here: not in a notebook without ipywidgets.

    rich needs ipywidgets to animate in Jupyter and otherwise warns (``install
    "ipywidgets"``); the stage lines are printed either way.
    """
    if not _out.is_jupyter:
        return True
    import importlib.util

    return importlib.util.find_spec("ipywidgets") is not None


def _bars(quiet: bool = False) -> bool:
    """Progress bars are drawn: a live display on a terminal (or a notebook with ipywidgets).

    Piped output gets none: a stopped bar would leave an empty line there; the stage lines
    say what runs.
    """
    return not quiet and _live() and (_out.is_terminal or _out.is_jupyter)


def _piped() -> bool:
    """stdout is neither a terminal nor a notebook (a pipe or a file): tables get no 80-column
    folding there."""
    return not (_out.is_terminal or _out.is_jupyter)


def _wide() -> Console:
    """The console for tables: piped, a wide one (an option table or design names folded at 80
    columns are unreadable)."""
    return Console(width=_PIPED_WIDTH) if _piped() else _out


def _progress(quiet: bool = False) -> Progress:
    """A progress bar for the artefacts or runs of a stage: a spinner, the current item, done
    of total and the elapsed time (no ETA: one artefact's verdict can take long)."""
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn,
                               TextColumn, TimeElapsedColumn)

    return Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                    MofNCompleteColumn(), TimeElapsedColumn(), console=_out, transient=True,
                    disable=not _bars(quiet))


@contextmanager
def _stage(text: str, quiet: bool = False) -> Iterator[None]:
    """Print a line as a stage starts, and a spinner while it runs (on a terminal only);
    nothing with ``quiet`` (``--json`` output must stay one JSON document)."""
    if quiet:
        yield
        return
    _out.print(f"- {text}", markup=False, highlight=False)
    if not _live():
        yield
        return
    with _out.status(text, spinner="dots"):
        yield



def _load(spec_path: str | None) -> Spec:
    from tanksynth.methods import load_spec, parse_spec_text

    if spec_path is None:
        text = resources.files("tanksynth.data").joinpath("demo.toml").read_bytes()
        return parse_spec_text(text, source="<built-in demo>")
    return load_spec(spec_path)


def _keyed(exc: TanksynthError, key: str, source: str | None) -> SpecError:
    """A bad-input error raised while working on spec key ``key``, naming the file and key."""
    if isinstance(exc, SpecError):
        if exc.key and exc.key.split(".")[0].split("[")[0] in ("design", "plant", "sampling",
                                                                "operating_point"):
            full = exc.key
        else:
            full = f"{key}.{exc.key}" if exc.key else key
        return type(exc)(exc.detail, key=full, source=exc.source or source)
    return SpecError(f"{type(exc).__name__}: {_one_line(exc)}", key=key, source=source)


def _rank_conditions(s: Spec) -> list[Check]:
    from tanksynth.analysis.checks import rank_conditions

    try:
        # as lists: the analysis takes sequences of float (the same numbers)
        given = None if s.given_u0 is None else s.given_u0.tolist()
        return rank_conditions(s.plant, s.x0.tolist(), s.ts, given)
    except InfeasibleDesign:
        raise
    except TanksynthError as exc:
        raise _keyed(exc, "plant", s.source) from None


def _print_checks(checks: Iterable[Check], title: str = "Rank conditions") -> None:
    table = Table(title=title)
    table.add_column("check")
    table.add_column("verdict")
    table.add_column("detail", overflow="fold")
    for c in checks:
        verdict = {True: "[green]pass[/]", False: "[red]FAIL[/]", None: "[blue]info[/]"}[c.passed]
        table.add_row(c.name, verdict, c.detail)
    _out.print(table)


def _refuse_other_spec(spec: Spec, outdir: Path, force: bool) -> None:
    """Refuse (exit 2) a directory written from another spec; with ``force``, remove that
    run's files first."""
    from tanksynth.artefacts.io import other_spec_files

    reason, files = other_spec_files(outdir, spec.sha256)
    if not reason:
        return
    if not force:
        raise SpecError(f"{reason}; choose another output directory, or pass --force to replace "
                        f"that run ({len(files)} file(s) besides plant.json and spec.toml)", source=str(outdir))
    for path in files:
        path.unlink(missing_ok=True)
    _out.print(f"--force: removed {len(files)} file(s) of another spec's run from {outdir}",
               markup=False, highlight=False, soft_wrap=True)


#: The files a design run writes before its designs (and a refused one beside them).
_RECORD_FILES = ("plant.json", "spec.toml", "refused.json")


def _run_record(outdir: Path) -> dict[str, bytes | None]:
    """The bytes of ``outdir``'s plant record, spec copy and refusal list (None: absent)."""
    return {name: (outdir / name).read_bytes() if (outdir / name).is_file() else None
            for name in _RECORD_FILES}


def _restore_run_record(outdir: Path, before: dict[str, bytes | None]) -> None:
    """Put the files of `_run_record` back as they were (a refused fit leaves no record of a
    spec that designed nothing: rerunning a fixed spec would otherwise need ``--force``)."""
    from tanksynth.artefacts.atomic import atomic_write

    for name, data in before.items():
        path = outdir / name
        if data is None:
            path.unlink(missing_ok=True)
        elif not path.is_file() or path.read_bytes() != data:
            atomic_write(path, data)


def _remove_interrupted(outdir: Path) -> None:
    """Remove what a killed run left mid-write (under the lock), saying so in one line."""
    from tanksynth.artefacts.io import remove_interrupted_writes

    removed = remove_interrupted_writes(outdir)
    if removed:
        _out.print(f"removed {len(removed)} file(s) left by an interrupted run in {outdir}: "
                   + ", ".join(p.name for p in removed), markup=False, highlight=False, soft_wrap=True)


@contextmanager
def _locked(directory: str | Path, command: str) -> Iterator[Path]:
    """Hold the directory's lock while a command writes into it; an interruption removes what
    the command's writers staged and had not renamed yet (a report worker ended by SIGKILL, see
    `tanksynth.report_worker`) before the lock is released."""
    from tanksynth.artefacts.atomic import directory_lock

    with directory_lock(directory, command=command) as lock:
        try:
            yield lock
        except KeyboardInterrupt:
            _remove_staged(Path(directory))
            raise


def _remove_staged(directory: Path) -> None:
    """Remove staged files and build directories left in ``directory`` and its figure
    directories by an interrupted writer (the caller holds the lock: nothing else is writing
    there); only names of the tool's own staging (`tanksynth.artefacts.atomic.stale_temporaries`)."""
    from tanksynth.artefacts.atomic import remove_stale, stale_temporaries
    from tanksynth.artefacts.io import remove_interrupted_writes

    remove_interrupted_writes(directory)
    for sub in directory.iterdir():
        if sub.is_dir() and not sub.is_symlink():
            remove_stale(stale_temporaries(sub))


def _design_all(spec: Spec, outdir: Path, export: tuple[str, ...]
                ) -> tuple[list[Path], list[str], list[Path]]:
    """Design every entry, writing each artefact as soon as its design finishes; return the
    artefacts, the refusals and the ``<name>_law.casadi`` files written (``--export law``).

    The spec's options were all validated when it was parsed. A refused design
    (`InfeasibleDesign`: infeasible, uncontrollable, unobservable, fragile, or
    `DesignTooLarge`, refused before it runs when its estimated memory exceeds
    the budget) is listed with its reason (no artefact for it) and the
    remaining designs are still attempted and written. The designs finished
    before a later one fails on bad input (exit 2) or kills the process keep
    their artefacts (each one complete: written atomically). Each distinct
    `DesignWarning` is printed once on stderr (``warning: <designs>: <text>``);
    the artefacts record theirs in ``diagnostics["warnings"]``.
    """

    from tanksynth.artefacts.io import file_sha256, write_artefact, write_plant_record
    from tanksynth.errors import DesignWarning
    from tanksynth.methods import METHODS

    from tanksynth.reports.refused import refusal, write_refused

    infeasible: list[str] = []
    refused: list[dict[str, Any]] = []
    seen: dict[str, list[str]] = {}
    plant_sha = file_sha256(write_plant_record(spec, outdir))
    written: list[Path] = []
    laws: list[Path] = []
    for k, design in enumerate(spec.designs, 1):
        result = None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", DesignWarning)
            try:
                with _stage(f"designing {design.name} ({design.method}) [{k}/{len(spec.designs)}]"):
                    result = METHODS[design.method].design(spec, design)
            except InfeasibleDesign as exc:
                infeasible.append(f"{design.name}: {_one_line(exc)}")
                refused.append(refusal(design.name, design.method, exc))
            except TanksynthError as exc:
                raise _keyed(exc, design.key, spec.source) from None
        for w in caught:
            if issubclass(w.category, DesignWarning):
                names = seen.setdefault(_one_line(w.message), [])
                if design.name not in names:
                    names.append(design.name)
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        if result is None:
            continue
        formats = list(dict.fromkeys(export))  # "--export law --export law": once
        derived = None
        if "law" in formats and "law" not in result.diagnostics:
            formats.remove("law")
            derived = _derived_law(spec, design, result)
        from tanksynth.artefacts.datafiles import data_copies, data_files
        from tanksynth.artefacts.io import artefact_document

        # the artefact checked (non-finite gains, ...) before anything is written; the data files
        # it read (a fit's logs) copied first, under the same lock (its verdict reads them), and
        # put back as they were if the artefact's write fails: an earlier fit's copies survive
        artefact_document(result, spec.sha256)
        with data_copies(outdir, data_files(result.diagnostics)):
            written.append(write_artefact(result, outdir, spec.sha256, export=formats,
                                          plant_record_sha256=plant_sha))
        if "law" in formats:
            laws.append(outdir / f"{design.name}_law.casadi")
        if derived is not None:  # the law (or estimator step) built from the written gains
            from tanksynth.artefacts.export import export_law, law_statement

            laws.append(export_law(derived, outdir, name=f"{design.name}_law",
                                   statement=law_statement(result.diagnostics, result.gains)).casadi)
    for text, names in seen.items():
        click.echo(f"warning: {', '.join(names)}: {text}", err=True)
    for line in infeasible:
        click.echo(f"refused {line}")
    write_refused(outdir, refused)
    return written, infeasible, laws


def _derived_law(spec: Spec, design: DesignSpec, result: DesignResult) -> casadi.Function | None:
    """The law / estimator step of a design without one in its diagnostics (None: says so)."""
    from tanksynth.artefacts.export import derived_law

    law = derived_law(result.gains, result.diagnostics, design.method, spec, design.config,
                      f"{design.name}_law")
    if law is None:
        _out.print(f"{design.name}: no control law or estimator step to export (method "
                   f"{design.method})", markup=False, highlight=False, soft_wrap=True)
    return law


class _Commands(click.Group):
    """The command group; an interruption passes through as `Interrupted` (click would turn it
    into an `Abort` after an empty line on stderr)."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except Interrupted as exc:
            raise _Stopped(exc.signum) from None
        except KeyboardInterrupt:
            raise _Stopped(int(signal.SIGINT)) from None


class _Stopped(BaseException):
    """`Interrupted`, carried through click (which catches every `KeyboardInterrupt`)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


@click.group(cls=_Commands, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="tanksynth")
@click.option("-v", "--verbose", is_flag=True,
              help="Also print the raw text of the library warnings the note summarises.")
def cli(verbose: bool) -> None:
    """Observer and controller synthesis for multi-tank hydraulic plants."""


@cli.command()
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of tables.")
@click.option("--markdown", is_flag=True, help="Print the families, their options and the custom "
                                               "plant as Markdown (docs/plant_families.md).")
def plants(as_json: bool, markdown: bool) -> None:
    """List the plant families: their options, parameters and units, and the custom plant."""
    from tanksynth.docgen import (custom_plant_markdown, plain_text, plant_families,
                                  plant_variants_markdown, plants_markdown)
    from tanksynth.plants import BUILTIN_PLANTS

    if markdown:
        click.echo(plants_markdown(), nl=False)
        return
    summaries = [builder().summary() for builder in BUILTIN_PLANTS.values()]
    families = {f["name"]: f for f in plant_families()}
    if as_json:
        click.echo(json.dumps([{**s, "options": families[s["name"]]["options"]} for s in summaries],
                              indent=2))
        return
    for s in summaries:
        table = Table(title=f"{s['name']}: {s['description']}")
        table.add_column("parameter")
        table.add_column("value", justify="right")
        table.add_column("unit")
        table.add_column("meaning")
        for p in s["parameters"]:
            table.add_row(p["name"], f"{p['value']:.6g}", p["unit"], p["description"])
        _out.print(table)
        signals = ("states: " + ", ".join(f"{v['name']} [{v['unit']}]" for v in s["states"])
                   + "; inputs: " + ", ".join(f"{v['name']} [{v['unit']}]" for v in s["inputs"])
                   + "; outputs: " + ", ".join(f"{v['name']} [{v['unit']}]" for v in s["outputs"]))
        _out.print(signals, markup=False, highlight=False)
        options = families[s["name"]]["options"]
        _out.print(plain_text("options ([plant] keys): " + ("; ".join(
            f"{o['name']} = {o['default']} ({o['type']}): {o['meaning'].rstrip('.')}" for o in options)
            if options else "none")), markup=False, highlight=False)
        for line in plant_variants_markdown(families[s["name"]]):
            _out.print(plain_text(line), markup=False, highlight=False)
        _out.print()
    _out.print(plain_text(custom_plant_markdown(level=2)), markup=False, highlight=False)


@cli.command()
@click.argument("name", required=False)
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of tables.")
@click.option("--markdown", is_flag=True, help="Print Markdown (docs/design_methods.md).")
def methods(name: str | None, as_json: bool, markdown: bool) -> None:
    """List the design methods; with NAME, each of its options (type, default, unit, meaning)."""
    from tanksynth.docgen import (method_catalogue, method_markdown, method_options, methods_markdown,
                                  option_cells)

    if markdown:
        click.echo(method_markdown(name) if name else methods_markdown(), nl=False)
        return
    if name is None:
        cat = method_catalogue()
        if as_json:
            click.echo(json.dumps(cat, indent=2))
            return
        from tanksynth.methods import ALIASES

        title = "Design methods (tanksynth methods NAME: its options)"
        rows = [(m["name"], " / ".join(m["kinds"]), m["summary"]) for m in cat]
        rows += [(each.name, "alias", each.describe()) for each in ALIASES.values()]
        if _piped():  # piped: one plain line per method (grep, less), not a wrapped table
            widths = [max(len(r[i]) for r in rows + [("method", "kind", "")]) for i in (0, 1)]
            for r in [("method", "kind", "designs"), *rows]:
                click.echo(f"{r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]}")
        else:
            table = Table(title=title)
            for col in ("method", "kind", "designs"):
                table.add_column(col, overflow="fold")
            for row in rows:
                table.add_row(*row)
            _out.print(table)
        return
    from tanksynth.methods import ALIASES, method

    entry = method(name)  # SpecError (exit 2) naming the methods for an unknown name
    docs = method_options(name)
    alias = ALIASES.get(name)
    if as_json:
        click.echo(json.dumps({"name": entry.name, "kinds": list(entry.kinds), "summary": entry.summary,
                               "options": docs, **({"alias": name, "alias_of": entry.name,
                                                    "alias_options": dict(alias.options)}
                                                   if alias else {})}, indent=2))
        return
    from rich.markup import escape

    if alias is not None:
        _out.print(f"{name}: {alias.describe()}", markup=False, highlight=False, soft_wrap=True)

    table = Table(title=escape(f"{entry.name} ({' / '.join(entry.kinds)}): {entry.summary}"))
    for col, ratio in (("option", 2), ("type", 2), ("default", 2), ("unit", 2), ("meaning", 3)):
        table.add_column(col, overflow="fold", ratio=ratio, min_width=15 if col == "unit" else None)
    for d in docs:
        typ, default = option_cells(d)
        table.add_row(escape(d["name"]), escape(typ),
                      "[bold]required[/]" if d["required"] else escape(default),
                      *(escape(d[k].replace("``", "")) for k in ("unit", "meaning")))
    _wide().print(table if docs else f"{entry.name}: no options")


@cli.command()
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("-o", "--output", "outdir", default=None, type=click.Path(file_okay=False),
              help="Also write the verdicts to DIR/checks.json (the file the report reads).")
@click.option("--spec-only", is_flag=True,
              help="Only validate SPEC (plant, operating point, every design's options); no rank checks.")
def check(spec: str, as_json: bool, outdir: str | None, spec_only: bool) -> None:
    """Observability/controllability rank conditions of SPEC's plant."""
    from tanksynth.artefacts.io import to_jsonable

    s = _load(spec)
    if spec_only:
        from tanksynth.spec.memory import conic_refusal

        too_large = [why for d in s.designs if (why := conic_refusal(d, s.plant, s.ts)) is not None]
        summary = {"spec": spec, "plant": s.plant.name, "designs": [d.name for d in s.designs],
                   "refused": too_large}
        if as_json:
            click.echo(json.dumps(summary, indent=2))
        else:
            _out.print(f"{spec}: valid; plant {s.plant.name}, {len(s.designs)} design(s)",
                       markup=False, highlight=False, soft_wrap=True)
            for why in too_large:
                click.echo(f"refused {why}")
        if too_large:
            raise _Fail(EXIT_INFEASIBLE, f"{len(too_large)} of {len(s.designs)} design(s) would be "
                                         "refused: over the memory budget")
        return
    with _stage("rank conditions (Kalman, PBH, nonlinear observability)", quiet=as_json):
        checks = _rank_conditions(s)
    text = json.dumps(to_jsonable([c.as_dict() for c in checks]), indent=2)
    if outdir is not None:
        from tanksynth.artefacts.atomic import atomic_write

        Path(outdir).mkdir(parents=True, exist_ok=True)
        atomic_write(Path(outdir) / "checks.json", text + "\n")
    if as_json:
        click.echo(text)
    else:
        _print_checks(checks)
        if outdir is not None:
            _out.print(f"rank verdicts: {Path(outdir) / 'checks.json'}", markup=False, highlight=False,
                       soft_wrap=True)
    if any(c.passed is False for c in checks):
        raise _Fail(EXIT_FAILED, "some rank conditions fail")


@cli.command()
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "outdir", required=True, type=click.Path(file_okay=False),
              help="Directory for the artefacts.")
@click.option("--export", multiple=True, type=click.Choice(["mat", "h", "law"]),
              help="Also write .mat files, C headers of the gains, or the control law as a "
                   "CasADi Function and generated C (repeatable).")
@click.option("--force", is_flag=True,
              help="Replace the files of a run of ANOTHER spec found in the output directory.")
def design(spec: str, outdir: str, export: tuple[str, ...], force: bool) -> None:
    """Write one artefact per [[design]] entry of SPEC."""
    s = _load(spec)
    if not s.designs:
        raise SpecError("the spec has no [[design]] entry", key="design", source=spec)
    with _locked(outdir, "design"):
        _refuse_other_spec(s, Path(outdir), force)
        _remove_interrupted(Path(outdir))
        written, infeasible, laws = _design_all(s, Path(outdir), export)
    for path in written:
        _out.print(f"artefact: {path}", markup=False, highlight=False, soft_wrap=True)  # one line, as given
    for path in laws:  # the files and the signature, read back from the written Function
        _out.print(law_line(path), markup=False, highlight=False, soft_wrap=True)
    if infeasible:
        raise _Fail(EXIT_INFEASIBLE, _refused_summary(infeasible, len(s.designs)))


def _refused_summary(infeasible: list[str], total: int) -> str:
    """``k of n design(s) refused: a, b`` (the reasons were printed one per line)."""
    names = [line.split(":", 1)[0] for line in infeasible]
    return f"{len(names)} of {total} design(s) refused (no artefact): {', '.join(names)}"


@cli.command()
@click.argument("spec", required=False, type=click.Path(dir_okay=False))
@click.option("-o", "--output", "outdir", default="tanksynth-out", show_default=True,
              type=click.Path(file_okay=False), help="Directory for artefacts and results.")
@click.option("--pdf/--no-pdf", default=None,
              help="Also compile the report to DIR/report.pdf (LaTeX). Default: on for the built-in "
                   "demo when pdflatex and latexmk are installed, off otherwise.")
@click.option("--force", is_flag=True,
              help="Replace the files of a run of ANOTHER spec found in the output directory.")
def run(spec: str | None, outdir: str, pdf: bool | None, force: bool) -> None:
    """Rank checks, every design of SPEC, their verification and the report.

    With no SPEC, the built-in demo: LMI-region and exact pole placement with integral
    action, a certified Takagi-Sugeno observer and an EKF on the DTS200 three-tank.
    """
    s = _load(spec)
    out = Path(outdir)
    with _locked(out, "run"):
        _refuse_other_spec(s, out, force)
        _remove_interrupted(out)
        _run_locked(s, spec, out, pdf)


def _run_locked(s: Spec, spec: str | None, out: Path, pdf: bool | None) -> None:
    have_tex = all(shutil.which(tool) for tool in ("pdflatex", "latexmk"))
    if pdf is None:
        pdf = spec is None and have_tex
    clock = StageClock()
    # the report's imports run in a forked worker on the other core meanwhile (report_worker)
    worker = ReportWorker.start(out, pdf) if s.designs else None
    try:
        _run_stages(s, spec, out, pdf, have_tex, clock, worker)
    except KeyboardInterrupt:  # interrupted: the worker ends now, before the lock is released
        if worker is not None:
            worker.stop()
        raise
    finally:
        if worker is not None:
            worker.cancel()


def _run_stages(s: Spec, spec: str | None, out: Path, pdf: bool, have_tex: bool, clock: StageClock,
                worker: ReportWorker | None) -> None:
    from tanksynth.artefacts.atomic import atomic_write
    from tanksynth.artefacts.io import to_jsonable
    from tanksynth.methods import verify_directory

    with _stage("rank conditions (Kalman, PBH, nonlinear observability)"), clock("rank checks"):
        checks = _rank_conditions(s)
    _print_checks(checks)
    if s.designs:
        _out.print(f"designing {len(s.designs)} gain(s): "
                   + ", ".join(f"{d.name} ({d.method})" for d in s.designs), markup=False,
                   highlight=False)
    with clock("design"):
        written, infeasible, _ = _design_all(s, out, ())
    checks_path = out / "checks.json"
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(checks_path, json.dumps(to_jsonable([c.as_dict() for c in checks]), indent=2) + "\n")
    if worker is not None and written:
        worker.designed()  # it draws the eigenvalue maps while the artefacts are verified
    for path in written:
        _out.print(f"artefact: {path}", markup=False, highlight=False, soft_wrap=True)
    _out.print(f"rank verdicts: {checks_path}", markup=False, highlight=False, soft_wrap=True)
    verdicts = []
    if written:
        _out.print("- verifying every artefact on the nonlinear plant", markup=False, highlight=False)
        with _progress() as bar, clock("verify"):
            task = bar.add_task("verifying artefacts", total=len(written))
            verdicts = verify_directory(out, progress=lambda d, n: bar.update(task, completed=d, total=n),
                                        started=_started(bar, task))
        with clock("report"):
            res = _write_report(out, pdf, worker)
        if res.pdf is not None:
            clock.part("report", "LaTeX", res.latex_seconds)
        print_summary(written, _wide())
        if spec is None and not have_tex:
            _out.print("no PDF: install pdflatex and latexmk (Debian: make tex) and run "
                       f"'tanksynth report {out} --pdf'", markup=False, highlight=False)
    else:
        _out.print("no report: no design artefact was written")
    _out.print(clock.line(), markup=False, highlight=False, soft_wrap=True)
    if infeasible:
        raise _Fail(EXIT_INFEASIBLE, _refused_summary(infeasible, len(s.designs)))
    failed = [c.name for c in checks if c.passed is False]
    failed += [v.name for v in verdicts if v.passed is False]
    if failed:
        raise _Fail(EXIT_FAILED, "some checks fail: " + ", ".join(failed))


#: A campaign estimated to take at least this long (s) shows its progress on stderr.
_LONG_CAMPAIGN = 10.0
#: Without a terminal, one progress line per this fraction of the tasks.
_PROGRESS_STEP = 0.1


@contextmanager
def _campaign_progress(total: int, seconds: float) -> Iterator[Callable[[int, int], None]]:
    """``progress(done, total)`` for a campaign, shown on stderr when it is long: a bar when stderr
    is a terminal, else one plain line per 10 % of the tasks (with the elapsed time)."""
    err = Console(stderr=True)
    if seconds < _LONG_CAMPAIGN:
        yield lambda done, n: None
        return
    if err.is_terminal and _live():
        from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                                   TimeElapsedColumn, TimeRemainingColumn)

        with Progress(TextColumn("campaign"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      TimeRemainingColumn(), console=err, transient=True) as bar:
            task = bar.add_task("campaign", total=total)
            yield lambda done, n: bar.update(task, completed=done, total=n)
        return
    import time

    start = time.monotonic()
    shown = [0]

    def plain(done: int, n: int) -> None:
        step = int(done / max(n, 1) / _PROGRESS_STEP)
        if step > shown[0]:
            shown[0] = step
            click.echo(f"campaign: {done} of {n} tasks ({100 * done // max(n, 1)} %), "
                       f"{time.monotonic() - start:.0f} s", err=True)

    yield plain


def _started(bar: Progress, task: TaskID) -> Callable[[int, int, str, str], None]:
    """``started(done, total, name, method)`` for `verify_directory`: the bar names the artefact
    being verified (its checks run inside one verdict)."""
    return lambda d, n, name, method: bar.update(task, completed=d, total=n,
                                                 description=f"verifying {name} ({method})")


def _write_report(directory: Path, pdf: bool, worker: ReportWorker | None = None) -> ReportSummary:
    """Write the report (by ``worker`` when given and it manages, else here) and say where."""
    with _stage("writing the report (figures, LaTeX" + (", PDF with latexmk)" if pdf else ")")):
        res = worker.finish() if worker is not None else None
        if res is None:
            from tanksynth.methods import write_report

            res = report_summary(write_report(directory, pdf=pdf))
    if res.pdf is not None:
        _out.print(f"report: {res.tex}, {res.pdf.name} ({res.pages} pages, LaTeX "
                   f"{res.latex_seconds:.1f} s)", markup=False, highlight=False, soft_wrap=True)
    else:
        tex = all(shutil.which(tool) for tool in ("pdflatex", "latexmk"))
        _out.print(f"report: {res.tex} (" + ("add --pdf for the PDF)" if tex else
                                             "for the PDF: install pdflatex and latexmk, then --pdf)"),
                   markup=False, highlight=False, soft_wrap=True)
    for title, count in res.errata:
        _out.print(f"paper vs tool ({title}): {count} printed value(s) in the "
                   "paper differ from the derivation (paper errata; not a failure of the designs: "
                   "the report's section 'Paper vs tool')", markup=False, highlight=False,
                   soft_wrap=True)
    return res


def _fit_design(s: Spec, data: tuple[str, ...], validate: tuple[str, ...]) -> DesignSpec:
    """The spec's fit design (its first one), or a default one named ``fit``, with the command
    line's files (absolute paths) in place of its own when given."""
    from dataclasses import replace

    from tanksynth.methods import METHODS
    from tanksynth.spec import DesignSpec

    entries = [d for d in s.designs if d.method == "fit"]
    if entries:
        entry = entries[0]
    else:
        entry = DesignSpec("fit", "fit", {}, f"design[{len(s.designs)}]")
    options = dict(entry.options)
    if data:
        options["data"] = [str(Path(p).resolve()) for p in data]
    if validate:
        options["validate"] = [str(Path(p).resolve()) for p in validate]
    if not options.get("data"):
        raise SpecError("no estimation data: pass --data FILE (repeatable) or give data = [...] in "
                        "the spec's fit design", key=f"{entry.key}.data", source=s.source)
    config = METHODS["fit"].validate(options, entry.key, s.plant, s.ts)
    return replace(entry, options=options, config=config)


def _fitted_toml(s: Spec, doc: dict, out: Path) -> Path:
    """Write ``DIR/fitted.toml``: the spec with the fitted values (see `tanksynth.spec.fitted`),
    checked to load as a spec relative to DIR."""
    from tanksynth.artefacts.atomic import atomic_write
    from tanksynth.methods import load_spec
    from tanksynth.spec.fitted import FittedValue, fitted_spec_text

    diag = doc["diagnostics"]
    level = float(diag.get("level", 0.95))
    unc = diag.get("uncertainty") or {}
    methods = unc.get("interval_method") or {}
    # a parameter the data do not determine keeps its start value: the optimum moved it freely
    fitted = {nm: FittedValue(float(p["value"]), float(p["ci95"][0]), float(p["ci95"][1]), level,
                              str(p.get("unit", "")))
              if methods.get(nm) != "unidentifiable" else
              FittedValue(float(p["start"]), float(p["lower"]), float(p["upper"]), level,
                          str(p.get("unit", "")), determined=False)
              for nm, p in diag["parameters"].items()}
    text = fitted_spec_text(s.text, fitted, f"{doc['name']}.json")
    target = atomic_write(out / "fitted.toml", text.encode("utf-8"))
    try:
        load_spec(target)  # it must load (relative to DIR) as a spec, or the user hears it now
    except BaseException:
        target.unlink(missing_ok=True)  # a fitted spec that does not load is not left behind
        raise
    return target


def _fit_preflight(s: Spec, entry: DesignSpec, free: tuple[Any, ...]) -> None:
    """Refuse, before the fit runs and anything is written, a spec whose fitted values cannot be
    written into ``fitted.toml`` and estimation data a fit cannot learn from (every sample
    missing or censored, fewer observed values than unknowns): exit 2 in seconds, not after
    the fit."""
    from tanksynth.measurements import read_experiments
    from tanksynth.measurements.read import check_fit_data
    from tanksynth.spec.context import resolve
    from tanksynth.spec.fitted import FittedValue, fitted_spec_text

    if s.text:
        fitted_spec_text(s.text, {p.name: FittedValue(p.start, p.lower, p.upper, 0.95, p.unit)
                                  for p in free}, f"{entry.name}.json")
    base = Path(s.source).parent if s.source and not s.source.startswith("<") else None
    paths = [str(resolve(p, base)) for p in entry.options.get("data", [])]
    experiments = read_experiments(paths, s.plant, s.data)
    check_fit_data(experiments, len(free), s.plant.n)


def _number(value: Any, spec: str) -> str:
    """``value`` formatted with ``spec`` when it is a number or the JSON text of a non-finite
    one (``"inf"``, ``"nan"``), else as written."""
    try:
        return format(float(value), spec)
    except (TypeError, ValueError):
        return str(value)


def _print_fit(doc: dict, output_units: dict[str, str]) -> None:
    """The fitted parameters (value, standard error, interval, unit) and the scores per output
    (RMSE in the output's unit)."""
    diag = doc["diagnostics"]
    level = 100 * float(diag.get("level", 0.95))
    table = Table(title=f"fit '{doc['name']}': output (simulation) error; "
                        f"{diag.get('starts_tried', '?')} start(s) tried (the search stops once 3 "
                        f"converged starts agree); IPOPT {diag.get('status', '?')}")
    for col in ("parameter", "value", "stderr", f"{level:g} % interval", "unit"):
        table.add_column(col, justify="right" if col not in ("parameter", "unit") else "left")
    for nm, p in diag["parameters"].items():
        lo, hi = p["ci95"]
        # an undetermined parameter's stderr is infinite: JSON holds it as the string "inf"
        table.add_row(nm, _number(p["value"], ".6g"), _number(p["stderr"], ".3g"),
                      f"[{_number(lo, '.6g')}, {_number(hi, '.6g')}]",
                      str(p.get("unit", "")) + (" (at a bound)" if p.get("at_bound") else ""))
    _out.print(table)
    scores = Table(title="output error (fit % = NRMSE fit, 100 (1 - |y - y_sim| / |y - mean y|))")
    for col in ("data", "output", "RMSE", "unit", "fit %"):
        scores.add_column(col, justify="right" if col in ("RMSE", "fit %") else "left")
    for part in ("estimation", "validation"):
        block = diag.get(part) or {}
        for nm, value in (block.get("rmse") or {}).items():
            scores.add_row(part, nm, _number(value, ".4g"), output_units.get(nm, ""),
                           _number(block.get("fit_percent", {}).get(nm, float("nan")), ".1f"))
    _out.print(scores)
    ident = diag.get("identifiability") or {}
    if not ident.get("identifiable", True):
        _out.print(f"identifiability: {ident.get('note', '')}", markup=False, highlight=False,
                   soft_wrap=True)


@cli.command()
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("--data", "data", multiple=True, type=click.Path(exists=True, dir_okay=False),
              help="Estimation data file (.csv, .npz, .mat; repeatable); default the spec's.")
@click.option("--validate", "validate", multiple=True, type=click.Path(exists=True, dir_okay=False),
              help="Validation data file (repeatable); default the spec's.")
@click.option("-o", "--output", "outdir", required=True, type=click.Path(file_okay=False),
              help="Directory for the fit artefact (<design name>.json), fitted.toml, the data copies and the report.")
@click.option("--pdf", is_flag=True, help="Also compile DIR/report.pdf (LaTeX).")
@click.option("--force", is_flag=True,
              help="Replace the files of a run of ANOTHER spec found in the output directory.")
def fit(spec: str, data: tuple[str, ...], validate: tuple[str, ...], outdir: str, pdf: bool,
        force: bool) -> None:
    """Fit SPEC's free parameters (fit = true) and initial states to logged data.

    Writes DIR/<name>.json (the fit artefact; name "fit" unless the spec's fit design says
    otherwise), DIR/data/ (the data files), DIR/fitted.toml (the spec with the fitted values,
    ready for tanksynth run), the verdict and the report.
    """
    from dataclasses import replace

    from tanksynth.artefacts.io import read_artefact
    from tanksynth.design.fit.adapters import free_parameters_of
    from tanksynth.methods import verify_directory

    s = _load(spec)
    free = free_parameters_of(s)  # none: exit 2 saying how to mark one, before anything is written
    entry = _fit_design(s, data, validate)
    try:
        _fit_preflight(s, entry, free)
    except TanksynthError as exc:
        raise _keyed(exc, entry.key, s.source) from None
    one = replace(s, designs=(entry,))
    out = Path(outdir)
    clock = StageClock()
    with _locked(out, "fit"):
        _refuse_other_spec(s, out, force)
        _remove_interrupted(out)
        before = _run_record(out)
        try:
            with clock("fit"):
                written, infeasible, _ = _design_all(one, out, ())
        except Exception:   # bad data found by the fit itself: the directory as it was too
            _restore_run_record(out, before)
            raise
        if infeasible:   # the directory as it was: a fixed spec reruns without --force
            _restore_run_record(out, before)
            raise _Fail(EXIT_INFEASIBLE, _refused_summary(infeasible, 1))
        (path,) = written
        doc = read_artefact(path)
        fitted = _fitted_toml(s, doc, out)
        _print_fit(doc, {q.name: str(q.unit) for q in s.plant.outputs})
        _out.print(f"artefact: {path}", markup=False, highlight=False, soft_wrap=True)
        _out.print(f"fitted spec: {fitted} (tanksynth run {fitted} -o DIR2)", markup=False,
                   highlight=False, soft_wrap=True)
        with clock("verify"):
            verdicts = verify_directory(out)
        _print_checks([c for v in verdicts for c in v.checks], title="Verdict of the fit")
        with clock("report"):
            _write_report(out, pdf)
    _out.print(clock.line(), markup=False, highlight=False, soft_wrap=True)
    failed = [v.name for v in verdicts if v.passed is False]
    if failed:
        raise _Fail(EXIT_FAILED, "the fit's verdict fails: " + ", ".join(failed))


@cli.command()
@click.argument("directory", type=click.Path(file_okay=False))
@click.option("--pdf", is_flag=True, help="Also compile DIR/report.pdf with latexmk/pdflatex.")
def report(directory: str, pdf: bool) -> None:
    """Write DIRECTORY/report.tex (and with --pdf report.pdf) from the files in it."""
    if not Path(directory).is_dir():
        raise SpecError("no such result directory", source=directory)
    with _locked(directory, "report"):
        _write_report(Path(directory), pdf)


@cli.command()
@click.argument("directory", type=click.Path(file_okay=False))
@click.option("--scheduler", default=None, metavar="ADDR",
              help="Dask scheduler address (tcp://host:port); default: this machine.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of tables.")
@click.option("--runs", default=0, show_default=True, type=click.IntRange(min=0, max=100_000),
              help="Also run a Monte-Carlo campaign of this many runs per scenario.")
@click.option("--scenario", "scenarios", multiple=True,
              help="Campaign scenario (repeatable; default: every one defined for the plant).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0), help="Campaign seed.")
@click.option("--workers", default=2, show_default=True, type=click.IntRange(min=1, max=MAX_WORKERS),
              help=f"Worker processes of the local Dask cluster (at most {MAX_WORKERS}: 4 per CPU).")
@click.option("--connect-timeout", default=10.0, show_default=True, type=_Seconds(min=0.1, max=600.0),
              help="Seconds to wait for the Dask scheduler given with --scheduler.")
@click.option("--worker-timeout", default=WORKER_TIMEOUT, show_default=True,
              type=_Seconds(min=0.1, max=3600.0),
              help="Seconds to wait while the Dask cluster has no worker (its only worker died) "
                   "before giving up.")
def verify(directory: str, scheduler: str | None, as_json: bool, runs: int,
           scenarios: tuple[str, ...], seed: int, workers: int, connect_timeout: float,
           worker_timeout: float) -> None:
    """Simulate every artefact of DIRECTORY and record the verdicts in it."""
    from tanksynth.sim.scenarios import scenario

    for name in scenarios:
        scenario(name)  # unknown names are bad input (exit 2) before any work
    if not Path(directory).is_dir():
        raise SpecError("no such result directory", source=directory)
    cluster = {"connect_timeout": connect_timeout, "worker_timeout": worker_timeout,
               "waiting": _say_waiting}
    with _locked(directory, "verify"):
        _verify_locked(directory, scheduler, as_json, runs, scenarios, seed, workers, cluster)


@cli.command()
@click.argument("directory", type=click.Path(file_okay=False))
@click.option("--data", "data", multiple=True, required=True, type=click.Path(dir_okay=False),
              help="Logged experiment (.csv with a header row, .npz or .mat; repeatable), in the "
                   "plant's signal names or mapped by the spec's [data] table.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of lines.")
def replay(directory: str, data: tuple[str, ...], as_json: bool) -> None:
    """Run every estimator, observer and detector artefact of DIRECTORY on logged data.

    Writes DIRECTORY/replay.json and the traces DIRECTORY/replay/*.npz; one line per artefact
    and file; exit 1 when a check on the data fails (`tanksynth report DIRECTORY` then adds the
    section "On measured data").
    """
    if not Path(directory).is_dir():
        raise SpecError("no such result directory", source=directory)
    with _locked(directory, "replay"):
        _replay_locked(Path(directory), data, as_json)


def _replay_locked(directory: Path, data: tuple[str, ...], as_json: bool) -> None:
    from rich.markup import escape

    from tanksynth.measurements import read_experiments
    from tanksynth.methods import RUNNERS, load_directory
    from tanksynth.verify.replay import replay_artefacts, replay_line, write_replay

    spec, docs = load_directory(directory)
    experiments = read_experiments(list(data), spec.plant, spec.data)
    with _stage(f"replaying {len(docs)} artefact(s) on {len(experiments)} log(s)", quiet=as_json):
        replays = replay_artefacts(spec, [d for _, d in docs], experiments, RUNNERS)
    path = write_replay(directory, replays, data)
    if as_json:
        from tanksynth.artefacts.io import to_jsonable

        click.echo(json.dumps(to_jsonable(json.loads(path.read_text(encoding="utf-8"))), indent=2))
    else:
        colour = {True: "green", False: "red", None: "blue"}
        for r in replays:
            line = replay_line(r)
            head, _, rest = line.partition(" · ")
            _out.print(f"[{colour[r.passed]}]{escape(head)}[/]" + (f" · {escape(rest)}" if rest else ""),
                       highlight=False, soft_wrap=True)
        _out.print(f"replay: {path} (traces in {path.parent / 'replay'})", markup=False, highlight=False)
    for r in replays:
        if r.kind == "detector" and r.summary.get("alarms"):
            click.echo(f"warning: {r.artefact} raised {r.summary['alarms']} alarm(s) on "
                       f"{r.experiment.name}, first at t = {r.summary['first_alarm']:g} s: a false "
                       "alarm if that run was fault-free", err=True)
    failed = [f"{r.artefact} on {r.experiment.name}" for r in replays if r.passed is False]
    if failed:
        raise _Fail(EXIT_FAILED, "some checks on measured data fail: " + ", ".join(failed))


def _say_waiting(text: str) -> None:
    """One line on stderr: the Dask cluster has no worker (`tanksynth.verify.cluster.completed`)."""
    click.echo(text, err=True)


def _verify_locked(directory: str, scheduler: str | None, as_json: bool, runs: int,
                   scenarios: tuple[str, ...], seed: int, workers: int, cluster: dict[str, Any]) -> None:
    from tanksynth.artefacts.io import to_jsonable
    from tanksynth.methods import verify_directory

    quiet = as_json
    table_path = None
    if runs:  # the campaign's modules only when one runs; its estimate before any other work
        from tanksynth.methods import RUNNERS, load_directory
        from tanksynth.sim.scenarios import SCENARIOS
        from tanksynth.verify.campaign import campaign_tasks, estimate_campaign, run_campaign

        spec, docs = load_directory(directory)
        names = list(scenarios) or [s for s in SCENARIOS if SCENARIOS[s].applies_to(spec.plant)]
        tasks = campaign_tasks(spec.text or (Path(directory) / "spec.toml").read_text(encoding="utf-8"),
                               [d for _, d in docs], names, runs, seed=seed, runners=RUNNERS)
        estimate = estimate_campaign(tasks, workers)  # refuses a table past the memory budget
        click.echo(estimate.line(), err=True)
    with _progress(quiet) as bar:
        task = bar.add_task("verifying artefacts", total=None)
        verdicts = verify_directory(directory, scheduler=scheduler,
                                    progress=lambda d, n: bar.update(task, completed=d, total=n),
                                    started=_started(bar, task), **cluster)
    if runs:
        with _campaign_progress(len(tasks), estimate.seconds) as progress:
            table = run_campaign(tasks, scheduler=scheduler, workers=workers, progress=progress,
                                 done=estimate.done, **cluster)
        table_path = table.to_csv(Path(directory) / "campaign.csv")
    if as_json:
        click.echo(json.dumps(to_jsonable({"artefacts": [{"name": v.name, "method": v.method,
                                                          **v.as_dict()} for v in verdicts],
                                           "campaign": None if table_path is None else str(table_path)}),
                              indent=2))
    else:
        for v in verdicts:
            verdict = "pass" if v.passed else "FAIL"
            _print_checks(v.checks, title=f"{v.name} ({v.method}): {verdict}")
        if table_path is not None:
            _out.print(f"campaign table: {table_path}", markup=False, highlight=False)
    if any(v.passed is False for v in verdicts):
        raise _Fail(EXIT_FAILED, "some verification checks fail: "
                    + ", ".join(v.name for v in verdicts if v.passed is False))


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; return the exit code (bad input: 2, one line, no traceback).

    Warnings raised by libraries while a command runs (numpy's RuntimeWarning
    on a NaN handled downstream, ...) do not reach stderr: they are counted in
    one note on stdout (none with ``--json``). A design's own `DesignWarning`
    lines go to stderr (``warning: <designs>: <text>``). A file-size limit
    (``ulimit -f``) is an error on the file being written (exit 2), not a signal.
    SIGINT, SIGTERM and SIGHUP interrupt any command the same way (`tanksynth.process`):
    children ended, staged files removed, the lock released, one line, exit 130.

    Parameters
    ----------
    argv : list of str, optional
        Arguments after ``tanksynth`` (default ``sys.argv[1:]``).
    """

    _ignore_file_size_signal()
    _one_blas_thread()
    args = list(sys.argv[1:] if argv is None else argv)
    with interruptible():
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                code = _main(args)
            note_warnings(caught, _out, quiet="--json" in args, code=code,
                          verbose=bool(args) and args[0] in ("-v", "--verbose"))
        except KeyboardInterrupt as exc:  # between commands' clean-ups (parsing, the note)
            code = _interrupted(exc.signum if isinstance(exc, Interrupted) else int(signal.SIGINT))
    return code


def _interrupted(signum: int) -> int:
    """Say, on one line, that the command was interrupted; the exit code `EXIT_INTERRUPTED`."""
    name = Interrupted(signum).signal_name
    try:
        click.echo(f"interrupted ({name}): stopped; child processes ended, no partial file left, "
                   "the result directory's lock released", err=True)
    except (OSError, ValueError):  # stderr gone with the terminal (SIGHUP)
        pass
    return EXIT_INTERRUPTED






def _main(argv: list[str]) -> int:
    try:
        cli.main(args=argv, prog_name="tanksynth", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.ClickException as exc:
        click.echo(f"error: {_one_line(exc.format_message())}", err=True)
        return EXIT_BAD_INPUT
    except _Stopped as exc:
        return _interrupted(exc.signum)
    except click.exceptions.Abort as exc:
        if isinstance(exc.__cause__, KeyboardInterrupt):  # while the arguments were parsed
            cause = exc.__cause__
            return _interrupted(cause.signum if isinstance(cause, Interrupted) else int(signal.SIGINT))
        return EXIT_BAD_INPUT
    except _Fail as exc:
        click.echo(f"{'infeasible' if exc.code == EXIT_INFEASIBLE else 'failed'}: {_one_line(exc)}",
                   err=True)
        return exc.code
    except InfeasibleDesign as exc:
        click.echo(f"infeasible: {_one_line(exc)}", err=True)
        return EXIT_INFEASIBLE
    except TanksynthError as exc:
        click.echo(f"error: {_design_index_note(_one_line(exc))}", err=True)
        return EXIT_BAD_INPUT
    except OSError as exc:  # a path the user gave: unwritable, missing, full disk ...
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"error: {where}{exc.strerror or _one_line(exc)[:200]}", err=True)
        return EXIT_BAD_INPUT
    except MemoryError:
        click.echo("error: out of memory: the problem is too large for this machine; reduce the "
                   "sizes in the spec (samples, windows, grids, steps) or "
                   "TANKSYNTH_MEMORY_BUDGET_MB", err=True)
        return EXIT_BAD_INPUT
    except Exception as exc:  # a bug: one line here, the traceback in a log file
        log = _internal_error_log()
        click.echo(f"internal error: {type(exc).__name__}: {_one_line(exc)[:200]} (traceback in {log}; "
                   "please report it)", err=True)
        return EXIT_INTERNAL
    return EXIT_OK






if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
