"""H-infinity state feedback by LMI on the N-tank network, beside python-control's Riccati LQR.

Issue 14. For ``tank_network(N)`` (DECENTER constants, N = 8, 16, 32, 64, N/2
pumps) linearised at the equilibrium with every pump at 4 V, with an unknown
inflow into each tank (``Bw = diag(1 / A_i)``, the ``"inflows"`` shortcut) and
Bryson's weights (``z = [Q^1/2 x; R^1/2 u]``), it times:

hinf_lmi
    `tanksynth.design.synthesis.synthesize_state_feedback` with
    ``objective="hinf"`` and the default back-off 1e-3 (two Clarabel solves:
    optimum, then the margin-maximising point) including problem construction
    and the library's re-check (Gramian H2, Hamiltonian H-infinity bisection);
    the gamma it certifies and the recomputed norm are recorded.
h2_lmi
    the H2 LMI (one solve), whose optimum is the LQR's.
lqr_riccati
    python-control ``lqr`` (Riccati, scipy) with the same weights: the
    H-infinity norm its closed loop reaches is recorded (the price of
    optimising H2 instead of H-infinity); it designs no H-infinity gain.

Runs are interleaved (every method and size in turn, ``--reps`` rounds,
default 3) and the minimum and median wall times are reported. Floor:
``hinf_lmi`` at N = 32 under 10 s (minimum over the rounds); exit status 1
when it fails. A JSON record is written to ``benchmarks/results/hinf.json``.

Run from the repository root::

    .venv/bin/python benchmarks/hinf.py               # N = 8 .. 64, 3 rounds
    .venv/bin/python benchmarks/hinf.py --sizes 8 16 --reps 3
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
    from tanksynth.design.synthesis import GeneralizedPlant
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


def _hinf(P):
    from tanksynth.design.synthesis import synthesize_state_feedback

    res = synthesize_state_feedback(P, objective="hinf", backoff=1e-3)
    return {"gamma": res.gamma, "gamma_lmi_optimum": res.gamma_optimum,
            "achieved_hinf": res.achieved_hinf[0], "status": res.status}


def _h2(P):
    from tanksynth.design.synthesis import synthesize_state_feedback

    res = synthesize_state_feedback(P, objective="h2")
    return {"h2": res.h2, "achieved_hinf": res.achieved_hinf[0]}


def _lqr(P, Q, R):
    import control

    from tanksynth.analysis.statespace import h2_norm, hinf_norm

    K, S, _ = control.lqr(P.A, P.B, Q, R)
    Acl, Ccl = P.A - P.B @ K, P.Cz - P.Dzu @ K
    return {"h2": h2_norm(Acl, P.Bw, Ccl), "achieved_hinf": hinf_norm(Acl, P.Bw, Ccl),
            "h2_riccati": float(np.sqrt(np.trace(P.Bw.T @ S @ P.Bw)))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[8, 16, 32, 64])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "hinf.json"))
    args = ap.parse_args(argv)
    problems = {N: _problem(N) for N in args.sizes}
    times: dict[tuple[int, str], list[float]] = {}
    info: dict[tuple[int, str], dict] = {}
    for rep in range(max(args.reps, 1)):
        for N in args.sizes:
            P, Q, R, _ = problems[N]
            for name, fn in (("hinf_lmi", lambda: _hinf(P)), ("h2_lmi", lambda: _h2(P)),
                             ("lqr_riccati", lambda: _lqr(P, Q, R))):
                t0 = time.perf_counter()
                out = fn()
                times.setdefault((N, name), []).append(time.perf_counter() - t0)
                info[(N, name)] = out
        print(f"round {rep + 1}/{args.reps} done", file=sys.stderr)
    rows = []
    print(f"{'N':>4} {'method':<12} {'min s':>9} {'median s':>9}  result")
    for N in args.sizes:
        for name in ("hinf_lmi", "h2_lmi", "lqr_riccati"):
            t = times[(N, name)]
            r = info[(N, name)]
            rows.append({"N": N, "method": name, "times_s": t, "min_s": min(t),
                         "median_s": statistics.median(t), **r})
            desc = ", ".join(f"{k} {v:.6g}" for k, v in r.items() if isinstance(v, float))
            print(f"{N:>4} {name:<12} {min(t):9.3f} {statistics.median(t):9.3f}  {desc}")
    floor = None
    if FLOOR_N in args.sizes:
        best = min(times[(FLOOR_N, "hinf_lmi")])
        floor = {"N": FLOOR_N, "limit_s": FLOOR_S, "min_s": best, "passed": best < FLOOR_S}
        print(f"floor: hinf_lmi N = {FLOOR_N} in {best:.3f} s (< {FLOOR_S:g} s): "
              f"{'PASS' if floor['passed'] else 'FAIL'}")
    record = {"benchmark": "hinf", "sizes": args.sizes, "reps": args.reps, "rows": rows,
              "floor": floor, "equilibrium_residuals": {N: problems[N][3] for N in args.sizes},
              "python": platform.python_version(), "machine": platform.machine(),
              "when": time.strftime("%Y-%m-%dT%H:%M:%S")}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=1, default=float))
    print(f"wrote {out}")
    return 0 if (floor is None or floor["passed"]) else 1


if __name__ == "__main__":
    sys.exit(main())
