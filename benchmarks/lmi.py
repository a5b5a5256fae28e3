"""Observer LMI (seed 001 eq. 28) on Takagi-Sugeno models of the N-tank network.

Issue 3, section 6. For ``tank_network(N, parameter_set="decenter")`` with
N = 4, 8, 16, 32, 64 this builds the TS model (`quasi_lpv`, default weights,
box [1, 40] cm per tank, interval premise bounds; for N > 12 the vertices are
not enumerated and ``A0 = A`` at the premise midpoints) and solves the
observer LMI at ``psi = 1e-3`` 1/s (variant ``Q = q I``), side by side:

dense
    full ``P``, free ``K`` (``L = P^-1 K`` dense). ``K`` is eliminated by the
    projection lemma (the library's default ``form="auto"``): the LMI has
    size ``2N - rank C`` instead of ``2N`` (with the decenter ``C = I`` it is
    just ``Q >= t I``, the normalisation ``P >= I`` being the only N x N
    cone) and the gain is recovered in closed form. ``--full-form`` solves
    the ``2N x 2N`` LMI with ``K`` as a variable instead, for comparison.
structured
    block-diagonal ``P`` with one block per tank and the gain restricted to
    the pattern E = own tank (``L[i, j] != 0`` only if output j measures
    tank i): a decentralised observer (always the full form: a gain pattern
    cannot be eliminated)

Both build the problem as `observer_lmi` does: the ``A0`` Parameter covers
only the non-zero entries of ``A0`` (``A0_pattern = A0 != 0``), so the LMI
keeps the network's sparsity for Clarabel's chordal decomposition.
solver
    cvxpy + Clarabel (interior point, the default) and cvxpy + SCS
    (first-order)

"Designed" time is the wall time of `ObserverLMIProblem` (cvxpy problem
construction) plus `observer_lmi` (observability test, skipped when ``C`` has
rank N; cvxpy compilation, solver, gain recovery, unpacking and the library's
re-check), cold, in a freshly forked
process that is killed after its time budget (shown as "> budget"). The TS
model build is timed separately. Every returned gain is re-checked here again,
independently of the library: the block matrix of eq. (28) is rebuilt in
numpy from the returned ``P``, ``Q`` and ``L`` (``K = P L``), and its largest
eigenvalue (normalised as in the library) is shown as the worst LMI
eigenvalue; ``P > 0``, ``Q > 0``, ``Re eig(A0 - L C) < -psi`` and the
requested structure (zero off-block ``P``, zero ``L`` outside the pattern) are
checked too.

psi sweep: "maximise psi" (bisection on feasibility) at N = 8 with one cvxpy
problem compiled once (cvxpy Parameters for ``A0`` and ``psi``), for both
structures and both solvers, against a baseline that rebuilds and recompiles
the problem at every trial. The decenter plant measures every tank (``C =
I``), which makes ``psi`` unbounded (any decay rate is reachable with a large
enough own-tank gain), so the sweep measures only the lower tanks (``y_i =
h_i``, i <= N/2, the quadruple-tank sensor layout).

Floors (each printed PASS/FAIL; exit status 1 on any FAIL or error):
structured N = 64 designed in under 30 s and dense N = 32 in under 5 s (with
Clarabel, the default solver; best of ``--floor-repeat`` cold runs, every run
printed), and no returned gain fails the re-check.

Run from the repository root::

    .venv/bin/python benchmarks/lmi.py            # N = 4 .. 64 (about a minute)
    .venv/bin/python benchmarks/lmi.py --quick    # N = 4 .. 16, Clarabel sweeps only
    .venv/bin/python benchmarks/lmi.py --full-form --sizes 16 32   # dense without elimination
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import platform
import sys
import traceback
import warnings
from time import perf_counter
from typing import Any, Callable

_T_IMPORT = perf_counter()
import numpy as np  # noqa: E402

try:
    import clarabel  # noqa: E402
    import cvxpy as cp  # noqa: E402
    import scs  # noqa: E402

    from tanksynth.design.observer_lmi.lmi import maximise_psi, observer_lmi  # noqa: E402
    from tanksynth.design.observer_lmi.problem import ObserverLMIProblem  # noqa: E402
    from tanksynth.analysis.quasi_lpv import domain_from_plant, quasi_lpv  # noqa: E402
    from tanksynth.analysis.takagi_sugeno import ts_model  # noqa: E402
    from tanksynth.errors import InfeasibleDesign  # noqa: E402
    from tanksynth.plants.tank_network import tank_network  # noqa: E402
except ImportError as exc:  # pragma: no cover - only when the package is broken
    sys.exit(f"benchmarks/lmi.py: cannot import tanksynth ({exc}); run `make bench` "
             "or `.venv/bin/python benchmarks/lmi.py` from the repository root")
IMPORT_SECONDS = perf_counter() - _T_IMPORT

SIZES = (4, 8, 16, 32, 64)
QUICK_SIZES = (4, 8, 16)
SOLVERS = ("CLARABEL", "SCS")
STRUCTURES = ("dense", "structured")
PSI = 1e-3                   # 1/s, Lipschitz constant of the table
BOX = (1.0, 40.0)            # cm, TS domain per tank (the weighted sums h_i must not vanish)
MARGIN, TOLERANCE = 1e-6, 0.5   # the library's defaults: normalised LMI <= -(1 - tol) margin
SWEEP_N = 8
SWEEP_RTOL = 1e-3
FLOORS = {("structured", 64): 30.0, ("dense", 32): 5.0}   # (structure, N): seconds, Clarabel

Send = Callable[[tuple], None]


# ------------------------------------------------------------------- TS model
def ts_network(N: int) -> dict[str, Any]:
    """TS model of the decenter N-tank network; returns A0, C and timings."""
    t = perf_counter()
    plant = tank_network(N, parameter_set="decenter")
    qlpv = quasi_lpv(plant)
    dom = domain_from_plant(plant, [BOX] * N)
    ts = ts_model(qlpv, dom, method="interval")
    return {"A0": ts.A0, "C": ts.C, "p": qlpv.p, "enumerated": ts.enumerated,
            "seconds": perf_counter() - t}


def structure_options(structure: str, C: np.ndarray) -> dict[str, Any]:
    """``blocks``/``pattern`` for one structure: one block per tank, E = own tank."""
    if structure == "dense":
        return {}
    n = C.shape[1]
    return {"blocks": [[i] for i in range(n)], "pattern": (C.T != 0).astype(float)}


def problem_options(structure: str, A0: np.ndarray, C: np.ndarray, full_form: bool) -> dict[str, Any]:
    """`ObserverLMIProblem` keywords: structure, ``A0_pattern`` (as `observer_lmi`), form."""
    form = "full" if full_form else "auto"
    return {**structure_options(structure, C), "A0_pattern": A0 != 0, "form": form}


# --------------------------------------------------------------- child tasks
def _cpu() -> float:
    """CPU time of this process, all threads (user + system), s."""
    t = os.times()
    return t.user + t.system


def design(send: Send, A0: np.ndarray, C: np.ndarray, structure: str, solver: str,
           psi: float, full_form: bool = False) -> None:
    """One observer LMI design, timed by stage; sends the returned P, Q, L."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cpu0 = _cpu()
        start = perf_counter()
        prob = ObserverLMIProblem(A0.shape[0], C, solver=solver,
                                  **problem_options(structure, A0, C, full_form))
        built = perf_counter() - start
        try:
            res = observer_lmi(A0, C, psi, margin=MARGIN, solver=solver, problem=prob)
        except InfeasibleDesign as exc:
            send(("data", {"refused": str(exc), "total": perf_counter() - start}))
            return
        total = perf_counter() - start
        cpu = _cpu() - cpu0
    stats = prob.problem.solver_stats
    send(("data", {"total": total, "cpu": cpu, "build": built, "solve_wall": res.solve_time,
                   "compile": float(prob.problem.compilation_time or 0.0),
                   "solver": float(stats.solve_time) if stats.solve_time is not None else float("nan"),
                   "iterations": stats.num_iters, "status": res.status,
                   "omega": res.scaling["omega_per_s"], "P": res.P, "Q": res.Q, "L": res.L,
                   "achieved_margin": res.achieved_margin, "form": prob.form}))


