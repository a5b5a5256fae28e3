"""The designed NARX excitation (issue 28): set-point equilibria and the PRBS schedule.

References are independent of the compiled model: the equilibrium of the hybrid three-tank
is derived by hand from the seed 002 reconstruction (eq. 1-12 with k5 = k7 = 0, hz = 0):
tank 3 balances ``Q1 + Q2 + Q3 + Q4 = Q6`` (solved for h3 by brentq), then
``Q1in = Q1 + Q3``, ``Q2in = Q2 + Q4``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from tanksynth.errors import SpecError
from tanksynth.plants import hybrid_three_tank
from tanksynth.sim.excitation import designed_excitation, setpoint_equilibrium

PLANT = hybrid_three_tank()
P = {p.name: p.value for p in PLANT.parameters}
G = 9.81


def _q(k, a, b):
    return k * math.copysign(math.sqrt(2 * G * abs(a - b)), a - b)


def _hand_equilibrium(h1, h2):
    h0 = P["h0"]

    def flows(h3):
        q1, q2 = _q(P["k1"], h1, h3), _q(P["k2"], h2, h3)
        q3 = _q(P["k3"], max(h1, h0), max(h3, h0))
        q4 = _q(P["k4"], max(h2, h0), max(h3, h0))
        return q1, q2, q3, q4, P["k6"] * math.sqrt(2 * G * h3)

    h3 = brentq(lambda h: sum(flows(h)[:4]) - flows(h)[4], 1e-9, max(h1, h2), xtol=1e-15)
    q1, q2, q3, q4, _ = flows(h3)
    return h3, (q1 + q3, q2 + q4)


@pytest.mark.parametrize("levels", [(0.32, 0.33), (0.20, 0.22), (0.36, 0.34)])
def test_setpoint_equilibrium_matches_the_hand_balance(levels):
    x, u = setpoint_equilibrium(PLANT, levels)
    h3, u_ref = _hand_equilibrium(*levels)
    assert x[:2] == pytest.approx(levels, abs=1e-15)
    assert x[2] == pytest.approx(h3, abs=1e-9)
    assert u == pytest.approx(u_ref, rel=1e-6)


def test_unreachable_setpoint_is_refused():
    # h1 above h0 fills tank 3 over h2: pump 2 would have to run backwards
    with pytest.raises(SpecError, match="no equilibrium"):
        setpoint_equilibrium(PLANT, (0.373, 0.244))


def test_designed_schedule_steps_prbs_and_both_modes():
    amp = 20e-3 / 3600
    kw = dict(steps=1500, runs=3, setpoint_range=(0.15, 0.5), hold=(60, 200), prbs_amplitude=amp,
              prbs_hold=(3, 20))
    X0, U = designed_excitation(PLANT, np.random.default_rng(4), **kw)
    X0b, Ub = designed_excitation(PLANT, np.random.default_rng(4), **kw)
    assert np.array_equal(U, Ub) and np.array_equal(X0, X0b)       # seeded
    lim = PLANT.input_limits
    assert U.shape == (1500, 3, 2) and np.all(U >= lim[:, 0]) and np.all(U <= lim[:, 1])
    # every initial state is an equilibrium of set-points in the range
    assert np.all((X0[:, :2] >= 0.15) & (X0[:, :2] <= 0.5))
    # equilibria of levels on both sides of h0 = 0.30 m: the inputs span both threshold modes
    lo = setpoint_equilibrium(PLANT, (0.2, 0.2))[1]
    hi = setpoint_equilibrium(PLANT, (0.4, 0.4))[1]
    assert U[..., 0].min() < lo[0] and U[..., 0].max() > hi[0]
    # between set-point changes the PRBS moves the input by +-amp or +-2 amp (a few changes
    # coincide with a set-point step or the clip at 0 and are neither)
    steps = np.abs(np.diff(U[:, 0, 0]))
    small = steps[(steps > 0) & (steps < 2.5 * amp)]
    prbs = np.isclose(small, amp, rtol=1e-9, atol=0) | np.isclose(small, 2 * amp, rtol=1e-9, atol=0)
    assert small.size > 20 and prbs.mean() > 0.9


def test_bad_range_is_refused():
    with pytest.raises(SpecError, match="setpoint_range"):
        designed_excitation(PLANT, np.random.default_rng(0), steps=10, runs=1,
                            setpoint_range=(0.5, 0.2))
