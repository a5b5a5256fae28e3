"""Observer LMI (seed 001 eq. 28): feasibility, independent re-check, psi search, structure.

Every feasible result is checked here again, independently of the library's own
re-check, in the spirit of cvxpy's ``SolverTestHelper``: the block matrix of
eq. (28) is rebuilt from the returned ``(P, Q, L)`` and its eigenvalues, ``P > 0``,
``Q > 0`` and the error eigenvalues are asserted.
"""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.design import lmi
from tanksynth.design.lmi import (ObserverLMIProblem, bisect_feasible, check_observer_lmi,
                                  maximise_psi, observer_lmi)
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError, UnobservableError

# A0 of the seed 001 TS model (paper weights, levels in [0.05, 0.62] m, all flow directions)
A0 = np.array([[0.0023673, -0.01690926, -0.05749147],
               [0.0, -0.01588282, 0.00402392],
               [-0.0023673, 0.00483751, 0.05346756]])
C12 = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def assert_lmi_solution(res, A0, C, tol=0.0):
    """SolverTestHelper-like primal feasibility check of an observer LMI result."""
    P, Q, L = res.P, res.Q, res.L
    np.testing.assert_allclose(P, P.T, atol=1e-12 * np.abs(P).max())
    K = P @ L
    X = A0.T @ P + P @ A0 - C.T @ K.T - K @ C + res.psi ** 2 * Q
    M = np.block([[X, P], [P, -Q]])
    assert np.max(np.linalg.eigvalsh(0.5 * (M + M.T))) < tol
    assert np.min(np.linalg.eigvalsh(P)) > 0
    assert np.min(np.linalg.eigvalsh(0.5 * (Q + Q.T))) > 0
    assert np.max(np.linalg.eigvals(A0 - L @ C).real) < -res.psi
    assert all(c.passed for c in res.checks)
    if res.variant == "qI":
        np.testing.assert_allclose(Q, Q[0, 0] * np.eye(len(Q)), atol=1e-12 * abs(Q[0, 0]))


@pytest.mark.parametrize("variant", ["qI", "full"])
def test_feasible_design_passes_independent_check(variant):
    res = observer_lmi(A0, C12, 0.03, variant=variant)
    assert_lmi_solution(res, A0, C12)
    assert res.solver == "CLARABEL" and res.status == "optimal"
    assert res.achieved_margin >= res.margin
    d = res.as_dict()
    assert d["variant"] == variant and d["lmi_max_eigenvalue"] < 0
    assert d["scaling"]["omega_per_s"] == pytest.approx(np.linalg.norm(A0, 2))
    assert "Q = q I" in d["Q_form"] if variant == "qI" else "full Q" in d["Q_form"]


def test_scs_gives_a_checked_solution_too():
    res = observer_lmi(A0, C12, 0.03, solver="SCS")
    assert_lmi_solution(res, A0, C12)
    assert res.solver == "SCS"


def test_safe_variant_refuses_the_paper_psi():
    """psi = 0.506 is feasible only with the full Q (not justified by the Euclidean bound)."""
    res = observer_lmi(A0, C12, 0.506, variant="full")
    assert_lmi_solution(res, A0, C12)
    with pytest.raises(InfeasibleDesign, match=r"achieved margin t = .* \(required 1e-06\).*qI"):
        observer_lmi(A0, C12, 0.506, variant="qI")


def test_maximise_psi_brackets_the_boundary():
    s = maximise_psi(A0, C12, variant="qI", rtol=1e-3)
    assert 0.04 < s.psi_max < 0.08
    assert s.psi_infeasible <= s.psi_max * 1.002
    assert_lmi_solution(s.result, A0, C12)
    with pytest.raises(InfeasibleDesign):
        observer_lmi(A0, C12, s.psi_infeasible * 1.01, variant="qI")
    assert not s.bounded_by_kappa
    trials = s.as_dict()["trials"]
    assert trials and all(isinstance(ok, bool) for _, ok in trials)


def test_full_variant_grows_with_the_conditioning_bound():
    """With (A0, C) observable, the full-Q LMI accepts any psi given enough conditioning."""
    small = maximise_psi(A0, C12, variant="full", kappa=1e2, rtol=1e-2).psi_max
    large = maximise_psi(A0, C12, variant="full", kappa=1e4, rtol=1e-2).psi_max
    assert large > 3 * small
    assert maximise_psi(A0, C12, variant="full", kappa=1e2, rtol=1e-2).bounded_by_kappa


def test_time_scaling_is_exact():
    """psi_max scales with A0 (the LMI is homogeneous in time)."""
    a = maximise_psi(A0, C12, rtol=1e-4).psi_max
    b = maximise_psi(100.0 * A0, C12, rtol=1e-4).psi_max
    assert b == pytest.approx(100.0 * a, rel=2e-3)


def test_output_scaling_does_not_change_the_gain_map():
    res1 = observer_lmi(A0, C12, 0.03)
    res2 = observer_lmi(A0, 10.0 * C12, 0.03)
    assert_lmi_solution(res2, A0, 10.0 * C12)
    assert res2.scaling["output_row_scale"] == pytest.approx([0.1, 0.1])
    # L C is what matters: the error dynamics must be stable either way
    assert np.max(np.linalg.eigvals(A0 - res1.L @ C12).real) < 0


