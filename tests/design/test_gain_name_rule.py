"""Issue 30 item 6: one naming rule for gains across the design results, as in the artefacts:
``K`` for a state feedback, ``L`` for an observer; the older ``gain`` is a deprecated alias.

References: python-control's ``place`` and ``lqr``; eigenvalues by numpy against the region's
definition."""

from __future__ import annotations

import control
import numpy as np
import pytest

from tanksynth.analysis.lmi_region import disk, half_plane
from tanksynth.design.placement.canonical import canonical_observer
from tanksynth.design.placement.exact import place_observer, place_state_feedback
from tanksynth.design.placement.regions import lmi_observer, lmi_state_feedback
from tanksynth.design.synthesis.synthesize import synthesize_observer, synthesize_state_feedback
from tanksynth.design.synthesis.lmis import generalized_plant

A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, -2.0, -3.0]])
B = np.array([[0.0], [0.0], [1.0]])
C = np.array([[1.0, 0.0, 0.0]])
POLES = [-2.0, -3.0, -4.0]


def _rule(res, kind: str, reference=None):
    """K (or L) is the gain; the other name is an AttributeError; gain warns and is the same."""
    own, other = ("K", "L") if kind == "state_feedback" else ("L", "K")
    gain = getattr(res, own)
    with pytest.raises(AttributeError, match=f"has {own}"):
        getattr(res, other)
    with pytest.warns(DeprecationWarning, match="use .K"):
        old = res.gain
    np.testing.assert_array_equal(old, gain)
    if reference is not None:
        np.testing.assert_allclose(gain, reference, rtol=1e-8, atol=1e-10)
    return gain


def test_exact_placement():
    _rule(place_state_feedback(A, B, POLES), "state_feedback", control.place(A, B, POLES))
    L = _rule(place_observer(A, C, POLES), "observer")
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(A - L @ C).real), sorted(POLES), rtol=1e-8)


def test_lmi_placement_state_feedback_was_gain_now_k():
    K = _rule(lmi_state_feedback(A, B, half_plane(1.0)), "state_feedback")
    assert np.all(np.linalg.eigvals(A - B @ K).real < -1.0)
    L = _rule(lmi_observer(A, C, half_plane(1.0)), "observer")
    assert np.all(np.linalg.eigvals(A - L @ C).real < -1.0)
    Ad = np.eye(3) + 0.1 * A
    Kd = _rule(lmi_state_feedback(Ad, 0.1 * B, disk(0.5, 0.4), domain="discrete"), "state_feedback")
    assert np.all(np.abs(np.linalg.eigvals(Ad - 0.1 * B @ Kd) - 0.5) < 0.4)


def test_synthesis_results():
    Q, R = np.eye(3), np.eye(1)
    Cz = np.vstack([np.eye(3), np.zeros((1, 3))])
    Dzu = np.vstack([np.zeros((3, 1)), np.eye(1)])
    sys = control.ss(A, np.hstack([B, B]), Cz, np.hstack([np.zeros((4, 1)), Dzu]))
    res = synthesize_state_feedback(generalized_plant(sys, 1), objective="h2")
    _rule(res, "state_feedback", control.lqr(A, B, Q, R)[0])
    obs = synthesize_observer(A, C, B, np.eye(1), np.eye(3), objective="h2")
    _rule(obs, "observer", control.lqe(A, B, C, np.eye(1), np.eye(1))[0])


def test_canonical_observer_has_l():
    co = canonical_observer(A, C, POLES)
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(A - co.L @ C).real), sorted(POLES), rtol=1e-9)
    with pytest.warns(DeprecationWarning, match="use .L"):
        np.testing.assert_array_equal(co.gain, co.L)
