"""The ``observer_lmi`` family's diagnostics (``ts_observer``): the Lipschitz bound and the form
of the LMI (28) of seed 001, and the TS model it was written on.
"""

from __future__ import annotations

from dataclasses import dataclass

from tanksynth.reports.diagnostics.common import Diagnostics, entry, is_number, is_text, section
from tanksynth.reports.diagnostics.takagi_sugeno import TsModel, ts_model_of

__all__ = ["TsObserver", "ts_observer_of"]


@dataclass(frozen=True)
class TsObserver:
    """What ``ts_observer`` records.

    Attributes
    ----------
    psi : float or None
        The Lipschitz bound of the remainder ``Delta`` (1/s).
    psi_source : str or None
        Where ``psi`` came from (given, maximised, estimated), in words.
    q_form : str or None
        The form of the matrix ``Q`` of the LMI, in words.
    ts_model : TsModel
        The TS model of the plant.
    """

    psi: float | None
    psi_source: str | None
    q_form: str | None
    ts_model: TsModel


def ts_observer_of(diag: Diagnostics) -> TsObserver:
    """The TS observer's record.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    lmi = section(diag, "lmi")
    return TsObserver(psi=entry(lmi, "psi", is_number), psi_source=entry(diag, "psi_source", is_text),
                      q_form=entry(lmi, "Q_form", is_text), ts_model=ts_model_of(diag))
