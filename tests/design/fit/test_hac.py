"""Autocorrelation-consistent (Newey-West) covariance of the fit, against independent references.

References: the Bartlett-weighted long-run variance of a sample mean written out by hand; a
Monte-Carlo coverage of a linear regression with AR(1) regressor and AR(1) errors (the white
intervals under-cover by the known factor ``(1 + rho_x rho_e) / (1 - rho_x rho_e)``, the HAC
ones come near nominal); a three-tank fit on AR(1) sensor noise (whiteness fails, the HAC
intervals are used and wider).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from tanksynth.design.fit.estimation import fit_parameters
from tanksynth.design.fit.statistics import fisher_covariance, hac_covariance, hac_lags
from tanksynth.measurements.experiment import Experiment
from tanksynth.plants import three_tank
from tanksynth.sim.simulate import simulate_inputs


def _bartlett_mean_variance(parts: list[np.ndarray], L: int, K: int) -> float:
    """Hand formula: variance of the pooled mean of several series, Bartlett weights."""
    N = sum(p.size for p in parts)
    mean = sum(p.sum() for p in parts) / N
    S = 0.0
    for p in parts:
        e = p - mean
        S += float(e @ e)
        for lag in range(1, L + 1):
            S += 2.0 * (1.0 - lag / (L + 1.0)) * float(e[lag:] @ e[:-lag])
    return S / N ** 2 * N / (N - K)


def test_hac_of_a_sample_mean_equals_the_bartlett_formula():
    rng = np.random.default_rng(3)
    parts = [np.cumsum(rng.standard_normal(120)) * 0.1 + 2.0, rng.standard_normal(80) + 2.0]
    y = np.concatenate(parts)
    mean = y.mean()
    J = -np.ones((y.size, 1))                        # residual y - theta: d/dtheta = -1
    r = y - mean
    exp = np.concatenate([np.zeros(120, int), np.ones(80, int)])
    smp = np.concatenate([np.arange(120), np.arange(80)])
    fisher = fisher_covariance(J, r, np.array([mean]), 1)
    for L in (0, 3, 9):
        hac = hac_covariance(J, r, np.array([mean]), 1, exp, smp, fisher, lags=[L, L])
        assert hac.covariance[0, 0] == pytest.approx(_bartlett_mean_variance(parts, L, 1), rel=1e-10)
        assert hac.lags == (L, L)
    # with L = 0 the sandwich of white residuals is the Fisher variance s^2 / N
    hac0 = hac_covariance(J, r, np.array([mean]), 1, exp, smp, fisher, lags=[0, 0])
    assert hac0.covariance[0, 0] == pytest.approx(fisher.covariance[0, 0], rel=1e-10)


def test_hac_sums_the_outputs_of_one_sample_before_the_lags():
    # two rows per sample (two outputs of one sample): the score of a sample is their sum, so
    # duplicating every row with the same residual doubles the score (x4 variance, /4 bread^2...)
    rng = np.random.default_rng(5)
    y = rng.standard_normal(200) + 1.0
    mean = y.mean()
    r1 = y - mean
    J2 = -np.ones((400, 1))
    r2 = np.repeat(r1, 2)
    smp2 = np.repeat(np.arange(200), 2)
    f2 = fisher_covariance(J2, r2, np.array([mean]), 1)
    hac = hac_covariance(J2, r2, np.array([mean]), 1, np.zeros(400, int), smp2, f2, lags=[4])
    # scores 2 r_t, bread 1/400: variance = 4 S1 / 400^2 * 400/399, S1 the single-row sum
    S1 = _bartlett_mean_variance([y], 4, 1) * 200 ** 2 * 199 / 200
    assert hac.covariance[0, 0] == pytest.approx(4 * S1 / 400 ** 2 * 400 / 399, rel=1e-10)


def test_lag_rule_grows_with_the_autocorrelation_and_keeps_the_newey_west_floor():
    rng = np.random.default_rng(0)
    white = rng.standard_normal((1000, 2))
    assert hac_lags(white) == int(np.floor(4 * (1000 / 100) ** (2 / 9)))     # = 6
    ar = np.zeros((1000, 2))
    for t in range(1, 1000):
        ar[t] = 0.9 * ar[t - 1] + white[t]
    # Andrews' AR(1) plug-in at rho = 0.9: 1.1447 (4 rho^2 / (1 - rho^2)^2 T)^(1/3) ~ 50
    expect = 1.1447 * (4 * 0.81 / (1 - 0.81) ** 2 * 1000) ** (1 / 3)
    assert abs(hac_lags(ar) - expect) <= 0.15 * expect


def _coverage(trials: int, N: int, rho: float, seed: int) -> tuple[float, float]:
    """Coverage of the slope's 95 % interval: white-noise Fisher vs HAC."""
    rng = np.random.default_rng(seed)
    beta = np.array([1.0, 2.0])
    hit_w = hit_h = 0
    q = stats.t.ppf(0.975, N - 2)
    for _ in range(trials):
        w = rng.standard_normal((N, 2))
        x = np.zeros(N)
        e = np.zeros(N)
        for t in range(1, N):
            x[t] = rho * x[t - 1] + w[t, 0]
            e[t] = rho * e[t - 1] + w[t, 1]
        X = np.column_stack([np.ones(N), x])
        y = X @ beta + e
        b, *_ = np.linalg.lstsq(X, y, rcond=None)
        r = y - X @ b
        fisher = fisher_covariance(-X, r, b, 2)
        hac = hac_covariance(-X, r, b, 2, np.zeros(N, int), np.arange(N), fisher)
        hit_w += abs(b[1] - beta[1]) <= q * fisher.stderr[1]
        hit_h += abs(b[1] - beta[1]) <= q * hac.stderr[1]
    return hit_w / trials, hit_h / trials


