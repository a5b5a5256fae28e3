"""Shared fixture of the campaign tests: the runner of every method.

The method table's ``campaign`` column (`tanksynth.methods.RUNNERS`), the
mapping the CLI hands to `campaign_tasks`.
"""

from __future__ import annotations

import pytest

from tanksynth.methods import RUNNERS


@pytest.fixture(scope="session")
def runners():
    """Method name -> campaign runner."""
    return dict(RUNNERS)
