"""tanksynth.papers.seed002: Tables 4-8 are complete and labelled."""

from __future__ import annotations

from tanksynth.papers import seed002 as paper


def test_every_experiment_has_every_controller():
    assert tuple(paper.TABLES) == paper.EXPERIMENTS == tuple(paper.TABLE_NUMBERS)
    for name, table in paper.TABLES.items():
        assert set(table) == set(paper.CONTROLLERS), name
        assert 4 <= paper.TABLE_NUMBERS[name] <= 8


def test_metrics_have_units_and_plausible_values():
    for name, table in paper.TABLES.items():
        metrics = {m for row in table.values() for m in row}
        assert metrics <= set(paper.METRIC_UNITS), name
        for row in table.values():
            assert row["ise_h1"] > 0 and row["ise_h2"] > 0
            assert all(isinstance(v, (int, float)) for v in row.values())
    # Table 7: the offset changes sign with the mismatch
    assert all(paper.TABLES["uncertainty_plus"][c]["offset"] > 0 > paper.TABLES["uncertainty_minus"][c]["offset"]
               for c in paper.CONTROLLERS)


def test_estimator_structure():
    assert paper.NARX_STRUCTURE["hidden"] == 5 and paper.NARX_STRUCTURE["delays"] == 2
    assert paper.UKF_PARAMETERS == {"beta": 2.0, "kappa": 0.0}
