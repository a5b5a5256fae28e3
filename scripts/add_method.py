#!/usr/bin/env python3
"""Add a design method to tanksynth: its skeleton in every stage of its family and its table row.

Usage (from the repository root; ``make method NAME=... FAMILY=... KIND=... [SUMMARY="..."]``
runs the same)::

    python scripts/add_method.py NAME --family FAMILY --kind KIND [--kind KIND ...]
                                 [--summary TEXT] [--plant-from SPEC] [--dry-run] [--root DIR]

Every module written to is found with `tanksynth.methods.home` (``home(part, FAMILY)``),
never spelled here, so the skeleton follows the package's layout wherever a part lives:

options
    ``<Name>Options``, a frozen `MethodOptions` dataclass with one documented example option
    (``example_option``) read by ``from_table``, in ``home("options", FAMILY)``.
adapter
    ``run_<name>(spec, design) -> DesignResult`` and ``<NAME> = DesignMethod(...)`` in
    ``home("adapter", FAMILY)``. The skeleton designs nothing yet: its one gain is the
    operating point ``x_op``.
verdict
    ``<name>_verdict(doc, spec) -> list[Check]`` in ``home("verdict", FAMILY)``. It FAILS, with
    the check ``verdict_not_written`` ("verdict not written yet"), so that a scaffolded method
    never passes verification silently.
campaign
    ``<name>_run(doc, spec)`` in ``home("campaign", FAMILY)``, annotated with what its kinds run
    (read from the table's other runners: a controller's closed loop, an estimator run...); it
    refuses (`ArtefactError`) until written: nothing runs in its place.
statement
    ``<name>_statement(diag) -> Tex`` in ``home("statement", FAMILY)`` (report).
table row
    A row of `tanksynth.methods.TABLE` after the family's last row (name, family, kinds,
    summary, each part by its attribute name in its family's module).
example
    ``examples/<name>.toml``: the plant, operating point and sampling of ``--plant-from``
    (default the built-in demo spec) and one ``[[design]]`` of the method.
test
    ``tests/design/test_<name>.py``: designs the example; the verdict passing and the property
    re-derived independently are strict xfails, which fail once the TODO is done (remove the
    marker then).
docs
    The generated sections of the documentation pages (``python -m tanksynth.docgen``:
    ``docs/design_methods.md`` and the other pages of `tanksynth.docgen.DOC_PAGES`); the
    Sphinx pages are generated from the table when the docs are built.

Each module gets its new names in ``__all__`` and the imports they need at its top (a module
that does not exist yet is created with a docstring and ``__all__``). A family that is not in
`tanksynth.methods.FAMILIES` gets its package in every stage and is added to ``FAMILIES``.

Everything is checked before anything is written; the files are then written one by one
atomically (temporary file, rename), the new tree is checked in a fresh interpreter (every
part of the table resolves, the example loads) and the generated pages are rewritten; if that fails,
every file is restored.

Parameters
----------
NAME : str
    The method's spec name (``method = "NAME"``): a lowercase identifier (``[a-z][a-z0-9_]*``,
    at most 48 characters) not yet in the table.
--family FAMILY : str
    The method family (`tanksynth.methods.FAMILIES`, or a new lowercase identifier).
--kind KIND : str
    What the method produces, one of `tanksynth.methods.KINDS`; repeat it (or separate kinds by
    commas) for a method of several kinds: ``--kind controller --kind observer``.
--summary TEXT : str, optional
    One line of plain text (no quotes or backslashes): what the method designs. Default a TODO
    line naming the method.
--plant-from SPEC : path, optional
    A spec whose ``[plant]``, ``[operating_point]`` and ``[sampling]`` the example copies;
    default the built-in demo spec (``tanksynth run`` without a spec).
--dry-run
    Check the input and list what would be written; write nothing.
--root DIR : path, optional
    The repository to scaffold into (its ``tanksynth`` package is the one imported); default
    the repository holding this script.

Returns
-------
int
    The exit code: 0 written; 2 bad input (one line on stderr, nothing written); 1 the written
    tree failed its check (every file restored).

Examples
--------
A detector beside ``fault_detection``, and a controller in a new family::

    python scripts/add_method.py residual_bank --family fault --kind detector \\
        --summary "bank of observer residuals, one per fault" --plant-from examples/seed004_fault_detection.toml
    python scripts/add_method.py sliding_mode --family sliding --kind controller
"""

from __future__ import annotations

import argparse
import ast
import importlib
import json
import keyword
import os
import re
import subprocess
import sys
import textwrap
import tomllib
import typing
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, Callable, NoReturn, Sequence

__all__ = ["Request", "BadInput", "Need", "plan", "main"]

#: The repository this script belongs to (the default ``--root``).
REPOSITORY = Path(__file__).resolve().parents[1]
#: A method or family name.
IDENTIFIER = re.compile(r"[a-z][a-z0-9_]*\Z")
#: Longest method name: the example's design name (``<name>_example``) stays within the spec's
#: 64 characters.
MAX_NAME = 48
#: The parts of a row, in the order the skeleton writes them.
PARTS = ("options", "adapter", "verdict", "campaign", "statement")
#: The skeleton's one option (documented, validated, recorded by the design).
EXAMPLE_OPTION = "example_option"
#: Longest line the edits produce where they can choose (``__all__`` entries, imports).
LINE = 100

