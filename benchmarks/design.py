"""`tanksynth design` on DECENTER's tank network, N = 16 ... 256 (issue 15).

Three designs of one spec, every level measured (``C = I``), pumps at 4 V, the
equilibrium levels of the eight-tank example repeated: ``linearize``,
``ts_observer`` (variant ``qI``, psi = 1e-3 1/s, box [1, 40] cm per tank) and
``decentralized_kalman`` (window 40, own-tank pattern, default route). Each
repetition runs the whole ``tanksynth design SPEC -o DIR`` command
(``tanksynth.cli.main``) in a fresh interpreter: its wall time (interpreter
start, imports, parse, designs, artefacts written), and inside it the time of
the imports and parse, of each ``design`` call (wall and CPU) and of the
artefact writing, the peak memory (max RSS) and each design's CPU time (wall time
on the shared 2-core machine is noisy). N values are interleaved,
``--reps`` repetitions (>= 3); min and median printed; the growth exponent of
the design time and of the command time over N = 16 ... 64 (least squares of
log t on log N) is reported.

There is no other tool that designs these three from one spec; the reference
is the same command before issue 15 (26-33 s at N = 64, 24.8 s of it in SVDs).
Floors (median, exit 1 on a miss): the three designs at N = 64 in under 5 s, and
the whole command at N = 64 in under 5 s wall.

Usage: ``python benchmarks/design.py [--sizes 16 32 64 128 256] [--reps 3] [--name NAME]``
(``--tree DIR`` measures the tanksynth of another source tree, e.g. the code
before a change, and ``--name`` keeps its record beside this one's).
"""

from __future__ import annotations

import argparse
import json
import math
import os
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
import json, resource, sys, time
t0 = time.perf_counter()
import tanksynth.artefacts.io as aio
import tanksynth.cli as cli
import tanksynth.methods as methods
tanksynth_path = methods.__file__
times, cpu, writes, first = {}, {}, [], []
design, write = methods.Method.design, aio.write_artefact

def timed_design(self, spec, d):
    if not first:
        first.append(time.perf_counter())
    s, c = time.perf_counter(), time.process_time()
    try:
        return design(self, spec, d)
    finally:
        times[d.name], cpu[d.name] = time.perf_counter() - s, time.process_time() - c

def timed_write(*args, **kwargs):
    s = time.perf_counter()
    try:
        return write(*args, **kwargs)
    finally:
        writes.append(time.perf_counter() - s)

