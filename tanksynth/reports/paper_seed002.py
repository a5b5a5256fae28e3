"""Seed 002 beside tanksynth: Tables 1-3 and 4-8 of the hybrid three-tank paper.

The printed values come from `tanksynth.papers.seed002`. Theirs is a real rig and
ours a simulation of a reconstructed plant (the paper's equations (1)-(12) are
missing from our copy): a table value counts as reproduced when it lies within a
factor of 2 of the printed one (`FACTOR`), and every value outside is shown as
not reproduced with its ratio.

* `estimators_rows`: Tables 1-3 against the plant record and the ``ekf``,
  ``ukf``, ``narx`` artefacts, and the NARX correction against the EKF from the
  stored ``closed_loop_bounded`` verdict;
* `control_rows`: Table 4 against the stored servo verdict of an
  ``inverse_dynamics`` artefact (the true state fed back);
* `table_rows`: Tables 4-8, every controller and metric, from the metrics of a
  controller comparison (``tanksynth.comparison.controller_comparison``, run by
  notebook 03 and the seed 002 tests), plus the paper's rankings and its timing
  order.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from tanksynth.errors import ReportError
from tanksynth.papers import seed002 as paper
from tanksynth.reports.comparison import (AGREES, DIFFERS, PaperRow, cell_number, ratio_note,
                                          verdict_check)
from tanksynth.reports.inputs import ReportInputs
from tanksynth.reports.latex import Tex, escape_latex, format_number

__all__ = ["FACTOR", "FIGURES", "estimators_applies", "estimators_rows", "control_applies", "control_rows",
           "table_rows", "table2_rows"]

#: A rig value counts as reproduced by the simulation within this factor either way (-).
FACTOR = 2.0

_METRIC_TEX = {"ise_h1": r"ISE $h_1$ (m$^2$\,s)", "ise_h2": r"ISE $h_2$ (m$^2$\,s)",
               "tracking_time": "tracking time (s)", "rejection_time": "rejection time (s)",
               "offset": "offset (m)"}


def _hybrid(inputs: ReportInputs) -> bool:
    return inputs.plant_name == "hybrid_three_tank"


# ===================================================================== Tables 1-2
def table2_rows(parameters: Mapping[str, float]) -> tuple[PaperRow, ...]:
    """Tables 1 and 2 against the plant's parameters.

    Parameters
    ----------
    parameters : mapping of str to float
        The hybrid plant's parameters by name (SI units: m, m^2, m^3/s).
    """
    rows: list[PaperRow] = []
    t2 = paper.TABLE_2
    for k, v in paper.TABLE_1.items():
        ours = parameters.get(k)
        same = ours is not None and ours == v
        rows.append(PaperRow(Tex(f"$k_{{{k[1:]}}}$ (m$^2$), Table~1"), cell_number(v),
                             cell_number(ours) if ours is not None else Tex("absent"),
                             AGREES if same else DIFFERS, Tex(""), None, v, ours))
    d = float(t2["tank_diameter"])
    area = parameters.get("A", math.nan)
    same = abs(area - math.pi * d ** 2 / 4) <= 1e-12 * area
    rows.append(PaperRow(Tex("tank inner diameter (m), Table~2"), cell_number(d),
                         Tex(f"$A = {format_number(area, 5)}$ m$^2$"), AGREES if same else DIFFERS,
                         Tex(r"$A = \pi d^2/4$" if same else r"$A \neq \pi d^2/4$")))
    over = float(t2["overflow_height"])
    hmax = parameters.get("hmax", math.nan)
    rows.append(PaperRow(Tex("overflow height (m), Table~2"), cell_number(over),
                         Tex(f"$h_{{\\max}} = {format_number(hmax, 4)}$ m"),
                         AGREES if hmax == over else DIFFERS,
                         Tex("the levels' upper bound of the region")))
    height = float(t2["tank_height"])
    rows.append(PaperRow(Tex("tank height (m), Table~2"), cell_number(height),
                         Tex(f"not a parameter: levels end at the overflow "
                             f"${format_number(hmax, 4)}$ m"),
                         AGREES if hmax < height else DIFFERS,
                         Tex("consistent: the overflow lies below the tank's top" if hmax < height
                             else "the overflow is not below the tank height")))
    rated = float(t2["rated_flow_lph"])
    qmax = parameters.get("Qmax", math.nan)
    rows.append(PaperRow(Tex("rated pump flow (lph), Table~2"), cell_number(rated),
                         Tex(f"$Q_{{\\max}} = {format_number(qmax / paper.LPH, 5)}$ lph"),
                         AGREES if abs(qmax / paper.LPH - rated) <= 1e-9 * rated else DIFFERS,
                         Tex("")))
    pipe = float(t2["pipe_diameter"])
    a_pipe = math.pi * pipe ** 2 / 4
    ks = [parameters[k] for k in paper.TABLE_1 if parameters.get(k, 0.0) > 0]
    cd = [k / a_pipe for k in ks]
    ok = bool(cd) and all(0 < c < 1 for c in cd)
    rows.append(PaperRow(Tex("connecting pipe diameter (m), Table~2"), cell_number(pipe),
                         Tex(f"$k_i/a = {format_number(min(cd), 3)}\\ldots{format_number(max(cd), 3)}$"
                             if cd else "no valve"),
                         AGREES if ok else DIFFERS,
                         Tex(f"pipe section $a = \\pi d^2/4 = {format_number(a_pipe, 4)}$ m$^2$; the "
                             r"Table~1 coefficients $k_i = c_d a$ give discharge coefficients $c_d$ "
                             + ("in $(0, 1)$: consistent" if ok else "outside $(0, 1)$"))))
    lo, hi = paper.PUMP_VOLTAGE
    rows.append(PaperRow(Tex("pump input (V), Table~2"), Tex(f"${format_number(lo, 2)}$--"
                                                             f"${format_number(hi, 2)}$ V"),
                         Tex(f"flow $0$--${format_number(qmax / paper.LPH, 4)}$ lph"),
                         DIFFERS,
                         Tex("the plant's input is the pump flow; the voltage is not modelled (a "
                             "linear map, rated flow at 5 V, is implied)")))
    return tuple(rows)


# ===================================================================== estimators
def estimators_applies(inputs: ReportInputs) -> bool:
    """Hybrid three-tank plant with an ``ekf``, ``ukf`` or ``narx`` artefact.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    return _hybrid(inputs) and any(inputs.by_method(m) for m in ("ekf", "ukf", "narx"))


