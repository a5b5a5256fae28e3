"""The runtime's caches (native kernels on disk and in memory, per-plant model pieces):
documented location, cleared by `tanksynth.runtime.clear_cache`, rebuilt bit for bit."""

import shutil

import numpy as np
import pytest

import tanksynth.runtime as runtime
from tanksynth.plants import hybrid_three_tank
from tanksynth.runtime.estimators import ExtendedKalmanFilter, KalmanTuning
from tanksynth.runtime.estimators.kernels import cache_dir

TUNING = dict(Q=1e-7 * np.eye(3), R=[[1e-6]], P0=1e-2 * np.eye(3), x0=[0.3, 0.3, 0.3], ts=1.0)


def _run(plant, backend):
    ekf = ExtendedKalmanFilter(plant, KalmanTuning(**TUNING), backend=backend)
    Y = 0.3 + 1e-3 * np.sin(np.arange(30))[:, None]
    return ekf.backend, ekf.run(Y, np.full((30, 2), 2.7e-5))


def test_cache_directory_is_documented_and_configurable(tmp_path, monkeypatch):
    monkeypatch.setenv("TANKSYNTH_CACHE", str(tmp_path / "k"))
    assert cache_dir() == tmp_path / "k"
    monkeypatch.delenv("TANKSYNTH_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "tanksynth" / "kernels"
    assert runtime.cache_info()["native_directory"] == str(tmp_path / "xdg" / "tanksynth" / "kernels")


def test_clear_cache_then_rebuild_vm():
    plant = hybrid_three_tank()
    _, before = _run(plant, "vm")
    assert runtime.cache_info()["plants"] >= 1               # the regularised Jacobian, compiled
    out = runtime.clear_cache()
    assert out["plants"] >= 1 and runtime.cache_info()["plants"] == 0
    _, after = _run(plant, "vm")
    assert runtime.cache_info()["plants"] == 1
    np.testing.assert_array_equal(after, before)


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None,
                    reason="no C compiler")
def test_clear_cache_then_rebuild_native(tmp_path, monkeypatch):
    monkeypatch.setenv("TANKSYNTH_CACHE", str(tmp_path))
    runtime.clear_cache()
    plant = hybrid_three_tank()
    backend, before = _run(plant, "native")
    assert backend == "native"
    libs = sorted(p.name for p in tmp_path.glob("tk_*.so"))
    assert libs and runtime.cache_info()["native_loaded"] >= 1
    out = runtime.clear_cache(disk=True)
    assert out["native_files"] == len(libs) and not list(tmp_path.glob("tk_*.so"))
    assert runtime.cache_info()["native_loaded"] == 0
    backend, after = _run(plant, "native")                   # compiled again, same library name
    assert backend == "native" and sorted(p.name for p in tmp_path.glob("tk_*.so")) == libs
    np.testing.assert_array_equal(after, before)
