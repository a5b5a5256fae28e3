"""Linear margins against hand derivations and python-control's own disk margin.

References are closed forms derived on paper for each loop (not the module's output):
a first-order loop k/(s + a), a double integrator under PD control, a discrete
integrator k/(z - 1), and two decoupled channels whose margins must each be the
first-order closed form.
"""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.analysis.linear_margins import (closed_loop_step, input_loop, loop_frequency_response,
                                              loop_margins, output_injection_loop)
from tanksynth.errors import DimensionError


def first_order_reference(k: float, a: float) -> tuple[float, float, float]:
    """k/(s + a): crossover sqrt(k^2 - a^2) rad/s, phase margin 180 - atan(wc/a) deg, delay pm/wc s."""
    wc = np.sqrt(k * k - a * a)
    pm = 180.0 - np.degrees(np.arctan(wc / a))
    return wc, pm, np.radians(pm) / wc


@pytest.mark.parametrize("k, a", [(5.0, 1.0), (40.0, 3.0), (2.0, 0.5)])
def test_first_order_phase_margin_closed_form(k, a):
    wc, pm, dm = first_order_reference(k, a)
    m = loop_margins([[-a]], [[1.0]], [[k]])
    (c,) = m.channels
    assert c.phase_margin_deg == pytest.approx(pm, rel=1e-6)
    assert c.gain_crossover == pytest.approx(wc, rel=1e-6)
    assert c.delay_margin_s == pytest.approx(dm, rel=1e-6)
    assert np.isinf(c.gain_margin)                 # the phase never reaches -180 deg
    # |1 + L(jw)|^2 = ((a + k)^2 + w^2) / (a^2 + w^2) decreases to 1 as w -> inf
    assert m.min_return_difference == pytest.approx(1.0, rel=1e-5)
    assert m.guaranteed_phase_deg == pytest.approx(60.0, rel=1e-4)
    assert m.guaranteed_gain[0] == pytest.approx(0.5, rel=1e-5) and np.isinf(m.guaranteed_gain[1])


def test_double_integrator_with_pd():
    """L = (kd s + kp)/s^2, kp = kd = 1: |L(jwc)| = 1 gives wc^4 = wc^2 + 1, pm = atan(wc) (deg);
    S = s^2/(s^2 + s + 1) peaks at 2/sqrt(3)."""
    m = loop_margins([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], [[1.0, 1.0]])
    wc = np.sqrt((1.0 + np.sqrt(5.0)) / 2.0)
    (c,) = m.channels
    assert c.gain_crossover == pytest.approx(wc, rel=1e-6)
    assert c.phase_margin_deg == pytest.approx(np.degrees(np.arctan(wc)), rel=1e-6)
    assert c.delay_margin_s == pytest.approx(np.arctan(wc) / wc, rel=1e-6)
    assert np.isinf(c.gain_margin)
    assert m.min_return_difference == pytest.approx(np.sqrt(3.0) / 2.0, rel=1e-6)
    fr = loop_frequency_response([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], [[1.0, 1.0]], points=4000)
    assert fr.sensitivity.max() == pytest.approx(2.0 / np.sqrt(3.0), rel=1e-4)


@pytest.mark.parametrize("k, ts", [(0.5, 0.1), (1.2, 2.0)])
def test_discrete_integrator(k, ts):
    """L(z) = k/(z - 1) at z = exp(j theta): |L| = 1 at sin(theta/2) = k/2, pm = pi/2 - theta/2;
    L(-1) = -k/2 so the gain margin is 2/k (the pole 1 - k g leaves the unit disk at g = 2/k)."""
    theta = 2.0 * np.arcsin(k / 2.0)
    pm = np.pi / 2.0 - theta / 2.0
    m = loop_margins([[1.0]], [[1.0]], [[k]], ts=ts)
    (c,) = m.channels
    assert c.gain_crossover == pytest.approx(theta / ts, rel=1e-6)
    assert c.phase_margin_deg == pytest.approx(np.degrees(pm), rel=1e-6)
    assert c.delay_margin_s == pytest.approx(pm / (theta / ts), rel=1e-6)
    assert m.delay_margin_samples[0] == pytest.approx(pm / theta, rel=1e-6)
    assert c.gain_margin == pytest.approx(2.0 / k, rel=1e-9)
    assert c.phase_crossover == pytest.approx(np.pi / ts)
    # 1 + L = (z - 1 + k)/(z - 1): smallest at z = -1, |2 - k| / 2
    assert m.min_return_difference == pytest.approx(abs(2.0 - k) / 2.0, rel=1e-6)


def test_decoupled_channels_are_the_first_order_closed_form():
    a, k = np.array([1.0, 3.0]), np.array([5.0, 40.0])
    m = loop_margins(np.diag(-a), np.eye(2), np.diag(k))
    for c, ai, ki in zip(m.channels, a, k):
        assert c.phase_margin_deg == pytest.approx(first_order_reference(ki, ai)[1], rel=1e-6)


def test_coupled_channels_respect_the_return_difference_bound():
    """|1 + L_i| = 1/|S_ii| >= min sigma(I + L): no channel's phase margin is below the guaranteed one."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 4)) - 3.0 * np.eye(4)
    B = rng.normal(size=(4, 2))
    K = rng.normal(size=(2, 4))
    m = loop_margins(A, B, K)
    assert m.closed_loop_stable
    for c in m.channels:
        if np.isfinite(c.phase_margin_deg):
            assert c.phase_margin_deg >= m.guaranteed_phase_deg - 1e-6


def test_return_difference_matches_python_control_disk_margin():
    import control
    L = control.ss([[-1.0, 0.0], [1.0, -0.2]], [[1.0], [0.0]], [[0.0, 3.0]], [[0.0]])
    omega = np.logspace(-3, 3, 20000)
    dm, _, dpm = control.disk_margins(L, omega, skew=1.0)     # skew 1: alpha = 1/||S||_inf
    m = loop_margins(L.A, L.B, L.C)
    assert m.min_return_difference == pytest.approx(float(dm), rel=1e-4)
    assert m.guaranteed_phase_deg == pytest.approx(float(dpm), rel=1e-3)


def test_loops_and_step():
    A, B, K = np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), np.array([[1.0, 1.0]])
    L = input_loop(A, B, K)
    assert complex(np.squeeze(L(2j))) == pytest.approx((1 + 2j) / (2j) ** 2)
    Lo = output_injection_loop(A, K.T, K)
    assert Lo.ninputs == 1 and Lo.noutputs == 1
    step = closed_loop_step(A - B @ K, B, [[1.0, 0.0]])
    assert step.outputs[0, 0, -1] == pytest.approx(1.0, abs=2e-3)        # 1/(s^2 + s + 1): DC gain 1
    with pytest.raises(DimensionError):
        loop_margins(A, B, np.ones((2, 2)))
