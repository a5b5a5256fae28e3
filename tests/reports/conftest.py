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
