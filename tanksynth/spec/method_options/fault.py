"""Options of ``fault_detection``: observer residual with a derived detection threshold."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np

from tanksynth.errors import SpecError
from tanksynth.spec.method_options.base import MethodOptions, OptionReader, option
from tanksynth.spec.options import parse_bool, parse_number, parse_poles, parse_vector

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["FaultDetectionOptions"]


def _bounds(value: Any, key: str) -> tuple[float, float]:
    """``[lower, upper]`` with lower < upper."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise SpecError(f"expected bounds = [lower, upper], got {value!r}", key=key)
    lo, hi = (float(v) for v in parse_vector(value, key, 2))
    if not lo < hi:
        raise SpecError(f"expected bounds = [lower, upper] with lower < upper, got [{lo:g}, {hi:g}]",
                        key=key)
    return lo, hi


def _states(value: Any, key: str, names: list[str]) -> tuple[np.ndarray, ...]:
    """A non-empty list of state vectors (lists of n numbers or tables keyed by state names)."""
    if not isinstance(value, (list, tuple)) or not value:
        raise SpecError(f"expected a list of initial states, each {len(names)} values "
                        f"({', '.join(names)})", key=key)
    return tuple(parse_vector(v, f"{key}[{i}]", names=names) for i, v in enumerate(value))


def _schedule(value: Any, key: str, m: int) -> tuple[np.ndarray, ...]:
    """Input held from t = 0: one number (every input), m values, or pieces
    ``[[t_start, u_1 .. u_m], ...]`` (s, input units) from 0 with increasing starts."""
    if not isinstance(value, (list, tuple)) or not value or \
            not all(isinstance(p, (list, tuple)) for p in value):
        u = parse_vector(value, key, m, broadcast=True)
        return (np.concatenate([[0.0], u]),)
    pieces = tuple(parse_vector(p, f"{key}[{i}]", m + 1) for i, p in enumerate(value))
    starts = [float(p[0]) for p in pieces]
    if starts[0] != 0.0 or any(b <= a for a, b in zip(starts, starts[1:])):
        raise SpecError(f"expected pieces [t_start, u...] starting at t = 0 with increasing "
                        f"starts, got starts {starts}", key=key)
    for p in pieces:
        p.flags.writeable = False
    return pieces


@dataclass(frozen=True, eq=False)
class FaultDetectionOptions(MethodOptions):
    """Options of ``fault_detection``: a Luenberger observer (canonical-form gain) of the healthy
    linear single-output plant, its output residual and the threshold bounding the residual
    of every healthy start with levels in ``(lower, upper]``; detection times of a declared
    fault from given initial states.

    Attributes
    ----------
    poles : tuple of complex
        Observer poles (1/s): n distinct real values; default (-5, -8, -10).
    bounds : tuple of float
        ``(lower, upper)`` of every initial level (state units, lower <
        upper); the observer starts at ``lower``; default (0.25, 4.0).
    delta_bar : float
        Declared fault size (> 0, the unit of the plant's fault parameter,
        1/s for a leak); default 1.
    t_fault : float
        Fault onset (s, > 0); default 2.
    conservative : bool
        Threshold with every term taken positive (true, default) or the
        exact bound.
    initial_states : tuple of ndarray or None
        Plant initial states (n values each, state units, inside ``(lower,
        upper]``) whose detection times are computed; default None: the
        operating point alone.
    input : tuple of ndarray or None
        Input of the detection-time runs, as pieces ``[t_start, u_1 .. u_m]``
        (s, input units) from t = 0 (one number or m values: held from 0);
        default None: the equilibrium input of the operating point, held.
    """

    method_name: ClassVar[str] = "fault_detection"

    poles: tuple[complex, ...] = option((-5.0, -8.0, -10.0), unit="1/s")
    bounds: tuple[float, float] = option((0.25, 4.0), unit="state units")
    delta_bar: float = option(1.0, unit="unit of the fault parameter (1/s for a leak)")
    t_fault: float = option(2.0, unit="s")
    conservative: bool = option(True, unit="-")
    initial_states: tuple[np.ndarray, ...] | None = option(None, unit="state units")
    input: tuple[np.ndarray, ...] | None = option(None, unit="s, input units")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "FaultDetectionOptions":
        """See `MethodOptions.from_table`; a single-output plant, starts inside the bounds."""
        r = OptionReader(cls, options, key, ts)
        if plant.q != 1:
            raise r.fail("method", f"fault detection needs a single-output plant, plant "
                                   f"'{plant.name}' has {plant.q} outputs")
        lo, hi = r.read("bounds", _bounds, parse_default=True)
        starts = r.read("initial_states", _states, [s.name for s in plant.states])
        for i, x in enumerate(starts or ()):
            if not np.all((x > lo) & (x <= hi)):
                raise r.fail("initial_states", f"initial state {i} = {x.tolist()} is not inside the "
                                               f"bounds ({lo:g}, {hi:g}] of the threshold")
        schedule = r.read("input", _schedule, plant.m)
        return cls(poles=r.read("poles", parse_poles, count=plant.n, real=True, distinct=True,
                                parse_default=True),
                   bounds=(lo, hi), delta_bar=r.read("delta_bar", parse_number, above=0.0),
                   t_fault=r.read("t_fault", parse_number, above=0.0),
                   conservative=r.read("conservative", parse_bool), initial_states=starts,
                   input=schedule)
