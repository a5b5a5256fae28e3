"""Helpers of the adversarial tests: a small TOML writer, the in-process CLI runner and the
exit-code contract every input must keep (exit 0/1/2/3, at most one stderr line, no traceback,
bounded time and memory)."""

from __future__ import annotations

import contextlib
import faulthandler
import io
import json
import math
import os
import re
import resource
import time
from pathlib import Path

from tanksynth.cli import main

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
#: Scale of the case counts: ``make fuzz`` sets TANKSYNTH_FUZZ_SCALE=10 (>= 20,000 cases).
SCALE = max(1, int(os.environ.get("TANKSYNTH_FUZZ_SCALE", "1")))
#: Time bound of one case (s) and of the process's peak memory (bytes).
MAX_SECONDS = float(os.environ.get("TANKSYNTH_FUZZ_SECONDS", "20"))
MAX_RSS = 3 * 1024 ** 3
#: A case still running after this many seconds is a hang: the process dumps its stacks and exits.
WATCHDOG_SECONDS = 300

_BARE = re.compile(r"[A-Za-z0-9_-]+\Z")


def toml_value(value) -> str:
    """One TOML value (inline tables and arrays; floats keep inf/nan)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string accepts JSON's escapes
    if isinstance(value, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise TypeError(type(value))


def toml_key(key) -> str:
    key = str(key)
    return key if _BARE.match(key) else json.dumps(key)


def toml_document(doc: dict) -> str:
    """A TOML document of top-level keys with inline values."""
    return "".join(f"{toml_key(k)} = {toml_value(v)}\n" for k, v in doc.items())


def run(argv: list[str]) -> tuple[int, str, str, float]:
    """``tanksynth.cli.main(argv)`` in this process: exit code, stdout, stderr, seconds."""
    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    # A hang (a blocking open, a runaway loop) must fail the run, not stall it: past the
    # watchdog the worker dumps every stack and exits.
    faulthandler.dump_traceback_later(WATCHDOG_SECONDS, exit=True)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main([str(a) for a in argv])
    finally:
        faulthandler.cancel_dump_traceback_later()
    return code, out.getvalue(), err.getvalue(), time.perf_counter() - t0


def assert_contract(code: int, err: str, seconds: float, what: str = "") -> None:
    """The exit-code contract: 0/1/2/3, one stderr line on failure, no traceback, bounded."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code in (0, 1, 2, 3), f"exit {code} ({what}): {err[:500]}"
    assert "Traceback" not in err, err[:2000]
    assert len(lines) <= 1, f"{len(lines)} stderr lines ({what}): {err[:1000]}"
    if code != 0:
        assert len(lines) == 1, f"exit {code} without a message ({what})"
        assert len(lines[0]) < 2000, f"stderr line of {len(lines[0])} characters"
    assert seconds < MAX_SECONDS, f"{seconds:.1f} s ({what})"
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    assert peak < MAX_RSS, f"peak memory {peak / 1e9:.2f} GB ({what})"
