"""The method table is complete, and it is the only map from method names to behaviour."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
import re
import tomllib
import typing
from pathlib import Path
from typing import Mapping

import pytest

import tanksynth
from tanksynth.methods import (ADAPTERS, FAMILIES, KINDS, METHODS, RUNNERS, STATEMENTS, TABLE, VERDICTS, load_spec,
                               resolve, resolve_table)
from tanksynth.spec.method_options import MethodOptions

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.toml"))
NAMES = [row.name for row in TABLE]


def _documented(cls: type) -> set[str]:
    """Names listed in the ``Attributes`` section of a class docstring (numpydoc)."""
    doc = inspect.getdoc(cls) or ""
    match = re.search(r"^Attributes\n-+\n(.*?)(?=^\S[^\n]*\n-+\n|\Z)", doc, re.S | re.M)
    if not match:
        return set()
    return {m.group(1) for m in re.finditer(r"^(\w+)(?: :.*)?$", match.group(1), re.M)}


def _described(cls: type, name: str) -> str:
    """The description lines under ``name`` in the Attributes section."""
    doc = inspect.getdoc(cls) or ""
    match = re.search(rf"^{name}(?: :[^\n]*)?\n((?:    [^\n]*\n?)+)", doc, re.M)
    return " ".join(match.group(1).split()) if match else ""


def _example_methods() -> dict[str, list[str]]:
    used: dict[str, list[str]] = {}
    for path in EXAMPLES:
        for entry in tomllib.loads(path.read_text(encoding="utf-8")).get("design", []):
            used.setdefault(entry.get("method"), []).append(path.name)
    return used


def test_table_lists_each_method_once():
    assert len(NAMES) == len(set(NAMES)) >= 18
    assert set(METHODS) == set(NAMES)


def test_every_part_resolves():
    """The rows name their parts (imported on first use): every name resolves to the right
    kind of object, so a typo in the table fails here even if no example uses the method."""
    resolve_table()
    for row in TABLE:
        refs = row.refs()
        assert all(isinstance(ref, str) for ref in refs.values()), row.name
        assert row.options is row.adapter.options is resolve(refs["options"])
        assert row.verdict is VERDICTS[row.name] and row.campaign is RUNNERS[row.name]
        assert row.statement is STATEMENTS[row.name] and row.adapter is ADAPTERS[row.name]
        assert len(inspect.signature(row.adapter.run).parameters) == 2, row.name
        assert len(inspect.signature(row.statement).parameters) >= 1, row.name
        assert len(inspect.signature(row.verdict).parameters) >= 2, row.name
        assert len(inspect.signature(row.campaign).parameters) >= 2, row.name


def test_every_part_is_defined_in_its_familys_module():
    """Issue 26: a reader who knows a method's family finds each part under that name in every
    stage: the object the row names is *defined* in the family's module of that stage (not
    re-exported there from elsewhere), and the family is one of FAMILIES."""
    from tanksynth.methods import FAMILIES, home

    for row in TABLE:
        assert row.family in FAMILIES, row.name
        for part, ref in row.refs().items():
            module = ref.partition(":")[0]
            assert module == home(part, row.family), (row.name, part, ref)
            obj = getattr(row, part)
            defined_in = getattr(obj, "__module__", None) or type(obj).__module__
            if part == "adapter":  # a DesignMethod constant: its design function is the part
                defined_in = obj.run.__module__
            assert defined_in == module, (row.name, part, defined_in)
    # every family has its module in every stage, and a method
    assert {row.family for row in TABLE} == set(FAMILIES)


def test_a_bad_reference_is_refused():
    """A malformed name fails the import-time check; a well-formed one naming nothing fails
    `resolve_table`."""
    from tanksynth.methods import _check_table

    row = TABLE[0]
    with pytest.raises(TypeError, match="not '<module>:<attribute>'"):
        _check_table((dataclasses.replace(row, verdict="tanksynth.verify.model.verdicts.linearize_verdict"),))
    with pytest.raises(TypeError, match="listed twice"):
        _check_table((row, row))
    with pytest.raises(AttributeError):
        resolve_table((dataclasses.replace(row, verdict="tanksynth.verify.model.verdicts:no_such_verdict"),))
    with pytest.raises(TypeError, match="options for 'kalman'"):
        resolve_table((dataclasses.replace(row, options="tanksynth.spec.method_options:KalmanOptions"),))


def test_import_loads_no_numerical_library():
    """``import tanksynth.methods`` loads none of the rows' parts: a command imports only the
    modules of its spec's methods (issue 15). Fresh interpreter, so this process's imports do
    not count."""
    import subprocess
    import sys

    code = ("import sys, tanksynth.methods as m; m.METHODS['kalman']; m.RUNNERS; repr(m.TABLE); "
            "print(sorted(k for k in ('numpy', 'sympy', 'scipy', 'casadi', 'cvxpy', 'control', "
            "'matplotlib', 'tanksynth.design', 'tanksynth.verify', 'tanksynth.spec') "
            "if k in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.strip()
    assert out == "[]"


@pytest.mark.slow
def test_parsing_a_spec_imports_no_design_code():
    """Validating a spec's options needs the Options classes only (`Method.validate`)."""
    import subprocess
    import sys

    code = ("import sys; from tanksynth.methods import load_spec; "
            f"s = load_spec({str(ROOT / 'examples' / 'seed000_akf.toml')!r}); "
            "print(len(s.designs), sorted(k for k in sys.modules if k.startswith(('tanksynth.design', "
            "'tanksynth.verify', 'cvxpy', 'control'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.strip()
    assert out.endswith(" []") and int(out.split()[0]) >= 1, out


@pytest.mark.parametrize("row", TABLE, ids=lambda r: r.name)
def test_row_is_complete(row):
    opts = row.options
    assert inspect.isclass(opts) and issubclass(opts, MethodOptions), f"{row.name}: no Options class"
    assert dataclasses.is_dataclass(opts) and opts.__dataclass_params__.frozen
    assert opts.method_name == row.name
    assert opts.from_table.__func__ is not MethodOptions.from_table.__func__, \
        f"{row.name}: Options.from_table not implemented"
    fields = {f.name for f in dataclasses.fields(opts)}
    documented = _documented(opts)
    assert fields <= documented, f"{row.name}: undocumented options {sorted(fields - documented)}"
    for name in fields:
        assert len(_described(opts, name)) > 15, f"{row.name}.{name}: no description"
    assert not hasattr(opts, "get"), "Options must not have a .get (verify reads getattr)"
    assert callable(row.adapter.run) and callable(row.design)
    assert callable(row.verdict) and callable(row.statement)
    assert row.kinds and set(row.kinds) <= set(KINDS)
    assert callable(row.campaign), f"{row.name}: no campaign runner"
    if "controller" in row.kinds:       # a controller's runner builds its closed loop
        from tanksynth.verify.laws.campaign import ClosedLoop

        returns = typing.get_type_hints(row.campaign).get("return")
        assert ClosedLoop in (returns, *typing.get_args(returns)), \
            f"{row.name}: campaign runner {row.campaign.__name__} returns {returns}, no ClosedLoop"
    assert row.summary


@pytest.mark.parametrize("name", NAMES)
def test_every_method_has_an_example(name):
    assert _example_methods().get(name), f"no spec in examples/ uses method {name!r}"


def test_examples_store_the_options_instances():
    for path in EXAMPLES:
        spec = load_spec(path)
        for d in spec.designs:
            config = d.config
            assert isinstance(config, METHODS[d.method].options), (path.name, d.name)
            for opt in config.option_names():       # what the verdicts read (getattr)
                getattr(config, opt)
            for opt, value in d.options.items():    # given values are kept, not defaults
                assert getattr(config, opt) is not None or value is None, (path.name, d.name, opt)


def test_defaults_are_the_field_defaults():
    from tanksynth.spec.method_options import FaultDetectionOptions, KalmanOptions, PolePlacementOptions

    assert KalmanOptions.required() == ("Q", "R", "P0")
    assert PolePlacementOptions.required() == ("poles", "target")
    assert FaultDetectionOptions.required() == ()
    assert FaultDetectionOptions.default("delta_bar") == 1.0


def _modules():
    for info in pkgutil.walk_packages(tanksynth.__path__, prefix="tanksynth."):
        if not info.name.endswith("__main__"):
            yield importlib.import_module(info.name)


def test_no_other_map_from_method_names():
    """Only `tanksynth.methods` derives name -> behaviour views (from `TABLE`)."""
    names = set(NAMES)
    derived = {"METHODS", "VERDICTS", "RUNNERS", "STATEMENTS", "ADAPTERS"}
    offenders = []
    for module in _modules():
        for attr, value in vars(module).items():
            if not isinstance(value, Mapping) or inspect.ismodule(value):
                continue
            keys = {k for k in value if isinstance(k, str)}
            if len(keys & names) >= 2:
                if module.__name__ == "tanksynth.methods" and attr in derived:
                    continue
                offenders.append(f"{module.__name__}.{attr}")
    assert offenders == []


def _names_and_keys(path: Path):
    """Identifiers and string dict keys (``"k": ...``, ``d["k"]``) of a module, with lines."""
    import ast
    import io
    import tokenize

    tokens = [t for t in tokenize.generate_tokens(io.StringIO(path.read_text(encoding="utf-8")).readline)
              if t.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.COMMENT, tokenize.INDENT,
                                tokenize.DEDENT)]
    for i, tok in enumerate(tokens):
        if tok.type == tokenize.NAME:
            yield tok.start[0], tok.string
        elif tok.type == tokenize.STRING:
            nxt = tokens[i + 1].string if i + 1 < len(tokens) else ""
            prev = tokens[i - 1].string if i else ""
            if nxt == ":" or (prev == "[" and nxt == "]"):
                try:
                    yield tok.start[0], str(ast.literal_eval(tok.string))
                except (ValueError, SyntaxError):  # f-string key
                    yield tok.start[0], tok.string


#: The option layer and the design adapters (the algorithms' modules are checked by their own
#: tests for the whole tree).
_ADAPTER_FILES = sorted([*(ROOT / "tanksynth" / "spec").rglob("*.py"),
                         *(ROOT / "tanksynth" / "design").rglob("adapters.py"),
                         ROOT / "tanksynth" / "design" / "result.py"])


@pytest.mark.slow
def test_no_seed_values_in_options_or_adapters():
    """Seed data (printed values, seed constants) lives in tanksynth.papers: no identifier or
    dict key of the spec layer or of a design adapter names a seed, a paper or a printed value,
    and no adapter branches on a plant's name."""
    bad = re.compile(r"seed0|SEED|paper|printed")
    assert sum(p.name == "adapters.py" for p in _ADAPTER_FILES) == len(FAMILIES)  # every family's
    found = [f"{path.relative_to(ROOT)}:{line}: {name}" for path in _ADAPTER_FILES
             for line, name in _names_and_keys(path) if bad.search(name)]
    assert found == []
    branches = [f"{path.relative_to(ROOT)}" for path in _ADAPTER_FILES
                if re.search(r"plant\.name\s*[!=]=", path.read_text(encoding="utf-8"))]
    assert branches == []
