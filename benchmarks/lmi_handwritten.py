"""Observer LMI: tanksynth vs the same LMI hand-written in cvxpy (issue 15).

Seed 001 eq. (28), variant ``Q = q I``, psi = 1e-3 1/s, on the TS model of
``tank_network(N)`` (default weights, box [1, 40] cm, interval premise bounds,
two output maps (``all``: every level measured, ``C = I``; ``half``: the N/2 lower
levels measured, ``C`` their rows of ``I``), two structures:

* dense: full ``P``, free ``K``. Both sides eliminate ``K`` by the projection lemma
  (issue 29: the same problem on both sides): the LMI in ``P``, ``q`` of size
  ``2n - rank C``, ``[[V2' X V2, V2' P], [P V2, -q I]] << -t I`` with ``V2`` the
  unmeasured directions and ``X = A0'P + P A0 + psi^2 q I``, then the gain in closed
  form for ``t_K = t - (t - margin) / 10``: ``G = (V2 V2' + V1 V1' / 2) Y V1 + t_K V1``,
  ``Y = X + P (q - t_K)^-1 P``, ``K = G pinv(C V1)``, ``L = P^-1 K``. With every level
  measured no LMI is left (``V2`` empty: ``q >= t``, ``t <= 1``): the hand-written side
  writes the gain in closed form with ``P = I``, ``q = 1``, no solver (a user with every
  level measured does just that), tanksynth still builds and solves its (trivial) problem;
* structured: diagonal ``P``, diagonal gain (each measured tank filters its own level);
  no elimination possible (a gain pattern), both sides solve the full ``2n x 2n`` LMI.

Contenders, interleaved, ``--reps`` (>= 3), each from scratch (problem
built, compiled, solved by Clarabel, gain recovered):

* ``tanksynth``: `observer_lmi(A0, C, psi, ...)`: input checks, observability
  (known without an SVD when ``C`` selects every state), time and output
  scaling, the solve (dense: ``K`` eliminated, cvxpy; structured: the full
  form built directly as Clarabel conic data, no cvxpy compilation), and the
  library's independent numpy re-check of the returned gain (eigenvalues of
  the ``2n x 2n`` block matrix twice, ``P``, ``Q``, ``A0 - L C``, cond P),
  all inside the timing;
* ``cvxpy``: a capable user's formulation. Structured: ``P = cp.diag(p)``,
  ``p >= 1``, ``K`` diagonal on the measured tanks, ``q``, ``t``; ``[[A0'P + P A0 -
  C'K' - K C + psi^2 q I, P], [P, -q I]] << -t I``, ``trace P <= kappa n``, ``t <= 1``,
  maximise ``t``; ``L = P^-1 K``. Dense: the eliminated form above (cvxpy for the LMI
  when one is left, numpy for the gain). It checks nothing inside the timing (no
  re-check, no scaling): the library does more work.

Both gains are re-checked here with numpy (A0 - L C Hurwitz). Floors (median of
per-rep ratios cvxpy / tanksynth; exit 1 on a miss): >= 1 for every N, structure and
output map. (The former floor ">= 20 for dense N = 32" compared the eliminated problem
with the hand-written full 2N x 2N LMI: not the same problem, dropped.)

Usage: ``python benchmarks/lmi_handwritten.py [--dense 8 16 32] [--structured 8 16 32 64]
[--measured all half] [--reps 5]``
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


def handwritten_eliminated(A0: np.ndarray, C: np.ndarray, psi: float,
                           margin: float = 1e-6) -> np.ndarray:
    """Dense LMI with ``K`` eliminated (projection lemma), the gain in closed form; returns L.

    ``C`` selects states (rows of the identity): ``V1`` the measured columns of ``I``,
    ``V2`` the others. Every level measured: no LMI is left, ``P = I``, ``q = t = 1``.
    """
    import cvxpy as cp

    n = A0.shape[0]
    I = np.eye(n)
    meas = [int(np.argmax(row)) for row in C]
    V1 = I[:, meas]
    V2 = I[:, [j for j in range(n) if j not in set(meas)]]
    if V2.shape[1] == 0:
        P, q, t = I, 1.0, 1.0
    else:
        Pv = cp.Variable((n, n), symmetric=True)
        qv, tv = cp.Variable(), cp.Variable()
        X = A0.T @ Pv + Pv @ A0 + psi ** 2 * qv * I
        Mx = cp.bmat([[V2.T @ X @ V2, V2.T @ Pv], [Pv @ V2, -qv * I]])
        cons = [0.5 * (Mx + Mx.T) << -tv * np.eye(Mx.shape[0]), Pv >> I,
                cp.trace(Pv) <= KAPPA * n, tv <= 1]
        cp.Problem(cp.Maximize(tv), cons).solve(solver="CLARABEL")
        P, q, t = np.asarray(Pv.value), float(qv.value), float(tv.value)
    tK = min(1.0, t - 0.1 * (t - margin))
    Y = A0.T @ P + P @ A0 + psi ** 2 * q * I + P @ P / (q - tK)
    G = (V2 @ V2.T + 0.5 * V1 @ V1.T) @ Y @ V1 + tK * V1
    K = G @ np.linalg.pinv(C @ V1)
    return np.linalg.solve(P, K)


def recheck(A0: np.ndarray, C: np.ndarray, L: np.ndarray) -> bool:
    """A0 - L C Hurwitz (the property the LMI certifies at the linear part)."""
    return bool(np.max(np.linalg.eigvals(A0 - L @ C).real) < 0)


def main() -> int:
    """Run the benchmark; exit 1 on a floor miss or a failed re-check."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dense", type=int, nargs="*", default=[8, 16, 32])
    ap.add_argument("--structured", type=int, nargs="*", default=[8, 16, 32, 64])
    ap.add_argument("--measured", nargs="+", choices=("all", "half"), default=["all", "half"])
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--strict", action="store_true",
                    help="exit 1 also on a miss against the closed-form gain (dense, all measured)")
    args = ap.parse_args()
    reps = max(args.reps, 3)
    before = machine()
    floors = Floors()
    rows = []
    print(f"observer LMI (28), qI, psi = {PSI}; {reps} interleaved reps; load {before['loadavg']}")
    for measured in args.measured:
        for structure, sizes in (("dense", args.dense), ("structured", args.structured)):
            for N in sizes:
                ts = ts_network(N)
                A0, C = ts["A0"], ts["C"]
                if measured == "half":
                    C = C[: N // 2]
                kw = {} if structure == "dense" else {"blocks": [[i] for i in range(N)],
                                                      "pattern": (C.T != 0).astype(float)}
                structured = structure == "structured"

                def hand(A0=A0, C=C, structured=structured):
                    return (handwritten(A0, C, PSI, True) if structured
                            else handwritten_eliminated(A0, C, PSI))

                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    ours = observer_lmi(A0, C, PSI, **kw)
                    L_hand = hand()
                    times = interleave({"tanksynth": lambda: observer_lmi(A0, C, PSI, **kw),
                                        "cvxpy": hand}, reps)
                ok = recheck(A0, C, np.asarray(ours.L)) and recheck(A0, C, L_hand)
                r = ratios(times["cvxpy"], times["tanksynth"])
                st, sc = summary(times["tanksynth"]), summary(times["cvxpy"])
                what = f"{structure} N={N} {measured} measured"
                print(f"\n{what}: form {ours.structure.get('form', '?')}; re-check "
                      f"{'ok' if ok else 'FAILED'}")
                print(f"  tanksynth min {st['min']:8.4f} s  median {st['median']:8.4f} s")
                print(f"  cvxpy     min {sc['min']:8.4f} s  median {sc['median']:8.4f} s")
                print("  cvxpy / tanksynth per rep: " + " ".join(f"{v:.2f}" for v in r)
                      + f"   median {statistics.median(r):.2f}")
                rows.append({"structure": structure, "measured": measured, "N": N,
                             "form": ours.structure.get("form"), "times": times, "ratios": r,
                             "recheck": ok})
                if not ok:
                    floors.rows.append({"what": f"re-check {what}", "ok": False})
                # issue 29's new comparison (closed-form gain, no solver): exit 1 only with --strict
                floors.check(f"{what} vs hand-written", statistics.median(r), 1.0,
                             strict_only=structure == "dense" and measured == "all")
    path = write_record("lmi_handwritten", {"reps": reps, "rows": rows, "floors": floors.rows},
                        before)
    print(f"\nrecord: {path}")
    return floors.exit_status(args.strict)


if __name__ == "__main__":
    sys.exit(main())
