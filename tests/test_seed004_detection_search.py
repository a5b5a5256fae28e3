"""Seed 004 detection times: the closed-form search of scripts/seed004_detection_search.py.

The search's closed form (matrix exponentials of plant + observer error + fault signals) is
checked against two independent references: the simulator's RK4 (`detection_time`, a leak)
and scipy's adaptive integrator with event location (an additive fault). The stored results
(tests/data/seed004_detection_search.json) are tied to the report's statement, and the key
facts of the statement are re-derived.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from tanksynth.design.fault.threshold import detection_time, fault_threshold
from tanksynth.papers import seed004 as paper
from tanksynth.plants import hydraulic_fault
from tanksynth.reports.paper_seed004 import (DETECTION_SEARCH, DETECTION_SEARCH_CLOSEST,
                                             DETECTION_SEARCH_CLOSEST_AT_ONSET)

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "seed004_detection_search.json"


@pytest.fixture(scope="module")
def search():
    spec = importlib.util.spec_from_file_location("seed004_detection_search",
                                                  ROOT / "scripts" / "seed004_detection_search.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def stored():
    return json.loads(DATA.read_text(encoding="utf-8"))


@pytest.mark.parametrize("delta_bar, conservative", [(1.0, True), (0.4, False)])
def test_closed_form_leak_matches_the_simulator(search, delta_bar, conservative):
    """The tool's leak of tank 2: closed form + Brent against the RK4 simulator (0.1 ms)."""
    th = fault_threshold(hydraulic_fault())
    ours = search.times_for("derived", "leak2", delta_bar, 2.0, "y", "55" if conservative else "54",
                            None)
    for x0, t in zip(paper.INITIAL_STATES, ours):
        ref = detection_time(th, x0, delta_bar, conservative=conservative,
                             input_schedule=paper.INPUT, check_false_alarm=False).t_detect
        assert ref is not None and t == pytest.approx(ref, abs=1e-9)


def test_closed_form_additive_fault_matches_solve_ivp(search):
    """A step into tank 3 (size 0.007 from 2 s), printed Gamma_d observer, threshold (55)."""
    theta, k = 0.007, 2.0
    Psi = paper.PSI[:, 0]
    A, B, C = paper.A, paper.B[:, 0], paper.C[0]
    ours = search.times_for("printed_gamma", "step_tank3", theta, 2.0, "y", "55", None)

    def rhs(t, z):
        x, xh = z[:3], z[3:]
        u = 2.0 if t < 1.0 else 1.0
        f = np.array([0.0, 0.0, theta]) if t >= 2.0 else np.zeros(3)
        return np.concatenate([A @ x + B * u + f, A @ xh + B * u + k * Psi * (C @ x - C @ xh)])

    def margin(t, z):
        return abs(C @ (z[:3] - z[3:])) - float(search.threshold("55", np.array(t)))

    margin.terminal, margin.direction = True, 1
    for x0, t in zip(paper.INITIAL_STATES, ours):
        z0 = np.concatenate([x0, np.full(3, 0.25)])
        mid = solve_ivp(rhs, (0.0, 2.0), z0, method="DOP853", rtol=1e-12, atol=1e-14)
        end = solve_ivp(rhs, (2.0, 2.06), mid.y[:, -1], method="DOP853", rtol=1e-12, atol=1e-14,
                        events=margin)
        assert end.t_events[0].size == 1
        assert t == pytest.approx(end.t_events[0][0], abs=1e-8)


def test_initial_error_residuals_behind_the_statement():
    """x0(2) - 1/4 is e_hat: its residual is (54) exactly; x0(1), x0(3) at 0.27 %, 8.9 %."""
    G = paper.A - np.outer(np.array([855.0, 509.0 / 3.0, 41.0]), paper.C[0])
    t = np.array([2.0, 2.015, 2.0235])
    bar54 = sum(c * np.exp(r * t) for c, r in paper.THRESHOLD_TERMS)
    eps = np.array([[paper.C[0] @ expm(G * s) @ (np.array(x0) - 0.25) for s in t]
                    for x0 in paper.INITIAL_STATES])
    np.testing.assert_allclose(eps[1], bar54, rtol=1e-10)
    np.testing.assert_allclose(eps[0] / bar54, 0.01 / 3.75, rtol=1e-10)
    assert np.all(np.abs(eps[2] / bar54 - 0.089) < 0.001)
    assert r"0.27~\%" in DETECTION_SEARCH and r"8.9~\%" in DETECTION_SEARCH


def test_stored_search_supports_the_report(search, stored):
    s = stored["summary"]
    assert s["values_reached"] == 0
    assert f"{s['combinations']} combinations" in DETECTION_SEARCH
    assert s["additive_span_feasible_at_printed_onset"] == []
    at_onset = [r for r in stored["additive_span"] if r["t_f"] == paper.T_FAULT]
    assert len(at_onset) == 3 * 2 * 4 and not any(r["feasible"] for r in at_onset)
    later = {(r["observer"], r["t_f"]) for r in stored["additive_span"] if r["feasible"]}
    assert later and all(obs == "printed_gamma" and t_f in (2.005, 2.01) for obs, t_f in later)
    assert r"only with the printed $\Gamma_d$ and an onset of 2.005 or 2.01 s" in DETECTION_SEARCH
    for best, said in ((s["closest"], DETECTION_SEARCH_CLOSEST),
                       (s["closest_at_printed_onset"], DETECTION_SEARCH_CLOSEST_AT_ONSET)):
        for key in ("fault", "t_f", "threshold", "sampling_s"):
            assert best[key] == said[key]
        assert best["theta"] == pytest.approx(said["theta"], rel=1e-2)
        np.testing.assert_allclose(best["times"], said["times"], atol=1e-9)
        assert all(f"{t:g}" in DETECTION_SEARCH for t in said["times"])
        # the stored times follow from the closed form afresh
        again = search.times_for(best["observer"], best["fault"], best["theta"], best["t_f"],
                                 best["residual"], best["threshold"], best["sampling_s"])
        np.testing.assert_allclose(again, best["times"], atol=1e-9)
        assert search.score(again) > 1.0
    assert r"raised by 1.02~\%" in DETECTION_SEARCH          # link flow 1.5 (1 - theta), theta = -0.0102


def test_additive_span_infeasible_at_the_printed_onset(search):
    """Every bounded additive fault at t_f = 2 s: no first crossings at the printed times."""
    for thr in ("54", "55"):
        assert not search.additive_bounded_feasible("derived", thr, 2.0, None)["feasible"]
    # 1 ms samples cannot print 2.0235 s
    assert "no sample" in search.additive_bounded_feasible("derived", "55", 2.0, 1e-3)["why"]


def test_a_leak_detects_x0_2_after_x0_3(search):
    """The statement's leak claim: continuous crossing of x0(2) after x0(3), every size."""
    for thr in ("54", "55"):
        for d in np.logspace(-3, 3, 13):
            t = search.times_for("derived", "leak2", float(d), 2.0, "y", thr, None, refine=False)
            if np.all(np.isfinite(t[1:])):
                assert t[1] > t[2]
