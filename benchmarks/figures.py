"""CPU and wall time of the report's figures alone (issue 15, item 7), old tree against new.

For every example the script needs a result directory made by ``tanksynth run`` (designed,
verified, traces written; made once into ``--runs`` when missing, with this tree). Each
measurement then runs in a FRESH process (``subprocess``, the tree under test first on
``PYTHONPATH``) on a private copy of that directory and times, as `tanksynth.reports.writer`
calls them:

import
    ``matplotlib.figure`` + ``matplotlib.backends.backend_pdf`` (+ what the figure modules import
    on first use): every ``tanksynth run`` that draws pays it once;
poles
    `pole_map` of every artefact;
traces
    `tanksynth.reports.context.trace_figures` (time-domain figures of the verdict traces);
regions
    `tanksynth.reports.ts_figures.region_figures` (certified regions of the TS PDC designs).

Times are ``time.process_time()`` (CPU of the process: the machine is a shared 2-core box, wall
time mostly measures the neighbours) and wall time; ``figures`` is the total of the three
drawing stages, ``total`` adds the import. With ``--baseline DIR`` (another source tree, e.g.
``git archive <commit> | tar -x -C DIR``) both trees run interleaved (this tree, baseline,
next example, ...) ``--reps`` times; min and median are printed with the median ratio
baseline / current. The number of figure files, their pages and the text each figure carries
(``pdftotext``, when installed) are printed for both trees, as a check that the same figures
were drawn. Record: ``benchmarks/results/figures.json``.

``--profile NAME`` prints the top cumulative costs (cProfile) of the figure stage of one
example with the current tree.

Usage::

    .venv/bin/python benchmarks/figures.py --baseline /tmp/figs-base          # every example, 3 reps
    .venv/bin/python benchmarks/figures.py --only three_tank_hinf --reps 5
    .venv/bin/python benchmarks/figures.py --profile seed003_tank_network --reps 0
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import machine, write_record  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable
#: The examples of issue 15's "< 3 s" target plus the two search-heavy ones (they draw figures too).
EXAMPLES = ("seed000_akf", "seed000_feedback_linearization", "seed000_pole_placement",
            "seed002_estimators", "seed002_inverse_dynamics", "seed003_tank_network",
            "seed004_fault_detection", "three_tank_hinf", "three_tank_robust", "tank_network_n8",
            "seed001_ts_observer", "three_tank_ts_control")
STAGES = ("import", "poles", "traces", "regions")

CHILD = r"""
import json, sys, time, cProfile, pstats, io
from pathlib import Path
directory, profile = Path(sys.argv[1]), sys.argv[2] == "1"
from tanksynth.reports import read_report_inputs
from tanksynth.reports import writer
from tanksynth.reports.context import trace_figures
from tanksynth.reports.ts_figures import region_figures
import tanksynth
out_tree = str(Path(tanksynth.__file__).resolve().parents[1])
inputs = read_report_inputs(directory)
out = {}
def timed(key, fn):
    c0, w0 = time.process_time(), time.perf_counter()
    res = fn()
    out[key] = {"cpu": time.process_time() - c0, "wall": time.perf_counter() - w0}
    return res
def imports():
    import matplotlib.figure, matplotlib.backends.backend_pdf, matplotlib.collections  # noqa
    import matplotlib.patches, matplotlib.ticker, matplotlib.colors  # noqa
def poles():
    figdir = directory / writer.FIGURE_DIR
    got = {}
    for i, art in enumerate(inputs.artefacts):
        f = writer.pole_map(art, figdir, writer._figure_stem(i, str(art.get("name", ""))))
        if f is not None:
            got[str(art["name"])] = f
    return got
prof = cProfile.Profile() if profile else None
timed("import", imports)
if prof:
    prof.enable()
p = timed("poles", poles)
t = timed("traces", lambda: trace_figures(inputs))
r = timed("regions", lambda: region_figures(inputs))
if prof:
    prof.disable()
    s = io.StringIO()
    pstats.Stats(prof, stream=s).sort_stats("cumulative").print_stats(45)
    out["profile"] = s.getvalue()
out["tree"] = out_tree
# trace_figures gives one figure per artefact in older trees, a tuple (main + extras) now
out["files"] = sorted(str(f.path.name) for d in (p, t, r) for v in d.values()
                      for f in (v if isinstance(v, tuple) else (v,)))
