"""Closed loop as ``verify`` runs it: tanksynth vs numba, JAX, compiled CasADi and numpy (issue 29).

Work: the integral tracking law ``u = sat(u0 - K1 (x - x0) - K2 z)``, ``z <- z + ts (r - C1 x)``
(`tanksynth.verify.simulations.IntegralStateFeedback`, the law a placement artefact runs in
closed loop), the true state fed back, the ``servo`` scenario of the campaigns (300 samples of
ts = 1 s, set-points +0.04 at sample 100, process noise 1e-5, measurement noise 5e-4 per
sample), 4 RK4 steps per sample with every stage and every end state clipped to the plant's
bounds, process noise added and clipped after each period: what `tanksynth.sim.simulate`
does, term for term.

Plants and gains:

* ``three_tank``: the demo's ``integral_pole_placement`` artefact (``tanksynth design`` of
  the built-in demo into a temporary directory; ``K1``, ``K2``, ``C1`` and the operating point
  read from the artefact, the loop built by `state_feedback_loop`, as ``verify`` does),
  M = 1, 200, 10,000 runs;
* ``tank_network(16)`` (DECENTER constants, 8 pumps at 4 V, every level measured, the lower
  tanks tracked): ``K1``, ``K2`` a discrete LQR (scipy DARE, Q = I, R = I) on the
  integral-augmented ZOH model linearised here by central differences, M = 1, 200.

Contenders (interleaved, ``--reps`` >= 3; ratio = contender time / tanksynth time per rep,
min and median; above 1: tanksynth is faster):

* ``tanksynth``: ``simulate(plant, controller=law, ...)`` (it also draws its noise, one
  generator per run, inside the timing);
* ``numba``: ``@njit`` loop over runs, samples, substeps (serial for M = 1) and
  ``numba_prange`` (``@njit(parallel=True)``, runs spread over the cores, M > 1);
* ``jax``: ``jit`` of a ``lax.scan`` over the samples, ``vmap`` over the runs, float64;
* ``casadi_jit``: the period (law + RK4 + clipping + noise) as an SX Function compiled with
  ``jit=True`` (the system C compiler), ``mapaccum`` over the horizon, ``map`` over the runs
  (``"thread"``, 2 threads);
* ``numpy``: the loop over samples, vectorised over runs (one 1-D array per tank);
* ``tanksynth_numpy``: tanksynth with ``TANKSYNTH_SIM_BACKEND=numpy`` (its period-by-period
  path, no compiled kernel), reported beside the default (no floor).

Every contender gets the process noise tanksynth draws (the same seeds), precomputed
outside its timing (it gains the draw). Their states must equal tanksynth's to 1e-12 m
(checked before timing; a disagreement is exit 1). The compile (first call) of every
compiled contender is timed apart and reported.

Floors (median ratio >= 1, issue 29): M = 1 tanksynth at least numba; M = 200 and 10,000
at least JAX. Reported pass/miss; exit 1 on a miss only with ``--strict`` (the compiled
closed-loop kernel is being built in the library). ``TANKSYNTH_SIM_BACKEND`` is left as it
is (``numpy`` forces the library's older path).

Usage: ``python benchmarks/closed_loop.py [--reps 5] [--quick] [--strict]
[--three-tank 1 200 10000] [--network 1 200]``
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import (Floors, environ, interleave, machine, ratios, scratch_cwd,  # noqa: E402
                     summary, write_record)

from tanksynth.plants import tank_network, three_tank  # noqa: E402
from tanksynth.sim.scenarios import SCENARIOS  # noqa: E402
from tanksynth.sim.simulate import run_seeds, simulate  # noqa: E402
from tanksynth.spec import load_spec  # noqa: E402
from tanksynth.verify.common import sampling_period  # noqa: E402
from tanksynth.verify.laws.campaign import state_feedback_loop  # noqa: E402
from tanksynth.verify.simulations import IntegralStateFeedback  # noqa: E402

SUBSTEPS = 4
AGREE = 1e-12          # m
DEMO = Path(__file__).resolve().parents[1] / "tanksynth" / "data" / "demo.toml"


# --------------------------------------------------------------------------- problems
class Problem:
    """One closed loop: plant constants, gains, scenario arrays (numpy), the tanksynth call."""

    def __init__(self, name, plant, law, setup, ts, unit_m):
        self.name, self.plant, self.law, self.setup, self.ts = name, plant, law, setup, float(ts)
        self.unit_m = unit_m                     # metres per state unit (1 or 0.01)
        self.K1, self.K2 = np.asarray(law.K1, float), np.asarray(law.K2, float)
        self.C1, self.x0, self.u0 = np.asarray(law.C1, float), np.asarray(law.x0, float), \
            np.asarray(law.u0, float)
        lo, hi = plant.state_bounds()
        self.xlo, self.xhi = np.asarray(lo, float), np.asarray(hi, float)
        sc = setup.scenario
        self.wstd, self.vstd = float(sc.process_std), float(sc.measurement_std)
        self.N = int(setup.steps)
        self.ref = np.asarray(setup.reference, float)          # (N + 1, p)
        self.built: set[int] = set()

    def noise(self, seeds):
        """Process noise (M, N, n) drawn as tanksynth draws it (process first, per run)."""
        n = self.plant.n
        W = np.empty((len(seeds), self.N, n))
        for r, s in enumerate(seeds):
            W[r] = np.random.default_rng(int(s)).standard_normal((self.N, n))
        return W * self.wstd

    def tanksynth(self, seeds):
        s = self.setup
        return simulate(self.plant, ts=self.ts, steps=self.N, x0=s.x0, seeds=seeds,
                        controller=self.law, reference=s.reference, x_hat0=s.x_hat0,
                        u_init=s.u_init, process_std=self.wstd, measurement_std=self.vstd,
                        substeps=SUBSTEPS)


def three_tank_problem(workdir: Path) -> Problem:
    """The demo's pole-placement artefact in the servo scenario (as verify runs it)."""
    out = workdir / "demo"
    subprocess.run([sys.executable, "-m", "tanksynth", "design", str(DEMO), "-o", str(out)],
                   check=True, capture_output=True)
    spec = load_spec(out / "spec.toml")
    doc = json.loads((out / "integral_pole_placement.json").read_text())
    loop = state_feedback_loop(doc, spec)
    ts = sampling_period(spec)
    setup = SCENARIOS["servo"].setup(spec.plant, loop.x_op, loop.u_op, loop.tracked, ts=ts)
    return Problem("three_tank", spec.plant, loop.controller, setup, ts, 1.0)


