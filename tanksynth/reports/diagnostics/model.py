"""The ``model`` family's diagnostics (``linearize``): the equilibrium, the linearisation's
eigenvalues and sampling period, and whether the smooth form of the model holds there.
"""

from __future__ import annotations

from dataclasses import dataclass

from tanksynth.reports.diagnostics.common import (Diagnostics, JsonNumber, eigenvalue_pairs, entries, entry,
                                                  is_flag, is_json_number, is_number, section)

__all__ = ["Equilibrium", "equilibrium_of", "Linearization", "linearization_of"]


@dataclass(frozen=True)
class Equilibrium:
    """The operating point's input (``diagnostics["equilibrium"]``, written by every design
    that linearises the plant).

    Attributes
    ----------
    residual : tuple or None
        ``f(x0, u0)`` with the model's equilibrium input, per state (state units per second).
    max_abs_residual : float, str or None
        Its largest magnitude (state units per second).
    is_equilibrium : bool or None
        Whether that residual is within the tolerance.
    within_input_bounds : bool or None
        Whether ``u0`` is inside the input bounds.
    given_u0 : tuple or None
        The spec's own input, when it gave one (input units).
    given_u0_residual : tuple or None
        ``f(x0, given_u0)`` per state (state units per second).
    given_u0_balances : bool or None
        Whether the spec's input is an equilibrium input.
    """

    residual: tuple[JsonNumber, ...] | None = None
    max_abs_residual: JsonNumber = None
    is_equilibrium: bool | None = None
    within_input_bounds: bool | None = None
    given_u0: tuple[JsonNumber, ...] | None = None
    given_u0_residual: tuple[JsonNumber, ...] | None = None
    given_u0_balances: bool | None = None


def equilibrium_of(diag: Diagnostics) -> Equilibrium:
    """The design's equilibrium (every field None when the artefact has none).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    eq = section(diag, "equilibrium")
    return Equilibrium(residual=entries(eq, "residual", is_json_number),
                       max_abs_residual=entry(eq, "max_abs_residual", is_json_number),
                       is_equilibrium=entry(eq, "is_equilibrium", is_flag),
                       within_input_bounds=entry(eq, "within_input_bounds", is_flag),
                       given_u0=entries(eq, "given_u0", is_json_number),
                       given_u0_residual=entries(eq, "given_u0_residual", is_json_number),
                       given_u0_balances=entry(eq, "given_u0_balances", is_flag))


@dataclass(frozen=True)
class Linearization:
    """What ``linearize`` records beside its matrices.

    Attributes
    ----------
    equilibrium : Equilibrium
        The operating point's input.
    eigenvalues_F : tuple of (float, float) or None
        Eigenvalues ``(re, im)`` of the Jacobian ``F`` (1/s).
    eigenvalues_Ad : tuple of (float, float) or None
        Eigenvalues of the discretised ``A_d`` (dimensionless).
    ts : float or None
        The sampling period (s).
    smooth_form_valid : bool or None
        Whether the operating point lies where the smooth model holds.
    """

    equilibrium: Equilibrium
    eigenvalues_F: tuple[tuple[float, float], ...] | None
    eigenvalues_Ad: tuple[tuple[float, float], ...] | None
    ts: float | None
    smooth_form_valid: bool | None


def linearization_of(diag: Diagnostics) -> Linearization:
    """The linearisation's record (fields None where the artefact has none).

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    return Linearization(equilibrium=equilibrium_of(diag),
                         eigenvalues_F=eigenvalue_pairs(diag, "eigenvalues_F"),
                         eigenvalues_Ad=eigenvalue_pairs(diag, "eigenvalues_Ad"),
                         ts=entry(diag, "ts", is_number),
                         smooth_form_valid=entry(diag, "smooth_form_valid", is_flag))