def estimators_rows(inputs: ReportInputs) -> tuple[PaperRow, ...]:
    """Tables 1-3 and the NARX correction against the EKF (stored verdict).

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    rows = list(table2_rows(inputs.parameters()))
    narx = inputs.by_method("narx")
    if narx:
        art = narx[0]
        st = (art.get("diagnostics") or {}).get("structure") or {}
        for key, ours_key, label in (("hidden", "hidden", "hidden neurons"),
                                     ("inputs", "exogenous_inputs", "exogenous inputs"),
                                     ("delays", "output_delays", "output delays")):
            printed = paper.NARX_STRUCTURE[key]
            ours = st.get(ours_key)
            rows.append(PaperRow(Tex(f"NARX {label}, Table~3"), cell_number(printed),
                                 cell_number(ours) if ours is not None else Tex("not recorded"),
                                 AGREES if ours == printed else DIFFERS, Tex("")))
        act = st.get("hidden_activation")
        rows.append(PaperRow(Tex("NARX hidden activation, Table~3"), Tex("tansig"),
                             Tex(escape_latex(str(act))), AGREES if act == "tanh" else DIFFERS,
                             Tex("tansig is tanh")))
        check = verdict_check(art, "closed_loop_bounded")
        data = (check or {}).get("data") or {}
        rmse, ekf = data.get("rmse"), data.get("ekf_rmse")
        if rmse is not None and ekf is not None:
            ratio = float(rmse) / float(ekf)
            ok = ratio <= 1.0
            rows.append(PaperRow(
                Tex("NARX correction vs EKF: state RMSE (m), Sec.~6"),
                Tex(escape_latex(paper.CLAIMS["narx_correction"])),
                Tex(f"NARX ${format_number(rmse, 3)}$, EKF ${format_number(ekf, 3)}$"),
                AGREES if ok else DIFFERS,
                Tex(f"NARX / EKF $= {format_number(ratio, 3)}$"
                    + ("" if ok else r": not reproduced, the NARX estimate is worse than the EKF's "
                       r"on the same measurements (verdict \texttt{closed\_loop\_bounded})")),
                None, None, ratio))
    ukf = inputs.by_method("ukf")
    if ukf:
        gains = ukf[0].get("gains") or {}
        for key in ("beta", "kappa"):
            g = gains.get(key)
            ours = None if g is None else float(np.asarray(g, dtype=float).ravel()[0])
            printed = paper.UKF_PARAMETERS[key]
            rows.append(PaperRow(Tex(f"UKF $\\{key}$, Sec.~3.2"), cell_number(printed),
                                 cell_number(ours) if ours is not None else Tex("not recorded"),
                                 AGREES if ours == printed else DIFFERS, Tex("")))
    timing = _timing_row(inputs)
    if timing is not None:
        rows.append(timing)
    return tuple(rows)


#: The paper's controller -> the estimator method it uses.
_ESTIMATOR_OF = {"EKFC": "ekf", "ANNC": "narx", "UKFC": "ukf"}


def _timing_row(inputs: ReportInputs) -> PaperRow | None:
    """The paper's timing order (EKF < NARX < UKF) against the measured time per estimator step.

    Each estimator's verdict stores its wall-clock time per sample (``estimator_time_s``) and
    the machine (``machine``) in a check's data; estimators without one are listed as not timed.
    """
    times: dict[str, float] = {}
    machine = ""
    for ctrl, method in _ESTIMATOR_OF.items():
        for art in inputs.by_method(method):
            for c in ((art.get("verification") or {}).get("checks") or ()):
                data = c.get("data") or {}
                if isinstance(data.get("estimator_time_s"), (int, float)) and ctrl not in times:
                    times[ctrl] = float(data["estimator_time_s"])
                    machine = machine or str(data.get("machine", ""))
    if not times:
        return None
    measured = tuple(sorted(times, key=lambda c: times[c]))
    expected = tuple(c for c in paper.TIMING_ORDER if c in times)
    complete = len(times) == len(paper.TIMING_ORDER)
    ok = measured == expected
    missing = [c for c in paper.TIMING_ORDER if c not in times]
    return PaperRow(Tex("estimator time per sample, fastest first (Sec.~5--6)"),
                    Tex(" $<$ ".join(paper.TIMING_ORDER) + " (rig: EKF about 1/4 of the ANN's, "
                        "1/8 of the UKF's)"),
                    Tex(" $<$ ".join(measured) + " (" + ", ".join(
                        f"{c} ${format_number(1e6 * times[c], 3)}\\,\\mu$s" for c in measured) + ")"),
                    AGREES if ok and complete else DIFFERS,
                    Tex(("order reproduced" if ok else "order not reproduced")
                        + (f" among the timed ones; not timed: {', '.join(missing)} (its verdict "
                           "stores no time)" if missing else "")
                        + "; measured by the verdict's convergence run (one run, mean wall-clock time "
                          f"per sample) on {escape_latex(machine) or 'this machine'}; the paper's are "
                          "LabVIEW times of the rig"))


# ===================================================================== control (true state)
def _law(inputs: ReportInputs) -> Mapping[str, Any] | None:
    for a in inputs.by_method("inverse_dynamics"):
        if verdict_check(a, "servo_scenario") is not None:
            return a
    return None


def control_applies(inputs: ReportInputs) -> bool:
    """Hybrid three-tank plant with an ``inverse_dynamics`` artefact whose verdict ran the servo test.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    return _hybrid(inputs) and _law(inputs) is not None


