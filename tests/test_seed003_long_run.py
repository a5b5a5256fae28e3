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
from tanksynth.verify.decentralized.long_run import centralized_gain_of, one_step_gain

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
    rows = {row.quantity: row for c in compare_with_papers(read_report_inputs(tmp_path)) for row in c.rows}
    assert rows["simulation: samples, seed, pump switch (s)"].verdict == AGREES
    assert rows["800-sample run: RMSE centralised vs one-step (cm)"].verdict == AGREES
    assert rows["800-sample run: estimates track the levels (figures)"].verdict == AGREES
