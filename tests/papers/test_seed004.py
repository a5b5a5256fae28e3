"""tanksynth.papers.seed004: the printed matrices agree with each other where the paper does."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.papers import seed004 as paper


def test_printed_structure_follows_from_the_printed_A_B_C():
    A, B, C = paper.A, paper.B, paper.C
    pr = paper.printed_matrices(0.0)
    np.testing.assert_allclose(pr["QC"], np.hstack([B, A @ B, A @ A @ B]))
    np.testing.assert_allclose(pr["QO"], np.vstack([C, C @ A, C @ A @ A]))
    np.testing.assert_allclose(pr["den"], np.poly(A))
    np.testing.assert_allclose(np.sort(pr["poles"]), np.sort(np.linalg.eigvals(A).real))
    np.testing.assert_allclose(pr["QO"] @ pr["Delta"], pr["QO_bar"], atol=1e-12)


@pytest.mark.parametrize("delta_bar", [0.3, 1.0])
def test_faulty_matrices(delta_bar):
    A = paper.A.copy()
    A[1, 1] -= delta_bar                                   # the leak of tank 2
    pr = paper.printed_matrices(delta_bar)
    np.testing.assert_allclose(pr["QC"], np.hstack([paper.B, A @ paper.B, A @ A @ paper.B]))
    np.testing.assert_allclose(pr["den"], np.poly(A))
    assert "QO_bar" not in pr and "Delta" not in pr


def test_printed_gamma_d_is_A_minus_psi_times_Co():
    """The erratum recorded in GAMMA_D_NOTE: C_o = [0 0 1] stands where C belongs."""
    np.testing.assert_allclose(paper.GAMMA_D, paper.A - paper.PSI @ np.array([[0.0, 0.0, 1.0]]))
    assert not np.allclose(np.sort(np.linalg.eigvals(paper.GAMMA_D).real),
                           np.sort(paper.OBSERVER_POLES))
    assert "C_o instead of C" in paper.GAMMA_D_NOTE


def test_threshold_terms_match_the_text():
    assert paper.THRESHOLD_TEXT == "78/64 e^{-5t} - 765/64 e^{-8t} + 807/64 e^{-10t}"
    assert [r for _, r in paper.THRESHOLD_TERMS] == list(paper.OBSERVER_POLES)
    # the threshold starts at the largest initial output error C e_hat = 0.5 (4 - 1/4)
    lo, hi = paper.INITIAL_STATE_BOUNDS
    assert sum(c for c, _ in paper.THRESHOLD_TERMS) == pytest.approx(0.5 * (hi - lo))


def test_detection_experiment():
    lo, hi = paper.INITIAL_STATE_BOUNDS
    assert len(paper.INITIAL_STATES) == len(paper.DETECTION_TIMES) == 3
    assert all(lo < v <= hi for x in paper.INITIAL_STATES for v in x)
    assert all(paper.T_FAULT < t < paper.T_FAULT + 0.1 for t in paper.DETECTION_TIMES)
    assert paper.INPUT[0] == (0.0, 2.0) and paper.INPUT[-1][0] < paper.T_FAULT
