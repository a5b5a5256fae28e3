"""Symbolic core: sparse Jacobian, control-affine split, Lie derivatives, relative degree."""

from __future__ import annotations

import random

import pytest
import sympy as sp

from tanksynth.analysis.symbolic import (control_affine, jacobian, lie_derivative, lie_derivatives,
                                       relative_degree)
from tanksynth.errors import DimensionError, TanksynthError
from tanksynth.plants import three_tank

X = sp.symbols("x1:5", real=True)
U = sp.symbols("u1:3", real=True)
P = sp.symbols("a b", positive=True)


def random_expr(rng: random.Random, depth: int = 3) -> sp.Expr:
    leaves = [*X, *U, *P, sp.Integer(rng.randint(1, 5)), sp.Rational(rng.randint(1, 9), 7)]
    if depth == 0 or rng.random() < 0.25:
        return rng.choice(leaves)
    op = rng.choice(["add", "mul", "sqrt", "pow", "abs", "exp", "sub", "div"])
    a = random_expr(rng, depth - 1)
    if op == "add":
        return a + random_expr(rng, depth - 1)
    if op == "sub":
        return a - random_expr(rng, depth - 1)
    if op == "mul":
        return a * random_expr(rng, depth - 1)
    if op == "div":
        return a / (random_expr(rng, depth - 1) + 3)
    if op == "sqrt":
        return sp.sqrt(a**2 + 1)
    if op == "pow":
        return a ** rng.randint(2, 3)
    if op == "abs":
        return sp.Abs(a)
    return sp.exp(-a**2)


@pytest.mark.parametrize("seed", range(12))
def test_sparse_jacobian_equals_sympy(seed):
    rng = random.Random(seed)
    n_eq = rng.randint(1, 4)
    exprs = sp.Matrix([random_expr(rng) for _ in range(n_eq)])
    variables = list(X[: rng.randint(1, 4)]) + list(U[: rng.randint(0, 2)])
    ours = jacobian(exprs, variables)
    ref = exprs.jacobian(variables)
    assert ours.shape == ref.shape == (n_eq, len(variables))
    assert (ours - ref).applyfunc(sp.simplify) == sp.zeros(*ref.shape)


def test_jacobian_skips_absent_variables():
    x1, x2, x3, _ = X
    J = jacobian(sp.Matrix([x1 * x2, sp.sqrt(x3)]), [x1, x2, x3])
    assert J == sp.Matrix([[x2, x1, 0], [0, 0, 1 / (2 * sp.sqrt(x3))]])


def test_jacobian_needs_a_column():
    with pytest.raises(DimensionError):
        jacobian(sp.Matrix([[X[0], X[1]]]), X[:2])


def test_control_affine_split():
    x1, x2 = X[:2]
    u1, u2 = U
    f = sp.Matrix([-x1 + sp.sqrt(x2) * u1, x1 * x2 + u2 * x1 - u1])
    f0, G = control_affine(f, U)
    assert f0 == sp.Matrix([-x1, x1 * x2])
    assert G == sp.Matrix([[sp.sqrt(x2), 0], [-1, x1]])
    assert sp.expand(f0 + G * sp.Matrix(U) - f) == sp.zeros(2, 1)


def test_control_affine_refuses_nonaffine():
    x1 = X[0]
    with pytest.raises(TanksynthError, match="not affine"):
        control_affine(sp.Matrix([x1 * U[0] ** 2]), U[:1])


def test_lie_derivative_known_values():
    x1, x2 = X[:2]
    f = sp.Matrix([x2, -x1])            # harmonic oscillator
    h = sp.Matrix([x1**2])
    assert lie_derivative(h, f, [x1, x2], 0) == h
    assert sp.expand(lie_derivative(h, f, [x1, x2], 1)[0] - 2 * x1 * x2) == 0
    assert sp.expand(lie_derivative(h, f, [x1, x2], 2)[0] - (2 * x2**2 - 2 * x1**2)) == 0
    # x1^2 + x2^2 is conserved
    assert sp.expand(lie_derivative(sp.Matrix([x1**2 + x2**2]), f, [x1, x2])[0]) == 0
    with pytest.raises(ValueError):
        lie_derivative(h, f, [x1, x2], -1)


def test_lie_derivatives_sequence():
    x1, x2 = X[:2]
    f = sp.Matrix([x2, -x1])
    seq = lie_derivatives(sp.Matrix([x1]), f, [x1, x2], 4)
    assert [s[0] for s in seq] == [x1, x2, -x1, -x2]
    # agree with lie_derivative of each order, vector output too
    h = sp.Matrix([x1 * x2, sp.sin(x1)])
    seq = lie_derivatives(h, f, [x1, x2], 3)
    for k, Lk in enumerate(seq):
        assert (Lk - lie_derivative(h, f, [x1, x2], k)).applyfunc(sp.simplify) == sp.zeros(2, 1)


def test_relative_degree_double_integrator():
    x1, x2 = X[:2]
    u = U[0]
    rd = relative_degree(sp.Matrix([x2, -sp.sin(x1) + 2 * u]), sp.Matrix([x1]), [x1, x2], [u])
    assert rd.degrees == (2,)
    assert rd.decoupling == sp.Matrix([[2]])
    assert rd.drift == sp.Matrix([-sp.sin(x1)])
    assert rd.total == 2


def test_relative_degree_undefined_raises():
    x1, x2 = X[:2]
    u = U[0]
    # y = x1 never sees u: x1 evolves on its own
    with pytest.raises(TanksynthError, match="relative degree"):
        relative_degree(sp.Matrix([-x1, -x2 + u]), sp.Matrix([x1]), [x1, x2], [u])


@pytest.mark.slow
def test_relative_degree_three_tank_middle_tank():
    """y = h3: the pumps reach tank 3 only through tanks 1 and 2, so theta = 2."""
    plant = three_tank()
    h1, h2, h3 = plant.x
    rd = relative_degree(plant.f_smooth, sp.Matrix([h3]), plant.x, plant.u)
    assert rd.degrees == (2,)
    A, Phi, g = plant.p["A"], plant.p["Phi"], plant.p["g"]
    # L_g L_f h3 = [d(q13 - q32)/dh1, d(q13 - q32)/dh2] / A^2
    k13 = plant.p["mu13"] * Phi * sp.sqrt(2 * g) / (2 * sp.sqrt(h1 - h3))
    k32 = plant.p["mu32"] * Phi * sp.sqrt(2 * g) / (2 * sp.sqrt(h3 - h2))
    expected = sp.Matrix([[k13 / A**2, k32 / A**2]])
    assert (rd.decoupling - expected).applyfunc(sp.simplify) == sp.zeros(1, 2)


def test_jacobian_by_form_is_the_jacobian():
    """Rows of one form (two tanks of one type) are differentiated once; the matrix equals
    sympy's own derivative of every row."""
    from tanksynth.analysis.symbolic import jacobian_by_form
    h = sp.symbols("h1:5", real=True)
    u = sp.Symbol("u", real=True)
    f = sp.Matrix([-2 * sp.sqrt(h[0]) + sp.sqrt(h[2]) + u, -2 * sp.sqrt(h[1]) + sp.sqrt(h[3]) + u,
                   -sp.sqrt(h[2]) + u, sp.sign(h[0] - h[3]) * sp.sqrt(sp.Abs(h[0] - h[3]))])
    memo: dict = {}
    J = jacobian_by_form(f, h, memo)
    assert J == sp.Matrix(4, 4, lambda i, j: sp.diff(f[i], h[j]))
    assert len(memo) == 3                         # rows 1 and 2 share a form
