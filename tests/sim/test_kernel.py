"""The compiled simulation kernel: same trajectories as the numpy/CasADi code and an independent
RK4, its disk cache (reused, never rebuilt), and the fallback when no compiler works."""

import os

import numpy as np
import pytest

import tanksynth.sim as sim
from tanksynth.plants import hybrid_three_tank, tank_network, three_tank
from tanksynth.plants.hybrid_three_tank import LPH
from tanksynth.sim import kernel, tape
from tanksynth.sim.integrate import Integrator
from tanksynth.sim.simulate import ParameterChange, StateJump


pytestmark = pytest.mark.slow   # every test compiles the simulator's C kernel into a private cache


def _fallback(monkeypatch, fn):
    """``fn()`` with the numpy/CasADi routes (native kernel refused), caches restored after."""
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "numpy")
    try:
        return fn()
    finally:
        monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "native")


def _inputs(plant, M, N, seed):
    rng = np.random.default_rng(seed)
    hi = np.array([b if np.isfinite(b) else 1e-4 for _, b in plant.input_limits])
    U = rng.uniform(-0.1, 1.1, (N, M, plant.m)) * hi
    lo_x, hi_x = plant.state_bounds()
    top = np.where(np.isfinite(hi_x), hi_x, 1.0)
    x0 = rng.uniform(0.0, 1.0, (M, plant.n)) * top
    x0[0] = 0.0                                              # empty tanks: clipping at 0
    if M > 1:
        x0[1] = 1e-3 * top                                   # draining: RK4 overshoots 0
        U[:, 1] = 0.0
    return x0, U


def _independent_rk4(plant, x0, U, ts, substeps):
    """RK4 of the CasADi plant (not the generated code), clipped like the integrator."""
    f = plant.compiled.f
    lo, hi = plant.state_bounds()
    ulo, uhi = plant.input_limits.T
    clip = lambda v: np.minimum(np.maximum(v, lo), hi)  # noqa: E731
    h = ts / substeps
    out = np.empty((U.shape[1], U.shape[0] + 1, plant.n))
    for r in range(U.shape[1]):
        x = clip(np.asarray(x0[r], dtype=float))
        out[r, 0] = x
        for k in range(U.shape[0]):
            u = np.clip(U[k, r], ulo, uhi)
            rhs = lambda v: np.asarray(f(clip(v), u)).ravel()  # noqa: E731
            for _ in range(substeps):
                k1 = rhs(x)
                k2 = rhs(x + h / 2 * k1)
                k3 = rhs(x + h / 2 * k2)
                k4 = rhs(x + h * k3)
                x = clip(x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))
            out[r, k + 1] = x
    return out


@pytest.mark.parametrize("plant", [three_tank(), tank_network(6)], ids=["three_tank", "network"])
def test_native_and_fallback_agree_with_an_independent_rk4(cache, monkeypatch, plant):
    x0, U = _inputs(plant, 11, 40, 1)                      # one block of 8 and 3 single runs
    native = sim.simulate_inputs(plant, x0, U, 2.0, substeps=3)
    fallback = _fallback(monkeypatch, lambda: sim.simulate_inputs(plant, x0, U, 2.0, substeps=3))
    assert native.backend == "native" and fallback.backend in ("casadi", "numpy")
    ref = _independent_rk4(plant, x0, U, 2.0, 3)
    assert np.max(np.abs(native.x - ref)) < 1e-12
    assert np.max(np.abs(fallback.x - ref)) < 1e-12
    assert np.array_equal(native.x, fallback.x)            # same operations, same order
    assert (native.clipped_low, native.clipped_high) == (fallback.clipped_low, fallback.clipped_high)
    assert native.clipped_low + native.clipped_high > 0     # clipping exercised