#: Shared names the skeletons use and the common modules that hold them (issue 26 keeps these at
#: the stages' tops); checked to exist before anything is written.
SHARED = {
    "MethodOptions": "tanksynth.spec.method_options.base",
    "OptionReader": "tanksynth.spec.method_options.base",
    "option": "tanksynth.spec.method_options.base",
    "parse_number": "tanksynth.spec.options",
    "Spec": "tanksynth.spec",
    "DesignSpec": "tanksynth.spec",
    "DesignMethod": "tanksynth.design.result",
    "DesignResult": "tanksynth.design.result",
    "options_of": "tanksynth.design.result",
    "Check": "tanksynth.analysis.checks",
    "ArtefactError": "tanksynth.errors",
    "Tex": "tanksynth.reports.latex",
}

#: What each created module says it holds (its docstring's first line).
MODULE_DOCS = {
    "options": "Options of ``<<name>>``: <<summary>>.",
    "adapter": "Design adapters of the ``<<family>>`` family: ``<<name>>``.",
    "verdict": "Verdicts of the ``<<family>>`` family: ``<<name>>``.",
    "campaign": "What Monte-Carlo campaigns run for the ``<<family>>`` family: ``<<name>>``.",
    "statement": "Report statements of the ``<<family>>`` family: ``<<name>>``.",
}


class BadInput(Exception):
    """Input refused before anything is written (one line, exit 2)."""


class CheckFailed(Exception):
    """The written tree failed its check (every file is restored, exit 1)."""


@dataclass(frozen=True)
class Request:
    """What to scaffold.

    Attributes
    ----------
    name : str
        The method's spec name.
    family : str
        Its family.
    kinds : tuple of str
        Some of `tanksynth.methods.KINDS`, in that order.
    summary : str
        One line: what it designs.
    root : Path
        The repository.
    plant_from : Path or None
        The spec the example copies its plant from (None: the built-in demo).
    """

    name: str
    family: str
    kinds: tuple[str, ...]
    summary: str
    root: Path
    plant_from: Path | None = None

    @property
    def options_class(self) -> str:
        """``kalman_bank`` -> ``KalmanBankOptions``."""
        return "".join(w[:1].upper() + w[1:] for w in self.name.split("_")) + "Options"

    @property
    def constant(self) -> str:
        """The design adapter's constant (``KALMAN_BANK``)."""
        return self.name.upper()

    def attributes(self) -> dict[str, str]:
        """Each part's attribute name in its family's module."""
        return {"options": self.options_class, "adapter": self.constant,
                "verdict": f"{self.name}_verdict", "campaign": f"{self.name}_run",
                "statement": f"{self.name}_statement"}


@dataclass(frozen=True)
class Need:
    """An import the generated code needs: ``from module import name`` (``import module as alias``
    when ``name`` is None).

    Attributes
    ----------
    module : str
        Absolute module name.
    name : str or None
        The imported attribute.
    alias : str
        The local name (``np`` for numpy).
    """

    module: str
    name: str | None = None
    alias: str = ""

    @property
    def local(self) -> str:
        """The name the import binds."""
        return self.alias or self.name or self.module.split(".")[0]


# ------------------------------------------------------------------------------- the skeletons

OPTIONS_CODE = '''
@dataclass(frozen=True, eq=False)
class <<Options>>(MethodOptions):
    """<<options_doc>>

    TODO(<<name>>): replace the example option with the method's own, each documented here
    with its unit and default, declared with `option` and read in `from_table`.

    Attributes
    ----------
    <<option>> : float
        Example option, to be replaced by the method's own (dimensionless, > 0); default 1.
    """

    method_name: ClassVar[str] = "<<name>>"

    <<option>>: float = option(1.0, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Any,
                   ts: float | None) -> "<<Options>>":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(<<option>>=r.read("<<option>>", parse_number, above=0.0))
'''

ADAPTER_CODE = '''
def run_<<name>>(spec: Spec, design: DesignSpec) -> DesignResult:
    """Design ``<<name>>``: a skeleton that designs nothing yet.

    TODO(<<name>>): compute the method's gains from the validated options; record in the
    diagnostics what the verdict re-derives and the report states.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).

    Returns
    -------
    DesignResult
        Until the design is written, one gain: ``x_op``, the operating point (state units).
    """
    options = options_of(design, spec, <<Options>>)
    plant = spec.plant
    gains = {"x_op": np.array(spec.x0, dtype=float)}
    diagnostics = {"scaffold": "design not written yet (skeleton of scripts/add_method.py)",
                   "<<option>>": options.<<option>>}
    return DesignResult(design.name, "<<name>>", plant.name, gains, diagnostics)


<<NAME>> = DesignMethod("<<name>>", run_<<name>>, <<Options>>)
'''

VERDICT_CODE = '''
def <<name>>_verdict(doc: Mapping[str, Any], spec: Any) -> list[Check]:
    """Verdict of ``<<name>>``: not written yet, so it fails (a scaffolded method never passes
    verification silently).

    TODO(<<name>>): re-derive what the design claims from the artefact (``doc["gains"]``,
    ``doc["diagnostics"]``) with this stage's own numerics and simulate it on the nonlinear
    plant; never import the design code.

    Parameters
    ----------
    doc : mapping
        The artefact (gains as arrays).
    spec : Spec
        The validated spec.

    Returns
    -------
    list of Check
        One failing check, ``verdict_not_written``.
    """
    return [Check("verdict_not_written", False,
                  f"verdict not written yet: the artefact '{doc['name']}' of method "
                  "'<<name>>' is not verified: "
                  "write <<name>>_verdict in <<module>>")]
'''