print("@@" + json.dumps(out))
"""


def _ensure_run(name: str, runs: Path) -> Path:
    d = runs / name
    if (d / "report.tex").is_file():
        return d
    print(f"  tanksynth run examples/{name}.toml -o {d}", flush=True)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    subprocess.run([PY, "-m", "tanksynth", "run", str(ROOT / "examples" / f"{name}.toml"), "-o", str(d)],
                   env=env, capture_output=True, check=False)
    if not (d / "report.tex").is_file():
        raise SystemExit(f"tanksynth run examples/{name}.toml made no report in {d}")
    return d


def _measure(tree: Path, run_dir: Path, profile: bool = False) -> dict:
    with tempfile.TemporaryDirectory(prefix="figs-") as tmp:
        d = Path(tmp) / run_dir.name
        shutil.copytree(run_dir, d, ignore=shutil.ignore_patterns("report-figures", "report*.pdf"))
        env = dict(os.environ, PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS="1")
        # cwd outside every tree: ``python -c`` puts the working directory first on sys.path
        res = subprocess.run([PY, "-c", CHILD, str(d), "1" if profile else "0"], env=env, cwd=tmp,
                             capture_output=True, text=True, check=False)
        line = [ln for ln in res.stdout.splitlines() if ln.startswith("@@")]
        if res.returncode != 0 or not line:
            raise SystemExit(f"figure stage failed with {tree} on {run_dir}:\n{res.stderr[-3000:]}")
        out = json.loads(line[0][2:])
        if Path(out["tree"]) != tree.resolve():
            raise SystemExit(f"measured {out['tree']}, expected {tree}")
        out["content"] = _content(d / "report-figures", out["files"])
    for key in ("cpu", "wall"):
        out.setdefault("figures", {})[key] = sum(out[s][key] for s in ("poles", "traces", "regions"))
        out.setdefault("total", {})[key] = out["figures"][key] + out["import"][key]
    return out


def _content(figdir: Path, files: list[str]) -> dict:
    """Pages, bytes and the words each figure shows (pdftotext), to compare the two trees."""
    out = {}
    have = shutil.which("pdftotext") is not None
    for f in files:
        p = figdir / f
        words = None
        if have:
            txt = subprocess.run(["pdftotext", "-raw", str(p), "-"], capture_output=True, text=True).stdout
            words = sorted(set(txt.split()))
        out[f] = {"bytes": p.stat().st_size, "words": words}
    return out


def _row(times: list[dict], stage: str, key: str = "cpu") -> tuple[float, float]:
    v = [t[stage][key] for t in times]
    return min(v), statistics.median(v)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", nargs="+", default=None, help="examples (default: every one in EXAMPLES)")
    ap.add_argument("--reps", type=int, default=3, help="interleaved repetitions (default 3)")
    ap.add_argument("--baseline", type=Path, default=None, help="another source tree to compare with")
    ap.add_argument("--runs", type=Path, default=Path(tempfile.gettempdir()) / "tanksynth-figure-runs",
                    help="where the `tanksynth run` directories are kept (made when missing)")
    ap.add_argument("--profile", nargs="+", default=[], help="cProfile the figure stage of these examples")
    args = ap.parse_args(argv)
    names = args.only or list(EXAMPLES)
    before = machine()
    needed = (set(names) if args.reps else set()) | set(args.profile)
    runs = {n: _ensure_run(n, args.runs) for n in sorted(needed)}
    for n in args.profile:
        print(f"== profile {n}\n" + _measure(ROOT, runs[n], profile=True)["profile"])
    trees = {"current": ROOT} | ({"baseline": args.baseline.resolve()} if args.baseline else {})
    times: dict[str, dict[str, list[dict]]] = {n: {k: [] for k in trees} for n in names}
    for rep in range(args.reps):
        for n in names:
            for k, tree in trees.items():
                times[n][k].append(_measure(tree, runs[n]))
        print(f"  rep {rep + 1}/{args.reps} done", flush=True)
    record = {"examples": {}, "reps": args.reps, "baseline": str(args.baseline) if args.baseline else None}
    if args.reps:
        print(f"\nCPU s per example, min / median over {args.reps} fresh processes "
              "(figures = poles + traces + regions; total adds the matplotlib import)")
        head = f"{'example':32s} {'tree':9s} {'files':>5s} " + " ".join(f"{s:>13s}" for s in
                                                                   ("import", "poles", "traces", "regions",
                                                                    "figures", "total"))
        print(head)
    for n in names:
        rec = {}
        for k in trees:
            ts = times[n][k]
            if not ts:
                continue
            cells = [_row(ts, s) for s in STAGES + ("figures", "total")]
            print(f"{n:32s} {k:9s} {len(ts[0]['files']):5d} "
                  + " ".join(f"{a:6.3f}/{b:6.3f}" for a, b in cells))
            rec[k] = {"cpu": {s: [t[s]["cpu"] for t in ts] for s in STAGES + ("figures", "total")},
                      "wall": {s: [t[s]["wall"] for t in ts] for s in STAGES + ("figures", "total")},
                      "files": ts[0]["files"], "content": ts[0]["content"]}
        if "baseline" in rec and "current" in rec:
            r = [b / c for b, c in zip(rec["baseline"]["cpu"]["figures"], rec["current"]["cpu"]["figures"])]
            rec["ratio_figures_cpu"] = r
            same_files = rec["baseline"]["files"] == rec["current"]["files"]
            same_words = all(rec["baseline"]["content"][f]["words"] == rec["current"]["content"].get(f, {})
                             .get("words") for f in rec["baseline"]["files"]) if same_files else False
            rec["same_files"], rec["same_words"] = same_files, same_words
            print(f"{'':32s} ratio baseline/current (figures CPU): median {statistics.median(r):.2f} "
                  f"(each rep {', '.join(f'{x:.2f}' for x in r)}); same files {same_files}, "
                  f"same words {same_words}")
        record["examples"][n] = rec
    if args.reps:
        path = write_record("figures", record, before)
        print(f"record: {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
