"""`simulate` refuses, before allocating, a simulation whose trajectories exceed the memory limit."""

import tracemalloc

import numpy as np
import pytest

from tanksynth.errors import DimensionError
from tanksynth.plants import three_tank
from tanksynth.sim.simulate import max_simulation_bytes, simulate, simulation_bytes


def test_bytes_count_every_buffer_by_hand():
    plant = three_tank()
    # n = 3, q = 3 (levels measured), m = 2: per sample 8 (9 + 6 + 2) + 3 bytes, twice
    n, q, m = plant.n, plant.q, plant.m
    assert simulation_bytes(plant, 10, 99) == 2 * 10 * 100 * (8 * (3 * n + 2 * q + m) + n)


def test_a_simulation_over_the_limit_is_refused_naming_its_size(monkeypatch):
    plant = three_tank()
    monkeypatch.setenv("TANKSYNTH_SIM_MAX_BYTES", "1e6")
    tracemalloc.start()
    with pytest.raises(DimensionError, match=r"100000 runs x 2000 samples need about .* GiB .*limit 0\.0 GiB"):
        simulate(plant, ts=1.0, steps=2000, x0=np.full(plant.n, 0.1), seeds=np.arange(100_000),
                 measurement_std=0.001)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 50e6          # refused before the 3 GB of buffers or noise


def test_limit_from_the_environment(monkeypatch):
    monkeypatch.setenv("TANKSYNTH_SIM_MAX_BYTES", "12345")
    assert max_simulation_bytes() == 12345
    monkeypatch.setenv("TANKSYNTH_SIM_MAX_BYTES", "lots")
    with pytest.raises(DimensionError, match="TANKSYNTH_SIM_MAX_BYTES must be a number of bytes, got 'lots'"):
        max_simulation_bytes()
    monkeypatch.delenv("TANKSYNTH_SIM_MAX_BYTES")
    assert max_simulation_bytes() > 2**28


def test_a_simulation_under_the_limit_runs(monkeypatch):
    plant = three_tank()
    monkeypatch.setenv("TANKSYNTH_SIM_MAX_BYTES", str(simulation_bytes(plant, 2, 5)))
    res = simulate(plant, ts=1.0, steps=5, x0=np.full(plant.n, 0.1), seeds=[1, 2])
    assert res.x.shape[:2] == (2, 6)
