"""Seed 003 beside tanksynth: the N-tank network of DECENTER's decentralised filtering example.

The printed constants come from `tanksynth.papers.seed003`; the rows compare them
with the plant record and the ``decentralized_kalman`` artefacts of a result
directory, and the example's claim behind its figures (finite-horizon gains cost no
more than one-step gains; the centralised filter bounds both) with the artefacts'
expected costs and stored verdicts. The example prints constants and figures, no
table of results.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from tanksynth.errors import ReportError
from tanksynth.papers import seed003 as paper
from tanksynth.reports.comparison import AGREES, DIFFERS, PaperRow, cell_number, verdict_check
from tanksynth.reports.inputs import ReportInputs
from tanksynth.reports.latex import Tex, escape_latex, format_number

__all__ = ["network_applies", "network_rows"]


def _designs(inputs: ReportInputs) -> dict[str, Mapping[str, Any]]:
    out: dict[str, Mapping[str, Any]] = {}
    for a in inputs.by_method("decentralized_kalman"):
        alg = str((a.get("diagnostics") or {}).get("algorithm", ""))
        out.setdefault("one_step" if alg == "one_step" else "finite_horizon", a)
    return out


def network_applies(inputs: ReportInputs) -> bool:
    """Tank network of `tanksynth.papers.seed003.N` tanks with a ``decentralized_kalman`` artefact.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    n = len(inputs.plant.get("plant", {}).get("states") or ())
    return inputs.plant_name == "tank_network" and n == paper.N and bool(_designs(inputs))


def _same(a: Any, b: float) -> bool:
    try:
        return bool(np.allclose(np.asarray(a, dtype=float), b, rtol=1e-12, atol=0.0))
    except (TypeError, ValueError):
        return False


def network_rows(inputs: ReportInputs) -> tuple[PaperRow, ...]:
    """The example's constants, the plant's DECENTER defaults and the cost ordering.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (spec, plant, artefacts).
    """
    designs = _designs(inputs)
    if not designs:
        raise ReportError("seed 003 comparison: no decentralized_kalman artefact")
    first = designs.get("finite_horizon") or designs["one_step"]
    diag = first.get("diagnostics") or {}
    par = inputs.parameters()
    rows: list[PaperRow] = []

    def row(label: str, printed: float, ours: Any, note: str = "") -> None:
        ok = ours is not None and _same(ours, printed)
        shown = (cell_number(float(np.asarray(ours, dtype=float).ravel()[0]))
                 if ours is not None and np.size(ours) else Tex("not recorded"))
        rows.append(PaperRow(Tex(label), cell_number(printed), shown, AGREES if ok else DIFFERS,
                             Tex(note if ok else "differs from the example's constant")))

    n = len(inputs.plant.get("plant", {}).get("states") or ())
    row("tanks $N$", paper.N, n)
    row("sampling period dT (s)", paper.TS, diag.get("ts"))
    row("relinearisation dTlin (steps)", paper.RELINEARIZE_EVERY, diag.get("relinearize_every"))
    row("window FH\\_w (steps)", paper.WINDOW, diag.get("window"))
    if "finite_horizon" in designs:
        fd = designs["finite_horizon"].get("diagnostics") or {}
        row("opts.epsl", paper.TOLERANCE, fd.get("tolerance"))
        row("opts.maxOLIt", paper.MAX_ITERATIONS, fd.get("max_iter"))
    E = np.asarray(diag.get("E") or [], dtype=float)
    eye = E.shape == (paper.N, paper.N) and bool(np.array_equal(E, np.eye(paper.N)))
    rows.append(PaperRow(Tex("gain pattern $E$ (each tank its own level)"), Tex("$I$"),
                         Tex("$I$" if eye else "other"), AGREES if eye else DIFFERS, Tex("")))
    half = paper.N // 2
    for label, key, pair in (("lower tank area $A$ (cm$^2$)", "A", paper.TANK_AREAS),
                             ("lower outlet area $a$ (cm$^2$)", "a", paper.OUTLET_AREAS),
                             ("valve split $\\gamma$", "gamma", paper.VALVE_SPLITS)):
        for parity, p in enumerate(pair):
            vals = [par.get(f"{key}{i}") for i in range(1 + parity, half + 1, 2)]
            ok = all(v is not None and v == p for v in vals)
            rows.append(PaperRow(Tex(label + (" (odd)" if parity == 0 else " (even)")), cell_number(p),
                                 cell_number(vals[0]) if vals and vals[0] is not None else Tex("absent"),
                                 AGREES if ok else DIFFERS,
                                 Tex("every tank of that parity" if ok else "not every tank")))
    upper = [par.get(f"a{i}") for i in range(half + 1, paper.N + 1)]
    ok = all(v == paper.UPPER_OUTLET_AREA for v in upper)
    rows.append(PaperRow(Tex("upper outlet area (cm$^2$)"), cell_number(paper.UPPER_OUTLET_AREA),
                         cell_number(upper[0]) if upper and upper[0] is not None else Tex("absent"),
                         AGREES if ok else DIFFERS, Tex("")))
    for label, key, printed in (("pump gain $k$ (cm$^3$/(V\\,s))", "k1", paper.PUMP_GAIN),
                                ("gravity $g$ (cm/s$^2$)", "g", paper.G),
                                ("sensor gain $k_c$ (V/cm)", "kc", paper.SENSOR_GAIN)):
        row(label, printed, par.get(key))
    if "finite_horizon" in designs and "one_step" in designs:
        fh = designs["finite_horizon"].get("diagnostics") or {}
        os_ = designs["one_step"].get("diagnostics") or {}
        costs = (fh.get("cost"), os_.get("cost"), fh.get("centralized_cost"))
        if all(isinstance(c, (int, float)) for c in costs):
            c_fh, c_os, c_cen = (float(c) for c in costs)   # type: ignore[arg-type]
            ok = c_cen <= c_fh <= c_os
            rows.append(PaperRow(
                Tex(r"expected cost $\sum_k \mathrm{tr}\,P(k|k)$ of the first window (cm$^2$)"),
                Tex("centralised $\\le$ FH $\\le$ OS"),
                Tex(f"${format_number(c_cen, 5)} \\le {format_number(c_fh, 7)} \\le "
                    f"{format_number(c_os, 7)}$" if ok else
                    f"centralised ${format_number(c_cen, 5)}$, FH ${format_number(c_fh, 7)}$, "
                    f"OS ${format_number(c_os, 7)}$"),
                AGREES if ok else DIFFERS,
                Tex(f"FH improves on OS by ${format_number(100 * (1 - c_fh / c_os), 3)}"
                    r"\,\%$; the decentralised gains cost "
                    f"${format_number(100 * (c_fh / c_cen - 1), 3)}\\,\\%$ more than "
                    "the centralised filter")))
    for key, a in designs.items():
        check = verdict_check(a, "filter_vs_open_loop")
        data = (check or {}).get("data") or {}
        if check is None or "rmse_filter" not in data:
            continue
        ok = bool(check.get("passed"))
        rows.append(PaperRow(
            Tex(f"{escape_latex(key.replace('_', ' '))} filter tracks the levels (figures)"),
            Tex("estimates follow tanks 13 and 31"),
            Tex(f"RMSE ${format_number(data['rmse_filter'], 3)}$ cm against open loop "
                f"${format_number(data['rmse_open_loop'], 3)}$ cm"),
            AGREES if ok else DIFFERS,
            Tex(f"verdict \\texttt{{filter\\_vs\\_open\\_loop}} of \\texttt{{{escape_latex(a.get('name', ''))}}}"
                ": one 40-step window")))
    rows.extend(_long_run_rows(inputs))
    return tuple(rows)