def test_unobservable_pair_is_refused_before_solving():
    A = np.diag([-1.0, -2.0, -3.0])
    C = np.array([[1.0, 0.0, 0.0]])
    with pytest.raises(UnobservableError, match=r"unobservable modes: .*x2.*x3|x3.*x2"):
        observer_lmi(A, C, 0.1)


@pytest.mark.parametrize("A,C,err", [
    (np.ones((3, 2)), C12, DimensionError),
    (A0, np.ones((2, 4)), DimensionError),
    (np.full((3, 3), np.nan), C12, DimensionError),
    (A0, np.array([[1.0, 0, 0], [0, 0, 0]]), DimensionError),
])
def test_bad_shapes(A, C, err):
    with pytest.raises(err):
        observer_lmi(A, C, 0.01)


def test_bad_options():
    with pytest.raises(SpecError, match="variant"):
        observer_lmi(A0, C12, 0.01, variant="diag")
    with pytest.raises(SpecError, match="margin"):
        observer_lmi(A0, C12, 0.01, margin=0.0)
    with pytest.raises(SpecError, match="solver"):
        observer_lmi(A0, C12, 0.01, solver="MOSEK")
    with pytest.raises(SpecError, match="psi"):
        observer_lmi(A0, C12, -1.0)
    with pytest.raises(SpecError, match="kappa"):
        ObserverLMIProblem(3, C12, kappa=0.5)


def test_recheck_refuses_a_solution_the_solver_called_optimal(monkeypatch):
    """Never trust a status: a tampered 'optimal' solution is refused by the numpy check."""
    real = ObserverLMIProblem.solve

    def tampered(self, A0_, psi, omega=None):
        out = real(self, A0_, psi, omega)
        out["K"] = -out["K"]                         # destroys the gain, status still 'optimal'
        return out

    monkeypatch.setattr(ObserverLMIProblem, "solve", tampered)
    with pytest.raises(InfeasibleDesign, match="independent re-check.*status optimal"):
        observer_lmi(A0, C12, 0.01)


def test_check_function_flags_each_failure():
    res = observer_lmi(A0, C12, 0.01)
    omega = res.scaling["omega_per_s"]
    checks, eig, err = check_observer_lmi(A0, C12, 0.01, -res.P, res.Q, res.K, 1e-6, omega)
    names = {c.name.split(" (")[0]: c.passed for c in checks}
    assert not names["P > 0"]
    checks, *_ = check_observer_lmi(A0, C12, 10.0, res.P, res.Q, res.K, 1e-6, omega)
    assert not all(c.passed for c in checks)


def _network(n=8, seed=0):
    rng = np.random.default_rng(seed)
    A = -np.eye(n) + 0.1 * rng.standard_normal((n, n))
    A[: n // 2, n // 2:] = 0.0
    A[n // 2:, : n // 2] *= 0.2
    C = np.eye(n)[::2]
    blocks = [list(range(n // 2)), list(range(n // 2, n))]
    pattern = np.zeros((n, C.shape[0]))
    pattern[: n // 2, : C.shape[0] // 2] = 1
    pattern[n // 2:, C.shape[0] // 2:] = 1
    return A, C, blocks, pattern


def test_structured_design_respects_blocks_and_pattern():
    A, C, blocks, pattern = _network()
    dense = maximise_psi(A, C, rtol=1e-2)
    struct = maximise_psi(A, C, blocks=blocks, pattern=pattern, rtol=1e-2)
    res = struct.result
    assert_lmi_solution(res, A, C)
    assert np.all(res.P[np.ix_(blocks[0], blocks[1])] == 0)
    assert np.all(res.L[pattern == 0] == 0)
    assert res.structure["P"] == "block-diagonal"
    assert struct.psi_max <= dense.psi_max * (1 + 1e-2)     # structure is more conservative


def test_structure_validation():
    A, C, blocks, pattern = _network()
    with pytest.raises(DimensionError, match="partition"):
        observer_lmi(A, C, 0.01, blocks=[[0, 1], [2, 3]])
    with pytest.raises(DimensionError, match="needs a block partition"):
        observer_lmi(A, C, 0.01, pattern=pattern)
    bad = pattern.copy()
    bad[0, :] = 1
    with pytest.raises(DimensionError, match="differ inside block"):
        observer_lmi(A, C, 0.01, blocks=blocks, pattern=bad)
    with pytest.raises(DimensionError, match="0/1"):
        observer_lmi(A, C, 0.01, blocks=blocks, pattern=2 * pattern)


def test_problem_is_compiled_once_for_many_psi():
    prob = ObserverLMIProblem(3, C12)
    first = prob.problem
    t = [prob.solve(A0, psi)["t"] for psi in (0.0, 0.01, 0.02, 1.0)]
    assert prob.problem is first
    assert t[0] >= t[1] - 1e-8 and t[1] >= t[2] - 1e-8     # margin capped at 1
    assert t[2] > 0 > t[3]


def test_bisect_feasible_on_a_known_predicate():
    lo, hi, hist = bisect_feasible(lambda x: x <= 3.7, start=0.1, rtol=1e-6)
    assert lo <= 3.7 < hi and hi - lo <= 1e-6 * hi
    lo, hi, _ = bisect_feasible(lambda x: True, start=1.0, max_doublings=5)
    assert hi == float("inf") and lo == 16.0


def test_module_exports():
    for name in lmi.__all__:
        assert hasattr(lmi, name)
