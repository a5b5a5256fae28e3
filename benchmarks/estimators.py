"""Estimator speed on the hybrid three-tank: tanksynth vs FilterPy, and batch throughput.

Issue 5, section 5. On ``hybrid_three_tank`` (only h3 measured, ts = 1 s, 100/100 lph with a
switch to 120/80 lph, levels crossing the middle pipes) this times:

single run (time per estimator step, best of ``--repeats``)
    tanksynth EKF, UKF and NARX (``step(y, u)``, compiled step kernel), beside FilterPy's
    ``ExtendedKalmanFilter`` and ``UnscentedKalmanFilter`` on the same model: FilterPy gets the
    same compiled transition, Jacobian and output functions (fast buffer calls, about 2 us
    each), so the comparison is the filters' own cost; the ratios FilterPy / tanksynth are
    printed, and so are seed 002's "control signal generation times" (EKF 0.0328 s, UKF
    0.1849 s, ANN 0.1038 s on their LabVIEW rig, Table 5).
batch (``--runs`` parallel runs, default 10,000)
    estimator-steps per second of the EKF, UKF and NARX in batch form.

Floors (asserted): single-run EKF step under 100 us; batch EKF throughput at least 1e6
estimator-steps/s. The estimates of tanksynth and FilterPy are checked to agree to 1e-9 m:
the EKF, and the UKF with alpha = 1 (against tanksynth's ``redraw=True`` or ``redraw=False``,
whichever FilterPy's version does: 2.x redraws the sigma points after the prediction, 1.x
used the propagated ones as seed 002 eq. 27). With alpha = 1e-3 the two UKFs agree to 1e-10 m
until the sigma points straddle a kink of the hybrid model (equal heads, a level at h0),
where rounding differences are amplified by the 1e6 weights: the spread is printed.

FilterPy is not a dependency of tanksynth; install it into the environment to compare::

    .venv/bin/python -m pip install filterpy
    .venv/bin/python benchmarks/estimators.py
    .venv/bin/python benchmarks/estimators.py --runs 2000 --steps 500      # quicker

Exit status 1 when a floor fails or the filters disagree.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import casadi as ca
import numpy as np

from tanksynth.runtime.estimators import (ExtendedKalmanFilter, KalmanTuning, NARXEstimator,
                                         UKFTuning, UnscentedKalmanFilter, discrete_model)
from tanksynth.design.narx import train_narx
from tanksynth.sim.simulate import simulate_inputs
from tanksynth.plants import hybrid_three_tank
from tanksynth.plants.hybrid_three_tank import LPH

try:
    import filterpy
    from filterpy.kalman import ExtendedKalmanFilter as FPExtendedKalmanFilter
    from filterpy.kalman import MerweScaledSigmaPoints
    from filterpy.kalman import UnscentedKalmanFilter as FPUnscentedKalmanFilter
except ImportError:          # optional comparison
    filterpy = None

PAPER_SECONDS = {"EKF": 0.0328, "UKF": 0.1849, "NARX": 0.1038}    # seed 002, Table 5
FLOOR_SINGLE_EKF_US = 100.0
FLOOR_BATCH_EKF = 1e6
TUNING = dict(Q=1e-7 * np.eye(3), R=[[1e-6]], P0=1e-2 * np.eye(3), x0=[0.2, 0.2, 0.2], ts=1.0)


def scenario(steps: int) -> tuple:
    """Measurements and inputs of one run (seed 002 section 5.2 initial mismatch)."""
    plant = hybrid_three_tank()
    U = np.full((steps, 2), 100 * LPH)
    U[steps // 2:, 0] = 120 * LPH
    U[steps // 2:, 1] = 80 * LPH
    X = simulate_inputs(plant, [0.28, 0.28, 0.23], U, 1.0, substeps=10).x[0, 1:]
    rng = np.random.default_rng(0)
    Y = X[:, 2:] + rng.normal(0, 1e-3, (steps, 1))
    return plant, X, Y, U


class FastModel:
    """The EKF's own compiled model pieces as plain callables (for FilterPy)."""

    def __init__(self, plant):
        model = discrete_model(plant, 1.0)
        x, u = ca.SX.sym("x", 3), ca.SX.sym("u", 2)
        fn = ca.Function("model", [x, u], [ca.densify(model.predict_sx(x, u)),
                                           ca.densify(model.transition_jacobian_sx(x, u).T)])
        self.x, self.u = np.zeros(3), np.zeros(2)
        self.xn, self.Phi = np.zeros(3), np.zeros((3, 3))
        fb, self._ev = fn.buffer()
        fb.set_arg(0, memoryview(self.x))
        fb.set_arg(1, memoryview(self.u))
        fb.set_res(0, memoryview(self.xn))
        fb.set_res(1, memoryview(self.Phi.reshape(-1)))
        self._fb = fb
        self.H = np.array([[0.0, 0.0, 1.0]])

    def step(self, x, u):
        """``F(x, u)`` and ``Phi(x, u)`` (copies)."""
        self.x[:] = np.ravel(x)
        self.u[:] = u
        self._ev()
        return self.xn.copy(), self.Phi.copy()

    def fx(self, x, dt, u):
        """FilterPy UKF transition."""
        return self.step(x, u)[0]

    def hx(self, x):
        """Output map h(x) = h3."""
        return np.asarray(x).ravel()[2:3]

    def HJ(self, x):
        """Output Jacobian."""
        return self.H


