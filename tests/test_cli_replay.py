"""`tanksynth replay DIR --data FILE...` end to end: `tanksynth run` on a small EKF spec, logs
simulated from the plant with the spec's sensor noise written as CSV, the replay's exit codes and
lines, and the report's section "On measured data"."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from tanksynth.cli import main
from tanksynth.methods import load_directory
from tanksynth.sim.simulate import simulate_inputs

#: The EKF's declared sensor noise (m): R = SIGMA^2 in verify/replay_spec.toml.
SIGMA = 2e-3

#: The replay tests' spec with a [data] table: h2 is logged in the column "level2".
SPEC = ((Path(__file__).parent / "verify" / "replay_spec.toml").read_text(encoding="utf-8")
        + '\n[data]\ncolumns = {h2 = "level2"}\n')


def write_log(path, spec, *, noise=1.0, samples=400, seed=2, drop=None):
    """A CSV log (columns t, q1, q2, h1, level2) of the plant under step changes of the pumps,
    noise ``noise * SIGMA``, h1 missing (empty cells) at samples 100-104."""
    rng = np.random.default_rng(seed)
    U = np.array([3.5e-5, 3.75e-5]) * np.repeat(rng.uniform(0.6, 1.4, size=(samples // 100 + 1, 2)),
                                                 100, axis=0)[:samples]
    res = simulate_inputs(spec.plant, spec.x0, U, 1.0, substeps=4)
    Y = np.array(res.y[0, :samples]) + noise * SIGMA * rng.standard_normal((samples, 2))
    Y[100:105, 0] = np.nan
    cols = {"t": np.arange(samples) * 1.0, "q1": U[:, 0], "q2": U[:, 1], "h1": Y[:, 0], "level2": Y[:, 1]}
    if drop:
        cols.pop(drop)
    lines = [",".join(cols)]
    for k in range(samples):
        lines.append(",".join("" if np.isnan(v[k]) else repr(float(v[k])) for v in cols.values()))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def rundir(tmp_path_factory):
    root = tmp_path_factory.mktemp("cli_replay")
    (root / "spec.toml").write_text(SPEC, encoding="utf-8")
    assert main(["run", str(root / "spec.toml"), "-o", str(root / "out"), "--no-pdf"]) == 0
    spec, _ = load_directory(root / "out")
    return root, spec


@pytest.mark.slow
def test_replay_passes_then_fails_on_ten_times_the_noise(rundir, capsys):
    root, spec = rundir
    out = root / "out"
    capsys.readouterr()
    good = write_log(root / "good.csv", spec)
    assert main(["replay", str(out), "--data", str(good)]) == 0
    text = capsys.readouterr().out
    assert "ekf (ekf) on good: pass" in text and "obs (luenberger) on good: pass" in text
    assert "5 samples with outputs left out of the update (5 missing and 0 censored output values)" in text
    assert re.search(r"RMSE h1 [0-9.e+-]+ m, h2 [0-9.e+-]+ m", text), text     # with their unit
    doc = json.loads((out / "replay.json").read_text())
    assert doc["schema"] == "tanksynth.replay/1" and doc["passed"] is True
    assert [f["name"] for f in doc["files"]] == ["good"] and len(doc["files"][0]["sha256"]) == 64
    assert (out / "replay" / "ekf__good.npz").is_file()
    assert main(["replay", str(out), "--data", str(good), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["replays"][0]["summary"]["missing"] == 5

    bad = write_log(root / "bad.csv", spec, noise=10.0)
    assert main(["replay", str(out), "--data", str(bad), "--data", str(good)]) == 1
    captured = capsys.readouterr()
    assert "ekf (ekf) on bad: FAIL" in captured.out and "ekf (ekf) on good: pass" in captured.out
    assert "failed: some checks on measured data fail: ekf on bad" in captured.err
    doc = json.loads((out / "replay.json").read_text())
    nis = next(c for e in doc["replays"] if e["artefact"] == "ekf" and e["experiment"] == "bad"
               for c in e["checks"] if c["check"] == "nis_mean")
    assert nis["passed"] is False and nis["data"]["value"] > nis["data"]["band"][1]

    assert main(["report", str(out)]) == 0
    tex = (out / "report.tex").read_text()
    assert r"\section{On measured data}" in tex
    assert tex.count(r"\subsection{\texorpdfstring{\texttt{ekf} on") == 2
    assert list((out / "report-figures").glob("replay-*.pdf"))


@pytest.mark.slow
@pytest.mark.parametrize("drop, named", [("level2", "h2"), ("q2", "q2")])
def test_a_log_lacking_a_column_is_exit_2_naming_it(rundir, capsys, drop, named):
    root, spec = rundir
    log = write_log(root / f"no_{drop}.csv", spec, drop=drop)
    capsys.readouterr()
    assert main(["replay", str(root / "out"), "--data", str(log)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and named in err and f"no_{drop}.csv" in err


def test_replay_of_no_directory_is_exit_2(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "nothing"), "--data", "x.csv"]) == 2
    assert "no such result directory" in capsys.readouterr().err


@pytest.mark.slow
def test_nis_quantile_uses_the_outputs_of_each_sample(rundir, capsys, tmp_path):
    """Issue 30: the replay figure drew the NIS quantile for every output at samples where a
    missing (or censored) output was left out of the update; the trace now records each sample's
    degrees of freedom, and they add up to the band's."""
    import shutil
    import subprocess

    root, spec = rundir
    out = tmp_path / "out"
    shutil.copytree(root / "out", out)
    good = write_log(tmp_path / "good.csv", spec)
    assert main(["replay", str(out), "--data", str(good)]) == 0
    with np.load(out / "replay" / "ekf__good.npz", allow_pickle=False) as z:
        dof, nis = z["nis_dof"], z["nis"]
    assert np.all(dof[100:105] == 1)                    # h1 missing: only h2 used
    assert np.all(dof[np.isfinite(nis)] >= 1) and np.all(dof[~np.isfinite(nis)] == 0)
    assert set(np.unique(dof[np.isfinite(nis)])) == {1.0, 2.0}
    doc = json.loads((out / "replay.json").read_text())
    band = next(c for e in doc["replays"] if e["artefact"] == "ekf"
                for c in e["checks"] if c["check"] == "nis_mean")
    assert int(dof.sum()) == band["data"]["dof"]      # the same degrees of freedom as the band's
    assert main(["report", str(out)]) == 0
    capsys.readouterr()
    if shutil.which("pdftotext"):
        fig = next((out / "report-figures").glob("replay-*ekf*.pdf"))
        text = subprocess.run(["pdftotext", str(fig), "-"], capture_output=True, text=True).stdout
        assert "outputs used at each sample" in " ".join(text.split())
