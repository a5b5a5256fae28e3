"""The compiled observer LMI: with C of full column rank no cone is built for P."""

import numpy as np
import pytest

from tanksynth.design.observer_lmi.problem import ObserverLMIProblem


def _eq28(A0, C, P, Q, L, psi):
    """Block matrix of seed 001 eq. (28), rebuilt here in numpy (K = P L)."""
    K = P @ L
    X = A0.T @ P + P @ A0 - C.T @ K.T - K @ C + psi ** 2 * Q
    M = np.block([[X, P], [P, -Q]])
    return 0.5 * (M + M.T)


@pytest.mark.parametrize("variant", ["qI", "full"])
def test_identity_output_drops_the_P_cone_and_the_gain_still_satisfies_eq28(variant):
    rng = np.random.default_rng(1)
    n = 6
    A0 = -np.diag(rng.uniform(0.5, 2.0, n)) + 0.3 * np.diag(rng.uniform(0, 1, n - 1), 1)
    prob = ObserverLMIProblem(n, np.eye(n), variant=variant)
    assert prob.fixed_P and prob.P is None
    # no n x n PSD cone for P: only Q's (variant "full") or none (variant "qI")
    psd = [c for c in prob.problem.constraints if c.__class__.__name__ == "PSD"]
    assert len(psd) == (1 if variant == "full" else 0)
    out = prob.solve(A0, psi=0.1)
    assert out["t"] > 0
    np.testing.assert_array_equal(out["P"], np.eye(n))
    lam = np.linalg.eigvalsh(_eq28(A0, np.eye(n), out["P"], out["Q"], out["L"], 0.1))
    assert lam.max() < 0                         # eq. (28) holds for the returned gain
    assert np.all(np.linalg.eigvals(A0 - out["L"]).real < 0)


def test_partial_output_keeps_P_as_a_variable():
    n = 4
    C = np.eye(n)[:2]
    prob = ObserverLMIProblem(n, C)
    assert not prob.fixed_P and prob.P is not None
