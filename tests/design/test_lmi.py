"""Observer LMI (seed 001 eq. 28): feasibility, independent re-check, psi search, structure.

Every feasible result is checked here again, independently of the library's own
re-check, in the spirit of cvxpy's ``SolverTestHelper``: the block matrix of
eq. (28) is rebuilt from the returned ``(P, Q, L)`` and its eigenvalues, ``P > 0``,
``Q > 0`` and the error eigenvalues are asserted.
"""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.design.bisection import bisect_feasible
from tanksynth.design.observer_lmi import lmi as lmi
from tanksynth.design.observer_lmi.lmi import ObserverLMIProblem, check_observer_lmi, maximise_psi, observer_lmi
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
    # trace P sits at kappa n at psi_max: the conditioning bound, not the plant, limits psi
    # (issue 12 item 3); a larger kappa gives a larger psi_max, so the flag is deserved.
    assert s.kappa_active and s.bounded_by_kappa
    assert np.trace(s.result.P) >= 0.999 * s.result.kappa * 3
    assert maximise_psi(A0, C12, variant="qI", kappa=1e6, rtol=1e-3).psi_max > s.psi_max * 1.005
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
        observer_lmi(A0, C12, 0.01, problem=ObserverLMIProblem(3, C12, form="eliminated"))
    # the direct Clarabel route (the default here) gets the same check
    from tanksynth.design.observer_lmi.conic_form import ConicEliminatedLMI

    real_conic = ConicEliminatedLMI.solve

    def tampered_conic(self, A0_, psi, omega=None, **kw):
        out = real_conic(self, A0_, psi, omega, **kw)
        out["K"] = -out["K"]
        return out

    monkeypatch.setattr(ConicEliminatedLMI, "solve", tampered_conic)
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


@pytest.mark.parametrize("form", ["eliminated", "full"])
def test_problem_is_compiled_once_for_many_psi(form):
    prob = ObserverLMIProblem(3, C12, form=form, A0_pattern=A0 != 0)
    assert prob.problem.is_dpp()
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


