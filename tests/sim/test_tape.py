"""The numpy tape of the plant and its cache (documented, clearable, rebuilt on demand)."""

import numpy as np
import pytest

import tanksynth.sim as sim
from tanksynth.plants import hybrid_three_tank
from tanksynth.plants.hybrid_three_tank import LPH
from tanksynth.sim.tape import cache_info, clear_cache, numpy_model


def test_clear_cache_then_rebuild_gives_the_same_numbers():
    plant = hybrid_three_tank()
    kw = dict(ts=1.0, steps=60, x0=[0.297, 0.29, 0.25], seeds=[4], u_init=[110 * LPH, 100 * LPH],
              measurement_std=1e-3)
    before = sim.simulate(plant, **kw)
    model = numpy_model(plant)
    assert cache_info()["models"] >= 1 and cache_info()["plants"] >= 1
    assert sim.clear_cache is clear_cache
    dropped = sim.clear_cache()
    assert dropped >= 1 and cache_info() == {"models": 0, "plants": 0}
    rebuilt = numpy_model(plant)
    assert rebuilt is not model                               # compiled again
    assert numpy_model(plant) is rebuilt and cache_info()["models"] == 1
    after = sim.simulate(plant, **kw)
    assert np.array_equal(before.x, after.x) and np.array_equal(before.y, after.y)


def _both_paths(monkeypatch, plant, **kw):
    import tanksynth.sim.integrate as integrate

    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "numpy")      # no compiled kernel (test_kernel.py)
    small = sim.simulate(plant, **kw)                      # M <= CASADI_MAX_RUNS: CasADi period
    monkeypatch.setattr(integrate, "CASADI_MAX_RUNS", 0)     # force the generated numpy code
    monkeypatch.setattr(integrate, "CASADI_MAX_RUNS_HYBRID", 0)
    rows = sim.simulate(plant, **kw)
    return small, rows


@pytest.mark.slow
def test_casadi_period_and_numpy_rows_give_the_same_runs_bit_for_bit(monkeypatch):
    plant = hybrid_three_tank()
    rng = np.random.default_rng(5)
    M = 6
    x0 = rng.uniform(0.0, 0.6, (M, 3))
    x0[:2] = [[1e-4, 2e-4, 0.0], [0.0, 1e-3, 1e-4]]           # nearly empty: RK4 overshoots 0
    kw = dict(ts=0.5, steps=300, x0=x0, seeds=sim.run_seeds(9, M),
              u_init=np.zeros(plant.m), process_std=1e-4, substeps=3,
              parameters={"k1": np.linspace(0.8, 1.2, M) * plant.parameter_values[plant.p["k1"]]})
    small, rows = _both_paths(monkeypatch, plant, **kw)
    assert (small.backend, rows.backend) == ("casadi", "numpy")
    assert rows.events > 0 and rows.clipped_low > 0          # crossings and clipping exercised
    # one source, two backends, the same operations in the same order: bit for bit
    assert np.array_equal(small.x, rows.x) and np.array_equal(small.y, rows.y)
    assert np.array_equal(small.modes, rows.modes)
    assert (small.events, small.clipped_low, small.clipped_high) == \
        (rows.events, rows.clipped_low, rows.clipped_high)


def test_generated_code_matches_an_independent_rk4_of_the_casadi_plant():
    from tanksynth.plants import three_tank

    plant = three_tank()
    f = plant.compiled.f                                      # sympy -> CasADi, not the tape
    lo, hi = plant.state_bounds()
    x = np.array([0.40, 0.05, 0.30])
    u = np.array([3e-5, 1e-5])
    h = 0.25
    clip = lambda v: np.minimum(np.maximum(v, lo), hi)  # noqa: E731
    rhs = lambda v: np.asarray(f(clip(v), u)).ravel()  # noqa: E731
    ref = [x]
    for _ in range(160):
        s = ref[-1]
        k1 = rhs(s); k2 = rhs(s + h / 2 * k1); k3 = rhs(s + h / 2 * k2); k4 = rhs(s + h * k3)  # noqa: E702
        ref.append(clip(s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)))
    for M in (1, 100):                                        # CasADi period, numpy rows
        out = sim.simulate_inputs(plant, np.tile(x, (M, 1)), np.tile(u, (40, 1)), 1.0, substeps=4)
        assert np.max(np.abs(out.x - np.array(ref)[::4][None])) < 1e-12


def test_generated_source_hoists_parameter_only_terms():
    from tanksynth.plants import three_tank

    model = numpy_model(three_tank())
    body = model.source.split("def f(")[1].split("def h(")[0]
    consts = model.source.split("def constants(p)")[1].split("def f(")[0]
    assert "def constants(p)" in model.source
    # sqrt(2 g) Phi mu / A is computed once in constants(), never per stage
    assert "numpy.sqrt(p_" in consts
    per_stage = [s for s in ("numpy.sqrt(p_", "numpy.sqrt(c_", "numpy.sqrt(2") if s in body]
    assert not per_stage, per_stage
    assert "numpy.sqrt(r_" in body or "numpy.sqrt(t_" in body    # the level-dependent roots stay


@pytest.mark.parametrize("name", ["three_tank", "tank_network", "hybrid_three_tank"])
def test_open_loop_horizon_in_one_call_equals_the_period_loop(monkeypatch, name):
    from tanksynth.plants import builtin_plant
    from tanksynth.sim.integrate import Integrator

    plant = builtin_plant(name)
    rng = np.random.default_rng(2)
    M, N = 5, 120
    hi = np.array([b if np.isfinite(b) else 1e-4 for _, b in plant.input_limits])
    U = rng.uniform(-0.1, 1.1, (N, M, plant.m)) * hi
    lo_x, hi_x = plant.state_bounds()
    top = np.where(np.isfinite(hi_x), hi_x, 40.0)
    x0 = rng.uniform(0.0, 1.0, (M, plant.n)) * top
    x0[0] = 0.0                                            # empty tanks: clipping at 0
    fast = sim.simulate_inputs(plant, x0, U, 1.0, substeps=3)
    monkeypatch.setattr(Integrator, "horizon", lambda self, *a, **k: None)
    loop = sim.simulate_inputs(plant, x0, U, 1.0, substeps=3)
    for key in ("x", "y", "u", "x_hat", "modes"):
        assert np.array_equal(getattr(fast, key), getattr(loop, key)), key
    assert (fast.events, fast.clipped_low, fast.clipped_high) == \
        (loop.events, loop.clipped_low, loop.clipped_high)
