"""Generate the logged three-tank experiments of the fit example (examples/data/*.csv).

Run once (the files are shipped; tests/measurements/test_example_data.py checks that this
script regenerates them bit for bit)::

    python scripts/make_fit_example.py            # writes examples/data/three_tank_*.csv
    python scripts/make_fit_example.py --out DIR  # elsewhere

What it does (stated with the true values in examples/data/README.md): the DTS200 three-tank
plant of `tanksynth.plants.three_tank`, with outflow coefficients that differ from the nominal
ones and a small unmodelled leak on tank 3, is driven by a multi-level PRBS of the two pumps
and simulated with the project's simulator (`tanksynth.sim.simulate_inputs`, RK4, the
simulator's clipping). The logged levels get a sensor offset, Gaussian noise, 1 mm
quantisation and the range of the tank 1 sensor (it saturates while h1 is above it). Every
random draw is seeded, so the files are the same on every run.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tanksynth.plants import custom_plant, three_tank  # noqa: E402
from tanksynth.sim import simulate_inputs  # noqa: E402

#: Sampling period (s): a tank alone has a time constant of about 90 s and the cascade settles
#: in 10-20 min, so 2 s resolves every transient while 1000 samples span 33 min of excitation.
TS = 2.0
#: Samples per experiment.
SAMPLES = 1000
#: True outflow coefficients of the simulated rig (nominal: 0.5, 0.5, 0.675).
TRUE = {"mu13": 0.46, "mu32": 0.52, "mu20": 0.70}
#: Unmodelled leak of tank 3: q_leak = LEAK * Phi * sqrt(2 g h3) (a small hole: about 4 % of the
#: flow of the pipe T3-T2 at equal head; the fitted model has no such term).
LEAK = 0.02
#: Level sensor noise standard deviation (m), quantisation step (m).
NOISE_STD = 0.0015
QUANT = 0.001
#: Constant offset of each level sensor (m): the tank 2 sensor reads 3 mm high.
OFFSET = {"h1": 0.0, "h2": 0.003, "h3": 0.0}
#: Measuring range of each level sensor (m): the tank 1 sensor saturates at 0.55 m.
SENSOR_RANGE = {"h1": (0.0, 0.55), "h2": (0.0, 0.62), "h3": (0.0, 0.62)}
#: Pump flow levels of the multi-level PRBS (m^3/s), and its hold times (samples).
Q1_LEVELS = (1.0e-5, 2.5e-5, 4.0e-5, 5.5e-5, 7.0e-5)
Q2_LEVELS = (0.0, 1.5e-5, 3.0e-5)
HOLD = (30, 150)
#: Seeds of the two experiments: (PRBS, noise), initial levels (m).
EXPERIMENTS = {
    "three_tank_estimation": {"seed": (3021, 4021), "x0": (0.30, 0.10, 0.20)},
    "three_tank_validation": {"seed": (3122, 4122), "x0": (0.40, 0.15, 0.28)},
}
#: Smallest margin (m) kept in h1 > h3 > h2 along the true trajectories (the model's sign/abs
#: are resolved under that ordering), and below the tank height (no overflow).
ORDER_MARGIN = 0.005
#: Fewest samples with tank 1 above its sensor's range (the saturation the example shows).
MIN_SATURATED = 30


def rig_plant():
    """The simulated rig: the three-tank of `three_tank` plus the leak of tank 3 (custom plant)."""
    nominal = {p.name: p.value for p in three_tank().parameters}
    values = {**nominal, **TRUE, "leak": LEAK}
    table = {
        "model": "custom", "name": "three_tank_rig",
        "states": {h: {"unit": "m", "min": 0.0, "max": nominal["hmax"]} for h in ("h1", "h2", "h3")},
        "inputs": {q: {"unit": "m^3/s", "min": 0.0, "max": nominal["qmax"]} for q in ("q1", "q2")},
        "parameters": {k: {"value": v} for k, v in values.items()},
        "equations": {
            "h1": "(q1 - mu13*Phi*sign(h1 - h3)*sqrt(2*g*abs(h1 - h3)))/A",
            "h2": "(q2 + mu32*Phi*sign(h3 - h2)*sqrt(2*g*abs(h3 - h2)) - mu20*Phi*sqrt(2*g*h2))/A",
            "h3": "(mu13*Phi*sign(h1 - h3)*sqrt(2*g*abs(h1 - h3)) - mu32*Phi*sign(h3 - h2)"
                  "*sqrt(2*g*abs(h3 - h2)) - leak*Phi*sqrt(2*g*h3))/A",
        },
        "outputs": {"h1": "h1", "h2": "h2", "h3": "h3"},
        "orderings": ["h1 > h3", "h3 > h2"],
    }
    return custom_plant(table)


def prbs(seed: int) -> np.ndarray:
    """Multi-level PRBS of the two pumps, (SAMPLES, 2) m^3/s: each pump holds a random level of
    its set for a random number of samples in HOLD, independently."""
    rng = np.random.default_rng(seed)
    u = np.empty((SAMPLES, 2))
    for j, levels in enumerate((Q1_LEVELS, Q2_LEVELS)):
        k = 0
        while k < SAMPLES:
            hold = int(rng.integers(HOLD[0], HOLD[1] + 1))
            u[k:k + hold, j] = levels[int(rng.integers(len(levels)))]
            k += hold
    return u


def experiment(plant, seed: tuple[int, int], x0: tuple[float, float, float]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Times (s), inputs (m^3/s), true levels and logged levels (m) of one experiment."""
    u = prbs(seed[0])
    result = simulate_inputs(plant, np.array(x0), u, TS)
    x = np.asarray(result.x, dtype=float)[0, :SAMPLES, :]   # the state at each sample time
    h1, h2, h3 = x.T
    margin = min(float(np.min(h1 - h3)), float(np.min(h3 - h2)))
    if margin < ORDER_MARGIN:
        raise SystemExit(f"seed {seed}: h1 > h3 > h2 fails by {margin:.4g} m; choose another seed")
    hmax = plant.parameter("hmax").value
    if float(np.max(x)) > hmax - ORDER_MARGIN:
        raise SystemExit(f"seed {seed}: a tank reaches {np.max(x):.4g} m (overflow at {hmax} m)")
    if int(np.sum(h1 > SENSOR_RANGE["h1"][1])) < MIN_SATURATED:
        raise SystemExit(f"seed {seed}: h1 exceeds its sensor range on fewer than {MIN_SATURATED} samples")
    rng = np.random.default_rng(seed[1])
    y = x + np.array([OFFSET[h] for h in ("h1", "h2", "h3")]) + rng.normal(0.0, NOISE_STD, x.shape)
    y = np.round(y / QUANT) * QUANT
    for j, h in enumerate(("h1", "h2", "h3")):
        y[:, j] = np.clip(y[:, j], *SENSOR_RANGE[h])
    t = TS * np.arange(SAMPLES)
    return t, u, x, y


