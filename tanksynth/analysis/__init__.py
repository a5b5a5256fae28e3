"""Analysis used by every stage: symbolic derivatives, linearisation, rank conditions.

==============================  ===============================================================
`tanksynth.analysis.symbolic`   Jacobians, Lie derivatives, relative degree, decoupling matrix
`tanksynth.analysis.linearize`  equilibrium input, linearisation, exact ZOH discretisation
`tanksynth.analysis.rank`       Kalman, PBH, nonlinear and symbolic rank conditions
`tanksynth.analysis.checks`     the rank conditions of a spec (``tanksynth check``)
`tanksynth.analysis.trim`       levels that given inputs hold still (root finding on f)
==============================  ===============================================================
"""

from __future__ import annotations

from tanksynth.analysis.checks import Check, rank_conditions
from tanksynth.analysis.linearize import (Equilibrium, LinearModel, discretize_zoh, equilibrium_input,
                                          linearize, symbolic_jacobians)
from tanksynth.analysis.rank import (NonlinearObservability, PBHMode, PBHResult, RankResult,
                                     SymbolicRank, controllability_matrix, controllability_rank,
                                     nonlinear_observability, observability_matrix,
                                     observability_rank, pbh_test, symbolic_observability)
from tanksynth.analysis.trim import Trim, trim
from tanksynth.analysis.symbolic import (RelativeDegree, control_affine, jacobian, lie_derivative,
                                         lie_derivatives, relative_degree)

__all__ = [
    "Check", "rank_conditions",
    "Equilibrium", "LinearModel", "discretize_zoh", "equilibrium_input", "linearize",
    "symbolic_jacobians",
    "NonlinearObservability", "PBHMode", "PBHResult", "RankResult", "SymbolicRank",
    "controllability_matrix", "controllability_rank", "nonlinear_observability",
    "observability_matrix", "observability_rank", "pbh_test", "symbolic_observability",
    "RelativeDegree", "control_affine", "jacobian", "lie_derivative", "lie_derivatives",
    "relative_degree",
    "Trim", "trim",
]
