"""Seed 000 (Widjiantoro, Indriawati, Wafi): DTS200 three-tank, linearisation, control, AKF.

Every value below is transcribed from the paper as printed, typos included; the
errata notes say where the printed value disagrees with the model equations (6a-c)
(found by the symbolic comparisons of ``tests/test_seed000_reference.py`` and the
report's paper-vs-tool section). The printed formulas of eq. (8) and of the control
law of Sec. IV are given as functions that evaluate them exactly as printed.
"""

from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

__all__ = [
    "TABLE_I",
    "Y0",
    "U0_TEXT",
    "U0",
    "F_PRINTED_LATEX",
    "F_FORMULA_ERRATA",
    "F_in_fractions",
    "printed_F",
    "POLES",
    "K",
    "AKF_X0",
    "AKF_P0",
    "AKF_Q0",
    "AKF_R0",
    "HMAX",
    "AKF_CLAIM",
    "LAW_PRINTED",
    "LAW_PRINTED_LATEX",
    "LAW_NOTE",
    "printed_law",
]

#: Table I: tank section A (m^2), pipe section Phi (m^2), outflow coefficients mu13, mu32,
#: mu20 (-) and gravity g (m/s^2).
TABLE_I: dict[str, float] = {"A": 0.0154, "Phi": 5e-5, "mu13": 0.5, "mu32": 0.5, "mu20": 0.675,
                             "g": 9.81}

#: Sec. IV: the operating point y0 = (y01, y02, y03) (m).
Y0: tuple[float, float, float] = (0.40, 0.20, 0.30)

#: Sec. IV: the input u0 (m^3/s) as the text printed (its digits give its precision).
U0_TEXT: tuple[str, str] = ("0.35e-4", "0.375e-4")

#: The same input as numbers (m^3/s).
U0: tuple[float, float] = (0.35e-4, 0.375e-4)

# The three printed fractions of eq. (8) (phi = sqrt(2 g), y0i = hi).
_T13 = r"\tfrac{\mu_{13}\Phi\varphi}{2A\sqrt{y_{01}-y_{03}}}"
_T32 = r"\tfrac{\mu_{32}\Phi\varphi}{2A\sqrt{y_{03}-y_{02}}}"
_T20 = r"\tfrac{\mu_{20}\Phi\varphi}{2A\sqrt{y_{02}}}"

#: Eq. (8): the printed entries of F that are wrong, in LaTeX (1-based (row, column)).
F_PRINTED_LATEX: dict[tuple[int, int], str] = {
    (2, 2): f"-{_T13}-{_T20}",
    (3, 1): f"-{_T13}",
    (3, 3): f"-{_T32}+{_T13}",
}

#: Eq. (8) errata: what is wrong in each printed entry of `F_PRINTED_LATEX` (LaTeX text).
F_FORMULA_ERRATA: dict[tuple[int, int], str] = {
    (2, 2): r"the $\mu_{13}$ (T1--T3) term stands where the $\mu_{32}$ (T3--T2) term belongs",
    (3, 1): r"sign flipped: tank 1 fills tank 3, $\partial\dot h_3/\partial h_1 > 0$",
    (3, 3): r"sign of the $\mu_{13}$ term flipped: both outflows of tank 3 lower its level",
}


def F_in_fractions(t13: Any, t32: Any, t20: Any) -> list[list[Any]]:
    """Eq. (8) as printed, in terms of its three printed fractions.

    ``t13 = mu13 Phi phi / (2 A sqrt(y01 - y03))``, ``t32 = mu32 Phi phi / (2 A sqrt(y03 -
    y02))``, ``t20 = mu20 Phi phi / (2 A sqrt(y02))`` (1/s), numbers or sympy expressions.

    Parameters
    ----------
    t13, t32, t20 : float or sympy.Expr
        The three printed fractions [1/s].

    Returns
    -------
    list of list
        The 3 x 3 entries of F (1/s), rows first.
    """
    return [[-t13, 0, t13],
            [0, -t13 - t20, t32],
            [-t13, t32, -t32 + t13]]


