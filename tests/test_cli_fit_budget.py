"""``tanksynth fit`` held to a memory budget and a time bound (issue 27, item B): a fit whose data
would exceed ``TANKSYNTH_MEMORY_BUDGET_MB`` is refused before its NLP is built, one that runs past
``max_time`` is refused saying so (exit 3 both, nothing written)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fit_data import spec_text, write_log  # noqa: E402

from tanksynth.cli import main  # noqa: E402

FIT_DESIGN = """
[[design]]
name = "fit"
method = "fit"
data = ["est.csv"]
validate = ["val.csv"]
starts = 1
"""


def _run(*args, capsys):
    code = main([str(a) for a in args])
    return code, capsys.readouterr()


def test_a_fit_over_the_memory_budget_is_refused_before_its_nlp(tmp_path, capsys, monkeypatch):
    """Issue 27 (B): 400 + 200 samples x 3 states need `fit_bytes` = 64 MiB + 5 KiB x 1800
    (about 73 MiB) > the 66 MiB budget: refused at once, exit 3, naming the samples."""
    write_log(tmp_path / "est.csv", seed=1, samples=400)
    write_log(tmp_path / "val.csv", seed=2, samples=200)
    (tmp_path / "s.toml").write_text(spec_text(FIT_DESIGN))
    monkeypatch.setenv("TANKSYNTH_MEMORY_BUDGET_MB", "66")
    code, out = _run("fit", tmp_path / "s.toml", "-o", tmp_path / "o", capsys=capsys)
    assert code == 3, out.err
    assert "600 logged samples x 3 states" in out.out and "decimate" in out.out, out.out
    assert "TANKSYNTH_MEMORY_BUDGET_MB" in out.out
    assert not (tmp_path / "o" / "fit.json").exists() and not (tmp_path / "o" / "data").exists()


@pytest.mark.slow
def test_a_fit_out_of_time_is_refused_saying_so(tmp_path, capsys):
    """Issue 27 (B): ``max_time`` bounds all the solves; a fit that runs out is refused (exit 3)."""
    for i in range(4):
        write_log(tmp_path / f"e{i}.csv", seed=i + 1, samples=1500)
    design = FIT_DESIGN.replace('["est.csv"]', '["e0.csv", "e1.csv", "e2.csv", "e3.csv"]')
    design = design.replace('validate = ["val.csv"]\n', "").replace("starts = 1", "starts = 8")
    (tmp_path / "s.toml").write_text(spec_text(design + "max_time = 1\n"))
    code, out = _run("fit", tmp_path / "s.toml", "-o", tmp_path / "o", capsys=capsys)
    assert code == 3, out.err
    assert "ran out of time (max_time = 1 s" in out.out, out.out
    assert not (tmp_path / "o" / "fit.json").exists() and not (tmp_path / "o" / "data").exists()
