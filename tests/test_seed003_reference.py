"""Seed 003 (DECENTER N-tank network): decentralised one-step / finite-horizon filters.

The constants come from ``examples/seed003_tank_network.toml`` (N = 40,
dT = 1 s, dTlin = 10, window 40, epsl = 1e-6, maxOLIt = 100, E = I,
P0 = 10 I, R = 4 I cm^2 = I V^2 at kc = 0.5 V/cm, the declared dense Q). The
simulation follows the seed's script: 20 cm in every tank, open-loop pumps at
6 V then 4 V after 400 s, 800 s, seed 7; the true plant is the nonlinear
model (RK4, levels kept >= 0) with Van Loan process noise; three filters run
on the same measurements:

centralised    `centralized_gain`
one-step       `one_step_gains` with E = I
finite horizon `finite_horizon_gains` (iterative route) window by window, the
               window's models linearised along the trajectory predicted from
               the estimate at the window start (DECENTER's scheme)

All three propagate their estimate with the model relinearised at their own
estimate every dTlin steps, so that they differ by their gains only. The
seed's script propagates the finite-horizon estimate with the window's models
instead (its "Finite-horizon (propagated)"); that variant is run as well and
only required to stay bounded and close: in our runs (seeds 0-5, 7) its RMSE
is between 0.3 % better and 2 % worse than one-step's (worse in 6 of 7), which
comes from the open-loop linearisation points of the mean, not from the gains.

What is asserted, and why. With every tank measured and E = I the
finite-horizon gains barely differ from the one-step gains: their expected
window costs differ by at most about 2e-4 relative. The ordering centralised <= FH <=
one-step is asserted strictly on the expected costs, window by window on the
same models. On the RMSE, centralised vs decentralised is a clear gap (5-15 %
with the correlated process noise), while FH vs one-step is within noise: over
seeds 0-5 and 7, RMSE(FH) / RMSE(one-step) - 1 ranged from -3.2e-3 to
+3.6e-4. At the seed script's own seed (7) FH is below one-step (by 5e-4),
which is asserted, together with the seed-independent bound of 5e-3.
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from tanksynth.design.decentralized.gains import (centralized_gain, equicorrelated_intensity,
                                            finite_horizon_gains, linear_model, one_step_gains,
                                            own_tank_pattern, window_models)
from tanksynth.methods import load_spec
from tanksynth.papers import seed003 as paper

SPEC = Path(__file__).resolve().parents[1] / "examples" / "seed003_tank_network.toml"

# Scenario of the seed's script (NTanksNetworkEstimationOSFH), see the TOML header.
X0_LEVEL = paper.X0_LEVEL                                             # cm, every tank
U_FIRST, U_SECOND, T_SWITCH = paper.PUMP_FIRST, paper.PUMP_SECOND, paper.T_SWITCH   # V, V, s
DURATION = paper.DURATION                                             # steps of dT = 1 s
SEED = paper.RANDOM_SEED


def _rk4_step(plant, ts: float, substeps: int = 4) -> ca.Function:
    """One ZOH step of the nonlinear plant by RK4 (levels clipped at 0: Torricelli)."""
    x = ca.SX.sym("x", plant.n)
    u = ca.SX.sym("u", plant.m)
    f = plant.compiled.f
    h = ts / substeps
    z = x
    for _ in range(substeps):
        k1 = f(z, u)
        k2 = f(ca.fmax(z + h / 2 * k1, 0), u)
        k3 = f(ca.fmax(z + h / 2 * k2, 0), u)
        k4 = f(ca.fmax(z + h * k3, 0), u)
        z = ca.fmax(z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), 0)
    return ca.Function("rk4_step", [x, u], [z])


def _simulate_network(spec, seed: int = SEED, steps: int = DURATION) -> dict:
    """The seed's simulation: truth, measurements and the three filters (private)."""
    plant, ts = spec.plant, spec.ts
    opt = spec.designs[0].options
    n, m = plant.n, plant.m
    Qc = equicorrelated_intensity(n, opt["process_noise"], opt["process_noise_correlation"])
    R = opt["measurement_noise"] * np.eye(plant.q)
    P0 = opt["initial_covariance"] * np.eye(n)
    relin, W = opt["relinearize_every"], opt["window"]
    E = own_tank_pattern(plant)
    step = _rk4_step(plant, ts)

    def u_of(k: int) -> np.ndarray:
        return np.full(m, U_FIRST if k * ts < T_SWITCH else U_SECOND)

    rng = np.random.default_rng(seed)
    x = np.full(n, X0_LEVEL)
    xhat0 = x + np.linalg.cholesky(P0) @ rng.standard_normal(n)
    X, Y = [], []
    for k in range(steps):
        u = u_of(k)
        if k % relin == 0:   # process-noise covariance at the true state (DECENTER)
            Lq = np.linalg.cholesky(linear_model(plant, x, u, ts, Qc, R).Q)
        x = np.maximum(np.asarray(step(x, u)).ravel() + Lq @ rng.standard_normal(n), 0.0)
        X.append(x)
        Y.append(x + np.sqrt(opt["measurement_noise"]) * rng.standard_normal(plant.q))
    X, Y = np.array(X), np.array(Y)

    est: dict[str, np.ndarray] = {}
    for name in ("centralized", "one_step"):
        xh, P, out = xhat0.copy(), P0.copy(), []
        for k in range(steps):
            u = u_of(k)
            if k % relin == 0:
                model = linear_model(plant, xh, u, ts, Qc, R)
            xp = model.predict(xh, u)
            Pp = model.A @ P @ model.A.T + model.Q
            st = (centralized_gain(model.A, model.C, model.Q, model.R, Pp) if name == "centralized"
                  else one_step_gains(model.A, model.C, model.Q, model.R, E, Pp))
            xh = xp + st.K @ (Y[k] - model.output(xp))
            P = st.P_filt
            out.append(xh)
        est[name] = np.array(out)

    def finite_horizon(decenter_mean: bool) -> tuple[np.ndarray, list[dict]]:
        windows: list[dict] = []
        xh, P, out = xhat0.copy(), P0.copy(), []
        for s in range(0, steps, W):
            T = min(W, steps - s)
            models, _ = window_models(plant, xh, np.array([u_of(s + j) for j in range(T + 1)]),
                                      ts, Qc, R, relinearize_every=relin)
            seqs = ([mo.A for mo in models[1:]], [mo.C for mo in models[1:]],
                    [mo.Q for mo in models[1:]], [mo.R for mo in models[1:]])
            P0_pred = models[0].A @ P @ models[0].A.T + models[0].Q
            res = finite_horizon_gains(*seqs, E, P0_pred, method="iterative",
                                       tol=opt["tolerance"], max_iter=opt["max_iter"])
            cen, Pp = 0.0, P0_pred
            for k in range(T):
                c = centralized_gain(seqs[0][k], seqs[1][k], seqs[2][k], seqs[3][k], Pp)
                cen, Pp = cen + c.cost, c.P_pred_next
            windows.append({"fh": res.cost, "one_step": res.one_step_cost, "centralized": cen,
                            "converged": res.converged,
                            "masked_zero": all(np.all(K[E == 0] == 0.0) for K in res.K)})
            for j in range(1, T + 1):
                k = s + j - 1
                if decenter_mean:      # the window's models, along the predicted trajectory
                    model, out_model = models[j - 1], models[j]
                elif k % relin == 0:   # relinearised at the estimate, as the other filters
                    model = out_model = linear_model(plant, xh, u_of(k), ts, Qc, R)
                xp = model.predict(xh, u_of(k))
                xh = xp + res.K[j - 1] @ (Y[k] - out_model.output(xp))
                out.append(xh)
            P = res.P[-1]
        return np.array(out), windows

    est["finite_horizon"], windows = finite_horizon(decenter_mean=False)
    est["finite_horizon_propagated"], _ = finite_horizon(decenter_mean=True)
    rmse = {k: float(np.sqrt(np.mean((v - X) ** 2))) for k, v in est.items()}
    rmse["measurement"] = float(np.sqrt(np.mean((Y - X) ** 2)))
    return {"X": X, "est": est, "rmse": rmse, "windows": windows}