def best_time(fn, repeats: int) -> float:
    """Best wall time of ``repeats`` calls after one warm-up call (s)."""
    fn()
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def run_filterpy_ekf(model: FastModel, Y, U):
    ekf = FPExtendedKalmanFilter(dim_x=3, dim_z=1)
    ekf.x = np.array(TUNING["x0"], dtype=float).reshape(3, 1)
    ekf.P = TUNING["P0"].copy()
    ekf.Q = TUNING["Q"].copy()
    ekf.R = np.array(TUNING["R"], dtype=float)
    out = np.empty((len(Y), 3))
    for k in range(len(Y)):
        xn, Phi = model.step(ekf.x, U[k])
        ekf.F = Phi
        ekf.x = xn.reshape(3, 1)
        ekf.P = Phi @ ekf.P @ Phi.T + ekf.Q                 # predict() with the nonlinear x
        ekf.update(Y[k].reshape(1, 1), lambda x: model.H, lambda x: x[2:3])
        out[k] = ekf.x.ravel()
    return out


def run_filterpy_ukf(model: FastModel, Y, U, alpha: float = 1e-3):
    points = MerweScaledSigmaPoints(3, alpha=alpha, beta=2.0, kappa=0.0)
    ukf = FPUnscentedKalmanFilter(dim_x=3, dim_z=1, dt=1.0, hx=model.hx, fx=model.fx,
                                  points=points)
    ukf.x = np.array(TUNING["x0"], dtype=float)
    ukf.P = TUNING["P0"].copy()
    ukf.Q = TUNING["Q"].copy()
    ukf.R = np.array(TUNING["R"], dtype=float)
    out = np.empty((len(Y), 3))
    for k in range(len(Y)):
        ukf.predict(u=U[k])
        ukf.update(Y[k])
        out[k] = ukf.x
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10000, help="parallel runs (batch)")
    parser.add_argument("--steps", type=int, default=2000, help="steps of the single run")
    parser.add_argument("--batch-steps", type=int, default=20, help="steps of the batch run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--backend", default="auto", choices=("auto", "native", "vm"))
    args = parser.parse_args(argv)

    print(f"# tanksynth estimators on hybrid_three_tank | python {platform.python_version()} | "
          f"casadi {ca.__version__} | numpy {np.__version__} | {os.cpu_count()} cpus")
    plant, X, Y, U = scenario(args.steps)
    ekf = ExtendedKalmanFilter(plant, KalmanTuning(**TUNING), backend=args.backend)
    ukf = UnscentedKalmanFilter(plant, UKFTuning(**TUNING), backend=args.backend)
    ukf_lit = UnscentedKalmanFilter(plant, UKFTuning(**TUNING, redraw=False), backend=args.backend)
    training = train_narx(plant, KalmanTuning(**TUNING), runs=4, steps=500, seed=0,
                          input_range=[[30 * LPH, 130 * LPH]] * 2, restarts=2, max_iter=150)
    narx = NARXEstimator(plant, training.tuning, backend=args.backend)
    print(f"# kernel back end: {ekf.backend}; operations per step: EKF {ekf.instructions}, "
          f"UKF {ukf.instructions}, NARX {narx.instructions}")

    ok = True
    single = {}
    for name, est in (("EKF", ekf), ("UKF", ukf), ("NARX", narx)):
        def go(est=est):
            est.reset()
            est.run(Y, U)
        single[name] = best_time(go, args.repeats) / args.steps
    x_ekf = (ekf.reset(), ekf.run(Y, U))[1]
    x_ukf = (ukf.reset(), ukf.run(Y, U))[1]
    x_ukf_lit = (ukf_lit.reset(), ukf_lit.run(Y, U))[1]

    fp = {}
    if filterpy is None:
        print("# FilterPy is not installed: `.venv/bin/python -m pip install filterpy` to compare")
    else:
        model = FastModel(plant)
        fp["EKF"] = best_time(lambda: run_filterpy_ekf(model, Y, U), args.repeats) / args.steps
        fp["UKF"] = best_time(lambda: run_filterpy_ukf(model, Y, U), args.repeats) / args.steps
        d_ekf = np.abs(run_filterpy_ekf(model, Y, U) - x_ekf).max()
        x_fp1 = run_filterpy_ukf(model, Y, U, alpha=1.0)
        d_ukf = np.inf
        for redraw in (True, False):
            u1 = UnscentedKalmanFilter(plant, UKFTuning(**TUNING, alpha=1.0, redraw=redraw),
                                       backend=args.backend)
            d = np.abs(x_fp1 - u1.run(Y, U)).max()
            if d < d_ukf:
                d_ukf, mode = d, "redraw" if redraw else "eq. 27, no redraw"
        spread = np.abs(run_filterpy_ukf(model, Y, U) - (x_ukf if mode == "redraw"
                                                         else x_ukf_lit)).max()
        print(f"# agreement with FilterPy {filterpy.__version__}: EKF max |dx| = {d_ekf:.2e} m; "
              f"UKF (alpha = 1, {mode}) max |dx| = {d_ukf:.2e} m; UKF alpha = 1e-3: "
              f"{spread:.2e} m (ill-conditioned at kinks)")
        if not (d_ekf < 1e-9 and d_ukf < 1e-9):
            print("FAIL: tanksynth and FilterPy disagree")
            ok = False

    print("\n## single run: time per step")
    print(f"{'estimator':10} {'tanksynth':>12} {'FilterPy':>12} {'ratio FP/ts':>12} "
          f"{'seed 002 rig':>14} {'rig/ts':>10}")
    for name in ("EKF", "UKF", "NARX"):
        ours = single[name]
        theirs = fp.get(name)
        ratio = f"{theirs / ours:12.1f}" if theirs else f"{'-':>12}"
        fp_txt = f"{theirs * 1e6:10.1f} us" if theirs else f"{'-':>12}"
        print(f"{name:10} {ours * 1e6:9.1f} us {fp_txt} {ratio} {PAPER_SECONDS[name]:12.4f} s "
              f"{PAPER_SECONDS[name] / ours:10.0f}")

    print(f"\n## batch: {args.runs} parallel runs, {args.batch_steps} steps")
    rng = np.random.default_rng(1)
    YB = Y[:args.batch_steps, None, :] + 1e-3 * rng.standard_normal((args.batch_steps, args.runs, 1))
    throughput = {}
    for name, est in (("EKF", ekf), ("UKF", ukf), ("NARX", narx)):
        batch = est.batch(args.runs)

        def go(batch=batch):
            batch.reset()
            for k in range(args.batch_steps):
                batch.step(YB[k], U[k])
        t = best_time(go, args.repeats)
        throughput[name] = args.runs * args.batch_steps / t
        print(f"{name:10} {throughput[name]:14,.0f} estimator-steps/s "
              f"({t / args.batch_steps * 1e3:.2f} ms per step of {args.runs} runs)")

    print("\n## floors")
    f1 = single["EKF"] * 1e6 < FLOOR_SINGLE_EKF_US
    f2 = throughput["EKF"] >= FLOOR_BATCH_EKF
    print(f"single-run EKF step {single['EKF'] * 1e6:.1f} us < {FLOOR_SINGLE_EKF_US:.0f} us: "
          f"{'PASS' if f1 else 'FAIL'}")
    print(f"batch EKF {throughput['EKF']:,.0f} steps/s >= {FLOOR_BATCH_EKF:,.0f}: "
          f"{'PASS' if f2 else 'FAIL'}")
    return 0 if (ok and f1 and f2) else 1


if __name__ == "__main__":
    sys.exit(main())
