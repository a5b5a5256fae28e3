"""One problem statement per design method: what was solved, in mathematics, for the report.

A statement ``<method>_statement(diag) -> Tex`` reads the artefact's diagnostics only (through
`tanksynth.reports.diagnostics`). Each method family has its module here, named as in every
stage (``statements.robust``, ``statements.synthesis`` ...), whose statements are made from one
template (`tanksynth.reports.statements.common.problem_statement`); the method table
(`tanksynth.methods`) names which statement belongs to which method.
"""

from __future__ import annotations

from tanksynth._lazy import lazy_exports as _lazy_exports

#: The statements of each family's module.
_FAMILIES = {
    "model": ["linearize"],
    "placement": ["pole_placement", "lmi_placement", "canonical_observer"],
    "observer_lmi": ["ts_observer"],
    "takagi_sugeno": ["ts_state_feedback", "ts_output_feedback"],
    "laws": ["feedback_linearization", "integral_tracking", "inverse_dynamics"],
    "decentralized": ["decentralized_kalman"],
    "estimators": ["kalman", "ekf", "ukf", "adaptive_kalman", "adaptive_scaling_kalman", "consensus_filter",
                   "luenberger", "narx"],
    "fault": ["fault_detection"],
    "robust": ["robust_state_feedback", "robust_observer"],
    "synthesis": ["h2_state_feedback", "h2_observer", "hinf_state_feedback", "hinf_observer",
                  "multiobjective"],
    "fit": ["fit"],
}

#: Re-exported statement -> its family's module, imported on first use (PEP 562): importing one
#: family's module does not load the others.
_EXPORTS = {f"{method}_statement": f"{__name__}.{family}"
            for family, methods in _FAMILIES.items() for method in methods}

__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)

__all__ = list(_EXPORTS)
