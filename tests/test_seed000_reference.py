"""Seed 000 (DTS200 three-tank, Table I): linearisation at y0 = (0.40, 0.20, 0.30) m.

The expected values are derived here from the model equations (6a-c) with the
flow directions h1 > h3 > h2, independently of the library, and then pinned.
The printed F of eq. (8) has typos; the tests below assert exactly where it
differs from the derivation (errata) instead of trusting it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
import sympy as sp

from tanksynth.analysis.linearize import equilibrium_input, linearize, symbolic_jacobians
from tanksynth.analysis.symbolic import relative_degree
from tanksynth.papers import seed000 as paper
from tanksynth.plants import three_tank

# Table I
A_, PHI, MU13, MU32, MU20, G = (paper.TABLE_I[k] for k in ("A", "Phi", "mu13", "mu32", "mu20", "g"))
Y0 = paper.Y0
PRINTED_U0 = paper.U0


def derived_jacobians(h1: float, h2: float, h3: float) -> tuple[np.ndarray, np.ndarray]:
    """F and B of eq. (6) with h1 > h3 > h2, written out by hand."""
    r2g = math.sqrt(2 * G)
    a13 = MU13 * PHI * r2g / (2 * A_ * math.sqrt(h1 - h3))
    a32 = MU32 * PHI * r2g / (2 * A_ * math.sqrt(h3 - h2))
    a20 = MU20 * PHI * r2g / (2 * A_ * math.sqrt(h2))
    F = np.array([
        [-a13, 0.0, a13],
        [0.0, -a32 - a20, a32],
        [a13, a32, -a13 - a32],
    ])
    B = np.array([[1 / A_, 0.0], [0.0, 1 / A_], [0.0, 0.0]])
    return F, B


def exact_u0(h1: float, h2: float, h3: float) -> np.ndarray:
    """Equilibrium inputs: q1 = q13, q2 = q20 - q32 (eq. 6 with dh/dt = 0)."""
    q13 = MU13 * PHI * math.sqrt(2 * G * (h1 - h3))
    q32 = MU32 * PHI * math.sqrt(2 * G * (h3 - h2))
    q20 = MU20 * PHI * math.sqrt(2 * G * h2)
    return np.array([q13, q20 - q32])


@pytest.fixture(scope="module")
def plant():
    return three_tank()


@pytest.fixture(scope="module")
def lin(plant):
    return linearize(plant, Y0, exact_u0(*Y0), ts=1.0)


# ----------------------------------------------------------------- (a) F and B
def test_F_B_equal_independent_jacobian(lin):
    F, B = derived_jacobians(*Y0)
    np.testing.assert_allclose(lin.F, F, rtol=1e-12, atol=0)
    np.testing.assert_allclose(lin.B, B, rtol=1e-12, atol=0)
    # zero pattern is exact
    assert lin.F[0, 1] == 0 and lin.F[1, 0] == 0
    assert np.all(lin.B[2] == 0)
    np.testing.assert_array_equal(lin.C, np.eye(3))


def test_F_B_pinned(lin):
    a13 = 0.01136943265902151          # mu13 Phi sqrt(2g) / (2 A sqrt(0.1))
    a20 = 0.010853193957441182         # mu20 Phi sqrt(2g) / (2 A sqrt(0.2))
    F_pinned = np.array([
        [-a13, 0.0, a13],
        [0.0, -a13 - a20, a13],          # a32 == a13 here: h3 - h2 == h1 - h3, mu32 == mu13
        [a13, a13, -2 * a13],
    ])
    np.testing.assert_allclose(lin.F, F_pinned, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(lin.F[1, 1], -0.022222626616462692, rtol=1e-12)
    np.testing.assert_allclose(lin.B, [[64.93506493506493, 0], [0, 64.93506493506493], [0, 0]],
                               rtol=1e-12)
    # stable, three real eigenvalues (F is symmetric at this point)
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(lin.F).real),
                               [-0.036738893784408616, -0.01739703416891438, -0.0021949966402042167],
                               rtol=1e-10)


def test_operating_point_is_an_equilibrium(lin):
    assert np.max(np.abs(lin.offset)) < 1e-15


# --------------------------------------------------------------- (b) errata
def _symbols(plant):
    p = plant.p
    return plant.x, p["A"], p["Phi"], p["mu13"], p["mu32"], p["mu20"], p["g"]


def _derived_symbolic_F(plant) -> sp.Matrix:
    (h1, h2, h3), A, Phi, mu13, mu32, mu20, g = _symbols(plant)
    phi = sp.sqrt(2 * g)
    a13 = mu13 * Phi * phi / (2 * A * sp.sqrt(h1 - h3))
    a32 = mu32 * Phi * phi / (2 * A * sp.sqrt(h3 - h2))
    a20 = mu20 * Phi * phi / (2 * A * sp.sqrt(h2))
    return sp.Matrix([[-a13, 0, a13], [0, -a32 - a20, a32], [a13, a32, -a13 - a32]])


def _printed_symbolic_F(plant) -> sp.Matrix:
    """Eq. (8) exactly as printed (phi = sqrt(2g), y0i = hi)."""
    (h1, h2, h3), A, Phi, mu13, mu32, mu20, g = _symbols(plant)
    phi = sp.sqrt(2 * g)
    t13 = mu13 * Phi * phi / (2 * A * sp.sqrt(h1 - h3))
    t32 = mu32 * Phi * phi / (2 * A * sp.sqrt(h3 - h2))
    t20 = mu20 * Phi * phi / (2 * A * sp.sqrt(h2))
    return sp.Matrix(paper.F_in_fractions(t13, t32, t20))


def test_symbolic_jacobian_equals_derivation(plant):
    F_sym, B_sym, C_sym = symbolic_jacobians(plant)
    diff = (F_sym - _derived_symbolic_F(plant)).applyfunc(sp.simplify)
    assert diff == sp.zeros(3, 3)
    A = plant.p["A"]
    assert (B_sym - sp.Matrix([[1 / A, 0], [0, 1 / A], [0, 0]])).applyfunc(sp.simplify) == sp.zeros(3, 2)
    assert C_sym == sp.eye(3)


def test_printed_F_errata(plant):
    """Printed eq. (8) differs from the derivation exactly at (2,2), (3,1), (3,3)."""
    derived = _derived_symbolic_F(plant)
    printed = _printed_symbolic_F(plant)
    diff = (printed - derived).applyfunc(sp.simplify)
    wrong = {(i + 1, j + 1) for i in range(3) for j in range(3) if diff[i, j] != 0}
    assert wrong == {(2, 2), (3, 1), (3, 3)} == set(paper.F_FORMULA_ERRATA) == set(paper.F_PRINTED_LATEX)
    (h1, h2, h3), A, Phi, mu13, mu32, mu20, g = _symbols(plant)
    a13 = mu13 * Phi * sp.sqrt(2 * g) / (2 * A * sp.sqrt(h1 - h3))
    a32 = mu32 * Phi * sp.sqrt(2 * g) / (2 * A * sp.sqrt(h3 - h2))
    # (2,2): the printed entry uses the mu13 term where the mu32 term belongs
    assert sp.simplify(diff[1, 1] - (a32 - a13)) == 0
    # (3,1): sign flipped
    assert sp.simplify(printed[2, 0] + derived[2, 0]) == 0
    # (3,3): sign of the mu13 term flipped
    assert sp.simplify(diff[2, 2] - 2 * a13) == 0


def test_printed_F_numeric_errata_at_y0(lin, plant):
    """At y0 the (2,2) typo is invisible (mu13 = mu32, h1-h3 = h3-h2); (3,1), (3,3) are not."""
    printed = _printed_symbolic_F(plant).xreplace(plant.parameter_values).xreplace(dict(zip(plant.x, map(sp.Rational, ("0.4", "0.2", "0.3")))))
    P = np.array(printed.evalf(30), dtype=float)
    np.testing.assert_allclose(paper.printed_F(paper.TABLE_I, Y0)[0], P, rtol=1e-12, atol=1e-17)
    wrong = {(i + 1, j + 1) for i in range(3) for j in range(3)
             if not np.isclose(P[i, j], lin.F[i, j], rtol=1e-12, atol=0)}
    assert wrong == {(3, 1), (3, 3)}
    np.testing.assert_allclose(P[2, 2], 0.0, atol=1e-15)   # printed -a32 + a13 = 0 here
    # so the printed F is not symmetric and has a complex pair (an oscillating mode the
    # plant does not have); the derived F is symmetric with three real eigenvalues
    ev = np.linalg.eigvals(P)
    assert np.sum(np.abs(ev.imag) > 1e-6) == 2
    np.testing.assert_allclose(np.sort_complex(ev),
                               [-0.02593604 + 0j, -0.00382801 - 0.00627998j, -0.00382801 + 0.00627998j],
                               rtol=1e-5)
    assert np.all(np.linalg.eigvals(lin.F).imag == 0)


# ------------------------------------------------------------------- (c) ZOH
AD_PINNED = np.array([
    [9.8875861630568318e-01, 6.3431312885060630e-05, 1.1177721825011592e-02],
    [6.3431312885060603e-05, 9.7808567901312948e-01, 1.1117170664512795e-02],
    [1.1177721825011588e-02, 1.1117170664512791e-02, 9.7764432579355665e-01],
])
BD_PINNED = np.array([
    [6.4568705677254741e+01, 1.3794276755765176e-03],
    [1.3794276755765172e-03, 6.4220241857649285e+01],
    [3.6497607679605254e-01, 3.6365928320025132e-01],
])


def test_zoh_against_independent_routes(lin):
    F, B = derived_jacobians(*Y0)
    # F is symmetric at y0: Ad = V exp(Lambda) V' from a symmetric eigendecomposition
    assert np.allclose(F, F.T, rtol=0, atol=1e-18)
    w, V = np.linalg.eigh(F)
    Ad = V @ np.diag(np.exp(w)) @ V.T
    # Bd = int_0^1 exp(F s) ds B = V diag(expm1(w)/w) V' B (F invertible; expm1 avoids
    # the cancellation of F^-1 (Ad - I) B in the small entries)
    Bd = V @ np.diag(np.expm1(w) / w) @ V.T @ B
    np.testing.assert_allclose(lin.Ad, Ad, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(lin.Bd, Bd, rtol=1e-10, atol=0)
    # and Bd by quadrature of exp(F s) B over [0, ts]
    Bq, _ = scipy.integrate.quad_vec(lambda s: (V @ np.diag(np.exp(w * s)) @ V.T @ B).ravel(), 0, 1.0,
                                     epsabs=1e-13, epsrel=1e-13)
    np.testing.assert_allclose(lin.Bd, Bq.reshape(3, 2), rtol=1e-9, atol=1e-12)


def test_zoh_pinned(lin):
    assert lin.ts == 1.0
    np.testing.assert_allclose(lin.Ad, AD_PINNED, rtol=1e-10, atol=0)
    np.testing.assert_allclose(lin.Bd, BD_PINNED, rtol=1e-10, atol=0)


# ------------------------------------------------------------- (d) equilibrium
def test_exact_equilibrium_inputs(plant):
    eq = equilibrium_input(plant, Y0, given_u0=PRINTED_U0)
    u0 = exact_u0(*Y0)
    np.testing.assert_allclose(u0, [3.501785258978626e-05, 3.183782218805142e-05], rtol=1e-12)
    np.testing.assert_allclose(eq.u0, u0, rtol=1e-10)
    np.testing.assert_allclose(eq.u0, [3.5018e-5, 3.1838e-5], rtol=5e-5)
    assert eq.is_equilibrium
    assert eq.within_bounds
    assert np.max(np.abs(eq.residual)) < 1e-15


def test_printed_u0_does_not_balance(plant):
    eq = equilibrium_input(plant, Y0, given_u0=PRINTED_U0)
    u0 = exact_u0(*Y0)
    expected = np.array([(PRINTED_U0[0] - u0[0]) / A_, (PRINTED_U0[1] - u0[1]) / A_, 0.0])
    np.testing.assert_allclose(eq.given_residual, expected, rtol=1e-9, atol=1e-17)
    # tank 2 is off by 3.68e-4 m/s (the printed q2 is 18 % too large); tank 1 by -1.16e-6 m/s
    np.testing.assert_allclose(eq.given_residual[1], 3.676738838e-4, rtol=1e-8)
    np.testing.assert_allclose(eq.given_residual[0], -1.159259e-6, rtol=1e-5)
    d = eq.as_dict()
    assert d["given_u0_balances"] is False
    np.testing.assert_allclose(d["given_u0"], PRINTED_U0)


# --------------------------------------------------- relative degree, decoupling
def test_relative_degree_and_decoupling_matrix():
    plant = three_tank(outputs="h1h2")
    rd = relative_degree(plant.f_smooth, plant.h, plant.x, plant.u)
    assert rd.degrees == (1, 1)
    assert rd.total == 2 < plant.n          # internal dynamics (tank 3), as the paper says
    (h1, h2, h3) = plant.x
    p = plant.p
    A, Phi, g = p["A"], p["Phi"], p["g"]
    assert (rd.decoupling - sp.diag(1 / A, 1 / A)).applyfunc(sp.simplify) == sp.zeros(2, 2)
    q13 = p["mu13"] * Phi * sp.sqrt(2 * g * (h1 - h3))
    q32 = p["mu32"] * Phi * sp.sqrt(2 * g * (h3 - h2))
    q20 = p["mu20"] * Phi * sp.sqrt(2 * g * h2)
    expected = sp.Matrix([-q13 / A, (q32 - q20) / A])
    assert (rd.drift - expected).applyfunc(sp.simplify) == sp.zeros(2, 1)
