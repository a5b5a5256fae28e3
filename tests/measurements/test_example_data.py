"""The shipped fit example data: regenerated bit for bit by its script, and what its README says."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from tanksynth.measurements import read_experiments
from tanksynth.plants import three_tank

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "examples" / "data"
FILES = ("three_tank_estimation.csv", "three_tank_validation.csv")


def test_script_regenerates_the_shipped_files_bit_for_bit(tmp_path):
    subprocess.run([sys.executable, str(ROOT / "scripts" / "make_fit_example.py"), "--out", str(tmp_path)],
                   check=True, capture_output=True, timeout=120, cwd=ROOT)
    for name in FILES:
        assert (tmp_path / name).read_bytes() == (DATA / name).read_bytes(), name


def test_shipped_files_read_and_match_the_readme():
    exps = read_experiments([DATA / n for n in FILES], three_tank(), {"limits": {"h1": [0.0, 0.55]}})
    readme = (DATA / "README.md").read_text()
    for e, saturated in zip(exps, (37, 61)):
        assert e.samples == 1000 and e.uniform_period == 2.0
        assert e.output_names == ("h1", "h2", "h3")
        assert int(e.censored_high[:, 0].sum()) == saturated and f"{saturated}" in readme
        assert not e.censored_high[:, 1:].any() and not e.censored_low.any()
        # 1 mm quantisation: every level is a whole number of mm
        np.testing.assert_allclose(e.y * 1000, np.round(e.y * 1000), atol=1e-9)
        # the logged ordering (noise of 1.5 mm aside) follows h1 > h3 > h2 on average
        assert np.mean(e.y[:, 0] > e.y[:, 2]) > 0.99 and np.mean(e.y[:, 2] > e.y[:, 1]) > 0.95
    for path in (DATA / n for n in FILES):
        assert path.stat().st_size < 100_000
