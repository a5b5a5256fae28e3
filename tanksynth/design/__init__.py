"""Design stage: gain synthesis (arrays in, result dataclasses out) and one adapter per spec method.

Nothing is registered on import: `tanksynth.methods` is the one table of the spec methods.
"""

from __future__ import annotations

from tanksynth.design.result import DesignMethod, DesignResult

__all__ = ["DesignMethod", "DesignResult"]
