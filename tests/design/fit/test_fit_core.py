"""The fit core: recovery, scipy reference optimum, coverage, censoring, identifiability, re-simulation.

References: data simulated with `tanksynth.sim` from known parameters with seeded noise; a
scipy ``least_squares`` of the same cost on a numpy RK4 written here; a closed-form censored
optimum; the structural scaling of the three-tank model (only mu/A enter the equations).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
import sympy as sp
from scipy.optimize import least_squares

from tanksynth.design.fit.estimation import fit_parameters
from tanksynth.design.fit.statistics import identifiable_note, whiteness_test
from tanksynth.design.fit.validation import simulate_outputs, validate_experiment
from tanksynth.errors import SpecError
from tanksynth.measurements.experiment import Experiment
from tanksynth.plants import three_tank
from tanksynth.plants.base import Parameter, Plant, Quantity, Region
from tanksynth.sim.simulate import simulate_inputs

TRUE = {"mu13": 0.45, "mu32": 0.55, "mu20": 0.70}
NOISE = 0.002           # m, measurement noise of every level


@dataclass(frozen=True)
class Free:
    """A free parameter as the spec gives it (name, start, box, unit)."""

    name: str
    start: float
    lower: float
    upper: float
    unit: str = "1"


def _inputs(N: int, rng: np.random.Generator) -> np.ndarray:
    """Piecewise-constant pump flows (m^3/s), a new level every 40 s."""
    levels = rng.uniform(0.2e-4, 1.0e-4, size=(N // 40 + 1, 2))
    return np.repeat(levels, 40, axis=0)[:N]


def _experiment(plant: Plant, name: str, N: int, seed: int, values: dict, x0=(0.3, 0.1, 0.2),
                noise: float = NOISE, t: np.ndarray | None = None) -> Experiment:
    rng = np.random.default_rng(seed)
    U = _inputs(N, rng)
    run = simulate_inputs(plant, list(x0), U[:-1], 1.0, substeps=4, parameters=values)
    Y = run.y[0] + noise * rng.standard_normal(run.y[0].shape)
    none = np.zeros(Y.shape, dtype=bool)
    names = tuple(o.name for o in plant.outputs)
    return Experiment(name, f"{name}.csv", np.arange(N, dtype=float) if t is None else t, U, Y,
                      ("q1", "q2"), names, none, none.copy(), ((0.0, 0.62),) * len(names))


def _mu_free() -> list[Free]:
    return [Free("mu13", 0.5, 0.2, 0.9), Free("mu32", 0.5, 0.2, 0.9), Free("mu20", 0.5, 0.2, 0.9)]


@pytest.fixture(scope="module")
def three_tank_fit():
    plant = three_tank()
    exps = [_experiment(plant, "e1", 300, 1, TRUE), _experiment(plant, "e2", 300, 2, TRUE)]
    return plant, exps, fit_parameters(plant, _mu_free(), exps, starts=3, seed=0)


def test_recovers_known_parameters_within_their_standard_errors(three_tank_fit):
    # one trial: within 3.5 standard errors (the 95 % coverage is measured in the slow test)
    _, _, res = three_tank_fit
    assert res.converged and res.identifiable and res.at_bound == ()
    assert res.names == ("mu13", "mu32", "mu20")
    for i, nm in enumerate(res.names):
        assert abs(res.values[i] - TRUE[nm]) <= 3.5 * res.stderr[i], (nm, res.values[i], res.stderr[i])
        assert res.stderr[i] < 0.01 * TRUE[nm]
        assert res.interval_method[i] == "wald"
        half = res.ci95[i, 1] - res.values[i]
        assert half == pytest.approx(res.values[i] - res.ci95[i, 0])
        assert half == pytest.approx(1.96 * res.stderr[i], rel=0.01)
    assert res.starts_tried == 3 and res.starts_agreeing >= 1
    # the noise level the fit reports is the one the data were made with
    for nm in ("h1", "h2", "h3"):
        assert res.sigma[nm] == pytest.approx(NOISE, rel=0.15)
        assert res.whiteness[nm].band == pytest.approx(1.96 / np.sqrt(600))
    assert res.x0.shape == (2, 3)
    np.testing.assert_allclose(res.x0, [[0.3, 0.1, 0.2]] * 2, atol=5 * NOISE)
    assert np.allclose(np.diag(res.correlation), 1.0)
    assert np.allclose(res.covariance, res.covariance.T)


def test_resimulation_with_tanksynth_sim_reproduces_the_fit(three_tank_fit):
    plant, exps, res = three_tank_fit
    for e, x0, Yp in zip(exps, res.x0, res.predicted):
        Ys = simulate_outputs(plant, res.parameters, e, x0, substeps=res.substeps)
        np.testing.assert_allclose(Ys, Yp, rtol=0, atol=1e-9)
        rms = np.sqrt(np.mean((Ys - e.y) ** 2, axis=0))
        np.testing.assert_allclose(rms, [res.rmse[e.name][nm] for nm in e.output_names], rtol=1e-9)


def test_nonuniform_sampling_resimulates_too():
    plant = three_tank()
    rng = np.random.default_rng(5)
    t = np.cumsum(np.r_[0.0, rng.uniform(0.5, 1.5, 199)])
    e = _experiment(plant, "nu", 200, 5, TRUE, t=t)
    res = fit_parameters(plant, _mu_free()[:2], [e], starts=1)
    Ys = simulate_outputs(plant, res.parameters, e, res.x0[0], substeps=res.substeps)
    np.testing.assert_allclose(Ys, res.predicted[0], rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------- scipy reference
def _rk4_three_tank(x, u, dt, mu, substeps=4):
    """The three-tank RK4 step written by hand (seed 000 parameters, clipped to [0, hmax])."""
    A, Phi, g, hmax, qmax = 0.0154, 5e-5, 9.81, 0.62, 1.2e-4
    u = np.clip(u, 0.0, qmax)
    clip = lambda v: np.clip(v, 0.0, hmax)  # noqa: E731

    def f(h):
        q13 = mu[0] * Phi * np.sign(h[0] - h[2]) * np.sqrt(2 * g * abs(h[0] - h[2]))
        q32 = mu[1] * Phi * np.sign(h[2] - h[1]) * np.sqrt(2 * g * abs(h[2] - h[1]))
        q20 = mu[2] * Phi * np.sqrt(2 * g * h[1])
        return np.array([u[0] - q13, u[1] + q32 - q20, q13 - q32]) / A

    h = dt / substeps
    for _ in range(substeps):
        k1 = f(clip(x))
        k2 = f(clip(x + h / 2 * k1))
        k3 = f(clip(x + h / 2 * k2))
        k4 = f(clip(x + h * k3))
        x = clip(x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))
    return x


def test_optimum_equals_scipy_least_squares_of_the_same_cost(three_tank_fit):
    _, exps, res = three_tank_fit
    w = np.array([res.weights[nm] for nm in ("h1", "h2", "h3")])

    def residuals(z):
        mu, out = z[:3], []
        for e, x0 in zip(exps, z[3:].reshape(len(exps), 3)):
            x = x0.copy()
            for k in range(e.samples):
                out.append(w * (x - e.y[k]))
                if k < e.samples - 1:
                    x = _rk4_three_tank(x, e.u[k], e.t[k + 1] - e.t[k], mu)
        return np.concatenate(out)

    z0 = np.r_[0.5, 0.5, 0.5, exps[0].y[0], exps[1].y[0]]
    ref = least_squares(residuals, z0, bounds=(np.r_[[0.2] * 3, [0.0] * 6], np.r_[[0.9] * 3, [0.62] * 6]),
                        xtol=1e-14, ftol=1e-14, gtol=1e-14)
    np.testing.assert_allclose(res.values, ref.x[:3], rtol=2e-6)
    np.testing.assert_allclose(res.x0.ravel(), ref.x[3:], atol=1e-7)
    assert res.cost == pytest.approx(2 * ref.cost, rel=1e-7)


# ----------------------------------------------------------------------------- censoring
def _constant_plant() -> Plant:
    """One state that does not move; the output is the parameter c itself (y = c)."""
    x, u, c = sp.Symbol("x", real=True), sp.Symbol("u", real=True), sp.Symbol("c", real=True, positive=True)
    return Plant("custom", "constant level", (Quantity("x", "m"),), (Quantity("u", "m/s"),),
                 (Quantity("y", "m"),), (Parameter("c", 0.3, "m", lower=0),),
                 sp.Matrix([0 * u]), sp.Matrix([c + 0 * x]), Region(bounds=((0.0, 1.0),)))


def _censored_experiment(y, high, limit):
    y = np.asarray(y, dtype=float)
    N = y.size
    hi = np.zeros((N, 1), dtype=bool)
    hi[high, 0] = True
    yy = y[:, None].copy()
    yy[high, 0] = limit
    return Experiment("c", "c.csv", np.arange(N, dtype=float), np.zeros((N, 1)), yy, ("u",), ("y",),
                      np.zeros((N, 1), dtype=bool), hi, ((0.0, limit),))


def test_censored_samples_pull_like_samples_at_the_limit_while_the_model_is_below_it():
    plant = _constant_plant()
    exact = np.array([0.40, 0.42, 0.38, 0.45, np.nan, 0.41])     # one missing sample
    limit = 0.5
    y = np.r_[exact, [0.0, 0.0, 0.0]]                            # three samples saturated at 0.5
    e = _censored_experiment(y, [6, 7, 8], limit)
    res = fit_parameters(plant, [Free("c", 0.3, 0.01, 0.99, "m")], [e], starts=2)
    # hand: d/dc [sum (c - y_k)^2 + 3 min(c - 0.5, 0)^2] = 0 with c < 0.5:
    # c = (sum y_k + 3 * 0.5) / (5 + 3)
    ok = exact[np.isfinite(exact)]
    hand = (ok.sum() + 3 * limit) / (ok.size + 3)
    assert hand < limit
    assert res.values[0] == pytest.approx(hand, abs=1e-8)
    # without the censored samples the mean of the exact ones
    plain = fit_parameters(plant, [Free("c", 0.3, 0.01, 0.99, "m")],
                           [_censored_experiment(exact, [], limit)], starts=1)
    assert plain.values[0] == pytest.approx(ok.mean(), abs=1e-8)


def test_censored_samples_do_not_count_where_the_model_is_beyond_the_limit():
    plant = _constant_plant()
    exact = np.array([0.60, 0.62, 0.58, 0.61])                  # mean 0.6025 above the limit
    e = _censored_experiment(np.r_[exact, [0.0, 0.0]], [4, 5], 0.5)
    res = fit_parameters(plant, [Free("c", 0.3, 0.01, 0.99, "m")], [e], starts=2)
    assert res.values[0] == pytest.approx(exact.mean(), abs=1e-8)


# ----------------------------------------------------------------------------- identifiability
def test_product_of_two_parameters_is_named():
    x, u = sp.Symbol("x", real=True), sp.Symbol("u", real=True)
    a, b = sp.Symbol("a", positive=True, real=True), sp.Symbol("b", positive=True, real=True)
    plant = Plant("custom", "decay", (Quantity("x", "m"),), (Quantity("u", "m/s"),), (Quantity("y", "m"),),
                  (Parameter("a", 1.0, "1/s", lower=0), Parameter("b", 0.05, "1", lower=0)),
                  sp.Matrix([-a * b * x + u]), sp.Matrix([x]), Region(bounds=((0.0, 10.0),)))
    rng = np.random.default_rng(3)
    N = 150
    U = np.repeat(rng.uniform(0.0, 0.2, N // 30 + 1), 30)[:N, None]
    run = simulate_inputs(plant, [1.0], U[:-1], 1.0, substeps=4)
    Y = run.y[0] + 0.01 * rng.standard_normal((N, 1))
    none = np.zeros((N, 1), dtype=bool)
    e = Experiment("d", "d.csv", np.arange(N, dtype=float), U, Y, ("u",), ("y",), none, none.copy(),
                   ((0.0, 10.0),))
    res = fit_parameters(plant, [Free("a", 1.5, 0.5, 2.0, "1/s"), Free("b", 0.04, 0.02, 0.1)], [e],
                         starts=2)
    assert not res.identifiable
    assert "only a*b is identifiable" in res.unidentifiable_note
    assert res.interval_method == ("unidentifiable", "unidentifiable")
    assert np.all(np.isinf(res.stderr))
    # the product itself is fitted: it is what the data determine
    assert res.values[0] * res.values[1] == pytest.approx(0.05, rel=0.05)


def test_three_tank_with_pipe_area_and_all_coefficients_free_names_the_products():
    # mu and Phi enter the three-tank model only as mu*Phi (the tank area A does not scale
    # with them: the pump term q/A fixes A), so with Phi and every mu free only the products are
    # determined
    plant = three_tank()
    e = _experiment(plant, "e", 200, 4, TRUE)
    free = [Free("Phi", 4e-5, 3e-5, 8e-5, "m^2"), *_mu_free()]
    res = fit_parameters(plant, free, [e], starts=1)
    assert not res.identifiable
    for nm in ("Phi*mu13", "Phi*mu32", "Phi*mu20"):
        assert nm in res.unidentifiable_note, res.unidentifiable_note
    product = res.values[1] * res.values[0]
    assert product == pytest.approx(TRUE["mu13"] * 5e-5, rel=0.01)


def test_identifiable_note_from_null_directions():
    v = np.array([[0.5, 0.5, 0.5, 0.5]])
    note = identifiable_note(["A", "mu13", "mu32", "mu20"], v)
    assert "only mu13/A, mu32/A, mu20/A are identifiable" in note
    assert "a*b" in identifiable_note(["a", "b"], np.array([[1.0, -1.0]]) / np.sqrt(2))
    # scaling a by c^-1 and b by c^2 leaves a^2 b unchanged
    assert "only a^2*b is identifiable" in identifiable_note(["a", "b"], np.array([[-1.0, 2.0]]))
    assert identifiable_note(["a"], np.zeros((0, 1))) == ""


# ----------------------------------------------------------------------------- whiteness, validation
def test_whiteness_detects_a_coloured_sequence():
    rng = np.random.default_rng(0)
    white = rng.standard_normal(2000)
    assert whiteness_test([white]).passed
    coloured = np.convolve(white, np.ones(5) / 5, mode="same")
    test = whiteness_test([coloured])
    assert not test.passed and test.outside >= 4
    assert test.autocorrelation[0] == pytest.approx(0.8, abs=0.05)    # MA(4) of equal weights: 4/5


def test_validation_estimates_the_initial_state_on_the_first_samples(three_tank_fit):
    plant, _, res = three_tank_fit
    v_exp = _experiment(plant, "v", 300, 9, TRUE, x0=(0.25, 0.12, 0.18))
    val = validate_experiment(plant, res.parameters, v_exp, init_samples=10, substeps=res.substeps)
    np.testing.assert_allclose(val.x0, [0.25, 0.12, 0.18], atol=3 * NOISE)
    for nm in ("h1", "h2", "h3"):
        assert val.rmse[nm] == pytest.approx(NOISE, rel=0.3)
        assert val.fit_percent[nm] > 90.0


def test_bad_free_parameter_and_mode_are_spec_errors(three_tank_fit):
    plant, exps, _ = three_tank_fit
    with pytest.raises(SpecError, match="not a parameter"):
        fit_parameters(plant, [Free("mu99", 0.5, 0.2, 0.9)], exps)
    with pytest.raises(SpecError, match="outside"):
        fit_parameters(plant, [Free("mu13", 0.95, 0.2, 0.9)], exps)
    with pytest.raises(SpecError, match="prediction"):
        fit_parameters(plant, _mu_free(), exps, mode="prediction")


# ----------------------------------------------------------------------------- coverage
@pytest.mark.slow
def test_coverage_of_the_95_percent_intervals():
    """>= 90 of 100 seeded trials contain the true parameters (each parameter's interval)."""
    plant = three_tank()
    free = [Free("mu13", 0.5, 0.2, 0.9), Free("mu20", 0.5, 0.2, 0.9)]
    values = {"mu13": 0.45, "mu20": 0.70}
    hits = np.zeros(2, dtype=int)
    both = converged = 0
    for trial in range(100):
        e = _experiment(plant, f"t{trial}", 200, 1000 + trial, values, noise=0.005)
        res = fit_parameters(plant, free, [e], starts=1)
        converged += res.converged
        inside = [res.ci95[i, 0] <= values[nm] <= res.ci95[i, 1] for i, nm in enumerate(res.names)]
        hits += inside
        both += all(inside)
    print(f"coverage of 100 trials: mu13 {hits[0]}, mu20 {hits[1]}, both {both}; converged {converged}")
    # measured: mu13 93, mu20 93, both 89; converged 99 (trial 68: IPOPT stops at its iteration
    # limit at the optimum, said so by converged = False)
    assert converged >= 98
    assert np.all(hits >= 90), hits