def printed_F(params: Mapping[str, float], h: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """F and B of eq. (8), evaluated exactly as printed (with phi = sqrt(2 g)).

    Parameters
    ----------
    params : mapping
        ``A`` (m^2), ``Phi`` (m^2), ``mu13``, ``mu32``, ``mu20`` (-), ``g`` (m/s^2), e.g.
        `TABLE_I`.
    h : sequence of 3 floats
        The operating point ``y0 = (y01, y02, y03)`` (m), with ``y01 > y03 > y02 > 0``.

    Returns
    -------
    F : ndarray, shape (3, 3)
        1/s.
    B : ndarray, shape (3, 2)
        1/m^2.
    """
    A, Phi, g = params["A"], params["Phi"], params["g"]
    phi = math.sqrt(2 * g)
    y1, y2, y3 = (float(v) for v in h)
    t13 = params["mu13"] * Phi * phi / (2 * A * math.sqrt(y1 - y3))
    t32 = params["mu32"] * Phi * phi / (2 * A * math.sqrt(y3 - y2))
    t20 = params["mu20"] * Phi * phi / (2 * A * math.sqrt(y2))
    F = np.array(F_in_fractions(t13, t32, t20), dtype=float)
    B = np.array([[1 / A, 0.0], [0.0, 1 / A], [0.0, 0.0]])
    return F, B


#: Sec. IV: the closed-loop eigenvalues placed by the tracking controller (eq. 13-16),
#: discrete time (ts = 1 s).
POLES: tuple[float, ...] = (0.92, 0.97, 0.90, 0.95, 0.94)

#: Sec. IV: the printed state-feedback gain of the augmented model (14), printed as
#: ``1e-4 x [...]`` (u in m^3/s, x in m).
K: np.ndarray = 1e-4 * np.array([[21.6, 3.0, -5.0, -0.95, -0.32],
                                 [2.9, 19.0, -4.0, -0.30, -0.91]])

#: Sec. IV: initial estimate of the adaptive Kalman filter (m).
AKF_X0: tuple[float, float, float] = (0.9, 0.55, 0.5)
#: Sec. IV: initial covariance P0 = 10 I3 (m^2), as the scalar factor.
AKF_P0: float = 10.0
#: Sec. IV: initial process noise covariance Q0 = 1e-12 I3 (m^2), as the scalar factor.
AKF_Q0: float = 1e-12
#: Sec. IV: measurement noise covariance R0 = 5^2 (m^2).
AKF_R0: float = 25.0

#: Table I: peak level h* of every tank (m).
HMAX: float = 0.62
#: Sec. IV, Fig. 8: what the paper says of the AKF run (no number is printed): the estimates
#: follow the true levels and the estimation errors stay small and bounded; Sec. III (eq. 38)
#: rests this on (Ad, H) observable and P0 > 0.
AKF_CLAIM: str = ("the estimated outputs closely follow the true states; the estimation errors "
                  "remain small and bounded")

#: Sec. IV: the nonlinear control input u = alpha + beta zeta as printed (text).
LAW_PRINTED: dict[str, str] = {
    "law": "u = (1/A) [-q13; q32 - q20] + [[A, 0], [0, A]] zeta",
    "alpha": "(1/A) [-q13; q32 - q20]",
    "beta": "[[A, 0], [0, A]]",
    "Lambda": "[[1/A, 0], [0, 1/A]]",
    "Lambda0": "[-q13/A; (q32 - q20)/A]",
}

#: The same printed terms in LaTeX (math mode).
LAW_PRINTED_LATEX: dict[str, str] = {
    "alpha": r"\tfrac{1}{A}\begin{bmatrix}-q_{13}\\ q_{32}-q_{20}\end{bmatrix}",
    "beta": r"\begin{bmatrix}A & 0\\ 0 & A\end{bmatrix}",
    "Lambda": r"\begin{bmatrix}\tfrac{1}{A} & 0\\ 0 & \tfrac{1}{A}\end{bmatrix}",
    "Lambda0": r"\tfrac{1}{A}\begin{bmatrix}-q_{13}\\ q_{32}-q_{20}\end{bmatrix}",
}

#: What is wrong in the printed law (eq. 22-24 give alpha = -Lambda^-1 Lambda0 = [q13; q20 - q32]).
LAW_NOTE = ("the printed alpha equals Lambda_0 (1/A instead of A, opposite sign); the printed "
            "Lambda, Lambda_0 and beta agree with the derivation")


def printed_law(params: Mapping[str, float], h: Sequence[float]) -> dict[str, np.ndarray]:
    """The printed ``alpha``, ``beta``, ``Lambda`` and ``Lambda0`` of Sec. IV, evaluated at ``h``.

    Outputs are (h1, h2). The flows are ``q13 = mu13 Phi sqrt(2 g (h1 - h3))``,
    ``q32 = mu32 Phi sqrt(2 g (h3 - h2))``, ``q20 = mu20 Phi sqrt(2 g h2)`` (m^3/s).

    Parameters
    ----------
    params : mapping
        As for `printed_F`.
    h : sequence of 3 floats
        Levels (m) with ``h1 > h3 > h2 > 0``.

    Returns
    -------
    dict
        ``alpha`` (2,) as printed, in m/s (an input needs m^3/s: the printed alpha is
        ``Lambda0``), ``beta`` (2, 2) m^2, ``Lambda`` (2, 2) 1/m^2, ``Lambda0`` (2,) m/s.
    """
    A, Phi, g = params["A"], params["Phi"], params["g"]
    h1, h2, h3 = (float(v) for v in h)
    q13 = params["mu13"] * Phi * math.sqrt(2 * g * (h1 - h3))
    q32 = params["mu32"] * Phi * math.sqrt(2 * g * (h3 - h2))
    q20 = params["mu20"] * Phi * math.sqrt(2 * g * h2)
    return {
        "alpha": np.array([-q13, q32 - q20]) / A,
        "beta": np.array([[A, 0.0], [0.0, A]]),
        "Lambda": np.array([[1 / A, 0.0], [0.0, 1 / A]]),
        "Lambda0": np.array([-q13 / A, (q32 - q20) / A]),
    }