@pytest.fixture(scope="module")
def spec():
    return load_spec(SPEC)


@pytest.fixture(scope="module")
def run(spec):
    return _simulate_network(spec)


def test_example_constants(spec):
    plant = spec.plant
    assert plant.name == "tank_network" and plant.n == paper.N and plant.m == paper.N // 2
    assert spec.ts == paper.TS
    fh, os_ = spec.designs
    o = fh.options
    assert (o["algorithm"], o["window"], o["tolerance"], o["max_iter"]) == (
        "casadi", paper.WINDOW, paper.TOLERANCE, paper.MAX_ITERATIONS)
    assert o["relinearize_every"] == paper.RELINEARIZE_EVERY and o["E"] == "own_tank"
    np.testing.assert_array_equal(own_tank_pattern(plant), np.eye(40))
    kc = plant.parameter("kc").value
    assert o["measurement_noise"] == pytest.approx(1.0 / kc**2)      # R = I V^2 at C = kc I
    assert o["initial_covariance"] == paper.P0
    assert os_.options["algorithm"] == "one_step"
    vals = {p.name: p.value for p in plant.parameters}
    assert tuple(vals[f"A{i}"] for i in (1, 2)) == paper.TANK_AREAS
    assert tuple(vals[f"a{i}"] for i in (1, 2)) == paper.OUTLET_AREAS
    assert vals["a21"] == vals["a40"] == paper.UPPER_OUTLET_AREA
    assert tuple(vals[f"gamma{j}"] for j in (1, 2)) == paper.VALVE_SPLITS
    assert vals["k1"] == paper.PUMP_GAIN and vals["g"] == paper.G and kc == paper.SENSOR_GAIN
    assert spec.x0[:paper.N // 2].tolist() == [paper.X0_LEVEL] * (paper.N // 2)


@pytest.mark.slow
def test_windows_order_centralized_fh_one_step(run):
    """Expected costs on the same models: centralised <= FH <= one-step, every window."""
    assert len(run["windows"]) == DURATION // 40
    for w in run["windows"]:
        assert w["converged"] and w["masked_zero"]
        assert w["centralized"] <= w["fh"] <= w["one_step"]
        assert w["centralized"] < w["one_step"] * (1 - 1e-2)


@pytest.mark.slow
def test_rmse_ordering_and_bounded(run):
    r = run["rmse"]
    for name in ("centralized", "one_step", "finite_horizon", "finite_horizon_propagated"):
        assert np.all(np.isfinite(run["est"][name]))
        # bounded, and far better than the raw measurements (2 cm standard deviation)
        assert r[name] < 0.5 * r["measurement"]
        err = np.abs(run["est"][name] - run["X"])
        assert err[DURATION // 2:].max() < 3.0
    assert r["centralized"] < r["one_step"] * (1 - 2e-2)
    assert r["centralized"] < r["finite_horizon"] * (1 - 2e-2)
    assert r["finite_horizon"] <= r["one_step"] * (1 + 5e-3)     # any seed (see docstring)
    assert r["finite_horizon"] <= r["one_step"]                  # the seed's rng(7)
    assert r["finite_horizon_propagated"] <= r["one_step"] * (1 + 3e-2)


@pytest.mark.slow
def test_first_window_routes_agree(spec):
    """The spec's first window (N = 40, 40 steps, 6 V): casadi and iterative costs agree."""
    opt = spec.designs[0].options
    plant = spec.plant
    Qc = equicorrelated_intensity(plant.n, opt["process_noise"], opt["process_noise_correlation"])
    R = opt["measurement_noise"] * np.eye(plant.q)
    models, _ = window_models(plant, spec.x0, np.full((41, plant.m), 6.0), spec.ts, Qc, R)
    P0 = models[0].A @ (opt["initial_covariance"] * np.eye(plant.n)) @ models[0].A.T + models[0].Q
    seqs = ([mo.A for mo in models[1:]], [mo.C for mo in models[1:]], [mo.Q for mo in models[1:]],
            [mo.R for mo in models[1:]])
    it = finite_horizon_gains(*seqs, np.eye(40), P0, method="iterative")
    cas = finite_horizon_gains(*seqs, np.eye(40), P0, method="casadi")
    assert it.converged and cas.converged
    assert abs(cas.cost - it.cost) <= 1e-6 * it.cost
    assert cas.cost <= cas.one_step_cost
