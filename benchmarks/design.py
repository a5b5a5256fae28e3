"""`tanksynth design` on DECENTER's tank network, N = 16 ... 256 (issue 15).

Three designs of one spec, every level measured (``C = I``), pumps at 4 V, the
equilibrium levels of the eight-tank example repeated: ``linearize``,
``ts_observer`` (variant ``qI``, psi = 1e-3 1/s, box [1, 40] cm per tank) and
``decentralized_kalman`` (window 40, own-tank pattern, default route). Each
repetition runs in a fresh interpreter (``python -c``): the time of the three
``design`` calls (after the imports), and the wall time of the whole command
(imports, designs, artefacts written). N values are interleaved, ``--reps``
repetitions (>= 3); min and median printed; the growth exponent of the design
time over N = 16 ... 64 (least squares of log t on log N) is reported.

There is no other tool that designs these three from one spec; the reference
is the same command before issue 15 (26-33 s at N = 64, 24.8 s of it in SVDs).
Floor (median, exit 1 on a miss): the three designs at N = 64 in under 5 s.

Usage: ``python benchmarks/design.py [--sizes 16 32 64 128 256] [--reps 3]``
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import Floors, machine, summary, write_record  # noqa: E402

LOWER = (21.70591608, 22.54471524)   # equilibrium of the 8-tank example at 4 V
UPPER = (9.04293578, 5.08665138)

CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
from pathlib import Path
from tanksynth.cli import _design_all, _load
spec = _load(sys.argv[1])
t1 = time.perf_counter()
from tanksynth.methods import METHODS
times = {}
c1 = time.process_time()
for d in spec.designs:
    s = time.perf_counter()
    METHODS[d.method].design(spec, d)
    times[d.name] = time.perf_counter() - s
t2 = time.perf_counter()
print(json.dumps({"import_and_parse": t1 - t0, "designs": times, "design_total": t2 - t1,
                  "design_cpu": time.process_time() - c1}))
"""


def spec_text(N: int) -> str:
    """The benchmark spec for N tanks (N a multiple of 4)."""
    lower = [LOWER[i % 2] for i in range(N // 2)]
    upper = [UPPER[i % 2] for i in range(N // 2)]
    dom = ", ".join(f"h{i} = [1.0, 40.0]" for i in range(1, N + 1))
    return "\n".join([
        f'title = "design benchmark N = {N}"', "", "[plant]", 'model = "tank_network"', f"N = {N}",
        "", "[operating_point]", "x = [" + ", ".join(f"{v:.8f}" for v in lower + upper) + "]",
        "u = [" + ", ".join("4.0" for _ in range(N // 2)) + "]", "", "[sampling]", "ts = 1.0", "",
        "[[design]]", 'name = "lin"', 'method = "linearize"', "",
        "[[design]]", 'name = "ts"', 'method = "ts_observer"', 'variant = "qI"', "psi = 1e-3",
        "domain = {" + dom + "}", "",
        "[[design]]", 'name = "dk"', 'method = "decentralized_kalman"', "window = 40",
        'E = "own_tank"', "process_noise = 0.01", "process_noise_correlation = 0.5",
        "measurement_noise = 4.0", "initial_covariance = 10.0", ""])


def main() -> int:
    """Run the benchmark; exit 1 when the floor is missed or a design fails."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 32, 64, 128, 256])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=600.0)
    args = ap.parse_args()
    reps = max(args.reps, 3)
    before = machine()
    tmp = Path(tempfile.mkdtemp(prefix="tanksynth-bench-design-"))
    specs = {}
    for N in args.sizes:
        specs[N] = tmp / f"net{N}.toml"
        specs[N].write_text(spec_text(N))
    rows = {N: {"design_total": [], "design_cpu": [], "command_wall": [], "designs": []}
            for N in args.sizes}
    failed = []
    print(f"tank_network, C = I: linearize + ts_observer + decentralized_kalman; {reps} reps; "
          f"load {before['loadavg']}")
    for rep in range(reps):
        order = args.sizes if rep % 2 == 0 else list(reversed(args.sizes))
        for N in order:
            t0 = time.perf_counter()
            try:
                proc = subprocess.run([sys.executable, "-c", CHILD, str(specs[N])],
                                      capture_output=True, text=True, timeout=args.timeout)
            except subprocess.TimeoutExpired:
                failed.append(N)
                print(f"N = {N}: > {args.timeout:g} s (timed out)")
                continue
            wall = time.perf_counter() - t0
            if proc.returncode != 0:
                failed.append(N)
                print(f"N = {N}: FAILED\n{proc.stderr[-2000:]}")
                continue
            out = json.loads(proc.stdout.strip().splitlines()[-1])
            rows[N]["design_total"].append(out["design_total"])
            rows[N]["design_cpu"].append(out["design_cpu"])
            rows[N]["command_wall"].append(wall)
            rows[N]["designs"].append(out["designs"])
    print(f"\n{'N':>5} {'designs min':>12} {'median':>8} {'cpu med':>8} {'command min':>12} {'median':>8}   "
          "per design (median)")
    for N in args.sizes:
        r = rows[N]
        if not r["design_total"]:
            continue
        d, c = summary(r["design_total"]), summary(r["command_wall"])
        per = {k: statistics.median(x[k] for x in r["designs"]) for k in r["designs"][0]}
        cpu = statistics.median(r["design_cpu"])
        print(f"{N:5d} {d['min']:11.2f}s {d['median']:7.2f}s {cpu:7.2f}s {c['min']:11.2f}s {c['median']:7.2f}s   "
              + "  ".join(f"{k} {v:.2f}s" for k, v in per.items()))
    fit = [N for N in args.sizes if 16 <= N <= 64 and rows[N]["design_total"]]
    exponent = None
    if len(fit) >= 2:
        xs = [math.log(N) for N in fit]
        ys = [math.log(statistics.median(rows[N]["design_total"])) for N in fit]
        mx, my = statistics.mean(xs), statistics.mean(ys)
        exponent = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
        print(f"\ngrowth exponent of the design time over N = {fit[0]}..{fit[-1]}: {exponent:.2f}")
    floors = Floors()
    if 64 in args.sizes and rows[64]["design_total"]:
        # a ratio >= 1 means under the 5 s budget
        floors.check("N=64 three designs under 5 s (5 s / median)", 5.0 / statistics.median(rows[64]["design_total"]), 1.0)
    name = "design" if args.sizes == [16, 32, 64, 128, 256] else \
        "design_N" + "-".join(map(str, args.sizes))
    path = write_record(name, {"reps": reps, "rows": {str(k): v for k, v in rows.items()},
                                   "growth_exponent_16_64": exponent, "failed": failed,
                                   "floors": floors.rows}, before)
    print(f"record: {path}")
    return 1 if failed or floors.failed else 0


if __name__ == "__main__":
    sys.exit(main())
