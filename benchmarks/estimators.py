"""Estimators on the three-tank: tanksynth vs FilterPy and a hand-vectorised numpy batch EKF.

Issue 15. Plant ``three_tank`` (DTS200, every level measured), ts = 1 s, one RK4 step per
period, Q = 1e-9 I m^2, R = 1e-6 I m^2, P0 = 1e-3 I m^2, x0 = (0.25, 0.15, 0.2) m (the
plant starts at 0.28 / 0.2 / 0.24 m; pumps 30/20 ml/s, switched to 40/15 ml/s half way).
The alternatives do NOT use tanksynth's compiled model: the model below (``f``, its
regularised Jacobian ``d sqrt(|dh|)/dh = 1 / (2 sqrt(|dh| + 1e-6))``, RK4, the transition
Jacobian as the 4th-order Taylor series of ``expm(h J)``) is written by hand in numpy from the
plant's physical parameters, the way a user without tanksynth writes it.

single run (``--steps``, default 2000)
    tanksynth ``ExtendedKalmanFilter.run`` / ``UnscentedKalmanFilter.run`` vs FilterPy's
    ``ExtendedKalmanFilter`` (``predict_x`` overridden with the hand model, ``F`` set per
    step, Joseph-form ``update``) and ``UnscentedKalmanFilter`` (``fx`` = the hand RK4,
    Merwe sigma points, alpha = 1e-3).
batch (``--runs`` M = 1,000 and 10,000 parallel runs, ``--batch-steps`` steps)
    tanksynth ``ekf.batch(M).step`` vs a hand-vectorised numpy EKF over (M, 3) states and
    (M, 3, 3) covariances: the same prediction, Joseph-form correction, symmetrisation and a
    Cholesky (positive-definite) check of both covariances per step, as tanksynth does.

Contenders interleaved, ``--reps`` >= 3 repetitions; min and median and the ratio
alternative / tanksynth of every repetition; JSON record ``benchmarks/results/estimators.json``.
Agreement (exit 1 otherwise): every estimate of tanksynth and FilterPy EKF, and of tanksynth and
the numpy batch EKF, within 1e-9 m; the UKFs with alpha = 1 (the sigma-point scheme FilterPy's
version implements: 2.x redraws after the prediction) within 1e-9 m; with alpha = 1e-3 (the
timed setting) the spread is printed (weights of 1e6 amplify rounding).
Floors (median ratio, exit 1 on a miss): tanksynth at least as fast as FilterPy (EKF and UKF)
and as the numpy batch EKF at every M (>= 1).

Usage::

    .venv/bin/python benchmarks/estimators.py
    .venv/bin/python benchmarks/estimators.py --steps 500 --runs 1000 --reps 5
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import Floors, interleave, machine, ratios, summary, write_record  # noqa: E402

from tanksynth.plants import three_tank  # noqa: E402
from tanksynth.runtime.estimators import (ExtendedKalmanFilter, KalmanTuning,  # noqa: E402
                                         UKFTuning, UnscentedKalmanFilter)
from tanksynth.sim.simulate import simulate_inputs  # noqa: E402

try:
    import filterpy
    from filterpy.kalman import ExtendedKalmanFilter as FPExtendedKalmanFilter
    from filterpy.kalman import MerweScaledSigmaPoints
    from filterpy.kalman import UnscentedKalmanFilter as FPUnscentedKalmanFilter
except ImportError:  # the benchmark says so and fails
    filterpy = None

TS = 1.0
EPS = 1e-6                      # m, regularisation of the Torricelli derivative (tanksynth default)
TUNING = dict(Q=1e-9 * np.eye(3), R=1e-6 * np.eye(3), P0=1e-3 * np.eye(3),
              x0=np.array([0.25, 0.15, 0.2]), ts=TS)
AGREE = 1e-9                    # m
BATCH_SIZES = (1000, 10000)


# ------------------------------------------------------------- hand-written model
class HandModel:
    """The three-tank in plain numpy, from its physical parameters (vectorised over rows)."""

    def __init__(self, params: dict[str, float]):
        c = params["Phi"] * np.sqrt(2.0 * params["g"]) / params["A"]
        self.k13, self.k32, self.k20 = params["mu13"] * c, params["mu32"] * c, params["mu20"] * c
        self.b = 1.0 / params["A"]

    def f(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """dh/dt, x (..., 3), u (..., 2)."""
        h1, h2, h3 = x[..., 0], x[..., 1], x[..., 2]
        d13, d32 = h1 - h3, h3 - h2
        q13 = self.k13 * np.sign(d13) * np.sqrt(np.abs(d13))
        q32 = self.k32 * np.sign(d32) * np.sqrt(np.abs(d32))
        q20 = self.k20 * np.sqrt(h2)
        return np.stack([self.b * u[..., 0] - q13, self.b * u[..., 1] + q32 - q20, q13 - q32],
                        axis=-1)

    def jac(self, x: np.ndarray) -> np.ndarray:
        """Regularised df/dx, (..., 3, 3)."""
        h1, h2, h3 = x[..., 0], x[..., 1], x[..., 2]
        a13 = 0.5 * self.k13 / np.sqrt(np.abs(h1 - h3) + EPS)
        a32 = 0.5 * self.k32 / np.sqrt(np.abs(h3 - h2) + EPS)
        a20 = 0.5 * self.k20 / np.sqrt(h2 + EPS)
        J = np.zeros(x.shape[:-1] + (3, 3))
        J[..., 0, 0], J[..., 0, 2] = -a13, a13
        J[..., 1, 1], J[..., 1, 2] = -a32 - a20, a32
        J[..., 2, 0], J[..., 2, 1], J[..., 2, 2] = a13, a32, -a13 - a32
        return J

    def predict(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One RK4 step of TS seconds."""
        h = TS
        k1 = self.f(x, u)
        k2 = self.f(x + 0.5 * h * k1, u)
        k3 = self.f(x + 0.5 * h * k2, u)
        k4 = self.f(x + h * k3, u)
        return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    def phi(self, x: np.ndarray) -> np.ndarray:
        """Transition Jacobian: 4th-order Taylor series of expm(TS J(x))."""
        hJ = TS * self.jac(x)
        eye = np.eye(3)
        T = eye + hJ / 4
        T = eye + hJ / 3 @ T
        T = eye + hJ / 2 @ T
        return eye + hJ @ T


