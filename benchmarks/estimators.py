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
    Issue 29: also ``numba`` (``@njit``, the 3 x 3 algebra written out: Jacobian series,
    RK4, Joseph form, symmetrisation, Cholesky checks of both covariances, the gain by a
    Cholesky solve of S) and ``jax`` (``jit`` of a ``lax.scan``, ``vmap`` for runs), the same
    equations as the hand numpy EKF below; their compile (first call) is reported apart.
    ``tanksynth_step``: tanksynth with ``TANKSYNTH_ESTIMATOR_BACKEND=step`` (the one-step
    path, no horizon kernel), reported beside the default (no floor).
batch (``--runs`` M = 200, 1,000 and 10,000 parallel runs, ``--batch-steps`` steps)
    tanksynth ``ekf.batch(M).run`` (the whole sequence) vs a hand-vectorised numpy EKF over
    (M, 3) states and (M, 3, 3) covariances: the same prediction, Joseph-form correction,
    symmetrisation and a Cholesky (positive-definite) check of both covariances per step, as
    tanksynth does; numba (serial over runs, and ``prange`` over the cores) and JAX (vmap).

Contenders interleaved, ``--reps`` >= 3 repetitions; min and median and the ratio
alternative / tanksynth of every repetition; JSON record ``benchmarks/results/estimators.json``.
Agreement (exit 1 otherwise): every estimate of tanksynth and FilterPy EKF, and of tanksynth and
the numpy batch EKF, within 1e-9 m; the UKFs with alpha = 1 (the sigma-point scheme FilterPy's
version implements: 2.x redraws after the prediction) within 1e-9 m; with alpha = 1e-3 (the
timed setting) the spread is printed (weights of 1e6 amplify rounding).
Floors (median ratio, exit 1 on a miss): tanksynth at least as fast as FilterPy (EKF and UKF)
and as the numpy batch EKF at every M (>= 1). Issue 29: at least numba's speed, single run
and batch (serial and prange): reported, exit 1 on a miss only with ``--strict`` (the
compiled estimator kernels are being built in the library).

Usage::

    .venv/bin/python benchmarks/estimators.py
    .venv/bin/python benchmarks/estimators.py --steps 500 --runs 1000 --reps 5
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import Floors, environ, interleave, machine, ratios, summary, write_record  # noqa: E402

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
BATCH_SIZES = (200, 1000, 10000)
COMPILED = ("numba", "numba_prange", "jax")   # issue 29's floors: exit 1 only with --strict


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
    """tanksynth's batch path: ``ekf.batch(M).run`` of the whole sequence (N, M, 3)."""
    steps, M, _ = Y.shape
    UB = np.ascontiguousarray(np.broadcast_to(U[:, None, :], (steps, M, U.shape[-1]))) \
        if U.ndim == 2 else U
    return ekf.batch(M).run(Y, UB)