def three_tank_constants(plant):
    """Hand constants of the three-tank: valve coefficients k13, k32, k20 (m^0.5/s) and 1/A."""
    prm = {q.name: float(q.value) for q in plant.parameters}
    r2g = math.sqrt(2 * prm["g"])
    k13, k32, k20 = (prm[k] * prm["Phi"] * r2g / prm["A"] for k in ("mu13", "mu32", "mu20"))
    return k13, k32, k20, 1.0 / prm["A"]


def three_tank_rhs(k, s, u, sign, sqrt, fabs):
    """dh/dt of the three-tank as three expressions, with a library's sign, sqrt and abs."""
    k13, k32, k20, ia = k
    d13, d32 = s[0] - s[2], s[2] - s[1]
    f13 = k13 * sign(d13) * sqrt(fabs(d13))
    f32 = k32 * sign(d32) * sqrt(fabs(d32))
    return u[0] * ia - f13, u[1] * ia + f32 - k20 * sqrt(s[1]), f13 - f32


def network_constants(plant):
    """Hand constants of tank_network(N): f(h, u) = -c sqrt(h) + c_in sqrt(h[src]) + B u."""
    p = {q.name: float(q.value) for q in plant.parameters}
    n, m = plant.n, plant.m
    half = n // 2
    r2g = math.sqrt(2.0 * p["g"])
    c = np.array([p[f"a{i}"] * r2g / p[f"A{i}"] for i in range(1, n + 1)])
    src = np.full(n, -1, dtype=np.int64)
    cin = np.zeros(n)
    B = np.zeros((n, m))
    for i in range(half):                              # lower tank i <- upper tank half + i
        src[i] = half + i
        cin[i] = p[f"a{half + i + 1}"] * r2g / p[f"A{i + 1}"]
        B[i, i] = p[f"gamma{i + 1}"] * p[f"k{i + 1}"] / p[f"A{i + 1}"]
    B[half, half - 1] = (1 - p[f"gamma{half}"]) * p[f"k{half}"] / p[f"A{half + 1}"]
    for i in range(half + 1, n):                       # upper tank i <- pump i - half - 1
        j = i - half - 1
        B[i, j] = (1 - p[f"gamma{j + 1}"]) * p[f"k{j + 1}"] / p[f"A{i + 1}"]
    return c, src, cin, B