CAMPAIGN_CODE = '''
def <<name>>_run(doc: Mapping[str, Any], spec: Any) -> <<returns>>:
    """What a Monte-Carlo campaign runs for a ``<<name>>`` artefact: not written yet, refused.

    TODO(<<name>>): build from the artefact what it ships and the campaign runs on each
    scenario (the kinds of run are listed in `tanksynth.verify.campaign`).

    Parameters
    ----------
    doc : mapping
        The artefact (gains as arrays).
    spec : Spec
        The validated spec.

    Returns
    -------
    <<returns>>
        Once written, what the campaign runs.

    Raises
    ------
    ArtefactError
        Always, until the runner is written: nothing runs in its place.
    """
    raise ArtefactError(f"artefact '{doc['name']}': the campaign runner of method "
                        "'<<name>>' is not written yet: "
                        "<<name>>_run in <<module>>")
'''

STATEMENT_CODE = '''
def <<name>>_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``<<name>>`` solves, in mathematics, from the artefact's diagnostics.

    TODO(<<name>>): state the problem solved from ``diag`` (tolerate missing or edited entries).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Tex(r"Problem statement of \\texttt{<<latex_name>>} not written yet.")
'''

TEST_CODE = '''\
"""<<test_doc>>

Scaffolded by ``scripts/add_method.py``. The two strict xfails fail loudly once their TODO is
done (an XPASS is an error): remove their markers then.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tanksynth.artefacts import read_artefact, write_artefact
from tanksynth.methods import METHODS, load_spec

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "<<name>>.toml"


def _designed():
    spec = load_spec(EXAMPLE)
    (entry,) = [d for d in spec.designs if d.method == "<<name>>"]
    return spec, METHODS["<<name>>"].design(spec, entry)


def test_<<name>>_designs_its_example():
    spec, result = _designed()
    assert result.method == "<<name>>" and result.name == "<<name>>_example"
    assert result.gains, "the design produced no gain"


@pytest.mark.xfail(strict=True, reason="TODO(<<name>>): <<name>>_verdict is not written yet")
def test_<<name>>_verdict_passes_on_its_design(tmp_path):
    spec, result = _designed()
    doc = read_artefact(write_artefact(result, tmp_path, spec.sha256))
    checks = METHODS["<<name>>"].verdict(doc, spec)
    failed = [c.name for c in checks if c.passed is not True]
    assert checks and failed == [], failed


@pytest.mark.xfail(strict=True, raises=NotImplementedError,
                   reason="TODO(<<name>>): re-derive the property the design guarantees")
def test_<<name>>_property_rederived_independently():
    """What ``<<name>>`` guarantees, recomputed from its gains with this test's own numerics
    (a reference independent of the design code: a paper's formula, another library)."""
    spec, result = _designed()
    raise NotImplementedError("TODO(<<name>>): re-derive the design's property here")
'''


def _wrap(text: str, indent: str = "", first: int = 3) -> str:
    """``text`` wrapped at `LINE` (a docstring's first lines: ``first`` characters of quotes or
    comment lead the first line, ``indent`` the next)."""
    return textwrap.fill(text, LINE - 4, initial_indent=" " * (len(indent) + first),
                         subsequent_indent=indent)[len(indent) + first:]


def _fill(template: str, values: dict[str, str]) -> str:
    for key, value in values.items():
        template = template.replace(f"<<{key}>>", value)
    return template


# ----------------------------------------------------------------------------- input and target

class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def _parser() -> argparse.ArgumentParser:
    doc = __doc__ or ""
    head, _, rest = doc.partition("\nParameters\n")
    epilog = "Exit codes: 0 written; 2 bad input (nothing written); 1 the new tree failed its " \
             "check (every file restored).\n\n" + rest.partition("\nExamples\n--------\n")[2]
    parser = _Parser(prog="add_method.py", description=head,
                     formatter_class=argparse.RawDescriptionHelpFormatter, epilog=epilog)
    parser.add_argument("name", metavar="NAME", help="the method's spec name: a new lowercase identifier")
    parser.add_argument("--family", required=True,
                        help="its family (tanksynth.methods.FAMILIES, or a new lowercase identifier)")
    parser.add_argument("--kind", action="append", required=True, metavar="KIND",
                        help="one of tanksynth.methods.KINDS; repeat or comma-separate for several")
    parser.add_argument("--summary", default=None,
                        help="one line of plain text: what the method designs (default a TODO line)")
    parser.add_argument("--plant-from", type=Path, default=None, metavar="SPEC",
                        help="spec whose [plant], [operating_point], [sampling] the example copies "
                             "(default the built-in demo)")
    parser.add_argument("--dry-run", action="store_true", help="check and list; write nothing")
    parser.add_argument("--root", type=Path, default=REPOSITORY, metavar="DIR",
                        help="repository to scaffold into (default this script's)")
    return parser


def _target(root: Path) -> ModuleType:
    """``tanksynth.methods`` of the repository ``root`` (imported from there, not from elsewhere)."""
    if not (root / "tanksynth" / "methods.py").is_file():
        raise BadInput(f"{root} is not a tanksynth repository (no tanksynth/methods.py)")
    sys.path.insert(0, str(root))
    import tanksynth.methods as methods   # here: from ``root``, whatever else is installed

    where = Path(methods.__file__).resolve()
    if where != (root / "tanksynth" / "methods.py").resolve():
        raise BadInput(f"tanksynth was already imported from {where.parent}, not from {root}")
    return methods


