"""The wall-clock budget of a symbolic step: run it in a forked child, kill the child at the budget.

A symbolic step on a user model (a determinant, a factorisation, a simplification) can run
for hours. An interval timer (SIGALRM) does not bound it everywhere: it is not delivered off
the main thread, it cannot be armed when the caller already runs a timer, and a signal reaches
Python code only after a long C call (big-integer arithmetic, a section with SIGALRM blocked)
returns. So the step runs in a child process forked for it (`os.fork`), which returns its
result pickled through a pipe; at the budget the parent kills the child (SIGKILL) and raises
`TooComplexError`. The child dies with its parent (``PR_SET_PDEATHSIG`` on Linux) and has a
CPU-time limit a little above the budget as a second guard. Where ``fork`` is unavailable (or
fails: no process to spare) the step runs in the process, under SIGALRM in the main thread and
without a budget elsewhere.

A fork (and the child's exit) costs about 30 ms per call for a 230 MB process on a loaded
2-core machine (measured: 50 trivial steps), against 0.8-1.3 s for the three-tank's relative
degree; callers run a step once per plant and design, and `run_within_budget` keeps the
results of the last calls (keyed by the step and its pickled arguments), so a repeated step
forks once.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import pickle
import selectors
import signal
import sys
import threading
import time
import traceback
from collections import OrderedDict
from typing import Any, Callable, Iterator, TypeVar

from tanksynth.errors import SpecError, TanksynthError

__all__ = ["SYMBOLIC_SECONDS", "TooComplexError", "budget_seconds", "run_within_budget",
           "forked_budget_available"]

#: Wall-clock budget (s) of one symbolic step (determinant, factorisation, simplification,
#: Lie derivatives) on a user model; override with TANKSYNTH_SYMBOLIC_SECONDS.
SYMBOLIC_SECONDS = 20.0

#: Largest pickled result (bytes) a child may send back; a larger one is refused as too complex.
RESULT_LIMIT_BYTES = 256 * 2**20

#: How many results of budgeted steps are kept (a repeated step is not forked again), and the
#: largest pickled result kept (bytes): at most 32 x 4 MiB.
MEMO_SIZE = 32
MEMO_MAX_BYTES = 4 * 2**20

T = TypeVar("T")

_state = threading.local()
_in_child = False                 # set in a forked child: nested budgets run in it directly
_memo: OrderedDict[bytes, Any] = OrderedDict()
_memo_lock = threading.Lock()


class TooComplexError(SpecError):
    """A symbolic step on the model did not finish within its budget ("too complex for
    symbolic analysis"): exit 2, naming the plant; checks report it as not attempted.

    Parameters
    ----------
    message : str
        Which step did not finish and what to do (simplify the expressions, raise the budget).
    key : str, optional
        Dotted spec key of the offending expression, e.g. ``plant.outputs``.
    source : str, optional
        File the spec came from, if any.
    """


def budget_seconds(seconds: float | None = None) -> float:
    """The budget of one symbolic step (s): ``seconds``, else ``TANKSYNTH_SYMBOLIC_SECONDS``,
    else `SYMBOLIC_SECONDS` (also for a value that is not a number in (0, 1e6)).

    Parameters
    ----------
    seconds : float, optional
        Explicit budget (s).
    """
    if seconds is not None:
        return float(seconds)
    try:
        value = float(os.environ.get("TANKSYNTH_SYMBOLIC_SECONDS", SYMBOLIC_SECONDS))
    except ValueError:
        return SYMBOLIC_SECONDS
    return value if 0 < value < 1e6 else SYMBOLIC_SECONDS


def forked_budget_available() -> bool:
    """Whether a budgeted step runs in a forked child (POSIX) rather than in the process."""
    return hasattr(os, "fork") and hasattr(os, "waitpid") and not _in_child


def _over_budget(what: str, limit: float, key: str, why: str | None = None) -> TooComplexError:
    return TooComplexError(f"too complex for symbolic analysis: {what} did not finish within "
                           f"{limit:g} s (TANKSYNTH_SYMBOLIC_SECONDS)"
                           + (f"; {why}" if why else "") + "; simplify the model expressions",
                           key=key)


def run_within_budget(step: Callable[..., T], *args: Any, what: str, seconds: float | None = None,
                      key: str = "plant") -> T:
    """``step(*args)`` under a wall-clock budget; past it, raise `TooComplexError`.

    The step runs in a forked child process killed at the budget (see the module notes), so
    the budget holds in any thread, beside a caller's interval timer and through long C
    calls. Inside a budgeted step a nested one runs directly (the outer budget governs). The
    results of the last `MEMO_SIZE` steps are kept: the same step on the same arguments
    returns its earlier result (unpickled again: the caller's copy is its own).

    Parameters
    ----------
    step : callable
        A module-level function; its result (or exception) must pickle.
    *args
        Its arguments (picklable).
    what : str
        The step, for the message (``"the symbolic observability determinant"``).
    seconds : float, optional
        Budget in s; default `SYMBOLIC_SECONDS` (or ``TANKSYNTH_SYMBOLIC_SECONDS``).
    key : str
        Spec key named by the error.

    Returns
    -------
    The step's result.

    Raises
    ------
    TooComplexError
        The step did not finish within the budget (or its process ended without a result,
        e.g. killed for memory).
    Exception
        Whatever the step raised, raised again in the caller.
    """
    limit = budget_seconds(seconds)
    if getattr(_state, "active", False):
        return step(*args)
    if not forked_budget_available():
        if _in_child:
            return step(*args)
        with _alarm_budget(what, limit, key):
            return step(*args)
    memo_key = _memo_key(step, args)
    if memo_key is not None:
        with _memo_lock:
            cached = _memo.get(memo_key)
            if cached is not None:
                _memo.move_to_end(memo_key)
        if cached is not None:
            return pickle.loads(cached)
    try:
        payload = _run_forked(step, args, what, limit, key)
    except _ForkFailed:                        # no process to spare (EAGAIN, ENOMEM): in here
        with _alarm_budget(what, limit, key):
            return step(*args)
    if memo_key is not None and len(payload) <= MEMO_MAX_BYTES:
        with _memo_lock:
            _memo[memo_key] = payload
            while len(_memo) > MEMO_SIZE:
                _memo.popitem(last=False)
    return pickle.loads(payload)


def _memo_key(step: Callable[..., Any], args: tuple) -> bytes | None:
    try:
        blob = pickle.dumps((step.__module__, step.__qualname__, args), pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - an argument that does not pickle: no memo, still run
        return None
    return hashlib.sha256(blob).digest()


# ------------------------------------------------------------------------ the forked child
class _ForkFailed(Exception):
    """``os.fork`` failed: the step runs in the process instead."""


def _run_forked(step: Callable[..., Any], args: tuple, what: str, limit: float, key: str) -> bytes:
    """Fork, run ``step(*args)`` in the child, return its pickled result (or raise its error)."""
    read_fd, write_fd = os.pipe()
    parent = os.getpid()
    try:
        pid = os.fork()
    except OSError:
        os.close(read_fd)
        os.close(write_fd)
        raise _ForkFailed from None
    if pid == 0:                                       # the child: never returns
        _child_main(step, args, read_fd, write_fd, parent, limit)
    os.close(write_fd)
    try:
        data = _read_until(read_fd, time.monotonic() + limit, what, limit, key)
    finally:
        os.close(read_fd)
        status = _reap(pid)
    if not data:                 # killed (memory, CPU limit) or crashed before sending anything
        why = (f"its process ended by signal {os.WTERMSIG(status)} without a result"
               if status is not None and os.WIFSIGNALED(status) else
               "its process ended without a result")
        raise _over_budget(what, limit, key, why)
    ok, payload = pickle.loads(data)
    if ok is None:
        raise _over_budget(what, limit, key, f"its result exceeds {RESULT_LIMIT_BYTES // 2**20} MiB")
    if ok:
        return payload
    raise _child_error(payload, what)


def _child_main(step: Callable[..., Any], args: tuple, read_fd: int, write_fd: int, parent: int,
                limit: float) -> None:
    global _in_child
    code = 0
    try:
        os.close(read_fd)
        _in_child = True
        _detach_from_parent_handlers(parent, limit)
        result: tuple[bool | None, Any]
        try:
            result = (True, pickle.dumps(step(*args), pickle.HIGHEST_PROTOCOL))
        except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
            result = (False, _error_record(exc))
        data = pickle.dumps(result, pickle.HIGHEST_PROTOCOL)
        if len(data) > RESULT_LIMIT_BYTES:
            data = pickle.dumps((None, None), pickle.HIGHEST_PROTOCOL)   # the parent says so
        view = memoryview(data)
        while view:
            view = view[os.write(write_fd, view):]
    except BaseException:  # noqa: BLE001 - the child must end here, whatever happened
        code = 70
    finally:
        os._exit(code)


def _detach_from_parent_handlers(parent: int, limit: float) -> None:
    """In the child: default signal dispositions (the parent's handlers release its lock, stop
    its workers: not the child's business), die with the parent, a CPU-time ceiling."""
    for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGALRM", "SIGCHLD", "SIGPIPE"):
        if hasattr(signal, name):
            with contextlib.suppress(OSError, ValueError):
                signal.signal(getattr(signal, name), signal.SIG_DFL)
    if hasattr(signal, "pthread_sigmask"):
        with contextlib.suppress(OSError, ValueError):
            signal.pthread_sigmask(signal.SIG_SETMASK, set())
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL, 0, 0, 0)       # PR_SET_PDEATHSIG
    if os.getppid() != parent:                            # the parent died before prctl
        os._exit(70)
    with contextlib.suppress(Exception):
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_CPU)
        used = time.process_time()
        cap = int(math.ceil(used + limit)) + 5
        if hard == resource.RLIM_INFINITY or cap < hard:
            resource.setrlimit(resource.RLIMIT_CPU, (cap, hard))


def _error_record(exc: BaseException) -> tuple[bytes | None, str, str, str]:
    """The child's exception, pickled when it pickles, with its type, text and traceback."""
    try:
        blob: bytes | None = pickle.dumps(exc, pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - unpicklable: the type and text still go back
        blob = None
    text = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    return blob, type(exc).__name__, str(exc), text[-20000:]


def _child_error(record: tuple[bytes | None, str, str, str], what: str) -> BaseException:
    blob, name, message, text = record
    exc: BaseException | None = None
    if blob is not None:
        with contextlib.suppress(Exception):
            exc = pickle.loads(blob)
    if not isinstance(exc, BaseException):
        exc = TanksynthError(f"{what}: {name}: {message}")
    with contextlib.suppress(Exception):
        exc.add_note("raised in the symbolic step's child process:\n" + text)
    return exc


def _read_until(fd: int, deadline: float, what: str, limit: float, key: str) -> bytes:
    chunks: list[bytes] = []
    size = 0
    with selectors.DefaultSelector() as sel:
        sel.register(fd, selectors.EVENT_READ)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise _over_budget(what, limit, key)
            if not sel.select(remaining):
                continue
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                return b"".join(chunks)
            size += len(chunk)
            if size > RESULT_LIMIT_BYTES + 2**16:
                raise _over_budget(what, limit, key, "its result is too large")
            chunks.append(chunk)


def _reap(pid: int) -> int | None:
    """Kill the child (a no-op once it has exited) and collect its status."""
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)
    try:
        return os.waitpid(pid, 0)[1]
    except ChildProcessError:                   # reaped by someone else (SIGCHLD ignored)
        return None


# ------------------------------------------------------------------ in-process fallback
@contextlib.contextmanager
def _alarm_budget(what: str, limit: float, key: str) -> Iterator[None]:
    """SIGALRM budget, where fork is unavailable: main thread only, never over another timer."""
    usable = (threading.current_thread() is threading.main_thread() and hasattr(signal, "setitimer")
              and signal.getitimer(signal.ITIMER_REAL)[0] == 0)
    _state.active = True
    try:
        if not usable:
            yield
            return

        def _expired(signum, frame):  # noqa: ARG001 - signal handler signature
            raise _over_budget(what, limit, key)

        previous = signal.signal(signal.SIGALRM, _expired)
        try:
            signal.setitimer(signal.ITIMER_REAL, limit)
            yield
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)
    finally:
        _state.active = False
