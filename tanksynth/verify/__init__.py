"""Verification stage: rank conditions, batch simulation, scenarios, metrics, verdicts, campaigns."""

from __future__ import annotations

from .checks import Check, rank_conditions
from .rank import (NonlinearObservability, PBHResult, RankResult, SymbolicRank,
                   controllability_matrix, controllability_rank, nonlinear_observability,
                   observability_matrix, observability_rank, pbh_test, symbolic_observability)
from .simulate import (BatchEstimator, ConstantInput, ControlLaw, EstimatorAdapter, ParameterChange,
                       SimulationError, SimulationResult, StateJump, run_seeds, simulate)
from .scenarios import SCENARIOS, Scenario, ScenarioSetup, run_scenario, scenario
from .metrics import Metric, compute_metrics
from .verdicts import VERDICTS, Verdict, register_verdict, verify_directory
from .campaign import (CLOSED_LOOPS, CampaignTable, CampaignTask, campaign_tasks, run_campaign,
                       seed002_table)

__all__ = [
    "Check", "rank_conditions", "NonlinearObservability", "PBHResult", "RankResult", "SymbolicRank",
    "controllability_matrix", "controllability_rank", "nonlinear_observability",
    "observability_matrix", "observability_rank", "pbh_test", "symbolic_observability",
    "BatchEstimator", "ConstantInput", "ControlLaw", "EstimatorAdapter", "ParameterChange",
    "SimulationError", "SimulationResult", "StateJump", "run_seeds", "simulate",
    "SCENARIOS", "Scenario", "ScenarioSetup", "run_scenario", "scenario", "Metric", "compute_metrics",
    "VERDICTS", "Verdict", "register_verdict", "verify_directory",
    "CLOSED_LOOPS", "CampaignTable", "CampaignTask", "campaign_tasks", "run_campaign", "seed002_table",
]