def sweep(send: Send, A0: np.ndarray, C: np.ndarray, structure: str, solver: str,
          baseline: bool, full_form: bool = False) -> None:
    """maximise_psi with one compiled problem; optionally the recompile-per-trial baseline."""
    opts = problem_options(structure, A0, C, full_form)
    calls: list[tuple[float, float]] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = perf_counter()
        prob = ObserverLMIProblem(A0.shape[0], C, solver=solver, **opts)
        first = prob.problem
        solve = prob.solve

        def timed(A0_, psi, omega=None):        # instrument the compiled problem's solves
            t = perf_counter()
            out = solve(A0_, psi, omega)
            calls.append((perf_counter() - t, float(prob.problem.compilation_time or 0.0)))
            return out

        prob.solve = timed                        # type: ignore[method-assign]
        s = maximise_psi(A0, C, margin=MARGIN, rtol=SWEEP_RTOL, solver=solver, problem=prob)
        total = perf_counter() - start
        res = s.result
        send(("data", {"psi_max": s.psi_max, "psi_infeasible": s.psi_infeasible,
                       "trials": len(s.history), "solves": len(calls), "total": total,
                       "same_problem": prob.problem is first,
                       "compile_first": calls[0][1],
                       "compile_later": float(np.median([c for _, c in calls[1:]])),
                       "solve_times": [w for w, _ in calls], "omega": res.scaling["omega_per_s"],
                       "P": res.P, "Q": res.Q, "L": res.L, "psi": res.psi}))
        if baseline:
            # Same trial sequence (plus the psi = 0 test), a fresh problem every time.
            psis = [0.0] + [p for p, _ in s.history]
            t = perf_counter()
            for psi in psis:
                ObserverLMIProblem(A0.shape[0], C, solver=solver, **opts).solve(A0, psi)
            send(("data", {"baseline_total": perf_counter() - t, "baseline_solves": len(psis)}))


