"""Exact pole placement (python-control's routines, called directly) with its accuracy report."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.design.placement.exact import (ackermann, place_observer, place_state_feedback,
                                              pole_errors)
from tanksynth.errors import DimensionError, SpecError


def random_system(n=4, m=2, seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, n)), rng.standard_normal((n, m))


# ------------------------------------------------------------- exact placement
def test_mimo_place_and_siso_acker():
    A, B = random_system()
    poles = [-1.0, -2.0, -3.0 + 1.0j, -3.0 - 1.0j]
    r = place_state_feedback(A, B, poles)
    assert r.method == "place" and r.max_pole_error < 1e-9 and r.eigenvector_condition >= 1
    r1 = place_state_feedback(A, B[:, :1], poles)
    assert r1.method == "acker" and r1.max_pole_error < 1e-6
    o = place_observer(A, B.T, poles)
    assert o.gain_matrix.shape == (4, 2)
    _, emax = pole_errors(poles, np.linalg.eigvals(A - o.gain_matrix @ B.T))
    assert emax < 1e-9


@pytest.mark.slow
def test_place_is_python_controls_place_bit_for_bit():
    control = pytest.importorskip("control")
    rng = np.random.default_rng(7)
    for n, m in [(3, 2), (4, 2), (5, 2), (5, 3), (6, 4)]:
        for _ in range(20):
            A, B = rng.standard_normal((n, n)), rng.standard_normal((n, m))
            re = -rng.uniform(0.5, 5.0, n)
            poles = re.astype(complex)
            if n >= 4:  # one complex pair
                poles[:2] = [re[0] + 1j, re[0] - 1j]
            r = place_state_feedback(A, B, poles, method="place")
            np.testing.assert_array_equal(r.gain_matrix, control.place(A, B, poles))


@pytest.mark.slow
def test_ackermann_agrees_with_python_control_acker_on_random_systems():
    control = pytest.importorskip("control")
    rng = np.random.default_rng(11)
    for n in range(1, 9):
        for _ in range(100):
            A, b = rng.standard_normal((n, n)), rng.standard_normal((n, 1))
            poles = -rng.uniform(0.1, 4.0, n)
            K = ackermann(A, b, poles)
            ref = np.asarray(control.acker(A, b, poles), dtype=float).reshape(1, n)
            W = np.hstack([np.linalg.matrix_power(A, k) @ b for k in range(n)])
            # both are W^-1 phi(A) rounded differently (Horner here, a power sum there)
            bound = 1e-13 * np.linalg.cond(W) * max(1.0, np.linalg.norm(A, 2)) ** n
            assert np.max(np.abs(K - ref)) <= bound * np.max(np.abs(ref))
            # and the closed loop has the requested characteristic polynomial
            np.testing.assert_allclose(np.poly(A - b @ K), np.poly(poles), rtol=0,
                                       atol=1e-7 * np.max(np.abs(np.poly(poles))) * np.linalg.cond(W))


def test_ackermann_refuses_an_uncontrollable_pair_and_several_inputs():
    A = np.diag([-1.0, -2.0])
    with pytest.raises(ValueError, match="not controllable"):
        ackermann(A, [[1.0], [0.0]], [-3.0, -4.0])
    with pytest.raises(ValueError, match="one input column"):
        ackermann(A, np.eye(2), [-3.0, -4.0])
    # a known gain: double integrator, poles -1, -2: K = [2, 3]
    K = ackermann([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], [-1.0, -2.0])
    np.testing.assert_allclose(K, [[2.0, 3.0]], rtol=0, atol=1e-14)


def test_placement_input_errors():
    A, B = random_system()
    with pytest.raises(SpecError, match="conjugate"):
        place_state_feedback(A, B, [-1, -2, -3 + 1j, -3 + 2j])
    with pytest.raises(DimensionError):
        place_state_feedback(A, B, [-1, -2])
    with pytest.raises(SpecError, match="cannot place"):
        place_state_feedback(A, B, [-1, -1, -1, -2])         # multiplicity 3 > rank(B) = 2
    with pytest.raises(SpecError):
        place_state_feedback(A, B, [-1, -2, -3, -4], method="varga")
    with pytest.raises(DimensionError):
        place_state_feedback(A, B, [-1, -2, -3, -4], method="acker")


# ------------------------------------------------- issue 12: repeated poles, fragile gains
# seed 004's hydraulic cascade: A = [[-1/2, 0, 0], [1/2, -3/2, 0], [0, 3/2, -1/2]], B = e1,
# C = [0, 0, 1/2] (tanksynth.plants.hydraulic_fault at its defaults).
HF_A = np.array([[-0.5, 0.0, 0.0], [0.5, -1.5, 0.0], [0.0, 1.5, -0.5]])
HF_B = np.array([[1.0], [0.0], [0.0]])
HF_C = np.array([[0.0, 0.0, 0.5]])


def _exact_gain_for_triple_pole(observer: bool):
    """The gain giving det(sI - Acl) = (s + 2)^3 exactly, solved in sympy."""
    import sympy as sp

    s = sp.Symbol("s")
    k = sp.symbols("k1:4")
    A = sp.Matrix([[sp.Rational(-1, 2), 0, 0], [sp.Rational(1, 2), sp.Rational(-3, 2), 0],
                   [0, sp.Rational(3, 2), sp.Rational(-1, 2)]])
    if observer:
        Acl = A - sp.Matrix(3, 1, k) * sp.Matrix([[0, 0, sp.Rational(1, 2)]])
    else:
        Acl = A - sp.Matrix([[1], [0], [0]]) * sp.Matrix(1, 3, k)
    eqs = sp.Poly(Acl.charpoly(s).as_expr() - (s + 2) ** 3, s).all_coeffs()
    sol = sp.solve(eqs, k, dict=True)[0]
    return np.array([float(sol[v]) for v in k])


def test_triple_pole_is_accepted_with_the_exact_gain():
    """Issue 12 item 1: (-2, -2, -2) used to be refused (eig of a Jordan block is off by eps^(1/3))."""
    ref = _exact_gain_for_triple_pole(observer=False)
    assert np.allclose(ref, [3.5, 6.5, 4.5])
    r = place_state_feedback(HF_A, HF_B, [-2, -2, -2])
    assert np.allclose(r.gain_matrix.ravel(), ref, rtol=1e-12)
    # the naive test would refuse: the computed eigenvalues miss -2 by ~eps^(1/3)
    assert r.max_pole_error > 1e-6
    acc = r.accuracy
    assert acc["passed"] and acc["multiplicity"] == [3, 3, 3]
    assert "characteristic polynomial" in acc["measure"]
    assert acc["characteristic_polynomial_relative_error"] < 1e-12
    # independent: numpy.poly of the closed loop is (s + 2)^3 = s^3 + 6 s^2 + 12 s + 8
    assert np.allclose(np.poly(HF_A - HF_B @ ref[None, :]), [1, 6, 12, 8], rtol=1e-12)
    o = place_observer(HF_A, HF_C, [-2, -2, -2])
    assert np.allclose(o.gain_matrix.ravel(), _exact_gain_for_triple_pole(observer=True), rtol=1e-10)


def test_wrong_gain_for_a_repeated_pole_is_still_refused():
    from tanksynth.design.placement.exact import placement_accuracy

    K = np.array([[3.5, 6.5, 4.5 + 1e-3]])              # characteristic polynomial off by 1e-3
    acc = placement_accuracy([-2, -2, -2], HF_A - HF_B @ K)
    assert not acc["passed"] and acc["characteristic_polynomial_relative_error"] > 1e-5
    # simple poles keep the plain test
    acc = placement_accuracy([-1, -2, -3], np.diag([-1, -2, -3 + 1e-5]))
    assert not acc["passed"] and acc["measure"].startswith("pole error")


def _nearly_uncontrollable(eps):
    A = np.array([[-1.0, 0.0], [0.0, -2.0]])
    B = np.array([[1.0], [eps]])
    return A, B


def test_nearly_uncontrollable_pair_is_flagged_fragile():
    """Issue 12 item 4: at eps = 1e-10 the placing gain has norm ~1e10 and a tiny change of A
    destabilises the loop; the robustness figure says so (and the adapters refuse it)."""
    import control

    from tanksynth.design.placement.exact import refuse_fragile, robustness_report
    from tanksynth.errors import InfeasibleDesign

    A, B = _nearly_uncontrollable(1e-10)
    K = np.asarray(control.acker(A, B, [-3.0, -4.0]), dtype=float).reshape(1, 2)      # reference gain
    assert np.linalg.norm(K) > 1e9
    rep = robustness_report(A, A - B @ K, K, "continuous")
    assert rep["fragile"] and rep["relative_stability_radius"] < 1e-8
    # independent: a perturbation of A of that relative size destabilises the loop. The
    # smallest destabilising E = -r u v^H from the SVD of (j w I - Acl) at the boundary point.
    w = rep["boundary_point"][1]
    U, s, Vh = np.linalg.svd(1j * w * np.eye(2) - (A - B @ K))
    E = s[-1] * np.outer(U[:, -1], Vh[-1])
    lam = np.linalg.eigvals(A - B @ K + E)
    assert np.min(np.abs(lam.real)) < 1e-6 * np.linalg.norm(A - B @ K, 2)
    assert np.linalg.norm(E, 2) / np.linalg.norm(A, 2) == pytest.approx(
        rep["relative_stability_radius"], rel=1e-6)
    with pytest.raises(InfeasibleDesign, match="allow_fragile"):
        refuse_fragile(rep, "A - B K")
    # a well-conditioned pair is not fragile
    A, B = _nearly_uncontrollable(1.0)
    K = np.asarray(control.acker(A, B, [-3.0, -4.0]), dtype=float).reshape(1, 2)
    assert not robustness_report(A, A - B @ K, K, "continuous")["fragile"]


def test_stability_radius_of_a_normal_matrix_is_the_distance_to_the_boundary():
    from tanksynth.design.placement.exact import stability_radius

    r, _ = stability_radius(np.diag([-0.5, -2.0]), "continuous")
    assert r == pytest.approx(0.5, rel=1e-6)
    r, _ = stability_radius(np.diag([0.9, -0.3]), "discrete")
    assert r == pytest.approx(0.1, rel=1e-6)


def test_stability_radius_of_a_block_diagonal_loop_is_the_smallest_block_radius():
    """Issue 15: a closed loop that is block diagonal up to a permutation is handled block by
    block; the radius is the smallest of the blocks' radii, each computed on its own (dense
    path), and the dense matrix's sigma_min at the returned point agrees."""
    import scipy.linalg as sla

    from tanksynth.design.placement.exact import stability_radius
    rng = np.random.default_rng(4)
    blocks = [rng.normal(size=(k, k)) - 3.0 * np.eye(k) for k in (1, 2, 2, 3)]
    perm = rng.permutation(8)
    A = sla.block_diag(*blocks)[perm][:, perm]
    for domain, scale in (("continuous", 1.0), ("discrete", 0.08)):
        r, z = stability_radius(scale * A, domain)
        each = [stability_radius(scale * b, domain)[0] for b in blocks]
        assert r == pytest.approx(min(each), rel=1e-9)
        s = np.linalg.svd(z * np.eye(8) - scale * A, compute_uv=False)[-1]
        assert s == pytest.approx(r, rel=1e-9)
