"""Certified-region figure of the Takagi-Sugeno PDC designs (tanksynth.reports.ts_figures)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tanksynth.cli import main
from tanksynth.reports import read_report_inputs
from tanksynth.reports.ts_figures import ellipse_outline, region_figure, region_figures

ROOT = Path(__file__).resolve().parents[2]


def test_ellipse_outline_lies_on_the_level_set():
    M = np.array([[3.0, 1.0], [1.0, 2.0]])
    pts = ellipse_outline(M, 0.5, np.array([0.4, 0.2]), points=50)
    e = pts - [0.4, 0.2]
    assert np.allclose(np.einsum("mi,ij,mj->m", e, M, e), 0.5)


def test_other_methods_have_no_region_figure(tmp_path):
    art = {"name": "k", "method": "pole_placement", "gains": {"K": [[1.0]]}, "diagnostics": {}}
    assert region_figure(art, tmp_path, tmp_path / "f", "region-00-k") is None


@pytest.fixture(scope="module")
def pdc_dir(tmp_path_factory):
    text = (ROOT / "examples" / "three_tank_ts_control.toml").read_text(encoding="utf-8")
    text = text[:text.index('name = "pdc_output"')].rsplit("[[design]]", 1)[0]   # the PDC only
    spec = tmp_path_factory.mktemp("spec") / "pdc.toml"
    spec.write_text(text, encoding="utf-8")
    out = tmp_path_factory.mktemp("run") / "pdc"
    assert main(["run", str(spec), "-o", str(out)]) == 0
    return out


@pytest.mark.slow
def test_report_has_the_region_figure(pdc_dir):
    tex = (pdc_dir / "report.tex").read_text(encoding="utf-8")
    assert "report-figures/region-00-pdc.pdf" in tex
    assert (pdc_dir / "report-figures" / "region-00-pdc.pdf").read_bytes().startswith(b"%PDF")
    figs = region_figures(read_report_inputs(pdc_dir))
    cap = figs["pdc"].caption
    assert "set-point" in cap and "trajectories" in cap and "c = 1" in cap


@pytest.mark.slow
def test_region_figure_without_a_trace_says_so(pdc_dir, tmp_path):
    inputs = read_report_inputs(pdc_dir)
    art = next(a for a in inputs.artefacts if a["name"] == "pdc")
    fig = region_figure(art, tmp_path, tmp_path / "figs", "region-00-pdc")   # no trace there
    assert fig is not None and "no verdict trace" in fig.caption
    assert fig.path.read_bytes().startswith(b"%PDF")


@pytest.mark.slow
def test_region_figure_shows_its_legend_and_labels(pdc_dir, tmp_path):
    import shutil
    import subprocess

    if not shutil.which("pdftotext"):
        pytest.skip("pdftotext not installed")
    inputs = read_report_inputs(pdc_dir)
    art = next(a for a in inputs.artefacts if a["name"] == "pdc")
    fig = region_figure(art, pdc_dir, tmp_path / "figs", "region-00-pdc")
    text = " ".join(subprocess.run(["pdftotext", "-raw", str(fig.path), "-"], capture_output=True, text=True,
                                   check=True).stdout.split())
    for words in ("TS domain", "verdict trajectories", "sampled initial states", "region (projection)",
                  "operating point x0", "set-point runs", "h1 [m]", "h2 [m]"):
        assert words in text, words