# -------------------------------------------------------------- child process
def _child(target: Callable, conn, args: tuple) -> None:
    try:
        target(conn.send, *args)
        conn.send(("done",))
    except BaseException:  # noqa: BLE001 - reported to the parent
        conn.send(("error", traceback.format_exc()))
    finally:
        conn.close()


def run_in_child(target: Callable, args: tuple, budget: float) -> dict[str, Any]:
    """Run ``target(send, *args)`` in a forked process, killed after ``budget`` s."""
    ctx = mp.get_context("fork")
    recv_end, send_end = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(target, send_end, args), daemon=True)
    out: dict[str, Any] = {"data": {}, "done": False, "error": None, "over_budget": False}
    start = perf_counter()
    proc.start()
    send_end.close()
    while True:
        remaining = budget - (perf_counter() - start)
        if remaining <= 0:
            out["over_budget"] = True
            break
        if not recv_end.poll(min(remaining, 0.25)):
            if not proc.is_alive() and not recv_end.poll():
                out["error"] = f"child exited with code {proc.exitcode}"
                break
            continue
        try:
            msg = recv_end.recv()
        except EOFError:
            out["error"] = f"child exited with code {proc.exitcode}"
            break
        if msg[0] == "data":
            out["data"].update(msg[1])
        elif msg[0] == "error":
            out["error"] = msg[1]
            break
        elif msg[0] == "done":
            out["done"] = True
            break
    out["wall"] = perf_counter() - start
    if proc.is_alive():
        proc.kill()
    proc.join()
    recv_end.close()
    return out


