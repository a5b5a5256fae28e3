"""Small matrix helpers every stage uses on numpy arrays.

`symmetrize`
    ``(M + M') / 2`` of one square matrix or of each of a stack: the one
    rounding rule that keeps covariances, Gram matrices and LMI blocks
    exactly symmetric after products that are symmetric only in exact
    arithmetic.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["symmetrize"]


def symmetrize(M: Any) -> np.ndarray:
    """Symmetric part ``(M + M') / 2`` of a square matrix, or of each matrix of a stack.

    Exactly symmetric in floating point (``a + b == b + a``), so a matrix symmetric in exact
    arithmetic (``P A'`` products, Joseph updates) stops carrying rounding asymmetry.

    Parameters
    ----------
    M : array_like, shape (..., n, n)
        Square matrices (any units; the result has the same).

    Returns
    -------
    ndarray, shape (..., n, n)
        ``0.5 * (M + swapaxes(M, -1, -2))``.
    """
    M = np.asarray(M)
    return 0.5 * (M + np.swapaxes(M, -1, -2))