# ------------------------------------------------------------------ numba, JAX
def build_numba(model: HandModel):
    """(single, batch, batch with prange) numba EKFs with the hand model: same equations as `numpy_batch_ekf`.

    3 x 3 algebra written out (Cholesky of S for the gain, Cholesky checks of both
    covariances, raising on a non-positive-definite one); ``batch`` spreads the runs over
    the cores (``prange``). Returns ``single(Y (N, 3), U (N, 2)) -> (N, 3)`` and
    ``batch(Y (N, M, 3), U (N, 2)) -> (N, M, 3)`` (serial loop over runs, and with ``prange``).
    """
    import math

    import numba as nb

    k13, k32, k20, b = model.k13, model.k32, model.k20, model.b
    Q, R, P0, x0 = (np.ascontiguousarray(TUNING[k], dtype=float) for k in ("Q", "R", "P0", "x0"))
    h = TS

    @nb.njit(inline="always")
    def f(x, u, out):
        d13, d32 = x[0] - x[2], x[2] - x[1]
        q13 = k13 * np.sign(d13) * math.sqrt(abs(d13))
        q32 = k32 * np.sign(d32) * math.sqrt(abs(d32))
        q20 = k20 * math.sqrt(x[1])
        out[0] = b * u[0] - q13
        out[1] = b * u[1] + q32 - q20
        out[2] = q13 - q32

    @nb.njit(inline="always")
    def pd(A):
        """Cholesky test of a symmetric 3 x 3 (True: positive definite)."""
        l00 = A[0, 0]
        if not l00 > 0:
            return False
        l00 = math.sqrt(l00)
        l10, l20 = A[1, 0] / l00, A[2, 0] / l00
        d1 = A[1, 1] - l10 * l10
        if not d1 > 0:
            return False
        l11 = math.sqrt(d1)
        l21 = (A[2, 1] - l20 * l10) / l11
        return A[2, 2] - l20 * l20 - l21 * l21 > 0

    @nb.njit(inline="always")
    def mm(A, B, out):
        """out = A B (3 x 3)."""
        for i in range(3):
            for j in range(3):
                out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]

    @nb.njit(inline="always")
    def mmt(A, B, out):
        """out = A B' (3 x 3)."""
        for i in range(3):
            for j in range(3):
                out[i, j] = A[i, 0] * B[j, 0] + A[i, 1] * B[j, 1] + A[i, 2] * B[j, 2]

    @nb.njit(inline="always")
    def sym(A):
        for i in range(3):
            for j in range(i + 1, 3):
                v = 0.5 * (A[i, j] + A[j, i])
                A[i, j] = v
                A[j, i] = v

    @nb.njit
    def one(Y, U, out):
        x = x0.copy()
        P = P0.copy()
        k1, k2, k3, k4, s, e = (np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3),
                                np.empty(3))
        J, T, T2, Phi, W = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), \
            np.zeros((3, 3))
        Pp, S, K, IKH, L = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), \
            np.zeros((3, 3))
        for k in range(Y.shape[0]):
            u = U[k]
            # transition Jacobian: 4th-order Taylor series of expm(h J(x)), Horner form
            a13 = 0.5 * k13 / math.sqrt(abs(x[0] - x[2]) + EPS)
            a32 = 0.5 * k32 / math.sqrt(abs(x[2] - x[1]) + EPS)
            a20 = 0.5 * k20 / math.sqrt(x[1] + EPS)
            J[0, 0], J[0, 1], J[0, 2] = -a13 * h, 0.0, a13 * h
            J[1, 0], J[1, 1], J[1, 2] = 0.0, (-a32 - a20) * h, a32 * h
            J[2, 0], J[2, 1], J[2, 2] = a13 * h, a32 * h, (-a13 - a32) * h
            for i in range(3):
                for j in range(3):
                    T[i, j] = (1.0 if i == j else 0.0) + J[i, j] / 4
            for c in (3.0, 2.0):                                        # noqa: B007
                for i in range(3):
                    for j in range(3):
                        T2[i, j] = ((1.0 if i == j else 0.0) + (J[i, 0] / c) * T[0, j]
                                    + (J[i, 1] / c) * T[1, j] + (J[i, 2] / c) * T[2, j])
                T[:, :] = T2
            mm(J, T, Phi)
            for i in range(3):
                Phi[i, i] += 1.0
            # RK4 prediction
            f(x, u, k1)
            for i in range(3):
                s[i] = x[i] + 0.5 * h * k1[i]
            f(s, u, k2)
            for i in range(3):
                s[i] = x[i] + 0.5 * h * k2[i]
            f(s, u, k3)
            for i in range(3):
                s[i] = x[i] + h * k3[i]
            f(s, u, k4)
            for i in range(3):
                x[i] = x[i] + (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            mm(Phi, P, W)
            mmt(W, Phi, Pp)
            for i in range(3):
                for j in range(3):
                    Pp[i, j] += Q[i, j]
            sym(Pp)
            if not pd(Pp):
                raise ValueError("predicted covariance not positive definite")
            for i in range(3):
                for j in range(3):
                    S[i, j] = Pp[i, j] + R[i, j]
            sym(S)
            # K = Pp S^-1 (H = I): Cholesky S = L L', solve S K' = Pp column by column
            L[0, 0] = math.sqrt(S[0, 0])
            L[1, 0] = S[1, 0] / L[0, 0]
            L[2, 0] = S[2, 0] / L[0, 0]
            L[1, 1] = math.sqrt(S[1, 1] - L[1, 0] ** 2)
            L[2, 1] = (S[2, 1] - L[2, 0] * L[1, 0]) / L[1, 1]
            L[2, 2] = math.sqrt(S[2, 2] - L[2, 0] ** 2 - L[2, 1] ** 2)
            for c in range(3):
                z0 = Pp[0, c] / L[0, 0]
                z1 = (Pp[1, c] - L[1, 0] * z0) / L[1, 1]
                z2 = (Pp[2, c] - L[2, 0] * z0 - L[2, 1] * z1) / L[2, 2]
                w2 = z2 / L[2, 2]
                w1 = (z1 - L[2, 1] * w2) / L[1, 1]
                w0 = (z0 - L[1, 0] * w1 - L[2, 0] * w2) / L[0, 0]
                K[c, 0], K[c, 1], K[c, 2] = w0, w1, w2
            for i in range(3):
                e[i] = Y[k, i] - x[i]
            for i in range(3):
                x[i] = x[i] + K[i, 0] * e[0] + K[i, 1] * e[1] + K[i, 2] * e[2]
            for i in range(3):
                for j in range(3):
                    IKH[i, j] = (1.0 if i == j else 0.0) - K[i, j]
            mm(IKH, Pp, W)
            mmt(W, IKH, P)
            mm(K, R, W)
            mmt(W, K, T2)
            for i in range(3):
                for j in range(3):
                    P[i, j] += T2[i, j]
            sym(P)
            if not pd(P):
                raise ValueError("covariance not positive definite")
            out[k] = x

    @nb.njit
    def single(Y, U):
        out = np.empty((Y.shape[0], 3))
        one(Y, U, out)
        return out

    def batch_body(Y, U):
        steps, M = Y.shape[0], Y.shape[1]
        out = np.empty((M, steps, 3))
        for r in nb.prange(M):            # a plain range in the serial compilation
            one(np.ascontiguousarray(Y[:, r, :]), U, out[r])
        return out.transpose(1, 0, 2)

    batch_serial = nb.njit(batch_body)
    batch = nb.njit(parallel=True)(batch_body)
    return single, batch_serial, batch


def build_jax(model: HandModel):
    """jit(scan) EKF with the hand model, vmapped over runs; the same equations.

    Returns ``run(Y (N, M, 3), U (N, 2)) -> (N, M, 3)``; raises when a covariance's Cholesky
    factor was not finite at some step (checked after the call: a traced function cannot raise).
    """
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    k13, k32, k20, b = model.k13, model.k32, model.k20, model.b
    Q, R, P0, x0 = (jnp.asarray(TUNING[k], dtype=float) for k in ("Q", "R", "P0", "x0"))
    h = TS
    eye = jnp.eye(3)

    def f(x, u):
        d13, d32 = x[0] - x[2], x[2] - x[1]
        q13 = k13 * jnp.sign(d13) * jnp.sqrt(jnp.abs(d13))
        q32 = k32 * jnp.sign(d32) * jnp.sqrt(jnp.abs(d32))
        return jnp.stack([b * u[0] - q13, b * u[1] + q32 - k20 * jnp.sqrt(x[1]), q13 - q32])

    def step(carry, inp):
        x, P, ok = carry
        y, u = inp
        a13 = 0.5 * k13 / jnp.sqrt(jnp.abs(x[0] - x[2]) + EPS)
        a32 = 0.5 * k32 / jnp.sqrt(jnp.abs(x[2] - x[1]) + EPS)
        a20 = 0.5 * k20 / jnp.sqrt(x[1] + EPS)
        J = h * jnp.array([[-a13, 0.0, a13], [0.0, -a32 - a20, a32], [a13, a32, -a13 - a32]])
        T = eye + J / 4
        T = eye + J / 3 @ T
        T = eye + J / 2 @ T
        Phi = eye + J @ T
        k1 = f(x, u)
        k2 = f(x + 0.5 * h * k1, u)
        k3 = f(x + 0.5 * h * k2, u)
        k4 = f(x + h * k3, u)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        Pp = Phi @ P @ Phi.T + Q
        Pp = 0.5 * (Pp + Pp.T)
        S = Pp + R
        S = 0.5 * (S + S.T)
        K = jnp.linalg.solve(S, Pp).T
        x = x + K @ (y - x)
        IKH = eye - K
        P = IKH @ Pp @ IKH.T + K @ R @ K.T
        P = 0.5 * (P + P.T)
        ok = ok & jnp.all(jnp.isfinite(jnp.linalg.cholesky(Pp))) \
            & jnp.all(jnp.isfinite(jnp.linalg.cholesky(P)))
        return (x, P, ok), x

    def one(Y, U):
        (_, _, ok), xs = jax.lax.scan(step, (x0, P0, jnp.array(True)), (Y, U))
        return xs, ok

    fn = jax.jit(jax.vmap(one, in_axes=(1, None), out_axes=(1, 0)))

    def run(Y, U):
        xs, ok = fn(jnp.asarray(Y), jnp.asarray(U))
        xs = np.asarray(xs.block_until_ready())
        if not bool(np.all(np.asarray(ok))):
            raise ValueError("covariance not positive definite")
        return xs
    return run


def report(name: str, times: dict, floor_against: dict[str, str], floors: Floors) -> dict:
    """Print min/median and per-rep ratios alternative / tanksynth; check floors (>= 1).

    ``floor_against`` maps an alternative to the description in its floor's name.
    """
    for who, t in times.items():
        sm = summary(t)
        print(f"  {who:12s} min {sm['min'] * 1e3:9.3f} ms  median {sm['median'] * 1e3:9.3f} ms")
    row = {"name": name, "times": times, "ratios": {}, "median_ratios": {}}
    for alt in times:
        if alt == "tanksynth":
            continue
        r = ratios(times[alt], times["tanksynth"])
        med = statistics.median(r)
        row["ratios"][alt], row["median_ratios"][alt] = r, med
        print(f"  {alt} / tanksynth per rep: " + " ".join(f"{v:.3f}" for v in r)
              + f"   min {min(r):.3f} median {med:.3f}")
        if alt in floor_against:
            floors.check(f"{name}: tanksynth vs {floor_against[alt]}", med, 1.0,
                         strict_only=alt in COMPILED)
    return row


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; exit 1 on a floor miss, a disagreement or without FilterPy."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000, help="steps of the single run")
    ap.add_argument("--runs", type=int, nargs="+", default=list(BATCH_SIZES), help="batch sizes M")
    ap.add_argument("--batch-steps", type=int, default=50)
    ap.add_argument("--record", default="estimators",
                    help="name of the JSON record in benchmarks/results (default %(default)s)")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--strict", action="store_true",
                    help="exit 1 also when a floor against a compiled contender is missed")
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

    # the library's compiled horizon kernels (if any) built now, outside the timing, as a
    # campaign's first block builds them; the default setting then loads them
    t0 = time.perf_counter()
    with environ(TANKSYNTH_ESTIMATOR_BACKEND="horizon"):
        ekf.reset()
        ekf.run(Y, U)
        tanksynth_batch(ekf, Y1[:, :, :].repeat(2, axis=1)[:40], U[:40])
    build_s = time.perf_counter() - t0
    print(f"tanksynth kernels built (TANKSYNTH_ESTIMATOR_BACKEND=horizon, warm-up) in {build_s:.2f} s")

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

    compiled = {}
    try:
        nb_single, nb_serial, nb_batch = build_numba(model)
        t0 = time.perf_counter()
        d_nb = float(np.abs(nb_single(Y, U) - x_ts).max())
        compiled["numba"] = {"first_call_s": time.perf_counter() - t0, "max_abs_diff": d_nb}
    except ImportError:
        nb_single = nb_serial = nb_batch = None
        print("numba not installed (pip install -e '.[bench]'): skipped")
    try:
        jax_run = build_jax(model)
        t0 = time.perf_counter()
        d_jax = float(np.abs(jax_run(Y[:, None, :], U)[:, 0] - x_ts).max())
        compiled["jax"] = {"first_call_s": time.perf_counter() - t0, "max_abs_diff": d_jax}
    except ImportError:
        jax_run = None
        print("jax not installed (pip install -e '.[bench]'): skipped")
    for name, c in compiled.items():
        print(f"{name}: first call (compile) {c['first_call_s']:.2f} s; single run max |dx| vs "
              f"tanksynth {c['max_abs_diff']:.1e} m")
        if c["max_abs_diff"] > AGREE:
            print("  ESTIMATES DISAGREE")
            ok = False

    print(f"\nsingle run, EKF ({args.steps} steps):")
    def step_path(fn):
        """tanksynth with TANKSYNTH_ESTIMATOR_BACKEND=step: the one-step path (no horizon kernel)."""
        def call():
            with environ(TANKSYNTH_ESTIMATOR_BACKEND="step"):
                return fn()
        return call

    contenders = {"tanksynth": lambda: run_ts(ekf), "tanksynth_step": step_path(lambda: run_ts(ekf)),
                  "FilterPy": lambda: filterpy_ekf(model, Y, U)}
    if nb_single is not None:
        contenders["numba"] = lambda: nb_single(Y, U)
    if jax_run is not None:
        contenders["jax"] = lambda: jax_run(Y[:, None, :], U)
    t = interleave(contenders, reps)
    rows.append(report("EKF single run", t, {"FilterPy": "FilterPy EKF + numpy model",
                                             "numba": "numba EKF"}, floors))
    print(f"\nsingle run, UKF alpha = 1e-3 ({args.steps} steps):")
    t = interleave({"tanksynth": lambda: run_ts(ukf), "FilterPy": lambda: filterpy_ukf(model, Y, U)},
                   reps)
    rows.append(report("UKF single run", t, {"FilterPy": "FilterPy UKF + numpy model"}, floors))

    for M in args.runs:
        _, YB, UB = scenario(plant, args.batch_steps, runs=M, seed=1)
        a, b = tanksynth_batch(ekf, YB, UB), numpy_batch_ekf(model, YB, UB)
        diffs = {"numpy": float(np.abs(a - b).max())}
        contenders = {"tanksynth": lambda: tanksynth_batch(ekf, YB, UB),
                      "tanksynth_step": step_path(lambda: tanksynth_batch(ekf, YB, UB)),
                      "numpy": lambda: numpy_batch_ekf(model, YB, UB)}
        if nb_batch is not None:
            diffs["numba"] = float(np.abs(a - nb_serial(YB, UB)).max())
            diffs["numba_prange"] = float(np.abs(a - nb_batch(YB, UB)).max())
            contenders["numba"] = lambda: nb_serial(YB, UB)
            contenders["numba_prange"] = lambda: nb_batch(YB, UB)
        if jax_run is not None:
            diffs["jax"] = float(np.abs(a - jax_run(YB, UB)).max())
            contenders["jax"] = lambda: jax_run(YB, UB)
        print(f"\nbatch EKF, M = {M} runs x {args.batch_steps} steps: max |dx| "
              + ", ".join(f"{k} {v:.1e} m" for k, v in diffs.items()))
        if max(diffs.values()) > AGREE:
            print("  ESTIMATES DISAGREE")
            ok = False
        t = interleave(contenders, reps)
        row = report(f"EKF batch M={M}", t, {"numpy": "hand-vectorised numpy EKF",
                                             "numba": "numba EKF (serial over runs)",
                                             "numba_prange": "numba prange EKF"}, floors)
        row["M"] = M
        row["max_abs_diff"] = diffs
        rows.append(row)

    path = write_record(args.record, {"reps": reps, "steps": args.steps,
                                       "batch_steps": args.batch_steps, "rows": rows,
                                       "agreement": {"ekf": d_ekf, "ukf_alpha1": d_ukf,
                                                     "ukf_alpha1e-3_spread": spread},
                                       "compiled": compiled, "backend": ekf.backend,
                                       "tanksynth_build_s": build_s,
                                       "floors": floors.rows}, before)
    print(f"\nrecord: {path}")
    status = floors.exit_status(args.strict)
    return 0 if ok and not status else 1


if __name__ == "__main__":
    sys.exit(main())
