"""BLAS threads for small dense linear algebra.

On a small, shared machine, a multi-threaded BLAS (OpenBLAS) makes small
dense work slower, not faster: one SVD of a 4096 x 64 Kalman matrix took
0.46 s with OpenBLAS's threads on the loaded 2-core machine and 0.005 s with
one thread (issue 15). `small_dense` runs a block with the BLAS limited to
one thread (threadpoolctl), and restores the previous limits after it.
Large problems (an LMI solver's factorisations) are left alone.
"""

from __future__ import annotations

from contextlib import contextmanager
from typing import Any, Iterator

__all__ = ["small_dense"]

_CONTROLLER: list[Any] = []


def _controller() -> Any:
    """One `threadpoolctl.ThreadpoolController` (scans the loaded BLAS once)."""
    if not _CONTROLLER:
        # numpy and scipy each bring their own OpenBLAS; load both before the one scan, or a
        # library loaded later would never be limited.
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController

        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0]


@contextmanager
def small_dense(threads: int = 1) -> Iterator[None]:
    """Limit the BLAS to ``threads`` threads inside the block.

    Parameters
    ----------
    threads : int
        Number of BLAS threads (>= 1); default 1.

    Yields
    ------
    None
    """
    with _controller().limit(limits=max(int(threads), 1), user_api="blas"):
        yield
