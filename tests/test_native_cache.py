"""The one native-compile cache (`tanksynth.native_cache`): directory, names, builds, fall-back."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys

import pytest

from tanksynth import native_cache
from tanksynth.native_cache import NativeBuildError, NativeCache, cache_root, find_compiler

needs_cc = pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None,
                              reason="no C compiler")

SOURCE = "double tk_twice(double x) { return 2.0 * x; }\n"


def _load(path, name):
    lib = ctypes.CDLL(str(path))
    lib.tk_twice.restype = ctypes.c_double
    lib.tk_twice.argtypes = [ctypes.c_double]
    return lib


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("TANKSYNTH_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("TANKSYNTH_CC", raising=False)
    return NativeCache("test", "tk_test_")


def test_directories(tmp_path, monkeypatch):
    monkeypatch.delenv("TANKSYNTH_CACHE_DIR", raising=False)
    monkeypatch.delenv("TANKSYNTH_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "xdg" / "tanksynth"
    family = NativeCache("kernels", "tk_", directory_env="TANKSYNTH_CACHE")
    assert family.directory() == tmp_path / "xdg" / "tanksynth" / "kernels"
    monkeypatch.setenv("TANKSYNTH_CACHE_DIR", str(tmp_path / "root"))
    assert family.directory() == tmp_path / "root" / "kernels"
    monkeypatch.setenv("TANKSYNTH_CACHE", str(tmp_path / "own"))
    assert family.directory() == tmp_path / "own"


def test_names_depend_on_source_compiler_and_flags(cache):
    base = cache.name(["a"], "/usr/bin/gcc", ["-O3"])
    assert base.startswith("tk_test_") and len(base) == len("tk_test_") + 24
    assert base.isidentifier()
    others = {cache.name(["b"], "/usr/bin/gcc", ["-O3"]), cache.name(["a"], "/usr/bin/cc", ["-O3"]),
              cache.name(["a"], "/usr/bin/gcc", ["-O2"])}
    assert base not in others and len(others) == 3


def test_no_compiler_is_none(monkeypatch):
    monkeypatch.setenv("TANKSYNTH_CC", "/nonexistent/cc")
    assert find_compiler() is None


@needs_cc
def test_built_once_then_loaded_from_disk(cache, tmp_path):
    cc = find_compiler()
    lib = cache.library(["twice"], lambda name: SOURCE, _load, cc)
    assert lib.handle.tk_twice(1.5) == 3.0 and lib.compile_seconds > 0
    assert lib.path.parent == tmp_path / "test" and lib.flags in native_cache.flag_sets()
    assert cache.library(["twice"], lambda name: SOURCE, _load, cc) is lib      # in memory
    assert cache.info()["compiles"] == 1 and cache.info()["files"] == 1
    cache.clear()
    again = cache.library(["twice"], lambda name: SOURCE, _load, cc, build=False)
    assert again.path == lib.path and again.compile_seconds == 0 and cache.compiles == 1
    assert not list(lib.path.parent.glob(".build-*"))
    assert cache.clear(disk=True) == {"loaded": 1, "files": 1} and not lib.path.exists()
    assert cache.library(["twice"], lambda name: SOURCE, _load, cc, build=False) is None


@needs_cc
def test_a_failed_build_is_remembered_and_says_why(cache):
    cc = find_compiler()
    with pytest.raises(NativeBuildError, match="exited with status") as first:
        cache.library(["broken"], lambda name: "this is not C", _load, cc)
    assert not first.value.repeated and cache.info()["failed"] == len(native_cache.flag_sets())
    with pytest.raises(NativeBuildError) as second:
        cache.library(["broken"], lambda name: "this is not C", _load, cc)
    assert second.value.repeated and cache.compiles == 0
    assert not list(cache.directory().glob("*.so"))


@needs_cc
def test_a_failing_loader_is_a_build_error(cache):
    def load(path, name):
        raise AttributeError("no symbol tk_run")
    with pytest.raises(NativeBuildError, match="no symbol tk_run"):
        cache.library(["twice"], lambda name: SOURCE, load, find_compiler())


@needs_cc
def test_memory_is_bounded(cache, monkeypatch):
    """Beyond MAX_LOADED libraries in memory, the oldest is forgotten (its file stays)."""
    monkeypatch.setattr(native_cache, "MAX_LOADED", 2)
    libs = [cache.library([f"twice {i}"], lambda name: SOURCE, _load, find_compiler())
            for i in range(3)]
    assert list(cache.loaded.values()) == libs[1:] and cache.info()["files"] == 3


@needs_cc
def test_concurrent_builds_compile_once(tmp_path):
    """Two processes asking for the same library: one compiler run (the lock), one file."""
    code = ("import ctypes, sys; from tanksynth.native_cache import NativeCache, find_compiler; "
            "c = NativeCache('test', 'tk_test_'); "
            f"lib = c.library(['twice'], lambda n: {SOURCE!r}, lambda p, n: ctypes.CDLL(str(p)), "
            "find_compiler()); print(c.compiles)")
    env = {"TANKSYNTH_CACHE_DIR": str(tmp_path), "PATH": "/usr/bin:/bin",
           "PYTHONPATH": ":".join(sys.path)}
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-500:] for o in outs]
    assert sorted(int(o[0]) for o in outs) == [0, 1]
    assert len(list((tmp_path / "test").glob("tk_test_*.so"))) == 1
