"""Fixtures of the simulator tests."""

import pytest

from tanksynth.sim import kernel, tape


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A private kernel cache; compiled models and loaded kernels forgotten before and after."""
    monkeypatch.setenv("TANKSYNTH_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("TANKSYNTH_CC", raising=False)
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "native")   # compile even for small simulations
    tape.clear_cache()
    kernel.clear_cache()
    yield tmp_path
    tape.clear_cache()
    kernel.clear_cache()
