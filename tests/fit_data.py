"""Logged three-tank experiments generated with `tanksynth.sim` from known parameters (tests of
the fit: the data the fit must explain, written as CSV files)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tanksynth.methods import parse_spec_text
from tanksynth.sim.simulate import simulate_inputs

__all__ = ["TRUE", "PLANT_TOML", "spec_text", "write_log"]

#: The parameters the data are simulated with.
TRUE = {"mu13": 0.55, "mu32": 0.45, "mu20": 0.70}

PLANT_TOML = """
[plant]
model = "three_tank"
outputs = "h1h2"
[plant.parameters]
mu13 = {value = 0.5, min = 0.2, max = 0.9, fit = true}
mu32 = {value = 0.5, min = 0.2, max = 0.9, fit = true}
mu20 = {value = 0.6, min = 0.3, max = 0.9, fit = true}

[operating_point]
u = {q1 = 0.35e-4, q2 = 0.375e-4}
trim = "states"                       # the levels these flows hold, whatever the parameters
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}

[sampling]
ts = 1.0
"""


def spec_text(designs: str = "", free: bool = True) -> str:
    """A three-tank spec (h1, h2 measured) with mu13, mu32, mu20 free, and ``designs``."""
    text = PLANT_TOML if free else PLANT_TOML.replace(
        "mu13 = {value = 0.5, min = 0.2, max = 0.9, fit = true}", "mu13 = 0.5").replace(
        "mu32 = {value = 0.5, min = 0.2, max = 0.9, fit = true}", "mu32 = 0.5").replace(
        "mu20 = {value = 0.6, min = 0.3, max = 0.9, fit = true}", "mu20 = 0.675")
    return 'title = "fit test"\n' + text + designs


def write_log(path: Path, *, seed: int, samples: int = 300, noise: float = 5e-4,
              values: dict | None = None) -> Path:
    """Simulate the three-tank at `TRUE` under random pump steps and write ``t, q1, q2, h1, h2``.

    Parameters
    ----------
    path : Path
        The CSV file to write.
    seed : int
        Seed of the input steps and the noise.
    samples : int
        Samples (ts = 1 s).
    noise : float
        Standard deviation of the level noise (m).
    values : dict, optional
        Parameters simulated (default `TRUE`).
    """
    plant = parse_spec_text(spec_text(free=False)).plant
    rng = np.random.default_rng(seed)
    steps = np.repeat(rng.uniform(0.2e-4, 0.8e-4, size=(samples // 40 + 1, 2)), 40, axis=0)[:samples]
    res = simulate_inputs(plant, [0.35, 0.15, 0.25], steps[:-1], 1.0, substeps=4,
                          parameters=values or TRUE)
    y = np.asarray(res.y)[0] + noise * rng.standard_normal((samples, 2))
    t = np.arange(samples, dtype=float)
    table = np.column_stack([t, steps, y])
    np.savetxt(path, table, delimiter=",", header="t,q1,q2,h1,h2", comments="", fmt="%.10g")
    return path
