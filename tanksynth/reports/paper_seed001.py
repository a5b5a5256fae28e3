"""Seed 001 beside tanksynth: the observability matrix, determinant and rank claim of Sec. III-C.

The printed formulas come from `tanksynth.papers.seed001`; tanksynth's side is
`tanksynth.analysis.rank.symbolic_observability` of the printed ``A(z)``. The
comparison is of the paper's own formulas, so any ``ts_observer`` artefact on the
three-tank plant brings it into the report.
"""

from __future__ import annotations

import sympy as sp

from tanksynth.analysis.rank import symbolic_observability
from tanksynth.papers import seed001 as paper
from tanksynth.reports.comparison import AGREES, ERRATUM, PaperRow, cell_terms
from tanksynth.reports.inputs import ReportInputs
from tanksynth.reports.latex import Tex

__all__ = ["observability_applies", "observability_rows"]


def observability_applies(inputs: ReportInputs) -> bool:
    """Three-tank plant with at least one ``ts_observer`` artefact.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    return inputs.plant_name == "three_tank" and bool(inputs.by_method("ts_observer"))


def _values(lam, gam) -> dict:
    vals = dict(zip(lam, (sp.Rational(str(v)) for v in paper.LAMBDA)))
    vals.update(zip(gam, (sp.Rational(str(v)) for v in paper.GAMMA)))
    return vals


def _claimed_sets(lam, gam) -> list[dict]:
    by_name = {str(s): s for s in (*lam, *gam)}
    return [{by_name[k]: int(v) if float(v).is_integer() else v for k, v in d.items()}
            for d in paper.RANK_CLAIM]


def observability_rows(inputs: ReportInputs) -> tuple[PaperRow, ...]:
    """Printed O1, det(O1), det(O1) at the Sec. IV weightings, and the rank claim.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    (z1, z2, z3), lam, gam = paper.symbols()
    A = paper.A_eq10()
    C = sp.Matrix([[1, 0, 0]])
    res = symbolic_observability(A, C, variables=(z1, z2, z3))
    O = sp.Matrix.vstack(C, C * A, C * A * A).applyfunc(sp.expand)
    rows: list[PaperRow] = []
    o_same = (O - paper.O1()).applyfunc(sp.expand) == sp.zeros(3, 3)
    rows.append(PaperRow(Tex(r"$O_1 = [C;\,CA;\,CA^2]$, $C=[1\;0\;0]$"),
                         Tex(r"rows with $(*)_1,(*)_2,(*)_3$ (Sec.~III-C)"),
                         Tex(r"$[C;\,CA;\,CA^2]$ of eq.~(10), expanded"),
                         AGREES if o_same else ERRATUM,
                         Tex("" if o_same else "entries differ from C A^k")))
    printed = paper.det_O1()
    derived = sp.expand(res.determinant)
    diff = sp.expand(derived - printed)
    rows.append(PaperRow(Tex(r"$\det O_1$"), cell_terms(printed), cell_terms(derived),
                         AGREES if diff == 0 else ERRATUM,
                         Tex("" if diff == 0 else
                             "printed minus derived is $" + sp.latex(sp.factor(-diff))
                             + r"$: the sign of the $\lambda_2\lambda_3 z_1^2 z_2$ term is wrong")))
    vals = _values(lam, gam)
    pv, dv = sp.factor(printed.xreplace(vals)), sp.factor(derived.xreplace(vals))
    same = sp.expand(pv - dv) == 0
    where = (r"$\lambda=(" + ",".join(f"{v:g}" for v in paper.LAMBDA) + r")$, $\gamma=("
             + ",".join(f"{v:g}" for v in paper.GAMMA) + ")$")
    rows.append(PaperRow(Tex(r"$\det O_1$ at " + where + r" (Sec.~IV)"),
                         Tex("$" + sp.latex(pv) + "$"), Tex("$" + sp.latex(dv) + "$"),
                         AGREES if same else ERRATUM,
                         Tex("" if same else "the $z_2$ coefficient has the wrong sign")))
    sets = [dict(d) for d in res.degenerate_parameters]
    sets_tex = "; ".join("$" + ", ".join(f"{sp.latex(k)} = {sp.latex(v)}" for k, v in
                                         sorted(d.items(), key=lambda kv: str(kv[0]))) + "$"
                         for d in sets)
    claimed = _claimed_sets(lam, gam)
    # the claim: rank 3 iff lambda2 != 0 and lambda3 != 0, i.e. the degenerate sets are
    # exactly {lambda2 = 0} and {lambda3 = 0}
    claim_ok = sorted(map(str, sets)) == sorted(map(str, claimed))
    counter = ""
    if not claim_ok:
        counter = (r"$\det O_1$ vanishes identically only on these sets; e.g.\ $\lambda_2 = 0$ "
                   r"with $\gamma_2\lambda_3 \neq 0$ leaves $\det O_1 = \gamma_2\lambda_3^2 z_1^2 "
                   r"z_3 \not\equiv 0$ (rank 3), so $\lambda_2\neq0$ is not necessary")
    claim_tex = " and ".join(f"${sp.latex(k)} \\neq {sp.latex(v)}$" for d in claimed
                             for k, v in d.items())
    rows.append(PaperRow(Tex(r"rank $O_1 = 3$ condition"),
                         Tex("iff " + claim_tex),
                         Tex("rank drops for every $z$ exactly on: " + sets_tex),
                         AGREES if claim_ok else ERRATUM, Tex(counter)))
    return tuple(rows)
