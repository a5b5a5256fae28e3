"""The ``placement`` family's diagnostics: what exact pole placement (``placement``) and LMI
region placement (``lmi``) record about the poles asked for and the region certified, and where
any design records its poles (`design_poles_of`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from tanksynth.reports.diagnostics.common import (Diagnostics, description, eigenvalue_pairs, entry,
                                                  is_number, is_text, section)

__all__ = ["ExactPlacement", "exact_placement_of", "RegionPlacement", "region_placement_of", "design_poles_of"]


def _is_observer(kind: object) -> bool:
    """A placement ``kind`` of ``"observer..."`` places the error dynamics ``A - LC``."""
    return str(kind).startswith("observer")


@dataclass(frozen=True)
class ExactPlacement:
    """Exact pole placement (``diagnostics["placement"]``; also the observer of
    ``fault_detection`` and the poles of ``integral_tracking``).

    Attributes
    ----------
    observer : bool
        The gain places the error dynamics ``A - LC`` (else the closed loop ``A - BK``).
    requested : tuple of (float, float) or None
        The poles asked for, ``(re, im)`` (1/s, or dimensionless in discrete time).
    achieved : tuple of (float, float) or None
        The eigenvalues the gain gives, same units.
    method : str or None
        The algorithm (``place``, ``acker``).
    """

    observer: bool = False
    requested: tuple[tuple[float, float], ...] | None = None
    achieved: tuple[tuple[float, float], ...] | None = None
    method: str | None = None


def exact_placement_of(diag: Diagnostics) -> ExactPlacement:
    """The exact placement's record (a state feedback with nothing known when there is none).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    placement = section(diag, "placement")
    return ExactPlacement(observer=_is_observer(placement.get("kind", "state_feedback")),
                          requested=eigenvalue_pairs(placement, "requested"),
                          achieved=eigenvalue_pairs(placement, "achieved"),
                          method=entry(placement, "method", is_text))


@dataclass(frozen=True)
class RegionPlacement:
    """Pole placement in an LMI region (``diagnostics["lmi"]`` of ``lmi_placement``).

    Attributes
    ----------
    observer : bool
        The gain places the error dynamics ``A - LC`` (else the closed loop ``A - BK``).
    region : str or None
        The region in words (``|z - 0.9| < 0.08``).
    domain : str or None
        ``"continuous"`` or ``"discrete"``.
    margin : float or None
        The margin imposed on the strict LMI, after scaling (dimensionless).
    """

    observer: bool = False
    region: str | None = None
    domain: str | None = None
    margin: float | None = None


def region_placement_of(diag: Diagnostics) -> RegionPlacement:
    """The LMI region placement's record.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    lmi = section(diag, "lmi")
    return RegionPlacement(observer=_is_observer(lmi.get("kind", "state_feedback")),
                           region=description(lmi, "region"), domain=entry(lmi, "domain", is_text),
                           margin=entry(lmi, "margin", is_number))


#: Where a design records the poles it asked for or achieved, in the order they are looked for.
_POLE_PATHS = (("placement", "requested"), ("placement", "achieved"), ("achieved_poles",), ("requested_poles",),
               ("poles",))


def design_poles_of(diag: Diagnostics) -> tuple[complex, ...] | None:
    """The poles the design asked for (else achieved): the first of ``placement.requested``,
    ``placement.achieved``, ``achieved_poles``, ``requested_poles``, ``poles`` that is a
    non-empty list of numbers or ``[re, im]`` pairs (1/s, or dimensionless in discrete time).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    for path in _POLE_PATHS:
        node: Any = diag
        for key in path:
            node = node.get(key) if isinstance(node, Mapping) else None
        if isinstance(node, list) and node:
            try:
                return tuple(complex(*v) if isinstance(v, list) else complex(v) for v in node)
            except (TypeError, ValueError):
                continue
    return None
