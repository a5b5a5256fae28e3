"""How well simulated outputs match logged ones: RMSE and fit % (NRMSE), on the samples that count.

A sample counts when it is present and not censored (`Experiment.observed`): a sample at a
sensor limit says only that the true output is at or beyond it. Both the fit (design) and its
verdict (verify) score outputs with these definitions, so that the numbers they record can be
compared.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["rmse", "fit_percent", "pooled_scores", "WHITENESS_LAGS", "WHITENESS_LEVEL",
           "ljung_box"]

#: Lags of the residual whiteness test (fit diagnostics and fit verdict alike).
WHITENESS_LAGS = 20
#: Level of its chi-square bound: 95 % (bound 31.41 at 20 lags).
WHITENESS_LEVEL = 0.95


def rmse(y: np.ndarray, y_hat: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Root-mean-square error per output over the samples of ``mask``.

    Parameters
    ----------
    y, y_hat : ndarray, shape (N, p)
        Measured and simulated outputs (output units).
    mask : ndarray of bool, shape (N, p)
        Samples that count.

    Returns
    -------
    ndarray, shape (p,)
        Output units; NaN for an output without a sample that counts.
    """
    err = np.where(mask, np.nan_to_num(np.asarray(y, float) - np.asarray(y_hat, float)), 0.0)
    count = mask.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, np.sqrt((err ** 2).sum(axis=0) / np.maximum(count, 1)), np.nan)


def fit_percent(y: np.ndarray, y_hat: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """NRMSE fit per output, ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)`` over ``mask``.

    100 % is a perfect match, 0 % no better than the mean of the data, negative worse.

    Parameters
    ----------
    y, y_hat : ndarray, shape (N, p)
        Measured and simulated outputs (output units).
    mask : ndarray of bool, shape (N, p)
        Samples that count.

    Returns
    -------
    ndarray, shape (p,)
        Percent; NaN for an output without samples or constant over them.
    """
    y = np.asarray(y, float)
    out = np.full(y.shape[1], np.nan)
    for j in range(y.shape[1]):
        m = mask[:, j]
        if m.sum() < 2:
            continue
        yj, hj = y[m, j], np.asarray(y_hat, float)[m, j]
        spread = float(np.linalg.norm(yj - yj.mean()))
        if spread > 0:
            out[j] = 100.0 * (1.0 - float(np.linalg.norm(yj - hj)) / spread)
    return out


def pooled_scores(ys: Sequence[np.ndarray], y_hats: Sequence[np.ndarray],
                  masks: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """RMSE and fit % per output over several experiments (their samples pooled).

    Parameters
    ----------
    ys, y_hats : sequence of ndarray, shape (N_e, p)
        Measured and simulated outputs of each experiment (output units).
    masks : sequence of ndarray of bool, shape (N_e, p)
        Samples that count.

    Returns
    -------
    rmse : ndarray, shape (p,)
        Output units.
    fit : ndarray, shape (p,)
        Percent.
    """
    y, y_hat, mask = (np.concatenate(list(a), axis=0) for a in (ys, y_hats, masks))
    return rmse(y, y_hat, mask), fit_percent(y, y_hat, mask)


def ljung_box(series: Sequence[np.ndarray], lags: int = WHITENESS_LAGS,
              level: float = WHITENESS_LEVEL) -> tuple[np.ndarray, float, float, int, int]:
    """Ljung-Box whiteness test of residual sequences, one per experiment (NaN = not counted).

    Each sequence is centred on its own mean; the autocorrelation is pooled over the
    experiments (lag products within an experiment only, pairs with a missing sample left out)
    and normalised by the lag-0 sum: ``r_l``. The statistic ``Q = N (N + 2) sum_l r_l^2 / (N - l)``
    (``N`` the samples counted) is compared with the ``level`` quantile of chi-square with ``L``
    degrees of freedom, ``L = min(lags, N // 4)``. The fit's diagnostics and its verdict both
    call this, so they report the same number.

    Parameters
    ----------
    series : sequence of ndarray, shape (N_e,)
        Residuals of one output per experiment, in time order (output units).
    lags : int
        Largest lag ``L``.
    level : float
        Level of the chi-square bound, in (0, 1) (dimensionless).

    Returns
    -------
    autocorrelation : ndarray, shape (L,)
        ``r_1 .. r_L`` (1).
    statistic, bound : float
        ``Q`` and its chi-square bound (1); NaN when no sample counts.
    lags : int
        ``L`` (0 when no sample counts).
    samples : int
        ``N``.
    """
    from scipy import stats  # deferred: scipy.stats imports in 0.3-0.5 s

    parts = [np.asarray(s, dtype=float).ravel() for s in series]
    centred = []
    for s in parts:
        c = s - np.nanmean(s) if np.any(np.isfinite(s)) else s
        centred.append(np.where(np.isfinite(c), c, 0.0))
    n0 = int(sum(int(np.isfinite(s).sum()) for s in parts))
    denom = sum(float(c @ c) for c in centred)
    if n0 < 4 or denom <= 0:
        return np.zeros(0), float("nan"), float("nan"), 0, n0
    L = max(1, min(int(lags), n0 // 4))
    acf = np.zeros(L)
    for lag in range(1, L + 1):
        acf[lag - 1] = sum(float(c[:-lag] @ c[lag:]) for c in centred if c.size > lag) / denom
    q = float(n0 * (n0 + 2) * np.sum(acf ** 2 / np.maximum(n0 - np.arange(1, L + 1), 1)))
    return acf, q, float(stats.chi2.ppf(level, L)), L, n0
