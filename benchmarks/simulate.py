"""Batch closed-loop simulator vs a per-run scipy solve_ivp loop (what a user writes).

Closed loop: DTS200 three-tank (seed 000) + the seed 000 tracking controller
with integral action (printed gains), true state fed back, dynamic step
references, process and measurement noise, pump saturation. M runs x N
samples. The solve_ivp loop integrates each sampling period of each run with
RK45 (rtol 1e-6, atol 1e-9) on a hand-written numpy right-hand side; it is
timed on a subset of runs and extrapolated. Both are checked against a tight
(rtol 1e-12) solve_ivp run, so the comparison is at (at least) the same
accuracy.

Usage: ``python benchmarks/simulate.py [--runs M] [--steps N] [--baseline-runs K]``
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.integrate import solve_ivp

from tanksynth.analysis.linearize import equilibrium_input
from tanksynth.plants import three_tank
from tanksynth.verify.campaign import IntegralStateFeedback
from tanksynth.sim.scenarios import scenario
from tanksynth.sim.simulate import run_seeds, simulate

K = 1e-4 * np.array([[21.6, 3.0, -5.0, -0.95, -0.32], [2.9, 19.0, -4.0, -0.30, -0.91]])  # seed 000
X0 = np.array([0.40, 0.20, 0.30])
PROCESS, MEASURE = 1e-5, 1e-4


def _law(u0):
    C1 = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    return IntegralStateFeedback(K[:, :3], K[:, 3:], C1, X0, u0, 1.0)


def _user_loop(plant, ref, u0, steps, seed, rtol=1e-6, atol=1e-9, noise=True):
    """One run as a user writes it: a solve_ivp call per sampling period."""
    p = {q.name: q.value for q in plant.parameters}
    A, Phi, g = p["A"], p["Phi"], p["g"]
    c13, c32, c20 = p["mu13"] * Phi, p["mu32"] * Phi, p["mu20"] * Phi

    def rhs(t, h, q1, q2):
        h1, h2, h3 = max(h[0], 0.0), max(h[1], 0.0), max(h[2], 0.0)
        q13 = c13 * math.copysign(math.sqrt(2 * g * abs(h1 - h3)), h1 - h3)
        q32 = c32 * math.copysign(math.sqrt(2 * g * abs(h3 - h2)), h3 - h2)
        q20 = c20 * math.sqrt(2 * g * h2)
        return [(q1 - q13) / A, (q2 + q32 - q20) / A, (q13 - q32) / A]

    rng = np.random.default_rng(seed)
    w = rng.standard_normal((steps, 3)) * (PROCESS if noise else 0.0)
    law = _law(u0)
    law.reset(1)
    x = X0.copy()
    xs = [x]
    for k in range(steps):
        u = np.clip(law(x[None], ref[k][None], float(k))[0], 0.0, p["qmax"])
        x = solve_ivp(rhs, (k, k + 1), x, args=tuple(u), rtol=rtol, atol=atol).y[:, -1]
        x = np.clip(x + w[k], 0.0, p["hmax"])
        xs.append(x)
    return np.array(xs)


def main() -> None:
    """Run the benchmark and print throughputs and the ratio."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--baseline-runs", type=int, default=10)
    ap.add_argument("--substeps", type=int, default=2)
    args = ap.parse_args()
    plant = three_tank()
    u0 = equilibrium_input(plant, X0).u0
    setup = scenario("dynamic_steps").setup(plant, X0, u0, (0, 1))
    ref = setup.reference
    if args.steps + 1 > ref.shape[0]:
        ref = np.vstack([ref, np.tile(ref[-1], (args.steps + 1 - ref.shape[0], 1))])
    ref = ref[: args.steps + 1]

    # Accuracy on one noise-free run against a tight (rtol 1e-12) loop.
    tight = _user_loop(plant, ref, u0, 300, 0, rtol=1e-12, atol=1e-14, noise=False)
    user = _user_loop(plant, ref, u0, 300, 0, noise=False)
    ours = simulate(plant, ts=1.0, steps=300, x0=X0, seeds=[0], controller=_law(u0), reference=ref[:301],
                    u_init=u0, substeps=args.substeps)
    err_user = float(np.max(np.abs(user - tight)))
    err_ours = float(np.max(np.abs(ours.x[0] - tight)))

    seeds = run_seeds(0, args.runs)
    simulate(plant, ts=1.0, steps=5, x0=X0, seeds=seeds[:2], u_init=u0)   # compile outside the timing
    t0 = time.perf_counter()
    res = simulate(plant, ts=1.0, steps=args.steps, x0=X0, seeds=seeds, controller=_law(u0),
                   reference=ref, u_init=u0, process_std=PROCESS, measurement_std=MEASURE,
                   substeps=args.substeps)
    t_batch = time.perf_counter() - t0
    assert np.all(np.isfinite(res.x))
    t0 = time.perf_counter()
    for r in range(args.baseline_runs):
        _user_loop(plant, ref, u0, args.steps, int(seeds[r]))
    t_user = (time.perf_counter() - t0) / args.baseline_runs * args.runs

    rate_b = args.runs * args.steps / t_batch
    rate_u = args.runs * args.steps / t_user
    print(f"closed loop: three_tank + seed 000 integral tracking, {args.runs} runs x {args.steps} samples")
    print(f"max level error vs RK45 at rtol 1e-12, 300 s: batch RK4 x{args.substeps} {err_ours:.2e} m, "
          f"solve_ivp RK45 (rtol 1e-6) {err_user:.2e} m")
    print(f"batch simulator      : {t_batch:8.2f} s   {rate_b:12.0f} run-steps/s")
    print(f"solve_ivp per run    : {t_user:8.2f} s   {rate_u:12.0f} run-steps/s "
          f"(timed on {args.baseline_runs} runs, extrapolated)")
    print(f"ratio                : {t_user / t_batch:8.1f}x")


if __name__ == "__main__":
    main()
