"""The simulator: one integrator of the nonlinear plant, batch simulation, scenarios, metrics.

Caches: the compiled numpy models of plants live in `tanksynth.sim.tape`
(``_MODELS``, ``_BY_ID``, in memory only); `clear_cache` empties them. The
plants' native kernels (C, compiled once per plant structure) live on disk
and in memory in `tanksynth.sim.kernel` (its `~tanksynth.sim.kernel.clear_cache`);
`kernel_status` says which route the last simulation could use and why.
"""

from __future__ import annotations

from tanksynth.sim.integrate import (Integrator, SymbolicStep, casadi_step, input_limits,
                                     param_arrays, rk4_matrix, symbolic_rk4)
from tanksynth.sim.kernel import kernel_status
from tanksynth.sim.metrics import Metric, compute_metrics
from tanksynth.sim.scenarios import SCENARIOS, Scenario, ScenarioSetup, run_scenario, scenario
from tanksynth.sim.simulate import (BatchEstimator, ConstantInput, ControlLaw, EstimatorAdapter,
                                    InputSequence, ParameterChange, SimulationResult, StateJump,
                                    run_seeds, simulate, simulate_inputs)
from tanksynth.sim.tape import NumpyModel, cache_info, clear_cache, numpy_model

__all__ = [
    "Integrator", "SymbolicStep", "casadi_step", "input_limits", "param_arrays", "rk4_matrix",
    "symbolic_rk4",
    "Metric", "compute_metrics",
    "SCENARIOS", "Scenario", "ScenarioSetup", "run_scenario", "scenario",
    "BatchEstimator", "ConstantInput", "ControlLaw", "EstimatorAdapter", "InputSequence",
    "ParameterChange", "SimulationResult", "StateJump", "run_seeds", "simulate", "simulate_inputs",
    "NumpyModel", "cache_info", "clear_cache", "numpy_model",
    "kernel_status",
]
