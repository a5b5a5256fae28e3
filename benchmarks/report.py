"""The README's figures, rendered from ``benchmarks/results/*.json`` (never typed by hand).

``benchmarks/README.md`` holds generated blocks::

    <!-- report:closed_loop -->
    ... (rendered from results/closed_loop.json) ...
    <!-- /report:closed_loop -->

`update` replaces the inside of every block by `render` of the record it names; the text
around the blocks (what is measured, how to run it) is written by hand and carries no
figure. ``python benchmarks/report.py --write`` rewrites the README (``make bench`` does,
after the benchmarks); ``--check`` exits 1 when the README differs from what the committed
results render (``tests/test_benchmark_readme.py`` checks the same). Not a benchmark
(``make bench`` skips it).

Usage: ``python benchmarks/report.py [--write | --check]``
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
import sys
from pathlib import Path
from typing import Any, Callable

__all__ = ["README", "RESULTS", "RENDERERS", "render", "update", "blocks", "main"]

HERE = Path(__file__).resolve().parent
README = HERE / "README.md"
RESULTS = HERE / "results"
BLOCK = re.compile(r"(<!-- report:([A-Za-z0-9_\-]+) -->\n)(.*?)(<!-- /report:\2 -->)", re.S)


# ------------------------------------------------------------------ formatting
def num(v: Any, digits: int = 3) -> str:
    """A figure with ``digits`` significant digits, thousands separated, inf/None spelt out."""
    if v is None:
        return "-"
    v = float(v)
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if v == 0:
        return "0"
    if abs(v) >= 10 ** digits:
        return f"{v:,.0f}"
    mag = int(math.floor(math.log10(abs(v))))
    dec = max(digits - 1 - mag, 0)
    if abs(v) < 1e-3:
        return f"{v:.{digits - 1}e}"
    return f"{v:.{dec}f}"


def ms(v: Any) -> str:
    """Seconds as milliseconds."""
    return num(None if v is None else float(v) * 1e3)


def min_med(values: list[float], scale: float = 1.0) -> str:
    """``min / median`` of a list (times ``scale``)."""
    return f"{num(min(values) * scale)} / {num(statistics.median(values) * scale)}"


def table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A markdown table."""
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out


def provenance(rec: dict, name: str) -> list[str]:
    """Where the figures come from: file, time, commit, load average before and after."""
    m = rec.get("machine") if isinstance(rec.get("machine"), dict) else {"time": rec.get("when")}
    load = m.get("loadavg")
    after = rec.get("loadavg_after")
    commit = m.get("commit")
    edited = " (library edited, uncommitted)" if m.get("library_edited") else ""
    parts = [f"`results/{name}.json`"]
    if m.get("time"):
        parts.append(f"measured {m['time']}")
    parts.append(f"commit {commit}{edited}" if commit else "commit not recorded")
    if load:
        parts.append(f"load average {num(load[0], 2)} before"
                     + (f", {num(after[0], 2)} after" if after else ""))
    if m.get("cpus"):
        parts.append(f"{m['cpus']} CPUs")
    return ["Source: " + "; ".join(parts) + "."]


def floors_table(rec: dict) -> list[str]:
    """Every floor of a record: what, the ratio it was checked on, the floor, pass/miss."""
    rows = []
    for f in rec.get("floors") or []:
        if "floor" not in f:                       # an agreement check
            rows.append([f["what"], "-", "-", "ok" if f.get("ok") else "**DISAGREE**"])
            continue
        stat = f.get("stat", "median")
        verdict = "pass" if f.get("ok") else "**miss**"
        if not f.get("ok") and f.get("strict_only"):
            verdict += " (exit 1 with --strict)"
        rows.append([f["what"], f"{num(f['median_ratio'])} ({stat})", num(f["floor"]), verdict])
    if not rows:
        return []
    return ["", "Floors:", ""] + table(["floor", "ratio", "floor value", "verdict"], rows)


# ------------------------------------------------------------------ renderers
def closed_loop(rec: dict) -> list[str]:
    out = [f"{rec.get('reps')} interleaved reps; `TANKSYNTH_SIM_BACKEND` = "
           f"{rec.get('env_backend') or 'unset'}. Times in ms, min / median; ratio = contender / "
           "tanksynth per rep, min / median (below 1: the contender is faster); largest state "
           "difference to tanksynth in m; first call (compile) in s.", ""]
    rows = []
    for r in rec["rows"]:
        for k in r["times"]:
            ratio = "-" if k == "tanksynth" else min_med(r["ratios"][k])
            err = "-" if k == "tanksynth" else num(r["errors_m"][k], 2)
            first = num(r.get("first_call_s", {}).get(k), 2)
            label = f"{k} ({r['backend']})" if k == "tanksynth" else k
            rows.append([r["plant"], str(r["M"]), label, min_med(r["times"][k], 1e3), ratio, err,
                         first])
    out += table(["plant", "M", "contender", "ms", "ratio", "max dx (m)", "first call (s)"], rows)
    return out + floors_table(rec)


