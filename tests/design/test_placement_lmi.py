"""Pole placement in LMI regions: gains, re-check, refusals."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.analysis.lmi_region import disk, half_plane, sector
from tanksynth.design.placement.regions import lmi_observer, lmi_state_feedback
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError, UncontrollableError, UnobservableError


def random_system(n=4, m=2, seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, n)), rng.standard_normal((n, m))


# -------------------------------------------------------------- LMI placement
def test_state_feedback_in_half_plane_and_sector():
    A, B = random_system()
    region = half_plane(0.5) & sector(np.radians(40))
    res = lmi_state_feedback(A, B, region)
    lam = np.linalg.eigvals(A - B @ res.gain_matrix)
    assert all(region.contains(z) for z in lam)
    assert all(c.passed for c in res.checks) and res.achieved_margin >= res.margin
    # P is a Lyapunov matrix of the closed loop
    Acl = A - B @ res.gain_matrix
    assert np.max(np.linalg.eigvalsh(Acl.T @ res.P + res.P @ Acl)) < 0


def test_observer_in_a_discrete_disk():
    A, B = random_system(seed=1)
    Ad = 0.5 * A / np.max(np.abs(np.linalg.eigvals(A)))
    C = B.T
    region = disk(0.2, 0.5)
    res = lmi_observer(Ad, C, region, domain="discrete")
    lam = np.linalg.eigvals(Ad - res.gain_matrix @ C)
    assert res.kind == "observer" and all(region.contains(z) for z in lam)
    assert res.as_dict()["scaling"]["formulation"] == "dual (A', C')"
    # P is a Lyapunov matrix of the discrete error dynamics
    Acl = Ad - res.gain_matrix @ C
    assert np.max(np.linalg.eigvalsh(Acl.T @ res.P @ Acl - res.P)) < 0


def test_infeasible_region_raises_with_the_achievable_margin():
    A, B = random_system()
    with pytest.raises(InfeasibleDesign, match=r"largest achievable margin t\* = "):
        lmi_state_feedback(A, B, disk(-100.0, 1e-3), kappa=1.5)


def test_region_outside_stability_domain_is_refused():
    A, B = random_system()
    with pytest.raises(SpecError, match="stability domain"):
        lmi_state_feedback(A, B, half_plane(-1.0))
    with pytest.raises(SpecError, match="stability domain"):
        lmi_state_feedback(A, B, half_plane(1.0), domain="discrete")


def test_uncontrollable_and_unobservable_are_named():
    A = np.diag([-1.0, -2.0, -3.0])
    B = np.array([[1.0], [1.0], [0.0]])
    # the fixed mode -3 lies outside Re z < -4: refused, named (inside Re z < -1 it is kept,
    # see test_fixed_mode_inside_region_is_kept)
    with pytest.raises(UncontrollableError, match="x3"):
        lmi_state_feedback(A, B, half_plane(4.0), state_names=None)
    with pytest.raises(UnobservableError, match="h3"):
        lmi_observer(A, B.T, half_plane(4.0), state_names=["h1", "h2", "h3"])


def test_lmi_placement_bad_inputs():
    A, B = random_system()
    with pytest.raises(DimensionError):
        lmi_state_feedback(A, B[:3], half_plane(1.0))
    with pytest.raises(SpecError):
        lmi_state_feedback(A, B, half_plane(1.0), domain="hybrid")
    with pytest.raises(SpecError):
        lmi_state_feedback(A, B, half_plane(1.0), margin=2.0)
    with pytest.raises(SpecError):
        lmi_state_feedback(A, B, "disk")


# --------------------------------------------- issue 12: stabilisability relative to the region
def test_fixed_mode_inside_region_is_kept():
    """Issue 12 item 2: an uncontrollable mode at -5 with region Re s < -1 used to be refused."""
    import control

    A = np.array([[0.0, 1.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, -5.0]])
    B = np.array([[0.0], [1.0], [0.0]])
    # independent reference: place the controllable part (python-control), leave x3 alone
    K1 = np.asarray(control.place(A[:2, :2], B[:2], [-2.0, -3.0]), dtype=float)
    Kref = np.hstack([K1, [[0.0]]])
    assert np.allclose(np.sort(np.linalg.eigvals(A - B @ Kref).real), [-5, -3, -2])
    region = half_plane(1.0)
    res = lmi_state_feedback(A, B, region, state_names=["x1", "x2", "x3"])
    lam = np.linalg.eigvals(A - B @ res.gain_matrix)
    assert all(region.contains(z) for z in lam)
    assert np.min(np.abs(lam - (-5.0))) < 1e-9                  # the fixed mode stays
    assert res.fixed_modes[0]["states"] == ["x3"]
    obs = lmi_observer(A.T, B.T, region, state_names=["x1", "x2", "x3"])
    assert all(region.contains(z) for z in np.linalg.eigvals(A.T - obs.gain_matrix @ B.T))
    # the same mode at -0.5 lies outside the region: refused, naming the mode and the state
    A[2, 2] = -0.5
    with pytest.raises(UncontrollableError, match=r"outside.*-0\.5.*x3"):
        lmi_state_feedback(A, B, region, state_names=["x1", "x2", "x3"])
    with pytest.raises(InfeasibleDesign):                      # a design refusal (exit 3)
        lmi_observer(A.T, B.T, region)


# ------------------------------------------------- issue 12: an active conditioning bound
def _slow_cascade():
    import scipy.linalg as sla

    a1, a2, a3 = 0.01, 0.012, 0.015           # 1/s: a slow three-tank cascade, y = h3
    A = np.array([[-a1, 0, 0], [a1, -a2, 0], [0, a2, -a3]])
    return sla.expm(A * 1.0), np.array([[0.0, 0.0, 1.0]])


def test_active_kappa_bound_is_relaxed_then_named():
    """Issue 12 item 3: |z - 0.5| < 0.3 for an observer of h3 was 'certified infeasible'."""
    import control
    import cvxpy as cp

    Ad, C = _slow_cascade()
    region = disk(0.5, 0.3)
    # python-control places (0.5, 0.6, 0.7), inside the disk: the region is reachable
    Lref = np.asarray(control.place(Ad.T, C.T, [0.5, 0.6, 0.7]), dtype=float).T
    assert all(region.contains(z) for z in np.linalg.eigvals(Ad - Lref @ C))
    # hand-built dual LMI (disk: [[-r X, (A'X - C'Y)' - c X]; [., -r X]] < 0) is feasible with
    # X <= 1e8 I
    n = 3
    X = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((1, n))
    M = Ad.T @ X - C.T @ Y - 0.5 * X
    lmi = cp.bmat([[-0.3 * X, M.T], [M, -0.3 * X]])
    prob = cp.Problem(cp.Minimize(0), [0.5 * (lmi + lmi.T) << -1e-6 * np.eye(2 * n),
                                       X >> np.eye(n), X << 1e8 * np.eye(n)])
    prob.solve(solver="CLARABEL")
    assert prob.status == "optimal"
    # with kappa = 1e4 and no relaxation the refusal says the bound is active and names the option
    with pytest.raises(InfeasibleDesign, match=r"bound is active.*kappa_max"):
        lmi_observer(Ad, C, region, domain="discrete", kappa=1e4, kappa_max=1e4)
    # with the relaxation up to 1e8 the design is found and the tries are reported
    res = lmi_observer(Ad, C, region, domain="discrete", kappa=1e4, kappa_max=1e8)
    assert all(region.contains(z) for z in np.linalg.eigvals(Ad - res.gain_matrix @ C))
    tries = res.scaling["kappa_tries"]
    assert tries[0]["bound_active"] and tries[0]["largest_margin_t"] < 0
    assert res.scaling["kappa"] > 1e4 and res.scaling["kappa_relaxed"]


# ------------------------------------------------ direct Clarabel route vs hand-written cvxpy
def _cvxpy_largest_margin(As, Bs, reg, kappa):
    """Phase 1 written here in cvxpy (Clarabel): max t, region LMI <= -t I, I <= X <= kappa I."""
    import cvxpy as cp

    n, m = Bs.shape
    X, Y, t = cp.Variable((n, n), symmetric=True), cp.Variable((m, n)), cp.Variable()
    AX = As @ X - Bs @ Y
    R = cp.kron(reg.L, X) + cp.kron(reg.M, AX) + cp.kron(reg.M.T, AX.T)
    d = R.shape[0]
    prob = cp.Problem(cp.Maximize(t), [0.5 * (R + R.T) << -t * np.eye(d), t <= 1.0,
                                       X >> np.eye(n), X << kappa * np.eye(n)])
    prob.solve(solver="CLARABEL")
    return float(t.value)


@pytest.mark.parametrize("seed", [0, 3])
def test_direct_clarabel_route_meets_a_hand_written_cvxpy_problem(seed):
    """The region LMI written straight in Clarabel's conic form (no cvxpy) reaches the largest
    margin t* that a plain cvxpy formulation of phase 1 reaches on the same scaled data."""
    A, B = random_system(seed=seed)
    region = half_plane(0.5) & sector(np.radians(40))
    res = lmi_state_feedback(A, B, region, kappa=1e3)
    sc = res.scaling
    s, su, w = np.array(sc["state_balance"]), np.array(sc["input_scale"]), sc["time_scale"]
    As = A * (1.0 / s)[:, None] * s[None, :] / w
    Bs = B / s[:, None] * su[None, :] / w
    ref = _cvxpy_largest_margin(As, Bs, region.scaled(w), 1e3)
    assert sc["largest_margin_t"] == pytest.approx(ref, rel=1e-6, abs=1e-9)
    assert all(region.contains(z) for z in np.linalg.eigvals(A - B @ res.gain_matrix))


@pytest.mark.slow
def test_scs_route_through_cvxpy_meets_the_clarabel_route():
    A, B = random_system()
    region = half_plane(0.5) & sector(np.radians(40))
    a = lmi_state_feedback(A, B, region, kappa=1e3)
    b = lmi_state_feedback(A, B, region, kappa=1e3, solver="SCS")
    assert b.solver == "SCS" and "phase 2" in b.status
    assert b.scaling["largest_margin_t"] == pytest.approx(a.scaling["largest_margin_t"], rel=1e-3)
    assert all(region.contains(z) for z in np.linalg.eigvals(A - B @ b.gain_matrix))


def test_boundary_distance_is_the_euclidean_distance_to_the_boundary():
    """Issue 30.3: the distance of a point to the region's boundary, in the units of the point."""
    assert half_plane(0.5).boundary_distance(-0.5 - 5.9e-4 + 3j) == pytest.approx(5.9e-4)
    assert half_plane(0.5).margin(-0.5 - 5.9e-4) == pytest.approx(2 * 5.9e-4)   # f_D: twice it
    assert disk(0.9, 0.08).boundary_distance(0.9 + 0.05j) == pytest.approx(0.03)
    th = np.radians(30)
    z = -2.0 + 0.5j     # distance to the upper ray y = tan(th) (-x): |x sin + y cos|
    assert sector(th).boundary_distance(z) == pytest.approx(abs(-2.0 * np.sin(th) + 0.5 * np.cos(th)))
    both = half_plane(0.5) & disk(-1.0, 0.7)
    assert both.boundary_distance(-0.6) == pytest.approx(0.1)
    assert both.boundary_distance(0.0) < 0


def test_lmi_gain_records_the_distance_of_its_eigenvalues_to_the_region_boundary():
    """Issue 30.3: a gain accepted near the boundary gets its distance to it (1/s) in its diagnostics."""
    A, B = random_system()
    res = lmi_state_feedback(A, B, half_plane(0.5))
    lam = np.linalg.eigvals(A - B @ res.gain_matrix)
    dist = res.as_dict()["min_boundary_distance"]
    assert dist == pytest.approx(float(np.min(-0.5 - lam.real)), rel=1e-9, abs=1e-12) and dist > 0
