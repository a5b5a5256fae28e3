"""Verification stage: rank conditions (and, later, simulation and metrics)."""