def test_hac_intervals_reach_near_nominal_coverage_where_white_ones_under_cover():
    # rho_x = rho_e = 0.6: the white variance is short by (1 + 0.36) / (1 - 0.36) = 2.1, so the
    # white 95 % interval covers P(|Z| < 1.96 / sqrt(2.1)) = 0.82
    white, hac = _coverage(400, 400, 0.6, seed=11)
    expect_white = 2 * stats.norm.cdf(1.96 / np.sqrt(1.36 / 0.64)) - 1
    assert abs(white - expect_white) < 0.05, (white, expect_white)
    assert 0.90 <= hac <= 0.98, hac
    assert hac - white > 0.07


def _ar1_experiment(plant, name: str, N: int, seed: int, rho: float, sigma: float) -> Experiment:
    rng = np.random.default_rng(seed)
    levels = rng.uniform(0.2e-4, 1.0e-4, size=(N // 40 + 1, 2))
    U = np.repeat(levels, 40, axis=0)[:N]
    run = simulate_inputs(plant, [0.3, 0.1, 0.2], U[:-1], 1.0, substeps=4,
                          parameters={"mu13": 0.45, "mu32": 0.55, "mu20": 0.70})
    noise = np.zeros((N, 3))
    w = rng.standard_normal((N, 3)) * sigma * np.sqrt(1 - rho ** 2)
    noise[0] = rng.standard_normal(3) * sigma
    for t in range(1, N):
        noise[t] = rho * noise[t - 1] + w[t]
    Y = run.y[0] + noise
    none = np.zeros(Y.shape, dtype=bool)
    return Experiment(name, f"{name}.csv", np.arange(N, dtype=float), U, Y, ("q1", "q2"),
                      ("h1", "h2", "h3"), none, none.copy(), ((0.0, 0.62),) * 3)


class _Free:
    def __init__(self, name: str):
        self.name, self.start, self.lower, self.upper, self.unit = name, 0.5, 0.2, 0.9, "1"


def test_fit_on_coloured_noise_reports_the_hac_intervals():
    plant = three_tank()
    exps = [_ar1_experiment(plant, "e1", 300, 1, 0.9, 0.002)]
    res = fit_parameters(plant, [_Free("mu13"), _Free("mu32"), _Free("mu20")], exps, starts=1)
    assert not all(w.passed for w in res.whiteness.values())
    assert res.covariance_method == "hac" and "not white" in res.covariance_note
    assert np.all(res.stderr == res.stderr_hac)
    assert np.all(res.stderr_hac > 1.5 * res.stderr_white)      # AR(0.9): far wider
    assert np.all(res.ci95[:, 1] - res.ci95[:, 0] > res.ci95_white[:, 1] - res.ci95_white[:, 0])
    assert res.hac_lags[0] >= int(np.floor(4 * 3 ** (2 / 9)))
