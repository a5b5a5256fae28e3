"""The generated method pages speak TOML: option types as a TOML user writes them, a TOML example
(a ``[[design]]`` table of an example spec that parses) and a Python example that designs,
verifies and loads that design; the curated API page lists ``tanksynth.__all__``.

The Sphinx build of these pages is tests/test_docs.py (slow); here the generated Markdown.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

import tanksynth
from tanksynth import docgen
from tanksynth.methods import TABLE

ROOT = Path(__file__).resolve().parents[1]

#: Python words a TOML user never writes (the numpydoc types of the Options docstrings).
PYTHON_WORDS = re.compile(r"\b(tuple|ndarray|mapping|str|float|int|bool|None|dict|list)\b")


def _options():
    for row in TABLE:
        for doc in docgen.method_options(row.name):
            yield row.name, doc


def test_option_types_are_written_as_in_toml():
    for method, doc in _options():
        typ, _ = docgen.option_cells(doc)
        assert not PYTHON_WORDS.search(typ), (method, doc["name"], typ)
        for choice in doc["choices"]:
            assert choice in typ, (method, doc["name"], typ)


@pytest.mark.parametrize(("python", "toml"), [
    ("tuple of float", "array of numbers"),
    ("tuple of tuple of str, or None", "array of arrays of strings"),
    ("tuple of mapping", "array of tables"),
    ("mapping of str to float, or None", "table of numbers"),
    ("mapping of str to (float, float), or None", "table of [number, number] arrays"),
    ("tuple of (str, float, float)", "array of [string, number, number] arrays"),
    ("int", "integer"),
    ("bool or None", "boolean"),
])
def test_toml_type_translations(python, toml):
    assert docgen.toml_type(python) == toml


def test_toml_type_of_a_choice_names_every_value():
    assert docgen.toml_type("str or None", ('"s"', '"z"')) == 'string, one of "s", "z"'


def test_lmi_region_is_an_array_of_tables():
    doc = next(d for d in docgen.method_options("lmi_placement") if d["name"] == "region")
    assert docgen.option_cells(doc)[0] == "array of tables"


@pytest.fixture(scope="module")
def pages(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("pages")
    docgen.write_pages(out)
    return out


@pytest.mark.parametrize("name", [row.name for row in TABLE])
def test_method_page_has_a_toml_and_a_python_example(name, pages):
    page = (pages / "methods" / f"{name}.md").read_text(encoding="utf-8")
    toml = re.search(r"## TOML example\n.*?```toml\n(.*?)```", page, re.S)
    python = re.search(r"## Python example\n.*?```python\n(.*?)```", page, re.S)
    assert toml and python, name
    table = tomllib.loads(toml.group(1))["design"]
    assert len(table) == 1 and table[0]["method"] == name
    code = python.group(1)
    # the Python example designs the very table the TOML example shows
    if "tanksynth.design(" in code:   # the public API, with the spec's tables as Python values
        assert f'tanksynth.design(plant, "{name}",' in code
        assert f'name="{table[0]["name"]}",' in code
        for key in table[0]:
            if key not in ("name", "method"):
                assert f"{key}=" in code, key
        return
    spec_file = re.search(r'load_spec\("([^"]+)"\)', code).group(1)
    assert f'd.name == "{table[0]["name"]}"' in code
    spec = tanksynth.load_spec(ROOT / spec_file)
    assert [d.method for d in spec.designs if d.name == table[0]["name"]] == [name]


def test_python_examples_call_the_public_design_function():
    """Issue 30: the method pages showed internals (`tanksynth.methods.design`,
    `write_artefact`) where `tanksynth.design(...)` does it; only a spec that needs more than
    one design's tables (a fit's [data]) keeps the spec-file form."""
    assert "tanksynth.design(plant, \"lmi_placement\"," in docgen.python_example("lmi_placement")
    assert "write_artefact" not in docgen.python_example("pole_placement")
    assert "load_spec" in docgen.python_example("fit")   # [data] table
    rest = [row.name for row in TABLE if "tanksynth.design(" not in docgen.python_example(row.name)]
    assert rest == ["fit"], rest
    # an estimator's initial estimate (its option x0) is tanksynth.design's x_hat0
    assert "x_hat0=[0.9, 0.55, 0.5]," in docgen.python_example("kalman")


def test_python_example_call_form_comes_from_one_function(monkeypatch):
    """The design call of every Python example is `docgen.python_design_call`'s (the one place
    to switch to another API form)."""
    monkeypatch.setattr(docgen, "python_design_call", lambda spec, design, directory: ["CALL_FORM()"])
    for row in TABLE:
        assert "CALL_FORM()" in docgen.python_example(row.name), row.name


@pytest.mark.slow   # designs and verifies one design (a few seconds)
def test_a_python_example_runs(tmp_path, monkeypatch):
    page = docgen.python_example("lmi_placement")
    code = re.search(r"```python\n(.*?)```", page, re.S).group(1)
    code = code.replace('"examples/', f'"{ROOT / "examples"}/')
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(code, "example", "exec"), namespace)
    art, verdict = namespace["art"], namespace["verdict"]
    assert art.name == "integral_lmi_disk" and "K" in art.gains
    assert verdict.passed is True
    # the same gain as the CLI's design of the spec file (bit for bit: same spec, same solver)
    spec = tanksynth.load_spec(ROOT / "examples" / "seed000_pole_placement.toml")
    from tanksynth.methods import METHODS
    entry = next(d for d in spec.designs if d.name == "integral_lmi_disk")
    np.testing.assert_array_equal(art.gains["K"], METHODS[entry.method].design(spec, entry).gains["K"])


def test_api_reference_lists_every_public_name():
    text = docgen.api_reference_markdown()
    public = [n for n in tanksynth.__all__ if n != "__version__"]
    documented = re.findall(r"^\.\. auto(?:function|class|exception):: tanksynth\.(\w+)$", text, re.M)
    assert sorted(documented) == sorted(public)
    assert "tanksynth.verify.runner" not in re.findall(r"auto\w+:: (\S+)", text)


def test_api_reference_documents_the_verdict_design_verify_returns():
    """Issue 30: `Design.verify()` returns a `Verdict` the API page did not document."""
    text = docgen.api_reference_markdown()
    assert ".. autoclass:: tanksynth.Verdict" in text
    assert ".. autoclass:: tanksynth.Check" in text
    results = text.split("## Results")[1].split("\n## ")[0]
    assert "tanksynth.Verdict" in results and "tanksynth.Check" in results
    from tanksynth.verify.runner import Verdict
    assert tanksynth.Verdict is Verdict
