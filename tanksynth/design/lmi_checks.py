"""What every LMI design shares: the re-check of returned matrices, the solver table, the
conditioning bound.

DESIGN.md's rule for LMIs: after every solve the returned matrices are re-checked in numpy,
independently of the solver's status, and a gain whose check fails is refused. Each re-check
item is an `LMICheck` (what was checked, the value, the limit, passed or not), listed in the
design's diagnostics.

The homogeneous LMIs are normalised by a conditioning bound ``kappa`` on the Lyapunov matrix
(``trace P <= kappa n`` for the observer LMI of seed 001, ``X <= kappa I`` for the region LMIs):
when a refused LMI has its matrix at the bound, the bound, not the plant, limits the margin. The
designs then retry with ``kappa`` times `KAPPA_STEP` up to their ``kappa_max`` option; the bound
counts as active when the matrix reaches `KAPPA_ACTIVE` of it (`kappa_active`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from tanksynth.design.matrices import symmetrized
from tanksynth.errors import SpecError

__all__ = ["LMICheck", "RELATIONS", "holds", "SOLVERS", "check_solver", "KAPPA_STEP", "KAPPA_ACTIVE", "kappa_active"]

#: Solvers accepted for the LMIs (Clarabel is the default, SCS for comparisons).
SOLVERS = ("CLARABEL", "SCS")
#: Factor by which ``kappa`` is relaxed on each retry of a refused LMI (up to ``kappa_max``).
KAPPA_STEP = 100.0
#: The conditioning bound is active when the bounded quantity reaches this fraction of it.
KAPPA_ACTIVE = 1.0 - 1e-3


#: The directions a re-check compares its value to its limit in.
RELATIONS = ("<=", "<", ">=", ">")


def holds(value: float, relation: str, limit: float, tolerance: float = 0.0) -> bool:
    """Whether ``value relation limit`` holds, the tolerance given to the value's side: ``value <=
    limit + tolerance`` for ``"<="``/``"<"`` (strict: ``<``), ``value >= limit - tolerance`` for
    ``">="``/``">"``.

    Parameters
    ----------
    value, limit : float
        The checked quantity and its bound (same units).
    relation : {"<=", "<", ">=", ">"}
        Direction of the test.
    tolerance : float
        Non-negative allowance for rounding (units of ``value``); a value beyond the limit by at
        most this much passes.
    """
    if relation not in RELATIONS:
        raise ValueError(f"relation must be one of {RELATIONS}, got {relation!r}")
    if relation == "<=":
        return bool(value <= limit + tolerance)
    if relation == "<":
        return bool(value < limit + tolerance)
    if relation == ">=":
        return bool(value >= limit - tolerance)
    return bool(value > limit - tolerance)


@dataclass(frozen=True)
class LMICheck:
    """One item of the independent numpy re-check.

    Attributes
    ----------
    name : str
        What was checked (``"LMI (28) block matrix"``, ``"P > 0"``, ...).
    value : float
        The checked quantity (a largest or smallest eigenvalue, or a real
        part), in the units given by ``unit``.
    limit : float
        The bound it had to satisfy.
    passed : bool
    unit : str
        Units/normalisation of ``value``.
    relation : str
        Direction of the test (one of `RELATIONS`; empty when not recorded).
    tolerance : float
        Allowance the test gave the value beyond the limit (see `holds`).
    """

    name: str
    value: float
    limit: float
    passed: bool
    unit: str = ""
    relation: str = ""
    tolerance: float = 0.0

    @classmethod
    def test(cls, name: str, value: float, relation: str, limit: float, tolerance: float = 0.0,
             unit: str = "") -> "LMICheck":
        """The check ``value relation limit`` (within ``tolerance``, see `holds`), decided here.

        Parameters
        ----------
        name : str
            What is checked, as the report prints it.
        value : float
            The re-computed quantity, in ``unit``.
        relation : str
            ``"<="`` or ``">="``: the direction of the test.
        limit : float
            The bound the value is tested against, in ``unit``.
        tolerance : float, optional
            Slack allowed past ``limit``, in ``unit`` (default 0).
        unit : str, optional
            Unit of ``value`` and ``limit`` (default: none).

        Returns
        -------
        LMICheck
            The check with ``passed`` decided by `holds`.
        """
        return cls(name, float(value), float(limit), holds(float(value), relation, float(limit), tolerance),
                   unit, relation, float(tolerance))

    def as_dict(self) -> dict:
        """JSON-friendly form (``relation`` and ``tolerance`` when the test recorded them)."""
        out = {"name": self.name, "value": self.value, "limit": self.limit,
               "passed": self.passed, "unit": self.unit}
        if self.relation:
            out.update(relation=self.relation, tolerance=self.tolerance)
        return out


def check_solver(solver: str) -> None:
    """Refuse a solver outside `SOLVERS` (`SpecError` keyed ``solver``).

    Parameters
    ----------
    solver : str
        A cvxpy solver name.
    """
    if solver not in SOLVERS:
        raise SpecError(f"unknown solver {solver!r}; expected one of {list(SOLVERS)}", key="solver")


def kappa_active(P: Any, kappa: float, bound: str = "trace") -> bool:
    """Whether the Lyapunov matrix sits at the conditioning bound (to `KAPPA_ACTIVE`).

    Parameters
    ----------
    P : array_like, shape (n, n)
        Lyapunov matrix of the normalised problem (``P >= I``); dimensionless.
    kappa : float
        The bound (dimensionless).
    bound : {"trace", "eigenvalue"}
        ``"trace"``: the bound ``trace P <= kappa n`` (observer LMI of seed 001);
        ``"eigenvalue"``: the bound ``P <= kappa I`` (largest eigenvalue of the symmetric part).

    Returns
    -------
    bool
    """
    P = np.atleast_2d(np.asarray(P, dtype=float))
    if bound == "trace":
        return bool(np.trace(P) >= KAPPA_ACTIVE * kappa * P.shape[0])
    if bound == "eigenvalue":
        return bool(np.max(np.linalg.eigvalsh(symmetrized(P))) >= KAPPA_ACTIVE * kappa)
    raise ValueError(f"bound must be 'trace' or 'eigenvalue', got {bound!r}")
