"""The closed-loop kernel (`tanksynth.sim.closed_loop`) against the period-by-period loop.

The reference is the same `simulate` call with ``TANKSYNTH_SIM_BACKEND=numpy`` (no compiled
kernel at all: the law evaluated by CasADi's virtual machine or numpy each period, the plant by
its CasADi period function or generated numpy code). Measured: the kernel's states, outputs
and inputs equal to the loop's bit for bit (relative difference 0.0) for the CasADi laws;
within 1e-12 relative asked for everywhere (numpy laws may sum in another order).
"""

import logging

import numpy as np
import pytest

from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.plants import hybrid_three_tank, tank_network, three_tank
from tanksynth.runtime.laws import integral_tracking_law, inverse_dynamics_law
from tanksynth.sim import closed_loop, kernel, tape
from tanksynth.sim.simulate import ParameterChange, StateJump, simulate
from tanksynth.verify.batch_call import CasadiControlLaw, CasadiIntegralLaw
from tanksynth.verify.robust.traces import PeakRecordingLaw
from tanksynth.verify.simulations import IntegralStateFeedback, StateFeedback

TOL = 1e-12

TANK = three_tank()
X0 = np.array([0.40, 0.20, 0.30])
U0 = equilibrium_input(TANK, X0).u0


@pytest.fixture
def loop_cache(tmp_path, monkeypatch):
    """A private kernel cache, kernels built whatever the size; everything forgotten after."""
    monkeypatch.setenv("TANKSYNTH_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("TANKSYNTH_CC", raising=False)
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "native")
    for clear in (tape.clear_cache, kernel.clear_cache, closed_loop.clear_cache):
        clear()
    yield tmp_path
    for clear in (tape.clear_cache, kernel.clear_cache, closed_loop.clear_cache):
        clear()


def _tracking_law():
    """Integral tracking law on h1, h2 with saturation inside (gains making the pumps saturate)."""
    K1 = 50 * np.array([[2e-3, 3e-4, -5e-4], [3e-4, 2e-3, -5e-4]])
    K2 = 10 * np.array([[-9e-5, -3e-5], [-3e-5, -9e-5]])
    return integral_tracking_law(K1, K2, X0, U0, np.eye(3)[:2], 1.0, TANK.input_limits).law


def _reference(N, p=2):
    ref = np.tile(X0[:p], (N + 1, 1))
    ref[N // 4:] += 0.05                   # a set-point step: the pumps saturate for a while
    return ref


def _both(monkeypatch, make, **kw):
    """(kernel result, loop result, the law objects after each) of the same simulation."""
    fast_law, slow_law = make(), make()
    fast = simulate(controller=fast_law, **kw)
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "numpy")
    slow = simulate(controller=slow_law, **kw)
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "native")
    return fast, slow, fast_law, slow_law


def _rel(a, b):
    if a.size == 0:
        return 0.0
    scale = np.max(np.abs(b))
    return float(np.max(np.abs(a - b)) / scale) if scale else float(np.max(np.abs(a - b)))


def _agree(fast, slow, tol=TOL):
    assert "loop" in fast.backend and "loop" not in slow.backend
    for name in ("x", "y", "u", "x_hat", "modes"):
        a, b = getattr(fast, name), getattr(slow, name)
        assert a.shape == b.shape, name
        assert _rel(a.astype(float), b.astype(float)) <= tol, name
    assert (fast.clipped_low, fast.clipped_high) == (slow.clipped_low, slow.clipped_high)
    assert fast.timing["calls"] == slow.timing["calls"]


