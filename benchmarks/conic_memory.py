"""Calibration of the conic memory estimate against measured peak RSS (issue 31, item 2).

`tanksynth.spec.memory.conic_bytes` refuses an LMI design before it is built when its estimate
exceeds the budget; it must be an upper bound of what a real solve takes, and not a wild one.
For each size, a fresh interpreter parses a ``tank_network`` spec with one ``multiobjective``
design (H-infinity + disk, discrete), takes VmRSS after the imports, runs the design (both
solver phases) and reports VmHWM - VmRSS: the peak the design added. Floor (exit 1 on a miss):
``measured <= estimate <= 2.5 x measured`` at every size.

Measured on the development machine (MiB, measured / estimated): N = 8: 13 / 24; 12: 32 / 53;
16: 86 / 132; 20: 231 / 297; 24: 412 / 596 (N = 24 takes about 75 s).
Record: ``results/conic_memory.json``.

Usage::

    .venv/bin/python benchmarks/conic_memory.py                 # N = 8, 12, 16 (about 20 s)
    .venv/bin/python benchmarks/conic_memory.py --sizes 8 16 24
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import machine, write_record  # noqa: E402

from tanksynth.methods import parse_spec_text  # noqa: E402
from tanksynth.spec.memory import conic_bytes  # noqa: E402

#: Peak added by the design, measured in a fresh interpreter (bytes on stdout).
_PEAK = """
import sys, warnings
warnings.simplefilter("ignore")
from tanksynth.methods import METHODS, parse_spec_text
import tanksynth.design.synthesis.synthesize, clarabel, scipy.sparse
def kib(field):
    with open("/proc/self/status") as status:
        return next(int(l.split()[1]) for l in status if l.startswith(field + ":"))
spec = parse_spec_text(sys.stdin.read())
rss = kib("VmRSS")
METHODS[spec.designs[0].method].design(spec, spec.designs[0])
print(1024 * (kib("VmHWM") - rss))
"""

#: How far above the measured peak the estimate may be.
CEILING = 2.5


def spec_text(N: int) -> str:
    """``tank_network`` with N (a multiple of 4) tanks at 4 V, one multiobjective design."""
    x = [21.70591608, 22.54471524] * (N // 4) + [9.04293578, 5.08665138] * (N // 4)
    return (f'[plant]\nmodel = "tank_network"\nN = {N}\n[operating_point]\nx = {x}\n'
            f'u = {[4.0] * (N // 2)}\n[sampling]\nts = 1.0\n[[design]]\nname = "mo"\n'
            'method = "multiobjective"\ntarget = "state_feedback"\nregion = [{type = "disk", center = 0.9, radius = 0.08}]\n')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[8, 12, 16])
    args = parser.parse_args()
    before = machine()
    rows, failed = [], []
    print(f"{'N':>4s} {'measured MiB':>13s} {'estimate MiB':>13s} {'ratio':>6s}")
    for N in args.sizes:
        text = spec_text(N)
        spec = parse_spec_text(text)
        estimate = conic_bytes(spec.designs[0].config.conic_size(spec.plant, spec.ts))
        done = subprocess.run([sys.executable, "-c", _PEAK], input=text, capture_output=True,
                              text=True, timeout=3600, check=True)
        measured = int(done.stdout.split()[-1])
        ok = measured <= estimate <= CEILING * measured
        print(f"{N:4d} {measured / 2 ** 20:13.0f} {estimate / 2 ** 20:13.0f} "
              f"{estimate / measured:6.2f}  {'ok' if ok else 'MISS'}")
        rows.append({"N": N, "measured_bytes": measured, "estimate_bytes": estimate, "ok": ok})
        if not ok:
            failed.append(N)
    path = write_record("conic_memory", {"ceiling": CEILING, "rows": rows}, before)
    print(f"record: {path.name}" + (f"; missed at N = {failed}" if failed else ""))
    print(json.dumps({"failed": failed}))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
