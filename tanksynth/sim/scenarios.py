"""Test scenarios from the seed papers, as data the simulator runs.

A `Scenario` says what happens to the plant (initial state, set-points,
water added or removed, parameter mismatch, faults from a given sample,
noise) and which samples the metrics look at (set-point steps,
disturbances). `Scenario.setup` turns it into concrete arrays for one plant
and operating point; `run_scenario` simulates it with a closed loop.

=====================  =================================================================
``servo``              set-point step of +0.04 m at sample 100 (seed 002 5.1)
``regulatory``         water added at sample 50, removed at sample 250 (seed 002 5.1)
``mismatch``           estimator starts at (0, 0, 0.23), plant at (0.28, 0.28, 0.23) m
                       (seed 002 5.2)
``uncertainty_plus``   areas and valve coefficients of the model 10 % above the plant's
``uncertainty_minus``  ... and 10 % below (seed 002 5.3)
``leakage``            leak of the closed valve 5 from sample 100 (seed 002 5.4)
``clogging``           valve 6 partly clogged from sample 100 (seed 002 5.4)
``dynamic_steps``      dynamic step references of h1 and h2 (seed 000 figures 6-7)
``additive_fault``     leak fault delta_bar from t_f = 2 s (seed 004)
=====================  =================================================================

Values the papers do not publish (amount of water added, leak and clogging
sizes, the step times of seed 000's references, the fault size of seed 004,
noise levels) are our choices, listed in each scenario's ``assumptions``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable, ClassVar, Mapping, Sequence

import numpy as np
import numpy.typing as npt

from tanksynth.errors import SpecError
from tanksynth.plants.base import Plant
from tanksynth.sim.simulate import BatchEstimator, ParameterChange, SimulationResult, StateJump, simulate

__all__ = [
    "Scenario",
    "ScenarioSetup",
    "InputSchedule",
    "SCENARIOS",
    "CONTROL_BENCHMARK_SCENARIOS",
    "scenario",
    "uncertain_parameters",
    "run_scenario",
]


@dataclass(frozen=True)
class InputSchedule:
    """Open-loop input that is piecewise constant in time (a `ControlLaw`).

    Attributes
    ----------
    times : tuple of float
        Switching times (s), increasing; ``values[i]`` holds from
        ``times[i]`` on (``values[0]`` also before ``times[0]``).
    values : tuple of tuple of float
        Input vectors, in the plant's input units.
    """

    times: tuple[float, ...]
    values: tuple[tuple[float, ...], ...]

    #: The input never depends on the estimate: `simulate` runs an estimator after the plant.
    open_loop: ClassVar[bool] = True

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """The input at time ``t`` for every run, shape (M, m)."""
        i = max(int(np.searchsorted(np.asarray(self.times), t + 1e-12, side="right")) - 1, 0)
        return np.tile(np.asarray(self.values[i], dtype=float), (x_hat.shape[0], 1))


@dataclass(frozen=True)
class ScenarioSetup:
    """A scenario made concrete for one plant and operating point.

    Attributes
    ----------
    scenario : Scenario
    steps : int
    x0, x_hat0 : ndarray, shape (n,)
        Initial plant state and initial estimate (state units).
    reference : ndarray, shape (N + 1, r)
        Set-points of the tracked states at each sample.
    tracked : tuple of int
        State indices that the reference components refer to.
    parameters : dict
        Plant parameter values for the whole run (mismatch).
    changes : tuple of ParameterChange
    jumps : tuple of StateJump
    setpoint_samples, disturbance_samples : tuple of int
        Samples where the set-point steps / a disturbance hits.
    u_init : ndarray, shape (m,)
    controller : callable or None
        Open-loop input schedule of the scenario, if it prescribes one.
    """

    scenario: "Scenario"
    steps: int
    x0: np.ndarray
    x_hat0: np.ndarray
    reference: np.ndarray
    tracked: tuple[int, ...]
    parameters: Mapping[str, float]
    changes: tuple[ParameterChange, ...]
    jumps: tuple[StateJump, ...]
    setpoint_samples: tuple[int, ...]
    disturbance_samples: tuple[int, ...]
    u_init: np.ndarray
    controller: Callable | None = None

    @property
    def fault_sample(self) -> int | None:
        """First sample at which a parameter changes (a fault), None without faults."""
        return min((c.sample for c in self.changes), default=None)

    def without_faults(self) -> "ScenarioSetup":
        """The same setup with its parameter changes removed (the fault-free twin)."""
        return replace(self, changes=(),
                       disturbance_samples=tuple(sorted(s for s, _ in self.scenario.jumps)))


@dataclass(frozen=True)
class Scenario:
    """A test scenario (what happens to the plant, and when).

    Attributes
    ----------
    name, description, source : str
    steps : int
        Number of sampling periods.
    plants : tuple of str
        Plant models it applies to (empty: any).
    x0, x_hat0 : tuple of float or None
        Initial plant state / estimate (state units); None: the operating
        point (the estimate defaults to the plant state).
    setpoint_steps : tuple of (int, float)
        ``(sample, step)``: every tracked set-point moves by ``step`` (state
        units) from ``sample`` on.
    reference_steps : tuple of (int, int, float)
        ``(sample, component, step)``: one set-point component moves.
    jumps : tuple of (int, float)
        ``(sample, delta)``: every tracked state jumps by ``delta`` (water
        added (+) or removed (-)).
    parameter_factor : float
        Plant parameters in m^2 (tank areas, valve coefficients) are set to
        ``nominal / parameter_factor``, i.e. the nominal model used by
        estimators and controllers is ``parameter_factor`` times the plant.
    faults : tuple of (int or float, str, str, float)
        ``(when, parameter, kind, value)``: from ``when`` (a sample, or a
        time in s when a float) the parameter becomes ``value`` (kind
        ``"set"``), ``value`` times a reference parameter's nominal value
        (kind ``"times:<name>"``) or its own nominal value times ``value``
        (kind ``"scale"``).
    input_schedule : InputSchedule or None
        Open-loop input the scenario prescribes (seed 004).
    process_std, measurement_std : float
        Noise standard deviations (state units per sample, output units).
    assumptions : tuple of str
        Values chosen by us where the paper gives none.
    """

    name: str
    description: str
    source: str
    steps: int
    plants: tuple[str, ...] = ()
    x0: tuple[float, ...] | None = None
    x_hat0: tuple[float, ...] | None = None
    setpoint_steps: tuple[tuple[int, float], ...] = ()
    reference_steps: tuple[tuple[int, int, float], ...] = ()
    jumps: tuple[tuple[int, float], ...] = ()
    parameter_factor: float = 1.0
    faults: tuple[tuple[Any, str, str, float], ...] = ()
    input_schedule: InputSchedule | None = None
    process_std: float = 0.0
    measurement_std: float = 0.0
    assumptions: tuple[str, ...] = field(default=())

    def applies_to(self, plant: Plant) -> bool:
        """Whether the scenario is defined for this plant model.

        Parameters
        ----------
        plant : Plant
            The plant model.
        """
        return not self.plants or plant.name in self.plants

    def setup(self, plant: Plant, x_op: npt.ArrayLike, u_op: npt.ArrayLike | None = None,
              tracked: Sequence[int] | np.ndarray | None = None, ts: float = 1.0) -> ScenarioSetup:
        """Concrete arrays for one plant and operating point.

        Parameters
        ----------
        plant : Plant
        x_op : array_like, shape (n,)
            Operating levels (state units): initial state (unless the scenario
            gives one) and initial set-points of the tracked states.
        u_op : array_like, shape (m,), optional
            Operating input (input units, held before t = 0); default zeros.
        tracked : sequence of int or ndarray of int, optional
            Indices of the controlled states (default: the first ``m``).
        ts : float
            Sampling period (s), to place faults given in seconds.

        Raises
        ------
        SpecError
            The scenario is not defined for this plant, or a fault time is
            not a whole number of samples.
        """
        if not self.applies_to(plant):
            raise SpecError(f"scenario '{self.name}' is defined for {', '.join(self.plants)}, "
                            f"not for plant '{plant.name}'", key="scenario")
        n = plant.n
        x_point = np.asarray(x_op, dtype=float).reshape(n)
        tracked_states = (tuple(range(min(plant.m, n))) if tracked is None
                          else tuple(int(i) for i in tracked))
        u_init = np.zeros(plant.m) if u_op is None else np.asarray(u_op, dtype=float).reshape(plant.m)
        N = self.steps
        ref = np.tile(x_point[list(tracked_states)], (N + 1, 1))
        for sample, step in self.setpoint_steps:
            ref[sample:] += step
        for sample, comp, step in self.reference_steps:
            ref[sample:, comp] += step
        x0 = x_point.copy() if self.x0 is None else np.asarray(self.x0, dtype=float)
        xh0 = x0.copy() if self.x_hat0 is None else np.asarray(self.x_hat0, dtype=float)
        jumps = []
        for sample, delta in self.jumps:
            d = np.zeros(n)
            d[list(tracked_states)] = delta
            jumps.append(StateJump(sample, tuple(d)))
        nominal = {p.name: p.value for p in plant.parameters}
        params = {}
        if self.parameter_factor != 1.0:
            params = {name: nominal[name] / self.parameter_factor for name in uncertain_parameters(plant)}
        changes = []
        for when, name, kind, value in self.faults:
            if isinstance(when, float):
                k = when / ts
                if abs(k - round(k)) > 1e-9 * max(1.0, abs(k)):
                    raise SpecError(f"scenario '{self.name}': fault time {when} s is not a multiple "
                                    f"of ts = {ts} s", key="sampling.ts")
                when = int(round(k))
            if kind == "set":
                new = value
            elif kind == "scale":
                new = nominal[name] * value
            elif kind.startswith("times:"):
                new = nominal[kind.split(":", 1)[1]] * value
            else:
                raise SpecError(f"unknown fault kind {kind!r}", key="scenario.faults")
            changes.append(ParameterChange(int(when), {name: float(new)}))
        disturbances = tuple(sorted({s for s, _ in self.jumps} | {c.sample for c in changes}))
        setpoint_samples = ({s for s, _ in self.setpoint_steps}
                            | {s for s, _, _ in self.reference_steps})
        if self.x0 is not None:
            setpoint_samples.add(0)  # reaching the set-points from a distant initial state
        return ScenarioSetup(self, N, x0, xh0, ref, tracked_states, params, tuple(changes),
                             tuple(jumps), tuple(sorted(setpoint_samples)), disturbances, u_init,
                             self.input_schedule)


def uncertain_parameters(plant: Plant) -> tuple[str, ...]:
    """Parameters scaled by the uncertainty scenarios: areas and valve coefficients.

    Every parameter in m^2 (tank cross-sections, valve/pipe discharge
    coefficients) or in cm^2 (tank networks).

    Parameters
    ----------
    plant : Plant
        The plant model.
    """
    return tuple(p.name for p in plant.parameters if p.unit in ("m^2", "cm^2"))


_BENCH = "seed 002 (Vellayikot & Vaidyan, JEET 2016) section 5"
_HYBRID = ("hybrid_three_tank",)
_NOISE = ("process noise 1e-5 m and measurement noise 5e-4 m (1 sigma, per sample) are our "
          "choice: the paper's rig noise levels are not published",)

#: Built-in scenarios by name.
SCENARIOS: dict[str, Scenario] = {s.name: s for s in (
    Scenario("servo", "set-points of the tracked levels step by +0.04 m at sample 100", _BENCH + ".1",
             steps=300, setpoint_steps=((100, 0.04),), process_std=1e-5, measurement_std=5e-4,
             assumptions=_NOISE + ("the initial set-points are the operating levels",)),
    Scenario("regulatory", "water added to the tracked tanks at sample 50, removed at sample 250",
             _BENCH + ".1", steps=400, jumps=((50, 0.03), (250, -0.03)), process_std=1e-5,
             measurement_std=5e-4,
             assumptions=_NOISE + ("the amount of water is not published: +-0.03 m of level in each "
                                   "tracked tank",)),
    Scenario("mismatch", "estimator starts at (0, 0, 0.23) m, plant at (0.28, 0.28, 0.23) m",
             _BENCH + ".2", steps=400, plants=_HYBRID, x0=(0.28, 0.28, 0.23), x_hat0=(0.0, 0.0, 0.23),
             process_std=1e-5, measurement_std=5e-4, assumptions=_NOISE),
    Scenario("uncertainty_plus", "model areas and valve coefficients 10 % above the plant's",
             _BENCH + ".3", steps=400, parameter_factor=1.1, process_std=1e-5, measurement_std=5e-4,
             assumptions=_NOISE + ("'+10 %' read as: the model's values are 1.1 times the plant's "
                                   "(the plant's are nominal / 1.1)",)),
    Scenario("uncertainty_minus", "model areas and valve coefficients 10 % below the plant's",
             _BENCH + ".3", steps=400, parameter_factor=0.9, process_std=1e-5, measurement_std=5e-4,
             assumptions=_NOISE + ("'-10 %' read as: the model's values are 0.9 times the plant's",)),
    Scenario("leakage", "closed valve 5 leaks from sample 100", _BENCH + ".4", steps=400,
             plants=_HYBRID, faults=((100, "k5", "times:k1", 0.25),), process_std=1e-5,
             measurement_std=5e-4,
             assumptions=_NOISE + ("leak size not published: k5 = 0.25 k1 from sample 100",)),
    Scenario("clogging", "valve 6 partly clogged from sample 100", _BENCH + ".4", steps=400,
             plants=_HYBRID, faults=((100, "k6", "scale", 0.5),), process_std=1e-5,
             measurement_std=5e-4,
             assumptions=_NOISE + ("clogging size not published: k6 halved from sample 100",)),
    Scenario("dynamic_steps", "dynamic step references of h1 and h2 around the operating point",
             "seed 000 (Widjiantoro et al.) figures 6-7", steps=1000, plants=("three_tank",),
             reference_steps=((100, 0, 0.05), (300, 1, 0.05), (500, 0, -0.05), (700, 1, -0.05)),
             process_std=0.0, measurement_std=0.0,
             assumptions=("the figures' step times and sizes cannot be read: h1 +0.05 m at 100 s, "
                          "h2 +0.05 m at 300 s, back at 500 s and 700 s (ts = 1 s)",)),
    Scenario("additive_fault", "leak fault delta_bar of tank 2 from t_f = 2 s, input 2 then 1",
             "seed 004 section IV", steps=1000, plants=("hydraulic_fault",),
             faults=((2.0, "delta_bar", "set", 0.5),),
             input_schedule=InputSchedule((0.0, 1.0), ((2.0,), (1.0,))),
             assumptions=("fault size not published: delta_bar = 0.5 from t_f = 2 s",
                          "horizon 1000 samples (10 s at ts = 0.01 s)")),
)}

#: The controller benchmark of seed 002 section 5 (servo, regulatory, initial mismatch,
#: +-10 % model uncertainty, leakage, clogging).
CONTROL_BENCHMARK_SCENARIOS = ("servo", "regulatory", "mismatch", "uncertainty_plus", "uncertainty_minus",
                     "leakage", "clogging")


def scenario(name: str) -> Scenario:
    """The built-in scenario called ``name``.

    Parameters
    ----------
    name : str
        Scenario name.

    Raises
    ------
    SpecError
        Unknown name.
    """
    if name not in SCENARIOS:
        raise SpecError(f"unknown scenario {name!r}; expected one of: " + ", ".join(SCENARIOS),
                        key="scenario")
    return SCENARIOS[name]


def run_scenario(setup: ScenarioSetup, plant: Plant, *, ts: float, seeds: Sequence[int] | np.ndarray,
                 controller: Callable | None = None, estimator: BatchEstimator | None = None,
                 substeps: int = 4, **kwargs: Any) -> SimulationResult:
    """Simulate a concrete scenario for every seed (one batch).

    Parameters
    ----------
    setup : ScenarioSetup
    plant : Plant
        The plant with its nominal parameters (the scenario sets mismatch
        and faults).
    ts : float
        Sampling period (s).
    seeds : sequence of int or ndarray of int
        One per run.
    controller : ControlLaw, optional
        Default: the scenario's input schedule, or the operating input held.
    estimator : BatchEstimator, optional
        Default: the true state (perfect estimator).
    substeps : int
        RK4 steps per period.
    **kwargs
        Passed on to `simulate` (e.g. ``event_iterations``).
    """
    return simulate(plant, ts=ts, steps=setup.steps, x0=setup.x0, seeds=seeds,
                    controller=controller if controller is not None else setup.controller,
                    estimator=estimator, reference=setup.reference, x_hat0=setup.x_hat0,
                    u_init=setup.u_init, process_std=setup.scenario.process_std,
                    measurement_std=setup.scenario.measurement_std, parameters=setup.parameters,
                    changes=setup.changes, jumps=setup.jumps, substeps=substeps, **kwargs)
