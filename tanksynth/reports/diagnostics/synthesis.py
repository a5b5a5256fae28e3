"""The ``synthesis`` family's diagnostics (``h2_*``, ``hinf_*``, ``multiobjective``): the route,
the bounds imposed and the norms recomputed from the closed loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from tanksynth.reports.diagnostics.common import Diagnostics, description, entry, is_number, is_text, section

__all__ = ["Synthesis", "synthesis_of"]


@dataclass(frozen=True)
class Synthesis:
    """What an optimal convex synthesis records (``diagnostics["synthesis"]`` and beside it).

    Attributes
    ----------
    domain : str or None
        ``"continuous"`` or ``"discrete"`` as the synthesis wrote it.
    route : str or None
        ``"riccati"`` or ``"lmi"``.
    observer : bool
        The design is an observer (``target = "observer"`` of ``multiobjective``).
    objective : str or None
        What ``multiobjective`` minimised: ``"hinf"`` (the default) or ``"h2"``.
    h2_bound : float or None
        The certified bound on ``||T_zw||_2`` (units of z per unit of w).
    gamma : float or None
        The certified bound on ``||T_zw||_inf`` (units of z per unit of w).
    achieved_h2 : float or None
        ``||T_zw||_2`` recomputed from the closed loop (of the nominal model; units of z per
        unit of w).
    achieved_hinf : float or None
        ``||T_zw||_inf`` recomputed likewise (units of z per unit of w).
    backoff : float or None
        The relative back-off from the optimal ``gamma`` (dimensionless).
    region : str or None
        The pole region of ``multiobjective``, in words.
    """

    domain: str | None = None
    route: str | None = None
    observer: bool = False
    objective: str | None = "hinf"
    h2_bound: float | None = None
    gamma: float | None = None
    achieved_h2: float | None = None
    achieved_hinf: float | None = None
    backoff: float | None = None
    region: str | None = None


def _first_number(node: Any, key: str) -> float | None:
    """The first entry of the list ``node[key]`` (one value per model) when it is a number."""
    values = node.get(key)
    return values[0] if isinstance(values, list) and values and is_number(values[0]) else None


def synthesis_of(diag: Diagnostics) -> Synthesis:
    """The synthesis's record (nothing certified when the artefact has none).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    synthesis = section(diag, "synthesis")
    objective = synthesis.get("objective", "hinf")
    return Synthesis(domain=entry(synthesis, "domain", is_text), route=entry(diag, "route", is_text),
                     observer=diag.get("target") == "observer",
                     objective=objective if isinstance(objective, str) else None,
                     h2_bound=entry(synthesis, "h2_bound", is_number), gamma=entry(synthesis, "gamma", is_number),
                     achieved_h2=_first_number(synthesis, "achieved_h2"),
                     achieved_hinf=_first_number(synthesis, "achieved_hinf"),
                     backoff=entry(section(synthesis, "scaling"), "backoff", is_number),
                     region=description(synthesis, "region"))