def estimators(rec: dict) -> list[str]:
    agree = rec.get("agreement", {})
    out = [f"{rec.get('reps')} interleaved reps; single run {rec.get('steps')} steps, batch "
           f"{rec.get('batch_steps')} steps; tanksynth back end {rec.get('backend', '-')}. "
           f"Agreement: EKF vs FilterPy {num(agree.get('ekf'), 2)} m, UKF (alpha = 1) "
           f"{num(agree.get('ukf_alpha1'), 2)} m."]
    comp = rec.get("compiled") or {}
    if comp:
        out[0] += " Compiled contenders' first call (s) and single-run difference (m): " + "; ".join(
            f"{k} {num(v['first_call_s'], 2)} s, {num(v['max_abs_diff'], 2)} m" for k, v in comp.items()) + "."
    out += ["", "Times in ms, min / median; ratio = alternative / tanksynth per rep, min / median "
            "(above 1: tanksynth is faster).", ""]
    rows = []
    for r in rec["rows"]:
        rats = r.get("ratios") or {next(k for k in r["times"] if k != "tanksynth"): r.get("ratio")}
        for k, t in r["times"].items():
            ratio = "-" if k == "tanksynth" else min_med(rats[k])
            rows.append([r["name"], k, min_med(t, 1e3), ratio])
    out += table(["work", "contender", "ms", "ratio"], rows)
    return out + floors_table(rec)


def campaign(rec: dict) -> list[str]:
    tp = rec["throughput"]
    out = [f"`verify --runs {rec['runs']} --scenario {rec['scenario']}` on "
           f"{', '.join(rec['controllers'])} ({rec['total_runs']} runs), {rec['reps']} reps; "
           f"numba compile {num(rec['numba_compile_s'], 2)} s (not counted); metrics equal to "
           f"verify's `campaign.csv` to {num(rec['metrics_rel_diff'], 2)} relative.", ""]
    rows = [["tanksynth `verify` (whole command)", min_med(rec["times"]["tanksynth"]),
             min_med(rec["cpu_times"]["tanksynth"]), min_med(tp["tanksynth"])],
            ["tanksynth `verify --runs 0` (verdicts only)", min_med(rec["times"]["tanksynth_runs0"]),
             min_med(rec["cpu_times"]["tanksynth_runs0"]), "-"],
            ["tanksynth campaign alone (difference)", "-", "-",
             min_med(tp["tanksynth_campaign_only"])],
            ["numba loop (noise, prange closed loop, metrics)", min_med(rec["times"]["numba"]),
             min_med(rec["cpu_times"]["numba"]), min_med(tp["numba"])]]
    out += table(["contender", "wall s (min / median)", "CPU s (min / median)",
                  "runs per CPU-second (min / median)"], rows)
    out += ["", "tanksynth / numba runs per CPU-second, per rep: "
            + ", ".join(num(v) for v in rec["throughput_ratio"]) + "."]
    return out + floors_table(rec)


def simulate(rec: dict) -> list[str]:
    b = rec.get("build") or {}
    out = [f"{rec.get('reps')} interleaved reps{' (quick)' if rec.get('quick') else ''}; kernel: "
           f"{b.get('status', '-')}; first call {num(b.get('first_call_s'), 2)} s (compiler "
           f"{num(b.get('compiler_s'), 2)} s), from the disk cache {ms(b.get('cached_call_s'))} ms, "
           f"warm {ms(b.get('warm_call_s'))} ms. Times in ms, min / median; ratio = contender / "
           "tanksynth per rep, min / median; max dx in m (solve_ivp: another scheme).", ""]
    rows = []
    for r in rec["rows"]:
        for k, t in r["times"].items():
            ratio = "-" if k == "tanksynth" else min_med(r["ratios"][k])
            err = num(r["errors_m"].get(k), 2) if k in r["errors_m"] else "-"
            label = f"{k} ({r['backend']})" if k == "tanksynth" else k
            rows.append([str(r["M"]), str(r["N"]), label, min_med(t, 1e3), ratio, err])
    out += table(["M", "N", "contender", "ms", "ratio", "max dx (m)"], rows)
    pw = rec.get("periodwise") or []
    if pw:
        out += ["", "Period by period (measurement noise): the compiled kernel against the fallback "
                "(`TANKSYNTH_SIM_BACKEND=numpy`).", ""]
        out += table(["M", "N", "routes", "tanksynth ms", "fallback ms", "fallback / tanksynth"],
                     [[str(p["M"]), str(p["N"]), " / ".join(p["backends"]),
                       min_med(p["times"]["tanksynth"], 1e3), min_med(p["times"]["fallback"], 1e3),
                       min_med(p["ratios"])] for p in pw])
    return out + floors_table(rec)


