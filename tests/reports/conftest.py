"""Shared fixtures for the report tests: result directories built once per session."""

from __future__ import annotations

from pathlib import Path

import pytest

from tanksynth.cli import main


@pytest.fixture(scope="session")
def demo_dir(tmp_path_factory) -> Path:
    """`tanksynth run` on the seed 000 linearisation (examples/seed000_three_tank.toml): report.tex."""
    d = tmp_path_factory.mktemp("demo")
    spec = Path(__file__).resolve().parents[2] / "examples" / "seed000_three_tank.toml"
    assert main(["run", str(spec), "-o", str(d), "--no-pdf"]) == 0
    return d


_ROOT = Path(__file__).resolve().parents[2]
#: Example reports built to PDF once per session (kept few: the suite time stays modest).
PDF_EXAMPLES = ("seed000_pole_placement", "seed002_estimators", "custom_two_tank")


@pytest.fixture(scope="session")
def example_pdfs(tmp_path_factory) -> dict[str, Path]:
    """`tanksynth run EXAMPLE --pdf` for each of `PDF_EXAMPLES`: name -> result directory.

    Skipped (with the reason) when pdflatex/pdftotext are not installed.
    """
    import shutil

    if not all(shutil.which(t) for t in ("pdflatex", "latexmk", "pdftotext")):
        pytest.skip("pdflatex/latexmk/pdftotext not installed (make tex)")
    out = {}
    for name in PDF_EXAMPLES:
        d = tmp_path_factory.mktemp(name)
        assert main(["run", str(_ROOT / "examples" / f"{name}.toml"), "-o", str(d), "--pdf"]) == 0
        assert (d / "report.pdf").is_file()
        out[name] = d
    return out
