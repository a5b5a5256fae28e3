"""Decentralised finite-horizon gains: tanksynth's default route vs plain numpy and DECENTER.

Issue 15. The same window as ``benchmarks/decentralized.py`` (seed 003's set-up
on ``tank_network(N)``: 40 steps, relinearised every 10, q = 0.01 cm^2/s with
rho = 0.5, R = 4 I cm^2, P(0|0) = 10 I cm^2, tol 1e-6, at most 100 outer
iterations), both cases (``all measured``, E = I; ``lower measured``, 3N/2
free entries). Contenders, interleaved, ``--reps`` repetitions (>= 3):

* ``tanksynth``: ``finite_horizon_gains(...)`` with its default route, which
  also validates every input once (shapes, finiteness, symmetry, Q >= 0,
  R > 0, P(1|0) > 0), symmetrises every covariance it returns and
  re-checks every returned P(k|k) > 0 (Cholesky), all inside the timing;
* ``numpy``: the same algorithm (one-step start, Pedroso and Batista's
  backward sweep of masked gains with ``Lambda_k = I + M' Lambda_{k+1} M``,
  forward Joseph-form pass, relative change of every ``tr P(k|k)`` below tol)
  written plainly here in numpy, the way a capable user would (about 40
  lines): no validation, no symmetrisation, no positive-definiteness check,
  ``np.linalg.solve`` (LU) for the gain equation;
* ``decenter``: DECENTER's published algorithm (``kalmanFiniteHorizonLTV`` +
  ``sparseEqSolver`` + ``kalmanOneStepLTV``, the toolbox seed 003 runs), ported
  step for step in ``decenter_reference.py``: ``Lambda`` as printed, the sum
  of ``Gamma' Gamma`` over the rest of the window with every product rebuilt
  (O(T^3) matrix products per sweep, against O(T) for the recursion), the
  predicted covariance recomputed in the backward sweep, the stop checked
  from the second iteration on.

Same work on every side: the same window matrices (built once, outside the
timing), pattern, tolerance and iteration limit. Before timing, per N: cost
of each contender relative to tanksynth's (must be <= 1e-9), the largest gain
difference relative to the largest tanksynth gain entry (<= 1e-8) and the
outer iterations. BLAS threads: tanksynth runs its sweeps on one OpenBLAS
thread (``tanksynth.analysis.blas.small_dense``); by default the two
alternatives get the same (``threadpool_limits(1)`` entered inside their
timed call), so that the comparison is of the algorithms, not of OpenBLAS's
threads on a shared 2-core machine (``--alt-blas default`` leaves them alone:
at N = 128 that made the plain iteration 4-21 s instead of 0.6 s here).

Printed: wall min / median per contender and every repetition's wall time, the
median CPU time (``time.process_time``, all threads), the ratio alternative /
tanksynth per repetition (wall) and its median, in wall and CPU. Floors (exit 1
on a miss, and on a disagreement), N >= 16: tanksynth at least as fast as the
plain numpy iteration and DECENTER's algorithm (median ratio >= 1; DECENTER runs up to
``--decenter-max``, default N = 128: its O(T^3) sweep takes minutes at 256).
Record: ``results/decentralized_numpy.json`` (load average before and after,
every repetition). Issue 29's floor, at least plain numpy in EVERY repetition (the
smallest per-rep wall ratio >= 1), is reported; exit 1 on its miss only with ``--strict``.
N > 64 runs ``--reps-large`` repetitions (default 3).

Usage: ``python benchmarks/decentralized_numpy.py [--sizes 16 32 64 128 256] [--reps 15]
[--reps-large 3] [--alt-blas one|default] [--decenter-max 128]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from contextlib import nullcontext
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from decenter_reference import finite_horizon as decenter_fh
from decentralized import CASES, MAX_ITER, TOL, window
from harness import Floors, machine, ratios, summary, write_record
from threadpoolctl import threadpool_limits

from tanksynth.design.decentralized.gains import finite_horizon_gains


def plain_numpy(A, C, Q, R, E, P0, tol=TOL, max_iter=MAX_ITER):
    """Finite-horizon masked Kalman gains by the plain iteration; returns (gains, cost, iterations)."""
    T, n = len(A), A[0].shape[0]
    rows, cols = np.nonzero(E)
    rr, cc = np.ix_(rows, rows), np.ix_(cols, cols)
    eye = np.eye(n)

    def masked(L, S, rhs):
        K = np.zeros(E.shape)
        K[rows, cols] = np.linalg.solve(L[rr] * S[cc], rhs[rows, cols])
        return K

    def forward(K):
        Pp, pred, filt = P0, [], []
        for k in range(T):
            pred.append(Pp)
            IKC = eye - K[k] @ C[k]
            Pf = IKC @ Pp @ IKC.T + K[k] @ R[k] @ K[k].T
            filt.append(Pf)
            Pp = A[k] @ Pf @ A[k].T + Q[k]
        return pred, np.array([np.trace(P) for P in filt])

    K, Pp = [], P0
    for k in range(T):                                   # one-step gains: the start
        K.append(masked(eye, C[k] @ Pp @ C[k].T + R[k], Pp @ C[k].T))
        IKC = eye - K[k] @ C[k]
        Pp = A[k] @ (IKC @ Pp @ IKC.T + K[k] @ R[k] @ K[k].T) @ A[k].T + Q[k]
    pred, traces = forward(K)
    for it in range(1, max_iter + 1):
        L = eye
        for k in range(T - 1, -1, -1):                   # backward sweep
            if k < T - 1:
                M = (eye - K[k + 1] @ C[k + 1]) @ A[k]
                L = eye + M.T @ L @ M
            K[k] = masked(L, C[k] @ pred[k] @ C[k].T + R[k], L @ pred[k] @ C[k].T)
        pred, new = forward(K)
        done = np.max(np.abs(new - traces) / np.abs(traces)) < tol
        traces = new
        if done:
            break
    return K, float(traces.sum()), it


COST_RTOL, GAIN_RTOL = 1e-9, 1e-8
ALTERNATIVES = ("numpy", "decenter")


def interleave_cpu(contenders, reps: int) -> tuple[dict[str, list[float]], dict[str, list[float]]]:
    """Wall and CPU (``process_time``, all threads) seconds per call, contenders interleaved."""
    wall = {name: [] for name in contenders}
    cpu = {name: [] for name in contenders}
    for _ in range(int(reps)):
        for name, fn in contenders.items():
            c0, t0 = time.process_time(), time.perf_counter()
            fn()
            wall[name].append(time.perf_counter() - t0)
            cpu[name].append(time.process_time() - c0)
    return wall, cpu


def gain_diff(K, K_ref) -> float:
    """Largest entry of ``K - K_ref`` over the window, relative to the largest of ``K_ref``."""
    return float(max(np.abs(np.asarray(a) - np.asarray(b)).max() for a, b in zip(K, K_ref))
                 / max(np.abs(np.asarray(b)).max() for b in K_ref))


def main() -> int:
    """Run the benchmark; exit 1 on a floor miss or a disagreement."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 32, 64, 128, 256])
    ap.add_argument("--decenter-max", type=int, default=128,
                    help="largest N at which DECENTER's O(T^3) algorithm runs (minutes at 256)")
    ap.add_argument("--reps", type=int, default=15, help="repetitions for N <= 64 (>= 3)")
    ap.add_argument("--reps-large", type=int, default=3, help="repetitions for N > 64 (>= 3)")
    ap.add_argument("--alt-blas", choices=("one", "default"), default="one",
                    help="BLAS threads of the alternatives: one (as tanksynth) or untouched")
    ap.add_argument("--strict", action="store_true",
                    help="exit 1 also when a rep is slower than plain numpy (issue 29's floor)")
    args = ap.parse_args()
    before = machine()
    floors = Floors()
    rows = []

    def limited():
        return threadpool_limits(limits=1, user_api="blas") if args.alt_blas == "one" else nullcontext()

    print(f"decentralised FH gains, window 40, tol {TOL:g}; load {before['loadavg']}; "
          f"alternatives' BLAS threads: {args.alt_blas}")
    for case in CASES:
        for N in args.sizes:
            reps = max(args.reps if N <= 64 else args.reps_large, 3)
            seqs, E, P0 = window(N, case)

            def ours(seqs=seqs, E=E, P0=P0):
                return finite_horizon_gains(*seqs, E, P0, tol=TOL, max_iter=MAX_ITER)

            def numpy_(seqs=seqs, E=E, P0=P0):
                with limited():
                    return plain_numpy(*seqs, E, P0)

            def decenter(seqs=seqs, E=E, P0=P0):
                with limited():
                    return decenter_fh(*seqs, E, P0, epsl=TOL, max_it=MAX_ITER)

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                ref = ours()
                K_np, c_np, it_np = numpy_()
                agree = {
                    "numpy": {"cost": c_np, "cost_rel_diff": abs(c_np - ref.cost) / ref.cost,
                              "gain_rel_diff": gain_diff(K_np, ref.K), "iterations": it_np}}
                alternatives = ("numpy",)
                if N <= args.decenter_max:
                    K_dc, _, c_dc, it_dc = decenter()
                    agree["decenter"] = {"cost": c_dc, "cost_rel_diff": abs(c_dc - ref.cost) / ref.cost,
                                         "gain_rel_diff": gain_diff(K_dc, ref.K), "iterations": it_dc}
                    alternatives = ALTERNATIVES
                print(f"\n{case}, N = {N} ({int(E.sum())} free entries): tanksynth cost "
                      f"{ref.cost:.10g}, {ref.iterations} iterations")
                ok = True
                for name, a in agree.items():
                    good = a["cost_rel_diff"] <= COST_RTOL and a["gain_rel_diff"] <= GAIN_RTOL
                    ok &= good
                    print(f"  {name:9s} cost {a['cost']:.10g} (rel diff {a['cost_rel_diff']:.1e}), "
                          f"gains rel diff {a['gain_rel_diff']:.1e}, {a['iterations']} iterations"
                          + ("" if good else "   DISAGREE"))
                    floors.rows.append({"what": f"agreement {name} {case} N={N}", "ok": bool(good)})
                if not ok:
                    continue
                contenders = {"tanksynth": ours, "numpy": numpy_, "decenter": decenter}
                wall, cpu = interleave_cpu({k: contenders[k] for k in ("tanksynth",) + alternatives},
                                           reps)
            row = {"case": case, "N": N, "free_entries": int(E.sum()), "reps": reps,
                   "times": wall, "cpu_times": cpu, "cost_tanksynth": ref.cost,
                   "iterations_tanksynth": ref.iterations, "agreement": agree}
            for name in ("tanksynth",) + alternatives:
                sw = summary(wall[name])
                print(f"  {name:9s} wall min {sw['min'] * 1e3:9.1f} ms  median {sw['median'] * 1e3:9.1f} ms"
                      f"   cpu median {statistics.median(cpu[name]) * 1e3:9.1f} ms; every rep (ms): "
                      + " ".join(f"{v * 1e3:.1f}" for v in wall[name]))
            for name in alternatives:
                r, rc = ratios(wall[name], wall["tanksynth"]), ratios(cpu[name], cpu["tanksynth"])
                row[f"ratio_{name}_over_tanksynth"] = r
                row[f"cpu_ratio_{name}_over_tanksynth"] = rc
                print(f"  {name} / tanksynth per rep: " + " ".join(f"{v:.2f}" for v in r)
                      + f"   median {statistics.median(r):.2f} (cpu {statistics.median(rc):.2f})")
            rows.append(row)
            if N >= 16:
                for name in alternatives:
                    floors.check(f"{case} N={N} vs {name}",
                                 statistics.median(row[f"ratio_{name}_over_tanksynth"]), 1.0)
                # issue 29: at least plain numpy in EVERY rep (the smallest per-rep ratio)
                floors.check(f"{case} N={N} vs numpy in every rep",
                             min(row["ratio_numpy_over_tanksynth"]), 1.0, stat="smallest",
                             strict_only=True)
    path = write_record("decentralized_numpy", {"alt_blas": args.alt_blas, "reps": args.reps,
                                                "reps_large": args.reps_large, "rows": rows,
                                                "floors": floors.rows}, before)
    print(f"\nrecord: {path}")
    return floors.exit_status(args.strict)


if __name__ == "__main__":
    sys.exit(main())
