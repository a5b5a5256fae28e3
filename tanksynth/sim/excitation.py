"""Excitation of training and verification data: set-point steps held by their equilibrium
inputs plus a three-level PRBS (the NARX estimator's data, seed 002 Sec. 3.3, issue 28).

Used by the design (`tanksynth.design.estimators.narx_training`) and by the verdict's fresh
data (`tanksynth.verify.estimators.narx`), so both draw the same kind of signal.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tanksynth.errors import SpecError
from tanksynth.plants.base import Plant

__all__ = ["setpoint_equilibrium", "designed_excitation"]


def setpoint_equilibrium(plant: Plant, levels: Any, tracked: Any = None,
                         guess: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """Equilibrium state and input that hold the tracked states at given levels.

    Solves ``f(x, u) = 0`` for the untracked states and the ``m`` inputs, the tracked
    states fixed (``scipy.optimize.least_squares``, trust region), from ``guess``.

    Parameters
    ----------
    plant : Plant
    levels : array_like, shape (m,)
        Set-points of the tracked states (state units).
    tracked : sequence of int, optional
        Indices of the tracked states (default the first ``m``).
    guess : array_like, shape (n,), optional
        Starting state (state units); default the centre of the plant's region box.

    Returns
    -------
    x : ndarray, shape (n,)
        Equilibrium state (state units).
    u : ndarray, shape (m,)
        Equilibrium input (input units).

    Raises
    ------
    SpecError
        No equilibrium within ``1e-9`` (state units/s) with the input in the actuator range
        (key ``setpoint_range``).
    """
    from scipy.optimize import least_squares

    n, m = plant.n, plant.m
    idx = list(range(m)) if tracked is None else [int(i) for i in tracked]
    free = [i for i in range(n) if i not in idx]
    lv = np.asarray(levels, dtype=float).reshape(len(idx))
    box = np.array([b for b in plant.region.bounds], dtype=float).reshape(n, 2)
    x_guess = (box.mean(axis=1) if guess is None
               else np.asarray(guess, dtype=float).reshape(n)).copy()
    lim = plant.input_limits
    u_guess = np.where(np.isfinite(lim).all(axis=1), lim.mean(axis=1), 0.0)

    def assemble(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.empty(n)
        x[idx] = lv
        x[free] = z[:len(free)]
        return x, z[len(free):]

    def res(z: np.ndarray) -> np.ndarray:
        x, u = assemble(z)
        return np.asarray(plant.compiled.rhs(x[None], u[None]), dtype=float)[0] * 1e3

    sol = least_squares(res, np.concatenate([x_guess[free], u_guess]), method="trf",
                        xtol=1e-14, ftol=1e-14, gtol=1e-14)
    x, u = assemble(sol.x)
    if not (np.max(np.abs(res(sol.x))) <= 1e-6 and np.all(u >= lim[:, 0] - 1e-12)
            and np.all(u <= lim[:, 1] + 1e-12)):
        raise SpecError(f"no equilibrium holds the tracked states at {lv.tolist()} within the "
                        "actuator range", key="setpoint_range")
    return x, u


def designed_excitation(plant: Plant, rng: np.random.Generator, *, steps: int, runs: int,
                        setpoint_range: Any, hold: tuple[int, int] = (60, 200),
                        prbs_amplitude: float = 0.0, prbs_hold: tuple[int, int] = (3, 20),
                        tracked: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """Initial states and pump sequences of the ``designed`` NARX excitation (seeded).

    Every run starts at the equilibrium of a random set-point and then steps, every ``hold``
    samples, to the equilibrium input of a new set-point drawn uniformly in
    ``setpoint_range`` (a range straddling the pipes' threshold visits both threshold modes;
    a set-point no input in the actuator range holds is redrawn);
    on top of it, every pump gets a three-level PRBS ``{-a, 0, +a}`` switching after a
    random ``prbs_hold`` samples (excitation of the dynamics around each level). Inputs are
    clipped to the actuator range.

    Parameters
    ----------
    plant : Plant
    rng : numpy.random.Generator
        The seeded generator (consumed in a fixed order).
    steps, runs : int
        Samples per run and runs.
    setpoint_range : array_like, shape (2,)
        Lowest and highest set-point of the tracked states (state units).
    hold : (int, int)
        Range of samples a set-point is held.
    prbs_amplitude : float
        PRBS amplitude ``a`` (input units).
    prbs_hold : (int, int)
        Range of samples a PRBS level is held.
    tracked : sequence of int, optional
        Tracked states (default the first ``m``).

    Returns
    -------
    X0 : ndarray, shape (runs, n)
        Initial states (state units).
    U : ndarray, shape (steps, runs, m)
        Inputs (input units).
    """
    lo, hi = (float(v) for v in np.asarray(setpoint_range, dtype=float).reshape(2))
    if not lo < hi:
        raise SpecError("setpoint_range must be [low, high] with low < high", key="setpoint_range")
    m, n = plant.m, plant.n
    lim = plant.input_limits
    X0 = np.empty((runs, n))
    U = np.empty((steps, runs, m))

    def draw() -> tuple[np.ndarray, np.ndarray]:
        for _ in range(100):    # set-point pairs no input can hold are redrawn
            try:
                return setpoint_equilibrium(plant, rng.uniform(lo, hi, m), tracked)
            except SpecError:
                continue
        raise SpecError(f"100 set-points drawn in [{lo:g}, {hi:g}] and none can be held by the "
                        "actuators: narrow setpoint_range", key="setpoint_range")

    for r in range(runs):
        X0[r], _ = draw()
        k = 0
        while k < steps:
            length = int(rng.integers(hold[0], hold[1] + 1))
            U[k:k + length, r] = draw()[1]
            k += length
        for j in range(m):
            k = 0
            while k < steps:
                length = int(rng.integers(prbs_hold[0], prbs_hold[1] + 1))
                U[k:k + length, r, j] += prbs_amplitude * float(rng.integers(-1, 2))
                k += length
    return X0, np.clip(U, lim[:, 0], lim[:, 1])
