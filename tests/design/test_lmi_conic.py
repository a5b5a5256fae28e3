"""Observer LMI (28), full form, built straight into Clarabel's conic form (issue 15).

The reference is the same scaled LMI written here by hand in cvxpy (not the
library's `ObserverLMIProblem`): same optimum ``t``; every design that
`observer_lmi` returns through this route is re-checked here in numpy.
"""

from __future__ import annotations

import warnings

import cvxpy as cp
import numpy as np
import pytest

from tanksynth.design.observer_lmi.lmi import observer_lmi
from tanksynth.design.observer_lmi.conic_form import ConicObserverLMI
from tanksynth.errors import InfeasibleDesign, SpecError


def hand_cvxpy(A0, C, psi, variant, kappa, blocks, mask):
    """The scaled problem of seed 001 eq. (28) in cvxpy, written from the docstring."""
    n, q = C.shape[1], C.shape[0]
    w = np.linalg.norm(A0, 2)
    As, t2 = A0 / w, (psi / w) ** 2
    Cs = C / np.linalg.norm(C, axis=1)[:, None]
    blocks = blocks or [list(range(n))]
    Pb = [cp.Variable((len(b), len(b)), symmetric=True) for b in blocks]
    E = [np.eye(n)[:, b] for b in blocks]
    P = sum(Ei @ Pi @ Ei.T for Ei, Pi in zip(E, Pb))
    if variant == "qI":
        qv = cp.Variable()
        Q = qv * np.eye(n)
    else:
        Qb = [cp.Variable((len(b), len(b)), symmetric=True) for b in blocks]
        Q = sum(Ei @ Qi @ Ei.T for Ei, Qi in zip(E, Qb))
    if mask is None:
        K = cp.Variable((n, q))
    else:
        Kf = cp.Variable((n, q))
        K = cp.multiply(mask.astype(float), Kf)
    t = cp.Variable()
    X = As.T @ P + P @ As - Cs.T @ K.T - K @ Cs + t2 * Q
    M = cp.bmat([[X, P], [P, -Q]])
    cons = [0.5 * (M + M.T) << -t * np.eye(2 * n), cp.trace(P) <= kappa * n, t <= 1]
    cons += [Pi >> np.eye(Pi.shape[0]) for Pi in Pb]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)            # "may be inaccurate" (t < 0)
        cp.Problem(cp.Maximize(t), cons).solve(solver="CLARABEL")
    return float(t.value)


def eq28_holds(res, A0, C):
    P, Q, L = res.P, res.Q, res.L
    K = P @ L
    X = A0.T @ P + P @ A0 - C.T @ K.T - K @ C + res.psi ** 2 * Q
    M = np.block([[X, P], [P, -Q]])
    return (np.linalg.eigvalsh(0.5 * (M + M.T)).max() < 0
            and np.linalg.eigvals(A0 - L @ C).real.max() < -res.psi)


def _plant(seed=4, n=6):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) - 2 * np.eye(n)
    C = np.eye(n)[[0, 2, 4]] + 0.1 * rng.standard_normal((3, n))
    C2 = np.eye(n)[[0, 3]]
    mask = np.zeros((n, 2), dtype=bool)
    mask[:3, 0] = mask[3:, 1] = True
    return A, C, C2, mask


CASES = {
    "mixed blocks, free K": ("C", [[0, 1], [2, 3, 4], [5]], None),
    "dense P, free K": ("C", None, None),
    "two blocks, decentralised gain": ("C2", [[0, 1, 2], [3, 4, 5]], "mask"),
}


@pytest.mark.parametrize("variant", ["qI", "full"])
@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("psi", [0.3, 3.0])
def test_same_optimum_as_a_hand_written_cvxpy_problem(case, variant, psi):
    A, C, C2, mask = _plant()
    which, blocks, pat = CASES[case]
    Cm = C if which == "C" else C2
    m = mask if pat else None
    out = ConicObserverLMI(6, Cm, variant, 100.0, blocks, m).solve(A, psi)
    ref = hand_cvxpy(A, Cm, psi, variant, 100.0, blocks, m)
    if ref > 0:
        assert out["status"] == "optimal"
        assert out["t"] == pytest.approx(ref, abs=1e-6)
    else:      # infeasible (t < 0), solved by both to the solver's reduced accuracy only
        assert out["status"] in ("optimal", "optimal_inaccurate")
        assert out["t"] < 0 and ref < 0 and out["t"] == pytest.approx(ref, abs=1e-4)
    if blocks is not None:                     # the structure is exact, not approximate
        inside = np.zeros((6, 6), dtype=bool)
        for b in blocks:
            inside[np.ix_(b, b)] = True
        assert np.all(out["P"][~inside] == 0)
    if m is not None:
        assert np.all(out["L"][~m] == 0)


def test_observer_lmi_with_a_gain_pattern_takes_the_conic_route_and_is_rechecked():
    A, _, C2, mask = _plant()
    blocks = [[0, 1, 2], [3, 4, 5]]
    res = observer_lmi(A, C2, 0.05, blocks=blocks, pattern=mask.astype(float))
    assert "conic data built directly" in res.structure["A0_parameter"]
    assert res.structure["form"] == "full" and all(c.passed for c in res.checks)
    assert eq28_holds(res, A, C2)
    assert np.all(res.L[~mask] == 0)


