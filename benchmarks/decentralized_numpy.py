"""Decentralised finite-horizon gains: tanksynth's default route vs a plain numpy iteration.

Issue 15. The same window as ``benchmarks/decentralized.py`` (seed 003's set-up
on ``tank_network(N)``: 40 steps, relinearised every 10, q = 0.01 cm^2/s with
rho = 0.5, R = 4 I cm^2, P(0|0) = 10 I cm^2, tol 1e-6, at most 100 outer
iterations), both cases (``all measured``, E = I; ``lower measured``, 3N/2
free entries). Contenders, interleaved, ``--reps`` repetitions (>= 3):

* ``tanksynth``: ``finite_horizon_gains(...)`` with its default route, which
  also validates every input once (shapes, finiteness, symmetry, Q >= 0,
  R > 0, P(1|0) > 0), symmetrises every covariance it carries or returns and
  re-checks every returned P(k|k) > 0 (Cholesky), all inside the timing;
* ``numpy``: the same algorithm (one-step start, Pedroso and Batista's
  backward sweep of masked gains, forward Joseph-form pass, relative change of
  every ``tr P(k|k)`` below tol) written plainly here in numpy, the way a
  capable user would (about 40 lines): no validation, no symmetrisation,
  no positive-definiteness check, ``np.linalg.solve`` (LU) for the gain
  equation (tanksynth: LAPACK ``posv``, Cholesky, on the same free entries;
  ``np.linalg.solve``'s Python overhead is most of the difference at N = 16).

Both must reach the same cost (1e-9 relative). Printed: min and median per
contender, the ratio numpy / tanksynth per repetition. Floor (median ratio,
exit 1 on a miss): tanksynth at least as fast as the plain numpy iteration
(ratio >= 1) for N >= 16. The window models are built once, outside the timing.

Usage: ``python benchmarks/decentralized_numpy.py [--sizes 16 32 64] [--reps 15]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from decentralized import CASES, MAX_ITER, TOL, window  # noqa: E402
from harness import Floors, interleave, machine, ratios, summary, write_record  # noqa: E402

from tanksynth.design.decentralized import finite_horizon_gains  # noqa: E402


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


def main() -> int:
    """Run the benchmark; exit 1 on a floor miss or a cost mismatch."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 32, 64])
    ap.add_argument("--reps", type=int, default=15)
    args = ap.parse_args()
    reps = max(args.reps, 3)
    before = machine()
    floors = Floors()
    rows = []
    print(f"decentralised FH gains, window 40; {reps} interleaved reps; load {before['loadavg']}")
    for case in CASES:
        for N in args.sizes:
            seqs, E, P0 = window(N, case)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                ours = finite_horizon_gains(*seqs, E, P0, tol=TOL, max_iter=MAX_ITER)
                _, cost, iters = plain_numpy(*seqs, E, P0)
                times = interleave({
                    "tanksynth": lambda: finite_horizon_gains(*seqs, E, P0, tol=TOL, max_iter=MAX_ITER),
                    "numpy": lambda: plain_numpy(*seqs, E, P0)}, reps)
            rel = abs(ours.cost - cost) / cost
            r = ratios(times["numpy"], times["tanksynth"])
            row = {"case": case, "N": N, "times": times, "ratio_numpy_over_tanksynth": r,
                   "cost_tanksynth": ours.cost, "cost_numpy": cost, "cost_rel_diff": rel,
                   "iterations": {"tanksynth": ours.iterations, "numpy": iters}}
            rows.append(row)
            st, sn = summary(times["tanksynth"]), summary(times["numpy"])
            print(f"\n{case}, N = {N}: cost {ours.cost:.6g} vs {cost:.6g} (rel {rel:.1e}), "
                  f"iterations {ours.iterations} / {iters}")
            print(f"  tanksynth min {st['min'] * 1e3:8.1f} ms  median {st['median'] * 1e3:8.1f} ms")
            print(f"  numpy     min {sn['min'] * 1e3:8.1f} ms  median {sn['median'] * 1e3:8.1f} ms")
            print("  numpy / tanksynth per rep: " + " ".join(f"{v:.2f}" for v in r)
                  + f"   median {statistics.median(r):.2f}")
            if rel > 1e-9:
                floors.rows.append({"what": f"cost agreement {case} N={N}", "ok": False})
                print("  COSTS DISAGREE")
            if N >= 16:
                floors.check(f"{case} N={N} vs plain numpy", statistics.median(r), 1.0)
    path = write_record("decentralized_numpy", {"reps": reps, "rows": rows, "floors": floors.rows},
                        before)
    print(f"\nrecord: {path}")
    return 1 if floors.failed else 0


if __name__ == "__main__":
    sys.exit(main())
