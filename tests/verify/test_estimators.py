"""`EstimatorRebuild.build`: ``build(doc, spec) -> (BatchEstimator, x0_hat, description)``."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.cli import main
from tanksynth.methods import METHODS
from tanksynth.verify.estimators import verdicts as estimators
from tanksynth.verify.runner import load_directory

SPEC = """
title = "estimator builders"
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "ckf"
method = "kalman"
Q = 1e-8
R = 1e-6
P0 = 1e-3
x0 = [0.38, 0.21, 0.29]
[[design]]
name = "luenberger"
method = "luenberger"
poles = [0.8, 0.85, 0.9]
"""


@pytest.fixture(scope="module")
def loaded(tmp_path_factory):
    root = tmp_path_factory.mktemp("builders")
    (root / "spec.toml").write_text(SPEC, encoding="utf-8")
    assert main(["design", str(root / "spec.toml"), "-o", str(root / "out")]) == 0
    return load_directory(root / "out", METHODS)


@pytest.mark.parametrize("name", ["ckf", "luenberger"])
def test_builder_returns_the_estimator_and_the_initial_estimate_it_ships(loaded, name):
    spec, docs = loaded
    doc = next(doc for _, doc in docs if doc["name"] == name)
    rebuild = {"kalman": estimators.KALMAN, "luenberger": estimators.LUENBERGER}[doc["method"]]
    est, x0_hat, description = rebuild.build(doc, spec)
    n = spec.plant.n
    assert x0_hat.shape == (n,) and isinstance(description, str) and description
    np.testing.assert_array_equal(x0_hat, np.asarray(doc["gains"]["x_hat0"], dtype=float).reshape(n))
    if name == "ckf":
        np.testing.assert_allclose(x0_hat, [0.38, 0.21, 0.29])
    est.reset(np.tile(x0_hat, (2, 1)))                       # a batch of 2 runs
    y = np.tile(np.asarray(spec.x0, dtype=float)[:spec.plant.q], (2, 1))
    out = est.step(y, np.zeros((2, spec.plant.m)))
    assert out.shape == (2, n) and np.all(np.isfinite(out))
