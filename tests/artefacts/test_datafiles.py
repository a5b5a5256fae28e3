"""Data copies of a fit (issue 27, item C): a failure after the fit leaves the result directory as
it was, no new copy and the earlier fit's copies unchanged."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from tanksynth.artefacts.datafiles import data_copies, write_data_copies
from tanksynth.artefacts.io import write_artefact
from tanksynth.design.result import DesignResult
from tanksynth.errors import ArtefactError


def _entry(source, name):
    return {"file": f"data/{name}", "source": str(source),
            "sha256": hashlib.sha256(source.read_bytes()).hexdigest()}


def _result(cov):
    return DesignResult("fit", "fit", "three_tank", {"theta": np.array([0.5]), "covariance": cov})


def test_a_failed_artefact_write_puts_the_earlier_copies_back(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    old, new, extra = tmp_path / "old.csv", tmp_path / "new.csv", tmp_path / "extra.csv"
    old.write_text("t,h1\n0,0.1\n")
    new.write_text("t,h1\n0,0.9\n")
    extra.write_text("t,h1\n0,0.5\n")
    write_data_copies(out, [_entry(old, "log.csv")])        # an earlier fit's copy
    before = sorted(p.name for p in out.rglob("*"))
    with pytest.raises(ArtefactError, match="non-finite"):
        with data_copies(out, [_entry(new, "log.csv"), _entry(extra, "extra.csv")]):
            write_artefact(_result(np.array([[np.nan]])), out, "0" * 64)
    assert (out / "data" / "log.csv").read_text() == old.read_text()
    assert sorted(p.name for p in out.rglob("*")) == before   # no new copy, no staged file


def test_no_data_directory_is_left_by_a_failed_first_write(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    src = tmp_path / "log.csv"
    src.write_text("t,h1\n0,0.1\n")
    with pytest.raises(ArtefactError):
        with data_copies(out, [_entry(src, "log.csv")]):
            write_artefact(_result(np.array([[np.inf]])), out, "0" * 64)
    assert list(out.iterdir()) == []


def test_a_changed_source_copies_nothing(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text("t,h1\n0,0.1\n")
    b.write_text("t,h1\n0,0.2\n")
    files = [_entry(a, "a.csv"), _entry(b, "b.csv")]
    b.write_text("t,h1\n0,0.3\n")                           # changed after it was fitted
    with pytest.raises(ArtefactError, match="changed"):
        write_data_copies(out, files)
    assert not (out / "data" / "a.csv").exists()


def test_a_successful_write_keeps_the_copies(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    src = tmp_path / "log.csv"
    src.write_text("t,h1\n0,0.1\n")
    with data_copies(out, [_entry(src, "log.csv")]) as copies:
        write_artefact(_result(np.array([[1e-4]])), out, "0" * 64)
    assert copies == [out / "data" / "log.csv"] and copies[0].read_text() == src.read_text()
    assert sorted(p.name for p in (out / "data").iterdir()) == ["log.csv"]