def network_problem(N: int = 16) -> Problem:
    """tank_network(N) at 4 V on every pump, lower tanks tracked, discrete LQR gains."""
    from scipy.linalg import expm, solve_discrete_are

    plant = tank_network(N)
    c, src, cin, B = network_constants(plant)
    n, m = plant.n, plant.m
    u0 = np.full(m, 4.0)
    half = n // 2
    x0 = np.zeros(n)                                   # equilibrium, upper tanks first
    inflow = B @ u0
    x0[half:] = (inflow[half:] / c[half:]) ** 2
    x0[:half] = ((cin[:half] * np.sqrt(x0[half:]) + inflow[:half]) / c[:half]) ** 2

    def f(x, u):
        return -c * np.sqrt(x) + cin * np.where(src >= 0, np.sqrt(x[src]), 0.0) + B @ u

    A = np.empty((n, n))
    for j in range(n):
        d = np.zeros(n)
        d[j] = 1e-6 * x0[j]
        A[:, j] = (f(x0 + d, u0) - f(x0 - d, u0)) / (2 * d[j])
    ts = 1.0
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = A * ts, B * ts
    E = expm(big)
    Ad, Bd = E[:n, :n], E[:n, n:]
    C1 = np.eye(n)[:half]
    p = C1.shape[0]
    Aa = np.block([[Ad, np.zeros((n, p))], [-ts * C1, np.eye(p)]])
    Ba = np.vstack([Bd, np.zeros((p, m))])
    Qa, Ra = np.eye(n + p), np.eye(m)
    S = solve_discrete_are(Aa, Ba, Qa, Ra)
    K = np.linalg.solve(Ra + Ba.T @ S @ Ba, Ba.T @ S @ Aa)
    law = IntegralStateFeedback(K[:, :n], K[:, n:], C1, x0, u0, ts)
    setup = SCENARIOS["servo"].setup(plant, x0, u0, tuple(range(half)), ts=ts)
    return Problem(f"tank_network_{N}", plant, law, setup, ts, 0.01)