def test_a_tampered_solution_is_refused(monkeypatch):
    A, _, C2, mask = _plant()
    real = ConicObserverLMI.solve

    def tampered(self, *args, **kwargs):
        out = real(self, *args, **kwargs)
        out["L"] = -out["L"]
        out["K"] = -out["K"]                           # status still 'optimal'
        return out

    monkeypatch.setattr(ConicObserverLMI, "solve", tampered)
    with pytest.raises(InfeasibleDesign, match="independent re-check"):
        observer_lmi(A, C2, 0.05, blocks=[[0, 1, 2], [3, 4, 5]], pattern=mask.astype(float))


def test_solver_limit_and_bad_setting():
    A, C, _, _ = _plant()
    out = ConicObserverLMI(6, C).solve(A, 0.3, solver_options={"max_iter": 1})
    assert out["status"] == "user_limit" and out["t"] == -np.inf
    with pytest.raises(InfeasibleDesign, match="status user_limit"):
        observer_lmi(A, C, 0.3, form="full", solver_options={"max_iter": 1})
    with pytest.raises(SpecError, match="no_such_setting"):
        ConicObserverLMI(6, C).solve(A, 0.3, solver_options={"no_such_setting": 1})


def test_kappa_retry_on_the_conic_route():
    """Issue 12 item 3 through the full form: an active kappa bound is relaxed up to kappa_max."""
    A0 = np.array([[0.0023673, -0.01690926, -0.05749147],
                   [0.0, -0.01588282, 0.00402392],
                   [-0.0023673, 0.00483751, 0.05346756]])
    C12 = np.eye(3)[:2]
    psi = 0.0572
    with pytest.raises(InfeasibleDesign, match="kappa_max"):
        observer_lmi(A0, C12, psi, form="full", kappa=1e4)
    res = observer_lmi(A0, C12, psi, form="full", kappa=1e4, kappa_max=1e6)
    assert res.kappa > 1e4 and res.scaling["kappa_tries"][0]["bound_active"]
    assert eq28_holds(res, A0, C12)


# ----------------------------------------------------- eliminated form (ConicEliminatedLMI)
@pytest.mark.parametrize("variant", ["qI", "full"])
@pytest.mark.parametrize("case", ["mixed blocks, free K", "dense P, free K"])
@pytest.mark.parametrize("psi", [0.3, 3.0])
def test_eliminated_form_reaches_the_hand_written_full_lmi_optimum(case, variant, psi):
    """The projection lemma keeps the optimal margin: the eliminated LMI solved without cvxpy
    reaches the optimum of the full LMI (with K) written here in cvxpy; its recovered gain
    satisfies eq. (28)."""
    from tanksynth.design.observer_lmi.conic_form import ConicEliminatedLMI

    A, C, _, _ = _plant()
    _, blocks, _ = CASES[case]
    out = ConicEliminatedLMI(6, C, variant, 100.0, blocks).solve(A, psi)
    ref = hand_cvxpy(A, C, psi, variant, 100.0, blocks, None)
    if ref > 0:
        assert out["status"] == "optimal"
        assert out["t"] == pytest.approx(ref, abs=1e-6)
    else:
        assert out["t"] < 0 and out["t"] == pytest.approx(ref, abs=1e-4)


@pytest.mark.parametrize("which", ["C", "C2", "identity"])
@pytest.mark.parametrize("variant", ["qI", "full"])
def test_eliminated_form_matches_the_cvxpy_problem_point_for_point(which, variant):
    """Same problem as ObserverLMIProblem(form="eliminated") through cvxpy: same Clarabel
    iterates, hence the same (P, Q, L) -- also where the optimum is not unique (C = I: any
    Q >= t I is optimal)."""
    from tanksynth.design.observer_lmi.conic_form import ConicEliminatedLMI
    from tanksynth.design.observer_lmi.problem import ObserverLMIProblem

    A, C, C2, _ = _plant()
    Cm = {"C": C, "C2": C2, "identity": np.eye(6)}[which]
    for psi in (0.0, 0.5):
        a = ObserverLMIProblem(6, Cm, variant, 100.0, form="eliminated").solve(A, psi)
        b = ConicEliminatedLMI(6, Cm, variant, 100.0).solve(A, psi)
        assert a["status"] == b["status"] == "optimal"
        assert b["t"] == pytest.approx(a["t"], abs=1e-8)
        for key in ("P", "Q", "L"):
            np.testing.assert_allclose(b[key], a[key], rtol=1e-6, atol=1e-8 * np.abs(a[key]).max())


def test_observer_lmi_and_maximise_psi_take_the_direct_eliminated_route():
    from tanksynth.design.observer_lmi.lmi import maximise_psi

    A, C, _, _ = _plant()
    res = observer_lmi(A, C, 0.3)
    assert res.structure["form"] == "eliminated"
    assert "rebuilt for Clarabel" in res.structure["A0_parameter"]
    assert all(c.passed for c in res.checks) and eq28_holds(res, A, C)
    sweep = maximise_psi(A, C)
    assert "rebuilt for Clarabel" in sweep.result.structure["A0_parameter"]
    assert eq28_holds(sweep.result, A, C) and sweep.result.psi == sweep.psi_max