def lmi_handwritten(rec: dict) -> list[str]:
    out = [f"{rec.get('reps')} interleaved reps. Times in ms, min / median; ratio = hand-written / "
           "tanksynth per rep, min / median.", ""]
    rows = [[r["structure"], r.get("measured", "all"), str(r["N"]), r.get("form") or "-",
             min_med(r["times"]["tanksynth"], 1e3), min_med(r["times"]["cvxpy"], 1e3),
             min_med(r["ratios"]), "ok" if r["recheck"] else "FAILED"] for r in rec["rows"]]
    out += table(["structure", "measured", "N", "tanksynth form", "tanksynth ms", "hand-written ms",
                  "ratio", "re-check"], rows)
    return out + floors_table(rec)


def decentralized_numpy(rec: dict) -> list[str]:
    out = [f"Alternatives' BLAS threads: {rec.get('alt_blas')}. Wall ms, min / median (CPU median); "
           "ratio = alternative / tanksynth per rep, smallest / median; every rep's wall time "
           "(ms) in the last column.", ""]
    rows = []
    for r in rec["rows"]:
        for k, t in r["times"].items():
            cpu = num(statistics.median(r["cpu_times"][k]) * 1e3)
            ratio = "-" if k == "tanksynth" else min_med(r[f"ratio_{k}_over_tanksynth"])
            rows.append([r["case"], str(r["N"]), k, f"{min_med(t, 1e3)} ({cpu})", ratio,
                         ", ".join(num(v * 1e3) for v in t)])
    out += table(["case", "N", "contender", "wall ms", "ratio", "every rep (ms)"], rows)
    return out + floors_table(rec)


def run_examples(rec: dict) -> list[str]:
    out = [f"{rec.get('reps')} reps, fresh process each. Seconds.", ""]
    rows = [[f"`{r['command']}`", num(r["min"]), num(r["median"]),
             num(statistics.median(r["cpu_times"])) if r.get("cpu_times") else "-",
             num(r.get("floor")) if r.get("floor") else "-",
             "-" if r.get("ok") is None else ("pass" if r["ok"] else "**miss**")]
            for r in rec["rows"]]
    return out + table(["command", "min", "median", "CPU median", "floor", "verdict"], rows)


def limits(rec: dict) -> list[str]:
    rows = [[r["limit"], num(r["floor_s"]), num(r["min"]), num(r["median"]),
             "pass" if r["ok"] else "**miss**"] for r in rec["rows"]]
    return [f"{rec.get('reps')} reps. Seconds.", ""] + table(
        ["limit", "floor", "min", "median", "verdict"], rows)


def symbolic(rec: dict) -> list[str]:
    rows = [[r["case"], str(r["N"]), min_med(r["times"]["tanksynth"], 1e3),
             min_med(r["times"][next(k for k in r["times"] if k != "tanksynth")], 1e3),
             min_med(r["ratio_plain_over_tanksynth"])] for r in rec["rows"]]
    out = [f"{rec.get('reps')} interleaved reps; ms, min / median; ratio = plain sympy / tanksynth "
           "per rep, min / median.", ""]
    return out + table(["case", "N", "tanksynth ms", "plain sympy ms", "ratio"], rows) + floors_table(rec)


def conic_memory(rec: dict) -> list[str]:
    rows = [[str(r["N"]), num(r["measured_bytes"] / 2 ** 20), num(r["estimate_bytes"] / 2 ** 20),
             "ok" if r["ok"] else "**over**"] for r in rec["rows"]]
    return table(["N", "measured MiB", "estimate MiB", "verdict"], rows)


def design(rec: dict) -> list[str]:
    rows = []
    for N, r in rec["rows"].items():
        if not isinstance(r, dict) or "command_wall" not in r:
            continue
        d = ({k: [x[k] for x in r["designs"] if k in x] for k in ("lin", "ts", "dk")}
             if r.get("designs") else {})

        def med(key: str) -> str:
            v = [x for x in r.get(key) or [] if x is not None]
            return num(statistics.median(v)) if v else "-"

        rows.append([N, min_med(r["command_wall"]), med("command_cpu"), med("import_and_parse"),
                     min_med(r["design_total"]) if r.get("design_total") else "-", med("design_cpu"),
                     " / ".join(num(statistics.median(v)) if v else "-" for v in d.values()) if d else "-",
                     med("write"), num(max(r["maxrss_mb"])) if r.get("maxrss_mb") else "-"])
    out = [f"{rec.get('reps')} interleaved reps, fresh interpreter each. Seconds; min / median "
           "where two figures.", ""]
    out += table(["N", "command wall", "command CPU", "imports + parse", "designs wall",
                  "designs CPU", "linearize / ts_observer / decentralized_kalman (median)",
                  "writing", "max RSS MB"], rows)
    return out + floors_table(rec)


