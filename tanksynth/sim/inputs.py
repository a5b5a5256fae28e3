"""What the batch simulator calls and is given: estimator and control-law protocols, inputs.

`tanksynth.sim.simulate` integrates M runs of a plant; it calls a
`BatchEstimator` and a `ControlLaw` (protocols, batch over the runs), and is
given the open-loop laws `ConstantInput` / `InputSequence`, the events
`StateJump` / `ParameterChange`, and `EstimatorAdapter` (an estimator of
`tanksynth.runtime.estimators` as a `BatchEstimator`). All are re-exported
by `tanksynth.sim.simulate`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping, Protocol, runtime_checkable

import numpy as np

from tanksynth.errors import DimensionError

__all__ = ["BatchEstimator", "ControlLaw", "StateJump", "ParameterChange", "ConstantInput",
           "InputSequence", "EstimatorAdapter"]


@runtime_checkable
class BatchEstimator(Protocol):
    """What the simulator calls on a state estimator (batch over M runs).

    ``reset(x_hat0)`` sets the initial estimate, shape (M, n), in state
    units; ``step(y, u)`` takes the measurement ``y_k`` (M, q) and the input
    ``u_{k-1}`` held over the previous period (M, m) and returns the
    estimate ``x_hat_k`` (M, n). Estimators with a different interface are
    wrapped in a thin adapter.
    """

    def reset(self, x_hat0: np.ndarray) -> None:
        """Set the estimate at time 0, shape (M, n).

        Parameters
        ----------
        x_hat0 : ndarray, shape (M, n)
            Initial estimates (state units, m).
        """

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One sample: measurement (M, q) and previous input (M, m) -> estimate (M, n).

        Parameters
        ----------
        y : ndarray, shape (M, q)
            Measurements (output units, m).
        u : ndarray, shape (M, m)
            Inputs held over the previous period (input units, m^3/s).
        """


@runtime_checkable
class ControlLaw(Protocol):
    """What the simulator calls on a control law (batch over M runs).

    ``law(x_hat, reference, t)`` maps the estimate (M, n), the reference
    (M, r) and the time ``t`` (s) to the input (M, m), in the plant's input
    units (saturation is applied by the simulator). A stateful law (integral
    action) may also define ``reset(M)``, called once before the first
    sample.
    """

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m) for estimate (M, n) and reference (M, r) at time t (s)."""




# ----------------------------------------------------------------------------- inputs
@dataclass(frozen=True)
class StateJump:
    """Water added to or removed from the tanks at a sample.

    Attributes
    ----------
    sample : int
        Sample index ``k`` (the state at ``t_k`` jumps before it is measured).
    delta : tuple of float
        Change of each state, in state units (e.g. m); the result is clipped.
    """

    sample: int
    delta: tuple[float, ...]


@dataclass(frozen=True)
class ParameterChange:
    """New plant parameter values from a sample on (faults, e.g. a valve leak).

    Attributes
    ----------
    sample : int
        Sample index ``k``: the new values hold from ``t_k`` on.
    values : mapping of str to float or ndarray
        Parameter name -> value in the parameter's unit: one value for every run, or an array of
        shape ``(M,)`` with one value per run of a batch (a fault on half the runs).
    """

    sample: int
    values: Mapping[str, float | np.ndarray]


@dataclass(frozen=True)
class ConstantInput:
    """Open-loop control law holding a constant input (e.g. the equilibrium ``u0``).

    Attributes
    ----------
    u : tuple of float
        Input in the plant's input units.
    """

    u: tuple[float, ...]

    #: The input never depends on the estimate: `simulate` runs an estimator after the plant.
    open_loop: ClassVar[bool] = True

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """The constant input broadcast to (M, m)."""
        return np.broadcast_to(np.asarray(self.u, dtype=float), (x_hat.shape[0], len(self.u))).copy()


class InputSequence:
    """Open-loop control law replaying a given input sequence (one per run).

    Parameters
    ----------
    inputs : array_like, shape (N, m) or (N, M, m)
        Input held over period ``k`` (input units): the same sequence for
        every run, or one per run. The ``k``-th call returns row ``k``;
        `reset` (called by `simulate` before the first sample) rewinds.
    """

    def __init__(self, inputs: Any):
        arr = np.asarray(inputs, dtype=float)
        if arr.ndim not in (2, 3):
            raise DimensionError(f"inputs must have shape (N, m) or (N, M, m), got {arr.shape}")
        self.inputs = arr
        self._k = 0

    def reset(self, runs: int) -> None:
        """Back to the first period (``runs`` must match a per-run sequence).

        Parameters
        ----------
        runs : int
            Number of runs M.
        """
        if self.inputs.ndim == 3 and self.inputs.shape[1] != runs:
            raise DimensionError(f"the input sequence has {self.inputs.shape[1]} runs, the "
                                 f"simulation {runs}")
        self._k = 0

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input of the current period, (M, m)."""
        if self._k >= self.inputs.shape[0]:
            raise DimensionError(f"the input sequence has {self.inputs.shape[0]} periods; period "
                                 f"{self._k} was asked for")
        row = self.inputs[self._k]
        self._k += 1
        if row.ndim == 2:
            if row.shape[0] != x_hat.shape[0]:
                raise DimensionError(f"the input sequence has {row.shape[0]} runs, the "
                                     f"simulation {x_hat.shape[0]}")
            return row.copy()
        return np.repeat(row[None], x_hat.shape[0], axis=0)


class EstimatorAdapter:
    """A `BatchEstimator` from an estimator of `tanksynth.runtime.estimators`.

    Those estimators are built for a number of runs and offer
    ``batch(runs)`` (a fresh twin for M runs), ``reset(x0)`` and ``step(y,
    u)`` with the same sample convention as the simulator. `reset` makes the
    batch twin for the simulation's M runs and sets its initial estimate.

    Parameters
    ----------
    template : object
        An estimator (single run or batch) of the design stage.
    """

    def __init__(self, template: Any):
        self.template = template
        self._est: Any = None

    def reset(self, x_hat0: np.ndarray) -> None:
        """Fresh estimator for ``x_hat0.shape[0]`` runs, started at ``x_hat0`` (M, n).

        Parameters
        ----------
        x_hat0 : ndarray, shape (M, n)
            Initial estimates (state units, m).
        """
        self._est = self.template.batch(int(x_hat0.shape[0]))
        self._est.reset(x_hat0)

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Measurement (M, q) and previous input (M, m) -> estimate (M, n).

        Parameters
        ----------
        y : ndarray, shape (M, q)
            Measurements (output units, m).
        u : ndarray, shape (M, m)
            Inputs held over the previous period (input units, m^3/s).
        """
        return self._est.step(y, u)

    def run(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray | None:
        """Measurements (N, M, q) and previous inputs (N, M, m) -> estimates (N, M, n).

        The same as `step` at each sample in turn (the runtime estimator's ``run``); None
        when a subclass redefines `step` without redefining this (the caller then steps).

        Parameters
        ----------
        Y : ndarray, shape (N, M, q)
            Measurements (output units, m).
        U : ndarray, shape (N, M, m)
            Inputs held over the period before each measurement (input units, m^3/s).
        """
        if type(self).step is not EstimatorAdapter.step:
            return None
        return self._est.run(Y, U)
