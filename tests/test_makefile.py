"""The Makefile's targets: ``bytecode`` never leaves a stale .pyc that Python would use; ``test``
runs the type checker on the package; ``test-fast`` runs the suite without the tests marked slow."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _bytecode_command() -> list[str]:
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    recipe = re.search(r"^bytecode:.*\n\t@?(.+)$", text, re.MULTILINE)
    assert recipe is not None, "no bytecode target in the Makefile"
    words = shlex.split(recipe.group(1))
    assert words[0] == "$(PY)"
    return [sys.executable] + words[1:]


def test_bytecode_edit_in_the_same_second_with_the_same_size_is_seen(tmp_path: Path) -> None:
    pkg = tmp_path / "tanksynth"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    module = pkg / "constant.py"
    module.write_text("VALUE = 10\n")
    stamp = (1_700_000_000, 1_700_000_000)
    os.utime(module, stamp)
    subprocess.run(_bytecode_command(), cwd=tmp_path, check=True)
    assert list((pkg / "__pycache__").glob("constant.*.pyc"))
    module.write_text("VALUE = 12\n")   # same size, same whole-second mtime: a timestamp .pyc matches
    os.utime(module, stamp)
    env = dict(os.environ, PYTHONPATH=str(tmp_path), PYTHONDONTWRITEBYTECODE="1")
    out = subprocess.run([sys.executable, "-c", "import tanksynth.constant as c; print(c.VALUE)"],
                         cwd=tmp_path, env=env, check=True, capture_output=True, text=True)
    assert out.stdout.strip() == "12"


def _recipe(target: str) -> list[str]:
    """The command lines of a Makefile target (without make's ``@``/``-`` prefixes)."""
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    block = re.search(rf"^{re.escape(target)}:.*\n((?:\t.*\n?)*)", text, re.MULTILINE)
    assert block is not None, f"no {target} target in the Makefile"
    return [line.strip().lstrip("@-") for line in block.group(1).splitlines()]


def test_the_test_target_type_checks_the_package_after_the_import_contracts() -> None:
    lines = _recipe("test")
    mypy = [i for i, line in enumerate(lines) if shlex.split(line)[0] == "$(VENV)/bin/mypy"]
    lint = [i for i, line in enumerate(lines) if shlex.split(line)[0] == "$(VENV)/bin/lint-imports"]
    tests = [i for i, line in enumerate(lines) if "pytest" in line]
    assert mypy and lint and tests, lines
    assert lint[0] < mypy[0] < tests[0], lines
    args = [a for a in shlex.split(lines[mypy[0]])[1:] if not a.startswith("-")]
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    config = pyproject["tool"]["mypy"]
    # with no paths on the command line, mypy checks what [tool.mypy] names: the whole package
    checked = args or [*config.get("packages", []), *config.get("files", [])]
    assert "tanksynth" in checked, checked
    assert config.get("ignore_missing_imports") is not True, "untyped libraries are listed one by one"
    # the mypy that runs is the one `pip install -e '.[dev]'` installs
    dev = pyproject["project"]["optional-dependencies"]["dev"]
    assert any(re.match(r"mypy\b", req) for req in dev), dev


def test_test_fast_selects_the_tests_not_marked_slow() -> None:
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    target = re.search(r"^test-fast:(.*)\n((?:\t.*\n?)+)", text, re.MULTILINE)
    assert target is not None, "no test-fast target in the Makefile"
    assert {"$(STAMP)", "bytecode"} <= set(target.group(1).split())   # as `test`
    assert "test-fast" in re.search(r"^\.PHONY:(.*)$", text, re.MULTILINE).group(1).split()
    runs = [shlex.split(line.strip().lstrip("@")) for line in target.group(2).splitlines()]
    runs = [w for w in runs if w[:3] == ["$(PY)", "-m", "pytest"]]
    assert len(runs) == 1, target.group(0)
    words = runs[0]
    assert words[words.index("-m", 3) + 1] == "not slow"
    test_recipe = re.search(r"^test:.*\n((?:\t.*\n?)+)", text, re.MULTILINE).group(1)
    assert "slow" not in test_recipe                                    # `make test` runs everything


@pytest.mark.slow
def test_test_fast_arguments_make_pytest_leave_out_a_slow_test(tmp_path: Path) -> None:
    """The selection as pytest makes it with the target's arguments: a module with a slow test
    and another."""
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    recipe = re.search(r"^test-fast:.*\n\t@?(.+)$", text, re.MULTILINE).group(1)
    words = shlex.split(recipe)
    assert words[:3] == ["$(PY)", "-m", "pytest"]
    (tmp_path / "test_marks.py").write_text(
        "import pytest\n\n\n@pytest.mark.slow\ndef test_long():\n    pass\n\n\ndef test_short():\n    pass\n")
    args = [w for w in words[1:] if w not in ("-n", "2")]
    out = subprocess.run([sys.executable, *args, "--collect-only", "-p", "no:cacheprovider",
                          "-o", "markers=slow: long", "--rootdir", str(tmp_path), str(tmp_path)],
                         cwd=tmp_path, capture_output=True, text=True)
    assert "test_marks.py::test_short" in out.stdout and "test_long" not in out.stdout, out.stdout


def _prerequisites(text: str, target: str) -> list[str]:
    """The prerequisites of a Makefile rule (variables as written, e.g. ``$(STAMP)``)."""
    rule = re.search(rf"^{re.escape(target)}:([^\n]*)$", text, re.MULTILINE)
    assert rule is not None, f"no rule for {target}"
    return rule.group(1).split()


def test_demo_installs_only_the_runtime_dependencies() -> None:
    """Issue 30 item 13: `make demo` on a fresh clone installed `.[dev]` (pytest, mypy, Sphinx,
    dask, ...: 3 min). Everything `demo` builds, transitively, installs tanksynth without extras."""
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    seen, todo, installs = set(), ["demo"], []
    while todo:
        target = todo.pop()
        if target in seen:
            continue
        seen.add(target)
        installs += [line for line in _recipe(target) if "pip install" in line]
        todo += [p for p in _prerequisites(text, target)      # those with a rule of their own
                 if re.search(rf"^{re.escape(p)}:", text, re.MULTILINE)]
    assert installs, "demo installs nothing: a fresh clone has no venv"
    for line in installs:
        assert not re.search(r"\.\[", line), f"demo installs extras: {line}"
    # the development install builds on the runtime one (one venv, two stamps)
    dev_prereqs = _prerequisites(text, "$(STAMP)")
    assert "$(RUNTIME_STAMP)" in dev_prereqs, dev_prereqs


def test_readme_states_the_demo_times_with_and_without_the_install() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    para = re.search(r"`make demo` is the shortest complete story.*?\n\n", readme, re.S)
    assert para is not None
    assert re.search(r"fresh clone", para.group(0)) and len(re.findall(r"\d+ (?:s|min)\b", para.group(0))) >= 2, \
        para.group(0)
