"""verify/runner.py: the verification field written back into an artefact, byte for byte what
encoding the whole document gives, whatever the position of the field."""

import json

import pytest

from tanksynth.artefacts.jsontext import dumps
from tanksynth.verify.runner import _splice_top_level, _write_verification

VERDICT = {"passed": False, "checks": [{"check": "x", "passed": None, "detail": "a \"quoted\"\nline",
                                        "data": {"e": [1.0, 2.5e-17, -3.0], "empty": [], "n": None}}]}


@pytest.mark.parametrize("order", ["middle", "last", "absent", "first"])
def test_written_field_equals_the_whole_document_encoded(tmp_path, order):
    doc = {"schema": "tanksynth.artefact/1", "name": "a",
           "gains": {"K": [[1.5, -2.0], [0.1, 3e-300]]}, "diagnostics": {"note": "  \"verification\": x"}}
    if order == "middle":
        doc = {**doc, "verification": None, "provenance": {"spec_sha256": "0" * 64}}
    elif order == "last":
        doc = {**doc, "provenance": {}, "verification": {"passed": True, "checks": []}}
    elif order == "first":
        doc = {"verification": None, **doc}
    path = tmp_path / "a.json"
    path.write_text(dumps(doc) + "\n", encoding="utf-8")
    _write_verification(path, VERDICT)
    expected = dict(doc)
    expected["verification"] = VERDICT
    assert path.read_text(encoding="utf-8") == dumps(expected) + "\n"
    assert json.loads(path.read_text(encoding="utf-8")) == expected


def test_splice_needs_a_top_level_key():
    text = dumps({"a": {"verification": 1}}) + "\n"
    assert _splice_top_level(text, "verification", "2") is None      # nested only: not spliced
    assert json.loads(_splice_top_level(text, "a", "3")) == {"a": 3}


@pytest.mark.slow
def test_extra_traces_cross_the_scheduler_whole(tmp_path):
    """`verify --scheduler`: the verdicts run on a Dask worker; the trace files hold the same main
    and extra traces (the H2/H-infinity disturbance steps) as verifying in process."""
    import shutil
    from pathlib import Path

    import numpy as np

    distributed = pytest.importorskip("distributed")
    from tanksynth.artefacts.traces import read_trace
    from tanksynth.cli import main
    from tanksynth.methods import verify_directory

    example = Path(__file__).resolve().parents[2] / "examples" / "three_tank_hinf.toml"
    local = tmp_path / "local"
    assert main(["design", str(example), "-o", str(local)]) == 0
    remote = Path(shutil.copytree(local, tmp_path / "remote"))
    verify_directory(local)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:
        verify_directory(remote, scheduler=cluster.scheduler_address)
    for name in ("hinf_controller", "h2_observer"):
        a, b = (read_trace(x / f"{name}.traces.npz") for x in (local, remote))
        assert len(a["more"]) == len(b["more"]) == 1 and b["more"][0]["header"]["check"] == "disturbance_step"
        for ta, tb in [(a, b), (a["more"][0], b["more"][0])]:
            assert ta["header"] == tb["header"]
            assert set(ta["arrays"]) == set(tb["arrays"])
            for key in ta["arrays"]:
                np.testing.assert_array_equal(ta["arrays"][key], tb["arrays"][key])
