"""H-infinity state feedback on the N-tank network: Riccati and LMI routes beside python-control's LQR.

Issue 14. For ``tank_network(N)`` (DECENTER constants, N = 8, 16, 32, 64, N/2
pumps) linearised at the equilibrium with every pump at 4 V, with an unknown
inflow into each tank (``Bw = diag(1 / A_i)``, the ``"inflows"`` shortcut) and
Bryson's weights (``z = [Q^1/2 x; R^1/2 u]``), it times (every design includes
the library's independent re-check: Gramian H2, Hamiltonian H-infinity bisection):

hinf_riccati
    `tanksynth.design.synthesis.synthesize.synthesize_state_feedback` with
    ``objective="hinf"``, ``backoff=1e-3`` and the default ``route="auto"``:
    gamma bisection on the game Riccati equation (scipy ARE), the central gain
    at ``1.001 gamma_optimum``. This is what ``hinf_state_feedback`` runs.
hinf_lmi
    the same problem with ``route="lmi"`` and ``backoff=0`` (ONE Clarabel solve
    of the reduced bounded-real LMI; the default back-off would add a second
    solve): only for N <= ``--lmi-max`` (default 32; at N = 64 one solve takes
    tens of minutes: Clarabel factorises a dense block of size s(s+1)/2 for the
    LMI of size s = n + nz = 160).
h2_riccati, h2_lmi
    ``objective="h2"`` by the two routes (the LMI only up to ``--lmi-max``).
lqr_python_control
    python-control ``lqr`` (Riccati, scipy) with the same weights, and the
    H2 and H-infinity norms of its closed loop (tanksynth.analysis.statespace).

BLAS threads: the Riccati route limits BLAS to one thread inside the library
(threadpoolctl; on this loaded 2-core machine OpenBLAS's pool made the N = 64
bisection 48 s instead of 1.2 s); the LMI route and python-control run with the
process's default. ``--blas-threads 1`` limits every method to one thread
(same conditions for all).

Same problem for every method; runs are interleaved (every size and method in
turn, ``--reps`` rounds, default 3); minimum and median wall times reported.
Floor: ``hinf_riccati`` (the default route) at N = 32 under 10 s (minimum over
the rounds); exit status 1 when it fails. A JSON record is written to
``benchmarks/results/hinf.json``.

Run from the repository root::

    .venv/bin/python benchmarks/hinf.py               # N = 8 .. 64, 3 rounds
    .venv/bin/python benchmarks/hinf.py --sizes 8 16 --reps 3 --lmi-max 16
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

FLOOR_N, FLOOR_S = 32, 10.0


def _problem(N: int):
    import scipy.linalg as sla
    from scipy.optimize import fsolve

    from tanksynth.analysis.linearize import linearize
    from tanksynth.design.synthesis.synthesize import GeneralizedPlant
    from tanksynth.plants.tank_network import tank_network
    from tanksynth.spec.method_options.synthesis import (bryson_input_weight, bryson_state_weight,
                                                         inflow_matrix)

    plant = tank_network(N)
    u0 = np.full(plant.m, 4.0)
    rhs = plant.compiled.rhs
    guess = np.concatenate([np.full(N // 2, 22.0), np.full(N // 2, 7.0)])
    x0 = fsolve(lambda x: rhs(np.maximum(x, 1e-6)[None], u0[None])[0], guess, xtol=1e-12)
    lin = linearize(plant, x0, u0)
    Q, R = bryson_state_weight(plant), bryson_input_weight(plant)
    Cz = np.vstack([sla.sqrtm(Q).real, np.zeros((plant.m, N))])
    Dzu = np.vstack([np.zeros((N, plant.m)), sla.sqrtm(R).real])
    Bw = inflow_matrix(plant)
    return GeneralizedPlant(lin.F, lin.B, Bw, Cz, Dzu), Q, R, float(np.max(np.abs(rhs(x0[None], u0[None]))))


def _hinf(P, route):
    from tanksynth.design.synthesis.synthesize import synthesize_state_feedback

    res = synthesize_state_feedback(P, objective="hinf", route=route,
                                    backoff=1e-3 if route == "auto" else 0.0)
    return {"gamma": res.gamma, "gamma_optimum": res.gamma_optimum,
            "achieved_hinf": res.achieved_hinf[0], "route": res.route, "status": res.status}


def _h2(P, route):
    from tanksynth.design.synthesis.synthesize import synthesize_state_feedback

    res = synthesize_state_feedback(P, objective="h2", route=route)
    return {"h2": res.h2, "achieved_h2": res.achieved_h2[0], "achieved_hinf": res.achieved_hinf[0],
            "route": res.route}


def _lqr(P, Q, R):
    import control

    from tanksynth.analysis.statespace import h2_norm, hinf_norm

    K, S, _ = control.lqr(P.A, P.B, Q, R)
    Acl, Ccl = P.A - P.B @ K, P.Cz - P.Dzu @ K
    return {"h2": h2_norm(Acl, P.Bw, Ccl), "achieved_hinf": hinf_norm(Acl, P.Bw, Ccl),
            "h2_riccati": float(np.sqrt(np.trace(P.Bw.T @ S @ P.Bw)))}


METHODS = ("hinf_riccati", "hinf_lmi", "h2_riccati", "h2_lmi", "lqr_python_control")


def _methods(P, Q, R, lmi: bool):
    out = [("hinf_riccati", lambda: _hinf(P, "auto"))]
    if lmi:
        out.append(("hinf_lmi", lambda: _hinf(P, "lmi")))
    out.append(("h2_riccati", lambda: _h2(P, "auto")))
    if lmi:
        out.append(("h2_lmi", lambda: _h2(P, "lmi")))
    out.append(("lqr_python_control", lambda: _lqr(P, Q, R)))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[8, 16, 32, 64])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--lmi-max", type=int, default=32, help="largest N for the LMI route")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "hinf.json"))
    ap.add_argument("--blas-threads", type=int, default=None, help="limit BLAS threads for every method")
    args = ap.parse_args(argv)
    if args.blas_threads is not None:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=args.blas_threads, user_api="blas")
    problems = {N: _problem(N) for N in args.sizes}
    times: dict[tuple[int, str], list[float]] = {}
    info: dict[tuple[int, str], dict] = {}
    for rep in range(max(args.reps, 1)):
        for N in args.sizes:
            P, Q, R, _ = problems[N]
            for name, fn in _methods(P, Q, R, N <= args.lmi_max):
                t0 = time.perf_counter()
                out = fn()
                times.setdefault((N, name), []).append(time.perf_counter() - t0)
                info[(N, name)] = out
        print(f"round {rep + 1}/{args.reps} done", file=sys.stderr, flush=True)
    rows, agree = [], {}
    print(f"{'N':>4} {'method':<19} {'min s':>9} {'median s':>9}  result")
    for N in args.sizes:
        for name in METHODS:
            if (N, name) not in times:
                print(f"{N:>4} {name:<19} {'-':>9} {'-':>9}  not run (N > --lmi-max {args.lmi_max})")
                continue
            t = times[(N, name)]
            r = info[(N, name)]
            rows.append({"N": N, "method": name, "times_s": t, "min_s": min(t),
                         "median_s": statistics.median(t), **r})
            desc = ", ".join(f"{k} {v:.6g}" for k, v in r.items() if isinstance(v, float))
            print(f"{N:>4} {name:<19} {min(t):9.3f} {statistics.median(t):9.3f}  {desc}")
        if (N, "hinf_lmi") in info:
            a, b = info[(N, "hinf_riccati")]["gamma_optimum"], info[(N, "hinf_lmi")]["gamma_optimum"]
            c, d = info[(N, "h2_riccati")]["h2"], info[(N, "h2_lmi")]["h2"]
            agree[N] = {"gamma_optimum_rel_diff": (a - b) / b, "h2_rel_diff": (c - d) / d}
            print(f"{N:>4} routes agree: gamma_optimum Riccati - LMI {(a - b) / b:+.2e} relative, "
                  f"H2 {(c - d) / d:+.2e} relative")
    floor = None
    if FLOOR_N in args.sizes:
        best = min(times[(FLOOR_N, "hinf_riccati")])
        floor = {"N": FLOOR_N, "method": "hinf_riccati (route auto)", "limit_s": FLOOR_S,
                 "min_s": best, "passed": best < FLOOR_S}
        print(f"floor: hinf_state_feedback (route auto) N = {FLOOR_N} in {best:.3f} s (< {FLOOR_S:g} s): "
              f"{'PASS' if floor['passed'] else 'FAIL'}")
    record = {"benchmark": "hinf", "sizes": args.sizes, "reps": args.reps, "lmi_max": args.lmi_max,
              "blas_threads": args.blas_threads or "process default (Riccati route: 1, in the library)",
              "rows": rows, "routes_agree": agree, "floor": floor, "equilibrium_residuals": {N: problems[N][3] for N in args.sizes},
              "python": platform.python_version(), "machine": platform.machine(),
              "when": time.strftime("%Y-%m-%dT%H:%M:%S")}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=1, default=float))
    print(f"wrote {out}")
    return 0 if (floor is None or floor["passed"]) else 1


if __name__ == "__main__":
    sys.exit(main())
