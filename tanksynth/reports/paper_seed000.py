"""Seed 000 beside tanksynth: the linearisation of eq. (8) and the control law of Sec. IV.

The printed values come from `tanksynth.papers.seed000`; the rows compare them
with the ``linearize`` and ``feedback_linearization`` artefacts of a result
directory on the three-tank plant with the paper's Table I parameters.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from tanksynth.errors import ReportError
from tanksynth.papers import seed000 as paper
from tanksynth.plants import builtin_plant
from tanksynth.reports.comparison import (AGREES, DIFFERS, ERRATUM, PaperRow, artefact_arrays, cell_fit, cell_matrix, cell_number, close,
                                          first_artefact, latex_matrix_entries, params_match,
                                          printed_precision, verdict_check)
from tanksynth.reports.diagnostics.laws import controlled_outputs_of
from tanksynth.reports.diagnostics.model import equilibrium_of
from tanksynth.reports.inputs import ReportInputs
from tanksynth.reports.latex import Tex, escape_latex, format_eigenvalues, format_number

__all__ = ["linearisation_applies", "linearisation_rows", "law_applies", "law_rows", "akf_applies",
           "akf_rows"]

_LIN_SHAPES = {"F": (3, 3), "B": (3, 2), "u_op": (2,)}
_LAW_SHAPES = {"Lambda_op": (2, 2), "Lambda0_op": (2,), "x_op": (3,)}
_AKF_SHAPES = {"x_hat0": (3,), "P0": (3, 3), "Q0": (3, 3), "R": (3, 3)}


def linearisation_applies(inputs: ReportInputs) -> bool:
    """Three-tank plant at the paper's y0 with Table I and a ``linearize`` artefact there.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    x0 = inputs.x0
    return (inputs.plant_name == "three_tank" and x0 is not None and x0.shape == (3,)
            and np.allclose(x0, paper.Y0, rtol=0, atol=1e-9)
            and params_match(inputs, paper.TABLE_I)
            and first_artefact(inputs, "linearize", paper.Y0, _LIN_SHAPES) is not None)