# ------------------------------------------------------ independent re-check
def recheck(A0: np.ndarray, C: np.ndarray, psi: float, d: dict, structure: str) -> dict[str, Any]:
    """Re-check a returned (P, Q, L) in numpy, without the library's check.

    Returns the worst (largest) eigenvalue of the normalised block matrix,
    the list of failed conditions and whether all passed.
    """
    P, Q, L, omega = d["P"], d["Q"], d["L"], d["omega"]
    n = A0.shape[0]
    K = P @ L
    X = A0.T @ P + P @ A0 - C.T @ K.T - K @ C + psi ** 2 * Q
    M = np.block([[X, P], [P, -Q]])
    M = 0.5 * (M + M.T)
    s = np.concatenate([np.full(n, omega ** -0.5), np.full(n, omega ** 0.5)])
    worst = float(np.max(np.linalg.eigvalsh(M * s[:, None] * s[None, :])))
    failed = []
    if not worst <= -(1.0 - TOLERANCE) * MARGIN:
        failed.append(f"normalised LMI max eigenvalue {worst:.3g} > {-(1 - TOLERANCE) * MARGIN:.3g}")
    if not np.max(np.linalg.eigvalsh(M)) < 0:
        failed.append("LMI not negative definite in original units")
    if not np.allclose(P, P.T, rtol=0, atol=1e-12 * np.abs(P).max()):
        failed.append("P not symmetric")
    if not np.min(np.linalg.eigvalsh(0.5 * (P + P.T))) > 0:
        failed.append("P not positive definite")
    if not np.min(np.linalg.eigvalsh(0.5 * (Q + Q.T))) > 0:
        failed.append("Q not positive definite")
    err = float(np.max(np.linalg.eigvals(A0 - L @ C).real))
    if not err < -psi:
        failed.append(f"max Re eig(A0 - L C) = {err:.3g} not < -psi")
    if structure == "structured":
        opts = structure_options(structure, C)
        if np.any(P[~np.eye(n, dtype=bool)] != 0):        # one 1x1 block per tank
            failed.append("P not block-diagonal")
        if np.any(L[opts["pattern"] == 0] != 0):
            failed.append("L outside the pattern E")
    return {"worst": worst, "failed": failed, "ok": not failed, "error_rate": err}


# ------------------------------------------------------------------ reporting
def _fmt(seconds: float | None) -> str:
    if seconds is None or not np.isfinite(seconds):
        return "-"
    return f"{seconds:.3f}" if seconds < 10 else f"{seconds:.1f}"


def _ratio(a: float | None, b: float | None, a_lower: bool = False) -> str:
    if a is None or b is None or b <= 0:
        return "-"
    return f"{'> ' if a_lower else ''}{a / b:.2f}"


