"""Decentralised finite-horizon Kalman gains: CasADi/IPOPT route vs iterative route.

Issue 6, section 4. For ``tank_network(N, parameter_set="decenter")`` with
N = 4, 8, 16, 32, 40, 64 this designs one window of 40 steps in seed 003's
set-up (20 cm in every tank, 6 V on every pump, models relinearised every 10
steps along the predicted trajectory, Van Loan noise of the declared dense
intensity q = 0.01 cm^2/s, rho = 0.5, R = 4 I cm^2, P(0|0) = 10 I cm^2,
E = I, tol = 1e-6, max_iter = 100) with

iterative   ``finite_horizon_gains(..., method="iterative")`` (Pedroso &
            Batista's backward/forward sweeps, vectorised sparse solve)
casadi      ``finite_horizon_gains(..., method="casadi")`` (window problem in
            CasADi, masked gains as the decision variables, IPOPT warm-started
            from the one-step gains; NLP construction included in the time)

side by side: wall time (best of ``--repeat`` runs), iterations, cost
``sum_k tr P(k|k)`` and the ratios (time casadi / iterative, cost casadi /
iterative - 1). The one-step cost of the same window is shown for reference.

Two cases: ``all measured`` is seed 003 (every level measured, E = I: the
finite horizon barely improves on the one-step gains); ``lower measured``
measures the lower tanks only, and an upper tank's gain may use the level of
the lower tank it drains into and of the lower tank its pump also feeds (3N/2
free entries), a case where the finite horizon matters more.

Floors (issue 6), checked unless ``--quick``:

* N = 64: either route designs the window in under 60 s (both cases);
* every N and case: the casadi cost exceeds the iterative cost by at most
  1e-6 relative;
* N = 40, seed 003 case: the iterative route takes well under a second
  (< 0.5 s).

Run from the repository root::

    .venv/bin/python benchmarks/decentralized.py            # N = 4 .. 64
    .venv/bin/python benchmarks/decentralized.py --quick    # N = 4, 8, 16

Exit status 1 when a floor fails or a route errors or does not converge.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import warnings
from time import perf_counter

_T_IMPORT = perf_counter()
import numpy as np  # noqa: E402

try:
    import casadi  # noqa: E402

    from tanksynth.design.decentralized.gains import finite_horizon_gains  # noqa: E402
    from tanksynth.design.decentralized.models import equicorrelated_intensity, window_models  # noqa: E402
    from tanksynth.plants.tank_network import tank_network  # noqa: E402
except ImportError as exc:  # pragma: no cover - only when the package is broken
    sys.exit(f"benchmarks/decentralized.py: cannot import tanksynth ({exc}); run `make bench` or "
             "`.venv/bin/python benchmarks/decentralized.py` from the repository root")
IMPORT_SECONDS = perf_counter() - _T_IMPORT

SIZES = (4, 8, 16, 32, 40, 64)
QUICK_SIZES = (4, 8, 16)
WINDOW = 40
TS = 1.0
RELIN = 10
LEVEL, PUMP = 20.0, 6.0          # cm, V
Q_INTENSITY, Q_CORRELATION = 0.01, 0.5
R_CM2, P0_CM2 = 4.0, 10.0
TOL, MAX_ITER = 1e-6, 100
FLOOR_N64_SECONDS = 60.0
FLOOR_COST_RTOL = 1e-6
FLOOR_N40_ITERATIVE_SECONDS = 0.5


CASES = ("all measured", "lower measured")


def window(N: int, case: str = CASES[0]):
    """Seed 003's first window for N tanks: (A, C, Q, R) sequences, E and P(1|0)."""
    plant = tank_network(N)
    Qc = equicorrelated_intensity(N, Q_INTENSITY, Q_CORRELATION)
    models, _ = window_models(plant, np.full(N, LEVEL), np.full((WINDOW + 1, N // 2), PUMP), TS,
                              Qc, R_CM2 * np.eye(N), relinearize_every=RELIN)
    seqs = ([m.A for m in models[1:]], [m.C for m in models[1:]], [m.Q for m in models[1:]],
            [m.R for m in models[1:]])
    P0 = models[0].A @ (P0_CM2 * np.eye(N)) @ models[0].A.T + models[0].Q
    if case == CASES[0]:
        return seqs, np.eye(N), P0
    h = N // 2
    lower = np.arange(h)
    E = np.zeros((N, h))
    E[lower, lower] = 1                     # lower tank i: its own level
    E[h + lower, lower] = 1                 # upper tank h+i drains into lower tank i
    E[h + lower, (lower - 1) % h] = 1       # ... and is fed by the pump of lower tank i-1
    seqs = (seqs[0], [c[:h] for c in seqs[1]], seqs[2], [r[:h, :h] for r in seqs[3]])
    return seqs, E, P0


def run_route(seqs, E, P0, method: str, repeat: int):
    best, res = np.inf, None
    for _ in range(repeat):
        t = perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = finite_horizon_gains(*seqs, E, P0, method=method, tol=TOL, max_iter=MAX_ITER)
        best = min(best, perf_counter() - t)
    return best, res


def table(rows: list[list[str]], headers: list[str]) -> None:
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(headers)]
    print("  ".join(h.rjust(w) for h, w in zip(headers, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(c.rjust(w) for c, w in zip(r, widths)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="N = 4, 8, 16 only; floors not checked")
    parser.add_argument("--sizes", type=int, nargs="+", help="tank counts (even, 4..64)")
    parser.add_argument("--repeat", type=int, default=3, help="runs per route, best time kept")
    args = parser.parse_args(argv)
    sizes = tuple(args.sizes) if args.sizes else (QUICK_SIZES if args.quick else SIZES)
    repeat = max(1, args.repeat)
    print(f"decentralised FH Kalman gains, tank_network (decenter), N = {', '.join(map(str, sizes))}; "
          f"window {WINDOW}, tol {TOL:g}, max_iter {MAX_ITER}")
    print(f"machine: {os.cpu_count()} cores, Python {platform.python_version()}, numpy "
          f"{np.__version__}, casadi {casadi.__version__}; imports {IMPORT_SECONDS:.2f} s; "
          f"best of {repeat} runs per route")
    print()
    failures, results = [], {}
    for case in CASES:
        rows = []
        for N in sizes:
            try:
                seqs, E, P0 = window(N, case)
                t_it, it = run_route(seqs, E, P0, "iterative", repeat)
                t_ca, ca_ = run_route(seqs, E, P0, "casadi", repeat)
            except Exception as exc:  # report every size, then fail
                failures.append(f"{case}, N = {N}: {type(exc).__name__}: {exc}")
                continue
            results[case, N] = (t_it, it, t_ca, ca_)
            rel = (ca_.cost - it.cost) / it.cost
            rows.append([str(N), str(int(E.sum())), f"{t_it:.3f}", str(it.iterations),
                         f"{t_ca:.3f}", str(ca_.iterations), f"{t_ca / t_it:.1f}",
                         f"{it.cost:.6f}", f"{ca_.cost:.6f}", f"{rel:+.1e}",
                         f"{it.one_step_cost:.6f}",
                         f"{(it.one_step_cost - it.cost) / it.cost:.1e}"])
            for name, res in (("iterative", it), ("casadi", ca_)):
                if not res.converged:
                    failures.append(f"{case}, N = {N}: {name} route did not converge ({res.status})")
        print(f"case: {case}")
        table(rows, ["N", "free", "iter s", "its", "casadi s", "its", "time ratio",
                     "cost iterative", "cost casadi", "cost ratio-1", "cost one-step", "FH gain"])
        print()
    print("free = free gain entries per step; time ratio = casadi / iterative; cost ratio-1 = "
          "casadi / iterative - 1; FH gain = (one-step - FH) / FH")
    print()
    if not args.quick:
        checks = []
        for case in CASES:
            if (case, 64) in results:
                t_it, _, t_ca, _ = results[case, 64]
                checks.append((f"{case}: N = 64 window in < {FLOOR_N64_SECONDS:g} s with either "
                               f"route (iterative {t_it:.2f} s, casadi {t_ca:.2f} s)",
                               max(t_it, t_ca) < FLOOR_N64_SECONDS))
        worst = max(((r[3].cost - r[1].cost) / r[1].cost for r in results.values()), default=0.0)
        checks.append((f"casadi cost <= iterative cost (1 + {FLOOR_COST_RTOL:g}) for every N and "
                       f"case (worst {worst:+.1e})", worst <= FLOOR_COST_RTOL))
        if (CASES[0], 40) in results:
            t_it = results[CASES[0], 40][0]
            checks.append((f"{CASES[0]}: N = 40 iterative < {FLOOR_N40_ITERATIVE_SECONDS:g} s "
                           f"({t_it:.3f} s)", t_it < FLOOR_N40_ITERATIVE_SECONDS))
        for text, ok in checks:
            print(f"Floor (issue 6): {text}: {'PASS' if ok else 'FAIL'}")
            if not ok:
                failures.append(f"floor failed: {text}")
    else:
        print("Floors (issue 6) not checked with --quick.")
    for msg in failures:
        print(f"benchmarks/decentralized.py: {msg}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