def linearisation_rows(inputs: ReportInputs) -> tuple[PaperRow, ...]:
    """Eq. (8) F entry by entry (and as formulas), its eigenvalues, B, and the printed u0.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    art = first_artefact(inputs, "linearize", paper.Y0, _LIN_SHAPES)
    arrays = None if art is None else artefact_arrays(art, _LIN_SHAPES)
    if art is None or arrays is None:  # `applies` selected this entry; else a registry bug
        raise ReportError("seed 000 comparison: no linearize artefact at y0 = (0.40, 0.20, 0.30) m")
    F, B, u0 = arrays["F"], arrays["B"], arrays["u_op"]
    params = {k: inputs.parameters()[k] for k in paper.TABLE_I}
    Fp, Bp = paper.printed_F(params, paper.Y0)
    Fp[np.abs(Fp) < 1e-12 * np.max(np.abs(Fp))] = 0.0   # -t32 + t13 cancels exactly at y0
    name = escape_latex(art["name"])
    scale = float(np.max(np.abs(F)))
    errata = paper.F_FORMULA_ERRATA
    rows: list[PaperRow] = []
    symbolic = latex_matrix_entries((art.get("latex") or {}).get("F", ""))
    for i in range(3):
        for j in range(3):
            p, o = float(Fp[i, j]), float(F[i, j])
            same = abs(p - o) <= 1e-9 * scale
            entry = (i + 1, j + 1)
            note = ""
            if same and entry in errata:
                note = (r"equal at $y_0$ only: in the formula, " + errata[entry]
                        + r"; the two terms coincide here ($\mu_{13}=\mu_{32}$, "
                        r"$y_{01}-y_{03}=y_{03}-y_{02}$, "
                        f"$F_{{13}} = F_{{23}} = {format_number(F[0, 2])}$)")
            elif not same:
                rel = abs(p - o) / scale
                note = (f"differs by ${format_number(p - o, 4)}$ "
                        f"(${format_number(100 * rel, 3)}\\,\\%$ of $\\max|F|$)")
                if entry in errata:
                    note += "; " + errata[entry]
            rows.append(PaperRow(Tex(f"$F_{{{i + 1}{j + 1}}}$ at $y_0$"), cell_number(p),
                                 cell_number(o), AGREES if same else ERRATUM, Tex(note), entry, p, o))
    # formula-level rows for the entries the paper prints as formulas that may be wrong:
    # the verdict compares the printed formula with the Jacobian of the recorded plant model
    formula_gap = _formula_gaps(inputs)
    for entry, why in errata.items():
        i, j = entry
        ours = Tex(r"\emph{see the linearisation section}")
        if symbolic and len(symbolic) == 3 and all(len(r) == 3 for r in symbolic):
            ours = cell_fit(symbolic[i - 1][j - 1])
        gap = formula_gap[i - 1, j - 1]
        wrong = bool(gap > 1e-9)
        note = (why + r" (the printed formula and the Jacobian of the plant model differ by up to "
                f"${format_number(gap, 3)}$ relative on the region)") if wrong else \
            r"equal to the Jacobian of the plant model on the region"
        rows.append(PaperRow(Tex(f"$F_{{{i}{j}}}$ (formula)"),
                             cell_fit(paper.F_PRINTED_LATEX[entry]), ours,
                             ERRATUM if wrong else AGREES, Tex(note), entry))
    ev_p = np.linalg.eigvals(Fp)
    ev_o = np.linalg.eigvals(F)
    ev_same = close(np.sort_complex(ev_p), np.sort_complex(ev_o), 1e-8)
    complex_p = int(np.sum(np.abs(ev_p.imag) > 1e-12 * scale))
    ev_note = "" if ev_same else (
        f"the printed $F$ is not symmetric and has {complex_p} complex eigenvalues (an oscillating "
        r"mode the plant does not have); the Jacobian is symmetric with real eigenvalues")
    rows.append(PaperRow(Tex(r"eigenvalues of $F$ at $y_0$"),
                         Tex("$" + format_eigenvalues([[v.real, v.imag] for v in np.sort_complex(ev_p)], 4) + "$"),
                         Tex("$" + format_eigenvalues([[v.real, v.imag] for v in np.sort_complex(ev_o)], 4) + "$"),
                         AGREES if ev_same else ERRATUM, Tex(ev_note)))
    b_same = close(Bp, B)
    rows.append(PaperRow(Tex("$B$"), cell_matrix(Bp), cell_matrix(B), AGREES if b_same else ERRATUM,
                         Tex("" if b_same else "entries differ")))
    rows.extend(_u0_rows(art, B, u0, name))
    return tuple(rows)


def _formula_gaps(inputs: ReportInputs, points: int = 12) -> np.ndarray:
    """Largest relative gap, per entry, between eq. (8) as printed (formulas in the state) and the
    Jacobian of the smooth model of the recorded plant, at region points with y1 > y3 > y2 > 0."""
    plant = builtin_plant(inputs.plant_name)
    x = plant.x
    h1, h2, h3 = x
    p = plant.p
    phi = sp.sqrt(2 * p["g"])
    t13 = p["mu13"] * p["Phi"] * phi / (2 * p["A"] * sp.sqrt(h1 - h3))
    t32 = p["mu32"] * p["Phi"] * phi / (2 * p["A"] * sp.sqrt(h3 - h2))
    t20 = p["mu20"] * p["Phi"] * phi / (2 * p["A"] * sp.sqrt(h2))
    printed = sp.Matrix(paper.F_in_fractions(t13, t32, t20))
    jac = plant.f_smooth.jacobian(sp.Matrix(x))
    values = {p[k]: v for k, v in inputs.parameters().items() if k in p}
    f_gap = sp.lambdify(x, (printed - jac).xreplace(values), "numpy")
    f_ref = sp.lambdify(x, jac.xreplace(values), "numpy")
    rng = np.random.default_rng(0)
    gaps = np.zeros((3, 3))
    for _ in range(points):
        y2 = rng.uniform(0.05, 0.2)
        y3 = y2 + rng.uniform(0.05, 0.2)
        y1 = y3 + rng.uniform(0.05, 0.2)
        gap = np.abs(np.asarray(f_gap(y1, y2, y3), dtype=float))
        scale = float(np.max(np.abs(np.asarray(f_ref(y1, y2, y3), dtype=float))))
        gaps = np.maximum(gaps, gap / scale)
    return gaps


def _u0_rows(art, B: np.ndarray, u0: np.ndarray, name: str) -> list[PaperRow]:
    """The printed u0 (Sec. IV) against the exact equilibrium input of the artefact."""
    up = np.array([float(t) for t in paper.U0_TEXT])
    residual = equilibrium_of(art.get("diagnostics") or {}).residual
    base_res = np.asarray(residual if residual is not None else np.zeros(3), dtype=float)
    # the model is affine in u with constant B: f(x0, u) = f(x0, u0) + B (u - u0)
    res_printed = base_res + B @ (up - u0)
    rows = []
    for k, text in enumerate(paper.U0_TEXT):
        tol = printed_precision(text)
        diff = up[k] - u0[k]
        same = abs(diff) <= tol
        if same:
            note = r"equal to the printed digits"
        else:
            tanks = [f"$\\dot h_{{{i + 1}}} = {format_number(res_printed[i], 3)}$"
                     for i in range(3) if abs(res_printed[i]) > 1e-12]
            note = (f"the printed input does not balance the model at $y_0$: off by "
                    f"${format_number(diff, 3)}$~m$^3$/s "
                    f"(${format_number(100 * diff / u0[k], 3)}\\,\\%$); with the printed $u_0$, "
                    + ", ".join(tanks) + " m/s")
        mant, _, exp = text.partition("e")
        printed_tex = Tex(f"${mant} \\times 10^{{{int(exp)}}}$")     # as printed
        rows.append(PaperRow(Tex(f"$u_{{0,{k + 1}}}$ (m$^3$/s)"), printed_tex, cell_number(u0[k]),
                             AGREES if same else ERRATUM, Tex(note), (k + 1,), float(up[k]),
                             float(u0[k])))
    worst = float(np.max(np.abs(res_printed)))
    rows.append(PaperRow(Tex(r"equilibrium residual $\max|f(y_0,u_0)|$ (m/s)"),
                         cell_number(worst), cell_number(float(np.max(np.abs(base_res)))),
                         AGREES if worst <= 1e-9 else ERRATUM,
                         Tex(f"ours from artefact \\texttt{{{name}}}; the printed $u_0$ is not an "
                             r"equilibrium input" if worst > 1e-9 else "")))
    return rows


def _law_artefact(inputs: ReportInputs):
    for a in inputs.by_method("feedback_linearization"):
        outputs = controlled_outputs_of(a.get("diagnostics") or {})
        if outputs is not None and outputs != ("h1", "h2"):
            continue
        if artefact_arrays(a, _LAW_SHAPES) is not None:
            return a
    return None


def law_applies(inputs: ReportInputs) -> bool:
    """Three-tank plant with Table I and a decoupling law of (h1, h2).

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    return (inputs.plant_name == "three_tank" and params_match(inputs, paper.TABLE_I)
            and _law_artefact(inputs) is not None)


