"""Seed 003 (Pedroso, Batista, Oliveira & Silvestre, IJSS 2021): decentralised Kalman filtering.

The seed's N-tank network example (DECENTER, ``NTanksNetworkEstimationOSFH``): the
constants of its script as published with the paper, and the plant constants of
DECENTER's defaults (not printed in the paper itself; the ``tank_network`` plant
takes them as its defaults). The process-noise intensity is not published at all
(declared in ``examples/seed003_tank_network.toml``).
"""

from __future__ import annotations

__all__ = [
    "N",
    "TS",
    "RELINEARIZE_EVERY",
    "WINDOW",
    "TOLERANCE",
    "MAX_ITERATIONS",
    "P0",
    "X0_LEVEL",
    "PUMP_FIRST",
    "PUMP_SECOND",
    "T_SWITCH",
    "DURATION",
    "RANDOM_SEED",
    "TANK_AREAS",
    "OUTLET_AREAS",
    "UPPER_OUTLET_AREA",
    "VALVE_SPLITS",
    "PUMP_GAIN",
    "G",
    "SENSOR_GAIN",
]

#: Number of tanks (20 pumps).
N: int = 40
#: Sampling period dT (s).
TS: float = 1.0
#: dTlin: relinearise every this many steps.
RELINEARIZE_EVERY: int = 10
#: FH_w: finite-horizon window (steps).
WINDOW: int = 40
#: opts.epsl: convergence tolerance of the finite-horizon iteration (-).
TOLERANCE: float = 1e-6
#: opts.maxOLIt: iteration limit of the finite-horizon iteration.
MAX_ITERATIONS: int = 100
#: Initial covariance P0 = 10 I (cm^2), as the scalar factor.
P0: float = 10.0
#: Initial level of every tank (cm).
X0_LEVEL: float = 20.0
#: Open-loop pump command before `T_SWITCH` (V).
PUMP_FIRST: float = 6.0
#: Open-loop pump command from `T_SWITCH` on (V).
PUMP_SECOND: float = 4.0
#: Time of the pump command change (s).
T_SWITCH: float = 400.0
#: Simulation length (steps of `TS`).
DURATION: int = 800
#: Random seed of the script.
RANDOM_SEED: int = 7

#: Cross-sections A_i of the odd and even lower tanks (cm^2), DECENTER defaults.
TANK_AREAS: tuple[float, float] = (28.0, 32.0)
#: Outlet areas a_i of the odd and even lower tanks (cm^2).
OUTLET_AREAS: tuple[float, float] = (0.071, 0.057)
#: Outlet area of every upper tank (cm^2).
UPPER_OUTLET_AREA: float = 0.040
#: Valve splits gamma of the odd and even pumps (-).
VALVE_SPLITS: tuple[float, float] = (0.7, 0.6)
#: Pump gain k (cm^3/(V s)).
PUMP_GAIN: float = 3.33
#: Gravity (cm/s^2).
G: float = 981.0
#: Level sensor gain kc (V/cm).
SENSOR_GAIN: float = 0.5