@pytest.mark.parametrize("runs", [1, 37])
@pytest.mark.parametrize("noise", [False, True])
def test_integral_tracking_law_equals_the_loop(loop_cache, monkeypatch, runs, noise):
    law = _tracking_law()
    N = 120
    starts = X0 + np.linspace(-0.05, 0.05, runs)[:, None]
    fast, slow, fl, sl = _both(monkeypatch, lambda: CasadiIntegralLaw(law), plant=TANK, ts=1.0,
                               steps=N, x0=starts, seeds=np.arange(runs), reference=_reference(N),
                               u_init=U0, process_std=2e-3 if noise else 0.0,
                               measurement_std=1e-3 if noise else 0.0)
    _agree(fast, slow)
    assert np.array_equal(fast.x, slow.x) and np.array_equal(fast.u, slow.u)   # measured: 0.0
    assert np.array_equal(fl.z, sl.z)            # the law's integrators end where the loop's do
    hi = TANK.input_limits[:, 1]
    assert np.any(fast.u == hi) and np.any(fast.u < hi)          # saturation active, and not always
    if noise:
        assert fast.clipped_low + fast.clipped_high > 0 or np.any(fast.y != fast.x)


def test_inverse_dynamics_law_with_changes_and_jumps(loop_cache, monkeypatch):
    law = inverse_dynamics_law(TANK, [0.05, 0.04]).law
    N = 150
    ref = np.tile(X0[:2], (N + 1, 1))
    ref[40:] += [0.03, -0.02]
    fast, slow, _, _ = _both(monkeypatch, lambda: CasadiControlLaw(law), plant=TANK, ts=1.0,
                             steps=N, x0=np.tile(X0, (5, 1)), seeds=np.arange(5), reference=ref,
                             u_init=U0, parameters={"mu13": np.linspace(0.45, 0.55, 5)},
                             changes=[ParameterChange(60, {"mu20": 0.5}),
                                      ParameterChange(N, {"mu13": 0.4})],
                             jumps=[StateJump(0, (0.01, 0, 0)), StateJump(90, (0, 0.03, 0))],
                             process_std=1e-4)
    _agree(fast, slow)
    assert np.array_equal(fast.x, slow.x)


def test_numpy_laws_on_a_sixteen_tank_network(loop_cache, monkeypatch):
    plant = tank_network(16)
    x0 = np.full(plant.n, 0.2)
    u0 = equilibrium_input(plant, x0).u0
    B = linearize(plant, x0, u0).B
    K = 50.0 * B.T
    N = 60
    starts = x0 + 0.01 * np.sin(np.arange(3 * plant.n)).reshape(3, plant.n)
    fast, slow, _, _ = _both(monkeypatch, lambda: StateFeedback(K, x0, u0), plant=plant, ts=2.0,
                             steps=N, x0=starts, seeds=np.arange(3), u_init=u0)
    _agree(fast, slow)
    C1 = np.eye(plant.n)[: plant.m]
    fast, slow, fl, sl = _both(monkeypatch, lambda: IntegralStateFeedback(
        K, -1e-3 * np.eye(plant.m), C1, x0, u0, 2.0), plant=plant, ts=2.0, steps=N, x0=starts,
        seeds=np.arange(3), u_init=u0, reference=np.tile(x0[: plant.m] + 0.01, (N + 1, 1)),
        process_std=1e-4)
    _agree(fast, slow)
    assert _rel(fl.z, sl.z) <= TOL


def test_hybrid_plant_crossings_go_back_to_the_loop(loop_cache, monkeypatch):
    """A run that changes mode inside a period: the whole simulation by the loop (located)."""
    plant = hybrid_three_tank()
    law = inverse_dynamics_law(plant, [0.05, 0.05]).law
    x_eq = np.array([0.31918677, 0.3209075, 0.30968861])
    u0 = equilibrium_input(plant, x_eq).u0
    N = 100
    ref = np.tile(x_eq[:2], (N + 1, 1))
    common = dict(plant=plant, ts=1.0, steps=N, seeds=np.arange(2), reference=ref, u_init=u0)
    # near the equilibrium, no crossing: the kernel runs the loop
    fast, slow, _, _ = _both(monkeypatch, lambda: CasadiControlLaw(law), x0=x_eq, **common)
    _agree(fast, slow)
    # from levels below the middle pipe, crossing it: the loop locates the crossings
    low = np.array([0.10, 0.35, 0.22])
    fast = simulate(controller=CasadiControlLaw(law), x0=low, **common)
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "numpy")
    slow = simulate(controller=CasadiControlLaw(law), x0=low, **common)
    assert fast.events > 0 and fast.events == slow.events
    assert "loop" not in fast.backend
    assert np.array_equal(fast.x, slow.x) and np.array_equal(fast.u, slow.u)


