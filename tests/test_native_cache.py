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


_CUT_SHORT = """
import ctypes
from tanksynth.native_cache import NativeCache, find_compiler
cache = NativeCache("test", "tk_test_")
lib = cache.library(["twice"], lambda name: SOURCE, lambda path, name: ctypes.CDLL(str(path)),
                    find_compiler())
twice = lib.handle.tk_twice
twice.restype, twice.argtypes = ctypes.c_double, [ctypes.c_double]
print(twice(1.5), flush=True)
""".replace("SOURCE", repr(SOURCE))


@needs_cc
@pytest.mark.parametrize("keep", [0.1, 0.3, 0.6])
def test_a_library_cut_short_on_disk_is_built_again_not_loaded(tmp_path, keep):
    """A library truncated on disk (a copy or a full disk) killed the process that loaded it
    (SIGBUS in the dynamic loader, issue 29): it is compiled again instead."""
    env = {**__import__("os").environ, "TANKSYNTH_CACHE_DIR": str(tmp_path)}
    env.pop("TANKSYNTH_CC", None)
    first = subprocess.run([sys.executable, "-c", _CUT_SHORT], env=env, capture_output=True,
                           text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    libs = list((tmp_path / "test").glob("tk_test_*.so"))
    assert len(libs) == 1
    whole = libs[0].read_bytes()
    libs[0].write_bytes(whole[: int(len(whole) * keep)])
    second = subprocess.run([sys.executable, "-c", _CUT_SHORT], env=env, capture_output=True,
                            text=True, timeout=120)
    assert second.returncode == 0, (second.returncode, second.stderr[-500:])
    assert second.stdout.split()[0] == "3.0"
    assert list((tmp_path / "test").glob("tk_test_*.so")) == libs


@needs_cc
def test_another_library_under_a_kernels_name_is_refused(tmp_path, monkeypatch):
    """A file of the closed-loop kernel's name that defines no ``tk_loop`` (issue 29: an
    uncaught AttributeError): refused like a failed build, the kernel built under its other
    flag set or the loop used, with the loop's numbers."""
    import numpy as np

    from tanksynth.analysis.linearize import equilibrium_input
    from tanksynth.plants import three_tank
    from tanksynth.sim import closed_loop, kernel, tape
    from tanksynth.sim.simulate import simulate
    from tanksynth.verify.simulations import StateFeedback

    monkeypatch.setenv("TANKSYNTH_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("TANKSYNTH_CC", raising=False)
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "native")
    plant = three_tank()
    x0 = np.array([0.40, 0.20, 0.30])
    u0 = equilibrium_input(plant, x0).u0
    K = np.array([[1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0]])
    kw = dict(ts=1.0, steps=20, x0=x0 + 0.02, seeds=[0], u_init=u0)
    try:
        for clear in (tape.clear_cache, kernel.clear_cache, closed_loop.clear_cache):
            clear()
        first = simulate(plant, controller=StateFeedback(K, x0, u0), **kw)
        assert "loop" in first.backend
        files = list((tmp_path / "loop").glob("tk_loop_*.so"))
        for clear in (tape.clear_cache, kernel.clear_cache, closed_loop.clear_cache):
            clear()
        for path in files:
            path.write_bytes(_libm_bytes())
        again = simulate(plant, controller=StateFeedback(K, x0, u0), **kw)
        assert np.array_equal(again.x, first.x) and np.array_equal(again.u, first.u)
        assert "loop" in again.backend or "no tk_loop" in closed_loop.loop_status()
    finally:
        for clear in (tape.clear_cache, kernel.clear_cache, closed_loop.clear_cache):
            clear()


def _libm_bytes() -> bytes:
    """A real shared library of another name (the C maths library)."""
    import ctypes.util

    name = ctypes.util.find_library("m")
    for folder in ("/lib/x86_64-linux-gnu", "/usr/lib/x86_64-linux-gnu", "/lib64", "/usr/lib64",
                   "/lib", "/usr/lib"):
        path = __import__("pathlib").Path(folder) / (name or "libm.so.6")
        if path.is_file():
            return path.read_bytes()
    pytest.skip("no libm file found")
