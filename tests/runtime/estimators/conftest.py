"""Shared plant fixtures for the estimator tests."""

from __future__ import annotations

import pytest

from tanksynth.plants import hybrid_three_tank, hydraulic_fault, three_tank


@pytest.fixture(scope="session")
def fault_plant():
    """Seed 004's linear plant (exact ZOH model)."""
    return hydraulic_fault()


@pytest.fixture(scope="session")
def hybrid_plant():
    """Seed 002's hybrid three-tank."""
    return hybrid_three_tank()


@pytest.fixture(scope="session")
def tank_plant():
    """Seed 000's three-tank with all levels measured."""
    return three_tank("all")
