"""Seed 002 (Vellayikot & Vaidyan, JEET 2016): hybrid three-tank, EKF/UKF/NARX + inverse dynamics.

The results the paper printed for its real rig (Tables 4-8), the names of its
experiments and controllers, and the estimator structure of Sec. 3 (Table 3).
Theirs is a real rig and tanksynth's a declared reconstruction: compare orderings and
magnitudes, not digits.
"""

from __future__ import annotations

__all__ = [
    "CONTROLLERS",
    "EXPERIMENTS",
    "TABLE_NUMBERS",
    "TABLES",
    "METRIC_UNITS",
    "NARX_STRUCTURE",
    "UKF_PARAMETERS",
    "TABLE_1",
    "TABLE_2",
    "PUMP_VOLTAGE",
    "LPH",
    "CLAIMS",
    "TIMING_ORDER",
]

#: The three controllers compared: inverse-dynamics control fed by an EKF, a UKF or an ANN
#: (NARX) estimator.
CONTROLLERS: dict[str, str] = {
    "EKFC": "EKF + inverse dynamics",
    "UKFC": "UKF + inverse dynamics",
    "ANNC": "NARX (ANN) estimator + inverse dynamics",
}

#: The experiments of Sec. 5 (Tables 4-8), the model mismatch of Table 7 with both signs.
EXPERIMENTS: tuple[str, ...] = ("servo", "regulatory", "mismatch", "uncertainty_plus",
                                "uncertainty_minus", "leakage", "clogging")

#: Experiment -> the table that reports it.
TABLE_NUMBERS: dict[str, int] = {"servo": 4, "regulatory": 5, "mismatch": 6,
                                 "uncertainty_plus": 7, "uncertainty_minus": 7, "leakage": 8,
                                 "clogging": 8}

#: Units of the printed metrics.
METRIC_UNITS: dict[str, str] = {"ise_h1": "m^2 s", "ise_h2": "m^2 s", "tracking_time": "s",
                                "rejection_time": "s", "computation_time": "s", "offset": "m"}

#: Tables 4-8 (real rig): experiment -> controller -> metric -> value (units `METRIC_UNITS`).
TABLES: dict[str, dict[str, dict[str, float]]] = {
    "servo": {  # Table 4
        "EKFC": {"ise_h1": 0.0149, "ise_h2": 0.0132, "tracking_time": 34},
        "UKFC": {"ise_h1": 0.0160, "ise_h2": 0.0148, "tracking_time": 36},
        "ANNC": {"ise_h1": 0.0172, "ise_h2": 0.0144, "tracking_time": 32},
    },
    "regulatory": {  # Table 5
        "EKFC": {"ise_h1": 0.0308, "ise_h2": 0.0296, "rejection_time": 130, "computation_time": 0.0328},
        "UKFC": {"ise_h1": 0.0277, "ise_h2": 0.0304, "rejection_time": 120, "computation_time": 0.1849},
        "ANNC": {"ise_h1": 0.0200, "ise_h2": 0.0193, "rejection_time": 70, "computation_time": 0.1038},
    },
    "mismatch": {  # Table 6
        "EKFC": {"ise_h1": 0.3151, "ise_h2": 0.5480, "tracking_time": 275, "computation_time": 0.0293},
        "UKFC": {"ise_h1": 0.1767, "ise_h2": 0.3175, "tracking_time": 180, "computation_time": 0.1935},
        "ANNC": {"ise_h1": 0.0214, "ise_h2": 0.0592, "tracking_time": 68, "computation_time": 0.1017},
    },
    "uncertainty_plus": {  # Table 7, +10 %
        "EKFC": {"ise_h1": 0.0128, "ise_h2": 0.0131, "computation_time": 0.0294, "offset": 0.0087},
        "UKFC": {"ise_h1": 0.0124, "ise_h2": 0.0120, "computation_time": 0.2112, "offset": 0.0079},
        "ANNC": {"ise_h1": 0.0045, "ise_h2": 0.0069, "computation_time": 0.0999, "offset": 0.0039},
    },
    "uncertainty_minus": {  # Table 7, -10 %
        "EKFC": {"ise_h1": 0.0352, "ise_h2": 0.0341, "computation_time": 0.0373, "offset": -0.0152},
        "UKFC": {"ise_h1": 0.0297, "ise_h2": 0.0290, "computation_time": 0.2010, "offset": -0.0138},
        "ANNC": {"ise_h1": 0.0122, "ise_h2": 0.0131, "computation_time": 0.1037, "offset": -0.0064},
    },
    "leakage": {  # Table 8
        "EKFC": {"ise_h1": 0.1110, "ise_h2": 0.0072, "computation_time": 0.0518},
        "UKFC": {"ise_h1": 0.1026, "ise_h2": 0.0059, "computation_time": 0.1883},
        "ANNC": {"ise_h1": 0.0600, "ise_h2": 0.0077, "computation_time": 0.0768},
    },
    "clogging": {  # Table 8
        "EKFC": {"ise_h1": 0.7638, "ise_h2": 0.7610, "computation_time": 0.0268},
        "UKFC": {"ise_h1": 0.2616, "ise_h2": 0.2613, "computation_time": 0.1630},
        "ANNC": {"ise_h1": 0.0082, "ise_h2": 0.0078, "computation_time": 0.0943},
    },
}

#: Table 3: the NARX estimator: hidden tanh neurons, linear output layer, network inputs,
#: output feedback delays.
NARX_STRUCTURE: dict[str, object] = {"hidden": 5, "activation": "tanh", "output": "linear",
                                     "inputs": 4, "delays": 2}

#: Sec. 3.2: the UKF's sigma-point parameters beta and kappa (-).
UKF_PARAMETERS: dict[str, float] = {"beta": 2.0, "kappa": 0.0}

#: Table 1: discharge coefficients k1..k7 of the hand valves (m^2).
TABLE_1: dict[str, float] = {"k1": 2.6363e-5, "k2": 2.4891e-5, "k3": 3.7984e-5, "k4": 3.4316e-5,
                             "k5": 0.0, "k6": 2.2538e-5, "k7": 0.0}

#: Table 2: tank height (m), overflow height (m), tank inner diameter (m), diameter of the
#: connecting pipes (m) and rated flow of the pumps (lph).
TABLE_2: dict[str, float] = {"tank_height": 0.60, "overflow_height": 0.55, "tank_diameter": 0.15,
                             "pipe_diameter": 0.0125, "rated_flow_lph": 240.0}

#: Table 2 (and Sec. 2): the pumps' input voltage range (V).
PUMP_VOLTAGE: tuple[float, float] = (0.0, 5.0)

#: One litre per hour in m^3/s (the unit of Table 2's rated flow).
LPH: float = 1e-3 / 3600.0

#: The claims of Sec. 5-6 the tables are quoted for (text).
CLAIMS: dict[str, str] = {
    "annc_lowest_ise": ("except in servo operation, the ISE is the lowest for ANNC "
                        "(Sec. 6; Tables 5-8)"),
    "annc_best_mismatch": "ANNC is best under initial-state mismatch (Table 6)",
    "narx_correction": ("the ANN corrects the a-priori estimate better than the EKF's "
                        "linearised correction (Sec. 6)"),
}

#: Sec. 5-6: control-signal generation time, fastest first (EKFC "nearly 1/4th that for ANNC
#: and 1/8th that for UKFC").
TIMING_ORDER: tuple[str, str, str] = ("EKFC", "ANNC", "UKFC")
