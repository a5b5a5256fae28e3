"""Probe (issue 29, item 2): EKF/UKF per step, one-step path vs horizon kernel, single run and batch.

Not a benchmark with floors (``benchmarks/estimators.py`` is); a before/after measurement of
`KernelEstimator.run` with ``TANKSYNTH_ESTIMATOR_BACKEND=step`` (one native kernel call per
sample from Python, the path before horizon kernels) and ``auto`` (the horizon kernel:
256-sample chunks in one native call, mapped over the runs). Estimators: seed 002's EKF and
UKF on the hybrid three-tank (``examples/seed002_estimators.toml``: Q = 1e-7 I, R = 1e-6,
P0 = 1e-2 I, h3 measured, ts = 1 s) and the three-tank EKF of ``benchmarks/estimators.py``
(every level measured). Measurements: one run of the plant under random pump flows plus 1 mm noise (own noise per run).
Interleaved reps, min and median; agreement of the two paths printed (max |difference|, m).

Usage::

    .venv/bin/python benchmarks/estimator_kernel_probe.py [--steps 2000] [--runs 200] [--reps 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from tanksynth.plants import hybrid_three_tank, three_tank
from tanksynth.runtime.estimators import (ExtendedKalmanFilter, KalmanTuning, UKFTuning,
                                         UnscentedKalmanFilter)
from tanksynth.sim.simulate import simulate_inputs

LPH = 1e-3 / 3600.0


def data(plant, steps: int, runs: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """One simulated run under random pump flows; every run gets its own 1 mm sensor noise."""
    rng = np.random.default_rng(seed)
    U = (60 + 60 * rng.random((steps, plant.m))) * LPH
    res = simulate_inputs(plant, [0.3, 0.3, 0.3], U, 1.0, substeps=2)
    Y = res.y[0, 1:][:, None, :] + 1e-3 * rng.standard_normal((steps, runs, plant.q))
    return np.ascontiguousarray(Y), np.ascontiguousarray(np.broadcast_to(U[:, None], (steps, runs, plant.m)))


def timed(est, Y, U, mode: str) -> tuple[float, np.ndarray]:
    os.environ["TANKSYNTH_ESTIMATOR_BACKEND"] = mode
    est.reset()
    t0 = time.perf_counter()
    X = est.run(Y, U)
    return time.perf_counter() - t0, X


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args()
    hyb, tank = hybrid_three_tank(), three_tank("all")
    seed002 = dict(Q=1e-7 * np.eye(3), R=[[1e-6]], P0=1e-2 * np.eye(3), x0=[0.2] * 3, ts=1.0)
    cases = [
        ("seed002 EKF (hybrid, h3)", ExtendedKalmanFilter(hyb, KalmanTuning(**seed002)), hyb),
        ("seed002 UKF (hybrid, h3)", UnscentedKalmanFilter(hyb, UKFTuning(**seed002, alpha=1e-3)),
         hyb),
        ("three-tank EKF (all levels)", ExtendedKalmanFilter(tank, KalmanTuning(
            Q=1e-9 * np.eye(3), R=1e-6 * np.eye(3), P0=1e-3 * np.eye(3), x0=[0.25, 0.15, 0.2],
            ts=1.0)), tank),
    ]
    N = args.steps
    print(f"steps {N}, batch M = {args.runs}, {args.reps} interleaved reps; load "
          f"{os.getloadavg()[0]:.1f}; us per step (batch: per step of all M runs)")
    for label, est, plant in cases:
        for M in (None, args.runs):
            Y, U = data(plant, N, 1 if M is None else M)
            e = est if M is None else est.batch(M)
            if M is None:
                Y, U = Y[:, 0], U[:, 0]
            timed(e, Y, U, "horizon")              # build / load the horizon kernel once
            t = {"step": [], "auto": []}
            X = {}
            for _ in range(args.reps):
                for mode in ("step", "auto"):
                    dt, X[mode] = timed(e, Y, U, mode)
                    t[mode].append(dt / N * 1e6)
            diff = float(np.abs(X["auto"] - X["step"]).max())
            s, h = t["step"], t["auto"]
            print(f"{label:30s} M={1 if M is None else M:4d}  step {min(s):8.2f} / "
                  f"{statistics.median(s):8.2f}  horizon {min(h):8.2f} / {statistics.median(h):8.2f}"
                  f"  speed-up (median) {statistics.median(s) / statistics.median(h):5.1f}x"
                  f"  max|diff| {diff:.1e} m", flush=True)
    os.environ.pop("TANKSYNTH_ESTIMATOR_BACKEND")


if __name__ == "__main__":
    main()
