"""The catalogue (`tanksynth methods NAME`, `MethodOptions.describe`) and the validator
(`from_table` / `OptionReader`) tell the same story for every method (issue 30 item 14).

For each method, its first ``[[design]]`` table in ``examples/`` is cut down to what the
catalogue calls necessary: the options listed ``required``, the member the example gives of
each "exactly one of" group, and the options the catalogue says the plant makes necessary
(``required_when``), plus the few optional options that change how a kept option's value
reads (`CONTEXT`: e.g. ``integral = true`` makes ``poles`` n + p long). That table must validate (so every option listed optional may be
omitted); removing any option listed required, or the one member of a group, must be refused
naming it.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import pytest

from tanksynth.errors import SpecError
from tanksynth.methods import METHODS, parse_spec

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def _first_table_of_each_method() -> dict[str, tuple[dict, int]]:
    found: dict[str, tuple[dict, int]] = {}
    for path in sorted(EXAMPLES.glob("*.toml")):
        spec = tomllib.loads(path.read_text())
        for i, entry in enumerate(spec.get("design", [])):
            found.setdefault(entry["method"], (spec, i))
    return found


TABLES = _first_table_of_each_method()
#: Optional options the example's value of a necessary option is written for (the value would
#: be wrong, not missing, without them): kept in the cut-down table.
CONTEXT = {"pole_placement": {"integral"}, "luenberger": {"form"}}


def _with_design(spec: dict, entry: dict) -> dict:
    out = copy.deepcopy(spec)
    out["design"] = [entry]
    return out


def test_every_method_has_an_example_table():
    assert set(METHODS) <= set(TABLES)


@pytest.mark.parametrize("name", sorted(METHODS))
def test_catalogue_required_and_optional_options_are_what_the_validator_enforces(name):
    spec, index = TABLES[name]
    entry = spec["design"][index]
    docs = {d.name: d for d in METHODS[name].options.describe()}
    necessary = {k for k, d in docs.items() if d.required or d.required_when or d.one_of}
    necessary |= CONTEXT.get(name, set())
    minimal = {k: v for k, v in entry.items() if k in ("name", "method") or k in necessary}
    for d in docs.values():
        if d.required:
            assert d.name in minimal, f"{name}: the example omits required option {d.name!r}"
        if d.one_of:
            assert sum(m in minimal for m in d.one_of) == 1, f"{name}: group {d.one_of}"
    parse_spec(_with_design(spec, minimal))  # every optional option omitted
    for option, d in docs.items():
        if option in minimal and (d.required or d.one_of):
            cut = {k: v for k, v in minimal.items() if k != option}
            with pytest.raises(SpecError) as info:
                parse_spec(_with_design(spec, cut))
            assert option in str(info.value), str(info.value)


def test_multiobjective_region_is_listed_required():
    region = next(d for d in METHODS["multiobjective"].options.describe() if d.name == "region")
    assert region.required and region.default == "required"


def test_one_of_group_is_in_the_catalogue_of_each_member():
    docs = {d.name: d for d in METHODS["luenberger"].options.describe()}
    assert docs["L"].one_of == docs["poles"].one_of == ("L", "poles")
    assert "exactly one of L and poles" in docs["L"].default_text
