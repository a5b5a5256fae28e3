"""Monte-Carlo campaign: ``tanksynth verify --runs R`` on the demo vs a numba loop with the same metrics.

Issue 29. The demo's two controller artefacts (``integral_pole_placement``,
``integral_lmi_disk``: `tanksynth design` of the built-in demo, copied without the
estimator artefacts into a verification directory), the ``servo`` scenario, R runs each
(default 1,000):

* ``tanksynth``: the command ``tanksynth verify DIR --runs R --scenario servo`` in a fresh
  process (default Dask workers), CPU seconds of the process and its children
  (``getrusage``), wall seconds. Also ``--runs 0`` (the verdicts without a campaign) so that
  the campaign's own cost is known: runs per CPU-second are given for the whole command and
  for the campaign alone (CPU of ``--runs R`` minus CPU of ``--runs 0``).
* ``numba``: what a capable user writes: the noise drawn as tanksynth draws it (one numpy
  generator per run, the campaign's seeds), the closed loop of `closed_loop.build_numba`
  (``prange`` over the runs) and the campaign's metrics (``ise_h1``, ``ise_h2``,
  ``offset_h1``, ``offset_h2``, ``tracking_time``: `tanksynth.sim.metrics`' definitions)
  in one ``@njit`` function, all inside the timing (CPU: ``time.process_time``, every thread).

Agreement: every metric of every run equal to the one ``verify`` wrote in
``campaign.csv`` (relative 1e-9; tracking times exactly), else exit 1.
Floor (issue 29): tanksynth's runs per CPU-second (whole command) at least half the numba
loop's; reported, exit 1 on a miss only with ``--strict``.

Usage: ``python benchmarks/campaign.py [--runs 1000] [--reps 3] [--quick] [--strict]``
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from closed_loop import DEMO, Problem, build_numba  # noqa: E402
from harness import Floors, machine, summary, write_record  # noqa: E402

from tanksynth.sim.scenarios import SCENARIOS  # noqa: E402
from tanksynth.sim.simulate import run_seeds  # noqa: E402
from tanksynth.spec import load_spec  # noqa: E402
from tanksynth.verify.common import sampling_period  # noqa: E402
from tanksynth.verify.laws.campaign import state_feedback_loop  # noqa: E402

CONTROLLERS = ("integral_pole_placement", "integral_lmi_disk")
SCENARIO = "servo"
RTOL = 1e-9


def prepare(tmp: Path) -> tuple[Path, dict[str, Problem]]:
    """Design the demo; a verification directory with the controller artefacts only."""
    out = tmp / "demo"
    subprocess.run([sys.executable, "-m", "tanksynth", "design", str(DEMO), "-o", str(out)],
                   check=True, capture_output=True)
    spec = load_spec(out / "spec.toml")
    ts = sampling_period(spec)
    problems = {}
    for name in CONTROLLERS:
        doc = json.loads((out / f"{name}.json").read_text())
        loop = state_feedback_loop(doc, spec)
        setup = SCENARIOS[SCENARIO].setup(spec.plant, loop.x_op, loop.u_op, loop.tracked, ts=ts)
        problems[name] = Problem("three_tank", spec.plant, loop.controller, setup, ts, 1.0)
    return out, problems


def verify_dir(src: Path, tmp: Path, tag: str) -> Path:
    """A fresh copy of the controller artefacts (verify writes into its directory)."""
    dst = tmp / f"verify-{tag}"
    if dst.exists():
        shutil.rmtree(dst)
    dst.mkdir()
    for f in ("spec.toml", "plant.json"):
        shutil.copy(src / f, dst / f)
    for name in CONTROLLERS:
        for ext in (".json", ".npz"):
            if (src / f"{name}{ext}").exists():
                shutil.copy(src / f"{name}{ext}", dst / f"{name}{ext}")
    return dst


def run_verify(directory: Path, runs: int) -> tuple[float, float]:
    """Wall and CPU seconds (the process and its children) of ``tanksynth verify``."""
    cmd = [sys.executable, "-m", "tanksynth", "verify", str(directory), "--json"]
    if runs:
        cmd += ["--runs", str(runs), "--scenario", SCENARIO]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 1):          # 1: a verdict failed (still a full campaign)
        raise RuntimeError(f"verify exited {proc.returncode}: {proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def build_user_loop(problems: dict[str, Problem]):
    """The numba contender: noise, closed loop (prange) and metrics, per controller."""
    import numba as nb

    def make(pb: Problem):
        _, parallel = build_numba(pb)
        ref = pb.ref
        tracked = np.array(pb.setup.tracked, dtype=np.int64)
        ts = pb.ts
        band = 0.05 * max(abs(s) for _, s in pb.setup.scenario.setpoint_steps)
        start = int(pb.setup.setpoint_samples[0])

        @nb.njit(parallel=True)
        def metrics(X):
            M, count = X.shape[0], X.shape[1]
            p = tracked.size
            w = max(1, count // 10)
            ise = np.zeros((M, p))
            off = np.zeros((M, p))
            ttime = np.zeros(M)
            for r in nb.prange(M):
                last = -1
                for k in range(count):
                    outside = False
                    for j in range(p):
                        e = ref[k, j] - X[r, k, tracked[j]]
                        ise[r, j] += e * e
                        if k >= count - w:
                            off[r, j] -= e
                        if k >= start and abs(e) > band:
                            outside = True
                    if outside:
                        last = k
                for j in range(p):
                    ise[r, j] *= ts
                    off[r, j] /= w
                if last >= 0:
                    ttime[r] = math.inf if last == count - 1 else (last - start + 1) * ts
            return ise, off, ttime

        def run(seeds):
            M = len(seeds)
            W = pb.noise(seeds)
            X0 = np.tile(np.asarray(pb.setup.x0, float), (M, 1))
            return metrics(parallel(X0, W))
        return run

    return {name: make(pb) for name, pb in problems.items()}


def check_metrics(csv_path: Path, results: dict, seeds: np.ndarray) -> float:
    """Largest relative difference between the numba metrics and verify's campaign.csv."""
    want: dict[tuple[str, int, str], float] = {}
    seed_of = {}
    with open(csv_path, newline="") as fh:
        for row in csv.DictReader(fh):
            if row["scenario"] == SCENARIO and row["artefact"] in results:
                want[(row["artefact"], int(row["run"]), row["metric"])] = float(row["value"])
                seed_of[int(row["run"])] = int(row["seed"])
    if any(seed_of[r] != int(seeds[r]) for r in seed_of):
        raise RuntimeError("campaign seeds differ from run_seeds(0, R)")
    worst = 0.0
    for name, (ise, off, ttime) in results.items():
        for r in range(len(seeds)):
            got = {"ise_h1": ise[r, 0], "ise_h2": ise[r, 1], "offset_h1": off[r, 0],
                   "offset_h2": off[r, 1], "tracking_time": ttime[r]}
            for metric, value in got.items():
                ref = want[(name, r, metric)]
                if metric == "tracking_time":
                    d = 0.0 if ref == value else math.inf
                else:
                    d = abs(value - ref) / max(abs(ref), 1e-300)
                worst = max(worst, d)
    return worst


