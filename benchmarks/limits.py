"""Wall-time limits that were assertions of the test suite (issue 26, item 7).

A test that asserts on wall-clock time fails on a loaded machine. The tests keep what they
check besides time (the refusal and its message, the exit code, the key named, that a cut-off
build leaves no process behind, that the configured budget or timeout is the one that acted);
how fast it happens is measured here, against the bound the test used to assert:

| limit | was asserted in | floor |
|---|---|---|
| ``parse``: 4 deeply nested texts | tests/plants/test_parser.py::test_deep_nesting_refused | 0.5 s each |
| ``parse``: 6 huge constants | tests/plants/test_parser.py::test_huge_constants_refused | 0.5 s each |
| ``parse``: 400 arbitrary / 400 grammar-shaped texts, slowest of each set | the two hypothesis properties of test_parser.py (``deadline=500`` ms) | 0.5 s |
| ``tank_network(64)`` build (sympy cache cleared) | tests/plants/test_tank_network.py::test_N64_builds_and_compiles | 2 s |
| ``check --spec-only`` on each crash input of issue 19 | tests/fuzz/test_crash_inputs.py::test_crash_input_is_exit_2_naming_the_key | 10 s each |
| ``check --json``, a symbolic step past a 2 s budget | test_crash_inputs.py::test_symbolic_step_past_its_budget_is_a_skipped_check | 60 s |
| ``verify``, a FIFO as ``plant.json`` / as the lock file | test_crash_inputs.py::test_a_fifo_* | 10 s each |
| ``verify --scheduler`` silent / refused / malformed, ``--connect-timeout 1`` | tests/verify/test_cluster.py | 15 s each |
| ``compile_pdf`` of a never-ending document, ``timeout=3`` | tests/reports/test_latex.py::test_latex_timeout_ends_the_whole_process_group | 20 s (skipped without pdflatex) |

Every limit runs once per repetition, all of them interleaved (A B C ..., A B C ...), ``--reps``
times (>= 3); the first repetition pays the imports (``distributed`` for the scheduler rows), as
the test did. Min and median wall time are printed beside the floor; a floor holds when the
median is under it. Each call's outcome is checked too (the ParseError, exit code 2 and its
message, no pdflatex left): a wrong outcome fails the run like a missed floor (exit 1).
Record: ``results/limits.json``.

Usage::

    .venv/bin/python benchmarks/limits.py                    # every limit, 3 reps (about 1 min)
    .venv/bin/python benchmarks/limits.py --reps 5 --only parse tank_network
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import machine, summary, write_record  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "fuzz"))

import sympy as sp  # noqa: E402

from tanksynth.errors import ParseError  # noqa: E402
from tanksynth.plants.parser import parse_expression  # noqa: E402
from tanksynth.plants.tank_network import tank_network  # noqa: E402

EXAMPLES = ROOT / "examples"
PARSE_FLOOR = 0.5         # s, tests/plants/test_parser.py
NETWORK_FLOOR = 2.0       # s, tests/plants/test_tank_network.py
CRASH_FLOOR = 10.0        # s, tests/fuzz/test_crash_inputs.py
BUDGET_FLOOR = 60.0       # s, the symbolic budget case (budget 2 s)
CLUSTER_FLOOR = 15.0      # s, tests/verify/test_cluster.py
LATEX_FLOOR = 20.0        # s, tests/reports/test_latex.py (timeout 3 s)
#: The silent scheduler's socket, closed at the end.
scratch_socket: list[socket.socket] = []

# The texts of tests/plants/test_parser.py.
_X, _Y, _A = sp.Symbol("x", real=True), sp.Symbol("y", real=True), sp.Symbol("A", positive=True)
NAMES = {"x": _X, "y": _Y, "A": _A}
KEY = "plant.equations.h1"
DEEP = {"1000 brackets": "(" * 1000 + "x" + ")" * 1000, "1000 minus": "-" * 1000 + "x",
        "500 sqrt": "sqrt(" * 500 + "x" + ")" * 500, "500 powers": "x" + "**x" * 500}
#: name: (text, what the refusal says)
HUGE = {"1e9999999": ("1e9999999", "out of range"), "1e-9999999": ("1e-9999999", "out of range"),
        "((2**64)**64)**64": ("((2**64)**64)**64", "4096 bits"),
        "(1.0...01**64)**64": ("(1.000000000000000000000000000000000001**64)**64", "4096 bits"),
        "2000 x 1e300": ("*".join(["1e300"] * 2000), "longer than"),
        "2**exp(exp(exp(exp(10))))": ("2**exp(exp(exp(exp(10))))", "exactly")}
GRAMMAR = list("xyA0123456789.eE+-*/() ,") + ["**", "sqrt(", "abs(", "sign(", "exp(", "log(",
                                             "min(", "max("]


def _parse(text: str):
    return parse_expression(text, NAMES, KEY)


def corpora(count: int = 400, seed: int = 0) -> dict[str, list[str]]:
    """The hypothesis properties' inputs, drawn with a fixed seed: arbitrary text (any code point
    but surrogates, mostly printable ASCII) and grammar-shaped text (up to 40 tokens)."""
    rng = random.Random(seed)

    def char() -> str:
        if rng.random() < 0.7:
            return chr(rng.randint(32, 126))
        c = rng.randint(0, 0x10FFFF)
        return chr(c) if not 0xD800 <= c <= 0xDFFF else "\u00e9"

    arbitrary = ["".join(char() for _ in range(rng.randint(0, 60))) for _ in range(count)]
    shaped = ["".join(rng.choice(GRAMMAR) for _ in range(rng.randint(0, 40))) for _ in range(count)]
    return {"arbitrary": arbitrary, "grammar-shaped": shaped}


class Limit:
    """One timed call, its floor (s) and the check of its outcome (raises on a wrong one)."""

    def __init__(self, name: str, source: str, floor: float, call: Callable[[], float | None]):
        self.name, self.source, self.floor, self.call = name, source, floor, call
        self.times: list[float] = []
        self.errors: list[str] = []

    def run(self) -> None:
        t0 = time.perf_counter()
        try:
            inner = self.call()       # a corpus returns the time of its slowest text
        except Exception as exc:  # noqa: BLE001 - reported, the run fails
            self.errors.append(f"{type(exc).__name__}: {exc}"[:300])
            inner = None
        self.times.append(inner if inner is not None else time.perf_counter() - t0)


def _refused(text: str, match: str) -> Callable[[], None]:
    def call() -> None:
        try:
            _parse(text)
        except ParseError as exc:
            if match not in str(exc):
                raise AssertionError(f"refused, but not by the limit expected ({match!r}): {exc}")
            return
        raise AssertionError("not refused")
    return call


def _corpus(texts: list[str]) -> Callable[[], float]:
    def call() -> float:
        worst = 0.0
        for text in texts:
            t0 = time.perf_counter()
            try:
                out = _parse(text)
            except ParseError:
                pass
            else:
                assert isinstance(out, sp.Basic) and out.free_symbols <= {_X, _Y, _A}, text
            worst = max(worst, time.perf_counter() - t0)
        return worst
    return call


def _network() -> float:
    from sympy.core.cache import clear_cache

    clear_cache()
    t0 = time.perf_counter()
    plant = tank_network(64)
    seconds = time.perf_counter() - t0
    assert (plant.n, plant.m) == (64, 32)
    return seconds


def _cli(argv: list, codes: tuple[int, ...], *needles: str, env: dict | None = None) -> Callable[[], float]:
    from fuzz_helpers import run

    def call() -> float:
        saved = {k: os.environ.get(k) for k in (env or {})}
        os.environ.update(env or {})
        try:
            got, out, err, seconds = run(argv)
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
        text = out + err
        if got not in codes or not all(n in text for n in needles):
            raise AssertionError(f"exit {got} (expected {codes}): {err.strip()[:300]}")
        return seconds
    return call


def _fifo_verify(base: Path, scratch: Path, which: str) -> Callable[[], float]:
    from fuzz_helpers import run

    def call() -> float:
        d = scratch / f"fifo-{which}"
        shutil.rmtree(d, ignore_errors=True)
        shutil.copytree(base, d)
        if which == "plant.json":
            (d / "plant.json").unlink()
        os.mkfifo(d / which)
        code, _, err, seconds = run(["verify", d, "--json"])
        if code != 2 or which not in err:
            raise AssertionError(f"exit {code}: {err.strip()[:300]}")
        return seconds
    return call


def _latex(scratch: Path) -> Callable[[], float]:
    from tanksynth.errors import ReportError
    from tanksynth.reports.pdf import compile_pdf

    def call() -> float:
        tex = scratch / "forever_loop_doc.tex"
        tex.write_text("\\documentclass{article}\\begin{document}\\def\\x{\\x}\\x\\end{document}\n")
        t0 = time.perf_counter()
        try:
            compile_pdf(tex, timeout=3)
        except ReportError as exc:
            seconds = time.perf_counter() - t0
            if "did not finish within 3 s" not in str(exc):
                raise
        else:
            raise AssertionError("a never-ending document compiled")
        for _ in range(300):
            left = subprocess.run(["pgrep", "-f", "forever_loop_doc"], capture_output=True,
                                  text=True).stdout.strip()
            if not left:
                return seconds
            time.sleep(0.1)
        raise AssertionError(f"processes left: {left}")
    return call


def limits(scratch: Path) -> list[Limit]:
    """Every limit, its call set up (designs and spec files written here, untimed)."""
    from fuzz_helpers import run
    from test_crash_inputs import CASES, CUSTOM

    out = [Limit(f"parse: {k}", "tests/plants/test_parser.py::test_deep_nesting_refused",
                 PARSE_FLOOR, _refused(t, "nested")) for k, t in DEEP.items()]
    out += [Limit(f"parse: {k}", "tests/plants/test_parser.py::test_huge_constants_refused",
                  PARSE_FLOOR, _refused(t, m)) for k, (t, m) in HUGE.items()]
    for k, texts in corpora().items():
        out.append(Limit(f"parse: {len(texts)} {k} texts, slowest",
                         "tests/plants/test_parser.py (hypothesis deadline 500 ms)",
                         PARSE_FLOOR, _corpus(texts)))
    out.append(Limit("tank_network(64) build", "tests/plants/test_tank_network.py::"
                     "test_N64_builds_and_compiles", NETWORK_FLOOR, _network))

    specs = scratch / "specs"
    specs.mkdir()
    for case in sorted(CASES):
        text, key, match = CASES[case]
        spec = specs / f"{case}.toml"
        spec.write_text(text, encoding="utf-8")
        out.append(Limit(f"check --spec-only: {case}", "tests/fuzz/test_crash_inputs.py::"
                         "test_crash_input_is_exit_2_naming_the_key", CRASH_FLOOR,
                         _cli(["check", "--spec-only", spec], (2,), match)))
    budget = specs / "symbolic_budget.toml"
    budget.write_text(CUSTOM.replace('y = {expr = "h2"', 'y = {expr = "(h1+h2+1)**64"'), encoding="utf-8")
    out.append(Limit("check --json: symbolic step past a 2 s budget", "tests/fuzz/test_crash_inputs.py::"
                     "test_symbolic_step_past_its_budget_is_a_skipped_check", BUDGET_FLOOR,
                     _cli(["check", "--json", budget], (0,), "did not finish within 2 s",
                          env={"TANKSYNTH_SYMBOLIC_SECONDS": "2"})))

    base = scratch / "custom"
    for argv in (["design", EXAMPLES / "custom_two_tank.toml", "-o", base], ["verify", base, "--json"]):
        code, _, err, _ = run(argv)
        assert code == 0, err
    for which, test in (("plant.json", "test_a_fifo_or_device_in_a_result_directory_does_not_hang"),
                        (".tanksynth.lock", "test_a_fifo_as_the_lock_file_does_not_hang")):
        out.append(Limit(f"verify: a FIFO as {which}", f"tests/fuzz/test_crash_inputs.py::{test}",
                         CRASH_FLOOR, _fifo_verify(base, scratch, which)))

    designed = scratch / "seed000"
    code, _, err, _ = run(["design", EXAMPLES / "seed000_three_tank.toml", "-o", designed])
    assert code == 0, err
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(5)                  # accepts connections (backlog), never answers
    scratch_socket.append(silent)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        refused = s.getsockname()[1]
    for what, address in (("silent", f"tcp://127.0.0.1:{silent.getsockname()[1]}"),
                          ("refused", f"tcp://127.0.0.1:{refused}"), ("malformed", "bogus!!")):
        out.append(Limit(f"verify --scheduler: {what}", "tests/verify/test_cluster.py", CLUSTER_FLOOR,
                         _cli(["verify", designed, "--scheduler", address, "--connect-timeout", "1"],
                              (2,), "Dask scheduler")))
    if shutil.which("pdflatex"):
        out.append(Limit("compile_pdf: never-ending document, timeout 3 s", "tests/reports/"
                         "test_latex.py::test_latex_timeout_ends_the_whole_process_group",
                         LATEX_FLOOR, _latex(scratch)))
    else:
        print("compile_pdf row skipped: pdflatex not installed (make tex)")
    return out

def main(argv: list[str] | None = None) -> int:
    """Time every limit; exit 1 on a floor missed or a wrong outcome."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=3, help="interleaved repetitions (>= 3)")
    ap.add_argument("--only", nargs="+", default=None, help="limits whose name contains one of these")
    args = ap.parse_args(argv)
    reps = max(int(args.reps), 3)
    before = machine()
    with tempfile.TemporaryDirectory(prefix="tanksynth-limits-") as tmp:
        os.environ["TANKSYNTH_CACHE_DIR"] = str(Path(tmp) / "cache")
        try:
            rows = limits(Path(tmp))
            if args.only:
                rows = [r for r in rows if any(o in r.name for o in args.only)]
            for rep in range(reps):
                for row in rows:
                    row.run()
                print(f"  rep {rep + 1}/{reps} done, load {[round(v, 2) for v in os.getloadavg()]}")
        finally:
            for s in scratch_socket:
                s.close()
    print(f"\n{'limit':58s} {'min s':>8s} {'median s':>9s} {'floor s':>8s}")
    records, failed = [], []
    for row in rows:
        sm = summary(row.times)
        ok = sm["median"] < row.floor and not row.errors
        mark = "ok  " if ok else "MISS" if not row.errors else "FAIL"
        print(f"{row.name[:58]:58s} {sm['min']:8.3f} {sm['median']:9.3f} {row.floor:8.1f}  {mark}")
        for e in sorted(set(row.errors)):
            print(f"    {e}")
        if not ok:
            failed.append(row.name)
        records.append({"limit": row.name, "test": row.source, "floor_s": row.floor, "times": row.times,
                        **sm, "ok": ok, "errors": row.errors})
    held = sum(r["ok"] for r in records)
    print(f"\n{held} of {len(records)} floors hold" + (f"; missed or failed: {', '.join(failed)}" if failed else ""))
    path = write_record("limits", {"reps": reps, "only": args.only, "rows": records}, before)
    print(f"record: {path.relative_to(ROOT)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
