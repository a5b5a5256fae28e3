"""The verdicts' own numerics (`tanksynth.verify.numerics`), on cases worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tanksynth.analysis.lmi_region import disk, half_plane, intersect
from tanksynth.errors import DimensionError
from tanksynth.verify.numerics import (integral_augmentation, match_poles, observer_lmi_recheck,
                                       region_lmi_matrix)


# ----------------------------------------------------------------------------- poles
def test_eigenvalues_of_a_companion_matrix_match_a_permuted_list():
    A = np.array([[0.0, 1.0], [-2.0, -3.0]])          # s^2 + 3 s + 2: eigenvalues -1, -2
    m = match_poles([-2.0, -1.0], np.linalg.eigvals(A))
    np.testing.assert_allclose(m.achieved, [-2.0, -1.0], atol=1e-12)
    assert m.max_error < 1e-12 and m.max_relative_error < 1e-12


def test_complex_pair_matches_its_conjugate_order():
    A = np.array([[-1.0, 2.0], [-2.0, -1.0]])          # eigenvalues -1 +- 2j
    m = match_poles([-1 - 2j, -1 + 2j], np.linalg.eigvals(A))
    np.testing.assert_allclose(m.achieved, [-1 - 2j, -1 + 2j], atol=1e-12)
    assert m.max_error < 1e-12


def test_error_is_relative_to_max_one_and_the_pole():
    m = match_poles([-1.0, -2.5], [-2.0, -1.0])
    np.testing.assert_allclose(m.errors, [0.0, 0.5])
    np.testing.assert_allclose(m.relative_errors, [0.0, 0.5 / 2.5])
    assert m.max_error == pytest.approx(0.5) and m.max_relative_error == pytest.approx(0.2)
    small = match_poles([0.1], [0.3])                 # |p| < 1: relative to 1
    assert small.max_relative_error == pytest.approx(0.2)


def test_matching_is_optimal_not_greedy():
    # Greedy in the requested order pairs 0.5 -> 0.4 and then 0 -> 1.0 (error 1.0); the optimal
    # one-to-one matching pairs 0.5 -> 1.0 and 0 -> 0.4 (total 0.9 < 1.1, largest error 0.5).
    m = match_poles([0.5, 0.0], [0.4, 1.0])
    np.testing.assert_allclose(m.achieved, [1.0, 0.4])
    assert m.max_error == pytest.approx(0.5)


def test_repeated_pole_is_not_matched_twice():
    m = match_poles([-1.0, -1.0], [-1.0, -3.0])
    assert sorted(m.achieved.real) == [-3.0, -1.0] and m.max_error == pytest.approx(2.0)


def test_pole_lists_of_different_length_are_refused():
    with pytest.raises(DimensionError):
        match_poles([-1.0, -2.0], [-1.0])


# ------------------------------------------------------------------------ region LMI
def test_half_plane_lmi_of_a_stable_and_an_unstable_matrix():
    region = half_plane(0.5)                           # L = [1], M = [1]: X + A X + X A'
    stable = region_lmi_matrix(region.L, region.M, np.diag([-1.0, -2.0]), np.eye(2))
    np.testing.assert_allclose(stable, np.diag([-1.0, -3.0]))   # 1 - 2, 1 - 4
    assert np.max(np.linalg.eigvalsh(stable)) < 0
    unstable = region_lmi_matrix(region.L, region.M, np.diag([1.0, -2.0]), np.eye(2))
    np.testing.assert_allclose(unstable, np.diag([3.0, -3.0]))  # 1 + 2: not negative definite
    assert np.max(np.linalg.eigvalsh(unstable)) > 0


def test_unit_disk_lmi_by_hand():
    region = disk(0.0, 1.0)                            # [[-X, A X], [X A', -X]]
    inside = region_lmi_matrix(region.L, region.M, 0.5 * np.eye(2), np.eye(2))
    np.testing.assert_allclose(np.linalg.eigvalsh(inside), [-1.5, -1.5, -0.5, -0.5])
    outside = region_lmi_matrix(region.L, region.M, 2.0 * np.eye(2), np.eye(2))
    np.testing.assert_allclose(np.linalg.eigvalsh(outside), [-3.0, -3.0, 1.0, 1.0])


def test_region_lmi_is_the_kronecker_form_for_a_non_normal_matrix():
    rng = np.random.default_rng(0)
    region = intersect(half_plane(0.1), disk(-1.0, 2.0))
    A = np.array([[-1.0, 5.0, 0.0], [0.0, -1.5, 2.0], [0.3, 0.0, -0.7]])
    G = rng.normal(size=(3, 3))
    X = G @ G.T + np.eye(3)
    AX = A @ X
    kron = np.kron(region.L, X) + np.kron(region.M, AX) + np.kron(region.M.T, AX.T)
    np.testing.assert_allclose(region_lmi_matrix(region.L, region.M, A, X), kron, atol=1e-12)


# ---------------------------------------------------------------------- observer LMI
def test_observer_lmi_scalar_case_by_hand():
    # A0 = -1, C = 1, L = 1: G = -2; P = Q = 1, psi = 1: W = [[-4 + 1, 1], [1, -1]],
    # eigenvalues -2 +- sqrt(2); G = -2 < -psi.
    rc = observer_lmi_recheck([[-1.0]], [[1.0]], [[1.0]], [[1.0]], [[1.0]], 1.0, margin=1e-6,
                              omega=1.0)
    np.testing.assert_allclose(np.sort(rc.lmi_eigenvalues), [-2 - math.sqrt(2), -2 + math.sqrt(2)])
    assert rc.passed and all(item.passed for item in rc.items)
    np.testing.assert_allclose(rc.error_eigenvalues, [-2.0])


def test_observer_lmi_normalisation_by_hand():
    # G = -1.5, psi = 1: G'P + P G + psi^2 Q = -2; omega = 4: [[-2/4, 1], [1, -4]]
    rc = observer_lmi_recheck([[-1.0]], [[1.0]], [[0.5]], [[1.0]], [[1.0]], 1.0, margin=1e-6,
                              omega=4.0)
    trace, det = -4.5, 2.0 - 1.0
    assert max(rc.lmi_eigenvalues) == pytest.approx((trace + math.sqrt(trace ** 2 - 4 * det)) / 2)
    assert rc.passed


def test_observer_lmi_fails_for_a_destabilising_gain():
    rc = observer_lmi_recheck([[-1.0]], [[1.0]], [[-3.0]], [[1.0]], [[1.0]], 1.0, margin=1e-6,
                              omega=1.0)                 # G = 2: G'P + P G + 1 = 5 > 0
    assert not rc.passed
    failed = {item.name for item in rc.items if not item.passed}
    assert any("block matrix" in name for name in failed) and any("psi" in name for name in failed)


def test_observer_lmi_refuses_mismatched_shapes():
    with pytest.raises(DimensionError):
        observer_lmi_recheck(np.eye(2), [[1.0, 0.0]], [[1.0]], np.eye(2), np.eye(2), 1.0,
                             margin=1e-6, omega=1.0)


# ---------------------------------------------------------------- integral augmentation
def test_integral_augmentation_by_hand():
    Aa, Ba = integral_augmentation([[-1.0]], [[2.0]], [[1.0]])
    np.testing.assert_array_equal(Aa, [[-1.0, 0.0], [-1.0, 0.0]])
    np.testing.assert_array_equal(Ba, [[2.0], [0.0]])
    Ad, Bd = integral_augmentation([[0.9]], [[0.1]], [[1.0]], ts=0.5)
    np.testing.assert_array_equal(Ad, [[0.9, 0.0], [-0.5, 1.0]])
    np.testing.assert_array_equal(Bd, [[0.1], [0.0]])


def test_integral_closed_loop_poles_by_hand():
    # A = -1, B = 1: det(sI - (Aa - Ba K)) = s (s + 1 + k1) - k2; poles -1, -2 <=> k1 = 2, k2 = -2
    Aa, Ba = integral_augmentation([[-1.0]], [[1.0]], [[1.0]])
    K = np.array([[2.0, -2.0]])
    m = match_poles([-1.0, -2.0], np.linalg.eigvals(Aa - Ba @ K))
    assert m.max_error < 1e-12


# ---------------------------------------------------- issue 12: repeated poles in the verdicts
def test_pole_agreement_accepts_a_jordan_block_with_the_right_polynomial():
    from tanksynth.verify.numerics import pole_agreement

    # A - B K of seed 004's cascade with K = [7/2, 13/2, 9/2]: (s + 2)^3, one Jordan block
    M = np.array([[-4.0, -6.5, -4.5], [0.5, -1.5, 0.0], [0.0, 1.5, -0.5]])
    assert np.allclose(np.poly(M), [1, 6, 12, 8])
    naive = match_poles([-2, -2, -2], np.linalg.eigvals(M))
    assert naive.max_relative_error > 1e-6               # the old test refused it
    ag = pole_agreement([-2, -2, -2], M)
    assert ag.passed and list(ag.multiplicity) == [3, 3, 3] and ag.polynomial_error < 1e-12
    # a wrong gain: the polynomial is off, refused although the poles are within 1e-2
    M2 = M.copy()
    M2[0, 2] -= 1e-4
    assert not pole_agreement([-2, -2, -2], M2).passed
    # simple poles: unchanged
    assert pole_agreement([-1, -2, -3], np.diag([-1.0, -2.0, -3.0])).passed
    assert not pole_agreement([-1, -2, -3], np.diag([-1.0, -2.0, -3.0 + 1e-5])).passed
