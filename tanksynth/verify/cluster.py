"""Dask: connecting to a scheduler (a bounded wait and one clear error) and waiting for results
while the cluster has workers (a cluster without any gives up after ``--worker-timeout``)."""

from __future__ import annotations

import os
import threading
import time
from typing import Any, Callable, Iterable, Iterator

from tanksynth.errors import SchedulerError

__all__ = ["CONNECT_TIMEOUT", "WORKER_TIMEOUT", "MAX_WORKERS", "connect", "completed"]

#: Seconds to wait for a scheduler to answer before giving up (``--connect-timeout``).
CONNECT_TIMEOUT = 10.0

#: Seconds a computation waits for the cluster to have a worker again (its only worker died, or
#: a scheduler that has none) before it gives up (``--worker-timeout``).
WORKER_TIMEOUT = 60.0

#: The most worker processes a local cluster may start (``--workers``): 4 per CPU, at least 4
#: (each is a Python process of about 150 MB; more would only queue for the CPUs).
MAX_WORKERS = max(4, 4 * (os.cpu_count() or 1))

#: Seconds between two looks at the cluster while results are awaited.
_POLL = 0.5


def connect(address: str, timeout: float = CONNECT_TIMEOUT) -> Any:
    """A ``distributed.Client`` of the scheduler at ``address`` (e.g. ``tcp://host:8786``).

    Parameters
    ----------
    address : str
    timeout : float
        Seconds to wait for the connection (s, > 0).

    Raises
    ------
    SchedulerError
        A malformed address, a refused connection, or a peer that does not answer within
        ``timeout`` (the message names the address).
    """
    from distributed import Client  # here: runner and campaign import this module on dask-free paths

    outcome: dict[str, Any] = {}

    def make() -> None:
        try:
            outcome["client"] = Client(address, timeout=f"{float(timeout)}s")
        except Exception as exc:  # reported below, in the caller's thread
            outcome["error"] = exc

    # A peer that accepts the connection and never answers the handshake is not bounded by
    # the client's own timeout: wait for it in a daemon thread, with a deadline.
    worker = threading.Thread(target=make, name="tanksynth-connect", daemon=True)
    worker.start()
    worker.join(float(timeout) + 1.0)
    if worker.is_alive():
        raise SchedulerError(f"the Dask scheduler {address!r} did not answer within "
                             f"{float(timeout):g} s")
    if "error" in outcome:
        exc = outcome["error"]
        detail = " ".join(f"{type(exc).__name__}: {exc}".split())[:200]
        raise SchedulerError(f"cannot use the Dask scheduler {address!r} (waited at most "
                             f"{float(timeout):g} s): {detail}") from None
    return outcome["client"]


def completed(client: Any, futures: Iterable[Any], *, worker_timeout: float = WORKER_TIMEOUT,
              waiting: Callable[[str], None] | None = None) -> Iterator[Any]:
    """The futures of ``client``, each as it completes; gives up when the cluster has had no
    worker for ``worker_timeout`` seconds while some are pending.

    Parameters
    ----------
    client : distributed.Client
    futures : iterable of distributed.Future
    worker_timeout : float
        Seconds without any worker before giving up (s, > 0).
    waiting : callable, optional
        ``waiting(text)``: called once (one line) when the cluster is found without a worker,
        saying what is awaited and for how long at most.

    Yields
    ------
    distributed.Future
        A finished future (done or failed).

    Raises
    ------
    SchedulerError
        The cluster had no worker for ``worker_timeout`` seconds; the message says how many
        results are missing.
    """
    from distributed import wait

    pending = set(futures)
    total = len(pending)
    alone_since: float | None = None
    told = False
    while pending:
        try:
            done, _ = wait(list(pending), timeout=_POLL, return_when="FIRST_COMPLETED")
        except TimeoutError:
            done = set()
        for fut in done:
            pending.discard(fut)
            yield fut
        if done or not pending:
            alone_since = None
            continue
        if client.nthreads():
            alone_since = None
            continue
        now = time.monotonic()
        if alone_since is None:
            alone_since = now
        if not told and waiting is not None:
            told = True
            waiting(f"waiting for Dask workers: the cluster has none ({len(pending)} of {total} "
                    f"task(s) pending); giving up after {float(worker_timeout):g} s "
                    "(--worker-timeout)")
        if now - alone_since > worker_timeout:
            raise SchedulerError(f"no Dask worker for {float(worker_timeout):g} s (--worker-timeout): "
                                 f"{len(pending)} of {total} task(s) not run; start workers for the "
                                 "scheduler, or run without --scheduler (a local cluster)")