def main() -> int:
    """Run the benchmark; exit 1 on a disagreement (and on a floor miss with --strict)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--record", default="campaign",
                    help="name of the JSON record in benchmarks/results (default %(default)s)")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="200 runs, 3 reps")
    ap.add_argument("--strict", action="store_true", help="exit 1 on a floor miss")
    args = ap.parse_args()
    R = 200 if args.quick else args.runs
    reps = max(3, args.reps)
    before = machine()
    floors = Floors()
    print(f"verify --runs {R} --scenario {SCENARIO} on the demo's {len(CONTROLLERS)} controllers "
          f"({len(CONTROLLERS) * R} runs); {reps} reps; load {before['loadavg']}")
    with tempfile.TemporaryDirectory(prefix="tanksynth-bench-") as tmpname:
        tmp = Path(tmpname)
        demo, problems = prepare(tmp)
        seeds = run_seeds(0, R)
        try:
            kernels = build_user_loop(problems)
        except ImportError:
            print("numba not installed (pip install -e '.[bench]')", file=sys.stderr)
            return 1
        t0 = time.perf_counter()
        results = {name: k(seeds) for name, k in kernels.items()}     # compiles
        compile_s = time.perf_counter() - t0
        first = verify_dir(demo, tmp, "check")
        run_verify(first, R)
        worst = check_metrics(first / "campaign.csv", results, seeds)
        print(f"numba loop first call (compile) {compile_s:.1f} s; metrics vs verify's campaign.csv: "
              f"largest relative difference {worst:.1e}")
        agree = worst <= RTOL
        times: dict[str, list[float]] = {"tanksynth": [], "tanksynth_runs0": [], "numba": []}
        cpu: dict[str, list[float]] = {k: [] for k in times}
        for i in range(reps):                                   # interleaved
            wall, c = run_verify(verify_dir(demo, tmp, f"r{i}"), R)
            times["tanksynth"].append(wall)
            cpu["tanksynth"].append(c)
            wall, c = run_verify(verify_dir(demo, tmp, f"z{i}"), 0)
            times["tanksynth_runs0"].append(wall)
            cpu["tanksynth_runs0"].append(c)
            c0, t0 = time.process_time(), time.perf_counter()
            for k in kernels.values():
                k(seeds)
            times["numba"].append(time.perf_counter() - t0)
            cpu["numba"].append(time.process_time() - c0)
    total = len(CONTROLLERS) * R
    throughput = {
        "tanksynth": [total / c for c in cpu["tanksynth"]],
        "tanksynth_campaign_only": [total / max(a - b, 1e-9) for a, b in
                                    zip(cpu["tanksynth"], cpu["tanksynth_runs0"])],
        "numba": [total / c for c in cpu["numba"]],
    }
    for name in times:
        sw, sc = summary(times[name]), summary(cpu[name])
        print(f"  {name:16s} wall min {sw['min']:8.3f} s median {sw['median']:8.3f} s; "
              f"CPU min {sc['min']:8.3f} s median {sc['median']:8.3f} s")
    for name, t in throughput.items():
        print(f"  {name:24s} runs per CPU-second per rep: " + " ".join(f"{v:.0f}" for v in t)
              + f"   median {statistics.median(t):.0f}")
    share = [a / b for a, b in zip(throughput["tanksynth"], throughput["numba"])]
    print("  tanksynth / numba throughput per rep: " + " ".join(f"{v:.4f}" for v in share))
    floors.check("verify --runs: tanksynth runs per CPU-second / numba loop's", statistics.median(share),
                 0.5, strict_only=True)
    if not agree:
        floors.rows.append({"what": "metrics equal to verify's campaign.csv", "ok": False})
    path = write_record(args.record, {"runs": R, "reps": reps, "scenario": SCENARIO,
                                     "controllers": list(CONTROLLERS), "total_runs": total,
                                     "numba_compile_s": compile_s, "metrics_rel_diff": worst,
                                     "times": times, "cpu_times": cpu, "throughput": throughput,
                                     "throughput_ratio": share, "floors": floors.rows,
                                     "workers": "default"}, before)
    print(f"\nrecord: {path}")
    return floors.exit_status(args.strict)


if __name__ == "__main__":
    sys.exit(main())
