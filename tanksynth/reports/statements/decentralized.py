"""The ``decentralized`` family's problem statement (``decentralized_kalman``)."""

from __future__ import annotations

from tanksynth.reports.statements.common import problem_statement

__all__ = ["decentralized_kalman_statement"]

decentralized_kalman_statement = problem_statement(
    "decentralized_kalman", __name__,
    r"Kalman gains $K(k)$ constrained to a sparsity pattern $E$ (each tank uses its own "
    r"measurements): minimise $\mathrm{tr}\,P(k|k)$ step by step (one-step) or "
    r"$\sum_k \mathrm{tr}\,P(k|k)$ over a window (finite horizon), with the covariance "
    r"recursion $P(k|k) = (I - KC)P(k|k-1)(I - KC)^\top + K R K^\top$ of the linearised network.")
