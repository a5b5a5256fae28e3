"""Design stage: gain synthesis (arrays in, result dataclasses out) and one adapter per spec method.

Called as a function, ``tanksynth.design(plant, method, x0=..., u0=..., ts=..., trim=...,
**options)`` designs one gain from Python objects and returns the `Design` ``tanksynth.load``
gives: its parameters are documented in `tanksynth.api.design` (``help(tanksynth.api.design)``).

Nothing is registered on import: `tanksynth.methods` is the one table of the spec methods. Each
method family is a sub-package (``placement``, ``observer_lmi``, ``estimators``, ...) whose
``adapters`` module holds its design methods; what the families share are the modules at this
level:

=========================  ====================================================================
`result`                   `DesignResult`, `DesignMethod`, the options of an entry, keyed errors
`audit`                    the warnings of a design (operating point, actuators, stability)
`operating_point`          equilibrium input and linearisation at the spec's operating point
`matrices`                 checked matrices, the symmetric part, eigenvalue lists
`linear_gains`             robustness, reference comparison and LaTeX of a linear gain
`lmi_checks`               the re-check items, the solver table, the conditioning bound
`bisection`                the largest parameter of a monotone family of LMIs
`conic`                    LMIs written straight in Clarabel's conic form (cvxpy for SCS)
=========================  ====================================================================
"""

from __future__ import annotations

import sys
import types
from typing import Any

from tanksynth.design.result import DesignMethod, DesignResult

__all__ = ["DesignMethod", "DesignResult"]


class _DesignPackage(types.ModuleType):
    """This package, callable: ``tanksynth.design(plant, "lmi_placement", ...)`` is
    `tanksynth.api.design` (python-control style; the package and the function share the name
    ``tanksynth.design``, and importing a sub-package would replace a function attribute of that
    name, so the package itself is the function)."""

    def __call__(self, plant: Any, method: str, **kwargs: Any) -> Any:
        """See `tanksynth.api.design`."""
        __import__("tanksynth.api")  # the top layer, named at call time (not a dependency of design/)
        return sys.modules["tanksynth.api"].design(plant, method, **kwargs)


sys.modules[__name__].__class__ = _DesignPackage
