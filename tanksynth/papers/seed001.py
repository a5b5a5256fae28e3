"""Seed 001 (Nagy, Marx, Mourot, Schutz, Ragot, CDC 2009): Takagi-Sugeno three-tank observer.

The quasi-LPV matrix ``A(z)`` of eq. (10), the observability matrices and
determinant of Sec. III-C, the rank claims, and the design of Sec. IV
(weightings ``lambda``, ``gamma``, the Lipschitz constant ``psi``, the gain ``L``),
all as printed. Symbolic values are sympy objects built on call (sympy is imported
lazily); the symbols are ``z1..z3``, ``lambda1..3``, ``gamma1..3``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "G",
    "LAMBDA",
    "GAMMA",
    "PSI",
    "L",
    "RANK_CLAIM",
    "TWO_OUTPUT_CLAIM",
    "FIG2_X0",
    "FIG2_XHAT0",
    "FIG2_CLAIM",
    "symbols",
    "A_eq10",
    "O1",
    "det_O1",
    "O12_entries",
]

#: Gravity as printed (m/s^2).
G: float = 9.82

#: Sec. IV (Fig. 2-3): the initial state of the multiple model as printed (no unit printed; the
#: levels of eq. (1) are in m).
FIG2_X0: tuple[float, float, float] = (1.8, 1.7, 5.5)
#: Sec. IV (Fig. 2-3): the observer's initial estimate as printed.
FIG2_XHAT0: tuple[float, float, float] = (4.8, 5.0, 2.1)
#: Sec. IV: what the paper says of the Fig. 2 run (no number printed).
FIG2_CLAIM: str = "a fast convergence of the state estimation error towards zero is obtained"

#: Sec. IV: the weighting lambda of the premise z1 (-).
LAMBDA: tuple[float, float, float] = (-0.7, 5.0, 17.0)

#: Sec. IV: the weighting gamma of the premise z3 (-).
GAMMA: tuple[float, float, float] = (0.0, -3.0, -1.0)

#: Sec. IV: the Lipschitz constant used in the observer LMI (28) (1/s).
PSI: float = 0.506

#: Sec. IV: the observer gain L (3 x 2, 1/s), outputs (h1, h2).
L: np.ndarray = np.array([[1.42, 0.0], [0.0, 0.97], [-0.08e-2, 0.12e-2]])

#: Sec. III-C: the claim for C = [1 0 0]: rank O1 = 3 iff lambda2 != 0 and lambda3 != 0,
#: as the parameter sets on which the rank drops.
RANK_CLAIM: tuple[dict[str, float], ...] = ({"lambda2": 0.0}, {"lambda3": 0.0})

#: Sec. III-C: the claim for C = [1 0 0; 0 1 0]: avoid lambda3 = gamma3 = 0.
TWO_OUTPUT_CLAIM: tuple[dict[str, float], ...] = ({"lambda3": 0.0, "gamma3": 0.0},)


def symbols() -> tuple[tuple[Any, Any, Any], tuple[Any, Any, Any], tuple[Any, Any, Any]]:
    """The sympy symbols ``(z1, z2, z3), (lambda1..3), (gamma1..3)`` of the paper."""
    import sympy as sp

    return (tuple(sp.symbols("z1 z2 z3")), tuple(sp.symbols("lambda1 lambda2 lambda3")),
            tuple(sp.symbols("gamma1 gamma2 gamma3")))


def A_eq10():
    """``A(z1, z2, z3)`` of eq. (10), as printed (sympy 3 x 3 matrix, 1/s)."""
    import sympy as sp

    (z1, z2, z3), (l1, l2, l3), (g1, g2, g3) = symbols()
    return sp.Matrix([
        [-l1 * z1, -l2 * z1, -l3 * z1],
        [g1 * z3, g2 * z3 - z2, g3 * z3],
        [l1 * z1 - g1 * z3, l2 * z1 - g2 * z3, l3 * z1 - g3 * z3],
    ])


def O1():
    """``O1 = [C; CA; CA^2]`` of Sec. III-C for ``C = [1 0 0]`` with its ``(*)1..(*)3``, as printed."""
    import sympy as sp

    (z1, z2, z3), (l1, l2, l3), (g1, g2, g3) = symbols()
    s1 = l1**2 * z1**2 - l3 * z1 * (l1 * z1 - g1 * z3) - l2 * z1 * g1 * z3
    s2 = l1 * z1**2 * l2 - l2 * z1 * (g2 * z3 - z2) - l3 * z1 * (l2 * z1 - g2 * z3)
    s3 = l1 * l3 * z1**2 - l3 * z1 * (l3 * z1 - g3 * z3) - l2 * z1 * g3 * z3
    return sp.Matrix([[1, 0, 0], [-l1 * z1, -l2 * z1, -l3 * z1], [s1, s2, s3]])


def det_O1():
    """``det(O1)`` of Sec. III-C, as printed (sympy expression)."""
    (z1, z2, z3), (l1, l2, l3), (g1, g2, g3) = symbols()
    return (l2 * g3 * z1**2 * z3 * (l2 - l3) - l3 * l2 * z1**2 * (g2 * z3 + z2)
            + l3**2 * g2 * z1**2 * z3)


def O12_entries() -> dict[tuple[int, int], Any]:
    """Printed entries of ``O_{1,2}`` (C = [1 0 0; 0 1 0], rows C, CA, CA^2), 1-based.

    Only the entries the reference tests compare: (3, 2) of the row printed as
    ``[-l1 z1, -l2 z2, -l3 z1]``, and (5, 1) .. (6, 3).
    """
    (z1, z2, z3), (l1, l2, l3), (g1, g2, g3) = symbols()
    return {
        (3, 2): -l2 * z2,
        (5, 1): l1 * z1**2 * (l1 - l3) + g1 * l3 * z1 * z3,
        (5, 2): z1 * (l2 * z1 * (l1 - l3) - g2 * z3 * (l2 - l3) + l2 * z2),
        (5, 3): l3 * z1**2 * (l1 - l3) - g3 * z1 * z3 * (l2 - l3),
        (6, 1): l1 * z1 * z3 * (g3 - g1) - g1 * z3 * (z2 - z3 * (g3 - g2)),
        (6, 2): (g2 * z3 - z2)**2 - g2 * g3 * z3**2,
        (6, 3): g3 * z3 * ((g2 - g3) * z3 - z2 + l3 * z1) - l3 * g1 * z1 * z3,
    }
