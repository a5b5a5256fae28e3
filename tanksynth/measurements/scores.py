"""How well simulated outputs match logged ones: RMSE and fit % (NRMSE), on the samples that count.

A sample counts when it is present and not censored (`Experiment.observed`): a sample at a
sensor limit says only that the true output is at or beyond it. Both the fit (design) and its
verdict (verify) score outputs with these definitions, so that the numbers they record can be
compared.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["rmse", "fit_percent", "pooled_scores"]


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
