"""Design results and the design adapter of a spec method."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, TypeVar

import numpy as np

from tanksynth.errors import SpecError
from tanksynth.plants.base import Plant
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options.base import MethodOptions

__all__ = ["DesignResult", "DesignMethod", "FeedbackGain", "options_of", "rekeyed", "keyed_call"]

T = TypeVar("T", bound=MethodOptions)
R = TypeVar("R")


class FeedbackGain:
    """One naming rule for the gain of a linear design result, as in the artefacts: ``K`` for a
    state feedback (``u = -K x``, m x n), ``L`` for an observer (``x_hat' = ... + L (y - C
    x_hat)``, n x q).

    Mixed into the results that design either by their ``kind`` (exact and LMI-region
    placement, H2 / H-infinity synthesis, robust designs); they store the matrix as
    ``gain_matrix``. The older name ``gain`` still reads it, with a `DeprecationWarning`.
    """

    kind: str
    gain_matrix: np.ndarray

    @property
    def K(self) -> np.ndarray:
        """The state-feedback gain (``kind == "state_feedback"``); AttributeError for an observer."""
        if self.kind != "state_feedback":
            raise AttributeError(f"{type(self).__name__} of an observer has L (its gain), not K")
        return self.gain_matrix

    @property
    def L(self) -> np.ndarray:
        """The observer gain (``kind == "observer"``); AttributeError for a state feedback."""
        if self.kind != "observer":
            raise AttributeError(f"{type(self).__name__} of a state feedback has K (its gain), not L")
        return self.gain_matrix

    @property
    def gain(self) -> np.ndarray:
        """Deprecated: ``K`` (state feedback) or ``L`` (observer)."""
        warnings.warn(f"{type(self).__name__}.gain is deprecated: use .K (state feedback) or .L "
                      "(observer)", DeprecationWarning, stacklevel=2)
        return self.gain_matrix


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
    run: Callable[[Spec, DesignSpec], DesignResult]
    options: type[MethodOptions]

    def __post_init__(self) -> None:
        if self.options.method_name != self.name:
            raise TypeError(f"design method {self.name!r} has the options of "
                            f"{self.options.method_name!r}")

    def validate(self, options: Mapping[str, Any], key: str, plant: Plant,
                 ts: float | None) -> MethodOptions:
        """Validate a ``[[design]]`` table's options: `MethodOptions.from_table` of `options`.

        Parameters
        ----------
        options : mapping
            The raw options of the ``[[design]]`` table.
        key : str
            Dotted key of the table, for error messages (e.g. ``design[1]``).
        plant : Plant
            The spec's plant.
        ts : float or None
            The spec's sampling period [s].

        Returns
        -------
        MethodOptions
            The options with their defaults (an instance of `options`).
        """
        return self.options.validated(options, key, plant, ts)


def options_of(design: DesignSpec, spec: Spec, cls: type[T]) -> T:
    """The validated options of a ``[[design]]`` entry (``design.config``).

    A `DesignSpec` parsed without the method table has no ``config``, and
    one copied with other ``options`` has a stale one: its raw options are
    then validated here, against ``spec``'s plant and sampling period.

    Parameters
    ----------
    design : DesignSpec
        The ``[[design]]`` entry.
    spec : Spec
        The validated spec (its plant and sampling period).
    cls : type
        The method's options class.

    Raises
    ------
    SpecError
        Invalid options (only when they were not validated at parse time).
    """
    config = getattr(design, "config", None)
    if isinstance(config, cls) and config.read_from(design.options):
        return config
    options = cls.validated(design.options, design.key, spec.plant, spec.ts)
    if not isinstance(options, cls):    # `validated` builds the class it is called on
        raise TypeError(f"{cls.__name__}.validated returned a {type(options).__name__}")
    return options


def rekeyed(design: DesignSpec, exc: SpecError, option: str | None = None,
            fallback: str = "options") -> SpecError:
    """A `SpecError` a design step raised, keyed to the spec option it is about.

    Parameters
    ----------
    design : DesignSpec
    exc : SpecError
        Raised by an algorithm, keyed by its own argument name (or not at all).
    option : str, optional
        The option to name, whatever ``exc.key`` says.
    fallback : str
        The option to name when ``exc`` has no key.

    Returns
    -------
    SpecError
        ``exc`` itself when it already names a key of this design, else the
        same message keyed ``design[i].<option>``.
    """
    if option is None and exc.key and exc.key.startswith(design.key):
        return exc
    return SpecError(exc.detail, key=f"{design.key}.{option or exc.key or fallback}")


def keyed_call(design: DesignSpec, build: Callable[..., R], renames: Mapping[str, str], /,
               **kwargs: Any) -> R:
    """``build(**kwargs)`` (a tuning class, a design step), its `SpecError` keyed to the spec option.

    A runtime tuning or a design algorithm names the argument it refuses (``key="a"``); the
    user wrote a spec option (``abc``): the error is re-raised as ``design[i].<option>``.

    Parameters
    ----------
    design : DesignSpec
        The ``[[design]]`` entry the call is for.
    build : callable
        What to call.
    renames : mapping of str to str
        Argument name -> spec option, where they differ (other keys are kept as they are).
    **kwargs
        The arguments of ``build``.

    Returns
    -------
    object
        What ``build`` returns.

    Raises
    ------
    SpecError
        ``build``'s, keyed ``design[i].<option>`` (unchanged when it already names a key of a
        ``[[design]]`` entry, or none).
    """
    try:
        return build(**kwargs)
    except SpecError as exc:
        if exc.key and not exc.key.startswith("design["):
            raise rekeyed(design, exc, renames.get(exc.key, exc.key)) from None
        raise
