"""The ``robust`` family's diagnostics (``robust_state_feedback``, ``robust_observer``): the
parameter box and its vertex models, the LMI region, the H-infinity bound and its channel, the
offsets without integral action and the saturation-aware ellipsoid.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from tanksynth.reports.diagnostics.common import (Diagnostics, JsonNumber, description, entries, entry,
                                                  is_flag, is_json_number, is_number, is_text, section)

__all__ = ["UncertainParameter", "HinfBound", "HinfChannel", "Robustness", "robustness_of"]


@dataclass(frozen=True)
class UncertainParameter:
    """One side of the parameter box: a parameter and its interval.

    Attributes
    ----------
    name : str
        The plant parameter.
    low, high : float or str
        Its bounds (the parameter's unit).
    """

    name: str
    low: JsonNumber
    high: JsonNumber


@dataclass(frozen=True)
class HinfBound:
    """The H-infinity bound certified at every vertex (``diagnostics["robust"]["hinf"]``).

    Attributes
    ----------
    gamma : float
        The bound on ``||T_zw||_inf`` (the units of z per unit of w).
    imposed : bool or None
        False when the design without the bound already met it (not imposed in the LMIs).
    lyapunov_scale : float or None
        The factor on the design's own Lyapunov matrix that certifies it then.
    """

    gamma: float
    imposed: bool | None = None
    lyapunov_scale: float | None = None


@dataclass(frozen=True)
class HinfChannel:
    """The H-infinity channel ``w -> z`` (``diagnostics["hinf_channel"]``).

    Attributes
    ----------
    observer : bool
        The channel of an observer's error (``z = C_z e``, no ``D_zu``).
    given : frozenset of str
        Which of ``Bw``, ``Cz``, ``Dzu`` the spec gave (the others are defaults).
    """

    observer: bool
    given: frozenset[str]


@dataclass(frozen=True)
class Robustness:
    """What a robust design records.

    Attributes
    ----------
    uncertain : tuple of UncertainParameter
        The parameter box (empty: the nominal model only).
    balanced : tuple of bool
        Per corner model, whether an input holds the operating levels there.
    region : str or None
        The LMI region in words.
    domain : str or None
        ``"continuous"`` or ``"discrete"``.
    margin : float or None
        The margin of the strict LMIs, after scaling (dimensionless).
    hinf : HinfBound or None
        The H-infinity bound, when one was asked for.
    channel : HinfChannel or None
        Its channel.
    offset : float or None
        Without integral action, the largest deviation from ``x0`` a vertex plant settles to
        (state units).
    ellipsoid_axes : tuple of float or None
        The semi-axes of the invariant ellipsoid when saturation was taken into account (state
        units); None without.
    saturation : bool
        Saturation was taken into account (an invariant ellipsoid on which the pumps stay in range).
    """

    uncertain: tuple[UncertainParameter, ...] = ()
    balanced: tuple[bool, ...] = ()
    region: str | None = None
    domain: str | None = None
    margin: float | None = None
    hinf: HinfBound | None = None
    channel: HinfChannel | None = None
    offset: float | None = None
    ellipsoid_axes: tuple[float, ...] | None = None
    saturation: bool = False


def _uncertain(value: object) -> tuple[UncertainParameter, ...]:
    if not isinstance(value, list):
        return ()
    return tuple(UncertainParameter(str(u[0]), u[1], u[2]) for u in value
                 if isinstance(u, list) and len(u) == 3 and is_json_number(u[1]) and is_json_number(u[2]))


def _hinf(robust: object) -> HinfBound | None:
    hinf = section(robust, "hinf")
    gamma = entry(hinf, "gamma", is_number)
    if gamma is None:
        return None
    return HinfBound(gamma, entry(hinf, "imposed", is_flag), entry(hinf, "lyapunov_scale", is_number))


def _channel(value: object) -> HinfChannel | None:
    if not isinstance(value, Mapping) or "observer" not in value:
        return None
    given = value.get("given")
    return HinfChannel(bool(value["observer"]),
                       frozenset(str(g) for g in given) if isinstance(given, list) else frozenset())


def robustness_of(diag: Diagnostics) -> Robustness:
    """The robust design's record (the nominal model only, nothing certified, when the artefact
    has none).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    robust = section(diag, "robust")
    balanced = section(diag, "vertex_models").get("balanced")
    saturation = diag.get("saturation")
    return Robustness(
        uncertain=_uncertain(diag.get("uncertain")),
        balanced=tuple(b for b in balanced if isinstance(b, bool)) if isinstance(balanced, list) else (),
        region=description(robust, "region"), domain=entry(robust, "domain", is_text),
        margin=entry(robust, "margin", is_number),
        hinf=_hinf(robust), channel=_channel(diag.get("hinf_channel")),
        offset=entry(section(diag, "offsets"), "max_abs_deviation", is_number),
        ellipsoid_axes=entries(section(saturation, "ellipsoid_axes"), "lengths", is_number),
        saturation=isinstance(saturation, Mapping))
