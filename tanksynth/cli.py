"""The ``tanksynth`` command.

Exit codes: 0 success, 1 a verification (rank) check failed, 2 bad input
(one line on stderr, no traceback), 3 a design was infeasible (no artefact
written for it).
"""

from __future__ import annotations

import json
import sys
from importlib import resources
from pathlib import Path

import click
from rich.console import Console
from rich.table import Table

from .errors import InfeasibleDesign, SpecError, TanksynthError

__all__ = ["main", "cli"]

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INFEASIBLE = 0, 1, 2, 3

_out = Console()


class _Fail(Exception):
    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def _load(spec_path: str | None):
    from .spec import load_spec, parse_spec_text

    if spec_path is None:
        text = resources.files("tanksynth.data").joinpath("demo.toml").read_bytes()
        return parse_spec_text(text, source="<built-in demo>")
    return load_spec(spec_path)


def _print_checks(checks) -> None:
    table = Table(title="Rank conditions")
    table.add_column("check")
    table.add_column("verdict")
    table.add_column("detail", overflow="fold")
    for c in checks:
        verdict = {True: "[green]pass[/]", False: "[red]FAIL[/]", None: "[blue]info[/]"}[c.passed]
        table.add_row(c.name, verdict, c.detail)
    _out.print(table)


def _design_all(spec, outdir: Path, export: tuple[str, ...]) -> tuple[list[Path], list[str]]:
    from .artefact import write_artefact, write_plant_record
    from .design import METHODS

    write_plant_record(spec, outdir)
    written, infeasible = [], []
    for design in spec.designs:
        try:
            result = METHODS[design.method].run(spec, design)
        except InfeasibleDesign as exc:
            infeasible.append(f"{design.name}: {_one_line(exc)}")
            continue
        written.append(write_artefact(result, outdir, spec.sha256, export=export))
    return written, infeasible


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="tanksynth")
def cli() -> None:
    """Observer and controller synthesis for multi-tank hydraulic plants."""


@cli.command()
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of tables.")
def plants(as_json: bool) -> None:
    """List the built-in plants, their parameters and units."""
    from .plants import BUILTIN_PLANTS

    summaries = [builder().summary() for builder in BUILTIN_PLANTS.values()]
    if as_json:
        click.echo(json.dumps(summaries, indent=2))
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


@cli.command()
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
def check(spec: str, as_json: bool) -> None:
    """Observability/controllability rank conditions of SPEC's plant."""
    from .artefact import to_jsonable
    from .verify.checks import rank_conditions

    s = _load(spec)
    checks = rank_conditions(s.plant, s.x0, s.ts, s.given_u0)
    if as_json:
        click.echo(json.dumps(to_jsonable([c.as_dict() for c in checks]), indent=2))
    else:
        _print_checks(checks)
    if any(c.passed is False for c in checks):
        raise _Fail(EXIT_FAILED, "some rank conditions fail")


@cli.command()
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "outdir", required=True, type=click.Path(file_okay=False),
              help="Directory for the artefacts.")
@click.option("--export", multiple=True, type=click.Choice(["mat", "h"]),
              help="Also write .mat files or C headers (repeatable).")
def design(spec: str, outdir: str, export: tuple[str, ...]) -> None:
    """Write one artefact per [[design]] entry of SPEC."""
    s = _load(spec)
    if not s.designs:
        raise SpecError("the spec has no [[design]] entry", key="design", source=spec)
    written, infeasible = _design_all(s, Path(outdir), export)
    for path in written:
        _out.print(f"wrote {path}")
    if infeasible:
        raise _Fail(EXIT_INFEASIBLE, "infeasible: " + "; ".join(infeasible))


@cli.command()
@click.argument("spec", required=False, type=click.Path(dir_okay=False))
@click.option("-o", "--output", "outdir", default="tanksynth-out", show_default=True,
              type=click.Path(file_okay=False), help="Directory for artefacts and results.")
def run(spec: str | None, outdir: str) -> None:
    """Rank checks and every design of SPEC (default: the built-in three-tank demo)."""
    from .artefact import to_jsonable

    from .verify.checks import rank_conditions

    s = _load(spec)
    out = Path(outdir)
    checks = rank_conditions(s.plant, s.x0, s.ts, s.given_u0)
    _print_checks(checks)
    written, infeasible = _design_all(s, out, ())
    checks_path = out / "checks.json"
    out.mkdir(parents=True, exist_ok=True)
    checks_path.write_text(json.dumps(to_jsonable([c.as_dict() for c in checks]), indent=2) + "\n")
    for path in written:
        _out.print(f"artefact: {path}")
    _out.print(f"rank verdicts: {checks_path}")
    if infeasible:
        raise _Fail(EXIT_INFEASIBLE, "infeasible: " + "; ".join(infeasible))
    if any(c.passed is False for c in checks):
        raise _Fail(EXIT_FAILED, "some rank conditions fail")


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; return the exit code (bad input: 2, one line, no traceback)."""
    try:
        cli.main(args=argv, prog_name="tanksynth", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.ClickException as exc:
        click.echo(f"error: {_one_line(exc.format_message())}", err=True)
        return EXIT_BAD_INPUT
    except click.exceptions.Abort:
        return EXIT_BAD_INPUT
    except _Fail as exc:
        click.echo(f"{'infeasible' if exc.code == EXIT_INFEASIBLE else 'failed'}: {_one_line(exc)}",
                   err=True)
        return exc.code
    except InfeasibleDesign as exc:
        click.echo(f"infeasible: {_one_line(exc)}", err=True)
        return EXIT_INFEASIBLE
    except TanksynthError as exc:
        click.echo(f"error: {_one_line(exc)}", err=True)
        return EXIT_BAD_INPUT
    return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
