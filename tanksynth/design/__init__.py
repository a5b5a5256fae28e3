"""Design stage: gain synthesis (arrays in, result dataclasses out) and one adapter per spec method.

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

from tanksynth.design.result import DesignMethod, DesignResult

__all__ = ["DesignMethod", "DesignResult"]
