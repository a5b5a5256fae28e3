"""The largest parameter for which a monotone family of LMIs is feasible (bisection).

Several designs maximise a scalar that enters their LMIs quasi-convexly: the Lipschitz constant
``psi`` of the observer LMI (28) of seed 001 (`tanksynth.design.observer_lmi.lmi.maximise_psi`,
the weighting search), the decay rate of a Takagi-Sugeno PDC (`tanksynth.design.takagi_sugeno`).
Feasibility is monotone in that scalar, so the largest feasible value is bracketed by doubling
and found by bisection, each trial one LMI solve (and re-check).
"""

from __future__ import annotations

from typing import Callable

__all__ = ["bisect_feasible"]


def bisect_feasible(feasible: Callable[[float], bool], start: float, rtol: float = 1e-3,
                    max_doublings: int = 40, max_steps: int = 60) -> tuple[float, float, list]:
    """Largest ``x >= 0`` with ``feasible(x)`` for a monotone predicate.

    Feasibility must be monotone (feasible at ``x`` implies feasible below
    ``x``), which holds for ``psi`` in eq. (28): the ``psi^2 Q`` term only
    grows. The bracket is found by doubling from ``start``.

    Parameters
    ----------
    feasible : callable
        ``feasible(x) -> bool``.
    start : float
        First trial value (> 0), in the units of ``x`` (1/s for ``psi``).
    rtol : float
        Relative width of the final bracket (dimensionless).
    max_doublings, max_steps : int
        Limits of the bracketing and of the bisection.

    Returns
    -------
    lo : float
        Largest value found feasible (0.0 if only 0 is).
    hi : float
        Smallest value found infeasible (``inf`` if none found).
    history : list of (float, bool)
        Every trial.
    """
    history: list = []

    def test(x: float) -> bool:
        ok = bool(feasible(x))
        history.append((float(x), ok))
        return ok

    lo, hi = 0.0, float(start)
    for _ in range(max_doublings):
        if test(hi):
            lo, hi = hi, 2.0 * hi
        else:
            break
    else:
        return lo, float("inf"), history
    for _ in range(max_steps):
        if hi - lo <= rtol * hi:
            break
        mid = 0.5 * (lo + hi)
        if test(mid):
            lo = mid
        else:
            hi = mid
    return lo, hi, history