# ---------------------------------------------------------------- LMI forms
def test_eliminated_and_full_forms_have_the_same_optimum():
    """Projection lemma: eliminating K changes neither the optimal margin nor psi_max."""
    prob_f = ObserverLMIProblem(3, C12, form="full")
    prob_e = ObserverLMIProblem(3, C12, form="eliminated")
    for psi in (0.0, 0.03, 0.05):
        tf, te = prob_f.solve(A0, psi)["t"], prob_e.solve(A0, psi)["t"]
        assert te == pytest.approx(tf, abs=1e-6) and te == pytest.approx(1.0, abs=1e-6)
    # beyond psi_max: the same sign; elimination is never the more conservative (with K
    # unbounded the full form approaches its supremum only as K grows)
    tf, te = prob_f.solve(A0, 0.06)["t"], prob_e.solve(A0, 0.06)["t"]
    assert tf < 0 and te < 0 and te >= tf - 1e-6 and te == pytest.approx(tf, rel=1e-2)
    for variant in ("qI", "full"):
        f = maximise_psi(A0, C12, variant=variant, kappa=1e2, rtol=1e-4, form="full")
        e = maximise_psi(A0, C12, variant=variant, kappa=1e2, rtol=1e-4, form="eliminated")
        assert e.psi_max == pytest.approx(f.psi_max, rel=2e-4)
        assert_lmi_solution(e.result, A0, C12)
        assert e.result.structure["form"] == "eliminated"
        assert f.result.structure["form"] == "full"


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_recovered_gain_meets_the_margin_it_was_built_for(seed):
    """The closed-form K gives LMI (28) <= -t_K I with t_K >= the required margin."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 8))
    A = rng.standard_normal((n, n))
    C = rng.standard_normal((int(rng.integers(1, n)), n))
    s = maximise_psi(A, C, rtol=1e-3, form="eliminated")
    res = s.result
    assert_lmi_solution(res, A, C)
    t_K = res.structure["gain_margin"]
    assert res.margin <= t_K <= res.structure["eliminated_lmi_margin"]
    assert np.max(res.lmi_eigenvalues) <= -t_K * (1 - 1e-6)
    full = maximise_psi(A, C, rtol=1e-3, form="full")
    assert s.psi_max == pytest.approx(full.psi_max, rel=3e-3)


def test_every_state_measured_reduces_the_lmi():
    """rank C = n: the eliminated LMI is Q >= t I; the design is still re-checked in full."""
    A, _, _, _ = _network()
    C = np.eye(8)
    prob = ObserverLMIProblem(8, C)
    assert prob.form == "eliminated" and prob.V2.shape == (8, 0)
    res = observer_lmi(A, C, 0.1, problem=prob)
    assert_lmi_solution(res, A, C)
    assert res.structure["K"].startswith("eliminated")


def test_auto_form_keeps_k_as_a_variable_for_a_gain_pattern():
    A, C, blocks, pattern = _network()
    assert ObserverLMIProblem(8, C).form == "eliminated"
    assert ObserverLMIProblem(8, C, blocks=blocks).form == "eliminated"
    assert ObserverLMIProblem(8, C, blocks=blocks, pattern=pattern).form == "full"
    with pytest.raises(SpecError, match="free gain"):
        ObserverLMIProblem(8, C, blocks=blocks, pattern=pattern, form="eliminated")
    with pytest.raises(SpecError, match="form"):
        ObserverLMIProblem(8, C, form="projected")


def test_block_diagonal_p_with_mixed_block_sizes():
    A, C, _, _ = _network()
    blocks = [[0, 1, 2], [3], [4, 5], [6], [7]]
    res = observer_lmi(A, C, 0.01, blocks=blocks)
    assert_lmi_solution(res, A, C)
    inside = np.zeros((8, 8), dtype=bool)
    for b in blocks:
        inside[np.ix_(b, b)] = True
    assert np.all(res.P[~inside] == 0)
    for b in blocks:                                 # normalisation P >= I per block
        assert np.min(np.linalg.eigvalsh(res.P[np.ix_(b, b)])) >= 1 - 1e-6


# ---------------------------------------------------------- A0 sparsity
@pytest.mark.parametrize("form", ["full", "eliminated"])
def test_a0_pattern_parameter(form):
    """A Parameter over the non-zeros of A0 gives the same optimum; A0 outside it is refused."""
    A, C, blocks, pattern = _network()
    struct = {"blocks": blocks, "pattern": pattern} if form == "full" else {}
    dense = ObserverLMIProblem(8, C, form=form, **struct)
    sparse = ObserverLMIProblem(8, C, form=form, A0_pattern=A != 0, **struct)
    for psi in (0.0, 0.05):
        assert sparse.solve(A, psi)["t"] == pytest.approx(dense.solve(A, psi)["t"], abs=1e-6)
    B = A.copy()
    B[0, 7] = 0.3                                    # outside the pattern
    with pytest.raises(DimensionError, match="outside the A0_pattern"):
        sparse.solve(B, 0.0)
    res = observer_lmi(A, C, 0.01, **struct)         # builds A0_pattern = A0 != 0 itself
    assert "sparse" in res.structure["A0_parameter"] if form == "full" else \
        "rebuilt for Clarabel" in res.structure["A0_parameter"]        # direct route, no Parameter
    with pytest.raises(DimensionError, match="A0_pattern"):
        ObserverLMIProblem(8, C, A0_pattern=np.ones((3, 3)))


# ------------------------------------------------------- observability test
def test_observability_test_is_skipped_when_c_has_full_column_rank(monkeypatch):
    def boom(*args, **kwargs):
        raise AssertionError("Kalman observability test run although rank C = n")

    monkeypatch.setattr(lmi._rank, "observability_rank", boom)
    A, _, _, _ = _network()
    assert_lmi_solution(observer_lmi(A, np.eye(8), 0.01), A, np.eye(8))
    with pytest.raises(AssertionError, match="Kalman"):
        observer_lmi(A0, C12, 0.01)                   # rank C < n: the test runs


# ------------------------------------------------------------ solver options
def test_solver_options_apply_per_solve_and_do_not_stick():
    prob = ObserverLMIProblem(3, C12, form="full")
    loose = {"tol_gap_abs": 1e-3, "tol_gap_rel": 1e-3, "tol_feas": 1e-3, "tol_ktratio": 1e-2}
    iters = []
    for opts in (None, loose, None):
        prob.solve(A0, 0.03, solver_options=opts)
        iters.append(prob.problem.solver_stats.num_iters)
    assert iters[1] < iters[0] and iters[2] == iters[0]
    assert prob._options(None) == {k: pytest.approx(v) for k, v in {
        "tol_gap_abs": 1e-8, "tol_gap_rel": 1e-8, "tol_feas": 1e-8, "tol_ktratio": 1e-6}.items()}
    res = observer_lmi(A0, C12, 0.03, solver_options=loose)
    assert_lmi_solution(res, A0, C12)


def test_maximise_psi_returns_a_checked_design_without_solving_again():
    prob = ObserverLMIProblem(3, C12)
    calls = []
    real = prob.solve

    def counted(*args, **kwargs):
        calls.append(args[1])
        return real(*args, **kwargs)

    prob.solve = counted
    s = maximise_psi(A0, C12, problem=prob, rtol=1e-3)
    assert len(calls) == len(s.history) + 1            # psi = 0, then every trial
    assert s.result.psi == s.psi_max and all(c.passed for c in s.result.checks)


def test_observer_lmi_relaxes_an_active_kappa_bound():
    """Issue 12 item 3 (ts_observer): psi just above psi_max(kappa = 1e4) is refused because
    trace P <= kappa n is active, not because no observer exists; relaxing kappa finds one."""
    psi = 0.0572                      # psi_max is 0.0570 at kappa = 1e4 and 0.0575 at 1e6
    with pytest.raises(InfeasibleDesign, match=r"bound trace P <= kappa n is active.*kappa_max"):
        observer_lmi(A0, C12, psi, variant="qI", kappa=1e4)
    res = observer_lmi(A0, C12, psi, variant="qI", kappa=1e4, kappa_max=1e6)
    assert_lmi_solution(res, A0, C12)
    tries = res.scaling["kappa_tries"]
    assert tries[0]["kappa"] == 1e4 and tries[0]["bound_active"] and res.kappa > 1e4
    # independent: the error dynamics decay faster than psi
    assert np.max(np.linalg.eigvals(A0 - res.L @ C12).real) < -psi