def scenario(plant, steps: int, runs: int = 1, seed: int = 0):
    """Levels (steps, 3), noisy measurements (steps, runs, 3) and inputs (steps, 2)."""
    U = np.tile([30e-6, 20e-6], (steps, 1))
    U[steps // 2:] = [40e-6, 15e-6]
    X = simulate_inputs(plant, [0.28, 0.2, 0.24], U, TS, substeps=10).x[0, 1:]
    rng = np.random.default_rng(seed)
    Y = X[:, None, :] + 1e-3 * rng.standard_normal((steps, runs, 3))
    return X, Y, U


# ------------------------------------------------------------------ FilterPy
def filterpy_ekf(model: HandModel, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
    """FilterPy's EKF with the hand model: predict_x overridden, F set every step."""

    class EKF(FPExtendedKalmanFilter):
        def predict_x(self, u=0):
            self.x = model.predict(self.x.ravel(), u).reshape(3, 1)

    ekf = EKF(dim_x=3, dim_z=3)
    ekf.x = TUNING["x0"].reshape(3, 1).copy()
    ekf.P, ekf.Q, ekf.R = TUNING["P0"].copy(), TUNING["Q"].copy(), TUNING["R"].copy()
    H = np.eye(3)
    out = np.empty((len(Y), 3))
    for k in range(len(Y)):
        ekf.F = model.phi(ekf.x.ravel())
        ekf.predict(u=U[k])
        ekf.update(Y[k].reshape(3, 1), lambda x: H, lambda x: x)
        out[k] = ekf.x.ravel()
    return out


def filterpy_ukf(model: HandModel, Y: np.ndarray, U: np.ndarray, alpha: float = 1e-3) -> np.ndarray:
    """FilterPy's UKF with the hand RK4 as fx."""
    points = MerweScaledSigmaPoints(3, alpha=alpha, beta=2.0, kappa=0.0)
    ukf = FPUnscentedKalmanFilter(dim_x=3, dim_z=3, dt=TS, hx=lambda x: x,
                                  fx=lambda x, dt, u: model.predict(x, u), points=points)
    ukf.x = TUNING["x0"].copy()
    ukf.P, ukf.Q, ukf.R = TUNING["P0"].copy(), TUNING["Q"].copy(), TUNING["R"].copy()
    out = np.empty((len(Y), 3))
    for k in range(len(Y)):
        ukf.predict(u=U[k])
        ukf.update(Y[k])
        out[k] = ukf.x
    return out


# ----------------------------------------------------------- numpy batch EKF
def numpy_batch_ekf(model: HandModel, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
    """Hand-vectorised EKF over M runs: Y (steps, M, 3), U (steps, 2); estimates (steps, M, 3)."""
    steps, M, _ = Y.shape
    Q, R = TUNING["Q"], TUNING["R"]
    x = np.tile(TUNING["x0"], (M, 1))
    P = np.tile(TUNING["P0"], (M, 1, 1))
    eye = np.eye(3)
    out = np.empty((steps, M, 3))
    for k in range(steps):
        Phi = model.phi(x)
        x = model.predict(x, U[k][None, :])
        Pp = Phi @ P @ Phi.transpose(0, 2, 1) + Q
        Pp = 0.5 * (Pp + Pp.transpose(0, 2, 1))
        np.linalg.cholesky(Pp)                                 # positive definite, or raise
        S = Pp + R                                             # H = I
        S = 0.5 * (S + S.transpose(0, 2, 1))
        K = np.linalg.solve(S, Pp).transpose(0, 2, 1)          # Pp H' S^-1 (S, Pp symmetric)
        x = x + (K @ (Y[k] - x)[:, :, None])[:, :, 0]
        IKH = eye - K
        P = IKH @ Pp @ IKH.transpose(0, 2, 1) + K @ R @ K.transpose(0, 2, 1)
        P = 0.5 * (P + P.transpose(0, 2, 1))
        np.linalg.cholesky(P)
        out[k] = x
    return out


def tanksynth_batch(ekf: ExtendedKalmanFilter, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
    """tanksynth's batch path (as the verification campaigns run it): one step of M runs."""
    steps, M, _ = Y.shape
    batch = ekf.batch(M)
    out = np.empty((steps, M, 3))
    for k in range(steps):
        out[k] = batch.step(Y[k], U[k])
    return out


def report(name: str, times: dict, alt: str, what: str, floors: Floors) -> dict:
    """Print min/median and per-rep ratios alt / tanksynth; check the floor (>= 1)."""
    r = ratios(times[alt], times["tanksynth"])
    for who in ("tanksynth", alt):
        sm = summary(times[who])
        print(f"  {who:12s} min {sm['min'] * 1e3:9.2f} ms  median {sm['median'] * 1e3:9.2f} ms")
    med = statistics.median(r)
    print(f"  {alt} / tanksynth per rep: " + " ".join(f"{v:.2f}" for v in r) + f"   median {med:.2f}")
    floors.check(f"{name}: tanksynth vs {what}", med, 1.0)
    return {"name": name, "times": times, "ratio": r, "median_ratio": med}


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; exit 1 on a floor miss, a disagreement or without FilterPy."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000, help="steps of the single run")
    ap.add_argument("--runs", type=int, nargs="+", default=list(BATCH_SIZES), help="batch sizes M")
    ap.add_argument("--batch-steps", type=int, default=50)
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args(argv)
    reps = max(args.reps, 3)
    if filterpy is None:
        print("benchmarks/estimators.py: FilterPy is not installed (pip install filterpy; it is in "
              "the dev extra)", file=sys.stderr)
        return 1
    before = machine()
    floors = Floors()
    plant = three_tank()
    model = HandModel({p.name: float(p.value) for p in plant.parameters})
    X, Y1, U = scenario(plant, args.steps)
    Y = Y1[:, 0, :]
    ekf = ExtendedKalmanFilter(plant, KalmanTuning(**TUNING))
    ukf = UnscentedKalmanFilter(plant, UKFTuning(**TUNING))
    print(f"three_tank, {args.steps} steps; tanksynth kernel back end {ekf.backend}; "
          f"FilterPy {filterpy.__version__}; {reps} interleaved reps; load {before['loadavg']}")

    # agreement
    ok = True
    x_ts = (ekf.reset(), ekf.run(Y, U))[1]
    d_ekf = float(np.abs(filterpy_ekf(model, Y, U) - x_ts).max())
    x_fp1 = filterpy_ukf(model, Y, U, alpha=1.0)
    u1 = UnscentedKalmanFilter(plant, UKFTuning(**TUNING, alpha=1.0, redraw=True))
    d_ukf = float(np.abs(x_fp1 - u1.run(Y, U)).max())
    spread = float(np.abs(filterpy_ukf(model, Y, U) - (ukf.reset(), ukf.run(Y, U))[1]).max())
    print(f"agreement: EKF max |dx| {d_ekf:.1e} m; UKF (alpha = 1, redraw) {d_ukf:.1e} m; "
          f"UKF alpha = 1e-3 spread {spread:.1e} m; estimate error vs truth "
          f"{np.abs(x_ts - X).max():.1e} m")
    if not (d_ekf <= AGREE and d_ukf <= AGREE):
        print("  ESTIMATES DISAGREE")
        ok = False

    rows = []

    def run_ts(est):
        est.reset()
        est.run(Y, U)

    print(f"\nsingle run, EKF ({args.steps} steps):")
    t = interleave({"tanksynth": lambda: run_ts(ekf), "FilterPy": lambda: filterpy_ekf(model, Y, U)},
                   reps)
    rows.append(report("EKF single run", t, "FilterPy", "FilterPy EKF + numpy model", floors))
    print(f"\nsingle run, UKF alpha = 1e-3 ({args.steps} steps):")
    t = interleave({"tanksynth": lambda: run_ts(ukf), "FilterPy": lambda: filterpy_ukf(model, Y, U)},
                   reps)
    rows.append(report("UKF single run", t, "FilterPy", "FilterPy UKF + numpy model", floors))

    for M in args.runs:
        _, YB, UB = scenario(plant, args.batch_steps, runs=M, seed=1)
        a, b = tanksynth_batch(ekf, YB, UB), numpy_batch_ekf(model, YB, UB)
        d = float(np.abs(a - b).max())
        print(f"\nbatch EKF, M = {M} runs x {args.batch_steps} steps: max |dx| {d:.1e} m")
        if d > AGREE:
            print("  ESTIMATES DISAGREE")
            ok = False
        t = interleave({"tanksynth": lambda: tanksynth_batch(ekf, YB, UB),
                        "numpy": lambda: numpy_batch_ekf(model, YB, UB)}, reps)
        row = report(f"EKF batch M={M}", t, "numpy", "hand-vectorised numpy EKF", floors)
        row["max_abs_diff"] = d
        rows.append(row)

    path = write_record("estimators", {"reps": reps, "steps": args.steps,
                                       "batch_steps": args.batch_steps, "rows": rows,
                                       "agreement": {"ekf": d_ekf, "ukf_alpha1": d_ukf,
                                                     "ukf_alpha1e-3_spread": spread},
                                       "floors": floors.rows}, before)
    print(f"\nrecord: {path}")
    return 0 if ok and not floors.failed else 1


if __name__ == "__main__":
    sys.exit(main())