def render(headers: list[str], rows: list[list[str]], title: str) -> None:
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(headers)]
    print(title)
    print("  ".join(h.rjust(w) for h, w in zip(headers, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(c.rjust(w) for c, w in zip(r, widths)))
    print()


# ----------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="N up to 16 and Clarabel-only psi sweeps (size floors not checked)")
    parser.add_argument("--sizes", type=int, nargs="+", default=None, help="override the N values")
    parser.add_argument("--budget", type=float, default=None,
                        help="time budget of one design, s (default 60, 20 with --quick)")
    parser.add_argument("--sweep-budget", type=float, default=180.0,
                        help="time budget of one psi sweep, s (default 180)")
    parser.add_argument("--floor-repeat", type=int, default=3,
                        help="cold runs of each floor cell, best kept (default 3)")
    parser.add_argument("--no-sweep", action="store_true", help="skip the psi bisection sweep")
    parser.add_argument("--full-form", action="store_true",
                        help="dense designs with K as an LMI variable (2N x 2N LMI) instead of "
                             "eliminated by the projection lemma (the library default)")
    args = parser.parse_args(argv)
    sizes = tuple(args.sizes) if args.sizes else (QUICK_SIZES if args.quick else SIZES)
    budget = args.budget if args.budget is not None else (20.0 if args.quick else 60.0)
    repeat = max(1, args.floor_repeat)

    print(f"observer LMI (seed 001 eq. 28, Q = q I) on TS models of tank_network (decenter), "
          f"N = {', '.join(map(str, sizes))}; psi = {PSI:g} 1/s, margin {MARGIN:g}, "
          f"TS box [{BOX[0]:g}, {BOX[1]:g}] cm per tank, interval premise bounds")
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at start; "
          f"Python {platform.python_version()}, cvxpy {cp.__version__}, clarabel "
          f"{clarabel.__version__}, scs {scs.__version__}, numpy {np.__version__}")
    print(f"each design runs cold in a freshly forked process (imports shared, "
          f"{IMPORT_SECONDS:.2f} s, not counted), budget {budget:g} s per design; floor cells "
          f"(Clarabel) best of {repeat}; time.perf_counter")
    print("LMI form: dense " + ("full (K an LMI variable, --full-form)" if args.full_form else
                                "K eliminated (projection lemma, closed-form gain)")
          + "; structured full (gain pattern); A0 Parameter over the non-zeros of A0")
    print()

    failures: list[str] = []
    refusals: list[str] = []
    checked = failed_checks = 0
    models: dict[int, dict] = {}
    cells: dict[tuple[int, str, str], dict] = {}
    floor_runs: dict[tuple[str, int], list[tuple[float, float]]] = {}

    for N in sizes:
        try:
            models[N] = ts_network(N)
        except Exception:  # noqa: BLE001
            failures.append(f"TS model of N = {N} failed:\n{traceback.format_exc()}")
            continue
        A0, C = models[N]["A0"], models[N]["C"]
        for structure in STRUCTURES:
            for solver in SOLVERS:
                key = (structure, N)
                runs = repeat if (key in FLOORS and solver == "CLARABEL") else 1
                best: dict | None = None
                for _ in range(runs):
                    o = run_in_child(design, (A0, C, structure, solver, PSI, args.full_form), budget)
                    d = o["data"]
                    if o["error"]:
                        failures.append(f"{structure} N = {N} {solver}: {o['error']}")
                    if o["done"] and "P" in d:
                        chk = recheck(A0, C, PSI, d, structure)
                        checked += 1
                        if not chk["ok"]:
                            failed_checks += 1
                            failures.append(f"re-check: {structure} N = {N} {solver} returned a "
                                            "gain that fails: " + "; ".join(chk["failed"]))
                        d["check"] = chk
                        if runs > 1:
                            floor_runs.setdefault(key, []).append((d["total"], d["cpu"]))
                    elif o["done"] and "refused" in d:
                        refusals.append(f"{structure} N = {N} {solver}: {d['refused']}")
                    cell = {"over_budget": o["over_budget"], "error": o["error"], **d}
                    if best is None or ("P" in d and ("P" not in best or d["total"] < best["total"])):
                        best = cell
                cells[(N, structure, solver)] = best or {}
                print(f"  N = {N:>2} {structure:>10} {solver:<8} "
                      + (f"{_fmt(best.get('total'))} s" if best and "P" in best else
                         "> budget" if best and best["over_budget"] else
                         "refused" if best and "refused" in best else "error"), flush=True)
    print()

    def time_of(N: int, structure: str, solver: str) -> tuple[str, float | None, bool]:
        c = cells.get((N, structure, solver), {})
        if "P" in c:
            return _fmt(c["total"]), c["total"], False
        if c.get("over_budget"):
            return f"> {budget:g}", budget, True
        if "refused" in c:
            return "refused", None, False
        return "error", None, False

    rows = []
    for N in sizes:
        if N not in models:
            rows.append([str(N)] + ["-"] * 9)
            continue
        t = {(s, v): time_of(N, s, v) for s in STRUCTURES for v in SOLVERS}
        row = [str(N), _fmt(models[N]["seconds"])]
        for s in STRUCTURES:
            (ct, cv, cl), (st, sv, sl) = t[(s, "CLARABEL")], t[(s, "SCS")]
            row += [ct, st, _ratio(sv, cv, sl) if not cl else "-"]
        for v in SOLVERS:
            (_, dv, dl), (_, sv, sl) = t[("dense", v)], t[("structured", v)]
            row.append(_ratio(dv, sv, dl) if not sl else "-")
        rows.append(row)
    render(["N", "TS build", "dense CLA", "dense SCS", "SCS/CLA", "struct CLA", "struct SCS",
            "SCS/CLA", "dense/struct CLA", "dense/struct SCS"], rows,
           f"Designed time, seconds (problem build + compile + solve + re-check, psi = {PSI:g})")

    rows = []
    for N in sizes:
        row = [str(N)]
        for s in STRUCTURES:
            for v in SOLVERS:
                c = cells.get((N, s, v), {})
                if "check" in c:
                    ch = c["check"]
                    row.append(f"{ch['worst']:.3g} {'ok' if ch['ok'] else 'FAIL'}")
                else:
                    row.append("-")
        rows.append(row)
    render(["N", "dense CLA", "dense SCS", "struct CLA", "struct SCS"], rows,
           "Worst LMI eigenvalue after the independent re-check (normalised block matrix of eq. 28, "
           f"must be <= {-(1 - TOLERANCE) * MARGIN:.1e}; ok = every condition holds)")

    rows = []
    for N in sizes:
        for s in STRUCTURES:
            c = cells.get((N, s, "CLARABEL"), {})
            if "P" not in c:
                continue
            rest = c["total"] - c["build"] - c["solve_wall"]
            rows.append([str(N), s, c.get("form", "-"), _fmt(c["total"]), _fmt(c["cpu"]),
                         _fmt(c["build"]), _fmt(c["compile"]),
                         _fmt(c["solver"]), str(c["iterations"]), _fmt(rest)])
    render(["N", "structure", "form", "total", "cpu", "cvxpy build", "cvxpy compile", "Clarabel solve",
            "iters", "obs test + re-check"], rows,
           "Where the Clarabel time goes, seconds (compile = problem.compilation_time, solve = "
           "solver_stats.solve_time as reported by Clarabel; cpu = process CPU time, all threads)")

    for key, runs_ in sorted(floor_runs.items(), key=lambda kv: kv[0][1]):
        print(f"floor cell {key[0]} N = {key[1]} (Clarabel), cold runs wall (cpu): "
              + ", ".join(f"{_fmt(w)} ({_fmt(c)})" for w, c in runs_) + " s")
    if floor_runs:
        print()

    # ---------------------------------------------------------------- sweep
    sweep_rows: list[list[str]] = []
    sweep_psi: dict[tuple[str, str], float] = {}
    if not args.no_sweep:
        try:
            m = models[SWEEP_N] if SWEEP_N in models else ts_network(SWEEP_N)
            A0s, Cs = m["A0"], m["C"][: SWEEP_N // 2]
        except Exception:  # noqa: BLE001
            failures.append(f"TS model of N = {SWEEP_N} failed:\n{traceback.format_exc()}")
            A0s = None
        solvers = ("CLARABEL",) if args.quick else SOLVERS
        for s in STRUCTURES if A0s is not None else ():
            for v in solvers:
                o = run_in_child(sweep, (A0s, Cs, s, v, v == "CLARABEL", args.full_form),
                                 args.sweep_budget)
                d = o["data"]
                if o["error"]:
                    failures.append(f"psi sweep {s} {v}: {o['error']}")
                if "P" in d:
                    chk = recheck(A0s, Cs, d["psi"], d, s)
                    checked += 1
                    if not chk["ok"]:
                        failed_checks += 1
                        failures.append(f"re-check: psi sweep {s} {v} final design fails: "
                                        + "; ".join(chk["failed"]))
                    if not d["same_problem"]:
                        failures.append(f"psi sweep {s} {v}: the cvxpy problem was rebuilt")
                    sweep_psi[(s, v)] = d["psi_max"]
                    later = d["solve_times"][1:] or [float("nan")]
                    per, worst_solve = float(np.median(later)), float(np.max(later))
                    base = d.get("baseline_total")
                    sweep_rows.append([
                        s, v, f"{d['psi_max']:.5g}", f"{d['psi_infeasible']:.5g}", str(d["trials"]),
                        _fmt(d["total"]), f"{per * 1e3:.1f} / {worst_solve * 1e3:.0f}",
                        f"{d['compile_first'] * 1e3:.1f}", f"{d['compile_later'] * 1e3:.1f}",
                        "yes" if d["same_problem"] else "NO",
                        _fmt(base) if base is not None else ("> budget" if o["over_budget"] else "-"),
                        _ratio(base, d["total"]) if base is not None else "-",
                        f"{chk['worst']:.3g} {'ok' if chk['ok'] else 'FAIL'}"])
                else:
                    sweep_rows.append([s, v] + (["> budget"] if o["over_budget"] else ["error"])
                                      + ["-"] * 10)
        render(["structure", "solver", "psi_max", "psi_infeas", "trials", "total s", "solve ms med / max",
                "compile 1st ms", "compile later ms (median)", "one problem", "recompile s", "recompile/once",
                "re-check"], sweep_rows,
               f"psi bisection sweep, N = {SWEEP_N}, lower tanks measured (C = first {SWEEP_N // 2} "
               f"rows of I), maximise_psi rtol {SWEEP_RTOL:g}, one compiled problem per row "
               "(Parameters A0, psi)")
        for s in STRUCTURES:
            a, b = sweep_psi.get((s, "CLARABEL")), sweep_psi.get((s, "SCS"))
            if a is not None and b is not None and abs(a - b) > 2 * SWEEP_RTOL * max(a, b):
                print(f"note: psi_max of the {s} sweep differs between solvers ({a:.5g} vs {b:.5g})")
        if ("dense", "CLARABEL") in sweep_psi and ("structured", "CLARABEL") in sweep_psi:
            print(f"structure costs psi: structured/dense psi_max = "
                  f"{sweep_psi[('structured', 'CLARABEL')] / sweep_psi[('dense', 'CLARABEL')]:.3f} "
                  "(the decentralised observer cannot correct the unmeasured upper tanks)")
        print()

    if refusals:
        print("Designs refused by the library (no gain returned):")
        for msg in refusals:
            print(f"  {msg}")
        print()

    # --------------------------------------------------------------- floors
    print(f"load average {os.getloadavg()[0]:.2f} at the end")
    verdicts = []
    for (structure, N), limit in FLOORS.items():
        name = f"{structure} N = {N} designed in under {limit:g} s (Clarabel)"
        if N not in sizes:
            verdicts.append(("not checked", f"{name}: N = {N} not in this run"))
            continue
        c = cells.get((N, structure, "CLARABEL"), {})
        if "P" in c and "check" in c and c["check"]["ok"] and c["total"] < limit:
            verdicts.append(("PASS", f"{name}: {c['total']:.3f} s (cpu {c['cpu']:.3f} s)"))
        else:
            got = (f"{c['total']:.3f} s (cpu {c.get('cpu', float('nan')):.3f} s)" if "P" in c else
                   f"> {budget:g} s" if c.get("over_budget") else
                   "refused" if "refused" in c else "error")
            verdicts.append(("FAIL", f"{name}: {got}"))
            failures.append(f"floor: {name}: {got}")
    ok = failed_checks == 0
    verdicts.append(("PASS" if ok else "FAIL",
                     f"no returned gain fails the re-check: {checked - failed_checks}/{checked} "
                     "returned gains pass"))
    for verdict, text in verdicts:
        print(f"Floor {verdict}: {text}")
    if failures:
        for msg in failures:
            print(f"benchmarks/lmi.py: {msg}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
