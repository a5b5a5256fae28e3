"""A verdict never calls the design code it judges, and holds no paper's data.

Checked on the source (every import, including those inside functions) in addition to the
import-linter contract, which sees only the module graph.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

import tanksynth.verify

VERIFY = Path(tanksynth.verify.__file__).parent
#: Every module of the stage, the families' sub-packages included; the Monte-Carlo campaign
#: modules are not verdicts (their own contract: tests/verify/test_campaign_runs.py).
MODULES = sorted(p for p in VERIFY.rglob("*.py") if p.name != "campaign.py")
FORBIDDEN_IMPORTS = ("tanksynth.design", "tanksynth.methods", "tanksynth.papers")
FORBIDDEN_NAMES = re.compile(r"(?i:seed0|paper|printed)|SEED")


def _tree(path: Path) -> ast.AST:
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(VERIFY)))
def test_no_import_of_the_design_stage(path):
    found = []
    for node in ast.walk(_tree(path)):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        found += [n for n in names if n.startswith(FORBIDDEN_IMPORTS)]
    assert not found, f"{path.name} imports {found}"


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(VERIFY)))
def test_no_paper_identifier_or_key(path):
    bad = []
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.Name):
            bad.append(node.id)
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)):
            bad.append(node.name)
        elif isinstance(node, ast.arg):
            bad.append(node.arg)
        elif isinstance(node, ast.Attribute):
            bad.append(node.attr)
        elif isinstance(node, ast.Dict):   # dict keys written as strings
            bad += [k.value for k in node.keys if isinstance(k, ast.Constant) and isinstance(k.value, str)]
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "get" and node.args \
                and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
            bad.append(node.args[0].value)   # keys read from artefacts
        elif isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) \
                and isinstance(node.slice.value, str):
            bad.append(node.slice.value)
    bad = sorted({b for b in bad if FORBIDDEN_NAMES.search(b)})
    assert not bad, f"{path.name} uses {bad}"


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(VERIFY)))
def test_modules_stay_readable(path):
    """Modules are cut by topic, not to fit a line count (issue 26): this is not a cap to cut
    to, only a ceiling far above any one topic's verdict, so a module that reaches it has grown
    a second topic and is split by topic."""
    assert len(path.read_text(encoding="utf-8").splitlines()) <= 1000, path.name