def law_rows(inputs: ReportInputs) -> tuple[PaperRow, ...]:
    """The printed Lambda, Lambda0, beta and alpha of Sec. IV at the artefact's x_op.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    art = _law_artefact(inputs)
    arrays = None if art is None else artefact_arrays(art, _LAW_SHAPES)
    if art is None or arrays is None:  # `applies` selected this entry
        raise ReportError("seed 000 comparison: no feedback_linearization artefact of (h1, h2)")
    x0, lam, lam0 = arrays["x_op"], arrays["Lambda_op"], arrays["Lambda0_op"]
    params = {k: inputs.parameters()[k] for k in paper.TABLE_I}
    try:
        printed = paper.printed_law(params, x0.tolist())
        beta = np.linalg.inv(lam)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise ReportError(f"seed 000 comparison: cannot evaluate the law at x_op = {x0.tolist()} "
                          f"({exc})") from None
    ours = {"Lambda": lam, "Lambda0": lam0, "beta": beta, "alpha": -beta @ lam0}
    sym = {k: v for k, v in (art.get("latex") or {}).items() if isinstance(v, str)}
    labels = {"Lambda": r"$\Lambda$", "Lambda0": r"$\Lambda_0$", "beta": r"$\beta$",
              "alpha": r"$\alpha$"}
    at = "at $x_0 = (" + ", ".join(format_number(v, 4) for v in x0) + ")$"
    rows: list[PaperRow] = []
    for key in ("Lambda", "Lambda0", "beta", "alpha"):
        p, o = np.asarray(printed[key]), np.asarray(ours[key])
        same = close(p, o, 1e-9)
        rows.append(PaperRow(Tex(labels[key] + " " + at), cell_matrix(p, 5), cell_matrix(o, 5),
                             AGREES if same else ERRATUM,
                             Tex("" if same else escape_latex(paper.LAW_NOTE))))
    same = close(printed["alpha"], ours["alpha"], 1e-9)
    rows.append(PaperRow(Tex(labels["alpha"] + " (formula)"), cell_fit(paper.LAW_PRINTED_LATEX["alpha"]),
                         cell_fit(sym["alpha"]) if sym.get("alpha") else
                         Tex(r"$-\Lambda^{-1}\Lambda_0$"),
                         AGREES if same else ERRATUM,
                         Tex("" if same else r"derived: $\alpha = -\Lambda^{-1}\Lambda_0$, an input "
                             r"in m$^3$/s; the printed $\alpha$ is $\Lambda_0$ (m/s)")))
    return tuple(rows)


# ===================================================================== AKF (Sec. III-IV)
def _akf_artefact(inputs: ReportInputs):
    for a in inputs.by_method("adaptive_kalman"):
        if artefact_arrays(a, _AKF_SHAPES) is not None:
            return a
    return None


def akf_applies(inputs: ReportInputs) -> bool:
    """Three-tank plant with Table I and an ``adaptive_kalman`` artefact of three states.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    return (inputs.plant_name == "three_tank" and params_match(inputs, paper.TABLE_I)
            and _akf_artefact(inputs) is not None)