def test_the_kernel_is_built_once_and_reused(loop_cache, monkeypatch):
    law = _tracking_law()
    kw = dict(plant=TANK, ts=1.0, steps=50, x0=X0, reference=_reference(50), u_init=U0)
    before = closed_loop.cache_info()["compiles"]
    first = simulate(controller=CasadiIntegralLaw(law), seeds=[0], **kw)
    assert "loop" in first.backend
    assert closed_loop.cache_info()["compiles"] == before + 1
    # another batch size, another law object of the same Function: the same kernel
    again = simulate(controller=CasadiIntegralLaw(law), seeds=np.arange(9), **kw)
    assert "loop" in again.backend and np.array_equal(again.x[0], first.x[0])
    assert closed_loop.cache_info()["compiles"] == before + 1
    # in-memory caches forgotten: loaded from the disk, not compiled
    tape.clear_cache()
    closed_loop.clear_cache()
    third = simulate(controller=CasadiIntegralLaw(law), seeds=[0], **kw)
    assert "loop" in third.backend and np.array_equal(third.x, first.x)
    info = closed_loop.cache_info()
    assert info["compiles"] == before + 1 and info["files"] == 1 and info["loaded"] == 1


def test_auto_builds_only_large_simulations_and_numpy_forces_the_loop(loop_cache, monkeypatch):
    law = _tracking_law()
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "auto")
    kw = dict(plant=TANK, ts=1.0, x0=X0, u_init=U0)
    small = simulate(controller=CasadiIntegralLaw(law), seeds=[0], steps=20,
                     reference=_reference(20), **kw)
    assert "loop" not in small.backend and "not built" in closed_loop.loop_status()
    large = simulate(controller=CasadiIntegralLaw(law), seeds=np.arange(300), steps=300,
                     reference=_reference(300), **kw)
    assert "loop" in large.backend
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "numpy")
    forced = simulate(controller=CasadiIntegralLaw(law), seeds=[0], steps=20,
                      reference=_reference(20), **kw)
    assert "loop" not in forced.backend and np.array_equal(forced.x, small.x)


def test_no_compiler_falls_back_and_says_so_once(loop_cache, monkeypatch, caplog):
    monkeypatch.setenv("TANKSYNTH_CC", "/nonexistent/cc")
    closed_loop._SAID.clear()
    law = _tracking_law()
    kw = dict(plant=TANK, ts=1.0, steps=30, x0=X0, reference=_reference(30), u_init=U0, seeds=[0])
    with caplog.at_level(logging.INFO, logger="tanksynth.sim"):
        a = simulate(controller=CasadiIntegralLaw(law), **kw)
        b = simulate(controller=CasadiIntegralLaw(law), **kw)
    assert "loop" not in a.backend and np.array_equal(a.x, b.x)
    said = [r for r in caplog.records if "closed loops step period by period" in r.getMessage()]
    assert len(said) == 1


def test_threads_give_the_numbers_of_one_block(loop_cache, monkeypatch):
    """Runs cut into blocks over threads: the same numbers and clipping counts as one call."""
    law = _tracking_law()
    kw = dict(plant=TANK, ts=1.0, steps=40, x0=X0 + np.linspace(-0.1, 0.1, 45)[:, None],
              reference=_reference(40), u_init=U0, seeds=np.arange(45), process_std=1e-3)
    monkeypatch.setattr(closed_loop, "THREAD_WORK", 0.0)
    many = simulate(controller=CasadiIntegralLaw(law), **kw)
    monkeypatch.setattr(closed_loop, "THREAD_WORK", 1e30)
    one = simulate(controller=CasadiIntegralLaw(law), **kw)
    assert np.array_equal(many.x, one.x) and np.array_equal(many.u, one.u)
    assert (many.clipped_low, many.clipped_high) == (one.clipped_low, one.clipped_high)
    assert closed_loop._cuts(45, 2) == [0, 24, 45] and closed_loop._cuts(7, 2) == [0, 7]


