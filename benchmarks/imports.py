"""Import and start-up times of tanksynth (issue 11: heavy libraries load where used).

Each command runs in a fresh interpreter, interleaved, ``--repeat`` times; the
script prints min and median wall time, and the ``python -X importtime``
cumulative total of the slowest-to-import top-level packages for one run.

* ``import tanksynth``: must stay under 1 s (floor of the issue);
* ``tanksynth --help``: must stay under 0.5 s;
* ``import tanksynth.methods``: the full method table (every numerical library)
  for reference: what any design/verify command pays once.

Usage: ``python benchmarks/imports.py [--repeat N]``; exits 1 when a floor fails.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

PY = sys.executable
CLI = str(Path(PY).with_name("tanksynth"))
COMMANDS = {
    "import tanksynth": [PY, "-c", "import tanksynth"],
    "tanksynth --help": [CLI, "--help"],
    "import tanksynth.methods": [PY, "-c", "import tanksynth.methods"],
}
FLOORS = {"import tanksynth": 1.0, "tanksynth --help": 0.5}


def _importtime(code: str, top: int = 8) -> list[tuple[str, float]]:
    """Cumulative import time (s) of each top-level package imported by ``code`` (largest first)."""
    err = subprocess.run([PY, "-X", "importtime", "-c", code], capture_output=True, text=True,
                         check=True).stderr
    totals: dict[str, float] = {}
    for line in err.splitlines():
        parts = line.split("|")
        if not line.startswith("import time:") or len(parts) != 3 or not parts[1].strip().isdigit():
            continue
        root = parts[2].strip().split(".")[0]
        # the outermost import of a package carries the largest cumulative time of its tree
        totals[root] = max(totals.get(root, 0.0), int(parts[1]) / 1e6)
    return sorted(totals.items(), key=lambda kv: -kv[1])[:top]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    times: dict[str, list[float]] = {name: [] for name in COMMANDS}
    for _ in range(args.repeat):  # interleaved: a busy moment hits every command alike
        for name, cmd in COMMANDS.items():
            start = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True)
            times[name].append(time.perf_counter() - start)
    failed = []
    print(f"{'command':28s} {'min (s)':>9s} {'median (s)':>11s} {'floor (s)':>10s}")
    for name, values in times.items():
        floor = FLOORS.get(name)
        ok = floor is None or min(values) < floor
        failed += [] if ok else [name]
        print(f"{name:28s} {min(values):9.3f} {statistics.median(values):11.3f} "
              f"{'' if floor is None else f'{floor:.1f}':>10s} {'' if ok else 'FAIL'}")
    for code in ("import tanksynth", "import tanksynth.methods"):
        print(f"\npython -X importtime -c '{code}': slowest top-level imports (cumulative s)")
        for name, total in _importtime(code):
            print(f"  {name:24s} {total:7.3f}")
    if failed:
        print("floors missed: " + ", ".join(failed))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
