"""Issue 31 through the CLI: a FIFO trace, an NPZ that is not the JSON's gains (every hash
recomputed) and a 400-digit gain are each exit 2 with one line naming the file, no hang."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tanksynth
from tanksynth.artefacts.io import content_digest, file_sha256
from tanksynth.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
PACKAGE_ROOT = Path(tanksynth.__file__).resolve().parents[1]
NAME = "cascade_linear_model"

pytestmark = pytest.mark.slow     # a design and a verification, then CLI runs


@pytest.fixture(scope="module")
def verified(tmp_path_factory):
    out = tmp_path_factory.mktemp("bounded") / "out"
    assert main(["design", str(EXAMPLES / "custom_two_tank.toml"), "-o", str(out)]) == 0
    assert main(["verify", str(out)]) == 0
    return out


@pytest.fixture
def d(verified, tmp_path):
    return Path(shutil.copytree(verified, tmp_path / "out"))


def _cli(*argv: str) -> subprocess.CompletedProcess:
    """The CLI in a child process (a blocking open fails the test instead of hanging it)."""
    try:
        return subprocess.run([sys.executable, "-m", "tanksynth", *argv], capture_output=True, text=True,
                              timeout=300, env={**os.environ, "PYTHONPATH": str(PACKAGE_ROOT)})
    except subprocess.TimeoutExpired:
        pytest.fail(f"tanksynth {' '.join(argv)} hung")


def _refused(proc: subprocess.CompletedProcess, *words: str) -> None:
    err = proc.stderr.strip()
    assert proc.returncode == 2, (proc.returncode, err[-2000:])
    assert "\n" not in err and "Traceback" not in err, err
    for word in words:
        assert word in err, err


def test_report_refuses_a_fifo_trace(d):
    (d / f"{NAME}.traces.npz").unlink()
    os.mkfifo(d / f"{NAME}.traces.npz")
    _refused(_cli("report", str(d)), f"{NAME}.traces.npz", "not a regular file")


def test_verify_and_report_refuse_an_npz_that_is_not_the_json_gains(d):
    art, npz = d / f"{NAME}.json", d / f"{NAME}.npz"
    with np.load(npz) as z:
        gains = {k: z[k] for k in z.files}
    name = sorted(gains)[0]
    np.savez(npz, **{**gains, name: 100 * gains[name]})
    doc = json.loads(art.read_text())
    doc["provenance"]["npz_sha256"] = file_sha256(npz)
    doc["provenance"]["content_sha256"] = content_digest(doc)
    art.write_text(json.dumps(doc, indent=2))
    _refused(_cli("verify", str(d)), f"{NAME}.npz", f"gain {name} differs")
    _refused(_cli("report", str(d)), f"{NAME}.npz", f"gain {name} differs")


def test_a_400_digit_gain_is_exit_2_naming_the_file_and_key(d):
    art = d / f"{NAME}.json"
    doc = json.loads(art.read_text())
    name = sorted(doc["gains"])[0]
    doc["gains"][name] = 10 ** 400
    art.write_text(json.dumps(doc, indent=2))
    _refused(_cli("verify", str(d)), f"{NAME}.json", f"gains.{name}")


def test_the_next_design_removes_what_a_killed_write_left(d, capsys):
    """A kill between the NPZ and the JSON renames: the next design (under the lock) removes the
    staged files of the tool's naming, and only those."""
    (d / f"{NAME}.json").rename(d / f".{NAME}.json.tanksynth-k1ll3d_x.tmp")
    (d / f".{NAME}.npz.tanksynth-abcdefgh.tmp").write_bytes(b"partial")
    (d / "notes.tmp").write_text("mine")
    assert main(["design", str(EXAMPLES / "custom_two_tank.toml"), "-o", str(d)]) == 0
    out = capsys.readouterr().out
    assert f"removed 3 file(s) left by an interrupted run in {d}" in out, out
    assert sorted(p.name for p in d.iterdir() if p.name.endswith(".tmp")) == ["notes.tmp"]
    assert main(["verify", str(d)]) == 0
