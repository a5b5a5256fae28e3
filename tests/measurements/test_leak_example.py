"""examples/three_tank_fit_leak.toml: the custom plant is the built-in three-tank plus a tank-3
leak and an h2 sensor offset, and its [data] table maps the logs onto its outputs.

References: the built-in `three_tank` (written independently in tanksynth/plants/three_tank.py),
the leak term computed by hand, and the CSV read with numpy.
"""

from pathlib import Path

import numpy as np

from tanksynth.measurements import read_experiments
from tanksynth.methods import load_spec
from tanksynth.plants import three_tank

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "examples" / "three_tank_fit_leak.toml"
DATA = ROOT / "examples" / "data"
G, PHI, A = 9.81, 5e-5, 0.0154


def _points(count=200, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.01, 0.6, size=(count, 3))
    u = rng.uniform(0.0, 1.2e-4, size=(count, 2))
    return x, u


def test_free_parameters_are_the_rigs_unknowns():
    spec = load_spec(SPEC)
    assert [p.name for p in spec.free_parameters] == ["mu13", "mu32", "mu20", "mu3l", "b2"]
    assert [o.name for o in spec.plant.outputs] == ["y1", "y2", "y3"]


def test_dynamics_are_the_builtin_three_tank_plus_the_leak():
    values = {"mu13": 0.46, "mu32": 0.52, "mu20": 0.70}
    custom = load_spec(SPEC).plant.with_parameters({**values, "mu3l": 0.02, "b2": 0.003})
    builtin = three_tank().with_parameters(values)
    x, u = _points()       # every flow direction, not only h1 > h3 > h2
    leak = 0.02 * PHI * np.sqrt(2 * G * x[:, 2]) / A
    expected = builtin.compiled.rhs(x, u) - np.stack([0 * leak, 0 * leak, leak], axis=1)
    np.testing.assert_allclose(custom.compiled.rhs(x, u), expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(custom.compiled.output(x), x + [0.0, 0.003, 0.0], rtol=0, atol=1e-15)
    # without leak and offset it is the built-in plant
    plain = load_spec(SPEC).plant.with_parameters({**values, "mu3l": 0.0, "b2": 0.0})
    np.testing.assert_allclose(plain.compiled.rhs(x, u), builtin.compiled.rhs(x, u), rtol=1e-12, atol=1e-15)


def test_data_columns_map_the_logs_onto_the_outputs():
    spec = load_spec(SPEC)
    csv = DATA / "three_tank_estimation.csv"
    (exp,) = read_experiments([csv], spec.plant, spec.data)
    raw = np.genfromtxt(csv, delimiter=",", names=True)
    assert exp.output_names == ("y1", "y2", "y3")
    np.testing.assert_array_equal(exp.t, raw["t"])
    np.testing.assert_array_equal(exp.u, np.stack([raw["q1"], raw["q2"]], axis=1))
    np.testing.assert_array_equal(exp.y, np.stack([raw["h1"], raw["h2"], raw["h3"]], axis=1))
    # the y1 sensor range declared on the output censors the saturated samples (README: 37)
    assert int(np.sum(exp.censored_high[:, 0])) == 37 == int(np.sum(raw["h1"] >= 0.55))
