"""Long work is visible and library warnings do not leak raw: stage lines of ``run``,
``design`` and ``report``, one meaningful line per warning, no live display in a notebook
without ipywidgets."""

from __future__ import annotations

import warnings

import pytest
import numpy as np

from tanksynth import cli
from tanksynth.cli import main
from tanksynth.errors import TanksynthWarning

SPEC = """
title = "progress"
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "obs"
method = "pole_placement"
target = "observer"
poles = [0.5, 0.6, 0.7]
[[design]]
name = "lin"
method = "linearize"
"""


@pytest.mark.slow
def test_design_and_report_print_each_stage(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC, encoding="utf-8")
    assert main(["design", str(spec), "-o", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "- designing obs (pole_placement) [1/2]" in out
    assert "- designing lin (linearize) [2/2]" in out
    assert out.index("[1/2]") < out.index("[2/2]") < out.index("artefact: ")
    assert main(["report", str(tmp_path / "o")]) == 0
    assert "- writing the report" in capsys.readouterr().out


@pytest.mark.slow
def test_run_prints_each_stage_in_order(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC, encoding="utf-8")
    assert main(["run", str(spec), "-o", str(tmp_path / "o"), "--no-pdf"]) == 0
    out = capsys.readouterr().out
    stages = ["- rank conditions", "- designing obs", "- designing lin",
              "- verifying every artefact", "- writing the report"]
    positions = [out.index(s) for s in stages]
    assert positions == sorted(positions)


def test_library_warnings_become_one_meaningful_line(tmp_path, capsys, monkeypatch):
    import tanksynth.analysis.checks as checks

    original = checks.rank_conditions
    generated = compile("def premise(h):\n    return np.sqrt(h)\n", "<lambdifygenerated-7>", "exec")
    scope = {"np": np}
    exec(generated, scope)

    def noisy(*args, **kwargs):
        for _ in range(3):  # repeated: shown once
            scope["premise"](np.array([-1.0]))
        warnings.warn("something odd", DeprecationWarning)
        return original(*args, **kwargs)

    monkeypatch.setattr(checks, "rank_conditions", noisy)
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC, encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main(["check", str(spec)]) == 0
    out, err = capsys.readouterr()
    assert err == ""   # library warnings never reach stderr
    assert out.count("note:") == 1, out
    note = " ".join(out[out.index("note:"):].split())   # rich wraps long lines at the width
    assert "4 library warning(s) (DeprecationWarning, RuntimeWarning) were handled" in note
    assert "numerical: invalid value encountered in sqrt (in generated model code)" in note
    assert "return np.sqrt" not in out   # no generated source line
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main(["check", str(spec), "--json"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and "note:" not in out   # --json: one JSON document, nothing else


def test_ts_premises_outside_their_domain_warn_with_a_meaning():
    from tanksynth.analysis.quasi_lpv import quasi_lpv
    from tanksynth.plants import three_tank

    q = quasi_lpv(three_tank(outputs="h1h2"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        values = q.atom_values(np.array([[0.4, -0.1, 0.3], [0.4, 0.2, 0.3]]))
    assert np.isnan(values[0]).any() and np.all(np.isfinite(values[1]))
    assert [w.category for w in caught] == [TanksynthWarning]
    assert "h2 = -0.1" in str(caught[0].message) and "1 of 2 point(s)" in str(caught[0].message)


def test_no_live_display_in_a_notebook_without_ipywidgets(monkeypatch):
    import importlib.util

    monkeypatch.setattr(cli._out, "is_jupyter", False)
    assert cli._live() is True
    monkeypatch.setattr(cli._out, "is_jupyter", True)
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "ipywidgets" else real(name, *a))
    assert cli._live() is False


@pytest.mark.slow
def test_run_piped_names_no_bar_and_the_pdf_hint_follows_tex(tmp_path, capsys, monkeypatch):
    import shutil

    spec = tmp_path / "s.toml"
    spec.write_text(SPEC, encoding="utf-8")
    real_which = shutil.which
    monkeypatch.setattr(shutil, "which", lambda tool, *a, **k: f"/usr/bin/{tool}"
                        if tool in ("pdflatex", "latexmk") else real_which(tool, *a, **k))
    assert main(["run", str(spec), "-o", str(tmp_path / "o"), "--no-pdf"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("- verifying every artefact"))
    assert lines[at + 1].strip() != ""     # piped: no bar, so no empty line left behind it
    text = " ".join(out.split())           # rich wraps long paths at the console width
    assert "report.tex (add --pdf for the PDF)" in text and "needs pdflatex" not in text
    assert sum(line.startswith("artefact: ") for line in lines) == 2
    assert not any(line.startswith("wrote ") for line in lines)
    monkeypatch.setattr(shutil, "which", lambda tool, *a, **k: None)
    assert main(["report", str(tmp_path / "o")]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "report.tex (for the PDF: install pdflatex and latexmk, then --pdf)" in text


def test_verify_names_each_artefact_as_its_verdict_starts(tmp_path):
    from tanksynth.methods import verify_directory

    spec = tmp_path / "s.toml"
    spec.write_text(SPEC, encoding="utf-8")
    assert main(["design", str(spec), "-o", str(tmp_path / "o")]) == 0
    events = []
    verify_directory(tmp_path / "o", progress=lambda d, n: events.append(("done", d, n)),
                     started=lambda d, n, name, method: events.append(("start", d, n, name, method)))
    starts = [e for e in events if e[0] == "start"]
    assert sorted(e[3] for e in starts) == ["lin", "obs"]
    assert {e[3]: e[4] for e in starts} == {"obs": "pole_placement", "lin": "linearize"}
    # each start comes before its artefact's completion: start(i) then done(i + 1)
    assert [e[:3] for e in events] == [("start", 0, 2), ("done", 1, 2), ("start", 1, 2), ("done", 2, 2)]


def test_known_library_warning_is_said_by_its_meaning_raw_only_with_verbose(monkeypatch, capsys):
    def noisy(argv):
        warnings.warn("Tight layout not applied. The bottom and top margins cannot be made large "
                      "enough to accommodate all Axes decorations.", UserWarning)
        warnings.warn("zork frobnicated", FutureWarning)
        return 0

    monkeypatch.setattr(cli, "_main", noisy)
    assert cli.main(["report", "x"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "note: 2 library warning(s) (FutureWarning, UserWarning) were handled" in out
    assert "a figure's layout could not be tightened (cosmetic" in out
    assert "a FutureWarning from" in out and "--verbose" in out
    assert "Tight layout not applied" not in out and "zork" not in out
    assert cli.main(["--verbose", "report", "x"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "raw: UserWarning: Tight layout not applied." in out and "raw: FutureWarning: zork" in out


def test_an_error_naming_design_i_says_the_index_counts_from_0(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC.replace("poles = [0.5, 0.6, 0.7]", "poles = [0.5, 0.6]")
                    .replace('method = "linearize"', 'method = "linearize"\nbogus = 1'), encoding="utf-8")
    assert main(["check", str(spec), "--spec-only"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ")
    assert "design[0] = [[design]] table 1" in err and "design[1] = [[design]] table 2" in err
    assert "indices count from 0" in err
    spec.write_text(SPEC, encoding="utf-8")
    assert main(["check", str(spec), "--spec-only"]) == 0


@pytest.mark.slow
def test_run_ends_with_the_wall_time_of_each_stage(tmp_path, capsys):
    """``run`` ends with one ``times:`` line: rank checks, design, verify, report and the
    total, in seconds; each stage takes part of the total and the stages sum to at most it."""
    import re

    spec = tmp_path / "s.toml"
    spec.write_text(SPEC, encoding="utf-8")
    assert main(["run", str(spec), "-o", str(tmp_path / "o"), "--no-pdf"]) == 0
    lines = capsys.readouterr().out.splitlines()
    times = [line for line in lines if line.startswith("times: ")]
    assert len(times) == 1 and lines[-1] == times[0], lines[-3:]
    m = re.fullmatch(r"times: (.+); total (\d+\.\d) s", times[0])
    assert m, times[0]
    stages = dict(re.fullmatch(r"(.+) (\d+\.\d) s", item).groups() for item in m.group(1).split(", "))
    assert list(stages) == ["rank checks", "design", "verify", "report"]
    seconds = {k: float(v) for k, v in stages.items()}
    total = float(m.group(2))
    assert all(s >= 0 for s in seconds.values()) and total > 0
    assert sum(seconds.values()) <= total + 0.05 * len(seconds)   # each rounded to 0.1 s


def test_stage_clock_sums_a_stage_and_shows_a_part(monkeypatch):
    import types

    from tanksynth import messages
    from tanksynth.messages import StageClock

    # a clock that moves only when told: the sums are exact, whatever the machine's load
    now = [100.0]
    monkeypatch.setattr(messages, "time", types.SimpleNamespace(perf_counter=lambda: now[0]))

    def sleep(seconds):
        now[0] += seconds

    clock = StageClock()
    sleep(0.5)                                   # before any stage: in the total only
    for _ in range(2):
        with clock("design"):
            sleep(0.06)
        sleep(1.0)                               # between stages: in the total only
    try:
        with clock("report"):
            sleep(0.02)
            raise ValueError("the time of a failed stage still counts")
    except ValueError:
        pass
    clock.part("report", "LaTeX", 1.234)
    assert list(clock.seconds) == ["design", "report"]
    assert abs(clock.seconds["design"] - 0.12) < 1e-9 and abs(clock.seconds["report"] - 0.02) < 1e-9
    line = clock.line()
    assert line == "times: design 0.1 s, report 0.0 s (LaTeX 1.2 s); total 2.6 s"
