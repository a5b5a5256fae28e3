"""Connecting to a Dask scheduler: a bounded wait and one clear error."""

from __future__ import annotations

import threading
from typing import Any

from tanksynth.errors import SchedulerError

__all__ = ["CONNECT_TIMEOUT", "connect"]

#: Seconds to wait for a scheduler to answer before giving up (``--connect-timeout``).
CONNECT_TIMEOUT = 10.0


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