def _request(args: argparse.Namespace, methods: ModuleType) -> Request:
    """The checked request (`BadInput` naming what is wrong)."""
    name, family = args.name, args.family
    for what, value in (("method name", name), ("family", family)):
        if not IDENTIFIER.match(value):
            raise BadInput(f"{what} {value!r} is not a lowercase identifier ([a-z][a-z0-9_]*)")
        if keyword.iskeyword(value):
            raise BadInput(f"{what} {value!r} is a Python keyword")
    if len(name) > MAX_NAME:
        raise BadInput(f"method name {name!r} is longer than {MAX_NAME} characters")
    if name in methods.METHODS:
        raise BadInput(f"method {name!r} is already in the table (family "
                       f"{methods.METHODS[name].family!r})")
    given = [k.strip() for text in args.kind for k in text.split(",")]
    bad = [k for k in given if k not in methods.KINDS]
    if bad or not given:
        raise BadInput(f"kind {bad[0] if bad else ''!r} is not one of {', '.join(methods.KINDS)}")
    if len(set(given)) != len(given):
        raise BadInput(f"a kind is given twice: {', '.join(given)}")
    kinds = tuple(k for k in methods.KINDS if k in given)
    summary = args.summary if args.summary is not None else f"{name} (TODO: one line saying what it designs)"
    if not summary.strip() or not summary.isprintable() or any(c in summary for c in '"\\`'):
        raise BadInput("summary must be one line of plain text, without quotes or backslashes")
    plant_from = args.plant_from.resolve() if args.plant_from is not None else None
    if plant_from is not None and not plant_from.is_file():
        raise BadInput(f"--plant-from {args.plant_from}: no such file")
    return Request(name, family, kinds, " ".join(summary.split()), args.root.resolve(), plant_from)


def _shared_names() -> dict[str, Need]:
    """The shared names as imports, each checked to exist where `SHARED` says."""
    out = {}
    for attr, module in SHARED.items():
        try:
            found = hasattr(importlib.import_module(module), attr)
        except ImportError:
            found = False
        if not found:
            raise BadInput(f"{module} has no {attr}: update SHARED in scripts/add_method.py")
        out[attr] = Need(module, attr)
    return out


def _run_types(methods: ModuleType, kinds: Sequence[str]) -> list[type]:
    """What a campaign runs for each kind: the class the table's runners of that kind alone return
    most often (``controller`` -> the closed loop)."""
    out: list[type] = []
    for kind in kinds:
        seen: Counter[type] = Counter()
        for row in methods.TABLE:
            if row.kinds != (kind,):
                continue
            try:
                returns = typing.get_type_hints(row.campaign).get("return")
            except Exception:  # noqa: BLE001 - a runner we cannot read tells nothing
                continue
            if isinstance(returns, type):
                seen[returns] += 1
        if seen:
            found = seen.most_common(1)[0][0]
            if found not in out:
                out.append(found)
    return out


# ---------------------------------------------------------------------------- reading a module

def _module_file(root: Path, module: str) -> tuple[Path, bool]:
    """The file of a dotted module under ``root`` and whether it exists (a new module is a
    ``.py`` file); `BadInput` where a package would have to replace a module."""
    parts = module.split(".")
    for i in range(1, len(parts)):
        package = root.joinpath(*parts[:i])
        if package.with_suffix(".py").is_file() and not package.is_dir():
            raise BadInput(f"{'.'.join(parts[:i])} is a module, not a package: no "
                           f"{module} can live under it (pick another family name)")
    path = root.joinpath(*parts)
    if (path / "__init__.py").is_file():
        return path / "__init__.py", True
    return path.with_suffix(".py"), path.with_suffix(".py").is_file()


def _bindings(tree: ast.Module) -> dict[str, str | None]:
    """Top-level names of a module -> ``"module:name"`` (imported), ``"module"`` (``import m``)
    or None (defined there)."""
    out: dict[str, str | None] = {}
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and not node.level:
            for alias in node.names:
                out[alias.asname or alias.name] = f"{node.module}:{alias.name}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                out[alias.asname or alias.name.split(".")[0]] = alias.name
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out[node.name] = None
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                for leaf in ast.walk(target):
                    if isinstance(leaf, ast.Name):
                        out.setdefault(leaf.id, None)
    return out


def _assigned(tree: ast.Module, name: str) -> list[ast.expr]:
    """The values assigned to a top-level ``name`` (``=``, annotated, ``+=``), in order."""
    out = []
    for node in tree.body:
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, (ast.AnnAssign, ast.AugAssign)) and node.value is not None:
            targets, value = [node.target], node.value
        else:
            continue
        if any(isinstance(t, ast.Name) and t.id == name for t in targets):
            out.append(value)
    return out


def _imported(node: ast.Import | ast.ImportFrom) -> str:
    """The module an import statement reads."""
    if isinstance(node, ast.ImportFrom):
        return node.module or ""
    return node.names[0].name


def _same(binding: str | None, want: str) -> bool:
    """A module's binding (`_bindings`) is the object ``want`` names (``"module:name"``), directly
    or through a re-export."""
    if binding == want:
        return True
    if binding is None or ":" not in binding or ":" not in want:
        return False
    try:
        found = [getattr(importlib.import_module(m), n) for m, n in
                 (binding.split(":"), want.split(":"))]
    except (ImportError, AttributeError):
        return False
    return found[0] is found[1]


