"""``scripts/add_method.py``: one command scaffolds a design method into its family.

The scaffolder runs on a copy of the package and what the checks need (never on this tree):
once into an existing family and once into a new one; the copy must then pass the table,
API and docstring tests, resolve every row, list the new option in ``tanksynth methods NAME``,
keep its import layers and fail the new method's verdict (it is not written yet). Bad input
exits 2 with one line and changes no file.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tanksynth.methods import TABLE

ROOT = Path(__file__).resolve().parents[1]
#: What the scaffolded copy needs: the package, the examples, the script, the documentation
#: pages it regenerates and the tests run on the result (with their configuration).
COPIED = ("tanksynth", "examples", "scripts/add_method.py", "docs", "pyproject.toml",
          ".importlinter", "tests/test_methods.py", "tests/test_api.py", "tests/test_docstrings.py",
          "tests/docstring_exceptions.txt")
#: The two methods scaffolded: one into an existing family (a detector with the plant of that
#: family's example), one into a new family (a controller and observer on the demo plant).
EXISTING = ("residual_bank", "--family", "fault", "--kind", "detector", "--summary",
            "bank of observer residuals, one per fault", "--plant-from",
            "examples/seed004_fault_detection.toml")
NEW = ("sliding_mode", "--family", "sliding", "--kind", "controller", "--kind", "observer",
       "--summary", "sliding-mode control law and observer with a boundary layer")


def _copy(tree: Path) -> Path:
    for name in COPIED:
        source, target = ROOT / name, tree / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if source.is_dir():
            shutil.copytree(source, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "_build", "_generated"))
        else:
            shutil.copy2(source, target)
    return tree


def _env(tree: Path) -> dict[str, str]:
    """The copy first on the path; no outer pytest settings leak into the inner runs."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    env.update(PYTHONPATH=str(tree), PYTHONDONTWRITEBYTECODE="1", COLUMNS="200")
    env.pop("FORCE_COLOR", None)
    return env


def _run(tree: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *args], cwd=tree, env=_env(tree), capture_output=True,
                          text=True, timeout=timeout)


def _scaffold(tree: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return _run(tree, str(tree / "scripts" / "add_method.py"), *args)


def _files(tree: Path) -> dict[str, bytes]:
    return {str(p.relative_to(tree)): p.read_bytes() for p in sorted(tree.rglob("*"))
            if p.is_file() and "__pycache__" not in p.parts}


def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path):
    tree = _copy(tmp_path)
    before = _files(tree)
    # a module at the design stage's top (shared by the families): a family of that name would
    # have to turn it into a package
    shared = next(p.stem for p in sorted((tree / "tanksynth" / "design").glob("*.py"))
                  if p.stem != "__init__")
    cases = {
        "existing name": (TABLE[0].name, "--family", TABLE[0].family, "--kind", TABLE[0].kinds[0]),
        "bad family": ("new_method", "--family", "Bad-Family", "--kind", "estimator"),
        "bad kind": ("new_method", "--family", "fault", "--kind", "regulator"),
        "bad name": ("NewMethod", "--family", "fault", "--kind", "detector"),
        "family shadowing a shared module": ("new_method", "--family", shared, "--kind", "controller"),
        "summary on two lines": ("new_method", "--family", "fault", "--kind", "detector",
                                 "--summary", "one\ntwo"),
        "no kind": ("new_method", "--family", "fault"),
    }
    for case, args in cases.items():
        run = _scaffold(tree, *args)
        assert run.returncode == 2, (case, run.stdout, run.stderr)
        lines = run.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("add_method.py: error: "), (case, run.stderr)
        assert "Traceback" not in run.stderr and _files(tree) == before, case


def test_a_tree_that_fails_its_check_is_restored(tmp_path):
    """The new tree is checked in a fresh interpreter (here a skeleton whose verdict's name differs
    from its row's, as a bug of the script would make it): exit 1 and every file as before."""
    tree = _copy(tmp_path)
    script = tree / "scripts" / "add_method.py"
    text = script.read_text(encoding="utf-8")
    assert text.count("def <<name>>_verdict(") == 1
    script.write_text(text.replace("def <<name>>_verdict(", "def <<name>>_verdict_typo("),
                      encoding="utf-8")
    before = _files(tree)
    run = _scaffold(tree, *NEW)
    assert run.returncode == 1, (run.stdout, run.stderr)
    assert "no attribute 'sliding_mode_verdict'" in run.stderr and "every file restored" in run.stderr
    assert _files(tree) == before


