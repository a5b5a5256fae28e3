"""Options of the control laws: ``feedback_linearization``, ``integral_tracking``,
``inverse_dynamics``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np

from tanksynth.spec.method_options.base import MethodOptions, OptionReader, option
from tanksynth.spec.method_options.placement import PLACE_METHODS
from tanksynth.spec.options import (parse_bool, parse_choice, parse_integer, parse_matrix, parse_names,
                                    parse_number, parse_poles, parse_vector)

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["ANTI_WINDUP_SCHEMES", "FeedbackLinearizationOptions", "IntegralTrackingOptions",
           "InverseDynamicsOptions"]

#: Largest number of control periods of the inverse-dynamics tuning scenario.
MAX_SERVO_SAMPLES = 1_000_000

#: Anti-windup schemes of the integral tracking law.
ANTI_WINDUP_SCHEMES = ("back_calculation", "clamping", "none")


@dataclass(frozen=True, eq=False)
class FeedbackLinearizationOptions(MethodOptions):
    """Options of ``feedback_linearization``: exact input-output linearisation with
    decoupling, ``u = alpha(x) + beta(x) zeta``, and a linear outer loop (continuous time).

    Attributes
    ----------
    tracked : tuple of str or None
        The m outputs to decouple, named as the plant's outputs or states;
        default None: every output (the plant must then have m of them).
    poles : tuple of complex or None
        Outer-loop poles (1/s, negative real part), one per relative degree,
        output by output; complex poles in conjugate pairs. Give ``poles``
        or ``bandwidth``.
    bandwidth : ndarray or None
        Outer-loop bandwidths ``omega_i`` (1/s, > 0), one value for every
        output or one per output: all poles of output ``i`` at ``-omega_i``.
    saturate : bool
        Clip ``u`` to the plant's actuator range in the law; default true.
    allow_unstable_zero_dynamics : bool
        Give the law even when the zero dynamics are unstable (recorded);
        default false.
    grid : int
        Grid points per state of the region checks (1 to 101); default 11.
    samples : int
        Random region points of the checks (>= 0); default 400.
    seed : int
        Seed of the random points (>= 0); default 0.
    """

    method_name: ClassVar[str] = "feedback_linearization"
    one_of: ClassVar[tuple[tuple[str, ...], ...]] = (("poles", "bandwidth"),)

    tracked: tuple[str, ...] | None = option(None, unit="-",
                                             required_when="the plant has not as many outputs as inputs")
    poles: tuple[complex, ...] | None = option(None, unit="1/s")
    bandwidth: np.ndarray | None = option(None, unit="1/s")
    saturate: bool = option(True, unit="-")
    allow_unstable_zero_dynamics: bool = option(False, unit="-")
    grid: int = option(11, unit="-")
    samples: int = option(400, unit="-")
    seed: int = option(0, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "FeedbackLinearizationOptions":
        """See `MethodOptions.from_table`; decoupling needs as many outputs as inputs."""
        r = OptionReader(cls, options, key, ts)
        outputs = [s.name for s in plant.outputs]
        known = outputs + [s.name for s in plant.states if s.name not in outputs]
        tracked = r.read("tracked", parse_names, known, what="output or state", count=plant.m)
        if tracked is None and plant.q != plant.m:
            raise r.fail("tracked", f"plant '{plant.name}' has {plant.q} outputs and {plant.m} "
                                    f"inputs: choose {plant.m} outputs (or states) to decouple")
        count = len(tracked) if tracked is not None else plant.q
        bandwidth = r.read("bandwidth", parse_vector, broadcast=True, above=0.0)
        if bandwidth is not None and bandwidth.size not in (1, count):
            raise r.fail("bandwidth", f"expected one bandwidth or one per output ({count}), got "
                                      f"{bandwidth.size}")
        return cls(tracked=tracked, poles=r.read("poles", parse_poles, negative_real=True),
                   bandwidth=bandwidth, saturate=r.read("saturate", parse_bool),
                   allow_unstable_zero_dynamics=r.read("allow_unstable_zero_dynamics", parse_bool),
                   grid=r.read("grid", parse_integer, at_least=1, at_most=101),
                   samples=r.read("samples", parse_integer, at_least=0, at_most=1_000_000),
                   seed=r.read("seed", parse_integer, at_least=0))

    def memory_estimate(self, plant: Plant, ts: float | None) -> tuple[float, str]:
        """``grid^n`` region points plus ``samples``, each with its n x n Jacobian (bytes)."""
        points = float(self.grid) ** plant.n + self.samples
        return 8.0 * 4 * points * (plant.n + plant.n ** 2 + plant.m), "grid"


@dataclass(frozen=True, eq=False)
class IntegralTrackingOptions(MethodOptions):
    """Options of ``integral_tracking``: sampled state feedback with integral action on the
    tracked outputs, pump saturation and anti-windup (ZOH model at ``[sampling] ts``).

    Attributes
    ----------
    poles : tuple of complex
        Required. Discrete-time poles (z-plane) of the augmented system, n + p
        of them (p tracked outputs); complex poles in conjugate pairs. Dimensionless.
    tracked : tuple of str
        Outputs to track (at most m, named as the plant's outputs); default the
        first m outputs.
    algorithm : str
        Placement routine: ``"auto"`` (default), ``"place"`` or ``"acker"``.
    anti_windup : str
        ``"back_calculation"`` (default), ``"clamping"`` or ``"none"``.
    aw_gain : float
        Back-calculation gain, in (0, 1] (dimensionless); default 1.
    reference_gain : ndarray or None
        An m x (n + p) gain to compare with the derived ``K = [K1 K2]``, e.g. a
        published one; default None. In the units of ``K`` (input units per state
        unit for ``K1``, per integrated-output unit for ``K2``).
    """

    method_name: ClassVar[str] = "integral_tracking"
    needs_sampling: ClassVar[bool] = True

    poles: tuple[complex, ...] = option(unit="- (z-plane)")
    tracked: tuple[str, ...] | None = option(None, unit="-")
    algorithm: str = option("auto", unit="-", choices=PLACE_METHODS)
    anti_windup: str = option("back_calculation", unit="-", choices=ANTI_WINDUP_SCHEMES)
    aw_gain: float = option(1.0, unit="-")
    reference_gain: np.ndarray | None = option(None, unit="units of K", default_text="unset: no comparison")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "IntegralTrackingOptions":
        """See `MethodOptions.from_table`; n + p poles for p tracked outputs."""
        r = OptionReader(cls, options, key, ts)
        outputs = [s.name for s in plant.outputs]
        tracked = r.read("tracked", parse_names, outputs, what="output", at_most=plant.m)
        tracked = tuple(outputs[: plant.m]) if tracked is None else tracked
        size = plant.n + len(tracked)
        note = f"{plant.n} states + {len(tracked)} integrators of the tracked outputs {list(tracked)}"
        return cls(poles=r.read("poles", parse_poles, count=size, count_note=note,
                                stable_in="discrete"), tracked=tracked,
                   algorithm=r.read("algorithm", parse_choice, PLACE_METHODS),
                   anti_windup=r.read("anti_windup", parse_choice, ANTI_WINDUP_SCHEMES),
                   aw_gain=r.read("aw_gain", parse_number, above=0.0, at_most=1.0),
                   reference_gain=r.read("reference_gain", parse_matrix, (plant.m, size)))


@dataclass(frozen=True, eq=False)
class InverseDynamicsOptions(MethodOptions):
    """Options of ``inverse_dynamics``: the estimator-based inverse-dynamics law of seed 002
    (eq. 46-47), rates ``C`` given or tuned by minimum ISE on a servo step.

    Attributes
    ----------
    controlled : tuple of str or None
        The m controlled states; default None: the states the inputs act on.
    C : ndarray or None
        Rates ``C_i`` (1/s, >= 0), one value for all or one per controlled
        state; default None: tuned.
    tune : bool
        Tune ``C`` by minimum ISE of the servo scenario; default true
        without ``C``, false with it.
    step : ndarray
        Set-point step of each controlled state (state units), one value for
        all or one per state; default 0.04.
    step_time : float
        Time of the step (s, >= 0); default 100.
    horizon : float
        Length of the servo scenario (s, > step_time, at most 10^6 periods ts); default 300.
    substeps : int
        RK4 substeps per control period of the scenario (1 to 1000); default 10.
    grid : ndarray
        Coarse values of each ``C_i`` tried by the tuning (1/s, >= 2 values
        inside ``bounds``); default 0.1, 0.2, ..., 1.0.
    bounds : ndarray
        Admissible range ``[min, max]`` of each ``C_i`` (1/s, 0 <= min < max);
        default [0, 1].
    saturate : bool
        Clip ``u`` to the actuator range; default true.
    """

    method_name: ClassVar[str] = "inverse_dynamics"
    needs_sampling: ClassVar[bool] = True

    controlled: tuple[str, ...] | None = option(None, unit="-")
    C: np.ndarray | None = option(None, unit="1/s")
    tune: bool | None = option(None, unit="-")
    step: np.ndarray | float = option(0.04, unit="state units")
    step_time: float = option(100.0, unit="s")
    horizon: float = option(300.0, unit="s")
    substeps: int = option(10, unit="-")
    grid: np.ndarray | tuple[float, ...] = option((0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0),
                                                  unit="1/s")
    bounds: np.ndarray | tuple[float, float] = option((0.0, 1.0), unit="1/s")
    saturate: bool = option(True, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "InverseDynamicsOptions":
        """See `MethodOptions.from_table`; ``C`` and ``tune = true`` exclude each other."""
        r = OptionReader(cls, options, key, ts)
        m = plant.m
        controlled = r.read("controlled", parse_names, [s.name for s in plant.states], what="state",
                            count=m)
        C = r.read("C", parse_vector, m, broadcast=True, at_least=0.0)
        tune = r.read("tune", parse_bool)
        if tune is None:
            tune = C is None
        if tune and C is not None:
            raise r.fail("C", "give either C (fixed rates) or tune = true, not both")
        if not tune and C is None:
            raise r.fail("C", "tune = false needs the rates C (1/s)")
        step_time = r.read("step_time", parse_number, at_least=0.0)
        horizon = r.read("horizon", parse_number, above=step_time)
        if ts is not None and horizon / ts > MAX_SERVO_SAMPLES:
            raise r.fail("horizon", f"{horizon:g} s is {horizon / ts:.3g} control periods of ts = "
                                    f"{ts:g} s; at most {MAX_SERVO_SAMPLES:,} are simulated")
        bounds = r.read("bounds", parse_vector, 2, at_least=0.0, parse_default=True)
        if not bounds[0] < bounds[1]:
            raise r.fail("bounds", f"expected [min, max] with min < max, got {bounds.tolist()}")
        grid = r.read("grid", parse_vector, at_least=float(bounds[0]), at_most=float(bounds[1]),
                      parse_default=True)
        if grid.size < 2:
            raise r.fail("grid", f"expected at least 2 values inside bounds {bounds.tolist()}")
        return cls(controlled=controlled, C=C, tune=tune,
                   step=r.read("step", parse_vector, m, broadcast=True, parse_default=True),
                   step_time=step_time, horizon=horizon,
                   substeps=r.read("substeps", parse_integer, at_least=1, at_most=1000), grid=grid,
                   bounds=bounds, saturate=r.read("saturate", parse_bool))

    def memory_estimate(self, plant: Plant, ts: float | None) -> tuple[float, str]:
        """``grid^m`` servo runs of ``horizon / ts`` samples, states and inputs kept (bytes)."""
        runs = float(np.size(self.grid)) ** plant.m
        samples = self.horizon / ts if ts else 1.0
        return 8.0 * 4 * runs * (samples + 1) * (plant.n + plant.m + 1), \
            ("grid" if runs > samples else "horizon")
