"""Seed 004 (Wafi): observer gain, fault threshold, detection times; ASKF and consensus filter.

Paper values: Psi_o = (399.625, 168.250, 20.500), Psi = (855, 169.667, 41), Gamma_d, the
threshold (54) = 78/64 e^{-5t} - 765/64 e^{-8t} + 807/64 e^{-10t} and its conservative form
(55); detection times 2.0235, 2.015, 2.0165 s for x0 = (0.26, 0.26, 0.26), (4, 4, 4),
(2.4, 3.6, 1.8). The fault size delta_bar is not printed: delta_bar = 1 is declared here and the
derived detection times are pinned beside the paper's.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from tanksynth.runtime.estimators import (AdaptiveScalingKalmanFilter, AdaptiveScalingTuning,
                                         ConsensusFilter, ConsensusTuning, LuenbergerObserver,
                                         LuenbergerTuning, discrete_model)
from tanksynth.design.fault.threshold import detection_time, fault_threshold, fit_fault_size
from tanksynth.papers.seed004 import DETECTION_TIMES as SEED004_DETECTION_TIMES
from tanksynth.papers.seed004 import INITIAL_STATES as SEED004_INITIAL_STATES
from tanksynth.papers.seed004 import INPUT as SEED004_INPUT
from tanksynth.plants import hydraulic_fault

DELTA_BAR = 1.0
#: Derived with delta_bar = 1, threshold (55), fault at t_f = 2 s (seconds); exact propagation
#: (matrix exponentials). The simulator's RK4 (0.1 ms steps) gives them within 4e-13 s.
DERIVED_T_DETECT = (2.0169779247665742, 2.01522566408112, 2.012684041049772)


@pytest.fixture(scope="module")
def th():
    return fault_threshold(hydraulic_fault())


def test_gain_and_error_dynamics_match_print(th):
    from tanksynth.design.placement.canonical import canonical_observer

    co = canonical_observer(th.A, th.C, [-5, -8, -10])
    assert list(co.Psi_o) == [sp.Rational(3197, 8), sp.Rational(673, 4), sp.Rational(41, 2)]
    np.testing.assert_allclose(np.array(co.Psi_o, dtype=float).ravel(), [399.625, 168.25, 20.5])
    np.testing.assert_allclose(np.array(th.Psi, dtype=float).ravel(), [855, 169.667, 41], atol=1e-3)
    # Erratum: the printed Gamma_d = [[-0.5, 0, -855], [0.5, -1.5, -169.667], [0, 1.5, -41.5]]
    # is A - Psi [0 0 1]; with the plant's C = [0 0 0.5] the third column is halved. The printed
    # matrix has eigenvalues -4.59 +- 1.50j and -34.3, not the designed -5, -8, -10; the
    # derived one has exactly the designed poles and reproduces the printed threshold (54).
    printed_gamma = np.array([[-0.5, 0.0, -855.000], [0.5, -1.5, -169.667], [0.0, 1.5, -41.500]])
    derived = np.array(th.Gamma_d, dtype=float)
    np.testing.assert_allclose(derived[:, :2], printed_gamma[:, :2])
    np.testing.assert_allclose(derived[:, 2], [-427.5, -84.833333, -21.0], atol=1e-6)
    assert th.Gamma_d[1, 2] == -sp.Rational(509, 6)
    assert sorted(th.Gamma_d.eigenvals()) == [-10, -8, -5]
    assert not np.allclose(np.sort(np.linalg.eigvals(printed_gamma).real), [-10, -8, -5])


def test_threshold_eq54_and_eq55(th):
    t = th.t
    assert sp.simplify(th.expression - (sp.Rational(78, 64) * sp.exp(-5 * t)
                                        - sp.Rational(765, 64) * sp.exp(-8 * t)
                                        + sp.Rational(807, 64) * sp.exp(-10 * t))) == 0
    assert all(c > 0 for c in th.conservative.as_coefficients_dict().values())


def test_detection_times_beside_the_paper(th):
    results = [detection_time(th, x0, DELTA_BAR, input_schedule=SEED004_INPUT, reference=paper,
                              plant=hydraulic_fault())
               for x0, paper in zip(SEED004_INITIAL_STATES, SEED004_DETECTION_TIMES)]
    for res, derived, paper in zip(results, DERIVED_T_DETECT, SEED004_DETECTION_TIMES):
        assert res.false_alarm is None
        assert res.t_detect == pytest.approx(derived, abs=1e-9)
        assert res.reference == paper
        # detection within ~25 ms of the fault, as in the paper; within 11 ms of each printed time
        assert 2.0 < res.t_detect < 2.025 and abs(res.t_detect - paper) < 0.011
    # the paper's second time is reproduced by delta_bar ~ 1.03; no single delta_bar gives all three
    d2 = fit_fault_size(th, SEED004_INITIAL_STATES[1], SEED004_DETECTION_TIMES[1],
                        bracket=(0.3, 3.0), input_schedule=SEED004_INPUT)
    assert d2 == pytest.approx(1.0298, abs=2e-3)


@pytest.mark.slow
def test_sampled_luenberger_residual_detects_the_fault_too(th):
    """A digital continuous-form observer flags the leak within 1 ms of the exact time.

    The threshold (55) is only 5.5e-5 at t_f = 2 s: the hold of y in a digital observer leaves a
    residual of order ts; at ts = 1 ms it already exceeds the threshold before the fault (false
    alarm), at 0.1 ms it stays below 7 % of it.
    """
    ts = 1e-4
    healthy = discrete_model(hydraulic_fault(), ts)
    faulty = discrete_model(hydraulic_fault().with_parameters({"delta_bar": DELTA_BAR}), ts)
    Psi = np.array(th.Psi, dtype=float)
    obs = LuenbergerObserver(hydraulic_fault(), LuenbergerTuning(L=Psi, x0=[0.25] * 3, ts=ts,
                                                                 form="continuous"))
    x = np.array(SEED004_INITIAL_STATES[2])
    t_detect = None
    worst_before = 0.0
    for k in range(1, 26000):
        tk = k * ts
        u = 2.0 if tk <= 1.0 + 1e-12 else 1.0
        mdl = healthy if tk <= 2.0 + 1e-12 else faulty
        x = mdl.Ad @ x + mdl.Bd[:, 0] * u
        xh = obs.step([0.5 * x[2]], [u])
        eps = 0.5 * (x[2] - xh[2])
        if 1.0 < tk <= 2.0:
            worst_before = max(worst_before, abs(eps) / th.evaluate(tk))
        if tk > 2.0 and abs(eps) > th.evaluate(tk):
            t_detect = tk
            break
    assert worst_before < 0.1
    assert t_detect == pytest.approx(DERIVED_T_DETECT[2], abs=1e-3)


@pytest.mark.parametrize("x0", SEED004_INITIAL_STATES)
def test_adaptive_scaling_and_consensus_track_the_faulty_plant(x0):
    """Section IV: both filters on the unhealthy system (leak from t_f = 2 s), bounded errors."""
    ts, steps = 0.01, 600
    plant = hydraulic_fault()
    healthy = discrete_model(plant, ts)
    faulty = discrete_model(plant.with_parameters({"delta_bar": DELTA_BAR}), ts)
    rng = np.random.default_rng(7)
    x = np.array(x0, dtype=float)
    tun = dict(Q=1e-4 * np.eye(3), R=np.array([[1e-4]]), P0=np.eye(3), x0=[0.25] * 3, ts=ts)
    askf = AdaptiveScalingKalmanFilter(plant, AdaptiveScalingTuning(**tun, a=0.1, b=0.6, c=0.3))
    cf = ConsensusFilter(plant, ConsensusTuning(Q=tun["Q"], R=(tun["R"], tun["R"]), P0=tun["P0"],
                                                x0=tun["x0"], ts=ts))
    err_as, err_cf, phi = [], [], []
    for k in range(1, steps + 1):
        tk = k * ts
        u = 2.0 if tk <= 1.0 + 1e-12 else 1.0
        mdl = healthy if tk <= 2.0 + 1e-12 else faulty
        x = mdl.Ad @ x + mdl.Bd[:, 0] * u
        y = 0.5 * x[2] + rng.normal(0, 1e-2, 2)
        err_as.append(askf.step(y[:1], [u]) - x)
        err_cf.append(cf.step(y, [u]) - x)
        phi.append(askf.phi)
    err_as, err_cf = np.array(err_as), np.array(err_cf)
    assert np.all(np.isfinite(err_as)) and np.all(np.isfinite(err_cf))
    # from initial errors up to 3.75, within 0.5 before the fault (x1 is only weakly observable
    # through y = x3 / 2); the fault, unknown to both models, biases x2 afterwards
    assert np.abs(err_as[150:200]).max() < 0.5 and np.abs(err_cf[150:200]).max() < 0.5
    assert np.abs(err_as).max() < 5.0 and np.abs(err_cf).max() < 5.0
    phi = np.array(phi)
    assert np.all(np.isfinite(phi)) and np.all(phi >= 0)
