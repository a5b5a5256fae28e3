"""Shared fixture of the campaign tests: the runner of every method.

This is the mapping the method table hands to `campaign_tasks` (its
``campaign`` column); `test_campaign_runs.test_every_method_has_a_runner`
checks that it covers the table.
"""

from __future__ import annotations

import pytest

from tanksynth.verify import campaign as c

ESTIMATORS = ("kalman", "ekf", "ukf", "adaptive_kalman", "adaptive_scaling_kalman", "consensus_filter",
              "luenberger")

RUNNERS = {
    "linearize": c.linearize_run,
    "pole_placement": c.placement_run,
    "lmi_placement": c.placement_run,
    "canonical_observer": c.canonical_observer_run,
    "ts_observer": c.ts_observer_run,
    "feedback_linearization": c.feedback_linearization_loop,
    "integral_tracking": c.integral_tracking_loop,
    "inverse_dynamics": c.inverse_dynamics_loop,
    "decentralized_kalman": c.decentralized_kalman_run,
    **{m: c.estimator_run for m in ESTIMATORS},
    "narx": c.narx_run,
    "fault_detection": c.fault_detection_run,
}


@pytest.fixture(scope="session")
def runners():
    """Method name -> campaign runner."""
    return dict(RUNNERS)
