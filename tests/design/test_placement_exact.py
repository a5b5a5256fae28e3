"""Exact pole placement (python-control) with its accuracy report."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.design.placement_exact import place_observer, place_state_feedback, pole_errors
from tanksynth.errors import DimensionError, SpecError


def random_system(n=4, m=2, seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, n)), rng.standard_normal((n, m))


# ------------------------------------------------------------- exact placement
def test_mimo_place_and_siso_acker():
    A, B = random_system()
    poles = [-1.0, -2.0, -3.0 + 1.0j, -3.0 - 1.0j]
    r = place_state_feedback(A, B, poles)
    assert r.method == "place" and r.max_pole_error < 1e-9 and r.eigenvector_condition >= 1
    r1 = place_state_feedback(A, B[:, :1], poles)
    assert r1.method == "acker" and r1.max_pole_error < 1e-6
    o = place_observer(A, B.T, poles)
    assert o.gain.shape == (4, 2)
    _, emax = pole_errors(poles, np.linalg.eigvals(A - o.gain @ B.T))
    assert emax < 1e-9


def test_placement_input_errors():
    A, B = random_system()
    with pytest.raises(SpecError, match="conjugate"):
        place_state_feedback(A, B, [-1, -2, -3 + 1j, -3 + 2j])
    with pytest.raises(DimensionError):
        place_state_feedback(A, B, [-1, -2])
    with pytest.raises(SpecError, match="cannot place"):
        place_state_feedback(A, B, [-1, -1, -1, -2])         # multiplicity 3 > rank(B) = 2
    with pytest.raises(SpecError):
        place_state_feedback(A, B, [-1, -2, -3, -4], method="varga")
    with pytest.raises(DimensionError):
        place_state_feedback(A, B, [-1, -2, -3, -4], method="acker")
