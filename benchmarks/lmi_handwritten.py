"""Observer LMI: tanksynth vs the same LMI hand-written in cvxpy (issue 15).

Seed 001 eq. (28), variant ``Q = q I``, psi = 1e-3 1/s, on the TS model of
``tank_network(N)`` (default weights, box [1, 40] cm, interval premise bounds,
``C = I``), two structures:

* dense: full ``P``, free ``K`` (tanksynth eliminates ``K``; with ``C = I``
  no cone is left for ``P``);
* structured: diagonal ``P``, diagonal gain (each tank filters its own level).

Contenders, interleaved, ``--reps`` (>= 3), each from scratch (problem
built, compiled, solved by Clarabel, gain recovered):

* ``tanksynth``: `observer_lmi(A0, C, psi, ...)`: input checks, observability
  (known without an SVD when ``C`` selects every state), time and output
  scaling, the solve (dense: ``K`` eliminated, cvxpy; structured: the full
  form built directly as Clarabel conic data, no cvxpy compilation), and the
  library's independent numpy re-check of the returned gain (eigenvalues of
  the ``2n x 2n`` block matrix twice, ``P``, ``Q``, ``A0 - L C``, cond P),
  all inside the timing;
* ``cvxpy``: a capable user's formulation: ``P`` (``cp.diag(p)``, ``p >= 1``
  when structured), ``K``, ``q``, ``t``; ``[[A0'P + P A0 - C'K' - K C +
  psi^2 q I, P], [P, -q I]] << -t I``, ``P >> I`` (dense), ``trace P <= kappa
  n``, ``t <= 1``, maximise ``t``; ``L = P^-1 K``. It checks nothing inside
  the timing (no re-check, no scaling): the library does more work.

Both gains are re-checked here with numpy (eq. 28 negative definite, A0 - L C
Hurwitz). Floors (median of per-rep ratios cvxpy / tanksynth; exit 1 on a
miss): >= 1 for every N and structure; >= 20 for dense N = 32.

Usage: ``python benchmarks/lmi_handwritten.py [--dense 8 16 32] [--structured 8 16 32 64] [--reps 5]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import Floors, interleave, machine, ratios, summary, write_record  # noqa: E402
from lmi import PSI, ts_network  # noqa: E402

from tanksynth.design.observer_lmi.lmi import observer_lmi  # noqa: E402

KAPPA = 1e4


def handwritten(A0: np.ndarray, C: np.ndarray, psi: float, structured: bool) -> np.ndarray:
    """The LMI as a user writes it in cvxpy; returns L."""
    import cvxpy as cp

    n, q = C.shape[1], C.shape[0]
    I = np.eye(n)
    if structured:
        p = cp.Variable(n)
        P = cp.diag(p)
        k = cp.Variable(n)
        K = cp.diag(k) @ C.T if q == n else cp.diag(k)[:, :q]
        cons = [p >= 1]
    else:
        P = cp.Variable((n, n), symmetric=True)
        K = cp.Variable((n, q))
        cons = [P >> I]
    qv, t = cp.Variable(), cp.Variable()
    X = A0.T @ P + P @ A0 - C.T @ K.T - K @ C + psi ** 2 * qv * I
    M = cp.bmat([[X, P], [P, -qv * I]])
    cons += [0.5 * (M + M.T) << -t * np.eye(2 * n), cp.trace(P) <= KAPPA * n, t <= 1]
    cp.Problem(cp.Maximize(t), cons).solve(solver="CLARABEL")
    return np.linalg.solve(np.asarray(P.value), np.asarray(K.value))


def recheck(A0: np.ndarray, C: np.ndarray, L: np.ndarray) -> bool:
    """A0 - L C Hurwitz (the property the LMI certifies at the linear part)."""
    return bool(np.max(np.linalg.eigvals(A0 - L @ C).real) < 0)


def main() -> int:
    """Run the benchmark; exit 1 on a floor miss or a failed re-check."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dense", type=int, nargs="*", default=[8, 16, 32])
    ap.add_argument("--structured", type=int, nargs="*", default=[8, 16, 32, 64])
    ap.add_argument("--reps", type=int, default=5)
    args = ap.parse_args()
    reps = max(args.reps, 3)
    before = machine()
    floors = Floors()
    rows = []
    print(f"observer LMI (28), qI, psi = {PSI}; {reps} interleaved reps; load {before['loadavg']}")
    for structure, sizes in (("dense", args.dense), ("structured", args.structured)):
        for N in sizes:
            ts = ts_network(N)
            A0, C = ts["A0"], ts["C"]
            kw = {} if structure == "dense" else {"blocks": [[i] for i in range(N)],
                                                  "pattern": (C.T != 0).astype(float)}
            structured = structure == "structured"
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ours = observer_lmi(A0, C, PSI, **kw)
                L_hand = handwritten(A0, C, PSI, structured)
                times = interleave({"tanksynth": lambda: observer_lmi(A0, C, PSI, **kw),
                                    "cvxpy": lambda: handwritten(A0, C, PSI, structured)}, reps)
            ok = recheck(A0, C, np.asarray(ours.L)) and recheck(A0, C, L_hand)
            r = ratios(times["cvxpy"], times["tanksynth"])
            st, sc = summary(times["tanksynth"]), summary(times["cvxpy"])
            print(f"\n{structure} N = {N}: re-check {'ok' if ok else 'FAILED'}")
            print(f"  tanksynth min {st['min']:8.3f} s  median {st['median']:8.3f} s")
            print(f"  cvxpy     min {sc['min']:8.3f} s  median {sc['median']:8.3f} s")
            print("  cvxpy / tanksynth per rep: " + " ".join(f"{v:.2f}" for v in r)
                  + f"   median {statistics.median(r):.2f}")
            rows.append({"structure": structure, "N": N, "times": times, "ratios": r, "recheck": ok})
            if not ok:
                floors.rows.append({"what": f"re-check {structure} N={N}", "ok": False})
            floors.check(f"{structure} N={N} vs hand-written cvxpy", statistics.median(r), 1.0)
            if structure == "dense" and N == 32:
                floors.check("dense N=32 >= 20x hand-written cvxpy", statistics.median(r), 20.0)
    path = write_record("lmi_handwritten", {"reps": reps, "rows": rows, "floors": floors.rows},
                        before)
    print(f"\nrecord: {path}")
    return 1 if floors.failed else 0


if __name__ == "__main__":
    sys.exit(main())
