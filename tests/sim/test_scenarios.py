"""Scenarios of the seed papers made concrete."""

import numpy as np
import pytest

from tanksynth.errors import SpecError
from tanksynth.plants import hybrid_three_tank, hydraulic_fault, three_tank
from tanksynth.sim.scenarios import (SCENARIOS, CONTROL_BENCHMARK_SCENARIOS, InputSchedule, run_scenario,
                                        scenario, uncertain_parameters)

HYBRID = hybrid_three_tank()
X_OP = [0.31918677, 0.3209075, 0.30968861]


def test_every_scenario_documents_its_source():
    for sc in SCENARIOS.values():
        assert sc.source and sc.description and sc.steps > 0
    assert set(CONTROL_BENCHMARK_SCENARIOS) <= set(SCENARIOS)


def test_servo_and_regulatory():
    servo = scenario("servo").setup(HYBRID, X_OP, tracked=(0, 1))
    assert np.allclose(servo.reference[99], X_OP[:2])
    assert np.allclose(servo.reference[100], np.add(X_OP[:2], 0.04))
    assert servo.setpoint_samples == (100,)
    reg = scenario("regulatory").setup(HYBRID, X_OP, tracked=(0, 1))
    assert [(j.sample, j.delta) for j in reg.jumps] == [(50, (0.03, 0.03, 0.0)), (250, (-0.03, -0.03, 0.0))]
    assert reg.disturbance_samples == (50, 250)


def test_mismatch_uncertainty_and_faults():
    mm = scenario("mismatch").setup(HYBRID, X_OP)
    assert np.allclose(mm.x0, [0.28, 0.28, 0.23]) and np.allclose(mm.x_hat0, [0.0, 0.0, 0.23])
    assert uncertain_parameters(HYBRID) == ("A", "k1", "k2", "k3", "k4", "k5", "k6", "k7")
    plus = scenario("uncertainty_plus").setup(HYBRID, X_OP)
    assert plus.parameters["A"] == pytest.approx(HYBRID.parameter("A").value / 1.1)
    leak = scenario("leakage").setup(HYBRID, X_OP)
    assert leak.changes[0].sample == 100
    assert leak.changes[0].values["k5"] == pytest.approx(0.25 * HYBRID.parameter("k1").value)
    clog = scenario("clogging").setup(HYBRID, X_OP)
    assert clog.changes[0].values["k6"] == pytest.approx(0.5 * HYBRID.parameter("k6").value)
    assert clog.fault_sample == 100 and mm.fault_sample is None
    healthy = clog.without_faults()
    assert healthy.changes == () and healthy.disturbance_samples == () and healthy.fault_sample is None
    assert np.array_equal(healthy.reference, clog.reference) and healthy.steps == clog.steps
    with pytest.raises(SpecError, match="hybrid_three_tank"):
        scenario("leakage").setup(three_tank(), [0.4, 0.2, 0.3])
    with pytest.raises(SpecError, match="unknown scenario"):
        scenario("nope")


def test_dynamic_steps_and_additive_fault():
    dyn = scenario("dynamic_steps").setup(three_tank(), [0.4, 0.2, 0.3], tracked=(0, 1))
    assert np.allclose(dyn.reference[150], [0.45, 0.2]) and np.allclose(dyn.reference[350], [0.45, 0.25])
    assert np.allclose(dyn.reference[-1], [0.4, 0.2])
    plant = hydraulic_fault()
    fault = scenario("additive_fault").setup(plant, [4.0, 4 / 3, 4.0], ts=0.01)
    assert fault.changes[0].sample == 200 and fault.changes[0].values == {"delta_bar": 0.5}
    with pytest.raises(SpecError, match="multiple"):
        scenario("additive_fault").setup(plant, [4.0, 4 / 3, 4.0], ts=0.3)
    sched = InputSchedule((0.0, 1.0), ((2.0,), (1.0,)))
    assert sched(np.zeros((2, 3)), np.zeros((2, 0)), 0.5)[0, 0] == 2.0
    assert sched(np.zeros((2, 3)), np.zeros((2, 0)), 1.0)[0, 0] == 1.0
    # Seed 004: the leak makes x2 drop after t_f = 2 s.
    res = run_scenario(fault, plant, ts=0.01, seeds=[0], substeps=1)
    x2 = res.x[0, :, 1]
    assert x2[400] < x2[200] - 0.1
