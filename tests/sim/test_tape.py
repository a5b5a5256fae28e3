"""The numpy tape of the plant and its cache (documented, clearable, rebuilt on demand)."""

import numpy as np

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
