"""Seed 003's 800-sample simulation as a verdict (`run_steps`), against the example's constants.

The gains of the verdict's filters are checked against a numerical minimisation of
``tr P(k|k)`` (scipy) over the free entries; the run against `tanksynth.papers.seed003`
(samples, seed, pump switch, initial level) and against the sensors' own noise (R = 4 cm^2:
the measurement RMSE is 2 cm up to sampling error).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize

from tanksynth.cli import main
from tanksynth.papers import seed003 as paper
from tanksynth.reports import compare_with_papers, read_report_inputs
from tanksynth.reports.paper import AGREES
from tanksynth.design.decentralized.gains import (equicorrelated_intensity, finite_horizon_gains,
                                                  own_tank_pattern, window_models)
from tanksynth.methods import parse_spec_text
from tanksynth.verify.decentralized.long_run import (centralized_gain_of, finite_horizon_gain_sequence,
                                                     one_step_gain)

_EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "seed003_tank_network.toml"


def _posterior_trace(K, P, C, R):
    IKC = np.eye(P.shape[0]) - K @ C
    return np.trace(IKC @ P @ IKC.T + K @ R @ K.T)


@pytest.mark.parametrize("pattern", ["dense", "mixed"])
def test_gains_minimise_the_posterior_trace(pattern):
    rng = np.random.default_rng(3)
    n, q = 4, 3
    G = rng.standard_normal((n, n))
    P = G @ G.T + n * np.eye(n)
    C = rng.standard_normal((q, n))
    H = rng.standard_normal((q, q))
    R = H @ H.T + np.eye(q)
    E = np.ones((n, q)) if pattern == "dense" else np.array([[1, 0, 0], [0, 1, 1], [1, 0, 1], [0, 0, 1]])
    free = np.flatnonzero(E.ravel())

    def cost(v):
        K = np.zeros(n * q)
        K[free] = v
        return _posterior_trace(K.reshape(n, q), P, C, R)

    best = minimize(cost, np.zeros(free.size), method="BFGS", options={"gtol": 1e-12}).x
    K = one_step_gain(P, C, R, E)
    np.testing.assert_allclose(K.ravel()[free], best, rtol=1e-5, atol=1e-7)
    assert np.all(K[E == 0] == 0)
    if pattern == "dense":
        np.testing.assert_allclose(centralized_gain_of(P, C, R), K, rtol=1e-10)


def _assert_same_gains(A, C, Q, R, E, P1, tol, max_iter):
    ours, P_filt, its, conv = finite_horizon_gain_sequence(A, C, Q, R, E, P1, tol, max_iter)
    design = finite_horizon_gains(A, C, Q, R, E, P1, method="iterative", tol=tol, max_iter=max_iter)
    assert conv and design.converged and its == design.iterations
    scale = max(float(np.max(np.abs(K))) for K in design.K)
    for k, (a, b) in enumerate(zip(ours, design.K)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * scale, err_msg=f"K_{k + 1}")
        assert np.all(a[np.asarray(E) == 0] == 0)
    np.testing.assert_allclose(P_filt[-1], design.P[-1], rtol=1e-9)


@pytest.mark.parametrize("tol", [1e-6, 1e-12])
def test_finite_horizon_gains_match_the_design_on_a_random_window(tol):
    """The verify-side sweeps against the design's solver: same window, same gains to 1e-9."""
    rng = np.random.default_rng(5)
    n, q, T = 5, 4, 12
    E = np.array([[1, 0, 0, 0], [0, 1, 1, 0], [1, 0, 0, 1], [0, 0, 1, 0], [0, 1, 0, 1]])
    A = [np.eye(n) + 0.3 * rng.standard_normal((n, n)) for _ in range(T)]
    C = [rng.standard_normal((q, n)) for _ in range(T)]
    Q = []
    for _ in range(T):
        G = rng.standard_normal((n, n))
        Q.append(0.1 * G @ G.T + 0.01 * np.eye(n))
    R = [np.diag(rng.uniform(0.5, 2.0, q)) for _ in range(T)]
    _assert_same_gains(A, C, Q, R, E, 10.0 * np.eye(n), tol, 200)


def test_finite_horizon_gains_match_the_design_on_the_first_seed003_window():
    """Seed 003's first 40-sample window (the design's window models): same gains to 1e-9."""
    spec = parse_spec_text(_EXAMPLE.read_text(), source=str(_EXAMPLE))
    plant = spec.plant
    n, m = plant.n, plant.m
    Qc = equicorrelated_intensity(n, 0.01, 0.5)
    R = 4.0 * np.eye(n)
    u = np.full((paper.WINDOW + 1, m), paper.PUMP_FIRST)
    models, _ = window_models(plant, np.full(n, paper.X0_LEVEL), u, paper.TS, Qc, R,
                              relinearize_every=paper.RELINEARIZE_EVERY)
    w = models[1:]
    P1 = models[0].A @ (paper.P0 * np.eye(n)) @ models[0].A.T + models[0].Q
    _assert_same_gains([mo.A for mo in w], [mo.C for mo in w], [mo.Q for mo in w], [mo.R for mo in w],
                       own_tank_pattern(plant), P1, paper.TOLERANCE, paper.MAX_ITERATIONS)


@pytest.mark.slow
def test_800_sample_run_against_the_example(tmp_path):
    assert main(["run", str(_EXAMPLE), "-o", str(tmp_path), "--no-pdf"]) == 0
    doc = json.loads((tmp_path / "decentralized_one_step.json").read_text())
    check = next(c for c in doc["verification"]["checks"] if c["check"] == "long_run")
    d = check["data"]
    assert check["passed"] is True
    assert (d["steps"], d["seed"], d["input_switch_s"]) == (paper.DURATION, paper.RANDOM_SEED,
                                                           paper.T_SWITCH)
    assert d["relinearize_every"] == paper.RELINEARIZE_EVERY
    assert d["x0"] == [paper.X0_LEVEL] * paper.N
    r = d["rmse"]
    # R = 4 cm^2 (kc = 0.5 V/cm, R = I V^2): the sensors' RMSE is 2 cm; 32000 samples
    assert r["measurement"] == pytest.approx(2.0, rel=0.02)
    assert r["centralized"] < r["one_step"] < 0.5 * r["measurement"]
    assert d["trace_P"]["centralized"] < d["trace_P"]["one_step"]
    # the paper's ordering (centralised <= FH <= OS) with the FH filter's windows solved to tol
    assert (d["window"], d["tolerance"]) == (paper.WINDOW, paper.TOLERANCE)
    assert d["fh_windows"]["windows"] == paper.DURATION // paper.WINDOW == d["fh_windows"]["converged"]
    assert r["centralized"] < r["finite_horizon"] <= r["one_step"]
    rows = {row.quantity: row for c in compare_with_papers(read_report_inputs(tmp_path)) for row in c.rows}
    assert rows["simulation: samples, seed, pump switch (s)"].verdict == AGREES
    assert rows["800-sample run: RMSE centralised vs finite-horizon vs one-step (cm)"].verdict == AGREES
    assert rows["800-sample run: estimates track the levels (figures)"].verdict == AGREES
