"""Monte-Carlo campaigns on Dask: every artefact runs what it ships.

A campaign is runs x scenarios x artefacts. It is cut into tasks (one
artefact, one scenario, a chunk of runs); each task rebuilds the plant from
the spec text, asks the artefact's method's runner (``runners[method](doc,
spec)``, handed over by the method table) for what to run, runs the
scenario for its runs in one batch and returns tidy rows:

``controller``
    the serialised law or gains in closed loop (`tanksynth.verify.laws.campaign`):
    ``ise_<y>``, ``offset_<y>``, tracking and rejection times;
``estimator``
    the estimator or observer on the noisy measurements
    (`tanksynth.verify.estimation`): ``rmse_<state>`` after the warm-up;
``detector``
    the residual test on the scenario and on its fault-free twin
    (`tanksynth.verify.fault.campaign`): ``detection_delay``,
    ``false_alarm_rate``, ``first_false_alarm``;
``model``
    the discrete linear model against the nonlinear plant
    (`tanksynth.verify.model.campaign`): ``prediction_rmse_<state>``,
    ``one_step_rmse_<state>``;

plus the computation time of what ran. Metric names use the plant's own
state and output names (`tanksynth.sim.metrics`). A method without a runner
is refused: nothing is silently run open loop.

Tasks go to a ``dask.distributed`` cluster: a `LocalCluster` started for
the campaign by default, or an existing cluster given its scheduler address
(the same code path). Each task has a unique key and its rows are stored by
that key, so a task that is re-run after a worker died replaces nothing and
adds nothing: no result is lost (Dask recomputes lost tasks; ``retries``
more on errors) and none is duplicated.

The table is tidy, one row per (artefact, scenario, run, metric), with the
seed that reproduces the run: ``simulate(..., seeds=[seed])`` gives the same
trajectory bit for bit, whatever chunk it ran in.
"""

from __future__ import annotations

import csv
import time
import uuid
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Callable, Mapping, Protocol, Sequence

import numpy as np

from tanksynth.errors import ArtefactError, SpecError, TanksynthError
from tanksynth.plants.base import Plant
from tanksynth.sim.metrics import Metric
from tanksynth.sim.scenarios import Scenario, scenario
from tanksynth.sim.simulate import run_seeds
from tanksynth.spec import Spec, parse_spec_text
from tanksynth.spec.method_options.base import memory_budget
from tanksynth.verify.cluster import CONNECT_TIMEOUT, WORKER_TIMEOUT, completed, connect
from tanksynth.verify.common import sampling_period

__all__ = ["CampaignRun", "Runner", "CampaignTask", "CampaignTable", "COLUMNS", "campaign_spec",
           "clear_cache", "auto_chunk", "MIN_CHUNK", "MAX_CHUNK", "campaign_tasks", "run_task",
           "run_campaign", "CampaignEstimate", "estimate_campaign", "ROW_BYTES"]

#: Fewest and most runs per task by default (`auto_chunk`).
MIN_CHUNK = 16
MAX_CHUNK = 512

#: Columns of the tidy campaign table (``loop`` describes what ran).
COLUMNS = ("artefact", "method", "kind", "plant", "scenario", "run", "seed", "metric", "value", "unit",
           "loop")


class CampaignRun(Protocol):
    """What a runner builds: something that simulates a scenario and measures it.

    Attributes
    ----------
    kind : str
        ``"controller"``, ``"estimator"``, ``"detector"`` or ``"model"``.
    description : str
        What runs, in one sentence (the table's ``loop`` column).
    """

    kind: str
    description: str

    def evaluate(self, sc: Scenario, plant: Plant, *, ts: float, seeds: Sequence[int],
                 substeps: int = 4) -> dict[str, Metric]:
        """Simulate ``sc`` for the runs of ``seeds`` and return the metrics (arrays over the runs).

        Parameters
        ----------
        sc, plant : Scenario, Plant
            The scenario and the plant model.
        ts, seeds, substeps : float, sequence of int, int
            Sampling period [s], one seed per run, RK4 steps per period.
        """


#: A method's campaign runner: ``runner(doc, spec) -> CampaignRun`` (a module-level function,
#: so that tasks pickle).
Runner = Callable[[Mapping[str, Any], Spec], CampaignRun]


# ------------------------------------------------------------------------- tasks
@dataclass(frozen=True)
class CampaignTask:
    """One unit of work: one artefact, one scenario, a chunk of runs (plain data).

    Attributes
    ----------
    key : str
        Unique within the campaign.
    artefact, method : str
    spec_text : str
        The spec TOML (plant, operating point, sampling period).
    doc : dict
        The artefact document (gains as nested lists).
    scenario : str
    runs : tuple of int
        Run indices.
    seeds : tuple of int
        Their seeds.
    substeps : int
    runner : callable
        The method's runner.
    """

    key: str
    artefact: str
    method: str
    spec_text: str
    doc: Mapping[str, Any]
    scenario: str
    runs: tuple[int, ...]
    seeds: tuple[int, ...]
    substeps: int
    runner: Runner


