"""Shared fixtures for the report tests: result directories built once per session."""

from __future__ import annotations

from pathlib import Path

import pytest

from tanksynth.cli import main


@pytest.fixture(scope="session")
def demo_dir(tmp_path_factory) -> Path:
    """`tanksynth run -o DIR` on the built-in demo (seed 000 linearisation): report.tex, no PDF."""
    d = tmp_path_factory.mktemp("demo")
    assert main(["run", "-o", str(d)]) == 0
    return d
