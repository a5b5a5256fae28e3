"""Shared helpers of the benchmarks: interleaved repetitions, summaries, JSON records.

Every benchmark times its contenders interleaved (A B C, A B C, ...), so a
change of machine load hits all of them alike, repeats at least three times,
prints min and median and the ratio of every repetition, checks its floors on
the median ratio (never on one shot) and writes a JSON record to
``benchmarks/results/<name>.json`` with the machine, the versions of the
libraries and the load average before and after.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import statistics
import time
from importlib import metadata
from pathlib import Path
from typing import Any, Callable, Mapping

__all__ = ["interleave", "summary", "ratios", "machine", "code_version", "write_record", "scratch_cwd", "environ",
           "Floors"]

RESULTS = Path(__file__).resolve().parents[1] / "results"


def interleave(contenders: Mapping[str, Callable[[], Any]], reps: int = 3,
               number: int = 1) -> dict[str, list[float]]:
    """Wall times (s, per call) of each contender, interleaved over ``reps`` repetitions.

    ``number`` calls are timed together and divided (for calls of a few microseconds).
    """
    times: dict[str, list[float]] = {name: [] for name in contenders}
    for _ in range(int(reps)):
        for name, fn in contenders.items():
            t0 = time.perf_counter()
            for _ in range(int(number)):
                fn()
            times[name].append((time.perf_counter() - t0) / int(number))
    return times


def summary(values: list[float]) -> dict[str, float]:
    """``min`` and ``median`` of a list of times."""
    return {"min": min(values), "median": statistics.median(values)}


def ratios(slow: list[float], fast: list[float]) -> list[float]:
    """Per-repetition ratio ``slow / fast`` (> 1: ``fast`` is faster)."""
    return [a / b for a, b in zip(slow, fast)]


def _version(pkg: str) -> str | None:
    try:
        return metadata.version(pkg)
    except metadata.PackageNotFoundError:
        return None


def code_version() -> dict[str, Any]:
    """The commit of the measured tree (``git rev-parse HEAD``) and whether it had local edits."""
    import subprocess

    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=10", "HEAD"],
                              capture_output=True, text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--", "tanksynth"],
                               capture_output=True, text=True, timeout=10).stdout.strip() != ""
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "library_edited": None}
    return {"commit": head or None, "library_edited": dirty}


def machine() -> dict[str, Any]:
    """Machine, interpreter, library versions, load average and the measured commit."""
    pkgs = ("numpy", "scipy", "sympy", "casadi", "cvxpy", "clarabel", "control", "threadpoolctl",
            "filterpy", "tanksynth", "numba", "llvmlite", "jax", "jaxlib")
    return {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
            "cpus": os.cpu_count(), "python": platform.python_version(),
            "versions": {p: _version(p) for p in pkgs},
            "loadavg": list(os.getloadavg()), "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            **code_version()}


def write_record(name: str, payload: Mapping[str, Any], before: Mapping[str, Any]) -> Path:
    """Write ``benchmarks/results/<name>.json``: ``payload`` plus the machine before and after."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / f"{name}.json"
    record = {"benchmark": name, "machine": before, "loadavg_after": list(os.getloadavg()),
              **payload}
    path.write_text(json.dumps(record, indent=1, default=float) + "\n")
    return path


@contextlib.contextmanager
def environ(**values: str):
    """Set environment variables for a block (e.g. force a library kernel to build now)."""
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


_SCRATCH: list[str] = []


@contextlib.contextmanager
def scratch_cwd():
    """Run a block in a scratch working directory, one per process under the system temp dir.

    CasADi's ``jit`` writes its C source and shared library to the current directory and
    removes them when the Function is destroyed: the directory is left in place for that
    (empty once they are gone), so no file lands in the work tree.
    """
    import tempfile

    if not _SCRATCH:
        _SCRATCH.append(tempfile.mkdtemp(prefix="tanksynth-bench-jit-"))
    old = os.getcwd()
    os.chdir(_SCRATCH[0])
    try:
        yield Path(_SCRATCH[0])
    finally:
        os.chdir(old)


class Floors:
    """Floors checked on median ratios; `failed` lists the misses."""

    def __init__(self) -> None:
        self.rows: list[dict[str, Any]] = []

    def check(self, what: str, median_ratio: float, floor: float, stat: str = "median",
              strict_only: bool = False) -> bool:
        """Record one floor: ``median_ratio`` (or the ``stat`` named) >= ``floor``.

        ``strict_only``: a miss makes the benchmark exit 1 only with ``--strict`` (issue 29's
        floors against compiled contenders, while the library's kernels are being built).
        """
        ok = median_ratio >= floor
        self.rows.append({"what": what, "median_ratio": median_ratio, "stat": stat, "floor": floor,
                          "ok": ok, "strict_only": strict_only})
        print(f"  floor {'ok  ' if ok else 'MISS'} {what}: {stat} ratio {median_ratio:.3g} "
              f"(floor {floor:g}){' [exit 1 only with --strict]' if strict_only and not ok else ''}")
        return ok

    def blocking(self, strict: bool) -> list[dict[str, Any]]:
        """The misses that make the benchmark exit 1 (every miss with ``strict``)."""
        return [r for r in self.failed if strict or not r.get("strict_only")]

    def exit_status(self, strict: bool = False) -> int:
        """Print the misses; 1 when one of them is `blocking`, else 0."""
        if self.failed:
            print("FLOORS MISSED: " + "; ".join(r["what"] for r in self.failed))
        return 1 if self.blocking(strict) else 0

    @property
    def failed(self) -> list[dict[str, Any]]:
        return [r for r in self.rows if not r["ok"]]