@lru_cache(maxsize=8)
def campaign_spec(text: str) -> Spec:
    """The spec of a campaign, parsed once per process (at most 8 kept; `clear_cache` empties it).

    Parsed without the method table: a worker needs the plant, the operating point and the
    sampling period, and each design's options as written.

    Parameters
    ----------
    text : str
        The spec TOML.
    """
    return parse_spec_text(text.encode("utf-8"), source="<campaign spec>")


def clear_cache() -> int:
    """Forget the campaign specs parsed in this process; returns how many."""
    count = campaign_spec.cache_info().currsize
    campaign_spec.cache_clear()
    return count


#: Errors of a run that are results (a diverging estimator, a law that drives the state
#: non-finite): recorded as a ``failed`` row instead of aborting the campaign.
_RUN_FAILURES = (TanksynthError, FloatingPointError, OverflowError, np.linalg.LinAlgError)


def run_task(task: CampaignTask) -> list[dict]:
    """Run one campaign task (on a worker or in process) and return its tidy rows.

    A run that fails numerically (`TanksynthError`, e.g. a non-finite
    estimate) gives one row per run with metric ``failed`` = 1 and the
    error in the ``loop`` column: a failure is a result, never a blank.

    Parameters
    ----------
    task : CampaignTask
        The task (artefact, scenario, seeds).

    Raises
    ------
    ArtefactError
        The runner could not rebuild what the artefact ships.
    """
    spec = campaign_spec(task.spec_text)
    plant = spec.plant
    doc = dict(task.doc)
    doc["gains"] = {k: np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
    run = task.runner(doc, spec)
    description = run.description
    try:
        metrics = run.evaluate(scenario(task.scenario), plant, ts=sampling_period(spec),
                               seeds=list(task.seeds), substeps=task.substeps)
    except _RUN_FAILURES as exc:
        message = " ".join(f"{type(exc).__name__}: {exc}".split())
        description = f"{description} -- the simulation failed: {message}"
        metrics = {"failed": Metric("failed", np.ones(len(task.runs)), "1",
                                    "the simulation of these runs failed (see loop)")}
    rows = []
    for i, (r, seed) in enumerate(zip(task.runs, task.seeds)):
        for name, metric in metrics.items():
            rows.append({"artefact": task.artefact, "method": task.method, "kind": run.kind,
                         "plant": plant.name, "scenario": task.scenario, "run": int(r),
                         "seed": int(seed), "metric": name, "value": float(metric.values[i]),
                         "unit": metric.unit, "loop": description})
    return rows


def auto_chunk(runs: int) -> int:
    """Runs per task by default: blocks of at least `MIN_CHUNK` runs, about eight tasks per
    (artefact, scenario) for load balance, at most `MAX_CHUNK` (memory of one batch).

    Parameters
    ----------
    runs : int
        Monte-Carlo runs per (artefact, scenario).
    """
    return int(max(MIN_CHUNK, min(MAX_CHUNK, -(-int(runs) // 8))))


def campaign_tasks(spec_text: str, artefacts: Sequence[Mapping[str, Any]], scenarios: Sequence[str],
                   runs: int, seed: int = 0, chunk: int | None = None, substeps: int = 4, *,
                   runners: Mapping[str, Runner]) -> list[CampaignTask]:
    """Cut a campaign into tasks.

    Parameters
    ----------
    spec_text : str
        The spec the artefacts were designed from.
    artefacts : sequence of mapping
        Artefact documents (gains as arrays or lists).
    scenarios : sequence of str
        Scenario names; those not defined for the plant are left out.
    runs : int
        Monte-Carlo runs per (artefact, scenario).
    seed : int
        Campaign seed; run ``r`` has seed ``run_seeds(seed, [r])``.
    chunk : int, optional
        Runs per task (one simulation batch); default `auto_chunk` (blocks of runs:
        the closed-loop kernel runs a block in one call).
    substeps : int
        RK4 steps per sampling period.
    runners : mapping of method name to Runner
        What each method's artefacts run (the method table's ``campaign``
        column).

    Raises
    ------
    SpecError
        ``runs`` or ``chunk`` below 1.
    ArtefactError
        An artefact's method has no runner.
    """
    chunk = auto_chunk(runs) if chunk is None else chunk
    if runs < 1 or chunk < 1:
        raise SpecError(f"runs and chunk must be >= 1, got {runs}, {chunk}", key="campaign")
    plant = campaign_spec(spec_text).plant
    seeds = run_seeds(seed, runs)
    tasks = []
    for doc in artefacts:
        method = str(doc["method"])
        runner = runners.get(method)
        if runner is None:
            raise ArtefactError(f"artefact '{doc['name']}': method {method!r} has no campaign runner "
                                "(nothing to run it with)")
        plain = {**doc, "gains": {k: np.asarray(v, dtype=float).tolist() for k, v in doc["gains"].items()}}
        for name in scenarios:
            if not scenario(name).applies_to(plant):
                continue
            for start in range(0, runs, chunk):
                idx = tuple(range(start, min(start + chunk, runs)))
                tasks.append(CampaignTask(f"{doc['name']}|{name}|{start}", str(doc["name"]), method,
                                          spec_text, plain, name, idx,
                                          tuple(int(seeds[i]) for i in idx), substeps, runner))
    return tasks


@dataclass(frozen=True)
class CampaignTable:
    """Tidy campaign results: one row per (artefact, scenario, run, metric).

    Attributes
    ----------
    rows : tuple of dict
        Keys `COLUMNS`, sorted by artefact, scenario, run, metric.
    tasks : int
        Tasks run.
    """

    rows: tuple[dict, ...]
    tasks: int

    def to_csv(self, path: str | Path) -> Path:
        """Write the table as CSV (UTF-8, header row, floats to 17 significant digits).

        Parameters
        ----------
        path : str or Path
            The CSV file.
        """
        path = Path(path)
        with path.open("w", newline="", encoding="utf-8") as fh:
            writer = csv.DictWriter(fh, fieldnames=COLUMNS)
            writer.writeheader()
            for row in self.rows:
                writer.writerow({**row, "value": repr(float(row["value"]))})
        return path

    def summary(self) -> dict[tuple[str, str, str], float]:
        """Mean over the runs of each (artefact, scenario, metric)."""
        acc: dict[tuple[str, str, str], list[float]] = {}
        for row in self.rows:
            acc.setdefault((row["artefact"], row["scenario"], row["metric"]), []).append(row["value"])
        return {k: float(np.mean(v)) for k, v in acc.items()}


def _collect(results: Mapping[str, list[dict]], tasks: int) -> CampaignTable:
    rows = [r for key in sorted(results) for r in results[key]]
    rows.sort(key=lambda r: (r["artefact"], r["scenario"], r["run"], r["metric"]))
    return CampaignTable(tuple(rows), tasks)


#: Memory one row of the campaign table takes in the process that gathers it (bytes: a dict of
#: 11 fields unpickled from a worker, measured 940 B on CPython 3.11, plus its share of the sort).
ROW_BYTES = 1024


@dataclass(frozen=True)
class CampaignEstimate:
    """What a campaign will cost, estimated from one task of each artefact run up front.

    Attributes
    ----------
    runs : int
        Simulated runs (runs x applicable scenarios x artefacts).
    rows : int
        Rows of the table (runs x metrics of each artefact).
    bytes : int
        Memory the table takes in this process (rows x `ROW_BYTES`).
    seconds : float
        Wall time on ``workers`` processes (s): the probes' seconds per run, times the runs,
        over the workers.
    budget : int
        The memory budget it is held to (bytes, `memory_budget`).
    done : dict
        The probes' own rows by task key (real results: `run_campaign` does not run them again).
    """

    runs: int
    rows: int
    bytes: int
    seconds: float
    budget: int
    done: Mapping[str, list[dict]]

    def line(self) -> str:
        """One line: the runs, the table's memory against the budget, the time."""
        return (f"campaign: {self.runs} runs, {self.rows} table rows, about "
                f"{self.bytes / 1024 ** 2:.0f} MiB of results (budget "
                f"{self.budget / 1024 ** 2:.0f} MiB), roughly {_duration(self.seconds)}")


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def estimate_campaign(tasks: Sequence[CampaignTask], workers: int = 2,
                      budget: int | None = None) -> CampaignEstimate:
    """Estimate a campaign's memory and time by running the first task of each artefact here.

    Parameters
    ----------
    tasks : sequence of CampaignTask
        The campaign (`campaign_tasks`).
    workers : int
        Processes the campaign runs on (for the time).
    budget : int, optional
        Memory budget (bytes); default `memory_budget` (``TANKSYNTH_MEMORY_BUDGET_MB``).

    Returns
    -------
    CampaignEstimate

    Raises
    ------
    SpecError
        The table would exceed the budget (key ``--runs``): the message gives the estimate, the
        budget and the most runs that fit.
    """
    budget = memory_budget() if budget is None else int(budget)
    runs_of: dict[str, int] = {}
    first: dict[str, CampaignTask] = {}
    for task in tasks:
        runs_of[task.artefact] = runs_of.get(task.artefact, 0) + len(task.runs)
        first.setdefault(task.artefact, task)
    done: dict[str, list[dict]] = {}
    rows = 0
    seconds = 0.0
    for name, task in first.items():
        start = time.perf_counter()
        done[task.key] = run_task(task)
        seconds += (time.perf_counter() - start) / len(task.runs) * runs_of[name]
        rows += len(done[task.key]) // len(task.runs) * runs_of[name]
    estimate = CampaignEstimate(sum(runs_of.values()), rows, rows * ROW_BYTES,
                                seconds / max(min(workers, len(tasks)), 1), budget, done)
    if estimate.bytes > budget:
        runs = max(t.runs[-1] for t in tasks) + 1  # per (artefact, scenario): --runs
        most = int(runs * budget / estimate.bytes)
        raise SpecError(f"the campaign's table would take about {estimate.bytes / 1024 ** 2:.0f} MiB "
                        f"({estimate.rows} rows of ~{ROW_BYTES} B), over the memory budget "
                        f"{budget / 1024 ** 2:.0f} MiB (TANKSYNTH_MEMORY_BUDGET_MB); lower --runs to at "
                        f"most {most}, or give fewer --scenario", key="--runs")
    return estimate


def run_campaign(tasks: Sequence[CampaignTask], *, scheduler: str | None = None, workers: int = 2,
                 local: bool = False, retries: int = 2,
                 progress: Callable[[int, int], None] | None = None,
                 connect_timeout: float = CONNECT_TIMEOUT, worker_timeout: float = WORKER_TIMEOUT,
                 waiting: Callable[[str], None] | None = None,
                 done: Mapping[str, list[dict]] | None = None) -> CampaignTable:
    """Run campaign tasks on Dask (or in this process) and gather a tidy table.

    Parameters
    ----------
    tasks : sequence of CampaignTask
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:port``).
        Default: a `LocalCluster` of ``workers`` processes, started and
        closed here.
    workers : int
        Worker processes of the local cluster (one thread each).
    local : bool
        Run in this process without Dask (for debugging and small runs).
    retries : int
        Extra attempts of a task that raised (a task lost with a dead worker
        is recomputed by the scheduler regardless).
    progress : callable, optional
        ``progress(done, total)`` after each task (the CLI draws a bar).
    connect_timeout : float
        Seconds to wait for the scheduler (`tanksynth.verify.cluster.connect`).
    worker_timeout : float
        Seconds the campaign waits for a cluster without any worker (its only worker died)
        before it gives up (`tanksynth.verify.cluster.completed`).
    waiting : callable, optional
        ``waiting(text)``: one line when the campaign waits for workers.
    done : mapping, optional
        Rows of tasks already run (by task key, e.g. `CampaignEstimate.done`): not run again.

    Returns
    -------
    CampaignTable

    Raises
    ------
    TanksynthError
        A task failed after its retries (its error is named).
    SchedulerError
        No worker for ``worker_timeout`` seconds.
    """
    total = len(tasks)
    keys = [t.key for t in tasks]
    if len(set(keys)) != total:
        raise SpecError("campaign task keys must be unique", key="campaign")
    results: dict[str, list[dict]] = {k: list(v) for k, v in (done or {}).items() if k in set(keys)}
    todo = [t for t in tasks if t.key not in results]
    if progress is not None and results:
        progress(len(results), total)
    if local:
        for task in todo:
            results[task.key] = run_task(task)
            if progress is not None:
                progress(len(results), total)
        return _collect(results, total)
    from distributed import LocalCluster  # here: dask stays off the local path

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        scheduler = cluster.scheduler_address
    prefix = f"tanksynth-{uuid.uuid4().hex[:12]}-"
    try:
        with connect(scheduler, connect_timeout) as client:
            futures = {client.submit(run_task, task, key=prefix + task.key, pure=False,
                                     retries=retries): task.key for task in todo}
            for fut in completed(client, futures, worker_timeout=worker_timeout, waiting=waiting):
                key = futures[fut]
                try:
                    rows = fut.result()
                except Exception as exc:  # a task error, re-raised with its task named
                    raise TanksynthError(f"campaign task {key} failed: {type(exc).__name__}: {exc}") from exc
                fut.release()  # its rows are here now: the cluster keeps no second copy
                results[key] = rows  # keyed: a recomputed task cannot add rows twice
                if progress is not None:
                    progress(len(results), total)
    finally:
        if cluster is not None:
            cluster.close()
    missing = sorted(set(keys) - set(results))
    if missing:
        raise TanksynthError(f"campaign lost {len(missing)} task(s): {', '.join(missing[:5])}")
    return _collect(results, total)

