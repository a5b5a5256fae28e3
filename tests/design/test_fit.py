"""``fit`` on its example (``examples/three_tank_fit.toml``): the rig's logged data, fitted."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tanksynth.methods import METHODS, load_spec

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "three_tank_fit.toml"


@pytest.mark.slow
def test_fit_designs_its_example():
    spec = load_spec(EXAMPLE)
    (entry,) = [d for d in spec.designs if d.method == "fit"]
    result = METHODS["fit"].design(spec, entry)
    assert result.method == "fit" and result.name == "fit"
    diag = result.diagnostics
    assert diag["converged"] is True and diag["names"] == ["mu13", "mu32", "mu20"]
    # the rig's coefficients (examples/data/README.md), biased by its unmodelled leak by a few
    # percent at most
    true = {"mu13": 0.46, "mu32": 0.52, "mu20": 0.70}
    for name, value in true.items():
        assert abs(diag["parameters"][name]["value"] - value) < 0.1 * value, name
    assert np.asarray(result.gains["covariance"]).shape == (3, 3)
    assert set(diag["validation"]["fit_percent"]) == {"h1", "h2", "h3"}
