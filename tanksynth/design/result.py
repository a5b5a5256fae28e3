"""Design results and the design adapter of a spec method."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, TypeVar

import numpy as np

from tanksynth.spec.method_options.base import MethodOptions

__all__ = ["DesignResult", "DesignMethod", "options_of"]

T = TypeVar("T", bound=MethodOptions)


@dataclass(frozen=True)
class DesignResult:
    """What a design produces: named gains plus the evidence behind them.

    Attributes
    ----------
    name : str
        Design name from the spec.
    method : str
        Method name (``"linearize"``, ...).
    plant : str
        Plant model name.
    gains : mapping of str to ndarray
        Every gain/matrix, in SI (or the plant's) units.
    diagnostics : mapping
        JSON-friendly evidence: solver status, residuals, eigenvalues, rank
        verdicts, assumptions made.
    latex : mapping of str to str
        LaTeX fragments for the report.
    """

    name: str
    method: str
    plant: str
    gains: Mapping[str, np.ndarray]
    diagnostics: Mapping[str, Any] = field(default_factory=dict)
    latex: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class DesignMethod:
    """The design side of a spec method: its options and its design function.

    Attributes
    ----------
    name : str
        The spec's ``method`` value.
    run : callable
        ``run(spec, design_spec) -> DesignResult``; reads the validated
        options from ``design_spec.config`` (see `options_of`).
    options : type of MethodOptions
        The method's Options dataclass (options, defaults, units,
        validation).
    """

    name: str
    run: Callable[..., DesignResult]
    options: type[MethodOptions]

    def __post_init__(self) -> None:
        if self.options.method_name != self.name:
            raise TypeError(f"design method {self.name!r} has the options of "
                            f"{self.options.method_name!r}")

    def validate(self, options: Mapping[str, Any], key: str, plant: Any,
                 ts: float | None) -> MethodOptions:
        """Validate a ``[[design]]`` table's options: `MethodOptions.from_table` of `options`.

        Returns
        -------
        MethodOptions
            The options with their defaults (an instance of `options`).
        """
        return self.options.from_table(options, key, plant, ts)


def options_of(design: Any, spec: Any, cls: type[T]) -> T:
    """The validated options of a ``[[design]]`` entry (``design.config``).

    A `DesignSpec` parsed without the method table has no ``config``: its
    raw options are then validated here, against ``spec``'s plant and
    sampling period.

    Raises
    ------
    SpecError
        Invalid options (only when they were not validated at parse time).
    """
    config = getattr(design, "config", None)
    if isinstance(config, cls):
        return config
    return cls.from_table(design.options, design.key, spec.plant, spec.ts)
