"""The symbolic budget holds wherever a step runs (issue 31 item 11).

A SIGALRM timer did not bound a step off the main thread, beside a caller's own interval timer,
or through a call that keeps the signal from Python (a long C call, a section with SIGALRM
blocked): `tanksynth check` then hung its xdist worker. Each test below runs a step that blocks
for `HANG_GUARD` s with SIGALRM blocked (a C call as seen by a signal) and asserts it was
skipped as over its budget and cut off there (the blocking call never ended in the caller's
process: it was not waited for), not the time it took.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest
import sympy as sp

from tanksynth.analysis.symbolic import TooComplexError, relative_degree
from tanksynth.errors import TanksynthError

pytestmark = pytest.mark.skipif(not hasattr(signal, "pthread_sigmask") or not hasattr(os, "fork"),
                                reason="POSIX signals and fork")

HANG_GUARD = 60.0      # s a blocked step lasts when nothing cuts it off (the budget is 1 s)


@pytest.fixture
def blocking_simplify(monkeypatch):
    """``sympy.simplify`` (the relative degree's step) blocks `HANG_GUARD` s with SIGALRM masked;
    returns the list of the blocking calls that ended in this process (slept to their end, or
    were interrupted here): a step cut off at its budget never ends here."""
    ended_here: list[int] = []
    real = sp.simplify

    def blocked(expr, *args, **kwargs):
        old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM})
        try:
            time.sleep(HANG_GUARD)
        finally:
            ended_here.append(os.getpid())   # first: a signal handled at unmasking comes after
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        return real(expr, *args, **kwargs)

    monkeypatch.setattr(sp, "simplify", blocked)
    monkeypatch.setenv("TANKSYNTH_SYMBOLIC_SECONDS", "1")
    return ended_here


def _double_integrator(tag: str):
    """A fresh model per test (fresh symbols: no earlier result of the same step is reused)."""
    x1, x2, u = sp.symbols(f"x1_{tag} x2_{tag} u_{tag}", real=True)
    return sp.Matrix([x2, -sp.sin(x1) + 2 * u]), sp.Matrix([x1]), [x1, x2], [u]


def _outcome(call) -> str:
    try:
        call()
    except TooComplexError as exc:
        assert "did not finish within 1 s" in str(exc), exc
        return "skipped"
    return "finished"


def test_budget_holds_through_a_call_that_blocks_sigalrm(blocking_simplify):
    assert _outcome(lambda: relative_degree(*_double_integrator("c"))) == "skipped"
    assert blocking_simplify == []                  # cut off, not waited for


def test_budget_holds_off_the_main_thread(blocking_simplify):
    outcome: list[str] = []
    worker = threading.Thread(target=lambda: outcome.append(
        _outcome(lambda: relative_degree(*_double_integrator("t")))), daemon=True)
    worker.start()
    worker.join(HANG_GUARD * 3)                     # hang guard only
    assert not worker.is_alive() and outcome == ["skipped"], outcome
    assert blocking_simplify == []


def test_budget_holds_beside_the_callers_interval_timer(blocking_simplify):
    fired: list[int] = []
    previous = signal.signal(signal.SIGALRM, lambda signum, frame: fired.append(signum))
    signal.setitimer(signal.ITIMER_REAL, 1000.0)    # the caller's own timer, left running
    try:
        assert _outcome(lambda: relative_degree(*_double_integrator("i"))) == "skipped"
        assert signal.getitimer(signal.ITIMER_REAL)[0] > 0   # and not replaced or cancelled
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert blocking_simplify == [] and fired == []


def test_a_real_long_computation_is_cut_off_in_a_thread():
    """sympy factorising a 200-digit semiprime (hours), from a worker thread."""
    from tanksynth.analysis.budget import run_within_budget

    p, q = sp.nextprime(10**99 + 12345), sp.nextprime(3 * 10**99 + 6789)
    outcome: list[str] = []

    def factor() -> None:
        try:
            run_within_budget(sp.factorint, p * q, what="a factorisation", seconds=1.0)
            outcome.append("finished")
        except TooComplexError:
            outcome.append("skipped")

    worker = threading.Thread(target=factor, daemon=True)
    worker.start()
    worker.join(HANG_GUARD * 3)
    assert not worker.is_alive() and outcome == ["skipped"]


def _dies() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def _raises() -> None:
    raise TanksynthError("relative degree undefined (from the step)")


def _matrix(n: int) -> sp.Matrix:
    return sp.Matrix(n, n, lambda i, j: sp.Symbol(f"a{i}{j}", positive=True) ** (i + j))


def test_results_and_errors_come_back_from_the_step():
    from tanksynth.analysis.budget import forked_budget_available, run_within_budget

    assert forked_budget_available()
    assert run_within_budget(_matrix, 3, what="m") == _matrix(3)       # sympy objects, pickled
    with pytest.raises(TanksynthError, match="from the step"):
        run_within_budget(_raises, what="r")
    with pytest.raises(TooComplexError, match="ended by signal 9"):  # e.g. killed for memory
        run_within_budget(_dies, what="d", seconds=30.0)


def test_a_result_past_its_size_limit_is_refused(monkeypatch):
    import tanksynth.analysis.budget as budget

    monkeypatch.setattr(budget, "RESULT_LIMIT_BYTES", 100)
    with pytest.raises(TooComplexError, match="its result exceeds"):
        budget.run_within_budget(_matrix, 6, what="a large matrix")


def test_a_repeated_step_is_not_run_again(monkeypatch):
    model = _double_integrator("memo")
    first = relative_degree(*model)
    monkeypatch.setattr(sp, "simplify", lambda *args, **kwargs: _raises())   # a second run fails
    again = relative_degree(*model)
    assert again == first and again.decoupling is not first.decoupling   # the caller's own copy
