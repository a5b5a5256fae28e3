"""Process set-up of a command (BLAS threads, signals, child processes) and the internal-error log.

Interruption (issue 31): SIGINT, SIGTERM and SIGHUP all end a command the same way. The first one
raises `Interrupted` in the main thread (`interruptible`); later ones are ignored while the
command cleans up, so the clean-up itself is not cut short. The clean-up is ordinary unwinding:
child processes are ended (the report worker's group by `end_process_group`, LaTeX's group by
the PDF build, the Dask cluster closed), staged files removed, the result directory's lock
released; the command prints one line
``interrupted (SIGTERM): ...`` and exits with `EXIT_INTERRUPTED`.

A forked child that writes into a result directory (the report worker) calls `die_with_parent`:
it is interrupted the same way (and unwinds the same way) when its parent dies, even by SIGKILL
(Linux ``PR_SET_PDEATHSIG``), or asks it to end (SIGTERM).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from contextlib import contextmanager
from typing import Any, Iterator

__all__ = ["one_blas_thread", "ignore_file_size_signal", "internal_error_log", "EXIT_INTERRUPTED",
           "INTERRUPTING_SIGNALS", "Interrupted", "interruptible", "die_with_parent",
           "end_process_group", "interruption", "raise_if_interrupted"]

#: Exit code of a command ended by SIGINT, SIGTERM or SIGHUP (128 + SIGINT, the shell's code for
#: Ctrl-C; one code for every interruption, the signal is named in the message).
EXIT_INTERRUPTED = 130

#: The signals that interrupt a command (those present on this platform).
INTERRUPTING_SIGNALS: tuple[int, ...] = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class Interrupted(KeyboardInterrupt):
    """A command was interrupted by a signal (a `KeyboardInterrupt`, so that every handler that
    lets Ctrl-C through lets it through too).

    Parameters
    ----------
    signum : int
        The signal received.
    """

    def __init__(self, signum: int = int(signal.SIGINT)):
        self.signum = int(signum)
        super().__init__(self.signal_name)

    @property
    def signal_name(self) -> str:
        """The signal's name, e.g. ``SIGTERM``."""
        try:
            return signal.Signals(self.signum).name
        except ValueError:
            return f"signal {self.signum}"


def end_process_group(pid: int, grace: float = 5.0) -> None:
    """End the process group led by child ``pid`` and reap ``pid``: SIGTERM, then SIGKILL after
    ``grace`` seconds if it is still there. Bounded: returns within about ``grace`` + 5 s.

    Parameters
    ----------
    pid : int
        A child of this process that leads its own process group.
    grace : float
        Seconds it gets to end its own children and exit (s).
    """
    for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(pid, sig)
        except (ProcessLookupError, PermissionError):
            pass
        deadline = time.monotonic() + wait
        while True:
            try:
                done, _ = os.waitpid(pid, os.WNOHANG)
            except ChildProcessError:
                return
            if done:
                return
            if time.monotonic() > deadline:
                break
            time.sleep(0.02)


#: The interruption received by this process (None: none yet); kept so that code whose
#: exceptions a library swallows (Python callbacks called from C, e.g. IPOPT's) still sees it.
_received: list[Interrupted] = []


def _raise_interrupted(signum: int, frame: Any) -> None:
    # the first signal interrupts; the ones after it would cut the clean-up short: ignored
    for sig in INTERRUPTING_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    exc = Interrupted(signum)
    _received[:] = [exc]
    raise exc


def interruption() -> Interrupted | None:
    """The interruption this command received, or None.

    The signal handler raises `Interrupted` wherever the main thread is; when that is a Python
    callback called from C (CasADi catches the exceptions of a ``Callback``), the exception is
    swallowed, but the interruption stays recorded here: long loops check it
    (`raise_if_interrupted`) and stop.

    Returns
    -------
    Interrupted or None
    """
    return _received[0] if _received else None


def raise_if_interrupted() -> None:
    """Raise the `Interrupted` this command received, if any (a no-op otherwise).

    Raises
    ------
    Interrupted
        A signal interrupted the command (`interruption`).
    """
    if _received:
        raise Interrupted(_received[0].signum)


@contextmanager
def interruptible() -> Iterator[None]:
    """SIGINT, SIGTERM and SIGHUP raise `Interrupted` in the main thread while this runs (the
    previous handlers are restored after). Elsewhere than the main thread: nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.getsignal(sig) for sig in INTERRUPTING_SIGNALS}
    _received.clear()  # a new command (in the same process: tests) starts uninterrupted
    for sig in INTERRUPTING_SIGNALS:
        signal.signal(sig, _raise_interrupted)
    try:
        yield
    finally:
        _received.clear()
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


#: ``prctl`` option: the signal a process gets when its parent dies (linux/prctl.h).
_PR_SET_PDEATHSIG = 1


def die_with_parent(parent: int, own_group: bool = True) -> None:
    """In a forked child: be interrupted like a command (`Interrupted` on SIGTERM, SIGINT,
    SIGHUP: the child unwinds, ending its own children and removing its staged files) and
    be sent SIGTERM when ``parent`` dies (Linux ``PR_SET_PDEATHSIG``, even when the parent was
    SIGKILLed). If ``parent`` is already gone, raises `Interrupted` at once.

    Parameters
    ----------
    parent : int
        The pid of the process that forked this one.
    own_group : bool
        Lead a process group of its own (the parent ends it with `end_process_group`; a
        terminal's Ctrl-C then reaches the parent only, which ends it).
    """
    if own_group:
        try:
            os.setpgid(0, 0)
        except OSError:
            pass
    _received.clear()
    for sig in INTERRUPTING_SIGNALS:
        signal.signal(sig, _raise_interrupted)
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before the death signal was set
        raise Interrupted(int(signal.SIGTERM))


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