@pytest.fixture(scope="module")
def scaffolded(tmp_path_factory) -> Path:
    """A copy of the package with ``residual_bank`` (family fault) and ``sliding_mode`` (new family
    sliding) scaffolded."""
    tree = _copy(tmp_path_factory.mktemp("scaffold"))
    for args in (EXISTING, NEW):
        run = _scaffold(tree, *args)
        assert run.returncode == 0, run.stderr
        assert f"method {args[0]!r} scaffolded" in run.stdout
    return tree


@pytest.mark.slow
def test_scaffolded_tree_passes_the_table_api_and_docstring_tests(scaffolded):
    tests = ["tests/test_methods.py", "tests/test_api.py", "tests/test_docstrings.py",
             f"tests/design/test_{EXISTING[0]}.py", f"tests/design/test_{NEW[0]}.py"]
    run = _run(scaffolded, "-m", "pytest", "-q", "-p", "no:cacheprovider", *tests)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    # each generated test designs its example; its verdict and re-derived property are strict
    # xfails until written
    assert " 4 xfailed" in run.stdout, run.stdout[-1000:]


@pytest.mark.slow
def test_every_part_lives_in_its_family_home_and_the_verdict_fails(scaffolded):
    code = """
import json, sys, tempfile
import tanksynth, tanksynth.methods as m
from tanksynth.artefacts import read_artefact, write_artefact
m.resolve_table()
out = {"file": tanksynth.__file__, "families": list(m.FAMILIES), "rows": {}}
for name in sys.argv[1:]:
    row = m.METHODS[name]
    spec = m.load_spec(f"examples/{name}.toml")
    with tempfile.TemporaryDirectory() as d:
        doc = read_artefact(write_artefact(row.design(spec, spec.designs[0]), d, spec.sha256))
    checks = [c.as_dict() for c in row.verdict(doc, spec)]
    homes = {part: ref.partition(":")[0] == m.home(part, row.family)
             for part, ref in row.refs().items()}
    out["rows"][name] = {"family": row.family, "kinds": list(row.kinds), "homes": homes,
                         "checks": checks, "statement": str(row.statement(doc["diagnostics"]))}
print(json.dumps(out))
"""
    run = _run(scaffolded, "-c", code, EXISTING[0], NEW[0])
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert Path(out["file"]).is_relative_to(scaffolded)
    assert "sliding" in out["families"]
    assert out["rows"][EXISTING[0]]["family"] == "fault"
    assert out["rows"][NEW[0]]["kinds"] == ["controller", "observer"]
    for name, row in out["rows"].items():
        assert all(row["homes"].values()), (name, row["homes"])
        assert [c["passed"] for c in row["checks"]] == [False], name
        assert "verdict not written yet" in row["checks"][0]["detail"]
        assert name.replace("_", r"\_") in row["statement"]


@pytest.mark.slow
def test_methods_command_lists_the_new_option(scaffolded):
    for name in (EXISTING[0], NEW[0]):
        run = _run(scaffolded, "-m", "tanksynth", "methods", name, "--json")
        assert run.returncode == 0, run.stderr
        assert [o["name"] for o in json.loads(run.stdout)["options"]] == ["example_option"]
        run = _run(scaffolded, "-m", "tanksynth", "methods", name)
        assert run.returncode == 0 and "example_option" in run.stdout


@pytest.mark.slow
def test_doc_pages_are_regenerated_and_layers_hold(scaffolded):
    assert _run(scaffolded, "-m", "tanksynth.docgen", "--check").returncode == 0
    page = (scaffolded / "docs" / "design_methods.md").read_text(encoding="utf-8")
    assert f"### `{EXISTING[0]}`" in page and f"### `{NEW[0]}`" in page
    lint = Path(sys.executable).with_name("lint-imports")
    if not lint.is_file():
        pytest.skip("import-linter is not installed beside this interpreter")
    run = subprocess.run([str(lint), "--no-logo"], cwd=scaffolded, env=_env(scaffolded),
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout[-3000:]


@pytest.mark.slow
def test_a_method_is_scaffolded_once(scaffolded):
    before = _files(scaffolded)
    run = _scaffold(scaffolded, *EXISTING)
    assert run.returncode == 2 and "already in the table" in run.stderr
    assert _files(scaffolded) == before