def csv_text(t: np.ndarray, u: np.ndarray, y: np.ndarray) -> str:
    """The CSV file: header ``t,q1,q2,h1,h2,h3``, times in s, flows in m^3/s, levels in m."""
    rows = ["t,q1,q2,h1,h2,h3"]
    for k in range(len(t)):
        rows.append(f"{t[k]:g},{u[k, 0]:.6g},{u[k, 1]:.6g},"
                    + ",".join(f"{v:.3f}" for v in y[k]))
    return "\n".join(rows) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write the two CSV files; print the coverage of each one."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "examples" / "data",
                        help="output directory (default examples/data)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    plant = rig_plant()
    for name, cfg in EXPERIMENTS.items():
        t, u, x, y = experiment(plant, cfg["seed"], cfg["x0"])
        path = args.out / f"{name}.csv"
        path.write_text(csv_text(t, u, y), encoding="utf-8", newline="\n")
        saturated = int(np.sum(y[:, 0] >= SENSOR_RANGE["h1"][1]))
        print(f"{path}: {len(t)} samples, h1 {x[:, 0].min():.3f}..{x[:, 0].max():.3f} m, "
              f"h2 {x[:, 1].min():.3f}..{x[:, 1].max():.3f} m, h3 {x[:, 2].min():.3f}.."
              f"{x[:, 2].max():.3f} m, min(h1-h3) {np.min(x[:, 0] - x[:, 2]):.3f} m, "
              f"min(h3-h2) {np.min(x[:, 2] - x[:, 1]):.3f} m, h1 sensor saturated on {saturated} samples")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
