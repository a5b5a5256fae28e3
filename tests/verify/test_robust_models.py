"""Linearisations at many parameter points from one parametric compilation (verify/robust_models.py)."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.errors import SpecError
from tanksynth.methods import load_spec
from tanksynth.sim.integrate import param_arrays
from tanksynth.sim.tape import numpy_model
from tanksynth.verify.robust.models import linear_models

EXAMPLE = "examples/three_tank_robust.toml"


@pytest.fixture(scope="module")
def plant_and_levels():
    spec = load_spec(EXAMPLE)
    return spec.plant, np.asarray(spec.x0, dtype=float)


def _points(plant, names, count=7):
    base = np.array([plant.parameter(nm).value for nm in names])
    rng = np.random.default_rng(5)
    return base * (1.0 + 0.3 * (rng.random((count, len(names))) - 0.5))


def test_matches_a_fresh_compile_per_point(plant_and_levels):
    plant, x0 = plant_and_levels
    names = ("mu13", "mu32", "mu20")
    values = _points(plant, names)
    u0, F, B, C = linear_models(plant, names, values, x0)
    for i, row in enumerate(values):
        pl = plant.with_parameters(dict(zip(names, row)))
        eq = equilibrium_input(pl, x0)
        lin = linearize(pl, x0, eq.u0)
        for got, ref in ((u0[i], eq.u0), (F[i], lin.F), (B[i], lin.B), (C[i], lin.C)):
            np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-15 * max(1.0, np.max(np.abs(ref))))


def test_balances_and_differentiates_the_numpy_model(plant_and_levels):
    """Against the independently generated numpy code: u0 balances f in least squares, F and B by
    central differences."""
    plant, x0 = plant_and_levels
    names = ("mu13", "mu20")
    values = _points(plant, names, 3)
    u0, F, B, _ = linear_models(plant, names, values, x0)
    model = numpy_model(plant)
    for i, row in enumerate(values):
        p = param_arrays(plant, dict(zip(names, row)), 1)
        f = lambda x, u: np.asarray(model.rhs(x[None], u[None], p), dtype=float).reshape(-1)  # noqa: E731
        scale = np.max(np.abs(f(x0, np.zeros(plant.m))))
        r = f(x0, u0[i])       # least-squares balance (3 levels, 2 inputs): r orthogonal to df/du
        assert np.max(np.abs(B[i].T @ r)) <= 1e-10 * np.max(np.abs(B[i])) * scale
        assert np.max(np.abs(r)) < scale
        for j in range(plant.n):
            d = np.zeros(plant.n)
            d[j] = 1e-6 * x0[j]
            col = (f(x0 + d, u0[i]) - f(x0 - d, u0[i])) / (2 * d[j])
            np.testing.assert_allclose(F[i][:, j], col, rtol=1e-5, atol=1e-9)
        for j in range(plant.m):
            d = np.zeros(plant.m)
            d[j] = 1e-6 * max(abs(u0[i][j]), 1e-6)
            col = (f(x0, u0[i] + d) - f(x0, u0[i] - d)) / (2 * d[j])
            np.testing.assert_allclose(B[i][:, j], col, rtol=1e-5, atol=1e-9)


def test_no_parameter_is_the_nominal_linearisation(plant_and_levels):
    plant, x0 = plant_and_levels
    u0, F, B, C = linear_models(plant, (), np.zeros((1, 0)), x0)
    eq = equilibrium_input(plant, x0)
    lin = linearize(plant, x0, eq.u0)
    assert F.shape == (1, plant.n, plant.n)
    np.testing.assert_allclose(F[0], lin.F, rtol=1e-12)
    np.testing.assert_allclose(u0[0], eq.u0, rtol=1e-12)


def test_out_of_range_values_are_refused(plant_and_levels):
    plant, x0 = plant_and_levels
    with pytest.raises(SpecError):
        linear_models(plant, ("mu13",), np.array([[-1.0]]), x0)