# --------------------------------------------------------------------------- numba
def build_numba(pb: Problem):
    """(serial, prange) numba kernels X (M, N + 1, n) = run(X0, W) for the problem."""
    import numba as nb

    n, m = pb.plant.n, pb.plant.m
    N, ts, h = pb.N, pb.ts, pb.ts / SUBSTEPS
    K1, K2, C1, x0c, u0c, ref = pb.K1, pb.K2, pb.C1, pb.x0, pb.u0, pb.ref
    xlo, xhi = pb.xlo, pb.xhi
    p = C1.shape[0]
    ulo, uhi = input_range(pb)
    if pb.name == "three_tank":
        k13, k32, k20, ia = three_tank_constants(pb.plant)

        @nb.njit(inline="always")
        def rhs(s, u, out):
            d13, d32 = s[0] - s[2], s[2] - s[1]
            f13 = k13 * math.copysign(math.sqrt(abs(d13)), d13)
            f32 = k32 * math.copysign(math.sqrt(abs(d32)), d32)
            out[0] = u[0] * ia - f13
            out[1] = u[1] * ia + f32 - k20 * math.sqrt(s[1])
            out[2] = f13 - f32
    else:
        c, src, cin, B = network_constants(pb.plant)

        @nb.njit(inline="always")
        def rhs(s, u, out):
            for i in range(n):
                v = -c[i] * math.sqrt(s[i])
                if src[i] >= 0:
                    v += cin[i] * math.sqrt(s[src[i]])
                for j in range(m):
                    v += B[i, j] * u[j]
                out[i] = v

    @nb.njit(inline="always")
    def clip(v, i):
        return min(max(v, xlo[i]), xhi[i])

    @nb.njit
    def one_run(x_init, W, X):
        x = x_init.copy()
        z = np.zeros(p)
        u = np.empty(m)
        st = np.empty(n)
        k1, k2, k3, k4 = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
        for k in range(N + 1):
            X[k] = x
            if k == N:
                break
            for i in range(m):
                v = u0c[i]
                for j in range(n):
                    v -= K1[i, j] * (x[j] - x0c[j])
                for j in range(p):
                    v -= K2[i, j] * z[j]
                u[i] = min(max(v, ulo[i]), uhi[i])
            for i in range(p):
                e = ref[k, i]
                for j in range(n):
                    e -= C1[i, j] * x[j]
                z[i] += ts * e
            for _ in range(SUBSTEPS):
                for i in range(n):
                    st[i] = clip(x[i], i)
                rhs(st, u, k1)
                for i in range(n):
                    st[i] = clip(k1[i] * (0.5 * h) + x[i], i)
                rhs(st, u, k2)
                for i in range(n):
                    st[i] = clip(k2[i] * (0.5 * h) + x[i], i)
                rhs(st, u, k3)
                for i in range(n):
                    st[i] = clip(k3[i] * h + x[i], i)
                rhs(st, u, k4)
                for i in range(n):
                    x[i] = clip(x[i] + (k2[i] * 2.0 + k1[i] + k3[i] * 2.0 + k4[i]) * (h / 6.0), i)
            for i in range(n):
                x[i] = clip(x[i] + W[k, i], i)

    def runs(X0, W):
        M = X0.shape[0]
        X = np.empty((M, N + 1, n))
        for r in nb.prange(M):            # a plain range in the serial compilation
            one_run(X0[r], W[r], X[r])
        return X

    serial = nb.njit(runs)
    parallel = nb.njit(parallel=True)(runs)
    return serial, parallel


def input_range(pb: Problem):
    prm = {q.name: float(q.value) for q in pb.plant.parameters}
    m = pb.plant.m
    top = prm["qmax"] if "qmax" in prm else prm["usat"]
    return np.zeros(m), np.full(m, top)


# --------------------------------------------------------------------------- JAX
def build_jax(pb: Problem):
    """jit(vmap(scan)) over runs: X (M, N + 1, n) = run(X0, W)."""
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    n = pb.plant.n
    N, ts, h = pb.N, pb.ts, pb.ts / SUBSTEPS
    K1, K2, C1, x0c, u0c = (jnp.asarray(a) for a in (pb.K1, pb.K2, pb.C1, pb.x0, pb.u0))
    ref = jnp.asarray(pb.ref)
    xlo, xhi = jnp.asarray(pb.xlo), jnp.asarray(pb.xhi)
    ulo, uhi = (jnp.asarray(a) for a in input_range(pb))
    if pb.name == "three_tank":
        kc = three_tank_constants(pb.plant)

        def rhs(s, u):
            return jnp.stack(three_tank_rhs(kc, s, u, jnp.sign, jnp.sqrt, jnp.abs))
    else:
        c, src, cin, B = network_constants(pb.plant)
        c, cin, B = jnp.asarray(c), jnp.asarray(cin), jnp.asarray(B)
        has = jnp.asarray(src >= 0)
        srcj = jnp.asarray(np.where(src >= 0, src, 0))

        def rhs(s, u):
            sq = jnp.sqrt(s)
            return -c * sq + jnp.where(has, cin * sq[srcj], 0.0) + B @ u

    def clip(v):
        return jnp.minimum(jnp.maximum(v, xlo), xhi)

    def period(carry, inp):
        x, z = carry
        r, w = inp
        u = clip_u(u0c - K1 @ (x - x0c) - K2 @ z)
        z = z + ts * (r - C1 @ x)
        for _ in range(SUBSTEPS):
            k1 = rhs(clip(x), u)
            k2 = rhs(clip(k1 * (0.5 * h) + x), u)
            k3 = rhs(clip(k2 * (0.5 * h) + x), u)
            k4 = rhs(clip(k3 * h + x), u)
            x = clip(x + (k2 * 2.0 + k1 + k3 * 2.0 + k4) * (h / 6.0))
        x = clip(x + w)
        return (x, z), x

    def clip_u(v):
        return jnp.minimum(jnp.maximum(v, ulo), uhi)

    def one(x_init, W):
        _, xs = jax.lax.scan(period, (x_init, jnp.zeros(C1.shape[0])), (ref[:-1], W))
        return jnp.concatenate([x_init[None], xs], axis=0)

    fn = jax.jit(jax.vmap(one))

    def run(X0, W):
        return np.asarray(fn(jnp.asarray(X0), jnp.asarray(W)).block_until_ready())
    return run


