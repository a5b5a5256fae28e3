"""Seed 002 section 5 in simulation: EKFC/UKFC/ANNC beside the paper's Table 4.

The comparison code is generic (`tanksynth.comparison`); the seed's
combinations, our declared tuning and the printed values it is compared
with are held here (until tanksynth.papers holds the printed ones). Every
combination whose estimator module is present runs, plus the perfect-
estimator baseline; a row is skipped (with its reason) only when its
estimator module is absent. Theirs is a real rig, ours a declared
reconstruction: the checks are on orderings and magnitudes, not digits.
"""

import math

import pytest

from tanksynth.plants import hybrid_three_tank
from tanksynth.comparison import FilterTuning, comparison_estimators, controller_comparison

PLANT = hybrid_three_tank()
X_OP = [0.31918677, 0.3209075, 0.30968861]   # examples/hybrid_three_tank.toml, 100/100 lph
#: Seed 002's controllers: EKF, UKF and NARX (ANN) estimators with inverse-dynamics control.
COMBINATIONS = {"PERFECT": None, "EKFC": "ekf", "UKFC": "ukf", "ANNC": "narx"}
#: Estimator tuning (not published: our declared choice).
TUNING = FilterTuning(Q=1e-9, R=2.5e-7, P0=1e-2, substeps=2, narx_runs=3, narx_steps=400,
                      narx_restarts=1, narx_iterations=60)
#: Table 4 of seed 002 (servo, 0.04 m step), ISE of h1 in m^2 s.
TABLE4_ISE_H1 = {"EKFC": 0.0149, "UKFC": 0.0160, "ANNC": 0.0172}


@pytest.fixture(scope="module")
def table():
    estimators = comparison_estimators(PLANT, 1.0, COMBINATIONS, TUNING, X_OP)
    return estimators, controller_comparison(PLANT, estimators, x_op=X_OP, gains=(0.05, 0.05),
                                             ts=1.0, runs=2,
                                             scenarios=("servo", "mismatch", "leakage"))


@pytest.mark.slow
def test_rows_run_or_say_why_not(table):
    estimators, rows = table
    assert {r.controller for r in rows} == set(COMBINATIONS)
    assert len(rows) == 3 * len(COMBINATIONS)
    for r in rows:
        if r.skipped:
            assert "absent" in r.skipped, r.skipped     # skipped only for a missing module
        else:
            assert r.metrics["ise_h1"] >= 0 and math.isfinite(r.metrics["ise_h2"])
            assert ("rmse_h1" in r.metrics) == (r.controller != "PERFECT")  # RMSE only of an estimator
            assert r.metrics["offset"] == pytest.approx(
                (r.metrics["offset_h1"] + r.metrics["offset_h2"]) / 2)


@pytest.mark.slow
def test_magnitudes_against_the_paper(table):
    _, rows = table
    ran = {(r.scenario, r.controller): r.metrics for r in rows if not r.skipped}
    servo = ran[("servo", "PERFECT")]
    # 0.04 m step: ISE of the same order as Table 4 (0.013-0.017 m^2 s), tracking time tens of s.
    lo, hi = min(TABLE4_ISE_H1.values()), max(TABLE4_ISE_H1.values())
    assert 0.2 * lo < servo["ise_h1"] < 5 * hi and 10 < servo["tracking_time"] < 150
    # Leakage (no integral action): offset in h1, as the paper reports for model mismatch.
    assert ran[("leakage", "PERFECT")]["offset_h1"] < -0.005
    for label in ("EKFC", "UKFC"):
        if ("mismatch", label) in ran:
            # An estimator started 0.28 m off costs more than the perfect baseline; after the
            # warm-up (first 10 % of the run) it has converged to within the noise.
            assert 0 < ran[("mismatch", label)]["rmse_h1"] < 0.005
            assert ran[("mismatch", label)]["ise_h1"] >= 0.9 * ran[("mismatch", "PERFECT")]["ise_h1"]


def test_unknown_estimator_kind_is_refused():
    with pytest.raises(ValueError, match="unknown estimator kind 'kf'"):
        comparison_estimators(PLANT, 1.0, {"X": "kf"}, TUNING)
