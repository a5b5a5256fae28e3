"""`Experiment`: one logged run of a plant, in the plant's signal names and units."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Experiment"]


@dataclass(frozen=True, eq=False)
class Experiment:
    """One logged experiment: inputs held between samples, outputs sampled, in plant units.

    Parameters
    ----------
    name : str
        Short name (the file's stem), unique among the experiments of one fit or replay.
    source : str
        The file it was read from, as given (named in every message about it).
    t : ndarray, shape (N,)
        Sample times (s), finite and strictly increasing, ``N >= 2``.
    u : ndarray, shape (N, m)
        Plant inputs in the plant's input units, finite; ``u[k]`` is held on
        ``[t[k], t[k+1])`` (zero-order hold, as a sampled rig applies them).
    y : ndarray, shape (N, p)
        Measured outputs in the plant's output units; NaN where a sample is missing.
    input_names, output_names : tuple of str
        The plant's names of the columns of ``u`` and ``y`` (``output_names`` may be a subset
        of the plant's outputs: an output not logged is not a column).
    censored_low, censored_high : ndarray of bool, shape (N, p)
        The sample sits at the sensor's lower / upper limit: the true output is at or beyond
        it, so the sample counts only where a model's output is inside the limit.
    limits : tuple of (float, float)
        Sensor range of each output column (``-inf``/``inf`` where none is declared).
    x_ref : ndarray or None, shape (N, n)
        Logged reference states (plant state units; NaN where missing), e.g. levels read by a
        second sensor; None when the log has none. Used for NEES in a replay.
    """

    name: str
    source: str
    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    censored_low: np.ndarray
    censored_high: np.ndarray
    limits: tuple[tuple[float, float], ...]
    x_ref: np.ndarray | None = field(default=None)

    @property
    def samples(self) -> int:
        """Number of sample times ``N``."""
        return int(self.t.shape[0])

    @property
    def observed(self) -> np.ndarray:
        """Mask (N, p) of samples that count as exact values (present and not censored)."""
        return ~np.isnan(self.y) & ~self.censored_low & ~self.censored_high

    @property
    def uniform_period(self) -> float | None:
        """The sampling period (s) when the samples are equally spaced (to 1e-9 relative), else None."""
        dt = np.diff(self.t)
        period = float(np.median(dt))
        return period if np.allclose(dt, period, rtol=1e-9, atol=0.0) else None
