"""tanksynth.papers.seed003: the script constants of the seed's network example."""

from __future__ import annotations

from tanksynth.papers import seed003 as paper


def test_scenario_constants_are_consistent():
    assert paper.N % 2 == 0 and paper.N == 40
    assert paper.DURATION % paper.WINDOW == 0                 # whole windows
    assert paper.WINDOW % paper.RELINEARIZE_EVERY == 0
    assert 0 < paper.T_SWITCH < paper.DURATION * paper.TS
    assert paper.PUMP_FIRST > paper.PUMP_SECOND > 0
    assert paper.TOLERANCE > 0 and paper.MAX_ITERATIONS > 0 and paper.P0 > 0
    assert len(paper.TANK_AREAS) == len(paper.OUTLET_AREAS) == len(paper.VALVE_SPLITS) == 2
    assert all(0 < g < 1 for g in paper.VALVE_SPLITS)
