"""Per-method verdicts and `tanksynth verify DIR`."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefact import gains_digest, read_artefact
from tanksynth.cli import main
from tanksynth.errors import ArtefactError
from tanksynth.verify.verdicts import VERDICTS, verify_directory

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


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


def test_method_without_verdict_is_not_a_pass(designed, tmp_path):
    d = _copy(designed, "seed004_fault_detection", tmp_path)
    verdicts = {v.name: v for v in verify_directory(d)}
    assert verdicts["hydraulic_linear_model"].passed is True      # linear plant: exact agreement
    canon = verdicts["luenberger_canonical"]
    if "canonical_observer" not in VERDICTS:
        assert canon.passed is None
        assert canon.checks[0].detail == "no verification defined for method canonical_observer"


def _rehash(path, mutate):
    doc = json.loads(path.read_text())
    mutate(doc)
    doc["provenance"]["gains_sha256"] = gains_digest({k: np.asarray(v) for k, v in doc["gains"].items()})
    path.write_text(json.dumps(doc))


def test_wrong_linearisation_fails_with_exit_1(designed, tmp_path, capsys):
    d = _copy(designed, "hybrid_three_tank", tmp_path)

    def scale_f(doc):  # F 50 % off, Ad and Bd its consistent ZOH: a wrong but coherent model
        from tanksynth.design.linearize import discretize_zoh

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
