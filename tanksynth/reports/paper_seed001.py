"""Seed 001 beside tanksynth: the observability matrix, determinant and rank claim of Sec. III-C.

The printed formulas come from `tanksynth.papers.seed001`; tanksynth's side is
`tanksynth.analysis.rank.symbolic_observability` of the printed ``A(z)``. The
comparison is of the paper's own formulas, so any ``ts_observer`` artefact on the
three-tank plant brings it into the report.
"""

from __future__ import annotations

import numpy as np
import sympy as sp
from scipy.optimize import minimize

from tanksynth.analysis.rank import symbolic_observability
from tanksynth.papers import seed001 as paper
from tanksynth.reports.comparison import (AGREES, DIFFERS, ERRATUM, PaperRow, cell_matrix, cell_terms,
                                          verdict_check)
from tanksynth.reports.inputs import ReportInputs
from tanksynth.reports.latex import Tex, escape_latex, format_number

__all__ = ["observability_applies", "observability_rows", "ORDER_GAP", "nearest_admissible",
           "fig2_applies", "fig2_rows"]

#: Separation kept between consecutive levels of the printed ordering when a printed initial
#: state is projected into the tank (m).
ORDER_GAP = 0.05


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
                         Tex(r"$[C;\,CA;\,CA^2]$ with the printed $A(z)$, expanded"),
                         AGREES if o_same else ERRATUM,
                         Tex("" if o_same else r"entries differ from $CA^k$")))
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


# ===================================================================== Fig. 2-3 initial states
def nearest_admissible(point, low: float, high: float, gap: float = ORDER_GAP) -> np.ndarray:
    """The point of the box nearest to ``point`` that keeps its ordering of the levels.

    "Nearest" is the Euclidean projection onto ``{low <= h_i <= high}`` intersected
    with the printed ordering ``h_a > h_b > h_c`` of ``point`` kept with a gap:
    ``h_a - h_b >= gap``, ``h_b - h_c >= gap`` (a convex quadratic programme).

    Parameters
    ----------
    point : sequence of float
        The printed state (m).
    low, high : float
        The box of every level (m).
    gap : float, optional
        Smallest separation kept between consecutive levels of the ordering (m).

    Returns
    -------
    ndarray
        The projected state (m).
    """
    p = np.asarray(point, dtype=float)
    order = np.argsort(-p, kind="stable")
    cons = [{"type": "ineq", "fun": (lambda h, a=int(a), b=int(b): h[a] - h[b] - gap),
             "jac": (lambda h, a=int(a), b=int(b): np.eye(len(p))[a] - np.eye(len(p))[b])}
            for a, b in zip(order[:-1], order[1:])]
    start = np.clip(p, low, high)
    res = minimize(lambda h: float(np.sum((h - p) ** 2)), start, jac=lambda h: 2 * (h - p),
                   bounds=[(low, high)] * len(p), constraints=cons, method="SLSQP",
                   options={"ftol": 1e-14, "maxiter": 200})
    return np.asarray(res.x, dtype=float)


def _paper_design(inputs: ReportInputs):
    arts = inputs.by_method("ts_observer")
    for a in arts:
        if verdict_check(a, "observer_declared_start") is not None:
            return a
    return arts[0] if arts else None


def fig2_applies(inputs: ReportInputs) -> bool:
    """Three-tank plant with a ``ts_observer`` artefact (the printed initial states apply).

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    return observability_applies(inputs)


def _vec(v) -> str:
    return "(" + ", ".join(format_number(float(x), 4) for x in v) + ")"


def fig2_rows(inputs: ReportInputs) -> tuple[PaperRow, ...]:
    """The printed initial states of Fig. 2-3 against the tank height, and the nearest admissible run.

    The printed states lie above the tank; the nearest admissible ones
    (`nearest_admissible` into ``[0, h_max]`` with the printed ordering kept by
    `ORDER_GAP`) are compared with the ``x_start``, ``x_hat_start`` the spec
    declares, and the paper's claim with the stored ``observer_declared_start``
    verdict of that run.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    hmax = float(inputs.parameters().get("hmax", np.nan))
    rows: list[PaperRow] = []
    near = {}
    for key, label, printed in (("x", r"initial state $x_0$ (Fig.~2)", paper.FIG2_X0),
                                ("xhat", r"initial estimate $\hat x_0$ (Fig.~2)", paper.FIG2_XHAT0)):
        p = np.asarray(printed, dtype=float)
        above = [i for i in range(len(p)) if p[i] > hmax]
        near[key] = nearest_admissible(p, 0.0, hmax)
        rows.append(PaperRow(
            Tex(label), Tex("$" + _vec(p) + "$"),
            Tex(f"{len(above)} of {len(p)} levels above $h_{{\\max}} = {format_number(hmax, 3)}$ m"),
            ERRATUM if above else AGREES,
            Tex((", ".join(f"$h_{{{i + 1}}} = {format_number(p[i], 3)}$" for i in above)
                 + f" m lie above the tank height ${format_number(hmax, 3)}$ m of the plant; "
                 f"nearest admissible: ${_vec(near[key])}$ m (Euclidean projection into "
                 f"$[0, {format_number(hmax, 3)}]^3$ keeping the printed order of the levels "
                 f"with gaps of ${format_number(ORDER_GAP, 2)}$ m)") if above else "")))
    art = _paper_design(inputs)
    check = None if art is None else verdict_check(art, "observer_declared_start")
    data = (check or {}).get("data") or {}
    xs, xhs = data.get("x_start"), data.get("x_hat_start")
    if check is None or xs is None or xhs is None:
        rows.append(PaperRow(Tex("Fig.~2 run from the nearest admissible states"),
                             Tex(escape_latex(paper.FIG2_CLAIM)), Tex("not run"), DIFFERS,
                             Tex(r"declare \texttt{x\_start} and \texttt{x\_hat\_start} of a "
                                 r"\texttt{ts\_observer} design and run \texttt{tanksynth verify}")))
        return tuple(rows)
    same = (np.allclose(xs, near["x"], atol=1e-6, rtol=0) and
            np.allclose(xhs, near["xhat"], atol=1e-6, rtol=0))
    rows.append(PaperRow(Tex(r"declared run: $x_0$, $\hat x_0$ (m)"),
                         Tex("nearest admissible"), cell_matrix(np.array([xs, xhs]), 4),
                         AGREES if same else DIFFERS,
                         Tex("" if same else "the spec runs other initial states than the nearest "
                                             "admissible ones")))
    ok = bool(check.get("passed"))
    e0, tail = data.get("e0"), data.get("tail_max")
    ours = (f"$|e|_\\infty$ from ${format_number(e0, 3)}$ m to ${format_number(tail, 3)}$ m "
            f"on $[H, 1.2H]$, $H = {format_number(data.get('horizon_s', np.nan), 3)}$ s"
            if e0 is not None and tail is not None else escape_latex(str(check.get("detail", ""))))
    rows.append(PaperRow(Tex("Fig.~2: estimation error from the nearest admissible states"),
                         Tex(escape_latex(paper.FIG2_CLAIM)), Tex(ours), AGREES if ok else DIFFERS,
                         Tex(f"verdict \\texttt{{observer\\_declared\\_start}} of "
                             f"\\texttt{{{escape_latex(str(art.get('name', '')))}}}"
                             + ("" if ok else ": not reproduced, the error does not decay to 5\\,\\% "
                                "of its start"))))
    return tuple(rows)
