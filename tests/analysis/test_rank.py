"""Rank verification: Kalman ranks, PBH, nonlinear and symbolic observability."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from tanksynth.errors import DimensionError
from tanksynth.plants import custom_plant, three_tank
from tanksynth.analysis.rank import (controllability_matrix, controllability_rank,
                                   nonlinear_observability, observability_matrix,
                                   observability_rank, pbh_test, symbolic_observability)


# -------------------------------------------------------------------- Kalman
def test_matrices_shapes_and_blocks():
    A = np.array([[0.0, 1.0], [-2.0, -3.0]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0]])
    np.testing.assert_array_equal(controllability_matrix(A, B), np.hstack([B, A @ B]))
    np.testing.assert_array_equal(observability_matrix(A, C), np.vstack([C, C @ A]))


def test_controllability_rank_and_condition_number():
    A = np.diag([1.0, 2.0])
    B = np.array([[1.0], [1.0]])
    r = controllability_rank(A, B)
    assert r.rank == 2 and r.full and r.n == 2
    # Q = [[1, 1], [1, 2]]: Q Q' = [[2, 3], [3, 5]], eigenvalues (7 +- sqrt 45)/2
    lam = np.array([(7 + np.sqrt(45)) / 2, (7 - np.sqrt(45)) / 2])
    np.testing.assert_allclose(r.singular_values, np.sqrt(lam), rtol=1e-12)
    np.testing.assert_allclose(r.condition_number, np.sqrt(lam[0] / lam[1]), rtol=1e-12)
    d = r.as_dict()
    assert d["rank"] == 2 and d["full"] is True and d["kind"] == "controllability"


def test_rank_deficient_reports_inf_condition():
    A = np.diag([-1.0, -2.0, -3.0])
    B = np.array([[1.0], [1.0], [0.0]])
    r = controllability_rank(A, B)
    assert r.rank == 2 and not r.full
    assert r.condition_number == float("inf")
    o = observability_rank(A, np.array([[0.0, 0.0, 1.0]]))
    assert o.rank == 1 and not o.full


def test_tolerance_changes_verdict():
    A = np.diag([-1.0, -1.0 - 1e-7])        # nearly repeated eigenvalue: almost uncontrollable
    B = np.array([[1.0], [1.0]])
    assert controllability_rank(A, B).rank == 2
    weak = controllability_rank(A, B)
    assert weak.condition_number > 1e6          # fragile verdict is visible
    assert controllability_rank(A, B, tol=1e-6).rank == 1


def _full_kalman_rank(M):
    """The rule on a whole Kalman matrix, by hand: numpy SVD, max(shape) eps s_max."""
    s = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(s > max(M.shape) * np.finfo(float).eps * s[0])), s


def test_every_state_measured_decides_on_c_alone():
    """rank C = n: one SVD of C, its singular values reported, the (n q) x n matrix never built."""
    rng = np.random.default_rng(3)
    n = 12
    A = rng.normal(size=(n, n))
    C = np.diag(rng.uniform(0.5, 2.0, n)) @ np.linalg.qr(rng.normal(size=(n, n)))[0]
    r = observability_rank(A, C)
    assert r.full and r.blocks == 1 and r.matrix.shape == (n, n)
    s = np.linalg.svd(C, compute_uv=False)
    np.testing.assert_allclose(r.singular_values, s, rtol=1e-12)
    np.testing.assert_allclose(r.condition_number, s[0] / s[-1], rtol=1e-12)
    assert r.as_dict()["blocks"] == 1


def test_leading_blocks_give_the_full_matrix_verdict_and_lower_bounds():
    """Random pairs, full and deficient: same rank as the whole matrix; reported singular values
    are those of the leading blocks [B, AB, ...] (each at most the whole matrix's)."""
    rng = np.random.default_rng(7)
    for n, m in ((5, 1), (6, 2), (6, 3), (8, 4), (9, 9)):
        A = rng.normal(size=(n, n)) / np.sqrt(n)
        B = rng.normal(size=(n, m))
        whole = np.hstack([np.linalg.matrix_power(A, j) @ B for j in range(n)])
        rank, s_whole = _full_kalman_rank(whole)
        r = controllability_rank(A, B)
        assert r.rank == rank == n
        k = r.blocks
        assert k in (1, 2, 4, 8, n) and k * m >= n
        lead = whole[:, :k * m]
        np.testing.assert_allclose(r.singular_values, np.linalg.svd(lead, compute_uv=False),
                                   rtol=1e-10)
        assert np.all(r.singular_values[:n] <= s_whole[:n] * (1 + 1e-12))
        # fewer blocks than k (the previous try) would not do
        if k > 1:
            prev = whole[:, :(1 << ((k - 1).bit_length() - 1)) * m]   # the try before k
            assert _full_kalman_rank(prev)[0] < n
        o = observability_rank(A, B.T)
        assert o.rank == n and o.blocks == k
    # a deficient pair is judged on the whole matrix, as before
    A = np.diag([-1.0, -2.0, -3.0, -4.0])
    B = np.array([[1.0], [1.0], [0.0], [1.0]])
    whole = np.hstack([np.linalg.matrix_power(A, j) @ B for j in range(4)])
    r = controllability_rank(A, B)
    rank, s_whole = _full_kalman_rank(whole)
    assert r.rank == rank == 3 and r.blocks == 4 and r.matrix.shape == (4, 4)
    np.testing.assert_allclose(r.singular_values, s_whole, rtol=1e-12)


def test_leading_blocks_not_fooled_by_growing_powers():
    """With ||A|| >> 1 the whole matrix's tolerance max(shape) eps s_max is dominated by A^(n-1):
    the naive full SVD loses rank that C = I already proves."""
    rng = np.random.default_rng(0)
    n = 30
    A = 50.0 * rng.normal(size=(n, n))
    C = np.eye(n)
    whole = np.vstack([np.linalg.matrix_power(A, j) for j in range(n)])
    assert _full_kalman_rank(whole)[0] < n            # the naive verdict
    r = observability_rank(A, C)
    assert r.full and r.blocks == 1
    np.testing.assert_allclose(r.singular_values, np.ones(n), rtol=1e-12)


def test_dimension_errors():
    with pytest.raises(DimensionError):
        controllability_rank(np.ones((2, 3)), np.ones((2, 1)))
    with pytest.raises(DimensionError):
        observability_rank(np.eye(2), np.ones((1, 3)))
    with pytest.raises(DimensionError):
        observability_rank(np.array([[np.nan, 0], [0, 1]]), np.ones((1, 2)))


# ----------------------------------------------------------------------- PBH
def test_pbh_names_unobservable_state():
    A = np.diag([-1.0, -2.0, -3.0])
    C = np.array([[1.0, 1.0, 0.0]])
    res = pbh_test(A, C=C, state_names=["h1", "h2", "h3"])
    assert not res.passed
    assert len(res.modes) == 1
    mode = res.modes[0]
    assert mode.eigenvalue == pytest.approx(-3.0)
    assert mode.states == ("h3",)
    assert mode.smallest_singular_value < 1e-12
    d = res.as_dict()
    assert d["modes"][0]["states"] == ["h3"] and d["passed"] is False


def test_pbh_names_uncontrollable_state_and_passes():
    A = np.array([[-1.0, 0.0, 0.0], [0.0, -2.0, 0.0], [1.0, 0.0, -3.0]])
    B = np.array([[1.0], [0.0], [0.0]])
    res = pbh_test(A, B=B)
    assert [m.states for m in res.modes] == [("x2",)]
    assert res.modes[0].eigenvalue == pytest.approx(-2.0)
    # coupled chain, fully observable from the last state
    A2 = np.array([[-1.0, 0, 0], [1.0, -2.0, 0], [0, 1.0, -3.0]])
    assert pbh_test(A2, C=np.array([[0, 0, 1.0]])).passed
    assert pbh_test(A2, B=np.array([[1.0], [0], [0]])).passed


def test_pbh_complex_mode():
    # oscillator (+-i) decoupled from an observed first-order state
    A = np.array([[-1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
    res = pbh_test(A, C=np.array([[1.0, 0, 0]]), state_names=["a", "b", "c"])
    assert sorted(round(m.eigenvalue.imag) for m in res.modes) == [-1, 1]
    assert all(set(m.states) == {"b", "c"} for m in res.modes)


def test_pbh_argument_checks():
    with pytest.raises(DimensionError):
        pbh_test(np.eye(2))
    with pytest.raises(DimensionError):
        pbh_test(np.eye(2), B=np.ones((2, 1)), C=np.ones((1, 2)))


# ---------------------------------------------------------- nonlinear (local)
def test_nonlinear_observability_three_tank_h1():
    plant = three_tank(outputs="h1")
    res = nonlinear_observability(plant, count=50, seed=3)
    assert res.full
    assert res.orders == 3                      # needs h1, L_f h1, L_f^2 h1
    assert len(res.drop_points) == 0
    assert np.all(res.ranks == 3)
    assert np.all(res.smallest_singular_values > 0)
    assert res.as_dict()["min_rank"] == 3


@pytest.mark.slow
def test_nonlinear_observability_of_a_hybrid_plant_equals_the_sympy_lie_derivatives():
    """The CasADi (AD) codistribution against sympy: Lie derivatives of the Piecewise/Max/sign
    model differentiated by sympy, lambdified, ranked here with the same scaling and tolerance."""
    from tanksynth.plants import hybrid_three_tank

    plant = hybrid_three_tank()
    res = nonlinear_observability(plant, count=60, seed=2)
    u = {s: sp.Float(v) for s, v in zip(plant.u, res.input_value)}
    f = plant.f_smooth_numeric.xreplace(u)
    L, rows = plant.h_numeric, []
    for _ in range(res.orders):
        grad = L.jacobian(plant.x)
        rows.append(grad)
        L = grad * f
    D = sp.Matrix.vstack(*rows).replace(sp.DiracDelta, lambda *a: sp.S.Zero)
    fn = sp.lambdify([plant.x], D, modules="numpy")
    with np.errstate(invalid="ignore", divide="ignore"):        # numpy evaluates every branch
        vals = np.array([np.asarray(fn(p), dtype=float) for p in res.points])
    vals = vals / np.linalg.norm(vals, axis=2, keepdims=True)
    sv = np.linalg.svd(vals, compute_uv=False)
    np.testing.assert_array_equal(res.ranks, np.sum(sv > 1e-9 * sv[:, :1], axis=1))
    np.testing.assert_allclose(res.smallest_singular_values, sv[:, plant.n - 1], rtol=1e-9)
    assert res.orders == 3 and res.full


def test_nonlinear_observability_three_tank_h1_depends_on_direction():
    """With only h1 measured, q1 enters L_f^k h1; still full for every input in range."""
    plant = three_tank(outputs="h1")
    res = nonlinear_observability(plant, count=30, seed=4, u=[0.0, 0.0])
    assert res.full


def oscillator_squared_output():
    """x1' = x2, x2' = -x1 + u, y = x1^2: d(y, L_f y) = [[2 x1, 0], [2 x2, 2 x1]], det 4 x1^2."""
    return custom_plant({
        "model": "custom", "name": "osc",
        "states": {"x1": {"unit": "1", "min": -1.0, "max": 1.0},
                   "x2": {"unit": "1", "min": -1.0, "max": 1.0}},
        "inputs": {"u": {"unit": "1", "min": -1.0, "max": 1.0}},
        "equations": {"x1": "x2", "x2": "-x1 + u"},
        "outputs": {"y": "x1**2"},
    })


def test_nonlinear_observability_drops_where_predicted():
    plant = oscillator_squared_output()
    points = np.array([[0.0, 0.5], [0.0, -0.3], [0.5, 0.5], [-0.7, 0.1], [1e-3, 0.9], [0.0, 0.0]])
    res = nonlinear_observability(plant, points=points)
    np.testing.assert_array_equal(res.ranks, [1, 1, 2, 2, 2, 0])
    assert not res.full
    np.testing.assert_array_equal(res.drop_points, points[[0, 1, 5]])
    d = res.as_dict()
    assert d["min_rank"] == 0 and d["full"] is False
    assert d["drop_points"] == points[[0, 1, 5]].tolist()
    # random region samples never hit x1 = 0 exactly: full there
    assert nonlinear_observability(plant, count=40, seed=1).full


def test_nonlinear_observability_unobservable_everywhere():
    plant = custom_plant({
        "model": "custom",
        "states": {"x1": {"min": 0.0, "max": 1.0}, "x2": {"min": 0.0, "max": 1.0}},
        "inputs": {"u": {"min": 0.0, "max": 1.0}},
        "equations": {"x1": "-x1 + u", "x2": "-x2*x2 + u"},
        "outputs": {"y": "x1"},
    })
    res = nonlinear_observability(plant, count=20)
    assert res.orders == 2
    assert np.all(res.ranks == 1)
    assert len(res.drop_points) == 20


def test_nonlinear_observability_without_inputs():
    plant = custom_plant({
        "model": "custom",
        "states": {"x1": {"min": 0.1, "max": 1.0}, "x2": {"min": 0.1, "max": 1.0}},
        "equations": {"x1": "-sqrt(x1) + sqrt(x2)", "x2": "-sqrt(x2)"},
        "outputs": {"y": "x1"},
    })
    assert plant.m == 0
    res = nonlinear_observability(plant, count=10)
    assert res.full


# ------------------------------------------------------------------ symbolic
def test_symbolic_observability_simple():
    k, c = sp.symbols("k c", real=True)
    A = sp.Matrix([[0, 1], [-k, -c]])
    pos = symbolic_observability(A, sp.Matrix([[1, 0]]))
    assert pos.determinant == 1 and pos.factors == () and pos.degenerate_parameters == ()
    vel = symbolic_observability(A, sp.Matrix([[0, 1]]))
    assert sp.expand(vel.determinant - k) == 0
    assert vel.factors == (k,)
    assert [dict(d) for d in vel.degenerate_parameters] == [{k: 0}]
    assert vel.as_dict()["factors"] == ["k"]


def test_symbolic_observability_with_varying_premise():
    a, z = sp.symbols("a z", real=True)
    A = sp.Matrix([[0, 1], [a * z, 0]])
    res = symbolic_observability(A, sp.Matrix([[0, 1]]), variables=(z,))
    assert sp.expand(res.determinant + a * z) == 0
    assert set(res.factors) == {a, z}
    # only a = 0 makes it unobservable for every z
    assert [dict(d) for d in res.degenerate_parameters] == [{a: 0}]


def test_symbolic_observability_not_polynomial_in_variables():
    a = sp.Symbol("a", real=True)
    z = sp.Symbol("z", positive=True)
    A = sp.Matrix([[0, 1], [a * sp.sqrt(z), 0]])
    res = symbolic_observability(A, sp.Matrix([[0, 1]]), variables=(z,))
    assert sp.simplify(res.determinant + a * sp.sqrt(z)) == 0
    assert [dict(d) for d in res.degenerate_parameters] == [{a: 0}]


def test_symbolic_observability_tall_matrix_gcd():
    """Two outputs: the condition is the gcd of the maximal minors."""
    a, b = sp.symbols("a b", real=True)
    A = sp.Matrix([[a, 0, 0], [0, b, 0], [1, 1, -1]])
    C = sp.Matrix([[0, 0, 1], [0, 0, 2]])
    res = symbolic_observability(A, C)
    assert res.matrix.shape == (6, 3)
    # O = rows [0 0 1], [1 1 -1], [a-1, b-1, 1] (times 1 or 2): every non-zero minor is +-(a - b)
    assert sp.expand(res.determinant - (a - b)) == 0 or sp.expand(res.determinant + (a - b)) == 0
    assert [{str(k): v for k, v in d.items()} for d in res.degenerate_parameters] in (
        [{"a": b}], [{"b": a}])


def test_nonlinear_observability_at_a_kink_is_a_keyed_error_and_sampled_kinks_are_left_out():
    """sqrt(2 g max(h2 - h0, 0)) has an infinite derivative for h2 <= h0 (breaker's case): a given
    point there is a SpecError on 'points' (no raw LinAlgError); sampled points there are left
    out and counted, and the rest still give a rank."""
    import sympy as sp

    from tanksynth.errors import SpecError
    from tanksynth.plants.custom import custom_plant

    table = {
        "name": "kink", "states": {"h1": {"unit": "m", "min": 0.0, "max": 0.6},
                                   "h2": {"unit": "m", "min": 0.0, "max": 0.6}},
        "inputs": {"q": {"unit": "m^3/s", "min": 0.0, "max": 1e-4}},
        "parameters": {"A": {"value": 0.0154, "unit": "m^2"}, "a": {"value": 2.5e-5, "unit": "m^2"},
                       "g": {"value": 9.81, "unit": "m/s^2"}, "h0": {"value": 0.3, "unit": "m"}},
        "equations": {"h1": "(q - a*sqrt(2*g*max(h1 - h2, 0)))/A",
                      "h2": "(a*sqrt(2*g*max(h1 - h2, 0)) - a*sqrt(2*g*max(h2 - h0, 0)))/A"},
        "outputs": {"y": {"expr": "h2", "unit": "m"}},
    }
    plant = custom_plant(table)
    assert isinstance(plant.f[1], sp.Expr)
    with pytest.raises(SpecError) as err:
        nonlinear_observability(plant, points=np.array([[0.5, 0.2]]))
    assert err.value.key == "points" and "not finite" in str(err.value)
    r = nonlinear_observability(plant, count=100, seed=1)
    assert r.undefined_points > 0 and len(r.points) + r.undefined_points == 100
    # kept: off both kinks (h2 > h0 and h1 > h2), where every derivative is finite
    assert np.all(r.points[:, 1] > 0.3) and np.all(r.points[:, 0] > r.points[:, 1])
    assert np.all(np.isfinite(r.smallest_singular_values))
    assert r.as_dict()["undefined_points"] == r.undefined_points