def _long_run_rows(inputs: ReportInputs) -> list[PaperRow]:
    """The example's 800-sample simulation, from a ``long_run`` verdict (option ``run_steps``)."""
    for a in inputs.by_method("decentralized_kalman"):
        check = verdict_check(a, "long_run")
        data = (check or {}).get("data") or {}
        rmse = data.get("rmse") or {}
        if check is None or "centralized" not in rmse or "one_step" not in rmse:
            continue
        rows: list[PaperRow] = []
        steps, seed = data.get("steps"), data.get("seed")
        same = steps == paper.DURATION and seed == paper.RANDOM_SEED and \
            data.get("input_switch_s") == paper.T_SWITCH
        rows.append(PaperRow(Tex("simulation: samples, seed, pump switch (s)"),
                             Tex(f"${paper.DURATION}$, ${paper.RANDOM_SEED}$, ${format_number(paper.T_SWITCH, 4)}$"),
                             Tex(f"${steps}$, ${seed}$, ${format_number(float(data.get('input_switch_s', math.nan)), 4)}$"),
                             AGREES if same else DIFFERS, Tex("")))
        c, o = float(rmse["centralized"]), float(rmse["one_step"])
        f = rmse.get("finite_horizon")
        fhw = data.get("fh_windows") or {}
        where = ("filters relinearised at their estimates every "
                 f"{data.get('relinearize_every')} samples (verdict \\texttt{{long\\_run}})")
        if f is None:
            rows.append(PaperRow(Tex(f"{steps}-sample run: RMSE centralised vs one-step (cm)"),
                                 Tex("centralised best (the optimum a decentralised filter approaches)"),
                                 Tex(f"${format_number(c, 4)}$ vs ${format_number(o, 4)}$"),
                                 AGREES if c < o else DIFFERS,
                                 Tex(where + "; no finite-horizon filter in this verdict")))
        else:
            fv = float(f)
            ok = c < fv <= o
            rows.append(PaperRow(Tex(f"{steps}-sample run: RMSE centralised vs finite-horizon vs one-step (cm)"),
                                 Tex("centralised $\\le$ FH $\\le$ OS"),
                                 Tex(f"${format_number(c, 4)}$ vs ${format_number(fv, 5)}$ vs "
                                     f"${format_number(o, 5)}$"),
                                 AGREES if ok else DIFFERS,
                                 Tex(where + f"; FH gains per {data.get('window')}-sample window, "
                                     f"{fhw.get('converged')}/{fhw.get('windows')} windows converged")))
        meas = rmse.get("measurement")
        if meas is not None:
            m = float(meas)
            worst = max(c, o) if f is None else max(c, o, float(f))
            ok = worst < 0.5 * m
            rows.append(PaperRow(Tex(f"{steps}-sample run: estimates track the levels (figures)"),
                                 Tex("estimates follow tanks 13 and 31"),
                                 Tex(f"RMSE ${format_number(worst, 3)}$ cm against the sensors' "
                                     f"${format_number(m, 3)}$ cm"),
                                 AGREES if ok else DIFFERS,
                                 Tex("every filter below half the measurement RMSE" if ok
                                     else "a filter is not below half the measurement RMSE")))
        return rows
    return []