@pytest.mark.parametrize("M", [1, 9, 130])                 # CasADi (<= 96 runs) and numpy fallback
def test_hybrid_switching_native_equals_the_numpy_event_location(cache, monkeypatch, M):
    plant = hybrid_three_tank()
    rng = np.random.default_rng(M)
    x0 = rng.uniform(0.0, 0.55, (M, 3))
    U = rng.uniform(-0.1, 1.2, (150, M, 2)) * 240 * LPH     # fills and drains through h0
    native = sim.simulate_inputs(plant, x0, U, 1.0, substeps=4)
    fallback = _fallback(monkeypatch, lambda: sim.simulate_inputs(plant, x0, U, 1.0, substeps=4))
    assert native.backend == "native"
    assert native.events > 0 and native.events == fallback.events   # crossings located, all
    assert np.max(np.abs(native.x - fallback.x)) < 1e-12
    assert np.array_equal(native.x, fallback.x) and np.array_equal(native.modes, fallback.modes)
    assert (native.clipped_low, native.clipped_high) == (fallback.clipped_low, fallback.clipped_high)


def test_closed_loop_noise_faults_and_jumps_native_equals_fallback(cache, monkeypatch):
    """Period by period (noise, per-run parameters, a fault, a jump) on the hybrid plant."""
    plant = hybrid_three_tank()
    M = 13
    k1 = plant.parameter_values[plant.p["k1"]]
    kw = dict(ts=0.5, steps=200, x0=[0.297, 0.29, 0.25], seeds=sim.run_seeds(3, M),
              controller=lambda xh, r, t: np.column_stack([(0.30 - xh[:, 2]) * 1e-3 + 1e-4,
                                                           np.full(xh.shape[0], 100 * LPH)]),
              process_std=2e-4, measurement_std=1e-3, substeps=3,
              parameters={"k1": np.linspace(0.8, 1.2, M) * k1},
              changes=[ParameterChange(80, {"k2": 0.5 * plant.parameter_values[plant.p["k2"]]})],
              jumps=[StateJump(120, (0.05, 0.0, -0.05))])
    native = sim.simulate(plant, **kw)
    fallback = _fallback(monkeypatch, lambda: sim.simulate(plant, **kw))
    assert native.backend == "native" and "native" not in fallback.backend
    assert native.events > 0
    for key in ("x", "y", "u", "modes"):
        assert np.array_equal(getattr(native, key), getattr(fallback, key)), key
    assert (native.events, native.clipped_low, native.clipped_high) == \
        (fallback.events, fallback.clipped_low, fallback.clipped_high)
    again = sim.simulate(plant, **kw)                      # same seeds: bit for bit
    assert np.array_equal(again.x, native.x) and np.array_equal(again.y, native.y)


def test_a_run_does_not_depend_on_its_batch(cache):
    """Vectorised blocks of runs and single runs give the same numbers."""
    plant = hybrid_three_tank()
    x0, U = _inputs(plant, 19, 60, 4)
    batch = sim.simulate_inputs(plant, x0, U, 1.0, substeps=2)
    for r in (0, 7, 8, 18):
        one = sim.simulate_inputs(plant, x0[r:r + 1], U[:, r:r + 1], 1.0, substeps=2)
        assert np.array_equal(one.x[0], batch.x[r])


def test_kernel_is_built_once_then_reused_from_disk(cache):
    plant = three_tank()
    before = kernel.cache_info()["compiles"]
    first = kernel.native_kernel(tape.numpy_model(plant))
    assert first is not None and kernel.cache_info()["compiles"] == before + 1
    assert first.path.parent == cache / "sim" and first.compile_seconds > 0
    mtime = os.stat(first.path).st_mtime_ns
    assert kernel.native_kernel(tape.numpy_model(plant)) is first        # in memory
    tape.clear_cache()
    kernel.clear_cache()                                     # a new process, in effect
    second = kernel.native_kernel(tape.numpy_model(plant))
    assert second is not None and second is not first and second.path == first.path
    assert kernel.cache_info()["compiles"] == before + 1 and second.compile_seconds == 0
    assert os.stat(second.path).st_mtime_ns == mtime       # not rebuilt
    assert kernel.clear_cache(disk=True)["files"] == 1 and not first.path.exists()
    assert not list((cache / "sim").glob(".build-*"))      # no temporary left behind


