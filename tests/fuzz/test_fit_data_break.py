"""Adversarial inputs of issue 27 (logged data, ``tanksynth fit``, ``tanksynth replay``,
``uncertain = "fit"``): each one a case that misbehaved before its fix (an internal error, a
wasted fit, a partial directory, a box from another plant)."""

from __future__ import annotations

import json
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from fit_data import spec_text, write_log  # noqa: E402

from tanksynth.cli import main  # noqa: E402
from tanksynth.errors import DataError, SpecError  # noqa: E402
from tanksynth.methods import parse_spec_text  # noqa: E402

FIT = """
[[design]]
name = "fit"
method = "fit"
data = ["est.csv"]
starts = 1
"""


def _plant():
    return parse_spec_text(spec_text(free=False)).plant


def _csv(path: Path, t, rows) -> Path:
    """``t, q1, q2, h1, h2`` rows (q in m^3/s, h in m)."""
    lines = ["t,q1,q2,h1,h2"] + [f"{float(tk)!r},{q1!r},{q2!r},{h1},{h2}"
                                 for tk, (q1, q2, h1, h2) in zip(t, rows)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _rows(n):
    return [(3e-5, 3e-5, 0.30 + 1e-4 * k, 0.10) for k in range(n)]


def _fit(tmp_path, capsys, spec: str, *extra):
    (tmp_path / "spec.toml").write_text(spec)
    code = main(["fit", str(tmp_path / "spec.toml"), "-o", str(tmp_path / "out"), *map(str, extra)])
    return code, capsys.readouterr()


# ----------------------------------------------------------------- time column
@pytest.mark.parametrize("t, words", [
    (np.r_[np.arange(50.0), 1e9 + np.arange(50.0)], "longer than 1e+06 s"),   # a huge gap
    (2.0 * np.arange(100) + np.r_[np.zeros(60), 5000.0 * np.ones(40)], "a gap in the log"),
    (1e300 + 1e290 * np.arange(100), "longer than 1e+06 s"),                  # not seconds
    (1e-300 * np.arange(100), "shorter than 1e-09 s"),                        # not seconds
])
def test_time_steps_a_model_cannot_bridge_are_refused(tmp_path, t, words):
    # before: read as is; the fit's RK4 over the gap gave NaN, an SVD error (exit 4) or a
    # non-finite covariance refused at the write (exit 2, data/ left)
    from tanksynth.measurements import read_experiments

    path = _csv(tmp_path / "log.csv", t, _rows(len(t)))
    with pytest.raises(DataError) as err:
        read_experiments([path], _plant())
    text = str(err.value)
    assert words in text and "time column 't'" in text and "row " in text and "log.csv" in text


def test_a_regular_log_with_jitter_still_reads(tmp_path):
    from tanksynth.measurements import read_experiments

    t = np.cumsum(np.r_[0.0, np.random.default_rng(0).uniform(0.5, 3.5, 99)])
    (e,) = read_experiments([_csv(tmp_path / "log.csv", t, _rows(100))], _plant())
    assert e.samples == 100


# ----------------------------------------------------------------- data a fit cannot learn from
def test_every_sample_censored_is_bad_input_before_the_fit(tmp_path, capsys):
    # before: the fit ran on nothing observed: NaN Jacobian, "internal error: LinAlgError" (exit 4)
    _csv(tmp_path / "est.csv", np.arange(100.0), [(3e-5, 3e-5, 0.55, 0.55)] * 100)
    spec = spec_text(FIT).replace("[operating_point]", "[data]\nlimits = {h1 = [0.0, 0.55], "
                                  "h2 = [0.0, 0.55]}\n[operating_point]")
    code, out = _fit(tmp_path, capsys, spec)
    assert code == 2, out.err
    line = out.err.strip()
    assert "\n" not in line and "est.csv" in line and "no output sample to fit" in line
    assert not (tmp_path / "out" / "fit.json").exists()
    assert not (tmp_path / "out" / "data").exists()


def test_fewer_observed_values_than_unknowns_is_bad_input_before_the_fit(tmp_path, capsys):
    # 3 samples x 2 outputs = 6 values for 3 parameters + 3 initial states: before, IPOPT ran
    # its 500 iterations and the design was refused (exit 3) after seconds
    _csv(tmp_path / "est.csv", np.arange(3.0), _rows(3))
    code, out = _fit(tmp_path, capsys, spec_text(FIT))
    assert code == 2, out.err
    assert "6 observed output value(s) for 6 unknowns" in out.err
    assert not (tmp_path / "out" / "fit.json").exists()


# ----------------------------------------------------------------- fitted.toml
def test_fitted_subtables_without_a_parent_table_give_one_parent():
    # before: "[plant.parameters]" inserted once per sub-table: the result did not parse, after
    # the fit had run (exit 2, fit.json left without its fitted.toml and report)
    from tanksynth.spec.fitted import FittedValue, fitted_spec_text

    text = ('[plant]\nmodel = "three_tank"\n'
            '[plant.parameters.mu13]\nvalue = 0.5\nmin = 0.2\nmax = 0.9\nfit = true\n'
            '[plant.parameters.mu32]  # second\nvalue = 0.5\nmin = 0.2\nmax = 0.9\nfit = true\n'
            '[sampling]\nts = 1.0\n')
    out = fitted_spec_text(text, {"mu13": FittedValue(0.51, 0.5, 0.52, 0.95),
                                  "mu32": FittedValue(0.47, 0.46, 0.48, 0.95)}, "fit.json")
    doc = tomllib.loads(out)
    assert doc["plant"]["parameters"] == {"mu13": 0.51, "mu32": 0.47}
    assert doc["sampling"] == {"ts": 1.0}


@pytest.mark.parametrize("form", [
    "mu13.value = 0.5\nmu13.min = 0.2\nmu13.max = 0.9\nmu13.fit = true\n",   # dotted keys
])
def test_a_parameter_form_fitted_toml_cannot_edit_is_refused_before_the_fit(tmp_path, capsys, form):
    # before: the fit ran, fit.json and data/ were written, then exit 2 on fitted.toml
    write_log(tmp_path / "est.csv", seed=1, samples=60)
    spec = spec_text(FIT, free=False).replace("mu13 = 0.5\n", form, 1)
    assert tomllib.loads(spec)["plant"]["parameters"]["mu13"]["fit"] is True
    code, out = _fit(tmp_path, capsys, spec)
    assert code == 2, out.err
    assert "plant.parameters.mu13" in out.err and "cannot write the fitted value" in out.err
    assert not (tmp_path / "out" / "fit.json").exists()


@pytest.mark.slow
def test_a_fitted_spec_that_does_not_load_is_not_left_behind(tmp_path, capsys):
    # a log 100x faster than the plant: mu20 runs to its bound, and the fitted values hold no
    # equilibrium at the spec's pump flows; before, fitted.toml stayed in DIR although it does
    # not load
    t = 0.001 * np.arange(200)
    _csv(tmp_path / "est.csv", t, [(3.5e-5, 3.75e-5, 0.30 + 1e-3 * k, 0.10 + 2e-3 * k)
                                   for k in range(200)])
    code, out = _fit(tmp_path, capsys, spec_text(FIT))
    if code == 2 and "fitted.toml" in out.err:
        assert not (tmp_path / "out" / "fitted.toml").exists()
    else:  # the fitted values load: then fitted.toml is there
        assert (tmp_path / "out" / "fitted.toml").exists(), out.err


# ----------------------------------------------------------------- uncertain = "fit"
def _fit_doc(plant: str) -> dict:
    return {"schema": "tanksynth.artefact/1", "name": "fit", "method": "fit", "plant": plant,
            "diagnostics": {"level": 0.95, "parameters": {"mu13": {"value": 0.5, "ci95": [0.45, 0.55]}}}}


def test_a_fit_of_another_plant_is_not_a_box(tmp_path):
    # before: any plant's fit whose parameter names this plant also has was taken as its box
    from tanksynth.spec.fit_box import read_fit_box

    plant = _plant()
    (tmp_path / "other.json").write_text(json.dumps(_fit_doc("custom_two_tank")))
    with pytest.raises(SpecError) as err:
        read_fit_box(tmp_path / "other.json", "design[0].fit", plant)
    assert "custom_two_tank" in str(err.value) and "three_tank" in str(err.value)
    (tmp_path / "same.json").write_text(json.dumps(_fit_doc(plant.name)))
    assert read_fit_box(tmp_path / "same.json", "design[0].fit", plant).box == (("mu13", 0.45, 0.55),)


# ----------------------------------------------------------------- replay trace names
def test_trace_stem_keeps_plain_names_and_bounds_the_others():
    from tanksynth.verify.replay import TRACE_STEM, trace_stem

    assert trace_stem("run_01.b-2") == "run_01.b-2"
    long = trace_stem("a" * 250)
    assert len(long) <= TRACE_STEM and long != trace_stem("a" * 251)
    assert "/" not in trace_stem("x/../y") and not trace_stem(".hidden").startswith(".")
    assert trace_stem("a__b") != "a__b"  # "<artefact>__<experiment>" stays unambiguous


@pytest.mark.slow
def test_replay_of_a_log_with_a_long_name(tmp_path, capsys):
    # before: "File name too long" (exit 2) after the first trace had been written beside the
    # previous replay.json
    spec = spec_text(free=False) + """
[[design]]
name = "ekf"
method = "ekf"
x0 = [0.35, 0.15, 0.25]
Q = 1e-9
R = 2.5e-7
P0 = 1e-3
"""
    (tmp_path / "spec.toml").write_text(spec)
    assert main(["design", str(tmp_path / "spec.toml"), "-o", str(tmp_path / "out")]) == 0
    short = write_log(tmp_path / "short.csv", seed=3, samples=60)
    long = write_log(tmp_path / ("L" * 240 + ".csv"), seed=3, samples=60)
    capsys.readouterr()
    code = main(["replay", str(tmp_path / "out"), "--data", str(short), "--data", str(long)])
    err = capsys.readouterr().err
    assert code in (0, 1), err
    doc = json.loads((tmp_path / "out" / "replay.json").read_text())
    traces = sorted(e["trace"]["file"] for e in doc["replays"])
    assert len(traces) == 2 and all((tmp_path / "out" / t).is_file() for t in traces)
    assert sorted(p.name for p in (tmp_path / "out" / "replay").iterdir()) == \
        sorted(Path(t).name for t in traces)


@pytest.mark.slow
def test_a_parameter_the_outputs_do_not_depend_on_is_printed_and_named(tmp_path, capsys):
    # hmax (the tank height) does not enter the outputs: its stderr is infinite, written "inf"
    # in fit.json; before, printing the table raised ValueError (exit 4, no verdict, no report)
    write_log(tmp_path / "est.csv", seed=1, samples=120)
    spec = spec_text(FIT, free=False).replace(
        "mu20 = 0.675\n", "mu20 = 0.675\nhmax = {value = 0.62, min = 0.5, max = 0.9, fit = true}\n", 1)
    code, out = _fit(tmp_path, capsys, spec)
    assert code in (0, 1), out.err
    assert "internal error" not in out.err and "hmax" in out.err
    row = next(line for line in out.out.splitlines() if "hmax" in line and "inf" in line)
    assert "0.5" in row and "0.9" in row
    assert (tmp_path / "out" / "report.tex").exists()