# --------------------------------------------------------------------------- CasADi
def build_casadi(pb: Problem, M: int):
    """Period Function compiled with jit=True, mapaccum over N, map over M runs."""
    import casadi as ca

    n, m = pb.plant.n, pb.plant.m
    N, ts, h = pb.N, pb.ts, pb.ts / SUBSTEPS
    p = pb.C1.shape[0]
    ulo, uhi = input_range(pb)
    x = ca.SX.sym("x", n)
    z = ca.SX.sym("z", p)
    r = ca.SX.sym("r", p)
    w = ca.SX.sym("w", n)
    xlo, xhi = pb.xlo, pb.xhi

    def clip(v):
        return ca.vertcat(*[ca.fmin(ca.fmax(v[i], xlo[i]), xhi[i]) if np.isfinite(xhi[i])
                            else ca.fmax(v[i], xlo[i]) for i in range(n)])

    if pb.name == "three_tank":
        kc = three_tank_constants(pb.plant)

        def rhs(s, u):
            return ca.vertcat(*three_tank_rhs(kc, s, u, ca.sign, ca.sqrt, ca.fabs))
    else:
        c, src, cin, B = network_constants(pb.plant)

        def rhs(s, u):
            out = []
            for i in range(n):
                v = -c[i] * ca.sqrt(s[i])
                if src[i] >= 0:
                    v += cin[i] * ca.sqrt(s[int(src[i])])
                out.append(v + ca.mtimes(ca.DM(B[i:i + 1]), u))
            return ca.vertcat(*out)

    v = ca.DM(pb.u0) - ca.mtimes(ca.DM(pb.K1), x - ca.DM(pb.x0)) - ca.mtimes(ca.DM(pb.K2), z)
    u = ca.vertcat(*[ca.fmin(ca.fmax(v[i], ulo[i]), uhi[i]) for i in range(m)])
    zn = z + ts * (r - ca.mtimes(ca.DM(pb.C1), x))
    xs = x
    for _ in range(SUBSTEPS):
        k1 = rhs(clip(xs), u)
        k2 = rhs(clip(k1 * (0.5 * h) + xs), u)
        k3 = rhs(clip(k2 * (0.5 * h) + xs), u)
        k4 = rhs(clip(k3 * h + xs), u)
        xs = clip(xs + (k2 * 2.0 + k1 + k3 * 2.0 + k4) * (h / 6.0))
    xs = clip(xs + w)
    opts = {"jit": True, "compiler": "shell", "jit_options": {"flags": ["-O2"], "verbose": False}}
    with scratch_cwd():
        step = ca.Function("period", [ca.vertcat(x, z), ca.vertcat(r, w)], [ca.vertcat(xs, zn)], opts)
    horizon = step.mapaccum("horizon", N)
    runs = horizon if M == 1 else horizon.map(M, "thread", 2)

    def run(X0, W):
        XZ0 = np.vstack([X0.T, np.zeros((p, M))])                  # (n + p, M)
        RW = np.concatenate([np.vstack([pb.ref[:-1].T, W[r].T]) for r in range(M)],
                            axis=1)                                  # (p + n, N M), run-major
        out = np.asarray(runs(XZ0, RW))[:n]                          # (n, N M), run-major
        return np.concatenate([X0[:, None, :], out.T.reshape(M, N, n)], axis=1)
    return run