def _offset(text: str, line: int, col: int) -> int:
    """Character offset of an ast position (``col`` counts UTF-8 bytes)."""
    lines = text.splitlines(keepends=True)
    return sum(len(s) for s in lines[:line - 1]) + len(lines[line - 1].encode()[:col].decode())


def _group(module: str) -> int:
    """Import group: 0 ``__future__``, 1 standard library, 2 third party, 3 tanksynth."""
    top = module.split(".")[0]
    if top == "__future__":
        return 0
    if top == "tanksynth":
        return 3
    return 1 if top in sys.stdlib_module_names else 2


def _import_lines(needs: Sequence[Need]) -> list[str]:
    """``from m import a, b`` / ``import m as a`` lines, one per module, wrapped at `LINE`."""
    lines = []
    by_module: dict[str, list[str]] = {}
    for need in needs:
        if need.name is None:
            lines.append(f"import {need.module}" + (f" as {need.alias}" if need.alias else ""))
        else:
            by_module.setdefault(need.module, []).append(need.name)
    for module, names in sorted(by_module.items()):
        names = sorted(set(names))
        line = f"from {module} import {', '.join(names)}"
        if len(line) > LINE:
            body = textwrap.fill(", ".join(names), LINE - 4, initial_indent="    ", subsequent_indent="    ")
            line = f"from {module} import (\n{body},\n)"
        lines.append(line)
    return lines


# --------------------------------------------------------------------------- editing a module

class Edit:
    """The text of one file being written: the original (None for a new file) and the new text.

    Parameters
    ----------
    path : Path
        The file.
    original : str or None
        Its text now (None: it does not exist).
    """

    def __init__(self, path: Path, original: str | None):
        self.path = path
        self.original = original
        self.text = original or ""

    def check_free(self, names: Sequence[str]) -> None:
        """`BadInput` if the module already binds one of ``names``.

        Parameters
        ----------
        names : sequence of str
            The names the skeleton defines there.
        """
        bound = _bindings(ast.parse(self.text)) if self.text else {}
        taken = [n for n in names if n in bound]
        if taken:
            raise BadInput(f"{self.path}: {taken[0]!r} is already defined there")

    def add_imports(self, needs: Sequence[Need], own_module: str) -> None:
        """Import what ``needs`` lists and the module does not bind yet, each after the last import
        of its group (`BadInput` if a name is bound to something else).

        Parameters
        ----------
        needs : sequence of Need
            The imports the new code uses.
        own_module : str
            This module's dotted name (names defined here are not imported).
        """
        tree = ast.parse(self.text)
        bound = _bindings(tree)
        missing: list[Need] = []
        for need in dict.fromkeys(needs):
            if need.module == own_module:
                continue
            want = need.module if need.name is None else f"{need.module}:{need.name}"
            if need.local not in bound:
                missing.append(need)
            elif not _same(bound[need.local], want):
                raise BadInput(f"{self.path}: {need.local!r} is bound to something other than "
                               f"{want.replace(':', '.')}: add the skeleton by hand")
        if not missing:
            return
        first_def = next((i for i, n in enumerate(tree.body)
                          if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))),
                         len(tree.body))
        imports = [n for n in tree.body[:first_def] if isinstance(n, (ast.Import, ast.ImportFrom))]
        lines = self.text.splitlines(keepends=True)
        inserts: dict[int, list[str]] = {}
        for group in sorted({_group(n.module) for n in missing}):
            same = [n for n in imports if _group(_imported(n)) == group]
            anchors = [n for n in imports if _group(_imported(n)) < group]
            for line in _import_lines([n for n in missing if _group(n.module) == group]):
                module = line.split()[1]
                if same:   # in alphabetical place among its group
                    later = [n for n in same if _imported(n) > module]
                    at = later[0].lineno - 1 if later else same[-1].end_lineno or 0
                    inserts.setdefault(at, []).append(line)
                    continue
                if anchors:
                    at = anchors[-1].end_lineno or 0
                elif tree.body and isinstance(tree.body[0], ast.Expr) and \
                        isinstance(tree.body[0].value, ast.Constant):
                    at = tree.body[0].end_lineno or 0   # after the module docstring
                else:
                    at = 0
                block = inserts.setdefault(at, [])
                if not block or _group(block[-1].split()[1]) != group:
                    block.append("")    # a new group: a blank line before it
                block.append(line)
        for at in sorted(inserts, reverse=True):
            lines.insert(at, "".join(line + "\n" for line in inserts[at]))
        self.text = "".join(lines)

    def add_to_all(self, names: Sequence[str]) -> None:
        """Append ``names`` to the module's ``__all__`` (the last list or tuple assigned to it).

        Parameters
        ----------
        names : sequence of str
            Public names of the new code.
        """
        tree = ast.parse(self.text)
        literals = [v for v in _assigned(tree, "__all__") if isinstance(v, (ast.List, ast.Tuple))]
        literal = literals[-1] if literals else None
        quoted = ", ".join(json.dumps(n) for n in names)
        if literal is None and "__all__" in _bindings(tree):   # computed: extend it at the end
            self.text = self.text.rstrip("\n") + f"\n\n__all__ += [{quoted}]\n"
            return
        if literal is None:
            self.text = self._insert_all(tree, quoted)
            return
        if not literal.elts:
            at = _offset(self.text, literal.lineno, literal.col_offset) + 1
            self.text = self.text[:at] + quoted + self.text[at:]
            return
        last, first = literal.elts[-1], literal.elts[0]
        at = _offset(self.text, last.end_lineno or 0, last.end_col_offset or 0)
        line_end = self.text.find("\n", at)
        line_start = self.text.rfind("\n", 0, at) + 1
        if (line_end if line_end >= 0 else len(self.text)) - line_start + len(quoted) + 2 > LINE:
            indent = " " * len(self.text.splitlines()[first.lineno - 1].encode()[:first.col_offset].decode())
            self.text = self.text[:at] + ",\n" + indent + quoted + self.text[at:]
        else:
            self.text = self.text[:at] + ", " + quoted + self.text[at:]

    def _insert_all(self, tree: ast.Module, quoted: str) -> str:
        """The text with ``__all__ = [...]`` after the top-level imports."""
        imports = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))]
        after = imports[-1].end_lineno if imports else (tree.body[0].end_lineno if tree.body else 0)
        lines = self.text.splitlines(keepends=True)
        lines.insert(after or 0, f"\n__all__ = [{quoted}]\n")
        return "".join(lines)

    def append(self, code: str) -> None:
        """Append a block of code (two blank lines before it).

        Parameters
        ----------
        code : str
            Top-level definitions.
        """
        self.text = self.text.rstrip("\n") + "\n\n\n" + code.strip("\n") + "\n"


