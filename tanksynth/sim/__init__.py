"""The simulator: one integrator of the nonlinear plant, batch simulation, scenarios, metrics.

Caches: the compiled numpy models of plants live in `tanksynth.sim.tape`
(``_MODELS``, ``_BY_ID``, in memory only); `clear_cache` empties them. The
plants' native kernels (C, compiled once per plant structure) live on disk
and in memory in `tanksynth.sim.kernel` (its `~tanksynth.sim.kernel.clear_cache`);
`kernel_status` says which route the last simulation could use and why.
"""

from __future__ import annotations

from tanksynth.sim.simulate import simulate  # eager: the name of its own module
from tanksynth._lazy import lazy_exports as _lazy_exports

#: Re-exported name -> its module, imported on first use (PEP 562): importing the package
#: loads none of its modules' dependencies (issue 15).
_EXPORTS = {
    **dict.fromkeys(["Integrator", "SymbolicStep", "casadi_step", "input_limits", "param_arrays",
                     "rk4_matrix", "symbolic_rk4"],
                    "tanksynth.sim.integrate"),
    "kernel_status": "tanksynth.sim.kernel",
    **dict.fromkeys(["Metric", "compute_metrics"], "tanksynth.sim.metrics"),
    **dict.fromkeys(["SCENARIOS", "Scenario", "ScenarioSetup", "run_scenario", "scenario"],
                    "tanksynth.sim.scenarios"),
    **dict.fromkeys(["BatchEstimator", "ConstantInput", "ControlLaw", "EstimatorAdapter",
                     "InputSequence", "ParameterChange", "SimulationResult", "StateJump",
                     "run_seeds", "simulate_inputs"],
                    "tanksynth.sim.simulate"),
    **dict.fromkeys(["NumpyModel", "cache_info", "clear_cache", "numpy_model"],
                    "tanksynth.sim.tape"),
}

__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)

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
