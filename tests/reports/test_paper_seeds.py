"""Paper-vs-tool rows of seed000_akf, seed 002 and seed 003 against the printed values.

Each row is checked against the value printed in the paper (`tanksynth.papers`)
with a tolerance from the paper's rounding, or against an independent evaluation
(pi d^2 / 4, litres per hour); where the tool does not reproduce the paper (the
NARX estimator of seed 002) the test asserts the documented non-reproduction.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tanksynth.cli import main
from tanksynth.papers import seed000 as paper000
from tanksynth.papers import seed002 as paper002
from tanksynth.papers import seed003 as paper003
from tanksynth.reports import compare_with_papers, read_report_inputs
from tanksynth.reports.comparison import printed_precision
from tanksynth.reports.paper import AGREES, DIFFERS, ERRATUM
from tanksynth.reports.paper_seed002 import FACTOR, table2_rows, table_rows

_EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _run(tmp_path_factory, name: str, code: int = 0):
    d = tmp_path_factory.mktemp(name)
    assert main(["run", str(_EXAMPLES / f"{name}.toml"), "-o", str(d), "--no-pdf"]) == code
    return {c.key: c for c in compare_with_papers(read_report_inputs(d))}


def _rows(comp):
    return {r.quantity: r for r in comp.rows}


@pytest.mark.slow
def test_seed000_akf_rows(tmp_path_factory):
    # exit 1: the example's UKF fails its verdict on the printed values (documented in the spec)
    comp = _run(tmp_path_factory, "seed000_akf", code=1)["seed000_akf"]
    rows = _rows(comp)
    x0 = rows[r"initial estimate $\mathbf{x}_0$ (m)"]
    # printed x0 = (0.9, 0.55, 0.5): h1 above the tank height 0.62 m of Table I, h3 < h2
    assert paper000.AKF_X0[0] > paper000.HMAX == 0.62
    assert x0.verdict == ERRATUM and "above the tank height" in x0.note and "0.62" in x0.note
    assert "reverses the flow order" in x0.note
    for label, printed in ((r"$\mathbf{P}_0$ (m$^2$)", paper000.AKF_P0),
                           (r"$\mathbf{Q}_0$ (m$^2$)", paper000.AKF_Q0),
                           (r"$\mathbf{R}_0$ (m$^2$)", paper000.AKF_R0)):
        assert rows[label].verdict == AGREES, label
    # R0 = 5^2 m^2: a 5 m standard deviation, beyond the 0.62 m tank
    assert "standard deviation $5$ m" in rows[r"$\mathbf{R}_0$ (m$^2$)"].note
    assert rows[r"$(A_d, \mathbf{H})$ observable"].verdict == AGREES
    assert rows["Fig.~8: estimation errors small and bounded"].verdict == AGREES


def test_seed002_tables_1_2_against_independent_values():
    from tanksynth.plants import hybrid_three_tank

    plant = hybrid_three_tank()
    par = {p.name: p.value for p in plant.parameters}
    rows = {r.quantity: r for r in table2_rows(par)}
    for k, v in paper002.TABLE_1.items():
        r = rows[f"$k_{{{k[1:]}}}$ (m$^2$), Table~1"]
        assert r.verdict == AGREES and abs(r.ours_value - v) <= printed_precision(f"{v:.4e}")
    assert par["A"] == pytest.approx(math.pi * 0.15 ** 2 / 4, rel=1e-12)
    assert rows["tank inner diameter (m), Table~2"].verdict == AGREES
    assert par["Qmax"] == pytest.approx(240e-3 / 3600, rel=1e-12)
    assert rows["rated pump flow (lph), Table~2"].verdict == AGREES
    assert rows["overflow height (m), Table~2"].verdict == AGREES
    assert rows["tank height (m), Table~2"].verdict == AGREES     # 0.55 m overflow < 0.60 m top
    # discharge coefficients k_i / (pi 0.0125^2 / 4): largest is k3 = 3.7984e-5 -> 0.3095
    pipe = rows["connecting pipe diameter (m), Table~2"]
    assert pipe.verdict == AGREES and "0.31" in pipe.ours
    assert 3.7984e-5 / (math.pi * 0.0125 ** 2 / 4) == pytest.approx(0.30952, abs=5e-5)
    # the 0-5 V input is not modelled: shown as a difference, not hidden
    assert rows["pump input (V), Table~2"].verdict == DIFFERS


def test_seed002_table_rows_reproduced_and_not():
    # the printed tables themselves reproduce every row; scaling ANNC by 8.6 (the servo ISE h1
    # of issue 28: 0.166 vs 0.0172) does not, and the row says so with the ratio
    exact = {(e, c): dict(v) for e, t in paper002.TABLES.items() for c, v in t.items()}
    rows = table_rows(exact)
    printed = [r for r in rows if r.printed_value is not None]
    assert printed and all(r.verdict == AGREES for r in printed)
    assert len(printed) == sum(len([m for m in v if m != "computation_time"])
                               for t in paper002.TABLES.values() for v in t.values())
    worse = {k: ({m: 8.6 * x for m, x in v.items()} if k[1] == "ANNC" else v) for k, v in exact.items()}
    worse[("servo", "ANNC")]["tracking_time"] = math.inf
    rows = {r.quantity: r for r in table_rows(worse)}
    r = rows[r"Table~4 servo ANNC: ISE $h_1$ (m$^2$\,s)"]
    assert r.verdict == DIFFERS and r.ours_value / r.printed_value > FACTOR
    assert "8.6" in r.note and "not reproduced" in r.note
    assert rows["Table~4 servo ANNC: tracking time (s)"].verdict == DIFFERS
    assert "never reached" in rows["Table~4 servo ANNC: tracking time (s)"].note
    assert rows["ANNC lowest ISE except servo (Sec.~6)"].verdict == DIFFERS
    assert rows["best under initial-state mismatch (Table~6)"].verdict == DIFFERS


def test_seed002_timing_order_row():
    exact = {(e, c): dict(v) for e, t in paper002.TABLES.items() for c, v in t.items()}
    for (e, c), m in exact.items():
        m["estimator_time"] = {"EKFC": 1e-5, "ANNC": 2e-5, "UKFC": 4e-5}[c]
    row = [r for r in table_rows(exact) if "generation time" in r.quantity][0]
    assert row.verdict == AGREES and paper002.TIMING_ORDER == ("EKFC", "ANNC", "UKFC")
    for (e, c), m in exact.items():
        m["estimator_time"] = {"EKFC": 1e-5, "ANNC": 5e-5, "UKFC": 4e-5}[c]    # UKF before NARX
    row = [r for r in table_rows(exact) if "generation time" in r.quantity][0]
    assert row.verdict == DIFFERS and "not reproduced" in row.note


@pytest.mark.slow
def test_seed002_estimators_rows(tmp_path_factory):
    rows = _rows(_run(tmp_path_factory, "seed002_estimators")["seed002_estimators"])
    for label, key in (("hidden neurons", "hidden"), ("exogenous inputs", "inputs"),
                       ("output delays", "delays")):
        r = rows[f"NARX {label}, Table~3"]
        assert r.verdict == AGREES and str(paper002.NARX_STRUCTURE[key]) in r.ours
    assert rows[r"UKF $\beta$, Sec.~3.2"].verdict == AGREES
    # documented non-reproduction (issue 28): the NARX estimate is worse than the EKF's
    narx = rows["NARX correction vs EKF: state RMSE (m), Sec.~6"]
    assert narx.verdict == DIFFERS and narx.ours_value > 1.0 and "not reproduced" in narx.note


@pytest.mark.slow
def test_seed002_servo_rows(tmp_path_factory):
    rows = _rows(_run(tmp_path_factory, "seed002_inverse_dynamics")["seed002_control"])
    for ctrl, values in paper002.TABLES["servo"].items():
        r = rows[f"Table~4 {ctrl}: ISE $h_1$ (m$^2$\\,s)"]
        assert r.printed_value == values["ise_h1"]
        # the true-state baseline within the factor-2 band of every printed controller
        assert r.verdict == AGREES and 1 / FACTOR <= r.ours_value / values["ise_h1"] <= FACTOR
    closed = rows["Tables~4--8, EKFC/UKFC/ANNC in closed loop"]
    assert closed.verdict == DIFFERS and "ANNC not reproduced" in closed.note


@pytest.mark.slow
def test_seed003_rows(tmp_path_factory):
    rows = _rows(_run(tmp_path_factory, "seed003_tank_network")["seed003_network"])
    for label, printed in (("tanks $N$", paper003.N), ("window FH\\_w (steps)", paper003.WINDOW),
                           ("relinearisation dTlin (steps)", paper003.RELINEARIZE_EVERY),
                           ("opts.epsl", paper003.TOLERANCE), ("opts.maxOLIt", paper003.MAX_ITERATIONS),
                           ("pump gain $k$ (cm$^3$/(V\\,s))", paper003.PUMP_GAIN),
                           ("sensor gain $k_c$ (V/cm)", paper003.SENSOR_GAIN)):
        assert rows[label].verdict == AGREES, label
    for label in ("lower tank area $A$ (cm$^2$) (odd)", "lower tank area $A$ (cm$^2$) (even)",
                  "valve split $\\gamma$ (odd)", "upper outlet area (cm$^2$)"):
        assert rows[label].verdict == AGREES, label
    cost = rows[r"expected cost $\sum_k \mathrm{tr}\,P(k|k)$ of the first window (cm$^2$)"]
    assert cost.verdict == AGREES
    # the 800-sample run (verdict long_run): the paper's ordering of the three filters' RMSE
    run = rows[f"{paper003.DURATION}-sample run: RMSE centralised vs finite-horizon vs one-step (cm)"]
    assert run.verdict == AGREES
    assert f"{paper003.DURATION // paper003.WINDOW}/{paper003.DURATION // paper003.WINDOW} windows converged" in str(run.note)


def test_nearest_admissible_by_hand():
    from tanksynth.papers import seed001 as paper001
    from tanksynth.reports.paper_seed001 import ORDER_GAP, nearest_admissible

    # every printed level is above the 0.62 m tank: the projection pushes each level as high as
    # the box and the printed order (h3 > h1 > h2, resp. h2 > h1 > h3) with 0.05 m gaps allow
    assert ORDER_GAP == 0.05
    assert nearest_admissible(paper001.FIG2_X0, 0.0, 0.62) == pytest.approx([0.57, 0.52, 0.62], abs=1e-9)
    assert nearest_admissible(paper001.FIG2_XHAT0, 0.0, 0.62) == pytest.approx([0.57, 0.62, 0.52],
                                                                               abs=1e-9)
    # a point inside the box with its gaps kept is its own projection
    assert nearest_admissible([0.4, 0.2, 0.3], 0.0, 0.62) == pytest.approx([0.4, 0.2, 0.3], abs=1e-9)
    # gap violated (h1 - h3 = 0.02 < 0.05): h1 and h3 move apart symmetrically, h2 untouched
    assert nearest_admissible([0.40, 0.10, 0.38], 0.0, 0.62) == pytest.approx([0.415, 0.10, 0.365],
                                                                              abs=1e-9)


@pytest.mark.slow
def test_seed001_fig2_rows(tmp_path_factory):
    # exit 1: the paper's observer fails its verdicts (documented in the spec and the report)
    rows = _rows(_run(tmp_path_factory, "seed001_ts_observer", code=1)["seed001_fig2"])
    x0 = rows[r"initial state $x_0$ (Fig.~2)"]
    assert x0.verdict == ERRATUM and "3 of 3 levels above" in x0.ours and "0.62" in x0.ours
    assert rows[r"initial estimate $\hat x_0$ (Fig.~2)"].verdict == ERRATUM
    assert rows[r"declared run: $x_0$, $\hat x_0$ (m)"].verdict == AGREES
    # the printed design (lambda, gamma, psi = 0.506) does not converge from there (F(x_op) - L C
    # is unstable: verdict local_error_dynamics), so the paper's claim is not reproduced
    run = rows["Fig.~2: estimation error from the nearest admissible states"]
    assert run.verdict == DIFFERS and "not reproduced" in run.note
