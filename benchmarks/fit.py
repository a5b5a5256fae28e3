"""Grey-box fit side by side with what a capable user writes instead (issue 27).

DTS200 three-tank (seed 000 parameters), 4 free parameters (mu13, mu32, mu20, A), 2
experiments of N samples of 1 s (piecewise-constant pump flows, seeded noise of 2 mm on the
three levels), each with its own initial state. The same cost on every side: the weighted
simulation error ``sum (w_i (yhat - y))^2`` of the simulator's scheme (4 clipped RK4 steps
per sample, inputs held), the weights ``w_i`` those tanksynth estimated (fixed for the
others), the same starting points (the spec's start, then tanksynth's Latin hypercube).

Contenders, interleaved, ``--reps`` repetitions:

* ``tanksynth``: `tanksynth.design.fit.estimation.fit_parameters` (CasADi + IPOPT, multiple
  shooting, statistics and profile checks included);
* ``scipy_lsq``: ``scipy.optimize.least_squares`` (trust-region reflective, finite-difference
  Jacobian) on a numpy RK4 vectorised over the experiments, single shooting;
* ``casadi_ipopt``: the same RK4 written by hand in CasADi (``mapaccum``), single shooting,
  IPOPT with its exact Hessian.

Same optimum checked (parameters to 1e-4 relative, cost to 1e-6 relative). No floor: the
timings are recorded in ``benchmarks/results/fit.json``.

Then tanksynth alone with its default starts (8; the multi-start stops once 3 converged
starts agree on the best optimum), ``--default-reps`` times: the issue's budget is < 10 s.

Usage: ``python benchmarks/fit.py [--reps 3] [--samples 1000] [--starts 8] [--default-reps 5]``
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np
from scipy.optimize import least_squares
from scipy.stats import qmc

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import interleave, machine, summary, write_record  # noqa: E402

from tanksynth.design.fit.estimation import fit_parameters  # noqa: E402
from tanksynth.measurements.experiment import Experiment  # noqa: E402
from tanksynth.plants import three_tank  # noqa: E402
from tanksynth.sim.simulate import simulate_inputs  # noqa: E402

TRUE = {"mu13": 0.45, "mu32": 0.55, "mu20": 0.70, "A": 0.0154}
LOWER = np.array([0.2, 0.2, 0.2, 0.010])
UPPER = np.array([0.9, 0.9, 0.9, 0.020])
START = np.array([0.5, 0.5, 0.5, 0.015])
PHI, G, HMAX, QMAX, SUB = 5e-5, 9.81, 0.62, 1.2e-4, 4


@dataclass(frozen=True)
class Free:
    name: str
    start: float
    lower: float
    upper: float
    unit: str


def experiments(N: int) -> list[Experiment]:
    plant = three_tank()
    out = []
    for e, seed in enumerate((1, 2)):
        rng = np.random.default_rng(seed)
        U = np.repeat(rng.uniform(0.2e-4, 1.0e-4, size=(N // 40 + 1, 2)), 40, axis=0)[:N]
        run = simulate_inputs(plant, [0.3, 0.1, 0.2], U[:-1], 1.0, substeps=SUB, parameters=TRUE)
        Y = run.y[0] + 0.002 * rng.standard_normal(run.y[0].shape)
        none = np.zeros(Y.shape, dtype=bool)
        out.append(Experiment(f"e{e}", f"e{e}.csv", np.arange(N, dtype=float), U, Y, ("q1", "q2"),
                              ("h1", "h2", "h3"), none, none.copy(), ((0.0, HMAX),) * 3))
    return out


def starts(count: int, seed: int = 0) -> np.ndarray:
    pts = [(START - LOWER) / (UPPER - LOWER)]
    if count > 1:
        pts += list(qmc.LatinHypercube(d=4, seed=seed).random(count - 1))
    return LOWER + (UPPER - LOWER) * np.array(pts)


def numpy_residuals(exps: list[Experiment], w: np.ndarray):
    U = np.stack([e.u for e in exps])            # (E, N, 2)
    Y = np.stack([e.y for e in exps])            # (E, N, 3)
    U = np.clip(U, 0.0, QMAX)
    E, N = U.shape[0], U.shape[1]

    def simulate(theta: np.ndarray, X0: np.ndarray) -> np.ndarray:
        mu13, mu32, mu20, A = theta
        c13, c32, c20 = (mu * PHI * np.sqrt(2 * G) / A for mu in (mu13, mu32, mu20))

        def f(x, u):
            h1, h2, h3 = x[:, 0], x[:, 1], x[:, 2]
            d13, d32 = h1 - h3, h3 - h2
            q13 = c13 * np.sign(d13) * np.sqrt(np.abs(d13))
            q32 = c32 * np.sign(d32) * np.sqrt(np.abs(d32))
            q20 = c20 * np.sqrt(h2)
            return np.stack([u[:, 0] / A - q13, u[:, 1] / A + q32 - q20, q13 - q32], axis=1)

        x = np.clip(X0, 0.0, HMAX)
        out = np.empty((E, N, 3))
        h = 1.0 / SUB
        for k in range(N):
            out[:, k] = x
            if k == N - 1:
                break
            u = U[:, k]
            for _ in range(SUB):
                k1 = f(np.clip(x, 0, HMAX), u)
                k2 = f(np.clip(x + h / 2 * k1, 0, HMAX), u)
                k3 = f(np.clip(x + h / 2 * k2, 0, HMAX), u)
                k4 = f(np.clip(x + h * k3, 0, HMAX), u)
                x = np.clip(x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), 0, HMAX)
        return out

    def residuals(z: np.ndarray) -> np.ndarray:
        return ((simulate(z[:4], z[4:].reshape(E, 3)) - Y) * w).ravel()

    return residuals


def run_scipy(exps: list[Experiment], w: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, float]:
    fn = numpy_residuals(exps, w)
    x0 = np.concatenate([e.y[0] for e in exps])
    lo = np.r_[LOWER, np.zeros(3 * len(exps))]
    hi = np.r_[UPPER, np.full(3 * len(exps), HMAX)]
    best = None
    for p in points:
        sol = least_squares(fn, np.clip(np.r_[p, x0], lo, hi), bounds=(lo, hi), x_scale="jac",
                            xtol=1e-10, ftol=1e-10, gtol=1e-10)
        if best is None or sol.cost < best.cost:
            best = sol
    return best.x[:4], 2 * best.cost


def casadi_solver(exps: list[Experiment], w: np.ndarray):
    x, u, th = ca.SX.sym("x", 3), ca.SX.sym("u", 2), ca.SX.sym("th", 4)
    mu13, mu32, mu20, A = th[0], th[1], th[2], th[3]

    def f(s):
        d13, d32 = s[0] - s[2], s[2] - s[1]
        q13 = mu13 * PHI * ca.sign(d13) * ca.sqrt(2 * G * ca.fabs(d13))
        q32 = mu32 * PHI * ca.sign(d32) * ca.sqrt(2 * G * ca.fabs(d32))
        q20 = mu20 * PHI * ca.sqrt(2 * G * s[1])
        uc = ca.fmin(ca.fmax(u, 0), QMAX)
        return ca.vertcat(uc[0] - q13, uc[1] + q32 - q20, q13 - q32) / A

    clip = lambda v: ca.fmin(ca.fmax(v, 0), HMAX)  # noqa: E731
    s, h = x, 1.0 / SUB
    for _ in range(SUB):
        k1 = f(clip(s))
        k2 = f(clip(s + h / 2 * k1))
        k3 = f(clip(s + h / 2 * k2))
        k4 = f(clip(s + h * k3))
        s = clip(s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))
    step = ca.Function("step", [x, u, th], [s])
    z = ca.MX.sym("z", 4 + 3 * len(exps))
    cost = 0
    for e, ex in enumerate(exps):
        N = ex.samples
        acc = step.mapaccum("acc", N - 1)
        x0 = z[4 + 3 * e:7 + 3 * e]
        X = ca.horzcat(x0, acc(x0, ex.u[:-1].T, ca.repmat(z[:4], 1, N - 1)))
        cost += ca.sumsqr((X - ex.y.T) * ca.DM(w))
    solver = ca.nlpsol("hand", "ipopt", {"x": z, "f": cost},
                       {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
                        "ipopt.tol": 1e-10})
    lo = np.r_[LOWER, np.zeros(3 * len(exps))]
    hi = np.r_[UPPER, np.full(3 * len(exps), HMAX)]
    return solver, lo, hi


def run_casadi(exps: list[Experiment], w: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, float]:
    solver, lo, hi = casadi_solver(exps, w)
    x0 = np.concatenate([e.y[0] for e in exps])
    best = None
    for p in points:
        sol = solver(x0=np.clip(np.r_[p, x0], lo, hi), lbx=lo, ubx=hi)
        if best is None or float(sol["f"]) < float(best["f"]):
            best = sol
    return np.asarray(best["x"]).ravel()[:4], float(best["f"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--default-reps", type=int, default=5,
                    help="repetitions of tanksynth alone with its default starts (8, early stop)")
    args = ap.parse_args()
    before = machine()
    exps = experiments(args.samples)
    free = [Free(nm, float(v), float(lo), float(hi), u) for nm, v, lo, hi, u in
            zip(("mu13", "mu32", "mu20", "A"), START, LOWER, UPPER, ("1", "1", "1", "m^2"))]
    plant = three_tank()
    ref = fit_parameters(plant, free, exps, starts=args.starts)
    w = np.array([ref.weights[nm] for nm in ("h1", "h2", "h3")])
    points = starts(args.starts)
    results: dict[str, tuple[np.ndarray, float]] = {}

    def tank() -> None:
        r = fit_parameters(plant, free, exps, starts=args.starts)
        results["tanksynth"] = (r.values, r.cost)

    def sci() -> None:
        results["scipy_lsq"] = run_scipy(exps, w, points)

    def cas() -> None:
        results["casadi_ipopt"] = run_casadi(exps, w, points)

    times = interleave({"tanksynth": tank, "scipy_lsq": sci, "casadi_ipopt": cas}, reps=args.reps)
    rows = {}
    for name, ts in times.items():
        values, cost = results[name]
        same = bool(np.allclose(values, ref.values, rtol=1e-4) and abs(cost - ref.cost) <= 1e-6 * ref.cost)
        rows[name] = {**summary(ts), "times": ts, "values": values.tolist(), "cost": cost,
                      "same_optimum": same}
        print(f"{name:14s} min {min(ts):8.2f} s  median {summary(ts)['median']:8.2f} s  "
              f"cost {cost:.6f}  same optimum: {same}")
    # the budget: 4 parameters, 2 x N samples, the default starts (8, the multi-start
    # stops once 3 converged starts agree), < 10 s
    default_times, tried = [], []
    for _ in range(args.default_reps):
        t0 = time.perf_counter()
        r = fit_parameters(plant, free, exps)
        default_times.append(time.perf_counter() - t0)
        tried.append(r.starts_tried)
    default = {**summary(default_times), "times": default_times, "starts_tried": tried,
               "starts_agreeing": r.starts_agreeing, "budget_s": 10.0,
               "same_optimum": bool(np.allclose(r.values, ref.values, rtol=1e-4))}
    print(f"{'default starts':14s} min {min(default_times):8.2f} s  median "
          f"{summary(default_times)['median']:8.2f} s  starts tried {tried}")
    path = write_record("fit", {"samples": args.samples, "experiments": len(exps),
                                "starts": args.starts, "parameters": list(TRUE), "rows": rows,
                                "default_starts": default,
                                "converged": ref.converged, "status": ref.status}, before)
    print(f"wrote {path}")
    return 0 if all(r["same_optimum"] for r in rows.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