# --------------------------------------------------------------------------- numpy
def build_numpy(pb: Problem):
    """Loop over samples, vectorised over runs (rows (n, M))."""
    n = pb.plant.n
    N, ts, h = pb.N, pb.ts, pb.ts / SUBSTEPS
    ulo, uhi = input_range(pb)
    lo, hi = pb.xlo[:, None], pb.xhi[:, None]
    if pb.name == "three_tank":
        k13, k32, k20, ia = three_tank_constants(pb.plant)

        def rhs(s, u):
            d13, d32 = s[0] - s[2], s[2] - s[1]
            f13 = k13 * np.copysign(np.sqrt(np.abs(d13)), d13)
            f32 = k32 * np.copysign(np.sqrt(np.abs(d32)), d32)
            return np.stack([u[0] * ia - f13, u[1] * ia + f32 - k20 * np.sqrt(s[1]), f13 - f32])
    else:
        c, src, cin, B = network_constants(pb.plant)
        has = src >= 0
        srcs = src[has]
        cc, cinc = c[:, None], cin[has][:, None]

        def rhs(s, u):
            sq = np.sqrt(s)
            out = B @ u - cc * sq
            out[has] += cinc * sq[srcs]
            return out

    def run(X0, W):
        M = X0.shape[0]
        X = np.empty((N + 1, n, M))
        x = np.array(X0.T)
        z = np.zeros((pb.C1.shape[0], M))
        for k in range(N):
            X[k] = x
            u = np.clip(pb.u0[:, None] - pb.K1 @ (x - pb.x0[:, None]) - pb.K2 @ z,
                        ulo[:, None], uhi[:, None])
            z = z + ts * (pb.ref[k][:, None] - pb.C1 @ x)
            for _ in range(SUBSTEPS):
                k1 = rhs(np.clip(x, lo, hi), u)
                k2 = rhs(np.clip(k1 * (0.5 * h) + x, lo, hi), u)
                k3 = rhs(np.clip(k2 * (0.5 * h) + x, lo, hi), u)
                k4 = rhs(np.clip(k3 * h + x, lo, hi), u)
                x = np.clip(x + (k2 * 2.0 + k1 + k3 * 2.0 + k4) * (h / 6.0), lo, hi)
            x = np.clip(x + W[:, k].T, lo, hi)
        X[N] = x
        return X.transpose(2, 0, 1)
    return run


