"""Fault-detection threshold (seed 004 eq. 52-55): exact derivation, residuals, detection."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import sympy as sp

from tanksynth.design.fault import (detection_time, fault_threshold, residual)
from tanksynth.errors import DimensionError, SpecError
from tanksynth.plants import hydraulic_fault, three_tank

t = sp.Symbol("t", nonnegative=True)
EQ54 = sp.Rational(78, 64) * sp.exp(-5 * t) - sp.Rational(765, 64) * sp.exp(-8 * t) \
    + sp.Rational(807, 64) * sp.exp(-10 * t)
EQ55 = sp.Rational(78, 64) * sp.exp(-5 * t) + sp.Rational(765, 64) * sp.exp(-8 * t) \
    + sp.Rational(807, 64) * sp.exp(-10 * t)


@pytest.fixture(scope="module")
def th():
    return fault_threshold(hydraulic_fault())


def test_threshold_is_eq54_exactly(th):
    assert sp.simplify(th.expression.subs(th.t, t) - EQ54) == 0
    assert sp.simplify(th.conservative.subs(th.t, t) - EQ55) == 0
    assert th.terms == ((sp.Rational(78, 64), -5), (sp.Rational(-765, 64), -8),
                        (sp.Rational(807, 64), -10))
    assert th.Psi == sp.Matrix([855, sp.Rational(509, 3), 41])
    assert th.e_hat == sp.Matrix([sp.Rational(15, 4)] * 3)
    # at t = 0 it is C e_hat = 15/8
    assert th.expression.subs(th.t, 0) == sp.Rational(15, 8)


def test_threshold_from_a_given_gain_matches(th):
    other = fault_threshold(hydraulic_fault(), gain=sp.Matrix([855, sp.Rational(509, 3), 41]))
    assert sp.simplify(other.expression - th.expression) == 0


def test_numeric_threshold_and_matrix_exponential_agree(th):
    A = np.array(th.A, dtype=float)
    C = np.array(th.C, dtype=float)
    Psi = np.array(th.Psi, dtype=float)
    for tk in (0.0, 0.05, 0.3, 1.0, 2.0):
        value = (C @ sla.expm((A - Psi @ C) * tk) @ np.full(3, 3.75))[0]
        assert th.evaluate(tk, conservative=False) == pytest.approx(value, rel=1e-12, abs=1e-14)
    assert np.all(th.evaluate(np.linspace(0, 3, 50)) > 0)


def test_residual_of_the_healthy_worst_case_is_the_threshold(th):
    ts = np.linspace(0, 1.9, 40)
    eps = residual(th, [4.0, 4.0, 4.0], ts, delta_bar=0.0)
    np.testing.assert_allclose(eps, th.evaluate(ts, conservative=False), rtol=1e-9, atol=1e-12)


def test_eq54_changes_sign_and_false_alarms(th):
    """Eq. 54 is negative on part of [0, 2): used as a threshold it alarms at t ~ 0.10 s."""
    ts = np.linspace(0, 2, 401)
    assert np.any(th.evaluate(ts, conservative=False) < 0)
    res = detection_time(th, [4.0, 4.0, 4.0], 1.0, conservative=False)
    assert res.false_alarm == pytest.approx(0.101, abs=2e-3)
    res55 = detection_time(th, [4.0, 4.0, 4.0], 1.0, conservative=True)
    assert res55.false_alarm is None


def test_detection_needs_a_fault(th):
    with pytest.raises(SpecError, match="delta_bar"):
        detection_time(th, [1, 1, 1], 0.0)


def test_larger_faults_are_detected_sooner(th):
    times = [detection_time(th, [2.4, 3.6, 1.8], d).t_detect for d in (0.3, 1.0, 3.0)]
    assert times[0] > times[1] > times[2] > 2.0


def test_bad_inputs():
    with pytest.raises(SpecError, match="linear plant"):
        fault_threshold(three_tank("h1"))
    with pytest.raises(SpecError, match="distinct real"):
        fault_threshold(hydraulic_fault(), (-5, -5, -10))
    with pytest.raises(SpecError, match="lower < upper"):
        fault_threshold(hydraulic_fault(), bounds=(4, 1))
    with pytest.raises(DimensionError, match="gain"):
        fault_threshold(hydraulic_fault(), gain=[1.0, 2.0])
