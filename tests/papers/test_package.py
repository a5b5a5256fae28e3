"""tanksynth.papers holds values only: it imports nothing else from tanksynth."""

from __future__ import annotations

import ast
from pathlib import Path

import tanksynth.papers as papers

ROOT = Path(papers.__file__).parent


def test_papers_import_no_other_tanksynth_module():
    for path in sorted(ROOT.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            for name in names:
                assert not name.startswith("tanksynth") or name.startswith("tanksynth.papers"), \
                    f"{path.name}:{node.lineno} imports {name}"


def test_one_module_per_seed_paper():
    assert sorted(p.stem for p in ROOT.glob("seed*.py")) == [f"seed00{i}" for i in range(5)]
    assert papers.__all__ == [f"seed00{i}" for i in range(5)]
