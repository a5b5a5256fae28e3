"""Paper vs tool: the seed papers' printed values beside what tanksynth derived.

The printed values live in `tanksynth.papers` (one module per seed paper); this
module holds the registry of seed reproductions (`REPRODUCTIONS`: when each applies
and how its rows are computed, in `tanksynth.reports.paper_seed000` ..
``paper_seed004``) and turns every ``reference_*`` comparison an artefact carries (a
printed gain given in the spec as ``reference_gain``, ``reference_L`` ...) into rows.
The verdict of a row is computed by comparing numbers (or symbolic expressions);
where a printed formula is wrong but happens to give the right number at the
operating point, the row says so.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.reports import paper_seed000, paper_seed001, paper_seed002, paper_seed003, paper_seed004
from tanksynth.reports.comparison import (AGREES, DIFFERS, ERRATUM, PaperComparison, PaperRow,
                                          Reproduction, cell_matrix, printed_precision)
from tanksynth.reports.diagnostics.common import references_of
from tanksynth.reports.diagnostics.placement import design_poles_of
from tanksynth.reports.inputs import ReportInputs
from tanksynth.reports.latex import Tex, escape_latex, format_eigenvalues, format_number

__all__ = [
    "AGREES", "ERRATUM", "DIFFERS",
    "PaperRow",
    "PaperComparison",
    "Reproduction",
    "REPRODUCTIONS",
    "compare_with_papers",
    "reference_rows",
    "POLE_ERROR_ERRATUM",
]


# ===================================================================== registry
#: Every seed reproduction the report knows, in report order.
REPRODUCTIONS: tuple[Reproduction, ...] = (
    Reproduction("seed000_linearisation", "000",
                 "Three-tank linearisation at y0 = (0.40, 0.20, 0.30) m",
                 "seed 000 (Widjiantoro et al.): the linearised model F and B, Table I, Sec. IV u0 and y0",
                 paper_seed000.linearisation_applies, paper_seed000.linearisation_rows),
    Reproduction("seed000_control_law", "000",
                 "Three-tank decoupling control law u = alpha + beta zeta",
                 "seed 000 (Widjiantoro et al.): the decoupling control law, Sec. IV nonlinear control input",
                 paper_seed000.law_applies, paper_seed000.law_rows),
    Reproduction("seed000_akf", "000",
                 "Three-tank adaptive covariance Kalman filter (AKF)",
                 "seed 000 (Widjiantoro et al.): the adaptive Kalman filter of Sec. III, Sec. IV initial conditions, Fig. 8",
                 paper_seed000.akf_applies, paper_seed000.akf_rows),
    Reproduction("seed001_observability", "001",
                 "Quasi-LPV three-tank: observability with one measured level",
                 Tex(r"seed 001: the state matrix $A(z)$, Sec.~III-C $\mathcal{O}_1$ and $\det\mathcal{O}_1$, "
                     r"Sec.~IV $\lambda$ and $\gamma$"),
                 paper_seed001.observability_applies, paper_seed001.observability_rows),
    Reproduction("seed001_fig2", "001",
                 "Quasi-LPV three-tank observer: the initial states of Fig. 2-3",
                 "seed 001: Sec. IV initial conditions of the multiple model and of the observer, Fig. 2-3",
                 paper_seed001.fig2_applies, paper_seed001.fig2_rows),
    Reproduction("seed002_estimators", "002",
                 "Hybrid three-tank: plant tables and the EKF, UKF and NARX estimators",
                 "seed 002 (Vellayikot & Vaidyan): Tables 1-3, EKF/UKF eqs. (13)-(14), NARX eqs. (44)-(45), Sec. 6",
                 paper_seed002.estimators_applies, paper_seed002.estimators_rows),
    Reproduction("seed002_control", "002",
                 "Hybrid three-tank: inverse-dynamics control, servo test",
                 "seed 002 (Vellayikot & Vaidyan): Table 4, Sec. 5.1, control law eqs. (46)-(47)",
                 paper_seed002.control_applies, paper_seed002.control_rows),
    Reproduction("seed003_network", "003",
                 "40-tank network: decentralised Kalman filtering",
                 "seed 003 (Pedroso et al.): DECENTER script NTanksNetworkEstimationOSFH (no numbered equations): constants, figures",
                 paper_seed003.network_applies, paper_seed003.network_rows),
    Reproduction("seed004_structure", "004",
                 "Hydraulic fault model: controllability, observability, transfer function",
                 "seed 004, Sec. III: controllability and observability matrices, transfer function, observer canonical form",
                 paper_seed004.structure_applies, paper_seed004.structure_rows),
    Reproduction("seed004_fault_detection", "004",
                 "Hydraulic fault model: observer, threshold and detection times",
                 "seed 004, Sec. II-F and IV: observer gain, residual threshold, detection times",
                 paper_seed004.detection_applies, paper_seed004.detection_rows,
                 paper_seed004.INITIAL_STATES_TEX),
)


# ===================================================================== spec references
def _half_unit(x: float) -> float:
    """Half a unit of the last digit of ``x`` as written (shortest round-trip repr)."""
    return printed_precision(repr(float(x)))


#: A printed gain whose poles miss the design's poles by more than this fraction of the
#: largest pole is an erratum (rounding of printed digits moves poles far less).
POLE_ERROR_ERRATUM = 0.05


def reference_rows(artefact: Mapping[str, Any]) -> tuple[PaperRow, ...]:
    """Rows for every ``reference_*`` comparison stored in an artefact's diagnostics.

    A design that was given a printed value (``reference_gain``,
    ``reference_L``, ``reference_closed_loop`` in the spec) stores the
    reference, the derived value and their difference. Verdicts:

    * `AGREES` when every entry matches to the digits written in the spec
      (half a unit of the last digit);
    * `ERRATUM` when the reference misses the design's poles by more than
      `POLE_ERROR_ERRATUM` of the largest pole (rounding cannot explain it);
    * `DIFFERS` otherwise: gains placing the same poles are not unique with
      several inputs or outputs, and LMI solutions are not unique.

    Parameters
    ----------
    artefact : mapping
        A loaded artefact.
    """
    rows: list[PaperRow] = []
    diag = artefact.get("diagnostics") or {}
    poles = design_poles_of(diag)
    scale_poles = max(abs(p) for p in poles) if poles else None
    for ref in references_of(diag):
        R, D = ref.reference, ref.derived
        if R.shape != D.shape or R.size > 64:
            continue
        scale = max(float(np.max(np.abs(D), initial=0.0)), 1e-300)
        diff = np.abs(R - D)
        maxdiff = float(np.max(diff, initial=0.0))
        tol = np.vectorize(_half_unit)(R) if R.size else R
        same = bool(np.all(diff <= tol + 1e-12 * scale))
        parts = []
        if not same:
            parts.append(f"largest difference ${format_number(maxdiff, 3)}$ "
                         f"(${format_number(100 * maxdiff / scale, 3)}\\,\\%$ of the largest entry)")
        elif maxdiff > 0:
            parts.append("equal to the digits given")
        verdict = AGREES if same else DIFFERS
        for eigenvalues in ref.eigenvalues:
            parts.append("the reference gives eigenvalues $"
                         + format_eigenvalues([list(p) for p in eigenvalues], 4) + "$")
        err = ref.max_pole_error
        if err is not None:
            rel = float(err) / scale_poles if scale_poles else None
            parts.append(f"largest pole error ${format_number(err, 3)}$"
                         + (f" (${format_number(100 * rel, 3)}\\,\\%$ of the largest pole)"
                            if rel is not None else ""))
            if not same and rel is not None and rel > POLE_ERROR_ERRATUM:
                verdict = ERRATUM
                parts.insert(0, "the printed value does not have the design's poles")
        if ref.note is not None:
            parts.append(escape_latex(ref.note))
        rows.append(PaperRow(
            Tex(r"\texttt{" + escape_latex(ref.label, breakable=True) + r"} of \texttt{"
                + escape_latex(artefact.get("name", ""), breakable=True) + "}"),
            cell_matrix(R, 4), cell_matrix(D, 4), verdict, Tex("; ".join(parts))))
    return tuple(rows)


def compare_with_papers(inputs: ReportInputs) -> tuple[PaperComparison, ...]:
    """Every registered reproduction that applies to ``inputs``, plus spec references.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).

    Returns
    -------
    tuple of PaperComparison
        Seed reproductions first (registry order), then one comparison
        with the ``reference_*`` rows of all artefacts (if any).
    """
    out = [PaperComparison(r.key, r.seed, r.title, r.source, r.compute(inputs), r.intro)
           for r in REPRODUCTIONS if r.applies(inputs)]
    refs = tuple(row for a in inputs.artefacts for row in reference_rows(a))
    if refs:
        out.append(PaperComparison("spec_references", "", "Printed gains given in the spec",
                                   "reference values in the spec's design tables", refs))
    return tuple(out)
