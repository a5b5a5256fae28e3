"""Seed 004 (Wafi): linear hydraulic model with a leak fault; observer-based fault detection.

The model parameters and matrices of Sec. III (controllability, observability,
transfer functions, observer canonical form), the observer design of eq. (27)-(29)
(gains ``Psi_o``, ``Psi`` and the printed ``Gamma_d``), the threshold of eq. (54),
and the detection experiment of Sec. IV (initial states, input, fault onset,
printed detection times), all as printed. The fault size ``delta_bar`` of Sec. IV is
not printed.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "PARAMETERS",
    "A",
    "B",
    "C",
    "printed_matrices",
    "OBSERVER_POLES",
    "PSI_O",
    "PSI",
    "GAMMA_D",
    "GAMMA_D_NOTE",
    "THRESHOLD_TEXT",
    "THRESHOLD_TERMS",
    "INITIAL_STATE_BOUNDS",
    "INITIAL_STATES",
    "DETECTION_TIMES",
    "INPUT",
    "T_FAULT",
]

#: Sec. III: psi_i (tank capacities, -) and delta_i (outflow coefficients, 1/s).
PARAMETERS: dict[str, float] = {"psi1": 2.0, "psi2": 1.0, "psi3": 2.0, "delta1": 1.0,
                                "delta2": 1.5, "delta3": 1.0}

#: Sec. III: the healthy state matrix (1/s), input matrix and output matrix.
A: np.ndarray = np.array([[-0.5, 0.0, 0.0], [0.5, -1.5, 0.0], [0.0, 1.5, -0.5]])
B: np.ndarray = np.array([[1.0], [0.0], [0.0]])
C: np.ndarray = np.array([[0.0, 0.0, 0.5]])


def printed_matrices(delta_bar: float) -> dict[str, np.ndarray]:
    """The printed structural matrices of Sec. III, evaluated at ``delta_bar`` (0: healthy).

    Parameters
    ----------
    delta_bar : float
        Leak coefficient of tank 2 (1/s); 0 gives the healthy system (eq. 13, 21a,
        23a), anything else the faulty one (eq. 14, 21b, 23b).

    Returns
    -------
    dict
        ``QC`` (eq. 21a/21b), ``QO`` (eq. 23a/23b), ``den`` (the denominator of the
        transfer function, eq. 13/14, highest power of s first), ``num`` (its
        numerator 0.375), ``poles`` (the factored denominator, 1/s), and for the
        healthy system only ``QO_bar`` and ``Delta`` (the observer canonical form and
        its transformation, eq. 27).
    """
    d = float(delta_bar)
    out = {
        "QC": np.array([[1, -0.5, 0.25], [0, 0.5, -1 - 0.5 * d], [0, 0.0, 0.75]]),
        "QO": np.array([[0.000, 0.000, 0.500], [0.000, 0.750, -0.250],
                        [0.375, -1.5 - 0.75 * d, 0.125]]),
        "den": np.array([1.0, 2.5 + d, 1.75 + d, 0.375 + 0.25 * d]),
        "num": np.array([0.375]),
        "poles": np.array([-0.5, -0.5, -1.5 - d]),
    }
    if d == 0.0:
        out["QO_bar"] = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, -2.5], [1.0, -2.5, 4.5]])
        out["Delta"] = np.array([[8 / 3, -4 / 3, 2 / 3], [0, 4 / 3, -8 / 3], [0, 0, 2]])
    return out


#: Eq. (27)-(29): the observer's error poles (1/s).
OBSERVER_POLES: tuple[float, float, float] = (-5.0, -8.0, -10.0)

#: The observer gain in the observer canonical form (1/s).
PSI_O: np.ndarray = np.array([[399.625], [168.250], [20.500]])

#: The observer gain Psi (1/s), as printed (169.667 is 509/3 rounded).
PSI: np.ndarray = np.array([[855.0], [169.667], [41.0]])

#: The error dynamics Gamma_d = A - Psi C as printed (1/s).
GAMMA_D: np.ndarray = np.array([[-0.5, 0.0, -855.0], [0.5, -1.5, -169.667], [0.0, 1.5, -41.5]])

#: What is wrong in the printed `GAMMA_D`.
GAMMA_D_NOTE = ("the printed Gamma_d is A - Psi [0 0 1] (C_o instead of C = [0 0 0.5]): its third "
                "column is twice the derived one and its eigenvalues are not the designed poles")

#: Eq. (54): the detection threshold (t in s, output units).
THRESHOLD_TEXT = "78/64 e^{-5t} - 765/64 e^{-8t} + 807/64 e^{-10t}"

#: Eq. (54) as (coefficient, rate) pairs: epsilon_bar(t) = sum c exp(r t) (rates in 1/s).
THRESHOLD_TERMS: tuple[tuple[float, float], ...] = ((78 / 64, -5.0), (-765 / 64, -8.0),
                                                    (807 / 64, -10.0))

#: Sec. II-F: the initial levels lie in (1/4, 4]; the observer starts at the lower bound.
INITIAL_STATE_BOUNDS: tuple[float, float] = (0.25, 4.0)

#: Sec. IV: the initial states x0(1), x0(2), x0(3) of the detection experiment.
INITIAL_STATES: tuple[tuple[float, float, float], ...] = ((0.26, 0.26, 0.26), (4.0, 4.0, 4.0),
                                                          (2.4, 3.6, 1.8))

#: Sec. IV: the printed detection times (s), in the order of `INITIAL_STATES`.
DETECTION_TIMES: tuple[float, float, float] = (2.0235, 2.015, 2.0165)

#: Sec. IV: the input as (t_start in s, u): 2 on [0, 1), then 1.
INPUT: tuple[tuple[float, float], ...] = ((0.0, 2.0), (1.0, 1.0))

#: Sec. IV: the fault onset t_f (s).
T_FAULT: float = 2.0
