"""Shared fixtures of the adversarial tests: a small result directory built once."""

from __future__ import annotations

import shutil

import pytest

from fuzz_helpers import EXAMPLES, run


@pytest.fixture(scope="session")
def result_dir(tmp_path_factory):
    """A directory designed (and verified) from the custom two-tank example: one artefact."""
    out = tmp_path_factory.mktemp("fuzz-base") / "out"
    code, _, err, _ = run(["design", EXAMPLES / "custom_two_tank.toml", "-o", out])
    assert code == 0, err
    code, _, err, _ = run(["verify", out, "--json"])
    assert code == 0, err
    return out


@pytest.fixture
def fresh_dir(result_dir, tmp_path):
    """A private copy of `result_dir` to edit."""
    target = tmp_path / "edit"
    shutil.copytree(result_dir, target)
    return target
