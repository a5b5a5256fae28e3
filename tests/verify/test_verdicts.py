"""Per-method verdicts and `tanksynth verify DIR`."""

import hashlib
import json
from dataclasses import replace
import shutil
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact
from tanksynth.artefacts.io import rehash
from tanksynth.cli import main
from tanksynth.errors import ArtefactError
from tanksynth.methods import METHODS, verify_directory
from tanksynth.verify import runner

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


pytestmark = pytest.mark.slow   # every test uses a designed example and verifies it


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    out = tmp_path_factory.mktemp("artefacts")
    for name in ("hybrid_three_tank", "seed004_fault_detection"):
        assert main(["design", str(EXAMPLES / f"{name}.toml"), "-o", str(out / name)]) == 0
    return out


def _copy(designed, name, tmp_path):
    return Path(shutil.copytree(designed / name, tmp_path / name))


def test_linearize_verdict_passes_and_is_recorded(designed, tmp_path, capsys):
    d = _copy(designed, "hybrid_three_tank", tmp_path)
    before = json.loads((d / "hybrid_linear_model.json").read_text())
    assert main(["verify", str(d), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    art = report["artefacts"][0]
    assert art["passed"] is True
    names = {c["check"] for c in art["checks"]}
    assert {"jacobian_recheck", "zoh_consistency", "equilibrium", "first_order_agreement",
            "rank_observability"} <= names
    doc = read_artefact(d / "hybrid_linear_model.json")     # gains hash still valid
    assert doc["verification"]["passed"] is True
    after = json.loads((d / "hybrid_linear_model.json").read_text())
    assert after["gains"] == before["gains"] and after["provenance"] == before["provenance"]
    first = next(c for c in art["checks"] if c["check"] == "first_order_agreement")
    errs = first["data"]["relative_errors"]
    assert errs[0] > errs[1] > errs[2] and min(first["data"]["orders"]) > 0.8


def test_every_artefact_gets_a_decided_verdict(designed, tmp_path):
    d = _copy(designed, "seed004_fault_detection", tmp_path)
    verdicts = {v.name: v for v in verify_directory(d)}
    assert verdicts["hydraulic_linear_model"].passed is True      # linear plant: exact agreement
    assert all(v.passed in (True, False) for v in verdicts.values())


def test_unknown_method_is_refused_and_nothing_written(designed, tmp_path, capsys):
    d = _copy(designed, "hybrid_three_tank", tmp_path)
    path = d / "hybrid_linear_model.json"
    _rehash(path, lambda doc: doc.update(method="evil"))
    assert main(["verify", str(d)]) == 2
    assert "unknown design method 'evil'" in capsys.readouterr().err
    assert json.loads(path.read_text())["verification"] is None


def test_a_verdict_that_decides_nothing_fails(designed, tmp_path):
    from tanksynth.analysis.checks import Check

    d = _copy(designed, "hybrid_three_tank", tmp_path)
    undecided = {**METHODS, "linearize": replace(METHODS["linearize"],
                                                 verdict=lambda doc, spec: [Check("x", None, "info")])}
    verdicts = runner.verify_directory(d, undecided)
    assert verdicts and all(v.passed is False for v in verdicts)


def _rehash(path, mutate):
    doc = json.loads(path.read_text())
    mutate(doc)
    path.write_text(json.dumps(doc))
    rehash(path)     # every digest (gains, NPZ, content) recomputed: consistently written


def test_wrong_linearisation_fails_with_exit_1(designed, tmp_path, capsys):
    d = _copy(designed, "hybrid_three_tank", tmp_path)

    def scale_f(doc):  # F 50 % off, Ad and Bd its consistent ZOH: a wrong but coherent model
        from tanksynth.analysis.linearize import discretize_zoh

        F = np.asarray(doc["gains"]["F"]) * 1.5
        Ad, Bd = discretize_zoh(F, np.asarray(doc["gains"]["B"]), 1.0)
        doc["gains"].update(F=F.tolist(), Ad=Ad.tolist(), Bd=Bd.tolist())
    _rehash(d / "hybrid_linear_model.json", scale_f)   # consistent hash: a wrong design, not tampering
    assert main(["verify", str(d)]) == 1
    doc = read_artefact(d / "hybrid_linear_model.json")
    failed = {c["check"] for c in doc["verification"]["checks"] if c["passed"] is False}
    assert failed == {"jacobian_recheck", "first_order_agreement"}


def test_tampered_or_foreign_artefact_is_refused_with_exit_2(designed, tmp_path, capsys):
    d = _copy(designed, "hybrid_three_tank", tmp_path)
    path = d / "hybrid_linear_model.json"
    doc = json.loads(path.read_text())
    doc["gains"]["F"][0][0] *= 1.001
    path.write_text(json.dumps(doc))
    assert main(["verify", str(d)]) == 2
    assert "provenance" in capsys.readouterr().err
    assert json.loads(path.read_text())["verification"] is None     # nothing written
    e = _copy(designed, "hybrid_three_tank", tmp_path / "other")
    (e / "spec.toml").write_text((e / "spec.toml").read_text() + "\n# edited\n")
    with pytest.raises(ArtefactError, match="another spec"):
        verify_directory(e)
    assert main(["verify", str(tmp_path / "missing")]) == 2


def test_verify_stores_traces_beside_artefacts(designed, tmp_path, monkeypatch):
    from tanksynth.analysis.checks import Check
    from tanksynth.artefacts.traces import read_trace

    d = _copy(designed, "seed004_fault_detection", tmp_path)
    before = {p.name: p.read_bytes() for p in d.glob("*.json") if "gains" in json.loads(p.read_bytes())}
    verify_directory(d)
    obs = read_trace(d / "luenberger_canonical.traces.npz")
    assert obs is not None and "x_hat" in obs["arrays"]
    assert obs["header"]["check"] == "observer_convergence" and obs["header"]["verdict_passed"] is True
    lin = read_trace(d / "hydraulic_linear_model.traces.npz")
    assert lin is not None and "x_hat" not in lin["arrays"]
    for name in before:  # gains and provenance untouched; the trace is not in the JSON, its sha256 is
        after = json.loads((d / name).read_text())
        assert after["gains"] == json.loads(before[name])["gains"]
        assert "traces" not in json.dumps({k: v for k, v in after.items() if k != "verification"})
        trace = d / f"{after['name']}.traces.npz"
        assert after["verification"].get("traces_sha256") == (
            hashlib.sha256(trace.read_bytes()).hexdigest() if trace.exists() else None)
        read_artefact(d / name)
    assert not list(d.glob(".*.tmp"))
    # a verdict that simulates nothing leaves no (stale) trace
    no_sim = {**METHODS, "canonical_observer": replace(METHODS["canonical_observer"],
                                                       verdict=lambda doc, spec: [Check("x", True, "")])}
    runner.verify_directory(d, no_sim)
    assert not (d / "luenberger_canonical.traces.npz").exists()
    assert "traces_sha256" not in json.loads((d / "luenberger_canonical.json").read_text())["verification"]
    assert (d / "hydraulic_linear_model.traces.npz").exists()


def test_verify_on_a_scheduler_stores_the_same_traces(designed, tmp_path):
    distributed = pytest.importorskip("distributed")
    from tanksynth.artefacts.traces import read_trace

    local = _copy(designed, "seed004_fault_detection", tmp_path / "local")
    remote = _copy(designed, "seed004_fault_detection", tmp_path / "remote")
    verify_directory(local)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:
        verify_directory(remote, scheduler=cluster.scheduler_address)
    for name in ("luenberger_canonical", "hydraulic_linear_model"):
        a, b = (read_trace(x / f"{name}.traces.npz") for x in (local, remote))
        assert a["header"] == b["header"]
        for key in a["arrays"]:
            np.testing.assert_array_equal(a["arrays"][key], b["arrays"][key])
