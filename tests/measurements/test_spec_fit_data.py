"""Spec syntax of issue 27: free parameters ({value, min, max, fit}) and the [data] table."""

from __future__ import annotations

import copy

import pytest

from tanksynth.errors import SpecError
from tanksynth.methods import parse_spec
from tanksynth.spec import DataTable, FreeParameter

BASE = {
    "plant": {"model": "three_tank",
              "parameters": {"mu13": {"value": 0.5, "min": 0.2, "max": 0.9, "fit": True},
                             "mu20": 0.675,
                             "mu32": {"value": 0.5, "min": 0.2, "max": 0.9, "fit": True}}},
    "operating_point": {"x": [0.4, 0.2, 0.3]},
    "sampling": {"ts": 1.0},
}

CUSTOM = {
    "plant": {
        "model": "custom", "name": "one_tank",
        "states": {"h": {"unit": "m", "min": 0.0, "max": 1.0}},
        "inputs": {"q": {"unit": "m^3/s", "min": 0.0, "max": 1e-4}},
        "parameters": {"A": {"value": 0.0154, "unit": "m^2", "min": 0.0},
                       "a": {"value": 5e-5, "unit": "m^2", "min": 1e-5, "max": 1e-4, "fit": True},
                       "g": 9.81},
        "equations": {"h": "(q - a*sqrt(2*g*h))/A"},
        "outputs": {"y": {"expr": "h", "unit": "m", "min": 0.0, "max": 0.9}},
    },
    "operating_point": {"x": [0.3]},
}


def spec_with(**changes):
    t = copy.deepcopy(BASE)
    for path, value in changes.items():
        node = t
        keys = path.split("__")
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        if value is None:
            del node[keys[-1]]
        else:
            node[keys[-1]] = value
    return t


def error(table, key, match):
    with pytest.raises(SpecError, match=match) as info:
        parse_spec(table)
    assert info.value.key == key, str(info.value)
    return info.value


def test_free_parameters_builtin_in_spec_order():
    spec = parse_spec(copy.deepcopy(BASE))
    assert spec.free_parameters == (FreeParameter("mu13", 0.5, 0.2, 0.9, "1"),
                                    FreeParameter("mu32", 0.5, 0.2, 0.9, "1"))
    assert spec.plant.parameter("mu13").value == 0.5 and spec.plant.parameter("mu20").value == 0.675
    assert spec.data is None


def test_value_table_without_fit_is_a_value():
    t = spec_with(plant__parameters__mu13={"value": 0.45, "min": 0.2, "max": 0.9},
                  plant__parameters__mu32={"value": 0.55, "fit": False})
    spec = parse_spec(t)
    assert spec.free_parameters == ()
    assert spec.plant.parameter("mu13").value == 0.45 and spec.plant.parameter("mu32").value == 0.55


def test_no_free_parameters_default():
    t = spec_with(plant__parameters=None)
    assert parse_spec(t).free_parameters == ()


@pytest.mark.parametrize("entry, key, match", [
    ({"value": 0.5, "min": 0.9, "max": 0.2, "fit": True}, "plant.parameters.mu13",
     r"min \(0.9\) must be smaller than max \(0.2\)"),
    ({"value": 0.5, "min": 0.5, "max": 0.5, "fit": True}, "plant.parameters.mu13", "smaller than max"),
    ({"value": 0.95, "min": 0.2, "max": 0.9, "fit": True}, "plant.parameters.mu13.value",
     r"above max \(0.9\)"),
    ({"value": 0.1, "min": 0.2, "max": 0.9, "fit": True}, "plant.parameters.mu13.value",
     r"below min \(0.2\)"),
    ({"value": 0.5, "min": 0.0, "max": 0.9, "fit": True}, "plant.parameters.mu13.min",
     r"must be > 0"),
    ({"value": 0.5, "min": 0.2, "max": 1.5, "fit": True}, "plant.parameters.mu13.max",
     r"must be <= 1"),
    ({"value": 0.5, "min": 0.2, "max": 0.9, "fit": "yes"}, "plant.parameters.mu13.fit",
     r"true or false"),
    ({"value": 0.5, "min": 0.2, "fit": True}, "plant.parameters.mu13.max", r"search box: give max"),
    ({"value": 0.5, "fit": True}, "plant.parameters.mu13.min", r"give min and max"),
    ({"min": 0.2, "max": 0.9, "fit": True}, "plant.parameters.mu13", r"give value"),
    ({"value": 0.5, "min": 0.2, "max": 0.9, "fit": True, "unit": "1"}, "plant.parameters.mu13.unit",
     r"unknown field 'unit'"),
    ({"value": "0.5", "min": 0.2, "max": 0.9, "fit": True}, "plant.parameters.mu13.value",
     r"expected a number"),
    ({"value": 0.5, "min": "low", "max": 0.9, "fit": True}, "plant.parameters.mu13.min",
     r"expected a number"),
])
def test_free_parameter_errors(entry, key, match):
    error(spec_with(plant__parameters__mu13=entry), key, match)


def test_fit_on_unknown_parameter():
    t = spec_with(plant__parameters__mu_13={"value": 0.5, "min": 0.2, "max": 0.9, "fit": True})
    err = error(t, "plant.parameters.mu_13", r"free parameter \(fit = true\) must be one of")
    assert "did you mean 'mu13'?" in str(err)
    t = spec_with(plant__parameters__mu99=0.5)
    error(t, "plant.parameters.mu99", r"unknown parameter")