def test_a_non_finite_input_is_still_the_loops_error(loop_cache):
    """The kernel stops at a non-finite input; the loop then names the run and sample."""
    import casadi as ca

    from tanksynth.errors import SimulationError

    x, r = ca.SX.sym("x", 3), ca.SX.sym("r", 2)
    bad = ca.Function("bad", [x, r], [ca.vertcat(ca.sqrt(0.35 - x[0]), 1e-5 + 0 * x[1])])
    with pytest.raises(SimulationError, match="non-finite input"):
        simulate(TANK, ts=1.0, steps=200, x0=X0 - 0.1, seeds=[0], controller=CasadiControlLaw(bad),
                 reference=_reference(200), u_init=U0)


def test_repeated_calls_follow_parameter_values_and_overflow_height(loop_cache, monkeypatch):
    """The per-call caches (tables of scalar parameter values, the plant's state bounds, the
    input limits handed to the kernel) follow the values: each call equals the loop's."""
    law = _tracking_law()
    N = 80
    kw = dict(plant=TANK, ts=1.0, steps=N, x0=X0, seeds=[7], reference=_reference(N), u_init=U0,
              process_std=1e-4, measurement_std=1e-3)
    runs = []
    for parameters in ({}, {"mu20": 0.4}, {"mu20": 0.4, "hmax": 0.45}, {"hmax": 0.45},
                       {"mu20": 0.4}, {}):
        fast, slow, fl, sl = _both(monkeypatch, lambda: CasadiIntegralLaw(law),
                                   parameters=parameters, **kw)
        _agree(fast, slow)
        assert np.array_equal(fast.x, slow.x) and np.array_equal(fast.y, slow.y)
        assert np.array_equal(fl.z, sl.z)
        runs.append(fast.x)
    assert np.array_equal(runs[0], runs[5]) and np.array_equal(runs[1], runs[4])
    assert not np.array_equal(runs[0], runs[1]) and not np.array_equal(runs[1], runs[2])
    assert runs[2].max() <= 0.45 < runs[1].max()      # the lower overflow height clips


@pytest.mark.parametrize("integral", [False, True])
def test_peak_recording_law_runs_in_the_kernel(loop_cache, monkeypatch, integral):
    """The robust verdict's saturation check (`PeakRecordingLaw` around the robust feedback):
    through the kernel, the peak ratio and the wrapped law's state end where the loop's do."""
    B = linearize(TANK, X0, U0).B
    K = 20.0 * B.T                                  # stiff enough to saturate after the step
    umax = np.array([5e-5, 4e-5])
    N = 90
    starts = X0 + np.array([[0.03, -0.02, 0.01], [-0.04, 0.0, 0.02], [0.0, 0.05, -0.03]])

    def make():
        inner = (IntegralStateFeedback(K, -1e-3 * np.eye(2), np.eye(3)[:2], X0, U0, 1.0)
                 if integral else StateFeedback(K, X0, U0))
        return PeakRecordingLaw(inner, U0, umax)

    fast, slow, fl, sl = _both(monkeypatch, make, plant=TANK, ts=1.0, steps=N, x0=starts,
                               seeds=np.arange(3), u_init=U0, process_std=1e-4,
                               reference=_reference(N) if integral else None)
    _agree(fast, slow)
    assert fl.peak.shape == (3,) and _rel(fl.peak, sl.peak) <= TOL
    assert np.all(fl.peak > 1.0)                    # the unclipped inputs went past umax
    # the peak is over the unclipped inputs: the clipped ones alone give less
    clipped = np.max(np.abs(fast.u - U0) / umax, axis=(1, 2))
    assert np.all(clipped <= fl.peak)
    if integral:
        assert _rel(fl.law.z, sl.law.z) <= TOL


