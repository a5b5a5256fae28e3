"""Design results and the design adapter of a spec method."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Callable, Mapping

import numpy as np

from tanksynth.errors import SpecError

__all__ = ["DesignResult", "DesignMethod"]


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
    """A spec design method.

    Attributes
    ----------
    name : str
    run : callable
        ``run(spec, design_spec) -> DesignResult``.
    options : mapping of str to (type, default)
        Accepted options; ``default`` None means required... unless the
        type is optional (see ``required``).
    required : tuple of str
        Options that must be present.
    needs_sampling : bool
        The method needs ``[sampling] ts``.
    """

    name: str
    run: Callable[..., DesignResult]
    options: Mapping[str, tuple[type | tuple[type, ...], Any]] = field(default_factory=dict)
    required: tuple[str, ...] = ()
    needs_sampling: bool = False

    def validate(self, options: Mapping[str, Any], key: str, plant, ts: float | None) -> Mapping[str, Any]:
        """Check a ``[[design]]`` table's options (types, unknown keys).

        Returns
        -------
        mapping
            The options with the defaults filled in (read-only).
        """
        for opt, value in options.items():
            if opt not in self.options:
                raise SpecError(f"unknown option {opt!r} for method '{self.name}'; expected: "
                                + (", ".join(self.options) or "no options"), key=f"{key}.{opt}")
            kind = self.options[opt][0]
            if isinstance(value, bool) and kind is not bool:
                raise SpecError(f"expected {_type_name(kind)}, got a boolean", key=f"{key}.{opt}")
            if not isinstance(value, kind):
                raise SpecError(f"expected {_type_name(kind)}, got {type(value).__name__} {value!r}",
                                key=f"{key}.{opt}")
        for opt in self.required:
            if opt not in options:
                raise SpecError(f"missing option {opt!r} for method '{self.name}'", key=f"{key}.{opt}")
        if self.needs_sampling and ts is None:
            raise SpecError(f"method '{self.name}' needs a sampling period: add [sampling] ts = ...",
                            key="sampling.ts")
        resolved = {k: d for k, (_, d) in self.options.items() if d is not None}
        resolved.update(options)
        return MappingProxyType(resolved)


def _type_name(kind) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join(k.__name__ for k in kinds)
