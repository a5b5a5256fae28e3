"""Campaign limits (issue 31 item 6): a ceiling on --workers, an up-front estimate of a campaign's
memory and time, and a refusal (exit 2 naming --runs and the budget) past the memory budget."""

from __future__ import annotations

from pathlib import Path

import pytest

from tanksynth.cli import main
from tanksynth.errors import SpecError
from tanksynth.methods import RUNNERS, load_directory
from tanksynth.verify.campaign import ROW_BYTES, campaign_tasks, estimate_campaign, run_task
from tanksynth.verify.cluster import MAX_WORKERS

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    d = tmp_path_factory.mktemp("limits") / "out"
    assert main(["design", str(ROOT / "examples" / "seed000_pole_placement.toml"), "-o", str(d)]) == 0
    return d


def test_workers_past_the_ceiling_are_refused_before_any_process(designed, capsys):
    code = main(["verify", str(designed), "--workers", "1000"])
    err = capsys.readouterr().err
    assert code == 2 and "--workers" in err and len(err.strip().splitlines()) == 1, err
    assert MAX_WORKERS < 1000


def _tasks(designed, runs):
    spec, docs = load_directory(designed)
    return campaign_tasks(spec.text, [d for _, d in docs], ["servo", "regulatory"], runs, chunk=4,
                          runners=RUNNERS)


def test_the_estimate_counts_every_row_the_campaign_keeps(designed):
    tasks = _tasks(designed, 8)
    est = estimate_campaign(tasks, workers=2, budget=1 << 40)
    rows = sum(len(run_task(t)) for t in tasks)       # the independent count: every task run
    assert est.rows == rows and est.bytes == rows * ROW_BYTES
    assert est.runs == sum(len(t.runs) for t in tasks) and est.seconds > 0
    assert set(est.done) <= {t.key for t in tasks} and est.done   # probes are real results


def test_a_campaign_past_the_memory_budget_is_refused_naming_runs_and_the_budget(designed):
    tasks = _tasks(designed, 64)
    rows = estimate_campaign(tasks, budget=1 << 40).rows
    budget = rows * ROW_BYTES // 2                    # half of what the table needs
    with pytest.raises(SpecError) as info:
        estimate_campaign(tasks, budget=budget)
    text = str(info.value)
    assert "--runs" in text and "memory budget" in text and "TANKSYNTH_MEMORY_BUDGET_MB" in text
    most = int(text.split("at most ")[1].split(",")[0])
    assert 0 < most <= 32                             # fits: half the runs at most


@pytest.mark.slow
def test_verify_runs_past_the_budget_is_exit_2_before_the_verdicts(designed, capsys, monkeypatch):
    monkeypatch.setenv("TANKSYNTH_MEMORY_BUDGET_MB", "1")
    before = {p.name: p.read_bytes() for p in designed.iterdir()}
    code = main(["verify", str(designed), "--runs", "5000"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "--runs" in err and "budget" in err, err
    assert {p.name: p.read_bytes() for p in designed.iterdir()} == before   # nothing written
