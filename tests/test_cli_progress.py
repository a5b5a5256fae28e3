"""Long work is visible and library warnings do not leak raw: stage lines of ``run``,
``design`` and ``report``, one meaningful line per warning, no live display in a notebook
without ipywidgets."""

from __future__ import annotations

import warnings

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