def test_custom_plant_free_parameter_and_sensor_range():
    spec = parse_spec(copy.deepcopy(CUSTOM))
    assert spec.free_parameters == (FreeParameter("a", 5e-5, 1e-5, 1e-4, "m^2"),)
    assert spec.plant.outputs[0].limits == (0.0, 0.9)
    # the search box is closed: a start on min is accepted
    t = copy.deepcopy(CUSTOM)
    t["plant"]["parameters"]["a"]["value"] = 1e-5
    assert parse_spec(t).free_parameters[0].start == 1e-5


@pytest.mark.parametrize("change, key, match", [
    ({"fit": "yes"}, "plant.parameters.a.fit", "true or false"),
    ({"min": None}, "plant.parameters.a.min", "search box: give min"),
    ({"min": 2e-4}, "plant.parameters.a", r"min \(0.0002\) must be smaller than max"),
    ({"value": 2e-4}, "plant.parameters.a.value", r"above max \(0.0001\)"),
    ({"value": 1e-6}, "plant.parameters.a.value", r"below min \(1e-05\)"),
    ({"value": "5e-5"}, "plant.parameters.a.value", r"expected a number"),
])
def test_custom_free_parameter_errors(change, key, match):
    t = copy.deepcopy(CUSTOM)
    for k, v in change.items():
        if v is None:
            del t["plant"]["parameters"]["a"][k]
        else:
            t["plant"]["parameters"]["a"][k] = v
    error(t, key, match)


def test_custom_output_range_errors():
    t = copy.deepcopy(CUSTOM)
    t["plant"]["outputs"]["y"] = {"expr": "h", "min": 0.0}
    error(t, "plant.outputs.y", "both 'min' and 'max'")
    t["plant"]["outputs"]["y"] = {"expr": "h", "min": 1.0, "max": 0.5}
    error(t, "plant.outputs.y", "must be smaller than max")
    t["plant"]["outputs"]["y"] = {"expr": "h", "range": [0, 1]}
    error(t, "plant.outputs.y", r"unknown field\(s\) \['range'\]")


def test_data_table_parsed():
    t = spec_with(data={"columns": {"q1": "pump1", "h1": "level1"}, "scale": {"h1": 0.01},
                        "limits": {"h1": [0.0, 0.6]}, "states": {"h2": "h2_ref"}})
    data = parse_spec(t).data
    assert isinstance(data, DataTable)
    assert data.time == "t" and data.ts is None
    assert dict(data.columns) == {"q1": "pump1", "h1": "level1"}
    assert data.column("h1") == "level1" and data.column("h2") == "h2"
    assert data.factor("h1") == 0.01 and dict(data.limits) == {"h1": (0.0, 0.6)}
    assert dict(data.states) == {"h2": "h2_ref"}
    data = parse_spec(spec_with(data={"ts": 2.0})).data
    assert data is not None and data.ts == 2.0 and data.time is None


@pytest.mark.parametrize("data, key, match", [
    ({"colums": {}}, "data.colums", r"unknown key 'colums'; did you mean 'columns'\?"),
    ({"columns": {"h_1": "x"}}, "data.columns.h_1", r"unknown input or output .h_1.*did you mean .h1."),
    ({"columns": {"h4": "x"}}, "data.columns.h4", r"expected one of: q1, q2, h1, h2, h3"),
    ({"columns": {"q1": ""}}, "data.columns.q1", "expected a column name"),
    ({"columns": {"q1": "h1"}}, "data.columns.h1", r"column 'h1' would feed both input q1 and output h1"),
    ({"columns": "q1"}, "data.columns", "expected a table"),
    ({"scale": {"h1": 0}}, "data.scale.h1", "a scale of 0"),
    ({"scale": {"h1": "cm"}}, "data.scale.h1", "expected a number"),
    ({"scale": {"hh1": 0.01}}, "data.scale.hh1", r"did you mean 'h1'\?"),
    ({"limits": {"h1": [0.6, 0.0]}}, "data.limits.h1", "must be smaller than max"),
    ({"limits": {"q1": [0.0, 1.0]}}, "data.limits.q1", r"unknown output 'q1'"),
    ({"states": {"h5": "ref"}}, "data.states.h5", r"unknown state 'h5'"),
    ({"states": {"h2": "t"}}, "data.states.h2", r"column 't' would feed both the time and reference state h2"),
    ({"time": "t", "ts": 1.0}, "data.ts", "not both"),
    ({"ts": 0.0}, "data.ts", r"expected a number"),
    ({"time": 3}, "data.time", "expected a column name"),
])
def test_data_table_errors(data, key, match):
    error(spec_with(data=data), key, match)


def test_data_table_not_a_table():
    error(spec_with(data=[1, 2]), "data", "expected a table")


SPEC_TEXT = """
[plant]
model = "three_tank"
[plant.parameters]
mu13 = {value = 0.5, min = 0.2, max = 0.9, fit = true}
[operating_point]
x = [0.4, 0.2, 0.3]
[data]
limits = {h1 = [0.0, 0.55]}
"""


@pytest.mark.parametrize("text, key", [
    (SPEC_TEXT.replace("fit = true", 'fit = "yes"'), "plant.parameters.mu13.fit"),
    (SPEC_TEXT.replace("limits = {h1", "limits = {h_1"), "data.limits.h_1"),
])
def test_cli_check_exits_2_on_bad_free_parameter_or_data_table(tmp_path, capsys, text, key):
    from tanksynth.cli import main

    path = tmp_path / "spec.toml"
    path.write_text(text)
    code = main(["check", str(path)])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip("\n").splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and f"key '{key}'" in lines[0], err
