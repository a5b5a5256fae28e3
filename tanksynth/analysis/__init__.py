"""Analysis used by every stage: symbolic derivatives, linearisation, rank conditions.

==============================  ===============================================================
`tanksynth.analysis.symbolic`   Jacobians, Lie derivatives, relative degree, decoupling matrix
`tanksynth.analysis.linearize`  equilibrium input, linearisation, exact ZOH discretisation
`tanksynth.analysis.rank`       Kalman, PBH, nonlinear and symbolic rank conditions
`tanksynth.analysis.checks`     the rank conditions of a spec (``tanksynth check``)
`tanksynth.analysis.trim`       levels that given inputs hold still (root finding on f)
`tanksynth.analysis.matrices`   small matrix helpers (symmetrize)
==============================  ===============================================================
"""

from __future__ import annotations

from tanksynth.analysis.linearize import linearize  # eager: the name of its own module
from tanksynth.analysis.trim import trim  # eager: the name of its own module
from tanksynth._lazy import lazy_exports as _lazy_exports

#: Re-exported name -> its module, imported on first use (PEP 562): importing the package
#: loads none of its modules' dependencies (issue 15).
_EXPORTS = {
    **dict.fromkeys(["Check", "rank_conditions"], "tanksynth.analysis.checks"),
    **dict.fromkeys(["Equilibrium", "LinearModel", "discretize_zoh", "equilibrium_input",
                     "symbolic_jacobians"],
                    "tanksynth.analysis.linearize"),
    **dict.fromkeys(["NonlinearObservability", "PBHMode", "PBHResult", "RankResult",
                     "SymbolicRank", "controllability_matrix", "controllability_rank",
                     "nonlinear_observability", "observability_matrix", "observability_rank",
                     "pbh_test", "symbolic_observability"],
                    "tanksynth.analysis.rank"),
    "Trim": "tanksynth.analysis.trim",
    "symmetrize": "tanksynth.analysis.matrices",
    **dict.fromkeys(["RelativeDegree", "control_affine", "jacobian", "lie_derivative",
                     "lie_derivatives", "relative_degree"],
                    "tanksynth.analysis.symbolic"),
}

__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)

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
    "symmetrize",
]
