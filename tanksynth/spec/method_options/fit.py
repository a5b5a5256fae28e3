"""Options of ``fit``: grey-box fit of free plant parameters and initial states to logged data
(CasADi + IPOPT, multiple shooting).

Scaffolded by scripts/add_method.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

from tanksynth.spec.method_options.base import MethodOptions, OptionReader, option
from tanksynth.spec.options import parse_number

__all__ = ["FitOptions"]


@dataclass(frozen=True, eq=False)
class FitOptions(MethodOptions):
    """Options of ``fit``: grey-box fit of free plant parameters and initial states to logged
    data (CasADi + IPOPT, multiple shooting).

    TODO(fit): replace the example option with the method's own, each documented here
    with its unit and default, declared with `option` and read in `from_table`.

    Attributes
    ----------
    example_option : float
        Example option, to be replaced by the method's own (dimensionless, > 0); default 1.
    """

    method_name: ClassVar[str] = "fit"

    example_option: float = option(1.0, unit="-")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Any,
                   ts: float | None) -> "FitOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        return cls(example_option=r.read("example_option", parse_number, above=0.0))
