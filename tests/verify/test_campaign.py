"""Monte-Carlo campaigns: local, and on a real Dask LocalCluster with a worker killed mid-way."""

import csv
import os
import signal
import threading
from pathlib import Path

import pytest

from tanksynth.artefacts import read_artefact
from tanksynth.cli import main
from tanksynth.errors import ArtefactError, SimulationError
from tanksynth.verify.campaign import COLUMNS, campaign_tasks, run_campaign, run_task

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
WALL_CLOCK = ("estimator_time", "controller_time")   # computation times are measured, not simulated


def _deterministic(rows):
    return [(r["scenario"], r["run"], r["metric"], r["value"]) for r in rows if r["metric"] not in WALL_CLOCK]


@pytest.fixture(scope="module")
def artefacts(tmp_path_factory):
    out = tmp_path_factory.mktemp("campaign")
    assert main(["design", str(EXAMPLES / "seed000_pole_placement.toml"), "-o", str(out)]) == 0
    docs = [read_artefact(p) for p in sorted(out.glob("*.json")) if p.name != "plant.json"]
    return out, (out / "spec.toml").read_text(), docs


def test_local_campaign_is_tidy_and_reproducible(artefacts, runners):
    out, text, docs = artefacts
    tasks = campaign_tasks(text, docs[:1], ["servo", "dynamic_steps"], runs=3, seed=5, chunk=2,
                           runners=runners)
    assert len(tasks) == 4 and len({t.key for t in tasks}) == 4
    table = run_campaign(tasks, local=True)
    keys = {(r["scenario"], r["run"], r["metric"]) for r in table.rows}
    assert len(keys) == len(table.rows)
    seeds = {(r["scenario"], r["run"]): r["seed"] for r in table.rows}
    assert seeds[("servo", 2)] == seeds[("dynamic_steps", 2)]     # same run, same seed
    # A run re-simulated alone (another chunking) gives the same numbers.
    again = campaign_tasks(text, docs[:1], ["servo"], runs=3, seed=5, chunk=3, runners=runners)
    rows = {(r["run"], r["metric"]): r["value"] for r in run_task(again[0])}
    for r in table.rows:
        if r["scenario"] == "servo" and r["metric"] not in WALL_CLOCK:
            assert rows[(r["run"], r["metric"])] == r["value"]
    path = table.to_csv(out / "table.csv")
    with path.open() as fh:
        read = list(csv.DictReader(fh))
    assert len(read) == len(table.rows) and float(read[0]["value"]) == table.rows[0]["value"]
    assert tuple(read[0]) == COLUMNS and {r["kind"] for r in read} == {"controller"}
    # a controller fed the true state: tracking metrics, no estimation RMSE
    metrics = {r["metric"] for r in table.rows}
    assert {"ise_h1", "ise_h2", "offset_h1", "offset_h2", "tracking_time", "controller_time"} <= metrics
    assert not any(m.startswith("rmse_") or m == "estimator_time" for m in metrics)


def test_integral_controller_tracks_the_dynamic_steps(artefacts, runners):
    _, text, docs = artefacts
    doc = next(d for d in docs if d["method"] == "pole_placement")
    rows = run_task(campaign_tasks(text, [doc], ["dynamic_steps"], runs=1, runners=runners)[0])
    values = {r["metric"]: r["value"] for r in rows}
    assert values["tracking_time"] < 200 and abs(values["offset_h1"]) < 1e-3
    assert "integral action" in rows[0]["loop"] and "open loop" not in rows[0]["loop"]


def test_a_method_without_runner_is_refused(artefacts, runners):
    _, text, docs = artefacts
    doc = {**docs[0], "method": "not_in_the_table"}
    with pytest.raises(ArtefactError, match="not_in_the_table"):
        campaign_tasks(text, [doc], ["servo"], runs=1, runners=runners)


class _Diverging:
    kind = "estimator"
    description = "an estimator that diverges"

    def evaluate(self, sc, plant, *, ts, seeds, substeps=4):
        raise SimulationError("run 0: non-finite state at sample 7")


def _diverging_runner(doc, spec):
    return _Diverging()


def test_a_failed_simulation_is_a_row_not_a_blank(artefacts):
    _, text, docs = artefacts
    rows = run_task(campaign_tasks(text, docs[:1], ["servo"], runs=2,
                                   runners={docs[0]["method"]: _diverging_runner})[0])
    assert [(r["run"], r["metric"], r["value"]) for r in rows] == [(0, "failed", 1.0), (1, "failed", 1.0)]
    assert "non-finite state at sample 7" in rows[0]["loop"] and rows[0]["kind"] == "estimator"


@pytest.mark.slow
def test_dask_cluster_survives_a_killed_worker(artefacts, runners):
    distributed = pytest.importorskip("distributed")
    _, text, docs = artefacts
    tasks = campaign_tasks(text, docs[:1], ["servo", "regulatory"], runs=6, seed=1, chunk=2,
                           substeps=1, runners=runners)
    expected = {(t.scenario, r) for t in tasks for r in t.runs}
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster.scheduler_address) as client:
            pids = list(client.run(os.getpid).values())
        killed = threading.Event()

        def progress(done, total):
            if done >= 2 and not killed.is_set():
                killed.set()
                os.kill(pids[0], signal.SIGKILL)   # one worker dies mid-campaign

        table = run_campaign(tasks, scheduler=cluster.scheduler_address, progress=progress)
    assert killed.is_set()
    got = [(r["scenario"], r["run"], r["metric"]) for r in table.rows]
    assert len(got) == len(set(got))                                   # nothing duplicated
    assert {(s, r) for s, r, _ in got} == expected                      # nothing lost
    local = run_campaign(tasks, local=True)
    assert _deterministic(local.rows) == _deterministic(table.rows)   # bit for bit
