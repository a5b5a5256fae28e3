"""Spec loading and validation: examples load, every error names its key, fuzzing."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.errors import ParseError, RegionError, SpecError
from tanksynth.methods import load_spec, parse_spec, parse_spec_text

ROOT = Path(__file__).resolve().parents[2]
SEED000 = ROOT / "examples" / "seed000_three_tank.toml"

SINGLE_TANK = """
title = "single tank"

[plant]
model = "custom"
name = "single_tank"

[plant.states]
h = {unit = "m", min = 0.0, max = 1.0}

[plant.inputs]
q = {unit = "m^3/s", min = 0.0, max = 1e-4}

[plant.parameters]
A = {value = 0.0154, unit = "m^2", min = 0.0}
a = {value = 5e-5, unit = "m^2", min = 0.0}
g = {value = 9.81, unit = "m/s^2"}

[plant.equations]
h = "(q - a*sqrt(2*g*h))/A"

[plant.outputs]
y = "h"

[operating_point]
x = [0.25]

[sampling]
ts = 2.0

[[design]]
name = "lin"
method = "linearize"
"""


def seed000_table() -> dict:
    return tomllib.loads(SEED000.read_text())


def single_tank_table() -> dict:
    return tomllib.loads(SINGLE_TANK)


def expect_error(table, key, cls=SpecError, source="spec.toml", match=None):
    with pytest.raises(cls) as info:
        parse_spec(table, source=source)
    assert info.value.key == key, str(info.value)
    msg = str(info.value)
    assert key in msg and source in msg
    if match:
        assert match in msg
    return info.value


# -------------------------------------------------------------------- valid
def test_seed000_example_loads():
    spec = load_spec(SEED000)
    assert spec.plant.name == "three_tank"
    np.testing.assert_array_equal(spec.x0, [0.40, 0.20, 0.30])
    np.testing.assert_array_equal(spec.given_u0, [0.35e-4, 0.375e-4])
    assert spec.ts == 1.0
    assert [(d.name, d.method) for d in spec.designs] == [("linear_model", "linearize")]
    assert spec.source == str(SEED000)
    assert len(spec.sha256) == 64
    import hashlib

    assert spec.sha256 == hashlib.sha256(SEED000.read_bytes()).hexdigest()
    assert spec.plant.parameter("A").value == 0.0154


def test_every_example_loads():
    for path in sorted((ROOT / "examples").glob("*.toml")):
        spec = load_spec(path)
        assert spec.plant.n >= 1, path


def test_custom_single_tank_loads_and_linearises():
    spec = parse_spec_text(SINGLE_TANK, source="single.toml")
    plant = spec.plant
    assert plant.name == "single_tank"
    assert [s.name for s in plant.states] == ["h"]
    eq = equilibrium_input(plant, spec.x0)
    a, g, A, h = 5e-5, 9.81, 0.0154, 0.25
    np.testing.assert_allclose(eq.u0, [a * math.sqrt(2 * g * h)], rtol=1e-12)
    lin = linearize(plant, spec.x0, eq.u0, ts=spec.ts)
    F = -a * math.sqrt(2 * g) / (2 * A * math.sqrt(h))
    np.testing.assert_allclose(lin.F, [[F]], rtol=1e-12)
    np.testing.assert_allclose(lin.B, [[1 / A]], rtol=1e-12)
    np.testing.assert_allclose(lin.C, [[1.0]])
    np.testing.assert_allclose(lin.Ad, [[math.exp(F * 2.0)]], rtol=1e-12)
    np.testing.assert_allclose(lin.Bd, [[math.expm1(F * 2.0) / F / A]], rtol=1e-10)


def test_autonomous_custom_plant_without_inputs():
    """Inputs are optional in a custom plant: equilibrium and linearisation still work."""
    text = (SINGLE_TANK.replace('[plant.inputs]\nq = {unit = "m^3/s", min = 0.0, max = 1e-4}\n', "")
            .replace('h = "(q - a*sqrt(2*g*h))/A"', 'h = "-a*sqrt(2*g*h)/A"'))
    spec = parse_spec_text(text, source="auto.toml")
    assert spec.plant.m == 0
    eq = equilibrium_input(spec.plant, spec.x0)
    assert eq.u0.shape == (0,)
    assert not eq.is_equilibrium                      # a draining tank is not at rest
    lin = linearize(spec.plant, spec.x0, eq.u0, ts=spec.ts)
    assert lin.B.shape == (1, 0) and lin.Bd.shape == (1, 0)
    np.testing.assert_allclose(lin.F, [[-5e-5 * math.sqrt(2 * 9.81) / (2 * 0.0154 * 0.5)]], rtol=1e-12)


def test_parameter_override_applies():
    t = seed000_table()
    t["plant"]["parameters"]["A"] = 0.02
    assert parse_spec(t).plant.parameter("A").value == 0.02


def test_operating_point_as_list_or_table():
    t = seed000_table()
    t["operating_point"]["x"] = [0.4, 0.2, 0.3]
    assert parse_spec(t).x0.tolist() == [0.4, 0.2, 0.3]


# -------------------------------------------------------------------- errors
def test_unknown_top_level_key():
    t = seed000_table()
    t["solver"] = "x"
    expect_error(t, "solver", match="unknown top-level")


def test_unknown_plant_model():
    t = seed000_table()
    t["plant"]["model"] = "four_tank"
    expect_error(t, "plant.model", match="four_tank")


def test_negative_area():
    t = seed000_table()
    t["plant"]["parameters"]["A"] = -0.0154
    expect_error(t, "plant.parameters.A", match="must be >")


def test_nan_from_toml():
    text = SEED000.read_text().replace("A = 0.0154", "A = nan")
    with pytest.raises(SpecError) as info:
        parse_spec_text(text, source="nan.toml")
    assert info.value.key == "plant.parameters.A"
    assert "finite" in str(info.value) and "nan.toml" in str(info.value)


def test_inf_from_toml():
    text = SEED000.read_text().replace("ts = 1.0", "ts = inf")
    with pytest.raises(SpecError) as info:
        parse_spec_text(text, source="inf.toml")
    assert info.value.key == "sampling.ts"


def test_huge_toml_integer():
    """TOML integers are unbounded: 10**400 must be a SpecError, not an OverflowError."""
    big = "1" + "0" * 400
    for old, new, key in (("A = 0.0154", f"A = {big}", "plant.parameters.A"),
                          ("ts = 1.0", f"ts = {big}", "sampling.ts"),
                          ("h1 = 0.40", f"h1 = -{big}", "operating_point.x.h1")):
        text = SEED000.read_text().replace(old, new)
        with pytest.raises(SpecError) as info:
            parse_spec_text(text, source="big.toml")
        assert info.value.key == key
    t = single_tank_table()
    t["plant"]["states"]["h"]["max"] = 10**400
    expect_error(t, "plant.states.h.max", match="finite")


def test_string_where_number():
    t = seed000_table()
    t["plant"]["parameters"]["Phi"] = "5e-5"
    expect_error(t, "plant.parameters.Phi", match="expected a number")
    t = seed000_table()
    t["operating_point"]["x"]["h2"] = "0.2"
    expect_error(t, "operating_point.x.h2", match="expected a number")
    t = seed000_table()
    t["sampling"]["ts"] = True
    expect_error(t, "sampling.ts")


def test_unknown_parameter():
    t = seed000_table()
    t["plant"]["parameters"]["mu99"] = 0.5
    expect_error(t, "plant.parameters.mu99", match="unknown parameter")


def test_operating_point_outside_region():
    t = seed000_table()
    t["operating_point"]["x"] = {"h1": 0.2, "h2": 0.4, "h3": 0.3}   # flow directions violated
    err = expect_error(t, "operating_point.x", cls=RegionError, match="outside the operating region")
    assert "h1 > h3" in str(err)
    t = seed000_table()
    t["operating_point"]["x"] = {"h1": 0.9, "h2": 0.2, "h3": 0.3}   # above hmax
    expect_error(t, "operating_point.x", cls=RegionError, match="h1 = 0.9 outside")


def test_wrong_vector_length():
    t = seed000_table()
    t["operating_point"]["x"] = [0.4, 0.2]
    expect_error(t, "operating_point.x", match="expected 3 values")
    t = seed000_table()
    t["operating_point"]["u"] = [1e-5, 1e-5, 1e-5]
    expect_error(t, "operating_point.u", match="expected 2 values")
    t = seed000_table()
    t["operating_point"]["x"] = {"h1": 0.4, "h2": 0.2}
    expect_error(t, "operating_point.x", match="missing")


def test_unknown_design_method():
    t = seed000_table()
    t["design"][0]["method"] = "magic"
    expect_error(t, "design[0].method", match="unknown method 'magic'")


def test_duplicate_design_name():
    t = seed000_table()
    t["design"].append(dict(t["design"][0]))
    expect_error(t, "design[1].name", match="duplicate")


def test_linearize_without_sampling():
    t = seed000_table()
    del t["sampling"]
    expect_error(t, "sampling.ts", match="sampling period")


def test_unknown_design_option():
    t = seed000_table()
    t["design"][0]["horizon"] = 3
    expect_error(t, "design[0].horizon", match="unknown option")


def test_invalid_toml_names_file(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("[plant\nmodel = 'three_tank'\n")
    with pytest.raises(SpecError) as info:
        load_spec(path)
    assert info.value.source == str(path)
    assert str(path) in str(info.value) and "invalid TOML" in str(info.value)


def test_missing_file_names_file(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(SpecError) as info:
        load_spec(path)
    assert str(path) in str(info.value)


def test_not_utf8(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(b"title = '\xe9'\n")
    with pytest.raises(SpecError, match="UTF-8"):
        load_spec(path)


@pytest.mark.parametrize("equation,token", [
    ("os.system('rm -rf /')", "'.'"),
    ("__import__('os').system('ls')", "'"),
    ("eval('1')", "eval"),
    ("h**99999", "99999"),
    ("unknown_name * h", "unknown_name"),
])
def test_custom_equation_outside_whitelist(equation, token):
    t = single_tank_table()
    t["plant"]["equations"]["h"] = equation
    err = expect_error(t, "plant.equations.h", cls=ParseError)
    assert token in str(err)


def test_custom_plant_errors_name_keys():
    t = single_tank_table()
    t["plant"]["equations"]["z"] = "h"
    expect_error(t, "plant.equations", match="not a state")
    t = single_tank_table()
    t["plant"]["states"]["h"] = {"unit": "m", "min": 1.0, "max": 0.0}
    expect_error(t, "plant.states.h", match="smaller than")
    t = single_tank_table()
    t["plant"]["parameters"]["A"]["value"] = -1.0
    expect_error(t, "plant.parameters.A.value")
    t = single_tank_table()
    t["plant"]["outputs"]["y"] = "h + q"
    expect_error(t, "plant.outputs.y", match="feedthrough")
    t = single_tank_table()
    t["plant"]["states"]["sqrt"] = {"unit": "m", "min": 0.0, "max": 1.0}
    expect_error(t, "plant.states.sqrt", cls=ParseError, match="reserved")


# ------------------------------------------------------------------ fuzzing
BAD_VALUES = [
    float("nan"), float("inf"), -float("inf"), -1, -1.0, 0, 0.0, 1e308, -1e308, 1e-320, 10**400,
    None, True, "", "abc", "nan", "1e999", '__import__("os")', "h1**99999", "h**99999",
    "os.system('ls')", "(" * 300, [], [1, 2], [[1]], ["a"], {}, {"a": 1}, {"value": "x"},
]


def _paths(node, prefix=()):
    """Every (path, value) in a nested dict/list document."""
    out = [(prefix, node)]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, prefix + (i,))
    return out


def _set(doc, path, value):
    node = doc
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value


def _delete(doc, path):
    node = doc
    for p in path[:-1]:
        node = node[p]
    del node[path[-1]]


@st.composite
def mutated_spec(draw):
    doc = draw(st.sampled_from([seed000_table, single_tank_table]))()
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p, _ in _paths(doc) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        action = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
        if action == "replace":
            value = draw(st.one_of(st.sampled_from(BAD_VALUES), st.text(max_size=12),
                                   st.floats(allow_nan=True, allow_infinity=True),
                                   st.integers(-10**6, 10**6)))
            _set(doc, path, copy.deepcopy(value))
        elif action == "delete":
            _delete(doc, path)
        else:
            parent = path[:-1]
            node = doc
            for p in parent:
                node = node[p]
            if isinstance(node, dict):
                node[draw(st.sampled_from(["zz", "__class__", "model", "value", "x", "1bad"]))] = \
                    copy.deepcopy(draw(st.sampled_from(BAD_VALUES)))
            else:
                node.append(copy.deepcopy(draw(st.sampled_from(BAD_VALUES))))
    return doc


@pytest.mark.slow
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_spec())
def test_fuzzed_specs_only_raise_spec_errors(doc):
    try:
        spec = parse_spec(doc, source="fuzz.toml")
    except SpecError as exc:
        assert (exc.key not in (None, "")) or "fuzz.toml" in str(exc)
        assert exc.source == "fuzz.toml"
        assert str(exc).strip()
    else:
        # what was accepted is usable: finite point inside the region
        assert np.all(np.isfinite(spec.x0))
        assert not spec.plant.region.violations(spec.x0, spec.plant.x)


@pytest.mark.slow
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_fuzzed_spec_text_only_raises_spec_errors(data):
    text = data.draw(st.sampled_from([SEED000.read_text(), SINGLE_TANK]))
    for _ in range(data.draw(st.integers(1, 4))):
        pos = data.draw(st.integers(0, len(text)))
        kind = data.draw(st.sampled_from(["insert", "delete", "replace"]))
        chunk = data.draw(st.sampled_from(["[", "]", "=", '"', "'", "\n", "nan", "-", "1e999",
                                           "__import__", "**99", "{", "}", ",", "\x00", "é"])
                          | st.text(max_size=4))
        if kind == "insert":
            text = text[:pos] + chunk + text[pos:]
        elif kind == "delete":
            text = text[:pos] + text[pos + len(chunk):]
        else:
            text = text[:pos] + chunk + text[pos + len(chunk):]
    try:
        parse_spec_text(text, source="fuzz.toml")
    except SpecError as exc:
        assert (exc.key not in (None, "")) or "fuzz.toml" in str(exc)


@pytest.mark.parametrize("design, match", [
    ('method = "pole_placement"\ntarget = "state_feedback"\npoles = [-0.5, -1.0, -2.0]', "look like s-plane poles"),
    ('method = "pole_placement"\ntarget = "state_feedback"\npoles = [1.5, 0.6, 0.7]', "inside the unit circle"),
    ('method = "pole_placement"\ntarget = "state_feedback"\ntime_domain = "continuous"\npoles = [0.5, 0.6, 0.7]',
     "look like z-plane poles"),
    ('method = "pole_placement"\ntarget = "state_feedback"\nintegral = true\npoles = [0.5, 0.6, 0.7]',
     r"expected 5 \(3 states \+ 2 integrators"),
    ('method = "ekf"\nQ = 1e-9\nR = 1e-6\nP0 = 1e-3\nsubsteps = 1000000000000', r"in \[1, 1000\]"),
    ('method = "narx"\nQ = 1e-9\nR = 1e-6\nP0 = 1e-3\nhidden = 99999999999', r"in \[1, 1000\]"),
])
def test_poles_and_sizes_refused_when_the_spec_is_read(design, match):
    """Unstable poles for the design's domain, a wrong count (with why) and absurd sizes: exit-2
    material, caught before any design runs."""
    text = ('[plant]\nmodel = "three_tank"\noutputs = "all"\n[operating_point]\n'
            'x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}\n[sampling]\nts = 1.0\n'
            f'[[design]]\nname = "d"\n{design}\n')
    with pytest.raises(SpecError, match=match):
        parse_spec_text(text)


@pytest.mark.parametrize("names, match", [
    (["plant"], "plant.json"), (["Checks"], "checks.json"), (["report"], "report.tex"),
    (["lin", "lin.traces"], "traces.npz"), (["ctl_law"], "exported control law"),
    (["lin", "LIN"], "differing only in case"),
])
def test_design_names_that_collide_with_files_are_refused(names, match):
    """A design whose files would overwrite the tool's own (or another design's) files: exit-2."""
    designs = "".join(f'[[design]]\nname = "{n}"\nmethod = "linearize"\n' for n in names)
    text = ('[plant]\nmodel = "three_tank"\n[operating_point]\nx = {h1 = 0.40, h2 = 0.20, h3 = 0.30}\n'
            f'[sampling]\nts = 1.0\n{designs}')
    with pytest.raises(SpecError, match=match):
        parse_spec_text(text)


_THREE_TANK = ('[plant]\nmodel = "three_tank"\noutputs = "all"\n[operating_point]\n'
               'x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}\n[sampling]\nts = 1.0\n')
#: Four designs, three of them invalid, each for a different reason.
_BAD_DESIGNS = ('[[design]]\nname = "a"\nmethod = "pole_placment"\n'
                '[[design]]\nname = "b"\nmethod = "linearize"\n'
                '[[design]]\nname = "c"\nmethod = "kalman"\nbogus = 3\n'
                '[[design]]\nname = "d"\nmethod = "pole_placement"\ntarget = "state_feedback"\npoles = [0.5, 0.6]\n')


def test_every_invalid_design_is_reported_at_once(tmp_path):
    """Several invalid [[design]] tables: one SpecError naming each (index, name, key, reason),
    listed first so a message cut at the CLI's line limit still names them all; the valid
    table is not named; ``errors`` holds each table's own error."""
    path = tmp_path / "spec.toml"
    path.write_text(_THREE_TANK + _BAD_DESIGNS)
    with pytest.raises(SpecError) as info:
        load_spec(path)
    exc, text = info.value, str(info.value)
    assert text.startswith(f"{path}: 3 invalid designs (design[0] 'a', design[2] 'c', design[3] 'd'): "), text
    for label, key, reason in [("design[0] 'a'", "design[0].method", "did you mean 'pole_placement'"),
                               ("design[2] 'c'", "design[2].bogus", "unknown option 'bogus'"),
                               ("design[3] 'd'", "design[3].poles", "2 poles given, expected 3")]:
        assert f"{label}: key '{key}': " in text and reason in text, (label, text)
    assert "design[1]" not in text and "'b'" not in text
    assert [e.key for e in exc.errors] == ["design[0].method", "design[2].bogus", "design[3].poles"]
    assert exc.source == str(path)


