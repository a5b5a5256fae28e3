"""The operating point every linear design starts from: its equilibrium input and the model there.

A design linearises at the spec's operating levels ``x0`` with the equilibrium input computed
from the model (the spec's ``u`` is only checked against it), ZOH-discretised with ``[sampling]
ts`` when the design is discrete (`tanksynth.analysis.linearize`).

===================  ===============================================================
`equilibrium_at`     the input that balances ``f(x0, u) = 0`` (the spec's ``u`` checked)
`linearized_at`      the Jacobian linearisation about ``(x0, u0)``, discretised with ``ts``
`discrete_pair`      ``(Ad, Bd)`` of a linearisation that was discretised
`sampling_period`    the spec's ``[sampling] ts``, which a discrete design needs
`time_domain_of`     the validated ``time_domain`` option of a linear design
`as_levels`          levels as the plant and analysis functions annotate them
===================  ===============================================================
"""

from __future__ import annotations

from typing import Any, Sequence, cast

import numpy as np

from tanksynth.analysis.linearize import Equilibrium, LinearModel, equilibrium_input, linearize
from tanksynth.errors import SpecError
from tanksynth.plants.base import Plant
from tanksynth.spec import Spec

__all__ = ["equilibrium_at", "linearized_at", "discrete_pair", "sampling_period", "time_domain_of",
           "as_levels"]


def as_levels(x: np.ndarray) -> Sequence[float]:
    """Levels (or inputs) as the plant and analysis functions annotate them: the same array.

    Those functions annotate a point as a sequence of floats and read it with ``np.asarray``;
    the array is passed as it is (a cast for the type checker, no conversion: the numbers are
    the same bit for bit).

    Parameters
    ----------
    x : ndarray, shape (n,)
        A point (state units, or input units).

    Returns
    -------
    sequence of float
        ``x`` itself.
    """
    return cast(Sequence[float], x)


def equilibrium_at(plant: Plant, x0: np.ndarray, given_u0: np.ndarray | None = None) -> Equilibrium:
    """The equilibrium input at the operating levels (`tanksynth.analysis.linearize.equilibrium_input`).

    Parameters
    ----------
    plant : Plant
        The plant model.
    x0 : ndarray, shape (n,)
        Operating levels (state units).
    given_u0 : ndarray, shape (m,), optional
        The input the spec states (input units): its residual is reported, not used.

    Returns
    -------
    Equilibrium
    """
    return equilibrium_input(plant, as_levels(x0), None if given_u0 is None else as_levels(given_u0))


def linearized_at(plant: Plant, x0: np.ndarray, u0: np.ndarray, ts: float | None = None) -> LinearModel:
    """The Jacobian linearisation about ``(x0, u0)`` (`tanksynth.analysis.linearize.linearize`).

    Parameters
    ----------
    plant : Plant
        The plant model.
    x0 : ndarray, shape (n,)
        Operating levels (state units).
    u0 : ndarray, shape (m,)
        Operating input (input units), usually the equilibrium input.
    ts : float, optional
        Sampling period (s): also the exact ZOH discretisation ``Ad``, ``Bd``.

    Returns
    -------
    LinearModel
    """
    return linearize(plant, as_levels(x0), as_levels(u0), ts=ts)


def discrete_pair(lin: LinearModel) -> tuple[np.ndarray, np.ndarray]:
    """``(Ad, Bd)`` of a linearisation discretised with a sampling period.

    Parameters
    ----------
    lin : LinearModel
        From `linearized_at` with ``ts``.

    Returns
    -------
    Ad : ndarray, shape (n, n)
        Dimensionless.
    Bd : ndarray, shape (n, m)
        State units per input unit.

    Raises
    ------
    ValueError
        The linearisation was not discretised (no ``ts``).
    """
    if lin.Ad is None or lin.Bd is None:
        raise ValueError("the linearisation was not discretised: give a sampling period ts")
    return lin.Ad, lin.Bd


def sampling_period(spec: Spec) -> float:
    """The spec's sampling period, which a discrete design needs.

    Parameters
    ----------
    spec : Spec
        The validated spec.

    Returns
    -------
    float
        ``[sampling] ts`` (s).

    Raises
    ------
    SpecError
        The spec has no ``[sampling] ts`` (the options of a discrete design refuse it when the
        spec is parsed; this is the same refusal for a spec built otherwise).
    """
    if spec.ts is None:
        raise SpecError("a discrete-time design needs a sampling period: add [sampling] ts = ...",
                        key="sampling.ts")
    return spec.ts


def time_domain_of(options: Any) -> str:
    """The time domain of a linear design's validated options.

    Parameters
    ----------
    options : MethodOptions
        Validated options with a ``time_domain`` option (filled in from ``[sampling] ts`` when
        the spec omits it).

    Returns
    -------
    str
        ``"continuous"`` or ``"discrete"``.

    Raises
    ------
    SpecError
        No time domain: options that were not validated.
    """
    domain = options.time_domain
    if domain is None:
        raise SpecError("no time domain: the options were not validated", key="time_domain")
    return str(domain)
