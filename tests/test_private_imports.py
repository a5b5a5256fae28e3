"""No module of the package uses another module's private names (issue 26).

A name with a leading underscore is a module's own business: another module that imports it
(``from tanksynth.x import _helper``), or reaches it through an imported module
(``rank._tol``), depends on what the owner may change without notice. A shared name is made
public (documented, in ``__all__`` where the module has one) or moved to a common module.

The check reads the source (``ast``): it sees every import, at module top or inside a function.
Private *modules* of the package (``tanksynth._lazy``) are package-internal and may be imported;
dunder names (``__version__``) are public by convention.
"""

from __future__ import annotations

import ast
from pathlib import Path

import tanksynth

PACKAGE = Path(tanksynth.__file__).parent


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _absolute(module: str, node: ast.ImportFrom, is_package: bool) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _is_tanksynth_module(name: str) -> bool:
    """Whether ``name`` is a module (or package) of tanksynth, not an attribute of one."""
    rel = name.split(".")[1:]
    path = PACKAGE.joinpath(*rel)
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def violations_in(path: Path, module: str | None = None) -> list[str]:
    """``"<module>:<line>: <what>"`` for every private name of another module that ``path`` uses
    (``module``: its dotted name, by default read from its place in the package)."""
    module = module or _module_name(path)
    is_package = path.name == "__init__.py"
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    found: list[str] = []
    aliases: dict[str, str] = {}  # local name -> the tanksynth module it is bound to
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            source = _absolute(module, node, is_package)
            if not source.startswith("tanksynth"):
                continue
            for alias in node.names:
                full = f"{source}.{alias.name}"
                if _is_tanksynth_module(full):
                    aliases[alias.asname or alias.name] = full
                    continue
                if _is_private(alias.name) and source != module:
                    found.append(f"{module}:{node.lineno}: imports {alias.name} from {source}")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("tanksynth") and alias.asname:
                    aliases[alias.asname] = alias.name
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in aliases and _is_private(node.attr)
                and aliases[node.value.id] != module):
            found.append(f"{module}:{node.lineno}: uses {aliases[node.value.id]}.{node.attr}")
    return found


def test_the_check_sees_a_private_import(tmp_path):
    # the checker itself: a private name imported, and one reached through a module alias
    probe = tmp_path / "probe.py"
    probe.write_text("from tanksynth.analysis.symbolic import _hidden, public\n"
                     "from tanksynth.analysis import blas as b\n"
                     "from tanksynth._lazy import lazy_exports as _lazy\n"
                     "x = b._threads\n")
    found = violations_in(probe, "tanksynth.analysis.probe")
    assert any("_hidden" in v for v in found) and any("blas._threads" in v for v in found)
    assert not any("public" in v or "_lazy" in v for v in found)
    assert len(found) == 2


def test_no_module_uses_another_modules_private_names():
    found = [v for path in sorted(PACKAGE.rglob("*.py")) for v in violations_in(path)]
    assert not found, "private names used across modules:\n" + "\n".join(found)
