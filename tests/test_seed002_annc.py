"""Seed 002, Tables 4-8: the ANNC rows (NARX estimator + inverse dynamics) against the paper.

The NARX is built the way Sec. 3.3 describes (issue 28): trained by Levenberg-Marquardt
(validation early stopping, at most 200 trial steps per restart, 2 restarts) on the EKF's
estimates of the simulated plant under the designed excitation (set-point steps of both
tracked levels in [0.15, 0.50] m, i.e. both threshold modes of the pipes at h0 = 0.30 m, plus
a three-level PRBS of +-20 lph on each pump), structure chosen by closed-loop ISE on held-out
scenarios (`benchmarks/narx_training.py`: 5 hidden neurons, 1 output delay won the 3/5/8 x 1/2
grid). Seeded: the same fit every run.

Every printed ANNC value (`tanksynth.papers.seed002.TABLES`) is compared through the report's
own rows (`tanksynth.reports.paper_seed002.table_rows`, factor 2 either way: rig data against a
reconstruction). Rows outside the band are listed in `EXPECTED_DEVIATIONS` with the reason the
controlled experiment gives (PERFECT: the same loop with the true state fed back, which bounds
what any unbiased estimator reaches with this plant and law); the test fails when a listed row
starts to agree (the list is stale) or an unlisted row stops agreeing.
"""

from __future__ import annotations

import math

import pytest

from tanksynth.comparison import FilterTuning, comparison_estimators, controller_comparison
from tanksynth.papers.seed002 import TABLE_NUMBERS, TABLES
from tanksynth.plants import hybrid_three_tank
from tanksynth.plants.hybrid_three_tank import LPH
from tanksynth.reports import paper_seed002
from tanksynth.reports.latex import escape_latex

X_OP = (0.31918677, 0.3209075, 0.30968861)
GAINS = (0.05, 0.05)
#: The benchmark's tuning with the structure it selected (benchmarks/narx_training.py).
TUNING = FilterTuning(Q=1e-9, R=2.5e-7, P0=1e-2, substeps=2, narx_runs=6, narx_steps=1500,
                      narx_restarts=2, narx_iterations=200, narx_hidden=5, narx_delays=1,
                      narx_excitation="designed", narx_setpoint_range=(0.15, 0.50),
                      narx_prbs_amplitude=20 * LPH, narx_hold=(60, 200))

#: ANNC entries of Tables 4-8 the reconstruction does not reproduce within a factor 2, and why
#: (ratios ours / printed measured with this seed; PERFECT = true state fed back).
EXPECTED_DEVIATIONS: dict[tuple[str, str], str] = {
    ("servo", "tracking_time"): "never within the 2 % band: the NARX's estimate has a bias of "
                                "a few mm (RMSE h1 0.013 m); PERFECT needs 58 s, not 32 s",
    ("servo", "ise_h2"): "2.1 x: h2 estimate biased (the NARX error, not the plant)",
    ("regulatory", "rejection_time"): "never within the band (same estimator bias)",
    ("mismatch", "ise_h2"): "0.43 x: even PERFECT gives 0.29 x; the paper's 0.0592 needs a loop "
                            "3.4 times worse than the true-state one: the rig's transient, "
                            "not reproducible with the reconstructed plant",
    ("mismatch", "tracking_time"): "never within the band (estimator bias)",
    ("uncertainty_plus", "ise_h1"): "0.24 x: the NARX bias happens to offset the model error",
    ("uncertainty_plus", "offset"): "offset of the opposite sign (estimator bias)",
    ("uncertainty_minus", "ise_h1"): "0.44 x: PERFECT gives 0.36 x: the paper's value exceeds "
                                     "what the true-state loop gives in the reconstruction",
    ("uncertainty_minus", "ise_h2"): "2.03 x, at the band's edge",
    ("clogging", "ise_h1"): "the NARX leaves its training distribution (clogged valve 6 is "
                            "never in the data) and diverges; PERFECT gives 0",
    ("clogging", "ise_h2"): "as ise_h1",
}


@pytest.fixture(scope="module")
def results():
    plant = hybrid_three_tank()
    est = comparison_estimators(plant, 1.0, {"PERFECT": None, "EKFC": "ekf", "UKFC": "ukf",
                                             "ANNC": "narx"}, TUNING, X_OP)
    rows = controller_comparison(plant, est, x_op=X_OP, gains=GAINS, ts=1.0, runs=2,
                                 scenarios=list(TABLES))
    return {(r.scenario, r.controller): dict(r.metrics) for r in rows if not r.skipped}


@pytest.mark.slow
def test_annc_rows_against_the_paper(results):
    rows = paper_seed002.table_rows(results)
    checked = 0
    for exp, table in TABLES.items():
        for metric, printed in table["ANNC"].items():
            if metric == "computation_time":
                continue
            ours = results[(exp, "ANNC")][metric]
            within = (math.isfinite(ours) and ours / printed > 0
                      and 0.5 <= ours / printed <= 2.0)
            expected_off = (exp, metric) in EXPECTED_DEVIATIONS
            assert within != expected_off, (exp, metric, printed, ours)
            head = f"Table~{TABLE_NUMBERS[exp]} {escape_latex(exp)} ANNC:"
            label = [r for r in rows if r.quantity.startswith(head) and r.printed_value == printed]
            assert label and all((r.verdict == "agrees") == within for r in label)
            checked += 1
    assert checked == 19
    # 8 of the 19 printed ANNC values (computation times aside) reproduced within a factor 2
    assert 19 - len(EXPECTED_DEVIATIONS) == 8


@pytest.mark.slow
def test_the_papers_ranking_is_not_reproduced(results):
    """Sec. 6: ANNC lowest ISE in every case but servo. In the reconstruction it is lowest in
    some columns (regulatory h1, mismatch h1, +-10 % h1, leakage h1: a biased estimate that
    offsets the model error) but not in all: the claim is not reproduced."""
    rows = {r.quantity: r for r in paper_seed002.table_rows(results)}
    claim = rows["ANNC lowest ISE except servo (Sec.~6)"]
    assert claim.verdict == "differs"
    lowest = sum(results[(e, "ANNC")][m] <= min(results[(e, c)][m] for c in ("EKFC", "UKFC"))
                 for e in TABLES if e != "servo" for m in ("ise_h1", "ise_h2"))
    assert 3 <= lowest < 12


@pytest.mark.slow
def test_perfect_estimator_bounds_the_unreachable_rows(results):
    """The controlled experiment: with the true state fed back, the paper's ANNC value of
    mismatch ISE h2 and -10 % ISE h1 is still more than twice what the loop gives, so no
    estimator without a systematic error reaches them in the reconstructed plant."""
    for exp, metric in (("mismatch", "ise_h2"), ("uncertainty_minus", "ise_h1")):
        perfect = results[(exp, "PERFECT")][metric]
        assert perfect < 0.5 * TABLES[exp]["ANNC"][metric], (exp, metric, perfect)
