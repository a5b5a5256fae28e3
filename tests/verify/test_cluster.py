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
