"""Verification stage: one verdict per design method, the runner, Dask campaigns."""

from __future__ import annotations

from tanksynth.verify.campaign import (CLOSED_LOOPS, CampaignTable, CampaignTask, campaign_tasks,
                                       run_campaign, seed002_table)
from tanksynth.verify.verdicts import VERDICTS, Verdict, register_verdict, verify_directory

__all__ = [
    "VERDICTS", "Verdict", "register_verdict", "verify_directory",
    "CLOSED_LOOPS", "CampaignTable", "CampaignTask", "campaign_tasks", "run_campaign", "seed002_table",
]
