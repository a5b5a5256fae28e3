"""The simulator: one batch integrator of the nonlinear plant, scenarios and metrics."""

from __future__ import annotations

from tanksynth.sim.metrics import Metric, compute_metrics
from tanksynth.sim.scenarios import SCENARIOS, Scenario, ScenarioSetup, run_scenario, scenario
from tanksynth.sim.simulate import (BatchEstimator, ConstantInput, ControlLaw, EstimatorAdapter,
                                    ParameterChange, SimulationResult, StateJump, run_seeds,
                                    simulate)

__all__ = [
    "Metric", "compute_metrics",
    "SCENARIOS", "Scenario", "ScenarioSetup", "run_scenario", "scenario",
    "BatchEstimator", "ConstantInput", "ControlLaw", "EstimatorAdapter", "ParameterChange",
    "SimulationResult", "StateJump", "run_seeds", "simulate",
]
