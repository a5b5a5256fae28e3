"""Discoverable options: ``tanksynth methods``, ``tanksynth plants``, ``check -o`` and the
generated documentation pages (docs/design_methods.md, docs/plant_families.md)."""

from __future__ import annotations

import dataclasses
import inspect
import json
import re
from pathlib import Path

import click
import pytest

from tanksynth import docgen
from tanksynth.cli import main
from tanksynth.methods import TABLE
from tanksynth.plants import BUILTIN_PLANTS

ROOT = Path(__file__).resolve().parents[1]
METHODS_PAGE = ROOT / "docs" / "design_methods.md"
PLANTS_PAGE = ROOT / "docs" / "plant_families.md"
COMMANDS_PAGE = ROOT / "docs" / "commands.md"
SEED000 = ROOT / "examples" / "seed000_three_tank.toml"


def run_cli(capsys, *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_methods_lists_every_row_with_its_kind(capsys):
    code, out, err = run_cli(capsys, "methods", "--json")
    assert code == 0 and err == ""
    listed = {m["name"]: m for m in json.loads(out)}
    assert list(listed) == [row.name for row in TABLE]
    for row in TABLE:
        assert listed[row.name]["kinds"] == list(row.kinds)
        assert listed[row.name]["summary"] == row.summary
    code, out, _ = run_cli(capsys, "methods")
    assert code == 0
    for name in ("luenberger", "consensus_filter", "fault_detection", "adaptive_scaling_kalman"):
        assert name in out


@pytest.mark.parametrize("row", TABLE, ids=lambda r: r.name)
def test_methods_name_gives_every_option_with_default_unit_and_meaning(capsys, row):
    code, out, err = run_cli(capsys, "methods", row.name, "--json")
    assert code == 0 and err == ""
    options = json.loads(out)["options"]
    fields = dataclasses.fields(row.options)
    assert [o["name"] for o in options] == [f.name for f in fields]
    for o, f in zip(options, fields):
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        assert o["required"] is required
        assert o["default"] == ("required" if required else repr(f.default))
        assert o["unit"], f"{row.name}.{f.name}: no unit (declare it with option(..., unit=...))"
        assert len(o["meaning"]) > 10, f"{row.name}.{f.name}: no meaning in the Attributes docstring"
        assert o["type"] and "\n" not in o["meaning"]


def test_methods_name_table_and_known_values(capsys):
    code, out, _ = run_cli(capsys, "methods", "lmi_placement", "--json")
    by_name = {o["name"]: o for o in json.loads(out)["options"]}
    assert by_name["margin"]["default"] == "1e-06" and by_name["margin"]["unit"] == "-"
    assert "Strictness margin" in by_name["margin"]["meaning"]
    assert by_name["region"]["required"] and "1/s" in by_name["region"]["unit"]
    code, out, _ = run_cli(capsys, "methods", "ekf", "--json")
    by_name = {o["name"]: o for o in json.loads(out)["options"]}
    assert by_name["Q"]["unit"] == "(state units)^2" and by_name["Q"]["required"]
    code, out, _ = run_cli(capsys, "methods", "ekf")
    assert code == 0 and "jacobian_eps" in out and "(state units)^2" in out and "required" in out


def test_methods_unknown_name_is_bad_input(capsys):
    code, out, err = run_cli(capsys, "methods", "pole_placment")
    assert code == 2 and "pole_placement" in err and len(err.strip().splitlines()) == 1


def test_methods_markdown_is_the_generated_text(capsys):
    code, out, _ = run_cli(capsys, "methods", "--markdown")
    assert code == 0 and out == docgen.methods_markdown()
    code, out, _ = run_cli(capsys, "methods", "kalman", "--markdown")
    assert out == docgen.method_markdown("kalman")
    assert ("| `Q` | array of numbers or array of arrays of numbers (a matrix) | **required** "
            "| (state units)^2 |") in out  # the type as written in TOML


def test_plants_shows_family_options_and_the_custom_plant(capsys):
    code, out, err = run_cli(capsys, "plants")
    assert code == 0 and err == ""
    assert "outputs = 'all'" in out and "parameter_set = 'decenter'" in out and "N = 4" in out
    assert 'model = "custom"' in out and "[plant.equations]" in out
    code, out, _ = run_cli(capsys, "plants", "--json")
    data = {p["name"]: p for p in json.loads(out)}
    for name, builder in BUILTIN_PLANTS.items():
        params = inspect.signature(builder).parameters
        assert [o["name"] for o in data[name]["options"]] == list(params)
        for o in data[name]["options"]:
            assert o["default"] == repr(params[o["name"]].default) and o["meaning"]
    code, out, _ = run_cli(capsys, "plants", "--markdown")
    assert out == docgen.plants_markdown()


def test_custom_plant_example_of_the_guide_parses():
    from tanksynth.methods import parse_spec_text

    text = docgen.custom_plant_markdown()
    example = re.search(r"```toml\n(.*?)```", text, re.S).group(1)
    spec = parse_spec_text(example + '\n[operating_point]\nx = {h = 0.3}\n', source="guide")
    assert spec.plant.n == 1 and [s.name for s in spec.plant.states] == ["h"]


def test_generated_doc_pages_are_up_to_date(monkeypatch):
    monkeypatch.chdir(ROOT)
    assert docgen.main(["--check"]) == 0   # python -m tanksynth.docgen --check, as CI runs it
    for page, sections in docgen.DOC_PAGES.items():
        stale = docgen.update_readme(ROOT / page, check=True, sections=sections)
        assert stale == [], f"{page} sections {stale} are stale: run python -m tanksynth.docgen"
    section = docgen.generated_section(METHODS_PAGE.read_text(encoding="utf-8"), "methods")
    for row in TABLE:
        assert f"### `{row.name}`" in section
        for name in row.options.option_names():
            assert f"| `{name}` |" in section, (row.name, name)
    plants = docgen.generated_section(PLANTS_PAGE.read_text(encoding="utf-8"), "plants")
    for name in [*BUILTIN_PLANTS, "custom"]:
        assert f'`model = "{name}"`' in plants


def test_the_readme_is_the_short_path():
    """The README holds no generated section: it links the pages that do."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "BEGIN GENERATED" not in text
    for page in docgen.DOC_PAGES:
        if page != "docs/gain_names.md":
            assert f"]({page})" in text, page
    for link in re.findall(r"\]\((docs/[\w/]+\.md)\)", text):
        assert (ROOT / link).is_file(), link


def test_docgen_check_reports_a_stale_page(tmp_path):
    readme = tmp_path / "design_methods.md"
    readme.write_text(METHODS_PAGE.read_text(encoding="utf-8").replace(
        "| `margin` |", "| `margin_old` |", 1), encoding="utf-8")
    assert docgen.main(["--check", str(readme)]) == 1
    assert docgen.main([str(readme)]) == 0
    assert docgen.main(["--check", str(readme)]) == 0
    assert readme.read_text(encoding="utf-8") == METHODS_PAGE.read_text(encoding="utf-8")


def test_check_output_writes_checks_json(tmp_path, capsys):
    code, out, err = run_cli(capsys, "check", str(SEED000), "-o", str(tmp_path / "res"), "--json")
    assert code == 0, err
    written = json.loads((tmp_path / "res" / "checks.json").read_text(encoding="utf-8"))
    assert written == json.loads(out)
    by_name = {c["check"]: c for c in written}
    assert by_name["observability"]["data"]["rank"] == 3


def _examples_by_method() -> dict[str, tuple[Path, int]]:
    """One example spec (and the index of its [[design]] table) per method."""
    import tomllib

    found: dict[str, tuple[Path, int]] = {}
    for path in sorted((ROOT / "examples").glob("*.toml")):
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        for i, table in enumerate(data.get("design", [])):
            found.setdefault(table["method"], (path, i))
    return found


EXAMPLES_BY_METHOD = _examples_by_method()


@pytest.mark.parametrize("row", TABLE, ids=lambda r: r.name)
def test_catalogue_row_says_what_a_none_default_is(row):
    """Every option whose default is None says what the default IS, and its type admits None."""
    section = docgen.generated_section(METHODS_PAGE.read_text(encoding="utf-8"), "methods")
    for d in row.options.describe():
        if d.default != "None":
            continue
        assert d.default_text, f"{row.name}.{d.name}: default None without a default_text"
        assert "None" in d.type, f"{row.name}.{d.name}: type {d.type!r} does not admit None"
        line = next(ln for ln in section.split(f"### `{row.name}`", 1)[1].splitlines()
                    if ln.startswith(f"| `{d.name}` |"))
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        assert cells[2] == docgen._cell(d.default_text.replace("``", "")), (row.name, d.name, cells)


@pytest.mark.slow
@pytest.mark.parametrize("row", [r for r in TABLE if r.name in EXAMPLES_BY_METHOD],
                         ids=lambda r: r.name)
def test_catalogue_row_lists_every_allowed_value_of_a_choice(row, capsys):
    """Each option is given a word no reader accepts: when the reader answers 'expected one of
    [...]', every value it names must be in the catalogue row and in ``tanksynth methods NAME``."""
    import tomllib

    from tanksynth.errors import SpecError
    from tanksynth.methods import parse_spec

    path, index = EXAMPLES_BY_METHOD[row.name]
    section = docgen.generated_section(METHODS_PAGE.read_text(encoding="utf-8"), "methods")
    rows = section.split(f"### `{row.name}`", 1)[1].split("\n### ", 1)[0]
    _, cli_out, _ = run_cli(capsys, "methods", row.name, "--markdown")
    probed = 0
    for name in row.options.option_names():
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        data["design"][index][name] = "zz_not_a_value"
        try:
            parse_spec(data, source=str(path))
        except SpecError as exc:
            match = re.search(r"expected one of \[(.*?)\]", str(exc))
            if match is None or f"design[{index}].{name}" not in str(exc):
                continue
            allowed = [eval(v) for v in re.findall(r"'[^']*'|-?[\d.e+-]+", match.group(1))]
            line = next(ln for ln in rows.splitlines() if ln.startswith(f"| `{name}` |"))
            for value in allowed:
                shown = f'"{value}"' if isinstance(value, str) else repr(value)
                assert shown in line, f"{row.name}.{name}: allowed value {shown} not in {line}"
                assert shown in cli_out
            probed += 1
    declared = [d for d in row.options.describe() if d.choices]
    assert probed >= len([d for d in declared if d.name != "pole_domain"]), \
        (row.name, probed)


def test_catalogue_shows_route_choices_and_the_poles_table_form(capsys):
    code, out, _ = run_cli(capsys, "methods", "h2_state_feedback", "--markdown")
    assert 'string, one of "auto", "riccati", "lmi"' in out   # types as written in TOML
    assert "| `Q` | array of numbers or array of arrays of numbers (a matrix) | computed: Bryson's" in out
    code, out, _ = run_cli(capsys, "methods", "pole_placement", "--markdown")
    assert "{values, domain}" in out and 'string, one of "s", "z"' in out
    code, out, _ = run_cli(capsys, "methods", "kalman", "--json")
    x0 = {o["name"]: o for o in json.loads(out)["options"]}["x0"]
    assert x0["default"] == "None" and x0["default_text"] == "computed: the operating point"
    code, out, _ = run_cli(capsys, "methods", "h2_state_feedback")
    assert code == 0 and "riccati" in out and "Bryson" in out


def test_no_option_shadows_a_design_table_key():
    """`name` and `method` name the design in a [[design]] table: an option with either name
    could never be set from a spec (pole_placement's placement routine was `method`)."""
    from tanksynth.methods import TABLE

    clashes = [(row.name, key) for row in TABLE for key in ("name", "method")
               if key in row.options.option_names()]
    assert clashes == []


def test_placement_algorithm_is_settable_from_a_spec():
    from tanksynth.methods import parse_spec_text

    text = ('[plant]\nmodel = "three_tank"\n[operating_point]\nx = {h1 = 0.4, h2 = 0.2, h3 = 0.3}\n'
            '[sampling]\nts = 1.0\n[[design]]\nname = "pp"\nmethod = "pole_placement"\n'
            'target = "state_feedback"\npoles = [0.6, 0.7, 0.8]\nalgorithm = "place"\n')
    assert parse_spec_text(text).designs[0].config.algorithm == "place"


def _command_rows() -> dict[str, str]:
    """The command table of docs/commands.md: command name -> its row (usage and what it does)."""
    text = COMMANDS_PAGE.read_text(encoding="utf-8")
    section = text[text.index("# Command line"):]
    rows = {}
    for line in section.splitlines():
        m = re.match(r"\| `tanksynth (\w+)[ `]", line)
        if m:
            rows[m.group(1)] = line
    return rows


def test_command_table_names_every_option_of_every_command():
    """Every option ``--help`` lists (long and short forms, ``--no-`` ones included) is in the
    docs/commands.md row of its command; every command has a row."""
    from tanksynth.cli import cli

    rows = _command_rows()
    assert set(rows) == set(cli.commands), (sorted(rows), sorted(cli.commands))
    missing = []
    for name, command in cli.commands.items():
        for param in command.params:
            if not isinstance(param, click.Option):
                continue
            said = [opt for opt in (*param.opts, *param.secondary_opts)
                    if re.search(re.escape(opt) + r"(?![\w-])", rows[name])]
            if not any(opt in said for opt in param.opts):   # -o or --output, either form
                missing.append(f"{name} {'/'.join(param.opts)}")
            missing += [f"{name} {opt}" for opt in param.secondary_opts if opt not in said]
    assert missing == [], f"docs/commands.md command table lacks {missing}"
    text = COMMANDS_PAGE.read_text(encoding="utf-8")
    for param in cli.params:  # the group's own options (tanksynth -v ...)
        assert any(f"`tanksynth {opt}" in text for opt in param.opts), param.opts


@pytest.mark.slow
def test_piped_methods_is_one_line_per_method():
    """Piped (stdout not a terminal), ``tanksynth methods`` prints a header and one plain line
    per method, whatever the width; ``methods NAME`` keeps each option on one line."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "80"}
    env.pop("FORCE_COLOR", None)
    run = subprocess.run([sys.executable, "-m", "tanksynth", "methods"], capture_output=True,
                         text=True, env=env, timeout=120, check=True)
    lines = run.stdout.splitlines()
    from tanksynth.methods import ALIASES

    assert len(lines) == 1 + len(TABLE) + len(ALIASES), run.stdout
    assert lines[0].split() == ["method", "kind", "designs"]
    for line, row in zip(lines[1:], TABLE):
        assert line.split()[0] == row.name and line.rstrip().endswith(row.summary), line
        assert " / ".join(row.kinds) in line
    for line, alias in zip(lines[1 + len(TABLE):], ALIASES.values()):   # same columns
        assert line.split()[:4] == [alias.name, "alias", "alias", "of"], line
    run = subprocess.run([sys.executable, "-m", "tanksynth", "methods", "ekf"], capture_output=True,
                         text=True, env=env, timeout=120, check=True)
    rows = [line for line in run.stdout.splitlines() if line.startswith("│")]
    meanings = {o["name"]: o["meaning"] for o in docgen.method_options("ekf")}
    assert len(rows) == len(meanings)                 # one line per option: nothing folded
    for line in rows:
        name = line.split("│")[1].strip()
        assert meanings[name] in line
