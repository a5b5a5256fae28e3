"""The layers hold: import-linter contracts, and no seed-paper names in general code.

(a) ``lint-imports`` (import-linter, a dev dependency) checks the contracts of
``.importlinter`` on this tree: data flows one way through the layers, verify never
imports design, and only reports (and tests, notebooks, benchmarks) import
`tanksynth.papers`.

(b) General code does not name a seed paper: in ``tanksynth/{analysis, sim, runtime,
design, verify}`` no identifier (variable, attribute, function, class, argument,
keyword argument, imported name or module) and no string used as a dict key matches
``seed_?0NN``, ``paper`` or ``printed`` (any case). Docstrings, comments and other
strings may cite "seed 002 eq. 13"; an RNG seed called ``seed`` is fine. Values
printed in a paper live in `tanksynth.papers`, and the comparison with them in
`tanksynth.reports`.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GENERAL = ("analysis", "measurements", "sim", "runtime", "design", "verify")
FORBIDDEN = re.compile(r"(?i)seed_?0\d\d|paper|printed")
#: Methods whose first (string) argument is a dict key.
_KEY_METHODS = {"get", "setdefault", "pop"}


def _lint_imports_command() -> list[str]:
    exe = Path(sys.executable).with_name("lint-imports")
    if exe.exists():
        return [str(exe)]
    try:
        import importlinter  # noqa: F401
    except ImportError:
        pytest.fail("import-linter is not installed (a dev dependency: pip install -e '.[dev]')")
    return [sys.executable, "-c", "import sys; from importlinter.cli import lint_imports_command; "
            "sys.exit(lint_imports_command())"]


def test_import_contracts_are_kept():
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    proc = subprocess.run([*_lint_imports_command(), "--no-cache", "--no-logo"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, "import-linter contracts broken:\n" + out
    assert "BROKEN" not in out and "KEPT" in out, out


def _names(node: ast.AST) -> list[tuple[int, str, str]]:
    """(line, kind, text) of every identifier and dict-key string one node introduces."""
    line = getattr(node, "lineno", 0)
    if isinstance(node, ast.Name):
        return [(line, "name", node.id)]
    if isinstance(node, ast.Attribute):
        return [(line, "attribute", node.attr)]
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
        return [(line, "function", node.name)]
    if isinstance(node, ast.ClassDef):
        return [(line, "class", node.name)]
    if isinstance(node, ast.arg):
        return [(line, "argument", node.arg)]
    if isinstance(node, ast.keyword) and node.arg:
        return [(line, "keyword argument", node.arg)]
    if isinstance(node, ast.alias):
        return [(line, "imported name", n) for n in (node.name, node.asname) if n]
    if isinstance(node, ast.ImportFrom) and node.module:
        return [(line, "imported module", node.module)]
    if isinstance(node, (ast.Global, ast.Nonlocal)):
        return [(line, "name", n) for n in node.names]
    if isinstance(node, ast.ExceptHandler) and node.name:
        return [(line, "name", node.name)]
    out = []
    if isinstance(node, ast.Dict):
        out += [(k.lineno, "dict key", k.value) for k in node.keys
                if isinstance(k, ast.Constant) and isinstance(k.value, str)]
    if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) \
            and isinstance(node.slice.value, str):
        out.append((line, "dict key", node.slice.value))
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
            and node.func.attr in _KEY_METHODS and node.args \
            and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
        out.append((line, "dict key", node.args[0].value))
    return out


def offenders(root: Path = ROOT) -> list[str]:
    """``file:line: kind 'text'`` for every forbidden name under the general packages."""
    found = []
    for pkg in GENERAL:
        for path in sorted((root / "tanksynth" / pkg).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            if FORBIDDEN.search(path.stem):
                found.append(f"{rel}:1: module '{path.stem}'")
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=rel)
            hits = set()
            for node in ast.walk(tree):
                for line, kind, text in _names(node):
                    if FORBIDDEN.search(text):
                        hits.add((line, kind, text))
            found += [f"{rel}:{line}: {kind} '{text}'" for line, kind, text in sorted(hits)]
    return found


@pytest.mark.slow
def test_no_seed_paper_names_in_general_code():
    found = offenders()
    assert not found, (f"{len(found)} seed-paper name(s) in general code (move the values to "
                       "tanksynth.papers, the comparison to tanksynth.reports):\n" + "\n".join(found))


def test_the_name_check_catches_what_it_should(tmp_path):
    """The check itself: identifiers and dict keys are caught, docstrings and comments are not."""
    pkg = tmp_path / "tanksynth" / "design"
    pkg.mkdir(parents=True)
    (pkg / "ok.py").write_text(
        '"""Seed 002 eq. 13, as printed in the paper."""\n'
        "# seed 004 section IV\n"
        "def run(seed=0):\n"
        '    """Printed in seed 001."""\n'
        '    return {"rate": seed, "note": "the paper prints 0.5"}, run_seeds(seed)\n',
        encoding="utf-8")
    (pkg / "bad.py").write_text(
        "from tanksynth.papers import seed004\n"
        "SEED004_TIMES = (2.0,)\n"
        "def f(paper=None, **kw):\n"
        '    d = {"paper_threshold": 1}\n'
        '    d["printed"] = kw.get("Printed_K")\n'
        "    return g(seed_003=1).paper, Seed002Row\n",
        encoding="utf-8")
    found = offenders(tmp_path)
    assert all(f.startswith("tanksynth/design/bad.py:") for f in found), found
    lines = {int(f.split(":")[1]) for f in found}
    assert lines == {1, 2, 3, 4, 5, 6}, found
    kinds = {f.split(": ", 1)[1].split(" '")[0] for f in found}
    assert {"imported module", "name", "argument", "dict key", "keyword argument",
            "attribute"} <= kinds, found


def test_test_modules_have_distinct_names():
    """pytest imports test files of directories without ``__init__.py`` by their base name: two
    ``test_x.py`` in such directories make the whole run fail at collection (CI saw it)."""
    from collections import defaultdict
    from pathlib import Path

    tests = Path(__file__).resolve().parent
    seen = defaultdict(list)
    for path in tests.rglob("test_*.py"):
        if not (path.parent / "__init__.py").is_file():
            seen[path.name].append(str(path.relative_to(tests)))
    assert {name: paths for name, paths in seen.items() if len(paths) > 1} == {}