@pytest.mark.parametrize("cc, reason", [("/bin/false", "unavailable"),
                                        ("/nonexistent/cc", "no C compiler")])
def test_broken_compiler_falls_back_with_a_diagnostic(cache, monkeypatch, caplog, cc, reason):
    plant = tank_network(4)
    x0, U = _inputs(plant, 3, 20, 2)
    good = sim.simulate_inputs(plant, x0, U, 1.0, substeps=2)
    assert good.backend == "native"
    monkeypatch.setenv("TANKSYNTH_CC", cc)
    tape.clear_cache()
    kernel.clear_cache()
    with caplog.at_level("INFO", logger="tanksynth.sim"):
        res = sim.simulate_inputs(plant, x0, U, 1.0, substeps=2)
    assert res.backend in ("casadi", "numpy")
    assert reason in kernel.kernel_status() and reason in caplog.text
    assert np.array_equal(res.x, good.x)
    assert Integrator.for_plant(plant).native(2) is None
    assert kernel.cache_info()["loaded"] == 0 and kernel.cache_info()["failed"] >= (cc == "/bin/false")


def test_auto_compiles_only_when_it_pays_or_is_already_built(cache, monkeypatch):
    plant = three_tank()
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "auto")
    before = kernel.cache_info()["compiles"]
    xs, Us = _inputs(plant, 2, 10, 3)
    small = sim.simulate_inputs(plant, xs, Us, 1.0, substeps=2)          # 40 run-steps
    assert small.backend != "native" and "not built" in kernel.kernel_status()
    assert kernel.cache_info()["compiles"] == before
    xl, Ul = _inputs(plant, 400, 500, 3)                                 # 800,000 run-steps
    large = sim.simulate_inputs(plant, xl, Ul, 1.0, substeps=4)
    assert large.backend == "native" and kernel.cache_info()["compiles"] == before + 1
    tape.clear_cache()
    kernel.clear_cache()
    again = sim.simulate_inputs(plant, xs, Us, 1.0, substeps=2)          # small, but built
    assert again.backend == "native" and kernel.cache_info()["compiles"] == before + 1
    assert np.array_equal(again.x, small.x)


def test_concurrent_processes_build_one_library_safely(cache):
    """Two interpreters building the same kernel at once: both run, one library, no temporaries."""
    import subprocess
    import sys

    code = ("import numpy as np; from tanksynth.plants import tank_network; "
            "from tanksynth.sim import simulate_inputs; p = tank_network(4); "
            "r = simulate_inputs(p, np.full((3, 4), 0.2), np.full((30, 2), 1e-5), 1.0); "
            "print(r.backend, repr(float(r.x.sum())))")
    env = {**os.environ, "TANKSYNTH_CACHE_DIR": str(cache), "TANKSYNTH_SIM_BACKEND": "native"}
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-500:] for o in outs]
    assert outs[0][0] == outs[1][0] and outs[0][0].startswith("native ")
    assert len(list((cache / "sim").glob("tk_sim_*.so"))) == 1
    assert not list((cache / "sim").glob(".build-*"))


def test_package_clear_cache_with_disk_deletes_the_simulator_kernels(cache, monkeypatch):
    import tanksynth

    monkeypatch.delenv("TANKSYNTH_CACHE", raising=False)    # the estimators' kernels: here too
    plant = three_tank()
    lib = kernel.native_kernel(tape.numpy_model(plant))
    assert lib is not None and lib.path.exists() and kernel.cache_info()["loaded"] >= 1
    kept = tanksynth.clear_cache()                           # memory only: the library stays
    assert kept["sim_native_loaded"] >= 1 and kept["sim_native_files"] == 0 and lib.path.exists()
    kernel.native_kernel(tape.numpy_model(plant))            # loaded again from disk
    dropped = tanksynth.clear_cache(disk=True)
    assert dropped["sim_native_loaded"] == 1 and dropped["sim_native_files"] == 1
    assert not lib.path.exists() and not list((cache / "sim").glob("tk_sim_*.so"))
    assert kernel.cache_info()["loaded"] == 0