def test_one_invalid_design_keeps_its_own_error():
    """One bad table among good ones: its error unchanged (key and message), no summary."""
    text = _THREE_TANK + _BAD_DESIGNS.split("[[design]]\nname = \"c\"")[0].replace("pole_placment",
                                                                                   "linearize")
    text += '[[design]]\nname = "d"\nmethod = "pole_placement"\ntarget = "state_feedback"\npoles = [0.5, 0.6]\n'
    with pytest.raises(SpecError) as info:
        parse_spec_text(text)
    assert info.value.key == "design[2].poles"
    assert "invalid designs" not in str(info.value)


def test_a_plant_or_sampling_error_stops_before_the_designs():
    """The designs are read against the plant and ts: a bad [sampling] is reported alone."""
    text = _THREE_TANK.replace("ts = 1.0", "ts = -1.0") + _BAD_DESIGNS
    with pytest.raises(SpecError) as info:
        parse_spec_text(text)
    assert info.value.key == "sampling.ts"
    assert "design" not in str(info.value)


def test_the_cli_names_every_invalid_design_and_writes_nothing(tmp_path, capsys):
    """`design` on a spec with several bad tables: exit 2, one line naming each, no file."""
    from tanksynth.cli import main

    spec = tmp_path / "spec.toml"
    spec.write_text(_THREE_TANK + _BAD_DESIGNS)
    out_dir = tmp_path / "out"
    code = main(["design", str(spec), "-o", str(out_dir)])
    _, err = capsys.readouterr()
    assert code == 2
    lines = err.strip("\n").splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in err, err
    for label in ("design[0] 'a'", "design[2] 'c'", "design[3] 'd'"):
        assert label in lines[0]
    assert not out_dir.exists() or not any(out_dir.iterdir())


