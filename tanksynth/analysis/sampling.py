"""Is the sampling period short enough for the plant? Time constants of the linearisation.

A period longer than the plant's slowest time constant samples every mode after it has
(nearly) settled: the ZOH model ``Ad = exp(F ts)`` then has eigenvalues ``exp(-ts / tau)``
that are tiny (zero to machine precision for the fast modes), and a discrete design or
estimator built on it sees the plant as (almost) static between samples. `sampling_warning`
says so, naming the time constants.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["TimeConstants", "time_constants", "sampling_warning"]


@dataclass(frozen=True)
class TimeConstants:
    """Time constants ``tau = -1 / Re(lambda)`` of the stable modes of a continuous ``F``.

    Attributes
    ----------
    taus : ndarray
        One per stable eigenvalue of ``F`` (s), sorted ascending (fastest first);
        modes with ``Re(lambda) >= 0`` (integrators, unstable modes) have none.
    """

    taus: np.ndarray

    @property
    def slowest(self) -> float:
        """The largest time constant (s); nan when no mode is stable."""
        return float(self.taus[-1]) if self.taus.size else float("nan")

    @property
    def fastest(self) -> float:
        """The smallest time constant (s); nan when no mode is stable."""
        return float(self.taus[0]) if self.taus.size else float("nan")


def time_constants(F: npt.ArrayLike) -> TimeConstants:
    """Time constants of the stable modes of a continuous state matrix.

    Parameters
    ----------
    F : array_like, shape (n, n)
        Continuous-time state matrix (1/s).

    Returns
    -------
    TimeConstants
    """
    eigs = np.linalg.eigvals(np.atleast_2d(np.asarray(F, dtype=float)))
    stable = eigs.real[eigs.real < 0.0]
    return TimeConstants(np.sort(-1.0 / stable))


def sampling_warning(F: npt.ArrayLike, ts: float) -> str:
    """One line when ``ts`` exceeds the slowest time constant of ``F`` (``""`` otherwise).

    Parameters
    ----------
    F : array_like, shape (n, n)
        Continuous-time state matrix of the linearisation at the operating point (1/s).
    ts : float
        Sampling period (s).

    Returns
    -------
    str
        E.g. ``"the sampling period ts = 1000 s is longer than the plant's slowest time
        constant (456 s, 2.2x; fastest 27.2 s, 37x): the ZOH modes exp(-ts/tau) are 1.1e-16,
        2.8e-08, 0.11 (1 below machine epsilon 2.2e-16: zero in the discrete model);
        ... sample faster (ts of about tau_fastest / 10 = 2.72 s)"``.
    """
    tc = time_constants(F)
    if not tc.taus.size or not ts > tc.slowest:
        return ""
    factors = ", ".join(f"{z:.2g}" for z in np.exp(-ts / tc.taus))
    eps = float(np.finfo(float).eps)
    lost = int(np.count_nonzero(np.exp(-ts / tc.taus) < eps))
    settled = f"the ZOH modes exp(-ts/tau) are {factors}" + (
        f" ({lost} below machine epsilon {eps:.2g}: zero in the discrete model)" if lost else "")
    return (f"the sampling period ts = {ts:g} s is longer than the plant's slowest time constant "
            f"({tc.slowest:.3g} s, {ts / tc.slowest:.2g}x; fastest {tc.fastest:.3g} s, "
            f"{ts / tc.fastest:.2g}x): {settled}; a discrete design sees the plant settled between "
            f"samples: sample faster (ts of about tau_fastest / 10 = {tc.fastest / 10:.3g} s)")
