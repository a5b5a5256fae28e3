"""Fault-detection threshold (seed 004 eq. 52-55): exact derivation, residuals, detection."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import sympy as sp

from tanksynth.design.fault.threshold import (detection_time, fault_threshold, residual)
from tanksynth.errors import DimensionError, SimulationError, SpecError
from tanksynth.plants import hydraulic_fault, three_tank
from tanksynth.sim.integrate import rk4_matrix

t = sp.Symbol("t", nonnegative=True)
EQ54 = sp.Rational(78, 64) * sp.exp(-5 * t) - sp.Rational(765, 64) * sp.exp(-8 * t) \
    + sp.Rational(807, 64) * sp.exp(-10 * t)
EQ55 = sp.Rational(78, 64) * sp.exp(-5 * t) + sp.Rational(765, 64) * sp.exp(-8 * t) \
    + sp.Rational(807, 64) * sp.exp(-10 * t)
#: A piecewise-constant input: 2 on [0, 1 s), then 1.
INPUT = ((0.0, 2.0), (1.0, 1.0))


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
    eps = residual(th, [4.0, 4.0, 4.0], ts, delta_bar=0.0, input_schedule=INPUT)
    np.testing.assert_allclose(eps, th.evaluate(ts, conservative=False), rtol=1e-9, atol=1e-12)


def test_eq54_changes_sign_and_false_alarms(th):
    """Eq. 54 is negative on part of [0, 2): used as a threshold it alarms at t ~ 0.10 s."""
    ts = np.linspace(0, 2, 401)
    assert np.any(th.evaluate(ts, conservative=False) < 0)
    res = detection_time(th, [4.0, 4.0, 4.0], 1.0, conservative=False, input_schedule=INPUT)
    assert res.false_alarm == pytest.approx(0.101, abs=2e-3)
    res55 = detection_time(th, [4.0, 4.0, 4.0], 1.0, conservative=True, input_schedule=INPUT)
    assert res55.false_alarm is None


def test_detection_needs_a_fault(th):
    with pytest.raises(SpecError, match="delta_bar"):
        detection_time(th, [1, 1, 1], 0.0)


def test_larger_faults_are_detected_sooner(th):
    times = [detection_time(th, [2.4, 3.6, 1.8], d, input_schedule=INPUT).t_detect
             for d in (0.3, 1.0, 3.0)]
    assert times[0] > times[1] > times[2] > 2.0


def test_residual_is_the_simulators_rk4_and_matches_the_matrix_exponential(th):
    """Plant and observer advanced by the integrator's RK4 step (a matrix on a linear system):
    within 1e-11 of the exact propagation, and the step is fourth order."""
    A = np.array(th.A, dtype=float)
    B = np.array(th.B, dtype=float)
    C = np.array(th.C, dtype=float)
    Psi = np.array(th.Psi, dtype=float)
    n = 3
    M = np.zeros((2 * n + 1, 2 * n + 1))
    M[:n, :n], M[n:2 * n, :n], M[n:2 * n, n:2 * n] = A, Psi @ C, A - Psi @ C
    M2 = M.copy()                                          # input 2 on [0, 1 s), then 1
    M[:n, -1] = M[n:2 * n, -1] = B[:, 0] * 1.0
    M2[:n, -1] = M2[n:2 * n, -1] = B[:, 0] * 2.0
    z0 = np.concatenate([[2.4, 3.6, 1.8], [0.25] * 3, [1.0]])
    exact = sla.expm(M * 1.5) @ sla.expm(M2 * 1.0) @ z0
    got = residual(th, [2.4, 3.6, 1.8], [2.5], input_schedule=INPUT)[0]
    assert got == pytest.approx((C @ (exact[:n] - exact[n:2 * n]))[0], rel=1e-9, abs=1e-14)
    errors = [np.abs(rk4_matrix(M, h) - sla.expm(M * h)).max() for h in (1e-3, 5e-4)]
    assert 25 < errors[0] / errors[1] < 40                 # local error O(h^5): ratio 32


def test_detection_carries_a_reference_time_and_checks_the_plant_bounds(th):
    res = detection_time(th, [2.4, 3.6, 1.8], 1.0, input_schedule=INPUT, reference=2.0165,
                         plant=hydraulic_fault())
    assert res.reference == 2.0165
    assert res.as_dict()["difference_to_reference"] == pytest.approx(res.t_detect - 2.0165)
    # a strong negative input drains the tanks below 0: the linear model no longer holds
    with pytest.raises(SimulationError, match="state bounds"):
        detection_time(th, [0.3, 0.3, 0.3], 1.0, input_schedule=((0.0, -5.0),),
                       plant=hydraulic_fault())
    zero = residual(th, [1.0, 1.0, 1.0], [0.5])           # default: no input
    assert zero == pytest.approx(residual(th, [1.0, 1.0, 1.0], [0.5], input_schedule=((0.0, 0.0),)))


@pytest.mark.parametrize("schedule, match", [
    (((0.5, 1.0),), "start at t <= 0"),
    (((0.0, 1.0), (0.0, 2.0)), "increase"),
    (((0.0, [1.0, 2.0]),), "1 finite values"),
    ((("x",),), "pairs"),
])
def test_bad_input_schedules(th, schedule, match):
    with pytest.raises(SpecError, match=match):
        residual(th, [1.0, 1.0, 1.0], [0.5], input_schedule=schedule)


def test_bad_inputs():
    with pytest.raises(SpecError, match="linear plant"):
        fault_threshold(three_tank("h1"))
    with pytest.raises(SpecError, match="distinct real"):
        fault_threshold(hydraulic_fault(), (-5, -5, -10))
    with pytest.raises(SpecError, match="lower < upper"):
        fault_threshold(hydraulic_fault(), bounds=(4, 1))
    with pytest.raises(DimensionError, match="gain"):
        fault_threshold(hydraulic_fault(), gain=[1.0, 2.0])