def test_a_parameter_of_zero_in_a_denominator_is_a_spec_error():
    """``A = 0`` makes ``(q - a sqrt(2 g h)) / A`` sympy's ``zoo``, which no compiler takes: a
    SpecError (exit 2) naming the plant and the likely cause, not a bare TanksynthError (the fuzz
    test found it)."""
    table = tomllib.loads(SINGLE_TANK)
    table["plant"]["parameters"]["A"] = 0
    with pytest.raises(SpecError, match="division by zero") as info:
        parse_spec(table)
    assert info.value.key == "plant"


def test_many_invalid_designs_stay_useful_within_the_cli_line(tmp_path, capsys):
    """40 tables with the same mistake plus one with a long list of valid values: the one
    line (cut at 600 characters) still names every bad table (as index ranges) and gives
    each distinct reason, instead of 600 characters of names and no reason."""
    from tanksynth.cli import MAX_MESSAGE, main

    bad = "".join(f'[[design]]\nname = "p{i}"\nmethod = "pole_placement"\ntarget = "state_feedback"\npoles = [0.5, 0.6]\n'
                  for i in range(40))
    good = '[[design]]\nname = "ok"\nmethod = "linearize"\n'
    spec = tmp_path / "spec.toml"
    spec.write_text(_THREE_TANK + bad + good + '[[design]]\nname = "m"\nmethod = "nosuch"\n'
                    + '[[design]]\nname = "k"\nmethod = "kalman"\nbogus = 1\n')
    with pytest.raises(SpecError) as info:
        load_spec(spec)
    assert len(info.value.errors) == 42
    assert main(["design", str(spec), "-o", str(tmp_path / "out")]) == 2
    line = capsys.readouterr().err.strip()
    assert "\n" not in line and len(line) <= MAX_MESSAGE + len("error: ")
    assert "42 invalid designs (design[0-39, 41-42])" in line, line
    assert "design[0-39]: key 'design[*].poles': 2 poles given, expected 3" in line, line
    assert "design[41] 'm': key 'design[41].method': unknown method 'nosuch'" in line, line
    assert "design[42] 'k': key 'design[42].bogus': unknown option 'bogus'" in line, line
    assert not (tmp_path / "out").exists()
