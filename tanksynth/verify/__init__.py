"""Verification stage: rank conditions (Kalman, PBH, nonlinear, symbolic) and verdicts."""

from __future__ import annotations

from .checks import Check, rank_conditions
from .rank import (NonlinearObservability, PBHResult, RankResult, SymbolicRank,
                   controllability_matrix, controllability_rank, nonlinear_observability,
                   observability_matrix, observability_rank, pbh_test, symbolic_observability)

__all__ = [
    "Check", "rank_conditions", "NonlinearObservability", "PBHResult", "RankResult", "SymbolicRank",
    "controllability_matrix", "controllability_rank", "nonlinear_observability",
    "observability_matrix", "observability_rank", "pbh_test", "symbolic_observability",
]
