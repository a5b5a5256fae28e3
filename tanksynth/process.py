"""Process set-up of a command (BLAS threads, file-size signal) and the internal-error log."""

from __future__ import annotations

import os
import sys

__all__ = ["one_blas_thread", "ignore_file_size_signal", "internal_error_log"]


def one_blas_thread() -> None:
    """One BLAS thread for a command, unless the user chose (``OPENBLAS_NUM_THREADS``, ...).

    The command's dense work is small (3-64 states): OpenBLAS's threads make it slower, badly
    so on a loaded machine (a 5 x 5 ``expm`` 0.4 ms instead of 0.017 ms; ``tanksynth run
    examples/three_tank_robust.toml`` 43 s instead of 13 s, issue 15). Read by the BLAS when it
    loads, so only before numpy is imported (a fresh ``tanksynth`` process, not a caller's).
    """
    if "numpy" not in sys.modules:
        for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(var, "1")


def ignore_file_size_signal() -> None:
    """Ignore SIGXFSZ (file size limit): a write past the limit then fails with an OSError the
    command reports on one line, instead of the process being killed without a word."""
    import signal
    import threading

    if hasattr(signal, "SIGXFSZ") and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


def internal_error_log() -> str:
    """Write the current exception's traceback to a temporary log file; return its path."""
    import tempfile
    import traceback

    fd, path = tempfile.mkstemp(prefix="tanksynth-internal-error-", suffix=".log")
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(traceback.format_exc())
    return path
