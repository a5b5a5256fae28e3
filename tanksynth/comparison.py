"""Estimator + controller combinations compared over a benchmark of scenarios (a study).

It designs (trains the NARX estimator), builds estimators and simulates, so it
sits above the pipeline's stages, beside the method table.

`controller_comparison` runs one control law (default: inverse dynamics,
`InverseDynamicsLaw`) with each estimator given (``label -> factory``) over
a list of scenarios, in this process, and returns the mean metrics of each
(scenario, combination). `comparison_estimators` builds the factories of
EKF, UKF and NARX estimators from one declared tuning; a combination with
no estimator (``None``) feeds back the true state (the perfect-estimator
baseline). Nothing here is specific to a paper: the combinations, tuning,
gains and operating point are arguments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from tanksynth.errors import TanksynthError
from tanksynth.plants.base import Plant
from tanksynth.sim.metrics import compute_metrics
from tanksynth.sim.scenarios import CONTROL_BENCHMARK_SCENARIOS, SCENARIOS, run_scenario
from tanksynth.sim.simulate import BatchEstimator, run_seeds
from tanksynth.verify.laws.campaign import InverseDynamicsLaw

if TYPE_CHECKING:  # the estimators load with the comparison that builds them
    from tanksynth.runtime.estimators.base import KernelEstimator

__all__ = ["ESTIMATOR_KINDS", "FilterTuning", "comparison_estimators", "ComparisonRow",
           "controller_comparison", "train_comparison_narx", "select_narx_structure",
           "StructureCandidate"]

#: Estimator kinds a comparison can build.
ESTIMATOR_KINDS = ("ekf", "ukf", "narx")

EstimatorFactories = Mapping[str, tuple[Callable[[], BatchEstimator] | None, str]]


@dataclass(frozen=True)
class FilterTuning:
    """One tuning for every estimator of a comparison (declared by the caller).

    Attributes
    ----------
    Q : float
        Process noise variance per state and sample (state units^2); ``Q I``.
    R : float
        Measurement noise variance (output units^2); ``R I``.
    P0 : float
        Initial covariance (state units^2); ``P0 I``.
    substeps : int
        RK4 steps of the filters' prediction per period.
    narx_runs, narx_steps, narx_restarts, narx_iterations : int
        NARX training: EKF data runs and samples per run, optimiser
        restarts and iterations.
    narx_hidden, narx_delays : int
        NARX structure: hidden ``tanh`` neurons and output feedback delays.
    narx_target : {"ekf", "true"}
        Train on the EKF's estimates (the paper) or on the true states (the controlled
        experiment).
    narx_excitation : {"random", "designed"}
        Training-data excitation (`tanksynth.design.estimators.narx_training.generate_ekf_data`).
    narx_setpoint_range : tuple of float, optional
        Set-point range of the designed excitation (state units).
    narx_prbs_amplitude : float
        PRBS amplitude of the designed excitation (input units).
    narx_hold : tuple of int
        Samples a level (random) or a set-point (designed) is held.
    narx_seed : int
        Seed of the training data and weights.
    narx_time_limit : float, optional
        Wall-clock cap of each Levenberg-Marquardt restart (s).
    """

    Q: float
    R: float
    P0: float
    substeps: int = 2
    narx_runs: int = 3
    narx_steps: int = 400
    narx_restarts: int = 1
    narx_iterations: int = 60
    narx_hidden: int = 5
    narx_delays: int = 2
    narx_target: str = "ekf"
    narx_excitation: str = "random"
    narx_setpoint_range: tuple[float, float] | None = None
    narx_prbs_amplitude: float = 0.0
    narx_hold: tuple[int, int] = (30, 150)
    narx_seed: int = 0
    narx_time_limit: float | None = None


def _factory(kind: str, plant: Plant, ts: float, x0: np.ndarray,
             t: FilterTuning) -> Callable[[], BatchEstimator]:
    from tanksynth.runtime.estimators.kalman import ExtendedKalmanFilter, KalmanTuning
    from tanksynth.runtime.estimators.narx import NARXEstimator
    from tanksynth.runtime.estimators.ukf import UKFTuning, UnscentedKalmanFilter
    from tanksynth.sim.simulate import EstimatorAdapter

    common: dict[str, Any] = dict(Q=t.Q * np.eye(plant.n), R=t.R * np.eye(plant.q),
                                  P0=t.P0 * np.eye(plant.n), x0=x0, ts=ts, substeps=t.substeps, clip=True)
    template: KernelEstimator
    if kind == "ekf":
        template = ExtendedKalmanFilter(plant, KalmanTuning(**common))
    elif kind == "ukf":
        template = UnscentedKalmanFilter(plant, UKFTuning(**common))
    else:
        template = NARXEstimator(plant, train_comparison_narx(plant, ts, x0, t).tuning)
    return lambda: EstimatorAdapter(template)


def train_comparison_narx(plant: Plant, ts: float, x0: Sequence[float] | np.ndarray,
                          t: FilterTuning) -> Any:
    """The NARX estimator of a comparison, trained on EKF data with the tuning's budget.

    Parameters
    ----------
    plant : Plant
    ts : float
        Sampling period (s).
    x0 : sequence of float or ndarray
        Initial estimate (state units).
    t : FilterTuning

    Returns
    -------
    NARXTraining
        `tanksynth.design.estimators.narx_training.NARXTraining` (tuning, data, diagnostics).
    """
    from tanksynth.design.estimators.narx_training import train_narx
    from tanksynth.runtime.estimators.kalman import KalmanTuning

    ekf = KalmanTuning(Q=t.Q * np.eye(plant.n), R=t.R * np.eye(plant.q), P0=t.P0 * np.eye(plant.n),
                       x0=np.asarray(x0, dtype=float), ts=ts, substeps=t.substeps, clip=True)
    return train_narx(plant, ekf, hidden=t.narx_hidden, delays=t.narx_delays, runs=t.narx_runs,
                      steps=t.narx_steps, restarts=t.narx_restarts, max_iter=t.narx_iterations,
                      clip=True, target=t.narx_target, excitation=t.narx_excitation,
                      setpoint_range=t.narx_setpoint_range, prbs_amplitude=t.narx_prbs_amplitude,
                      hold=t.narx_hold, seed=t.narx_seed, time_limit=t.narx_time_limit)


def comparison_estimators(plant: Plant, ts: float, combinations: Mapping[str, str | None],
                          tuning: FilterTuning, x0: Sequence[float] | None = None
                          ) -> dict[str, tuple[Callable[[], BatchEstimator] | None, str]]:
    """Estimator factories of the combinations, or the reason one is missing.

    Parameters
    ----------
    plant : Plant
    ts : float
        Sampling period (s).
    combinations : mapping of str to str or None
        Label -> estimator kind (one of `ESTIMATOR_KINDS`), or None for
        the true state fed back.
    tuning : FilterTuning
    x0 : sequence of float, optional
        Default initial estimate (state units); the scenarios may override it.
        Default: 0.3 for every state.

    Returns
    -------
    dict
        label -> ``(factory or None, reason)``: the baseline has factory
        None and an empty reason; an estimator that cannot be built has
        factory None and the reason it is skipped.

    Raises
    ------
    ValueError
        An unknown estimator kind.
    """
    start = np.full(plant.n, 0.3) if x0 is None else np.asarray(x0, dtype=float)
    out: dict[str, tuple[Callable[[], BatchEstimator] | None, str]] = {}
    for label, kind in combinations.items():
        if kind is None:
            out[label] = (None, "")
            continue
        if kind not in ESTIMATOR_KINDS:
            raise ValueError(f"combination {label!r}: unknown estimator kind {kind!r}; expected one "
                             "of " + ", ".join(ESTIMATOR_KINDS) + " or None")
        try:
            out[label] = (_factory(kind, plant, ts, start, tuning), "")
        except (TanksynthError, np.linalg.LinAlgError) as exc:
            out[label] = (None, f"{kind} estimator could not be built: {' '.join(str(exc).split())}")
    return out


@dataclass(frozen=True)
class ComparisonRow:
    """One (scenario, combination) line of a comparison.

    Attributes
    ----------
    scenario, controller : str
    metrics : dict of str to float
        Mean over the runs of every metric, plus ``offset`` (mean of the
        controlled variables' offsets) and ``computation_time`` (estimator
        + controller time per sample, s); empty when skipped.
    skipped : str
        Why the row was not run ("" when it ran).
    """

    scenario: str
    controller: str
    metrics: Mapping[str, float]
    skipped: str = ""


def controller_comparison(plant: Plant, estimators: EstimatorFactories, *, x_op: Sequence[float],
                          gains: Sequence[float], tracked: Sequence[int] = (0, 1), ts: float = 1.0,
                          runs: int = 4, seed: int = 0,
                          scenarios: Iterable[str] = CONTROL_BENCHMARK_SCENARIOS, substeps: int = 2,
                          law: Callable | None = None) -> list[ComparisonRow]:
    """Each estimator with one control law, over the scenarios (mean of ``runs`` runs).

    Parameters
    ----------
    plant : Plant
    estimators : mapping
        label -> ``(factory or None, reason)`` (as `comparison_estimators`
        returns); a non-empty reason skips the row.
    x_op : sequence of float
        Operating levels (initial state and set-points), state units.
    gains : sequence of float
        Inverse-dynamics rates ``c_i`` (1/s) of the default law.
    tracked : sequence of int
        Controlled states (as many as inputs).
    ts : float
        Sampling period (s).
    runs, seed : int
        Monte-Carlo runs per row and the seed (`run_seeds`).
    scenarios : iterable of str
        Names in `tanksynth.sim.scenarios.SCENARIOS`.
    substeps : int
        RK4 steps per period.
    law : ControlLaw, optional
        Default: `InverseDynamicsLaw` (plant, tracked, gains).

    Returns
    -------
    list of ComparisonRow
    """
    from tanksynth.analysis.linearize import equilibrium_input

    x_point = [float(v) for v in x_op]
    u_op = equilibrium_input(plant, x_point).u0.tolist()
    tracked = tuple(int(i) for i in tracked)
    if law is None:
        law = InverseDynamicsLaw(plant, tracked, tuple(float(g) for g in gains))
    seeds = run_seeds(seed, runs).tolist()  # Python ints: the same uint64 seeds
    rows = []
    for name in scenarios:
        setup = SCENARIOS[name].setup(plant, x_point, u_op, tracked, ts=ts)
        for label, (factory, reason) in estimators.items():
            if reason:
                rows.append(ComparisonRow(name, label, {}, reason))
                continue
            est = factory() if factory is not None else None
            result = run_scenario(setup, plant, ts=ts, seeds=seeds, controller=law, estimator=est,
                                  substeps=substeps)
            metrics = compute_metrics(result, setup, plant, estimated=est is not None)
            ours = {k: float(np.mean(m.values)) for k, m in metrics.items()}
            offsets = [v for k, v in ours.items() if k.startswith("offset_")]
            ours["offset"] = float(np.mean(offsets)) if offsets else math.nan
            ours["computation_time"] = ours.get("estimator_time", 0.0) + ours.get("controller_time", 0.0)
            rows.append(ComparisonRow(name, label, ours))
    return rows


@dataclass(frozen=True)
class StructureCandidate:
    """One NARX structure tried by `select_narx_structure`.

    Attributes
    ----------
    hidden, delays : int
        Hidden neurons and output feedback delays.
    ise : float
        Sum over the held-out scenarios and controlled states of the mean ISE (m^2 s for
        levels); inf when the loop failed.
    train_seconds : float
        Wall-clock training time (s).
    iterations : int
        Levenberg-Marquardt iterations of the kept restart.
    """

    hidden: int
    delays: int
    ise: float
    train_seconds: float
    iterations: int


def select_narx_structure(plant: Plant, ts: float, x_op: Sequence[float], tuning: FilterTuning, *,
                          gains: Sequence[float], hidden: Sequence[int] = (3, 5, 8),
                          delays: Sequence[int] = (1, 2),
                          scenarios: Sequence[str] = ("servo", "regulatory"), runs: int = 2,
                          seed: int = 101) -> tuple[FilterTuning, list[StructureCandidate]]:
    """Choose the NARX's hidden neurons and output delays by closed-loop ISE (seed 002 Sec. 3.3).

    Every (hidden, delays) pair is trained with the tuning's data and budget, then run
    in the loop (default inverse-dynamics law) on held-out scenarios with their own seed
    (``seed``: other noise than any comparison run with the default seed 0); the pair of
    least total ISE is kept.

    Parameters
    ----------
    plant : Plant
    ts : float
        Sampling period (s).
    x_op : sequence of float
        Operating levels (state units).
    tuning : FilterTuning
        Data, budget and everything but the structure.
    gains : sequence of float
        Inverse-dynamics rates ``c_i`` (1/s).
    hidden, delays : sequence of int
        The grid.
    scenarios : sequence of str
        Held-out scenarios (names in `tanksynth.sim.scenarios.SCENARIOS`).
    runs, seed : int
        Monte-Carlo runs per scenario and their base seed.

    Returns
    -------
    tuning : FilterTuning
        ``tuning`` with the chosen ``narx_hidden``, ``narx_delays``.
    candidates : list of StructureCandidate
        Every pair tried, in grid order.
    """
    import dataclasses
    import time

    from tanksynth.runtime.estimators.narx import NARXEstimator
    from tanksynth.sim.simulate import EstimatorAdapter

    out: list[StructureCandidate] = []
    for h in hidden:
        for d in delays:
            t = dataclasses.replace(tuning, narx_hidden=int(h), narx_delays=int(d))
            start = time.perf_counter()
            try:
                training = train_comparison_narx(plant, ts, x_op, t)
            except TanksynthError:
                out.append(StructureCandidate(int(h), int(d), math.inf, time.perf_counter() - start, 0))
                continue
            seconds = time.perf_counter() - start
            est = NARXEstimator(plant, training.tuning)

            def factory(e: NARXEstimator = est) -> BatchEstimator:
                return EstimatorAdapter(e)

            factories: EstimatorFactories = {"ANNC": (factory, "")}
            rows = controller_comparison(plant, factories, x_op=x_op, gains=gains, ts=ts, runs=runs,
                                         seed=seed, scenarios=scenarios)
            total = sum(v for r in rows for k, v in r.metrics.items() if k.startswith("ise_"))
            out.append(StructureCandidate(int(h), int(d), float(total) if math.isfinite(total)
                                          else math.inf, seconds,
                                          int(training.diagnostics["training"]["iterations"])))
    best = min(out, key=lambda c: c.ise)
    return dataclasses.replace(tuning, narx_hidden=best.hidden, narx_delays=best.delays), out