# --------------------------------------------------------------------------- driver
def measure(pb: Problem, M: int, reps: int, quick: bool, floors: Floors) -> dict:
    seeds = run_seeds(0, M)
    X0 = np.tile(np.asarray(pb.setup.x0, float), (M, 1))
    W = pb.noise(seeds)
    ours = lambda: pb.tanksynth(seeds).x  # noqa: E731
    t0 = time.perf_counter()
    if os.environ.get("TANKSYNTH_SIM_BACKEND") is None and M not in pb.built:
        # build the library's kernels for this loop now (as a campaign's first block would),
        # timed here, not in the reps; the default setting then loads them
        with environ(TANKSYNTH_SIM_BACKEND="native"):
            pb.tanksynth(seeds)
        pb.built.add(M)
    res = pb.tanksynth(seeds)
    first = {"tanksynth": time.perf_counter() - t0}
    ref = np.asarray(res.x)
    # warm-up: the library may build a compiled kernel once enough work has gone through a law;
    # the route of every warm-up call is recorded, and the one after the timed reps
    warm = [res.backend] + [pb.tanksynth(seeds).backend for _ in range(2)]
    builders = {}
    try:
        serial, parallel = build_numba(pb)
        builders["numba"] = lambda: (lambda: serial(X0, W))
        if M > 1:
            builders["numba_prange"] = lambda: (lambda: parallel(X0, W))
    except ImportError:
        print("  numba not installed (pip install -e '.[bench]'): skipped")
    try:
        import jax  # noqa: F401
        builders["jax"] = lambda: (lambda f=build_jax(pb): f(X0, W))
    except ImportError:
        print("  jax not installed (pip install -e '.[bench]'): skipped")
    builders["casadi_jit"] = lambda: (lambda f=build_casadi(pb, M): f(X0, W))
    builders["numpy"] = lambda: (lambda f=build_numpy(pb): f(X0, W))
    contenders = {"tanksynth": ours}
    errors = {}
    if os.environ.get("TANKSYNTH_SIM_BACKEND") is None:
        def ours_numpy():
            with environ(TANKSYNTH_SIM_BACKEND="numpy"):   # the library's period-by-period path
                return pb.tanksynth(seeds).x
        builders["tanksynth_numpy"] = lambda: ours_numpy
    for name, make in builders.items():
        t0 = time.perf_counter()
        fn = make()
        out = np.asarray(fn())
        first[name] = time.perf_counter() - t0
        errors[name] = float(np.max(np.abs(out - ref))) * pb.unit_m
        contenders[name] = fn
    times = interleave(contenders, reps)
    after = pb.tanksynth(seeds).backend
    if after != warm[-1]:
        print(f"  NOTE: tanksynth's route changed during the reps: {warm[-1]} -> {after}")
    row = {"plant": pb.name, "M": M, "N": pb.N, "n": pb.plant.n, "backend": after,
           "backend_warmup": warm,
           "first_call_s": first, "errors_m": errors, "times": times,
           "summary": {k: summary(v) for k, v in times.items()}, "ratios": {}}
    print(f"\n{pb.name}, M = {M}, N = {pb.N} (tanksynth backend {after}; warm-up "
          f"{' / '.join(warm)}):")
    for name, t in times.items():
        s = summary(t)
        extra = f"   max |x - tanksynth| {errors[name]:.1e} m" if name in errors else ""
        print(f"  {name:13s} min {s['min'] * 1e3:9.3f} ms  median {s['median'] * 1e3:9.3f} ms"
              f"  (first call {first[name]:.2f} s){extra}")
    for name in times:
        if name == "tanksynth":
            continue
        r = ratios(times[name], times["tanksynth"])
        row["ratios"][name] = r
        print(f"  {name:13s} / tanksynth per rep: " + " ".join(f"{v:.3f}" for v in r)
              + f"   min {min(r):.3f} median {statistics.median(r):.3f}")
    for name, e in errors.items():
        if e > AGREE:
            print(f"  DISAGREE: {name} differs from tanksynth by {e:.2e} m")
            floors.rows.append({"what": f"agreement {name} {pb.name} M={M}", "ok": False})
    strongest = "numba" if M == 1 else "jax"
    if strongest in row["ratios"]:
        floors.check(f"{pb.name} M={M} vs {strongest}", statistics.median(row["ratios"][strongest]),
                     1.0, strict_only=True)
    return row


def main() -> int:
    """Run the benchmark; exit 1 on a disagreement (and on a floor miss with --strict)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--record", default="closed_loop",
                    help="name of the JSON record in benchmarks/results (default %(default)s)")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--three-tank", type=int, nargs="*", default=[1, 200, 10000])
    ap.add_argument("--network", type=int, nargs="*", default=[1, 200])
    ap.add_argument("--quick", action="store_true", help="3 reps")
    ap.add_argument("--strict", action="store_true", help="exit 1 on a floor miss")
    args = ap.parse_args()
    reps = 3 if args.quick else max(args.reps, 3)
    before = machine()
    floors = Floors()
    rows = []
    print(f"closed loop (servo scenario, {SUBSTEPS} RK4 steps per sample); {reps} interleaved reps; "
          f"load {before['loadavg']}; TANKSYNTH_SIM_BACKEND="
          f"{os.environ.get('TANKSYNTH_SIM_BACKEND', '(unset)')}")
    with tempfile.TemporaryDirectory(prefix="tanksynth-bench-") as tmp:
        os.environ.setdefault("TANKSYNTH_CACHE_DIR", str(Path(tmp) / "cache"))
        problems = []
        if args.three_tank:
            problems.append((three_tank_problem(Path(tmp)), args.three_tank))
        if args.network:
            problems.append((network_problem(16), args.network))
        for pb, sizes in problems:
            for M in sizes:
                rows.append(measure(pb, M, reps, args.quick, floors))
    path = write_record(args.record, {"reps": reps, "quick": args.quick, "substeps": SUBSTEPS,
                                        "env_backend": os.environ.get("TANKSYNTH_SIM_BACKEND"),
                                        "rows": rows, "floors": floors.rows}, before)
    print(f"\nrecord: {path}")
    return floors.exit_status(args.strict)


if __name__ == "__main__":
    sys.exit(main())
