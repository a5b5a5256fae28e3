"""Helpers shared by the estimator tests (imported by name, not a conftest)."""

from __future__ import annotations

import numpy as np


def linear_data(model, steps, Q, R, x0, seed=0, u=None):
    """Simulate a linear DiscreteModel with process and measurement noise.

    Returns (X (steps, n) states at t_1..t_N, Y (steps, q), U (steps, m)).
    """
    rng = np.random.default_rng(seed)
    n, m = model.Ad.shape[0], model.Bd.shape[1]
    U = np.zeros((steps, m)) if u is None else np.asarray(u, dtype=float)
    X = np.empty((steps, n))
    Y = np.empty((steps, model.C.shape[0]))
    x = np.asarray(x0, dtype=float)
    Lq = np.linalg.cholesky(Q + 1e-300 * np.eye(n)) if np.any(Q) else np.zeros((n, n))
    Lr = np.linalg.cholesky(R)
    for k in range(steps):
        x = model.Ad @ x + model.Bd @ U[k] + model.cd + Lq @ rng.standard_normal(n)
        X[k] = x
        Y[k] = model.C @ x + model.dy + Lr @ rng.standard_normal(len(R))
    return X, Y, U
