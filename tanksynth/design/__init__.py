"""Design stage: symbolic analysis, linearisation and gain synthesis."""

from __future__ import annotations

from . import methods as _methods  # noqa: F401  (registers the spec methods)
from . import convex_methods as _convex_methods  # noqa: F401
from . import control_methods as _control_methods  # noqa: F401
from . import decentralized_methods as _decentralized_methods  # noqa: F401
from . import estimator_methods as _estimator_methods  # noqa: F401
from .linearize import (Equilibrium, LinearModel, discretize_zoh, equilibrium_input, linearize,
                        symbolic_jacobians)
from .result import METHODS, DesignMethod, DesignResult, register
from .symbolic import (RelativeDegree, control_affine, jacobian, lie_derivative, lie_derivatives,
                       relative_degree)

__all__ = [
    "Equilibrium", "LinearModel", "discretize_zoh", "equilibrium_input", "linearize",
    "symbolic_jacobians", "METHODS", "DesignMethod", "DesignResult", "register",
    "RelativeDegree", "control_affine", "jacobian", "lie_derivative", "lie_derivatives",
    "relative_degree", "lmi", "placement", "takagi_sugeno",
    "control", "feedback_linearization",
    "decentralized",
    "estimators", "fault",
]
