"""`--scheduler` addresses: a silent peer, a refused port and a malformed address are exit 2 in
bounded time (issue 19, item 6)."""

from __future__ import annotations

import socket
import time
from pathlib import Path

import pytest

from tanksynth.cli import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    d = tmp_path_factory.mktemp("cluster") / "out"
    assert main(["design", str(ROOT / "examples" / "seed000_three_tank.toml"), "-o", str(d)]) == 0
    return d


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_silent_refused_and_malformed_schedulers_are_bad_input(designed, capsys):
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(5)                 # accepts connections (backlog), never answers
    try:
        for address in (f"tcp://127.0.0.1:{silent.getsockname()[1]}",
                        f"tcp://127.0.0.1:{_free_port()}", "bogus!!"):
            start = time.perf_counter()
            code = main(["verify", str(designed), "--scheduler", address, "--connect-timeout", "1"])
            elapsed = time.perf_counter() - start
            err = capsys.readouterr().err
            assert code == 2, (address, err)
            assert len(err.strip().splitlines()) == 1 and "Dask scheduler" in err, err
            # the wait was the --connect-timeout given ("did not answer within 1 s" or
            # "waited at most 1 s", whichever deadline a loaded machine reaches first)
            assert "within 1 s" in err or "at most 1 s" in err, err
            # not a hang: a generous bound for a loaded machine; the time itself (< 15 s, the
            # import of distributed included) is a floor of benchmarks/limits.py
            assert elapsed < 60, (address, elapsed)
    finally:
        silent.close()


def _campaign_of(designed):
    from tanksynth.methods import RUNNERS, load_directory
    from tanksynth.verify.campaign import campaign_tasks

    spec, docs = load_directory(designed)
    return campaign_tasks(spec.text, [d for _, d in docs][:1], ["servo"], 2, chunk=1, runners=RUNNERS)


@pytest.mark.slow
def test_a_campaign_whose_only_worker_died_is_given_up(designed):
    """Issue 31 item 10: the cluster's only worker is gone before the campaign runs (deterministic:
    it is removed and the scheduler confirms it has none); the campaign says once that it waits
    for workers and gives up after --worker-timeout with a SchedulerError naming it."""
    from distributed import Client, LocalCluster

    from tanksynth.errors import SchedulerError
    from tanksynth.verify.campaign import run_campaign

    tasks = _campaign_of(designed)
    said: list[str] = []
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        cluster.scale(0)                       # the only worker goes
        deadline = time.monotonic() + 120      # hang guard only
        while client.nthreads() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not client.nthreads()
        with pytest.raises(SchedulerError, match=r"no Dask worker for 1 s \(--worker-timeout\)"):
            run_campaign(tasks, scheduler=cluster.scheduler_address, worker_timeout=1,
                         waiting=said.append)
    assert len(said) == 1 and said[0].startswith("waiting for Dask workers"), said


@pytest.mark.slow
def test_verify_on_a_cluster_without_workers_is_exit_2_after_the_worker_timeout(designed, capsys):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        assert not client.nthreads()
        code = main(["verify", str(designed), "--scheduler", cluster.scheduler_address,
                     "--worker-timeout", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, err
    assert len(err) == 2 and err[0].startswith("waiting for Dask workers"), err
    assert "no Dask worker for 1 s (--worker-timeout)" in err[1], err


@pytest.mark.parametrize("value", ["nan", "inf", "-5", "0"])
def test_a_non_finite_worker_timeout_is_bad_input(designed, capsys, value):
    code = main(["verify", str(designed), "--worker-timeout", value])
    err = capsys.readouterr().err
    assert code == 2 and "--worker-timeout" in err and len(err.strip().splitlines()) == 1, err