def test_long_horizons_are_cut_into_calls_with_the_same_numbers(loop_cache, monkeypatch):
    """Issue 29 (break): a horizon cut into many kernel calls (`CALL_WORK`, so that a signal
    is seen between two of them) gives the numbers of the period-by-period loop, the
    clipping counts and the law's state included, with parameter changes and jumps inside."""
    law = _tracking_law()
    N = 97
    monkeypatch.setattr(closed_loop, "CALL_WORK", 5 * 4 * 3 * 7.0)      # 7 periods per call
    fast, slow, fl, sl = _both(monkeypatch, lambda: CasadiIntegralLaw(law), plant=TANK, ts=1.0,
                               steps=N, x0=X0 + np.linspace(-0.05, 0.05, 5)[:, None],
                               seeds=np.arange(5), reference=_reference(N), u_init=U0,
                               process_std=2e-3, changes=[ParameterChange(30, {"mu20": 0.5})],
                               jumps=[StateJump(61, (0.02, 0, 0))])
    _agree(fast, slow)
    assert np.array_equal(fast.x, slow.x) and np.array_equal(fl.z, sl.z)


@pytest.mark.slow
def test_a_signal_interrupts_a_large_simulation_within_a_call(loop_cache):
    """Issue 29 (break): Ctrl-C during a large closed loop (the kernel, not Python, running)
    was seen only after the whole horizon (8 s of 10 measured for 20,000 runs x 2,000
    periods); now within one call of `CALL_WORK` (0.5-1.5 s measured, < 3 s asked, for 2,000
    runs x 2,000 periods x 40 RK4 steps, 4-10 s uninterrupted on a loaded machine: the signal
    came after the kernel call before the fix)."""
    import os
    import signal
    import threading
    import time

    B = linearize(TANK, X0, U0).B
    law = StateFeedback(20.0 * B.T, X0, U0)
    kw = dict(plant=TANK, ts=1.0, x0=X0 + 0.01, u_init=U0)
    simulate(controller=law, steps=5, seeds=[0], **kw)           # the kernel built
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        simulate(controller=law, steps=2000, seeds=np.arange(2000), substeps=40, **kw)
        time.sleep(5.0)                          # (finished before the signal: not the point)
    elapsed = time.perf_counter() - t0
    assert elapsed < 3.0, elapsed


_INTERRUPTED_THREADS = r"""
import os, signal, threading, time
import numpy as np
os.environ["TANKSYNTH_SIM_BACKEND"] = "native"
from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.plants import three_tank
from tanksynth.sim import closed_loop
from tanksynth.sim.simulate import simulate
from tanksynth.verify.simulations import StateFeedback
closed_loop.THREAD_WORK = 0.0                  # threads whatever the size
plant = three_tank()
x0 = np.array([0.40, 0.20, 0.30])
u0 = equilibrium_input(plant, x0).u0
law = StateFeedback(20.0 * linearize(plant, x0, u0).B.T, x0, u0)
kw = dict(ts=1.0, x0=x0 + 0.01, u_init=u0)
simulate(plant, controller=law, steps=5, seeds=np.arange(32), **kw)
for i in range(16):
    threading.Timer(0.05 + 0.02 * i, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
    try:
        simulate(plant, controller=law, steps=400, seeds=np.arange(512), substeps=40, **kw)
        time.sleep(2.0)
    except KeyboardInterrupt:
        pass
    np.ones(4_000_000).sum()                    # (reuses the memory freed by the interruption)
print("survived")
"""


@pytest.mark.slow
def test_an_interrupted_threaded_kernel_call_does_not_crash(loop_cache):
    """Issue 29 (break): a signal raised in the main thread while another thread still ran the
    kernel freed the arrays that thread was writing: a segmentation fault (seen once, in
    ``test_a_signal_interrupts_a_large_simulation_within_a_call`` of a longer test run: the
    worker thread in ``tk_loop``, the main thread already past the interruption). The main
    thread now waits for the other threads' call (bounded by `CALL_WORK`) before unwinding.
    A race: this test interrupts 16 threaded simulations in a separate process and asks that
    it survives; it did not fail on demand without the fix (3 tries), so it guards the path
    rather than proving the fix."""
    import os
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", _INTERRUPTED_THREADS], capture_output=True,
                          text=True, timeout=300, env={**os.environ})
    assert proc.returncode == 0 and "survived" in proc.stdout, (proc.returncode,
                                                                proc.stderr[-800:])