def akf_rows(inputs: ReportInputs) -> tuple[PaperRow, ...]:
    """The printed AKF initial conditions, the observability it rests on and the Fig. 8 claim.

    The paper prints no number of the AKF run (Fig. 8 only): its claim, that the
    estimation errors stay small and bounded, is set against the stored
    ``estimator_convergence`` verdict of the artefact.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    art = _akf_artefact(inputs)
    arrays = None if art is None else artefact_arrays(art, _AKF_SHAPES)
    if art is None or arrays is None:  # `applies` selected this entry
        raise ReportError("seed 000 comparison: no adaptive_kalman artefact of three states")
    hmax = inputs.parameters().get("hmax", paper.HMAX)
    x0 = arrays["x_hat0"]
    rows: list[PaperRow] = []
    px0 = np.array(paper.AKF_X0)
    same = close(px0, x0)
    above = [i for i in range(3) if px0[i] > paper.HMAX]
    order = "" if px0[0] > px0[2] > px0[1] else (
        r"; $h_3 < h_2$ reverses the flow order $h_1 > h_3 > h_2$ of the linearisation")
    bad = bool(above) or bool(order)
    note = ("used as printed" if same else "the artefact's initial estimate differs")
    if above:
        note = (", ".join(f"$h_{{{i + 1}}} = {format_number(px0[i], 3)}$" for i in above)
                + f" m lies above the tank height $h^* = {format_number(paper.HMAX, 3)}$ m "
                r"(Table~I)" + order + "; " + note)
    rows.append(PaperRow(Tex(r"initial estimate $\mathbf{x}_0$ (m)"), cell_matrix(px0[None, :], 3),
                         cell_matrix(x0[None, :], 4), ERRATUM if (bad and same) else
                         (AGREES if same else DIFFERS), Tex(note)))
    span = max(hmax, 1e-300)
    for key, label, printed, unit in (("P0", r"$\mathbf{P}_0$", paper.AKF_P0, "m$^2$"),
                                      ("Q0", r"$\mathbf{Q}_0$", paper.AKF_Q0, "m$^2$"),
                                      ("R", r"$\mathbf{R}_0$", paper.AKF_R0, "m$^2$")):
        ours = arrays[key]
        ok = close(ours, printed * np.eye(ours.shape[0]))
        sd = float(np.sqrt(printed))
        note = "" if ok else "the artefact's matrix is not the printed one"
        if key in ("P0", "R") and sd > span:
            note = (f"standard deviation ${format_number(sd, 3)}$ m exceeds the tank height "
                    f"${format_number(hmax, 3)}$ m (used as printed)" + ("; " + note if note else ""))
        rows.append(PaperRow(Tex(f"{label} ({unit})"), Tex(f"${format_number(printed, 3)}\\,I$"),
                             Tex(f"${format_number(float(ours[0, 0]), 3)}\\,I$") if ok
                             else cell_matrix(ours, 3), AGREES if ok else DIFFERS, Tex(note)))
    obs = (art.get("diagnostics") or {}).get("observability_at_operating_point") or {}
    rank, n = obs.get("rank"), obs.get("n")
    full = bool(obs.get("full"))
    rows.append(PaperRow(Tex(r"$(A_d, \mathbf{H})$ observable"),
                         Tex(r"$\operatorname{rank}[\mathbf{H};\,\mathbf{H}A_d;\,\mathbf{H}A_d^2] = 3$ "
                             "required"),
                         Tex(f"rank {rank}/{n}" if rank is not None else "not recorded"),
                         AGREES if full else DIFFERS,
                         Tex("" if full else "the artefact does not record a full-rank observability")))
    conv = verdict_check(art, "estimator_convergence")
    if conv is None:
        rows.append(PaperRow(Tex("Fig.~8: estimation errors small and bounded"),
                             Tex(escape_latex(paper.AKF_CLAIM)), Tex("no stored verdict"), DIFFERS,
                             Tex("run \\texttt{tanksynth verify} to check the claim")))
    else:
        data = conv.get("data") or {}
        e0, tail, tol = data.get("e0"), data.get("tail_max"), data.get("tolerance")
        ok = bool(conv.get("passed"))
        ours_tex = (f"$|e|_\\infty$ from ${format_number(e0, 3)}$ m to ${format_number(tail, 3)}$ m "
                    f"after ${format_number(data.get('horizon_s', float('nan')), 3)}$ s"
                    if e0 is not None and tail is not None else escape_latex(str(conv.get("detail", ""))))
        rows.append(PaperRow(Tex("Fig.~8: estimation errors small and bounded"),
                             Tex(escape_latex(paper.AKF_CLAIM)), Tex(ours_tex),
                             AGREES if ok else DIFFERS,
                             Tex((f"verdict \\texttt{{estimator\\_convergence}} of "
                                  f"\\texttt{{{escape_latex(art.get('name', ''))}}}: tail within "
                                  f"${format_number(tol, 3)}$ m; the verdict starts the plant 5\\,\\% of the region "
                                  "away from the estimate, not at the printed $\\mathbf{x}_0$"
                                  if tol is not None else "")
                                 + ("" if ok else "; not reproduced: the verdict fails"))))
    return tuple(rows)
