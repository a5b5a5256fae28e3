"""The Takagi-Sugeno diagnostics: the TS model and its domain (written by ``ts_observer`` and the
``takagi_sugeno`` family), and what the PDC designs record (relaxation, decay rate, certified
region, set-point change, the observer of ``ts_output_feedback``).
"""

from __future__ import annotations

from dataclasses import dataclass

from tanksynth.reports.diagnostics.common import (Diagnostics, JsonNumber, entries, entry, is_json_number,
                                                  is_number, is_text, names, section)

__all__ = ["DomainInequality", "TsDomain", "TsModel", "ts_model_of", "PdcDesign", "pdc_design_of",
           "CertifiedRegion", "certified_region_of", "SetpointChange", "setpoint_change_of"]


@dataclass(frozen=True)
class DomainInequality:
    """One linear inequality ``G x >= g`` of the TS domain (a flow ordering).

    Attributes
    ----------
    G : tuple of float
        Coefficients, one per state (per state unit).
    g : float
        Right-hand side (dimensionless).
    """

    G: tuple[float, ...]
    g: float


@dataclass(frozen=True)
class TsDomain:
    """The domain on which the TS model is exact: a box and linear inequalities.

    Attributes
    ----------
    description : str or None
        The domain in words.
    lower, upper : tuple of float or None
        The box (state units).
    inequalities : tuple of DomainInequality
        The further faces ``G x >= g``.
    """

    description: str | None = None
    lower: tuple[float, ...] | None = None
    upper: tuple[float, ...] | None = None
    inequalities: tuple[DomainInequality, ...] = ()


@dataclass(frozen=True)
class TsModel:
    """The Takagi-Sugeno model a design used (``diagnostics["ts_model"]``).

    Attributes
    ----------
    vertices : int or None
        The number ``r`` of vertex models.
    domain : TsDomain
        Where the model is exact.
    """

    vertices: int | None
    domain: TsDomain


def _inequality(row: object) -> DomainInequality | None:
    G, g = entries(row, "G", is_number), entry(row, "g", is_number)
    return None if G is None or g is None else DomainInequality(G, g)


def ts_model_of(diag: Diagnostics) -> TsModel:
    """The design's TS model (nothing known when the artefact has none).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    model = section(diag, "ts_model")
    domain = section(model, "domain")
    rows = domain.get("inequalities")
    inequalities = [_inequality(row) for row in rows] if isinstance(rows, list) else []
    r = model.get("r")
    return TsModel(vertices=r if isinstance(r, int) and not isinstance(r, bool) else None,
                   domain=TsDomain(description=entry(domain, "description", is_text),
                                   lower=entries(domain, "lower", is_number),
                                   upper=entries(domain, "upper", is_number),
                                   inequalities=tuple(q for q in inequalities if q is not None)))


@dataclass(frozen=True)
class PdcDesign:
    """What a PDC design (``ts_state_feedback``, ``ts_output_feedback``) records of its LMIs.

    Attributes
    ----------
    relaxation : str or None
        The relaxation whose LMIs were feasible (``vertex``, ``tuan``, ``all_pairs``).
    decay_rate : float or None
        The supremum of the decay rate of ``V`` the matrices certify (1/s): the LMIs hold with
        equality there.
    decay_at_least : float or None
        The decay rate certified with the LMIs strict (1/s), when recorded.
    decay_margin : float or None
        Minus the largest eigenvalue of the LMI conditions at ``decay_at_least`` (positive; units of the LMI, dimensionless).
    premises : str or None
        ``"measured"`` or ``"estimated"`` (output feedback).
    observer_psi : float or None
        The Lipschitz bound of the observer's remainder, estimated premises (1/s).
    composite : bool
        An observer runs with the controller (output feedback).
    composite_beta : float or None
        The weight of the observer's Lyapunov function in the composite certificate.
    error_ball : float or None
        Radius of the largest ball of initial estimation error the composite certificate allows
        with the plant starting at the operating point (state units).
    error_semi_axes : tuple of float or None
        Semi-axes of the ellipsoid of those errors, ascending (state units).
    plant_ball_estimate_at_x_op : float or None
        Radius of the largest ball of initial plant states certified when the estimate starts at
        the operating point (state units).
    """

    relaxation: str | None = None
    decay_rate: float | None = None
    decay_at_least: float | None = None
    decay_margin: float | None = None
    premises: str | None = None
    observer_psi: float | None = None
    composite: bool = False
    composite_beta: float | None = None
    error_ball: float | None = None
    error_semi_axes: tuple[float, ...] | None = None
    plant_ball_estimate_at_x_op: float | None = None


def pdc_design_of(diag: Diagnostics) -> PdcDesign:
    """The PDC design's record.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    composite = section(diag, "composite")
    bracket = section(section(diag, "lmi"), "decay_rate_bracket")
    return PdcDesign(relaxation=entry(diag, "relaxation", is_text),
                     decay_rate=entry(diag, "decay_rate", is_number),
                     decay_at_least=entry(bracket, "at_least", is_number),
                     decay_margin=entry(bracket, "margin", is_number),
                     premises=entry(diag, "premises", is_text),
                     observer_psi=entry(section(diag, "observer"), "psi", is_number),
                     composite=bool(composite), composite_beta=entry(composite, "beta", is_number),
                     error_ball=entry(section(composite, "initial_error"), "error_ball_at_x_op", is_number),
                     error_semi_axes=entries(section(composite, "initial_error"), "error_semi_axes", is_number),
                     plant_ball_estimate_at_x_op=entry(section(composite, "initial_error"),
                                                       "plant_ball_estimate_at_x_op", is_number))


