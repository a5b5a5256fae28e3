"""The Makefile's ``bytecode`` target never leaves a stale .pyc that Python would use."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

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
