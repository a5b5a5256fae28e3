"""A linear model ``x' = A x + B u``, ``y = C x`` as a plant (states ``x1..``, inputs ``u1..``,
outputs ``y1..``).

python-control users hold their model as a ``StateSpace``; `linear_plant_table` writes it as the
``[plant]`` table of a custom plant (``model = "custom"``, one equation per state), so that it
goes through the one spec validator and the one plant builder
(`tanksynth.plants.custom.custom_plant`) like any plant written in a spec. The variables are
deviations from an operating point at the origin (``x0 = 0``, ``u0 = 0``); the operating region is
a box ``|x_i| <= state_bound``, the actuator range ``|u_j| <= input_bound``.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from tanksynth.errors import DimensionError

__all__ = ["linear_plant_table", "statespace_matrices"]


def statespace_matrices(system: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C, D)`` of a continuous-time ``control.StateSpace`` (or anything with those
    attributes and ``dt`` in (None, 0)).

    Parameters
    ----------
    system : control.StateSpace
        A continuous-time model.

    Returns
    -------
    A, B, C, D : ndarray
        As float arrays.

    Raises
    ------
    TypeError
        Not a state-space model, or a discrete-time one (a plant is continuous: give the
        continuous model and the sampling period ``ts``).
    """
    if not all(hasattr(system, name) for name in ("A", "B", "C", "D")):
        raise TypeError(f"expected a control.StateSpace, got {type(system).__name__}")
    dt = getattr(system, "dt", 0)
    if dt not in (None, 0) and dt is not False:
        raise TypeError(f"a discrete-time StateSpace (dt = {dt}) is not a plant: give the continuous "
                        "model and the sampling period ts (the designs discretise it exactly, ZOH)")
    A, B, C, D = (np.atleast_2d(np.asarray(getattr(system, name), dtype=float)) for name in "ABCD")
    return A, B, C, D


def _number(value: float) -> str:
    text = repr(float(value))
    return f"({text})" if text.startswith("-") else text


def _linear_form(row: Sequence[float], names: Sequence[str]) -> str:
    terms = [f"{_number(c)}*{nm}" for c, nm in zip(row, names) if c != 0.0]
    return " + ".join(terms) or "0"


def linear_plant_table(A: Any, B: Any, C: Any, D: Any = None, *, name: str = "linear",
                       state_bound: float = 1.0, input_bound: float = 1.0,
                       unit: str = "1") -> dict[str, Any]:
    """The ``[plant]`` table (custom plant) of ``x' = A x + B u``, ``y = C x``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (1/s).
    B : array_like, shape (n, m)
        Input matrix (state unit per input unit per s).
    C : array_like, shape (q, n)
        Output matrix.
    D : array_like, shape (q, m), optional
        Feedthrough; must be zero (tanksynth's plants measure ``y = h(x)``).
    name : str
        The plant's name.
    state_bound : float
        Operating region ``|x_i| <= state_bound`` (state units, > 0).
    input_bound : float
        Actuator range ``|u_j| <= input_bound`` (input units, > 0).
    unit : str
        Unit of every state, input and output (default dimensionless ``"1"``).

    Returns
    -------
    dict
        ``{"model": "custom", "name", "states", "inputs", "equations", "outputs"}``.

    Raises
    ------
    DimensionError
        Inconsistent shapes, a non-finite entry or a nonzero ``D``.
    """
    A, B, C = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (A, B, C))
    n, m, q = A.shape[0], B.shape[1], C.shape[0]
    if A.shape != (n, n) or B.shape[0] != n or C.shape[1] != n:
        raise DimensionError(f"inconsistent shapes A {A.shape}, B {B.shape}, C {C.shape}")
    Dm = np.zeros((q, m)) if D is None else np.atleast_2d(np.asarray(D, dtype=float))
    if Dm.shape != (q, m) or np.any(Dm != 0.0):
        raise DimensionError(f"D must be zero ({q} x {m}): a plant measures y = C x (no feedthrough)")
    if not all(np.all(np.isfinite(M)) for M in (A, B, C)):
        raise DimensionError("A, B and C must be finite")
    xs, us, ys = ([f"{p}{i + 1}" for i in range(k)] for p, k in (("x", n), ("u", m), ("y", q)))
    box = lambda bound: {"unit": unit, "min": -float(bound), "max": float(bound)}  # noqa: E731
    return {"model": "custom", "name": name,
            "states": {x: box(state_bound) for x in xs},
            "inputs": {u: box(input_bound) for u in us},
            "equations": {x: _linear_form([*A[i], *B[i]], [*xs, *us]) for i, x in enumerate(xs)},
            "outputs": {y: _linear_form(C[i], xs) for i, y in enumerate(ys)}}
