"""Design stage: gain synthesis (arrays in, result dataclasses out) and the spec adapters."""

from __future__ import annotations

from tanksynth.design import control_methods as _control_methods  # noqa: F401
from tanksynth.design import convex_methods as _convex_methods  # noqa: F401
from tanksynth.design import decentralized_methods as _decentralized_methods  # noqa: F401
from tanksynth.design import estimator_methods as _estimator_methods  # noqa: F401
from tanksynth.design import methods as _methods  # noqa: F401  (registers the spec methods)
from tanksynth.design.result import METHODS, DesignMethod, DesignResult, register

__all__ = ["METHODS", "DesignMethod", "DesignResult", "register", "lmi", "placement",
           "takagi_sugeno", "control", "feedback_linearization", "decentralized", "fault"]
