"""Options of the ``model`` family: ``linearize``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

from tanksynth.spec.method_options.base import MethodOptions, OptionReader

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["LinearizeOptions"]


@dataclass(frozen=True, eq=False)
class LinearizeOptions(MethodOptions):
    """Options of ``linearize`` (none): the Jacobian linearisation at the operating point and its
    exact ZOH discretisation with ``[sampling] ts`` (required).

    Attributes
    ----------
    (none)
        The method takes no option.
    """

    method_name: ClassVar[str] = "linearize"
    needs_sampling: ClassVar[bool] = True

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "LinearizeOptions":
        """Refuse any option and a spec without a sampling period (see `MethodOptions.from_table`)."""
        OptionReader(cls, options, key, ts)
        return cls()
