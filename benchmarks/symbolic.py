"""Symbolic pipeline on the N-tank network: tanksynth vs a fair plain-sympy route.

Issue 15 (replaces issue 2's "naive" comparison, which redid ``lambdify`` at every
point and built every Lie derivative). For ``tank_network(N, parameter_set="decenter")``
and two output maps -- ``all measured`` (y = h, the decenter set) and ``lower measured``
(y = the N/2 lower levels, so the rank test needs the first Lie derivative too) -- both
contenders do the same work on the same points:

linearise
    tanksynth: ``equilibrium_input`` at 10 cm in every tank + ``linearize(ts=1)`` (this
    compiles the plant to CasADi on first use). plain: ``xreplace`` of the parameter values,
    ``Matrix.jacobian``, ``lambdify`` of f and of the Jacobian ONCE, least-squares u0,
    ``scipy.linalg.expm`` of the ZOH block.
jacobians
    the Jacobians [df/dx, df/du] at 200 region points. tanksynth: ``plant.compiled.jacobians``;
    plain: the Jacobian lambdified above, called at each point.
obs-rank
    rank of d(L_f^k h) at 200 points, stopping at the first order with full rank everywhere
    (the same early stop on both sides; rows scaled to unit norm, rank = singular values above
    1e-9 s_max). tanksynth: ``nonlinear_observability(plant, points)``; plain: ``L.jacobian``
    per order, ``lambdify`` of each new block once, numpy SVD.

Every repetition starts cold on both sides: a fresh plant object and ``sympy``'s cache
cleared before each contender. Contenders are interleaved (tanksynth, plain, tanksynth,
plain, ...), ``--reps`` >= 3 times. Both routes must agree: u0, F, B, Ad, Bd and the
Jacobians at the 200 points to 1e-9 relative, the rank at every point and the order.
Printed: min and median per contender, the ratio plain / tanksynth per repetition.
Floor (median ratio, exit 1 on a miss): tanksynth at least as fast as the plain route
(>= 1) for every N >= 8 and both output maps. JSON record: ``benchmarks/results/symbolic.json``.

Usage::

    .venv/bin/python benchmarks/symbolic.py                     # N = 4 .. 64, 3 reps
    .venv/bin/python benchmarks/symbolic.py --sizes 8 16 --reps 5
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
from pathlib import Path
from time import perf_counter

import numpy as np
import sympy as sp
from scipy.linalg import expm
from sympy.core.cache import clear_cache

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import Floors, machine, ratios, summary, write_record  # noqa: E402

from tanksynth.analysis.linearize import equilibrium_input, linearize  # noqa: E402
from tanksynth.analysis.rank import nonlinear_observability  # noqa: E402
from tanksynth.plants.tank_network import tank_network  # noqa: E402

SIZES = (4, 8, 16, 32, 64)
CASES = ("all measured", "lower measured")
POINTS = 200                 # region points for the Jacobians and the rank test
LEVEL = 10.0                 # cm, operating level in every tank
TS = 1.0                     # s, ZOH sampling period
RTOL_RANK = 1e-9             # singular values below RTOL_RANK * s_max count as zero
AGREE = 1e-9                 # relative agreement of every number
FLOOR = 1.0                  # median ratio plain / tanksynth, every N >= FLOOR_FROM
FLOOR_FROM = 8
STAGES = ("linearise", "jacobians", "obs-rank")


def make_plant(N: int, case: str):
    """A fresh ``tank_network(N)``; ``lower measured``: y = h1..h_{N/2}."""
    plant = tank_network(N, parameter_set="decenter")
    if case == "lower measured":
        half = N // 2
        plant = dataclasses.replace(plant, h=plant.h[:half, :], outputs=plant.outputs[:half])
    return plant


def points_and_input(plant):
    """The 200 region points ``nonlinear_observability`` samples by default and the mid input."""
    X = plant.region.sample(POINTS, plant.x, seed=0, margin=0.01)
    u_mid = np.array([0.5 * (lo + hi) for lo, hi in plant.input_limits])
    return X, u_mid


# --------------------------------------------------------------------- contenders
def tanksynth_route(plant, X, u_mid) -> tuple[dict, dict]:
    """Stage times (s) and results of tanksynth on a fresh plant."""
    t, out = {}, {}
    U = np.repeat(u_mid[None], len(X), axis=0)
    x0 = np.full(plant.n, LEVEL)
    t0 = perf_counter()
    eq = equilibrium_input(plant, x0)
    lin = linearize(plant, x0, eq.u0, ts=TS)
    t1 = perf_counter()
    Jx, Ju = plant.compiled.jacobians(X, U)
    t2 = perf_counter()
    obs = nonlinear_observability(plant, points=X, u=u_mid, rtol=RTOL_RANK)
    t3 = perf_counter()
    t = {"linearise": t1 - t0, "jacobians": t2 - t1, "obs-rank": t3 - t2}
    out = {"u0": eq.u0, "F": lin.F, "B": lin.B, "Ad": lin.Ad, "Bd": lin.Bd,
           "J": np.concatenate([Jx, Ju], axis=2), "ranks": obs.ranks, "orders": obs.orders}
    return t, out


def plain_route(plant, X, u_mid) -> tuple[dict, dict]:
    """The same work in plain sympy + numpy, as a capable user writes it."""
    xs, us = list(plant.x), list(plant.u)
    n, m = len(xs), len(us)
    values = dict(plant.parameter_values)                      # symbol -> exact number
    t0 = perf_counter()
    f = plant.f.xreplace(values)
    h = plant.h.xreplace(values)
    J = f.jacobian(xs + us)                                     # n x (n + m)
    f_fn = sp.lambdify([xs, us], f, "numpy")
    J_fn = sp.lambdify([xs, us], J, "numpy")                    # once
    x0 = np.full(n, LEVEL)
    f0 = np.asarray(f_fn(x0, np.zeros(m)), dtype=float).reshape(n)
    G = np.asarray(J_fn(x0, np.zeros(m)), dtype=float)[:, n:]
    u0, *_ = np.linalg.lstsq(G, -f0, rcond=None)                # f is affine in u: exact
    J0 = np.asarray(J_fn(x0, u0), dtype=float)
    F, B = J0[:, :n], J0[:, n:]
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = F, B
    E = expm(block * TS)
    t1 = perf_counter()
    U = np.repeat(u_mid[None], len(X), axis=0)
    Js = np.array([J_fn(x, u) for x, u in zip(X, U)], dtype=float)
    t2 = perf_counter()
    fd = f.xreplace(dict(zip(us, (sp.Float(v) for v in u_mid))))
    L, blocks = h, []
    for order in range(1, n + 1):
        grad = L.jacobian(xs)
        g_fn = sp.lambdify([xs], grad, "numpy")                # once per new block
        blocks.append(np.array([g_fn(x) for x in X], dtype=float))
        D = np.concatenate(blocks, axis=1)                      # (M, rows, n)
        norms = np.linalg.norm(D, axis=2, keepdims=True)
        D = np.divide(D, norms, out=np.zeros_like(D), where=norms > 0)
        s = np.linalg.svd(D, compute_uv=False)
        ranks = np.sum(s > RTOL_RANK * s[:, :1], axis=1)
        if np.all(ranks == n):
            break
        L = grad * fd
    t3 = perf_counter()
    t = {"linearise": t1 - t0, "jacobians": t2 - t1, "obs-rank": t3 - t2}
    out = {"u0": u0, "F": F, "B": B, "Ad": E[:n, :n], "Bd": E[:n, n:], "J": Js,
           "ranks": ranks, "orders": order}
    return t, out


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b))) / max(float(np.max(np.abs(b))), np.finfo(float).tiny)


def agreement(ours: dict, plain: dict) -> tuple[float, bool]:
    """Largest relative difference of the numbers; equal ranks and orders."""
    worst = max(_rel(plain[k], ours[k]) for k in ("u0", "F", "B", "Ad", "Bd", "J"))
    same = bool(np.array_equal(plain["ranks"], ours["ranks"])) and plain["orders"] == ours["orders"]
    return worst, same


# ----------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; exit 1 on a floor miss or a disagreement."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args(argv)
    reps = max(args.reps, 3)
    before = machine()
    floors = Floors()
    rows = []
    print(f"symbolic pipeline on tank_network (decenter), {POINTS} points, {reps} interleaved "
          f"reps, cold each rep; load {before['loadavg']}")
    for case in CASES:
        for N in args.sizes:
            X, u_mid = points_and_input(make_plant(N, case))
            times = {"tanksynth": [], "plain": []}
            stages = {"tanksynth": {s: [] for s in STAGES}, "plain": {s: [] for s in STAGES}}
            worst, same, orders = 0.0, True, None
            for _ in range(reps):
                results = {}
                for name, route in (("tanksynth", tanksynth_route), ("plain", plain_route)):
                    plant = make_plant(N, case)          # fresh: no compiled functions cached
                    clear_cache()                        # sympy's global cache, cold for both
                    st, results[name] = route(plant, X, u_mid)
                    times[name].append(sum(st.values()))
                    for s in STAGES:
                        stages[name][s].append(st[s])
                w, s_ok = agreement(results["tanksynth"], results["plain"])
                worst, same = max(worst, w), same and s_ok
                orders = results["tanksynth"]["orders"]
            r = ratios(times["plain"], times["tanksynth"])
            med = statistics.median(r)
            row = {"case": case, "N": N, "times": times, "stages": stages,
                   "ratio_plain_over_tanksynth": r, "max_rel_diff": worst, "ranks_equal": same,
                   "orders": orders}
            rows.append(row)
            print(f"\n{case}, N = {N}: orders {orders}, max rel. diff {worst:.1e}, "
                  f"ranks {'equal' if same else 'DIFFER'}")
            for name in ("tanksynth", "plain"):
                sm = summary(times[name])
                split = "  ".join(f"{s} {statistics.median(stages[name][s]) * 1e3:7.1f}"
                                  for s in STAGES)
                print(f"  {name:9s} min {sm['min'] * 1e3:8.1f} ms  median {sm['median'] * 1e3:8.1f} ms"
                      f"   (median ms: {split})")
            print("  plain / tanksynth per rep: " + " ".join(f"{v:.2f}" for v in r)
                  + f"   median {med:.2f}")
            if worst > AGREE or not same:
                floors.rows.append({"what": f"agreement {case} N={N}", "ok": False})
                print("  ROUTES DISAGREE")
            if N >= FLOOR_FROM:
                floors.check(f"{case} N={N} vs plain sympy", med, FLOOR)
    path = write_record("symbolic", {"reps": reps, "points": POINTS, "rows": rows,
                                     "floors": floors.rows}, before)
    print(f"\nrecord: {path}")
    return 1 if floors.failed else 0


if __name__ == "__main__":
    sys.exit(main())