@dataclass(frozen=True)
class CertifiedRegion:
    """The certified region ``{x : (x - x0)' P (x - x0) <= c}`` of a PDC design.

    Attributes
    ----------
    c : float or None
        The level of ``(x - x0)' P (x - x0)`` (dimensionless).
    binding : str or None
        The constraint that fixes ``c`` (a domain face or a pump margin).
    states : tuple of str
        The state names, in order.
    extents : tuple or None
        The largest deviation of each state on the region (m).
    semi_axes : tuple or None
        The ellipsoid's semi-axes (m).
    """

    c: float | None = None
    binding: str | None = None
    states: tuple[str, ...] = ()
    extents: tuple[JsonNumber, ...] | None = None
    semi_axes: tuple[JsonNumber, ...] | None = None


def certified_region_of(diag: Diagnostics) -> CertifiedRegion:
    """The design's certified region (``c`` None when there is none).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics (or the set-point change's section).
    """
    region = section(diag, "region")
    return CertifiedRegion(c=entry(region, "c", is_number), binding=entry(region, "binding", is_text),
                           states=names(region, "states"), extents=entries(region, "extents", is_json_number),
                           semi_axes=entries(region, "semi_axes", is_json_number))


@dataclass(frozen=True)
class SetpointChange:
    """A certified set-point change (``diagnostics["setpoint"]``).

    Attributes
    ----------
    x_op2 : tuple
        The new operating point (m).
    switch_level : float
        ``gamma``: the law switches once ``V1 <= gamma c1`` (dimensionless).
    region_c : float or None
        The level ``c2`` of the region about ``x_op2`` (dimensionless).
    dwell_time : float or None
        Time after which the switch is certain from anywhere in the first region (s).
    """

    x_op2: tuple[JsonNumber, ...]
    switch_level: float
    region_c: float | None = None
    dwell_time: float | None = None


def setpoint_change_of(diag: Diagnostics) -> SetpointChange | None:
    """The design's set-point change, or None without one.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    setpoint = section(diag, "setpoint")
    x_op2, gamma = entries(setpoint, "x_op2", is_json_number), entry(setpoint, "switch_level", is_number)
    if x_op2 is None or gamma is None:
        return None
    return SetpointChange(x_op2, gamma, region_c=certified_region_of(setpoint).c,
                          dwell_time=entry(setpoint, "dwell_time", is_number))