methods.Method.design, aio.write_artefact = timed_design, timed_write
code = cli.main(["design", sys.argv[1], "-o", sys.argv[2], "--force"])
t1 = time.perf_counter()
print(json.dumps({"code": code, "package": tanksynth_path, "import_and_parse": first[0] - t0 if first else None,
                  "designs": times, "designs_cpu": cpu, "design_total": sum(times.values()),
                  "design_cpu": sum(cpu.values()), "write": sum(writes), "in_process": t1 - t0,
                  "command_cpu": time.process_time(),
                  "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
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


def _exponent(sizes: list[int], values: dict[int, list[float]]) -> float | None:
    """Least-squares slope of log(median t) on log N over the sizes 16 ... 64 measured."""
    fit = [N for N in sizes if 16 <= N <= 64 and values[N]]
    if len(fit) < 2:
        return None
    xs = [math.log(N) for N in fit]
    ys = [math.log(statistics.median(values[N])) for N in fit]
    mx, my = statistics.mean(xs), statistics.mean(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def main() -> int:
    """Run the benchmark; exit 1 when a floor is missed or a design fails."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 32, 64, 128, 256])
    ap.add_argument("--reps", type=int, default=3,
                    help="repetitions (floors are checked only with >= 3)")
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--name", help="record name (default design or design_N<sizes>)")
    ap.add_argument("--tree", default=str(Path(__file__).resolve().parent.parent),
                    help="source tree whose tanksynth is measured (default this repository)")
    args = ap.parse_args()
    reps = max(args.reps, 1)
    before = machine()
    tmp = Path(tempfile.mkdtemp(prefix="tanksynth-bench-design-"))
    specs = {}
    for N in args.sizes:
        specs[N] = tmp / f"net{N}.toml"
        specs[N].write_text(spec_text(N))
    keys = ("design_total", "design_cpu", "command_wall", "command_cpu", "import_and_parse", "write",
            "maxrss_mb")
    rows = {N: {**{k: [] for k in keys}, "designs": [], "designs_cpu": []} for N in args.sizes}
    failed, package = [], None
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(args.tree).resolve())] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])}
    print(f"tree {Path(args.tree).resolve()}")
    print(f"tank_network, C = I: tanksynth design (linearize + ts_observer + decentralized_kalman); "
          f"{reps} reps; load {before['loadavg']}")
    for rep in range(reps):
        order = args.sizes if rep % 2 == 0 else list(reversed(args.sizes))
        for N in order:
            out_dir = tmp / f"out{N}_{rep}"
            t0 = time.perf_counter()
            try:
                proc = subprocess.run([sys.executable, "-c", CHILD, str(specs[N]), str(out_dir)],
                                      capture_output=True, text=True, timeout=args.timeout,
                                      cwd=tmp, env=env)
            except subprocess.TimeoutExpired:
                failed.append(N)
                print(f"N = {N}: > {args.timeout:g} s (timed out)")
                continue
            wall = time.perf_counter() - t0
            try:
                out = json.loads(proc.stdout.strip().splitlines()[-1])
            except (ValueError, IndexError):
                out = None
            if proc.returncode != 0 or out is None or out["code"] != 0:
                failed.append(N)
                print(f"N = {N}: FAILED\n{proc.stdout[-1000:]}\n{proc.stderr[-2000:]}")
                continue
            out["command_wall"] = wall
            if package is None:
                package = out["package"]
                print(f"  measuring {package}")
            for k in keys:
                rows[N][k].append(out[k])
            rows[N]["designs"].append(out["designs"])
            rows[N]["designs_cpu"].append(out["designs_cpu"])
            print(f"  rep {rep + 1} N = {N}: command {wall:.2f} s (cpu {out['command_cpu']:.2f} s), designs {out['design_total']:.2f} s "
                  f"(cpu {out['design_cpu']:.2f} s), imports+parse {out['import_and_parse']:.2f} s, "
                  f"write {out['write']:.2f} s", flush=True)
    print(f"\n{'N':>5} {'command min':>12} {'median':>8} {'designs min':>12} {'median':>8} {'cpu med':>8} "
          f"{'import+parse':>12} {'write':>6} {'RSS MB':>7}   per design (median)")
    for N in args.sizes:
        r = rows[N]
        if not r["design_total"]:
            continue
        d, c = summary(r["design_total"]), summary(r["command_wall"])
        med = {k: statistics.median(r[k]) for k in ("design_cpu", "import_and_parse", "write", "maxrss_mb")}
        per = {k: statistics.median(x[k] for x in r["designs"]) for k in r["designs"][0]}
        per_cpu = {k: statistics.median(x[k] for x in r["designs_cpu"]) for k in r["designs_cpu"][0]}
        print(f"{N:5d} {c['min']:11.2f}s {c['median']:7.2f}s {d['min']:11.2f}s {d['median']:7.2f}s "
              f"{med['design_cpu']:7.2f}s {med['import_and_parse']:11.2f}s {med['write']:5.2f}s "
              f"{med['maxrss_mb']:7.0f}   " + "  ".join(f"{k} {v:.2f}s (cpu {per_cpu[k]:.2f})"
                                                     for k, v in per.items()))
    exponent = _exponent(args.sizes, {N: rows[N]["design_total"] for N in args.sizes})
    exponent_cmd = _exponent(args.sizes, {N: rows[N]["command_wall"] for N in args.sizes})
    if exponent is not None:
        print(f"\ngrowth exponent over N = 16..64 (median times): designs {exponent:.2f}, "
              f"whole command {exponent_cmd:.2f}")
    floors = Floors()
    if 64 in args.sizes and len(rows[64]["design_total"]) >= 3:
        # a ratio >= 1 means under the 5 s budget
        floors.check("N=64 three designs under 5 s (5 s / median)",
                     5.0 / statistics.median(rows[64]["design_total"]), 1.0)
        floors.check("N=64 whole command under 5 s wall (5 s / median)",
                     5.0 / statistics.median(rows[64]["command_wall"]), 1.0)
    name = args.name or ("design" if args.sizes == [16, 32, 64, 128, 256] else
                         "design_N" + "-".join(map(str, args.sizes)))
    path = write_record(name, {"reps": reps, "package": package, "rows": {str(k): v for k, v in rows.items()},
                               "growth_exponent_16_64": exponent,
                               "growth_exponent_16_64_command": exponent_cmd, "failed": failed,
                               "floors": floors.rows}, before)
    print(f"record: {path}")
    return 1 if failed or floors.failed else 0


if __name__ == "__main__":
    sys.exit(main())