# ----------------------------------------------------------------------------------- the plan

def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def _toml_value(value: Any) -> str:
    """One TOML value (inline tables and arrays) of what `tomllib` read."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)   # JSON escapes are TOML escapes
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"
    raise BadInput(f"the plant's spec holds a value TOML inline tables cannot copy: {value!r}")


def _example(request: Request, methods: ModuleType) -> str:
    """``examples/<name>.toml``: the plant part of ``--plant-from`` (or the demo) and one design.
    The plant part is validated here (the new method's options are checked after writing)."""
    if request.plant_from is not None:
        source, label = request.plant_from, str(request.plant_from.relative_to(request.root)
                                                if request.plant_from.is_relative_to(request.root)
                                                else request.plant_from)
    else:
        import tanksynth.data   # the target's (see `_target`)

        source, label = Path(tanksynth.data.__file__).with_name("demo.toml"), "the built-in demo"
    try:
        raw = tomllib.loads(source.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise BadInput(f"--plant-from {source}: {exc}") from None
    tables = {k: raw[k] for k in ("plant", "operating_point", "sampling") if isinstance(raw.get(k), dict)}
    if "plant" not in tables or "operating_point" not in tables:
        raise BadInput(f"{source}: no [plant] and [operating_point] tables to copy")
    try:
        methods.parse_spec(tables, source=str(source))
    except Exception as exc:  # noqa: BLE001 - the spec's own message, one line
        raise BadInput(f"{source}: {' '.join(str(exc).split())}") from None
    model = tables["plant"].get("model", "custom")
    comment = textwrap.fill(
        f"``{request.name}``: {request.summary}. Scaffolded by scripts/add_method.py with the "
        f"plant, operating point and sampling of {label}. TODO({request.name}): give the design "
        "the options that show the method.", LINE - 2, break_on_hyphens=False)
    lines = [*(f"# {line}" for line in comment.splitlines()),
             f"title = {json.dumps(f'{request.name} on {model}')}", ""]
    for table, values in tables.items():
        lines.append(f"[{table}]")
        lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in values.items()]
        lines.append("")
    lines += ["[[design]]", f'name = "{request.name}_example"', f'method = "{request.name}"',
              f"{EXAMPLE_OPTION} = 1.0       # the skeleton's option: replace it with the method's"]
    text = "\n".join(lines) + "\n"
    reread = tomllib.loads(text)
    if {k: reread[k] for k in tables} != tables:
        raise BadInput(f"{source}: its plant tables do not survive a copy to TOML unchanged")
    return text


def _table_edit(edit: Edit, request: Request, methods: ModuleType) -> None:
    """Add the row (after the family's last one) and, for a new family, the family."""
    tree = ast.parse(edit.text)
    table = next(iter(_assigned(tree, "TABLE")), None)
    families = next(iter(_assigned(tree, "FAMILIES")), None)
    if not isinstance(table, ast.Tuple) or not table.elts or not all(
            isinstance(e, ast.Call) and isinstance(e.func, ast.Name) for e in table.elts):
        raise BadInput(f"{edit.path}: TABLE is not a tuple of row calls; add the row by hand")
    if not isinstance(families, ast.Tuple) or not families.elts:
        raise BadInput(f"{edit.path}: FAMILIES is not a tuple of names; add the family by hand")
    rows: list[ast.Call] = [e for e in table.elts if isinstance(e, ast.Call)]
    last = rows[-1]
    keywords = [k.arg for k in last.keywords]
    if sorted(k or "" for k in keywords) != sorted(PARTS):
        raise BadInput(f"{edit.path}: the table's rows name parts {keywords}, expected {list(PARTS)}")

    def family_of(call: ast.Call) -> Any:
        args = [a.value for a in call.args if isinstance(a, ast.Constant)]
        return args[1] if len(args) > 1 else None

    mine = [r for r in rows if family_of(r) == request.family]
    after = mine[-1] if mine else last
    refs = request.attributes()
    callee = last.func.id if isinstance(last.func, ast.Name) else "_row"
    parts = [f'{k}="{refs[k or ""]}"' for k in keywords]
    kinds = "(" + ", ".join(json.dumps(k) for k in request.kinds) + ("," if len(request.kinds) == 1 else "") + ")"
    pieces = textwrap.wrap(request.summary, LINE - 14, break_long_words=False, break_on_hyphens=False)
    summary = "\n         ".join(json.dumps(p + (" " if i < len(pieces) - 1 else ""))
                                for i, p in enumerate(pieces))
    row = (f'    {callee}({json.dumps(request.name)}, {json.dumps(request.family)}, {kinds},\n'
           f'         {summary},\n'
           f'         {parts[0]}, {parts[1]},\n'
           f'         {", ".join(parts[2:4])},\n'
           f'         {", ".join(parts[4:])})')
    inserts: list[tuple[ast.expr, str, bool]] = [(after, "\n" + row + ",", True)]
    if request.family not in methods.FAMILIES:
        inserts.append((families.elts[-1], f", {json.dumps(request.family)}", False))
    for node, text, after_comma in sorted(inserts, key=lambda i: (i[0].end_lineno, i[0].end_col_offset),
                                          reverse=True):
        at = _offset(edit.text, node.end_lineno or 0, node.end_col_offset or 0)
        if after_comma:
            comma = re.match(r"[ \t]*,", edit.text[at:])
            at, text = (at + comma.end(), text) if comma else (at, "," + text.rstrip(","))
        edit.text = edit.text[:at] + text + edit.text[at:]


def plan(request: Request, methods: ModuleType) -> list[Edit]:
    """Every file the scaffold writes, with its new text; nothing is written.

    Parameters
    ----------
    request : Request
        The checked request.
    methods : module
        The repository's ``tanksynth.methods``.

    Returns
    -------
    list of Edit
        New and changed files (packages' ``__init__.py`` first).

    Raises
    ------
    BadInput
        A target already defines a new name, a file to create exists, a family name would
        shadow a module, an import would clash.
    """
    root, name = request.root, request.name
    shared = _shared_names()
    edits: dict[Path, Edit] = {}

    def edit(path: Path) -> Edit:
        if path not in edits:
            edits[path] = Edit(path, path.read_text(encoding="utf-8") if path.is_file() else None)
        return edits[path]

    homes = {part: methods.home(part, request.family) for part in PARTS}
    refs = request.attributes()
    run_types = _run_types(methods, request.kinds)
    latex_name = name.replace("_", r"\_")
    returns = " | ".join(t.__name__ for t in run_types) or "Any"
    values = {"name": name, "family": request.family, "summary": request.summary,
              "Options": refs["options"], "NAME": refs["adapter"], "latex_name": latex_name,
              "returns": returns, "option": EXAMPLE_OPTION,
              "options_doc": _wrap(f"Options of ``{name}``: {request.summary}.", "    "),
              "test_doc": _wrap(f"``{name}`` ({request.summary}): designed on its example; what "
                                "is left to write is marked.")}
    typing_needs = [Need("typing", "Any"), Need("typing", "Mapping")]
    code = {
        "options": (OPTIONS_CODE, [refs["options"]],
                    [Need("dataclasses", "dataclass"), Need("typing", "ClassVar"), *typing_needs,
                     shared["MethodOptions"], shared["OptionReader"], shared["option"],
                     shared["parse_number"]]),
        "adapter": (ADAPTER_CODE, [f"run_{name}", refs["adapter"]],
                    [Need("numpy", None, "np"), shared["Spec"], shared["DesignSpec"],
                     shared["DesignMethod"], shared["DesignResult"], shared["options_of"],
                     Need(homes["options"], refs["options"])]),
        "verdict": (VERDICT_CODE, [refs["verdict"]], [*typing_needs, shared["Check"]]),
        "campaign": (CAMPAIGN_CODE, [refs["campaign"]],
                     [*typing_needs, shared["ArtefactError"],
                      *(Need(t.__module__, t.__name__) for t in run_types)]),
        "statement": (STATEMENT_CODE, [refs["statement"]], [*typing_needs, shared["Tex"]]),
    }
    created_packages: list[Path] = []
    for part in PARTS:
        template, public, needs = code[part]
        path, exists = _module_file(root, homes[part])
        if exists and request.family not in methods.FAMILIES and \
                request.family in homes[part].split("."):
            raise BadInput(f"family {request.family!r} would write into the existing module "
                           f"{homes[part]} (pick another family name)")
        e = edit(path)
        e.check_free(public)
        text = _fill(template, {**values, "module": homes[part]})
        if e.original is None and not e.text:
            doc = _wrap(_fill(MODULE_DOCS[part], values))
            e.text = f'"""{doc}\n\nScaffolded by scripts/add_method.py.\n"""\n\nfrom __future__ import annotations\n\n__all__: list[str] = []\n'
            package = path.parent
            while not (package / "__init__.py").is_file() and package != root:
                if package not in created_packages:
                    created_packages.append(package)
                package = package.parent
        e.add_imports(needs, homes[part])
        e.add_to_all(public)
        if e.original is None:   # typed while empty (mypy); a filled list needs no annotation
            e.text = e.text.replace('__all__: list[str] = ["', '__all__ = ["', 1)
        e.append(text)
    for package in created_packages:
        dotted = ".".join(package.relative_to(root).parts)
        what = f"The ``{request.family}`` family in ``{dotted.rpartition('.')[0]}``" \
            if package.name == request.family else f"``{dotted}``"
        e = edit(package / "__init__.py")
        e.text = f'"""{_wrap(f"{what}: {request.summary} (``{name}``).")}\n"""\n\n__all__: list[str] = []\n'

    _table_edit(edit(Path(str(methods.__file__)).resolve()), request, methods)

    example = root / "examples" / f"{name}.toml"
    test = root / "tests" / "design" / f"test_{name}.py"
    # pytest imports test modules by file name (tests/ has no packages): one name, one file
    clashes = sorted((root / "tests").rglob(test.name)) if (root / "tests").is_dir() else []
    for path in (example, test, *clashes):
        if path.exists():
            raise BadInput(f"{path} exists already")
    edit(example).text = _example(request, methods)
    edit(test).text = _fill(TEST_CODE, values)

    ordered = sorted(edits.values(), key=lambda e: (e.path.name != "__init__.py", str(e.path)))
    for e in ordered:
        if e.path.suffix == ".py":
            try:
                ast.parse(e.text)
            except SyntaxError as exc:  # a bug of this script: say where
                raise CheckFailed(f"generated {e.path} does not parse: {exc}") from None
    return ordered


# ---------------------------------------------------------------------------------- writing

def _write(edits: Sequence[Edit]) -> Callable[[], None]:
    """Write every edit atomically (temporary file, rename), all or none; returns the undo."""
    done: list[Edit] = []
    made_dirs: list[Path] = []

    def undo() -> None:
        for e in reversed(done):
            if e.original is None:
                e.path.unlink(missing_ok=True)
            else:
                _atomic(e.path, e.original)
        for d in reversed(made_dirs):
            if d.is_dir() and not any(p for p in d.iterdir() if p.name != "__pycache__"):
                for cache in d.glob("__pycache__"):
                    for f in cache.iterdir():
                        f.unlink()
                    cache.rmdir()
                d.rmdir()

    try:
        for e in edits:
            missing = [p for p in (e.path.parent, *e.path.parent.parents) if not p.exists()]
            for d in reversed(missing):
                d.mkdir()
                made_dirs.append(d)
            _atomic(e.path, e.text)
            done.append(e)
    except BaseException:
        undo()
        raise
    return undo


def _atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.add_method.tmp")
    tmp.write_text(text, encoding="utf-8")
    if path.exists():
        os.chmod(tmp, path.stat().st_mode & 0o7777)
    os.replace(tmp, path)


def _generated_pages(root: Path) -> list[Path]:
    """The documentation pages with generated sections (``python -m tanksynth.docgen`` rewrites them)."""
    docs = root / "docs"
    return sorted(p for p in docs.glob("*.md")
                  if "<!-- BEGIN GENERATED" in p.read_text(encoding="utf-8")) if docs.is_dir() else []


def _check_tree(request: Request) -> None:
    """In a fresh interpreter on the written tree: every part of the table resolves and the
    example loads with the new method; then the generated documentation pages are rewritten."""
    root = request.root
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1",
           "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}
    example = root / "examples" / f"{request.name}.toml"
    code = ("import tanksynth.methods as m; m.resolve_table(); "
            f"s = m.load_spec({str(example)!r}); "
            f"assert [d.method for d in s.designs] == [{request.name!r}], s.designs")
    steps = {"resolving the table and loading the example": [sys.executable, "-c", code]}
    if _generated_pages(root):
        steps["python -m tanksynth.docgen"] = [sys.executable, "-m", "tanksynth.docgen"]
    for what, step in steps.items():
        run = subprocess.run(step, cwd=root, env=env, capture_output=True, text=True)
        if run.returncode != 0:
            last = (run.stderr.strip() or run.stdout.strip() or "failed").splitlines()[-1]
            raise CheckFailed(f"the new tree fails {what}: {last}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command (see the module docstring).

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 written; 2 bad input (nothing written); 1 the new tree failed its check (restored).
    """
    args = _parser().parse_args(argv)
    prog = "add_method.py"
    try:
        methods = _target(args.root.resolve())
        request = _request(args, methods)
        edits = plan(request, methods)
    except BadInput as exc:
        sys.stderr.write(f"{prog}: error: {exc}\n")
        return 2
    except CheckFailed as exc:
        sys.stderr.write(f"{prog}: error: {exc}\n")
        return 1
    pages = _generated_pages(request.root)
    listing = [f"{'update' if e.original is not None else 'create'} {e.path.relative_to(request.root)}"
               for e in edits]
    listing += [f"update {p.relative_to(request.root)} (python -m tanksynth.docgen)" for p in pages]
    if args.dry_run:
        sys.stdout.write("".join(f"would {line}\n" for line in listing))
        return 0
    page_texts = {p: p.read_text(encoding="utf-8") for p in pages}
    undo = _write(edits)
    try:
        _check_tree(request)
    except BaseException as exc:
        undo()
        for page, text in page_texts.items():
            _atomic(page, text)
        if isinstance(exc, CheckFailed):
            sys.stderr.write(f"{prog}: error: {exc}; every file restored\n")
            return 1
        raise
    sys.stdout.write("".join(f"{line}\n" for line in listing))
    sys.stdout.write(
        f"method {request.name!r} scaffolded; its verdict fails until written. Next: grep -rn "
        f"'TODO({request.name})' tanksynth tests examples, write each part, then remove the xfail "
        f"markers of tests/design/test_{request.name}.py (a law for --export law is not scaffolded)\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