def figures(rec: dict) -> list[str]:
    rows = []
    for name, ex in rec["examples"].items():
        cur = ex.get("current", {}).get("cpu", {})
        base = (ex.get("baseline") or {}).get("cpu", {}) if isinstance(ex.get("baseline"), dict) else {}
        if not cur.get("figures"):
            continue
        rows.append([name, min_med(cur["figures"]), min_med(base["figures"]) if base.get("figures") else "-",
                     num(statistics.median(cur["import"])) if cur.get("import") else "-"])
    out = [f"{rec.get('reps')} reps; CPU s, min / median; `figures` = pole maps + traces + regions "
           "(the `matplotlib` import apart).", ""]
    return out + table(["example", "figures (this tree)", "figures (baseline)", "matplotlib import"], rows)


def narx_training(rec: dict) -> list[str]:
    """Seed 002's NARX: structure selection (closed-loop ISE) and the chosen network's training."""
    chosen = rec["chosen"]
    rows = [[str(c["hidden"]), str(c["delays"]), num(c["ise"]), num(c["train_seconds"]), str(c["iterations"])
             + (" (chosen)" if (c["hidden"], c["delays"]) == (chosen["hidden"], chosen["delays"]) else "")]
            for c in rec["candidates"]]
    out = [f"Structure selection: {num(rec['selection_seconds'])} s in all; the chosen network trained "
           f"again in {num(rec['final_training_seconds'])} s "
           f"({rec['final_training'].get('iterations')} LM steps, stopped: "
           f"{rec['final_training'].get('stopped')}).", ""]
    return out + table(["neurons", "output delays", "held-out ISE (m^2 s)", "training (s)", "LM steps"], rows)


def generic(rec: dict) -> list[str]:
    """Records without a table of their own: their floors (if any)."""
    return floors_table(rec)[3:] if rec.get("floors") else ["(no floors recorded)"]


RENDERERS: dict[str, Callable[[dict], list[str]]] = {
    "closed_loop": closed_loop, "estimators": estimators, "campaign": campaign,
    "simulate": simulate, "lmi_handwritten": lmi_handwritten,
    "decentralized_numpy": decentralized_numpy, "run_examples": run_examples, "limits": limits,
    "symbolic": symbolic, "conic_memory": conic_memory, "design": design, "figures": figures,
    "narx_training": narx_training,
}


def render(name: str, results: Path = RESULTS) -> str:
    """The block of ``results/<name>.json``: its table(s), floors and provenance (markdown)."""
    path = results / f"{name}.json"
    if not path.exists():
        return f"(no record: run `python benchmarks/{name.split('_N')[0]}.py`)\n"
    rec = json.loads(path.read_text())
    # a record named after its benchmark, or with a suffix (design_N16-32-64, closed_loop_main)
    key = next((k for k in sorted(RENDERERS, key=len, reverse=True) if name.startswith(k)), None)
    lines = (RENDERERS[key] if key else generic)(rec)
    return "\n".join(lines + [""] + provenance(rec, name)) + "\n"


def blocks(text: str) -> list[str]:
    """Names of the generated blocks in ``text``."""
    return [m.group(2) for m in BLOCK.finditer(text)]


def update(text: str, results: Path = RESULTS) -> str:
    """``text`` with every generated block rendered again from ``results``."""
    return BLOCK.sub(lambda m: m.group(1) + render(m.group(2), results) + m.group(4), text)


def main(argv: list[str] | None = None) -> int:
    """Write or check the README; without an option, print the rendered README."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--write", action="store_true", help="rewrite benchmarks/README.md")
    g.add_argument("--check", action="store_true", help="exit 1 when the README is stale")
    args = ap.parse_args(argv)
    text = README.read_text()
    new = update(text)
    if args.write:
        README.write_text(new)
        print(f"{README}: {len(blocks(new))} blocks rendered")
        return 0
    if args.check:
        if new != text:
            print(f"{README} differs from what results/*.json render: "
                  "run python benchmarks/report.py --write", file=sys.stderr)
            return 1
        return 0
    sys.stdout.write(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
