"""Seed 002 section 5 in simulation: EKFC/UKFC/ANNC beside the paper's Tables 4-8.

Runs every controller whose estimator module is present, plus the perfect-
estimator baseline; a row is skipped (with its reason) only when its
estimator module is absent. Theirs is a real rig, ours a declared
reconstruction: the checks are on orderings and magnitudes, not digits.
"""

import math

import pytest

from tanksynth.verify.campaign import PAPER_TABLES, SEED002_ESTIMATORS, seed002_estimators, seed002_table
from tanksynth.plants import hybrid_three_tank

PLANT = hybrid_three_tank()
X_OP = [0.31918677, 0.3209075, 0.30968861]


@pytest.fixture(scope="module")
def table():
    estimators = seed002_estimators(PLANT, 1.0, X_OP)
    return estimators, seed002_table(PLANT, runs=2, scenarios=("servo", "mismatch", "leakage"),
                                     estimators=estimators)


def test_rows_run_or_say_why_not(table):
    estimators, rows = table
    assert {r.controller for r in rows} == set(SEED002_ESTIMATORS)
    for r in rows:
        factory, reason = estimators[r.controller]
        if r.skipped:
            assert "absent" in r.skipped, r.skipped     # skipped only for a missing module
        else:
            assert r.ours["ise_h1"] >= 0 and math.isfinite(r.ours["ise_h2"])
            if r.controller != "PERFECT":
                assert r.paper == PAPER_TABLES[r.scenario][r.controller]


def test_magnitudes_against_the_paper(table):
    _, rows = table
    ran = {(r.scenario, r.controller): r for r in rows if not r.skipped}
    servo = ran[("servo", "PERFECT")].ours
    # 0.04 m step: ISE of the same order as Table 4 (0.013-0.017 m^2 s), tracking time tens of s.
    assert 0.003 < servo["ise_h1"] < 0.08 and 10 < servo["tracking_time"] < 150
    # Leakage (no integral action): offset in h1, as the paper reports for model mismatch.
    assert ran[("leakage", "PERFECT")].ours["offset_h1"] < -0.005
    for label in ("EKFC", "UKFC"):
        if ("mismatch", label) in ran:
            # An estimator started 0.28 m off costs more than the perfect baseline.
            assert ran[("mismatch", label)].ours["rmse_h1"] > 0.005
            assert ran[("mismatch", label)].ours["ise_h1"] >= 0.9 * ran[("mismatch", "PERFECT")].ours["ise_h1"]
