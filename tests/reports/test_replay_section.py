"""The report's view of a replay (`tanksynth.reports.replay.replay_view`): verdicts, files,
stale entries (an artefact designed again after the replay)."""

from __future__ import annotations

from tanksynth.reports.replay import replay_view

DOC = {"schema": "tanksynth.replay/1", "passed": False,
       "files": [{"name": "log", "samples": 600, "sha256": "ab" * 32}],
       "replays": [{"artefact": "ekf", "method": "ekf", "kind": "estimator", "experiment": "log",
                    "artefact_sha256": "1" * 64, "passed": False,
                    "checks": [{"check": "nis_mean", "passed": False, "detail": "NIS 9 > 2.2"}]},
                   {"artefact": "obs", "method": "luenberger", "kind": "observer", "experiment": "log",
                    "artefact_sha256": "2" * 64, "passed": True,
                    "checks": [{"check": "finite", "passed": True, "detail": "finite"}]}]}


def test_view_lists_checks_and_marks_stale_entries():
    view = replay_view(DOC, {}, {"ekf": "1" * 64, "obs": "3" * 64})
    assert "FAIL" in view["passed"]
    assert view["files"] == [{"name": "log", "samples": 600, "sha256": "ab" * 8}]
    ekf, obs = view["entries"]
    assert (ekf["stale"], obs["stale"]) == (False, True)
    assert "FAIL" in ekf["checks"][0]["verdict"] and "pass" in obs["verdict"]
    assert ekf["figure"] is None


def test_no_replay_no_section():
    assert replay_view(None, {}) is None