def control_rows(inputs: ReportInputs) -> tuple[PaperRow, ...]:
    """Table 4 (servo, 0.04 m step) against the stored servo verdict of the law.

    The verdict feeds the true state back: it is the best any estimator-based
    controller can do, and the rows compare it with each printed controller. The
    estimator-based rows of Tables 4-8 need the estimators in closed loop
    (`table_rows`, notebook 03); the last row says so and where the ANNC rows stand.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    art = _law(inputs)
    check = None if art is None else verdict_check(art, "servo_scenario")
    if art is None or check is None:
        raise ReportError("seed 002 comparison: no inverse_dynamics artefact with a servo verdict")
    data = check.get("data") or {}
    try:   # ISE per tracked level (one value per run), tracking time per tracked level
        ise = [float(np.mean(np.asarray(v, dtype=float))) for v in data.get("ise") or ()]
        tt = [float(np.max(np.asarray(v, dtype=float))) for v in data.get("tracking_time") or ()]
    except (TypeError, ValueError):
        ise, tt = [], []
    rows: list[PaperRow] = []
    printed = paper.TABLES["servo"]
    ours_by_metric = {"ise_h1": ise[0] if ise else math.nan, "ise_h2": ise[1] if len(ise) > 1 else math.nan,
                      "tracking_time": max(tt) if tt else math.nan}
    for metric, ours in ours_by_metric.items():
        for ctrl, values in printed.items():
            p = values.get(metric)
            if p is None:
                continue
            ok, note = ratio_note(ours, p, FACTOR)
            rows.append(PaperRow(Tex(f"Table~4 {ctrl}: {_METRIC_TEX[metric]}"), cell_number(p),
                                 Tex(cell_number(ours, 4) + " (true state)") if math.isfinite(ours)
                                 else Tex("never reached"), AGREES if ok else DIFFERS,
                                 Tex(note + "; the verdict feeds the true state back (no estimator)"),
                                 None, float(p), ours))
    rows.extend(_figure_rows(art))
    rows.append(PaperRow(Tex("Tables~4--8, EKFC/UKFC/ANNC in closed loop"),
                         Tex("rig values of three estimator-based controllers"),
                         Tex("not run by this spec (no estimator design)"), DIFFERS,
                         Tex(r"run in notebook~03, \texttt{tests/test\_seed002\_table.py} and "
                             r"\texttt{tests/test\_seed002\_annc.py} through "
                             r"\texttt{paper\_seed002.table\_rows}: EKFC and UKFC within the "
                             r"factor-2 band on most rows; ANNC not reproduced as a whole: the "
                             r"NARX built as Sec.~3.3 says (EKF data over both threshold modes, "
                             r"Levenberg--Marquardt, structure by closed-loop ISE) gives 8 of the "
                             r"19 printed ANNC values within a factor~2, not the paper's ranking; "
                             r"with the true state fed back the loop is still more than twice "
                             r"below the printed mismatch ISE~$h_2$ and $-10\,\%$ ISE~$h_1$ "
                             r"(issue~28, \texttt{benchmarks/narx\_training.py}; explained below)"),
                         explanation=Tex(_ANNC_EXPLANATION)))
    return tuple(rows)


#: Why the ANNC rows of Tables 4-8 are not reproduced: the controlled experiment of issue 28
#: (numbers measured by ``benchmarks/narx_training.py``, pinned by ``tests/test_seed002_annc.py``).
_ANNC_EXPLANATION = (
    r"ANNC, controlled experiment. The NARX was built as Sec.~3.3 describes: trained by "
    r"Levenberg--Marquardt with validation early stopping on the EKF's estimates of the simulated "
    r"plant under set-point steps in $[0.15, 0.50]$\,m (both threshold modes of the pipes) and a "
    r"$\pm 20$\,lph PRBS, structure chosen by closed-loop ISE on held-out scenarios (5 neurons, "
    r"1 output delay; the held-out ISE ranges from 0.085 to 2.88\,m$^2$\,s over the 3/5/8 "
    r"$\times$ 1/2 grid). Three loops were run beside it with the same plant, law and noise. "
    r"(i) PERFECT, the true state fed back, bounds what an estimator without systematic error "
    r"reaches: its mismatch ISE~$h_2$ (0.0173) and $-10\,\%$ ISE~$h_1$ (0.0044\,m$^2$\,s) are "
    r"less than half the paper's ANNC values (0.0592, 0.0122): no estimator reproduces them on "
    r"the reconstructed plant. (ii) ANNC beats PERFECT on the $\pm 10\,\%$ and leakage rows "
    r"only through a bias of a few mm that happens to offset the law's model error; the same bias "
    r"keeps the levels out of the tracking band (tracking and rejection times never reached), and "
    r"with valve~6 clogged, a condition absent from the training data, the network diverges "
    r"(ISE~$h_1$ 0.92 against the paper's 0.0082). (iii) The same network trained on the true "
    r"states (ANNC\_TRUE) is worse (RMSE~$h_1$ 0.016--0.019\,m): $h_1$, $h_2$ are not functions "
    r"of the regressors $[\hat x(k|k-1), \gamma(k), \hat x(k-1)]$ alone. Result: 8 of the 19 "
    r"printed ANNC values within a factor~2, and the paper's ranking (ANNC lowest ISE in every "
    r"case but servo) not reproduced.")


#: The paper's response figures and the verdict scenarios that draw them.
FIGURES: dict[str, tuple[str, ...]] = {"Fig.~7": ("uncertainty_plus", "uncertainty_minus"),
                                       "Fig.~8": ("leakage", "clogging")}


def _figure_rows(art: Mapping[str, Any]) -> list[PaperRow]:
    """Fig. 7 (+-10 % mismatch) and Fig. 8 (leak, clogging) against the informative scenario checks.

    Table 7 prints a steady offset for each sign of the mismatch: its sign is compared (the
    true state is fed back here, so only the law's model error is left, not an estimator's
    bias: the magnitude is shown with its ratio). Table 8 prints ISEs only: ISE ``h1`` is
    compared with the factor band.
    """
    rows: list[PaperRow] = []
    for fig, names in FIGURES.items():
        for name in names:
            check = verdict_check(art, f"scenario_{name}")
            data = (check or {}).get("data") or {}
            label = Tex(f"{fig} / Table~{paper.TABLE_NUMBERS[name]}: {escape_latex(name)}, response")
            printed = paper.TABLES[name]
            if check is None or "offset" not in data or "ise" not in data:
                rows.append(PaperRow(label, Tex("response figure"), Tex("not run"), DIFFERS,
                                     Tex("the inverse\\_dynamics verdict has no such scenario")))
                continue
            off, ise = [float(v) for v in data["offset"]], [float(v) for v in data["ise"]]
            fig_note = (f"drawn in the verdict figure of scenario\\_{escape_latex(name)} "
                        "(true state fed back)")
            if all("offset" in v for v in printed.values()):
                ps = [float(v["offset"]) for v in printed.values()]
                same = all(math.copysign(1.0, p) == math.copysign(1.0, off[0]) for p in ps)
                rows.append(PaperRow(
                    Tex(f"{fig} / Table~{paper.TABLE_NUMBERS[name]}: {escape_latex(name)}, "
                        "sign of the steady offset (m)"),
                    Tex(", ".join(f"{c} ${format_number(v['offset'], 3)}$" for c, v in printed.items())),
                    Tex(f"$h_1$ ${format_number(off[0], 3)}$, $h_2$ ${format_number(off[-1], 3)}$"),
                    AGREES if same else DIFFERS,
                    Tex(("same sign" if same else "opposite sign")
                        + f"; magnitude ${format_number(abs(off[0]) / max(abs(p) for p in ps), 2)}$ "
                        "times the largest printed: with the true state fed back only the law's "
                        "model error is left, an estimator's bias is absent; " + fig_note),
                    None, ps[0], off[0]))
            else:
                p_lo = min(float(v["ise_h1"]) for v in printed.values())
                ok, note = ratio_note(ise[0], p_lo, FACTOR)
                rows.append(PaperRow(
                    Tex(f"{fig} / Table~{paper.TABLE_NUMBERS[name]}: {escape_latex(name)}, "
                        + _METRIC_TEX["ise_h1"]),
                    Tex(", ".join(f"{c} ${format_number(v['ise_h1'], 3)}$" for c, v in printed.items())),
                    Tex(f"${format_number(ise[0], 3)}$ (true state)"),
                    AGREES if ok else DIFFERS,
                    Tex(note + " (against the smallest printed); the fault's size is not published "
                        "(the scenario declares it); " + fig_note),
                    None, p_lo, ise[0]))
    return rows


# ===================================================================== Tables 4-8
def table_rows(results: Mapping[tuple[str, str], Mapping[str, float]],
               factor: float = FACTOR) -> tuple[PaperRow, ...]:
    """Every printed entry of Tables 4-8 against a controller comparison, and the paper's claims.

    Parameters
    ----------
    results : mapping
        ``(experiment, controller) -> metrics`` (experiment names of
        `tanksynth.papers.seed002.EXPERIMENTS`, controllers ``EKFC``, ``UKFC``,
        ``ANNC``; metrics ``ise_h1``, ``ise_h2`` in m^2 s, ``tracking_time``,
        ``rejection_time`` in s (inf when never reached), ``offset`` in m,
        ``estimator_time`` in s per sample), as the ``metrics`` of
        ``tanksynth.comparison.ComparisonRow``.
    factor : float, optional
        A value is reproduced within this factor either way (-).

    Returns
    -------
    tuple of PaperRow
        One row per printed value (``printed_value`` and ``ours_value`` set;
        `DIFFERS` with the ratio when not reproduced), then the rankings of Sec. 6
        and the timing order.
    """
    rows: list[PaperRow] = []
    for exp, table in paper.TABLES.items():
        for ctrl, values in table.items():
            ours_m = results.get((exp, ctrl))
            for metric, p in values.items():
                if metric == "computation_time":
                    continue
                label = Tex(f"Table~{paper.TABLE_NUMBERS[exp]} {escape_latex(exp)} {ctrl}: "
                            f"{_METRIC_TEX[metric]}")
                if ours_m is None or metric not in ours_m:
                    rows.append(PaperRow(label, cell_number(p), Tex("not run"), DIFFERS,
                                         Tex("the comparison has no such row"), None, float(p), None))
                    continue
                ours = float(ours_m[metric])
                ok, note = ratio_note(ours, p, factor)
                if metric == "offset" and math.isfinite(ours) and ours * p < 0:
                    note += "; offset of the opposite sign"
                rows.append(PaperRow(label, cell_number(p),
                                     cell_number(ours, 4) if math.isfinite(ours) else Tex("never reached"),
                                     AGREES if ok else DIFFERS, Tex(note), None, float(p), ours))
    rows.extend(_claim_rows(results))
    return tuple(rows)


def _claim_rows(results: Mapping[tuple[str, str], Mapping[str, float]]) -> list[PaperRow]:
    rows: list[PaperRow] = []
    ctrls = ("EKFC", "UKFC", "ANNC")
    exps = [e for e in paper.TABLES if e != "servo"]

    def best(exp: str, metric: str) -> str | None:
        have = {c: results[(exp, c)][metric] for c in ctrls
                if (exp, c) in results and metric in results[(exp, c)]}
        return min(have, key=lambda c: have[c]) if len(have) == len(ctrls) else None

    winners = {(e, m): best(e, m) for e in exps for m in ("ise_h1", "ise_h2")}
    held = [k for k, w in winners.items() if w == "ANNC"]
    known = [k for k, w in winners.items() if w is not None]
    rows.append(PaperRow(Tex("ANNC lowest ISE except servo (Sec.~6)"),
                         Tex(escape_latex(paper.CLAIMS["annc_lowest_ise"])),
                         Tex(f"ANNC lowest in {len(held)} of {len(known)} ISE columns"),
                         AGREES if known and len(held) == len(known) else DIFFERS,
                         Tex("not reproduced" if len(held) < len(known) else "")))
    w = best("mismatch", "ise_h1")
    rows.append(PaperRow(Tex("best under initial-state mismatch (Table~6)"), Tex("ANNC"),
                         Tex(w or "not run"), AGREES if w == "ANNC" else DIFFERS,
                         Tex("" if w == "ANNC" else "not reproduced (lowest ISE $h_1$)")))
    times = {c: float(np.mean([m["estimator_time"] for (e, cc), m in results.items()
                               if cc == c and "estimator_time" in m]))
             for c in ctrls if any(cc == c and "estimator_time" in m for (_, cc), m in results.items())}
    if len(times) == len(ctrls):
        order = tuple(sorted(times, key=lambda c: times[c]))
        ok = order == paper.TIMING_ORDER
        rows.append(PaperRow(Tex("control-signal generation time, fastest first (Sec.~5-6)"),
                             Tex(" $<$ ".join(paper.TIMING_ORDER)),
                             Tex(" $<$ ".join(order) + " (" + ", ".join(
                                 f"{c} ${format_number(1e6 * times[c], 3)}\\,\\mu$s" for c in order)
                                 + " per sample)"),
                             AGREES if ok else DIFFERS,
                             Tex("estimator time per sample measured in this process, mean over "
                                 "the experiments; the paper's are LabVIEW times of the rig "
                                 "(0.03-0.21 s)" + ("" if ok else "; order not reproduced"))))
    return rows
