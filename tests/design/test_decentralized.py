"""Decentralised one-step / finite-horizon Kalman gains (issue 6, seed 003).

The models, patterns and noise discretisation are tested in
test_decentralized_models.py.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact, write_artefact
from tanksynth.methods import METHODS
from tanksynth.design.decentralized.gains import (KalmanStep, centralized_gain, covariance_recursion,
                                            equicorrelated_intensity, finite_horizon_gains,
                                            lower_tank_equilibrium, one_step_gains, window_models)
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError
from tanksynth.plants import tank_network
from tanksynth.methods import parse_spec

ROUTES = ("iterative", "casadi")


# --------------------------------------------------------------------- fixtures
def random_ltv(seed: int, T: int = 50, n: int = 5, o: int = 3, free_per_row: int = 1):
    """DECENTER's kalmanFiniteHorizonLTV tutorial system (drifting random A, C)."""
    rng = np.random.default_rng(seed)
    A, C, Q, R = [], [], [], []
    A0 = rng.random((n, n)) - 0.5
    C0 = rng.random((o, n)) - 0.5
    for _ in range(T):
        A0 = A0 + 0.1 * (rng.random((n, n)) - 0.5)
        C0 = C0 + 0.1 * (rng.random((o, n)) - 0.5)
        A.append(A0.copy())
        C.append(C0.copy())
        q = rng.random((n, n)) - 0.5
        Q.append(q @ q.T)
        r = rng.random((o, o)) - 0.5
        R.append(r @ r.T + 0.05 * np.eye(o))
    p = rng.random((n, n))
    P0 = 100 * p @ p.T + np.eye(n)
    E = np.zeros((n, o))
    for i in range(n):
        E[i, rng.choice(o, size=free_per_row, replace=False)] = 1
    return A, C, Q, R, E, P0


def centralized_sequence(A, C, Q, R, P0):
    out, Pp = [], P0
    for k in range(len(A)):
        st = centralized_gain(A[k], C[k], Q[k], R[k], Pp)
        out.append(st)
        Pp = st.P_pred_next
    return out


@pytest.fixture(scope="module")
def network_window():
    """N = 8 network, 40-step window under 6 V from 20 cm (time-varying models)."""
    N = 8
    plant = tank_network(N)
    Qc = equicorrelated_intensity(N, 0.1, 0.5)
    models, _ = window_models(plant, np.full(N, 20.0), np.full((41, N // 2), 6.0), 1.0, Qc,
                              4.0 * np.eye(N))
    P0 = models[0].A @ (10 * np.eye(N)) @ models[0].A.T + models[0].Q
    seqs = ([m.A for m in models[1:]], [m.C for m in models[1:]], [m.Q for m in models[1:]],
            [m.R for m in models[1:]])
    return plant, models, seqs, P0


def partial_measurement(network_window):
    """Lower tanks measured only; upper tank N/2+i uses the levels it drains into / is fed with."""
    plant, models, (A, C, Q, R), P0 = network_window
    h = plant.n // 2
    lower = np.arange(h)
    C2 = [c[:h] for c in C]
    R2 = [r[:h, :h] for r in R]
    E = np.zeros((plant.n, h))
    E[lower, lower] = 1
    E[h + lower, lower] = 1
    E[h + lower, (lower - 1) % h] = 1
    return A, C2, Q, R2, E, P0


# ------------------------------------------------------------ E all ones: = KF
@pytest.mark.parametrize("seed", [0, 1])
def test_full_pattern_gives_the_centralized_gains(seed):
    A, C, Q, R, _, P0 = random_ltv(seed, T=20)
    E = np.ones((5, 3))
    ref = centralized_sequence(A, C, Q, R, P0)
    # one step at a time
    Pp = P0
    for k in range(len(A)):
        st = one_step_gains(A[k], C[k], Q[k], R[k], E, Pp)
        np.testing.assert_allclose(st.K, ref[k].K, rtol=0, atol=1e-8 * max(1, np.abs(ref[k].K).max()))
        np.testing.assert_allclose(st.P_filt, ref[k].P_filt, rtol=1e-8, atol=1e-8)
        Pp = st.P_pred_next
    for route in ROUTES:
        res = finite_horizon_gains(A, C, Q, R, E, P0, method=route)
        assert res.converged
        for k in range(len(A)):
            np.testing.assert_allclose(res.K[k], ref[k].K, rtol=0,
                                       atol=1e-8 * max(1, np.abs(ref[k].K).max()))
        assert res.cost == pytest.approx(sum(s.cost for s in ref), rel=1e-10)


def test_full_pattern_through_the_sparse_solver():
    """The free-entry linear system itself (not the all-free shortcut) gives the KF gain."""
    from tanksynth.design.decentralized.recursion import GainPattern

    A, C, Q, R, _, P0 = random_ltv(3, T=1)
    pat = GainPattern(np.ones((5, 3), dtype=bool))
    pat.full = False
    S = C[0] @ P0 @ C[0].T + R[0]
    K = pat.solve(None, S, P0 @ C[0].T)
    np.testing.assert_allclose(K, P0 @ C[0].T @ np.linalg.inv(S), atol=1e-10)
    L = np.eye(5) + A[0].T @ A[0]
    np.testing.assert_allclose(pat.solve(L, S, L @ P0 @ C[0].T), K, atol=1e-9)


def test_centralized_gain_is_the_kalman_gain():
    A, C, Q, R, _, P0 = random_ltv(4, T=1)
    st = centralized_gain(A[0], C[0], Q[0], R[0], P0)
    K = P0 @ C[0].T @ np.linalg.inv(C[0] @ P0 @ C[0].T + R[0])
    np.testing.assert_allclose(st.K, K, rtol=1e-10)
    # standard form (I - K C) P equals the Joseph form at the optimal gain
    np.testing.assert_allclose(st.P_filt, (np.eye(5) - K @ C[0]) @ P0, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(st.P_pred_next, A[0] @ st.P_filt @ A[0].T + Q[0], rtol=1e-12)
    assert isinstance(st, KalmanStep)
    np.testing.assert_array_equal(np.asarray(st), st.K)
    assert st.cost == pytest.approx(np.trace(st.P_filt))


# ----------------------------------------------------- sparsity and optimality
def test_one_step_is_optimal_on_the_pattern_and_masked_entries_are_zero():
    A, C, Q, R, _, P0 = random_ltv(5, T=1)
    E = np.array([[1, 0, 1], [0, 1, 0], [0, 0, 1], [1, 0, 0], [0, 1, 1]], dtype=float)
    st = one_step_gains(A[0], C[0], Q[0], R[0], E, P0)
    assert np.all(st.K[E == 0] == 0.0)          # exactly zero, not approximately
    assert np.all(st.K[E == 1] != 0.0)

    def cost(K):
        IKC = np.eye(5) - K @ C[0]
        return np.trace(IKC @ P0 @ IKC.T + K @ R[0] @ K.T)

    assert cost(st.K) == pytest.approx(st.cost, rel=1e-12)
    rng = np.random.default_rng(0)
    for _ in range(20):
        D = rng.standard_normal((5, 3)) * E * 1e-3
        assert cost(st.K + D) > st.cost
    # the centralised gain is better (it has more freedom) but violates the pattern
    c = centralized_gain(A[0], C[0], Q[0], R[0], P0)
    assert c.cost < st.cost
    assert np.any(c.K[E == 0] != 0)


def test_one_step_with_own_measurements_is_the_scalar_kalman_gain():
    """C = I, E = I: the one-step gain of tank i is P_ii / (P_ii + R_ii) (DECENTER's local filter)."""
    rng = np.random.default_rng(8)
    G = rng.standard_normal((6, 6))
    P = G @ G.T + np.eye(6)
    R = np.diag(rng.uniform(0.5, 2.0, 6))
    st = one_step_gains(np.eye(6), np.eye(6), np.zeros((6, 6)), R, np.eye(6), P)
    np.testing.assert_allclose(np.diag(st.K), np.diag(P) / (np.diag(P) + np.diag(R)), rtol=1e-13)
    assert np.count_nonzero(st.K) == 6


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_ltv_routes_agree_and_beat_one_step(seed):
    A, C, Q, R, E, P0 = random_ltv(seed, free_per_row=1 + seed % 2)
    results = {route: finite_horizon_gains(A, C, Q, R, E, P0, method=route) for route in ROUTES}
    it, ca_ = results["iterative"], results["casadi"]
    for res in results.values():
        assert res.converged
        assert len(res.K) == len(res.P) == 50
        for K in res.K:
            assert np.all(K[E == 0] == 0.0)
        assert res.cost <= res.one_step_cost
        traj = covariance_recursion(A, C, Q, R, res.K, P0)       # cost re-checked from gains
        assert traj.cost == pytest.approx(res.cost, rel=1e-12)
        assert sum(np.trace(P) for P in res.P) == pytest.approx(res.cost, rel=1e-12)
    assert abs(ca_.cost - it.cost) <= 1e-6 * it.cost
    # here the finite horizon matters
    assert it.cost < it.one_step_cost * (1 - 1e-3)
    # the iterative route never increases the cost
    assert all(b <= a * (1 + 1e-12) for a, b in zip(it.history, it.history[1:]))


def test_finite_horizon_is_stationary():
    """Perturbing any single gain of the optimum (on the pattern) raises the window cost."""
    A, C, Q, R, E, P0 = random_ltv(7, T=12)
    res = finite_horizon_gains(A, C, Q, R, E, P0, method="iterative", tol=1e-12, max_iter=2000)
    rng = np.random.default_rng(1)
    for k in (0, 5, 11):
        for _ in range(5):
            K = [k_.copy() for k_ in res.K]
            K[k] = K[k] + 1e-3 * rng.standard_normal(K[k].shape) * E
            assert covariance_recursion(A, C, Q, R, K, P0).cost > res.cost


def test_partial_measurement_routes_agree_and_matter(network_window):
    A, C, Q, R, E, P0 = partial_measurement(network_window)
    it = finite_horizon_gains(A, C, Q, R, E, P0, method="iterative")
    ca_ = finite_horizon_gains(A, C, Q, R, E, P0, method="casadi")
    assert it.converged and ca_.converged
    assert abs(ca_.cost - it.cost) <= 1e-6 * it.cost
    assert it.cost < it.one_step_cost * (1 - 1e-3)
    cen = sum(s.cost for s in centralized_sequence(A, C, Q, R, P0))
    assert cen < it.cost
    for res in (it, ca_):
        assert all(np.all(K[E == 0] == 0.0) for K in res.K)


def test_every_tank_measured_barely_differs(network_window):
    """E = I, C = I (seed 003's set-up): finite-horizon and one-step costs almost equal."""
    _, _, (A, C, Q, R), P0 = network_window
    E = np.eye(8)
    res = {route: finite_horizon_gains(A, C, Q, R, E, P0, method=route) for route in ROUTES}
    for r in res.values():
        assert r.cost <= r.one_step_cost
        assert (r.one_step_cost - r.cost) / r.cost < 1e-3
        assert all(np.all(K[E == 0] == 0.0) for K in r.K)
    assert abs(res["casadi"].cost - res["iterative"].cost) <= 1e-6 * res["iterative"].cost


def test_deterministic_bit_for_bit():
    A, C, Q, R, E, P0 = random_ltv(2, T=15)
    for route in ROUTES:
        a = finite_horizon_gains(A, C, Q, R, E, P0, method=route)
        b = finite_horizon_gains(A, C, Q, R, E, P0, method=route)
        for Ka, Kb in zip(a.K, b.K):
            assert np.array_equal(Ka, Kb)


def test_accepts_3d_arrays():
    A, C, Q, R, E, P0 = random_ltv(2, T=6)
    a = finite_horizon_gains(A, C, Q, R, E, P0, method="iterative")
    b = finite_horizon_gains(np.array(A), np.array(C), np.array(Q), np.array(R), E, P0,
                             method="iterative")
    assert a.cost == b.cost
    assert b.gains.shape == (6, 5, 3)
    assert b.T == 6


def test_not_converged_warns_and_returns_finite_gains():
    A, C, Q, R, E, P0 = random_ltv(0)
    for route in ROUTES:
        with pytest.warns(RuntimeWarning, match="did not converge"):
            res = finite_horizon_gains(A, C, Q, R, E, P0, method=route, tol=1e-14, max_iter=1)
        assert res.converged is False
        assert all(np.all(np.isfinite(K)) for K in res.K)
        assert res.cost <= res.one_step_cost


# ------------------------------------------------------------------- bad input
def test_bad_inputs_raise_clear_errors():
    A, C, Q, R, E, P0 = random_ltv(1, T=4)
    with pytest.raises(DimensionError, match="E has shape"):
        finite_horizon_gains(A, C, Q, R, np.ones((3, 5)), P0)
    with pytest.raises(DimensionError, match="E has shape"):
        one_step_gains(A[0], C[0], Q[0], R[0], np.ones((5, 2)), P0)
    with pytest.raises(DimensionError, match="no free entry"):
        one_step_gains(A[0], C[0], Q[0], R[0], np.zeros((5, 3)), P0)
    with pytest.raises(DimensionError, match="at least one step"):
        finite_horizon_gains([], [], [], [], E, P0)
    with pytest.raises(DimensionError, match="R_seq has 3"):
        finite_horizon_gains(A, C, Q, R[:3], E, P0)
    with pytest.raises(DimensionError, match=r"C_seq\[2\] has shape"):
        finite_horizon_gains(A, C[:2] + [np.ones((2, 5))] + C[3:], Q, R, E, P0)
    with pytest.raises(SpecError, match="P0_pred is not positive definite"):
        finite_horizon_gains(A, C, Q, R, E, -P0)
    bad_R = list(R)
    bad_R[2] = -np.eye(3)
    with pytest.raises(SpecError, match=r"R_seq\[2\] is not positive definite"):
        finite_horizon_gains(A, C, Q, bad_R, E, P0)
    bad_Q = list(Q)
    bad_Q[1] = -np.eye(5)
    with pytest.raises(SpecError, match=r"Q_seq\[1\] is not positive semidefinite"):
        finite_horizon_gains(A, C, bad_Q, R, E, P0)
    asym = P0.copy()
    asym[0, 1] += 1.0
    with pytest.raises(SpecError, match="not symmetric"):
        one_step_gains(A[0], C[0], Q[0], R[0], E, asym)
    nan_A = [a.copy() for a in A]
    nan_A[3][0, 0] = np.nan
    with pytest.raises(DimensionError, match="non-finite"):
        finite_horizon_gains(nan_A, C, Q, R, E, P0)
    with pytest.raises(SpecError, match="method"):
        finite_horizon_gains(A, C, Q, R, E, P0, method="newton")
    with pytest.raises(SpecError, match="tol"):
        finite_horizon_gains(A, C, Q, R, E, P0, tol=0)
    with pytest.raises(SpecError, match="max_iter"):
        finite_horizon_gains(A, C, Q, R, E, P0, max_iter=0)


def test_covariance_breakdown_names_the_step():
    """A = 0, Q = 0 collapses P(2|1) to 0; with one output for three states P(2|2) is singular."""
    n, o, T = 3, 1, 4
    A = [np.zeros((n, n))] * T
    C = [np.array([[1.0, 0.0, 0.0]])] * T
    Q = [np.zeros((n, n))] * T
    R = [np.eye(o)] * T
    E = np.ones((n, o))
    with pytest.raises(InfeasibleDesign, match=r"P\(2\|2\) at window step 2"):
        finite_horizon_gains(A, C, Q, R, E, np.eye(n), method="iterative")


# ----------------------------------------------------------------- spec method
def _spec(design: dict, N: int = 8):
    plant = tank_network(N)
    x, u = lower_tank_equilibrium(plant, np.full(N // 2, 20.0))
    table = {
        "plant": {"model": "tank_network", "N": N},
        "operating_point": {"x": x.tolist(), "u": u.tolist()},
        "sampling": {"ts": 1.0},
        "design": [{"name": "dkf", "method": "decentralized_kalman", "process_noise": 0.05,
                    **design}],
    }
    return parse_spec(table)


@pytest.mark.parametrize("algorithm", ["iterative", "casadi", "one_step"])
def test_spec_method_artefact(tmp_path, algorithm):
    spec = _spec({"algorithm": algorithm, "window": 12, "input": [6.0] * 4,
                  "process_noise_correlation": 0.5, "measurement_noise": 4.0})
    design = spec.designs[0]
    result = METHODS["decentralized_kalman"].design(spec, design)
    d = result.diagnostics
    assert [f"K_{j}" for j in range(12)] == [k for k in result.gains if k.startswith("K_")]
    for j in range(12):
        K = result.gains[f"K_{j}"]
        assert K.shape == (8, 8)
        assert np.all(K[~np.eye(8, dtype=bool)] == 0.0)
    assert result.gains["P_diag"].shape == (12, 8)
    assert result.gains["x_pred"].shape == (13, 8)
    assert d["converged"] and d["centralized_cost"] <= d["cost"] <= d["one_step_cost"]
    path = write_artefact(result, tmp_path, spec.sha256, export=("mat", "h"))
    doc = read_artefact(path)
    np.testing.assert_array_equal(doc["gains"]["K_3"], result.gains["K_3"])
    assert (tmp_path / "dkf.h").exists()


def test_spec_method_explicit_pattern_and_matrices():
    E = np.eye(8)
    E[4, 0] = 1     # upper tank 5 also uses the level of tank 1 it drains into
    spec = _spec({"algorithm": "iterative", "window": 6, "E": E.astype(int).tolist(),
                  "measurement_noise": (2.0 * np.eye(8)).tolist(),
                  "initial_covariance": (5.0 * np.eye(8)).tolist()})
    result = METHODS["decentralized_kalman"].design(spec, spec.designs[0])
    assert result.gains["K_0"][4, 0] != 0.0
    assert result.diagnostics["free_entries"] == 9


@pytest.mark.parametrize("design, key", [
    ({"algorithm": "newton"}, "design[0].algorithm"),
    ({"window": 0}, "design[0].window"),
    ({"E": [[1, 0], [0, 1]]}, "design[0].E"),
    ({"E": "diagonal"}, "design[0].E"),
    ({"E": np.zeros((8, 8)).tolist()}, "design[0].E"),
    ({"process_noise": -1.0}, "design[0].process_noise"),
    ({"process_noise": np.eye(8).tolist(), "process_noise_correlation": 0.5},
     "design[0].process_noise_correlation"),
    ({"process_noise_correlation": 1.5}, "design[0].process_noise_correlation"),
    ({"measurement_noise": 0.0}, "design[0].measurement_noise"),
    ({"initial_covariance": (-np.eye(8)).tolist()}, "design[0].initial_covariance"),
    ({"input": [6.0]}, "design[0].input"),
    ({"tolerance": -1.0}, "design[0].tolerance"),
])
def test_spec_method_bad_options(design, key):
    with pytest.raises(SpecError) as exc:   # refused when the spec is read, before any design
        _spec(design)
    assert exc.value.key == key


def test_spec_requires_process_noise_and_own_measurements():
    plant = tank_network(8)
    x, u = lower_tank_equilibrium(plant, np.full(4, 20.0))
    table = {"plant": {"model": "tank_network", "N": 8},
             "operating_point": {"x": x.tolist()}, "sampling": {"ts": 1.0},
             "design": [{"name": "dkf", "method": "decentralized_kalman"}]}
    with pytest.raises(SpecError, match="process_noise"):
        parse_spec(table)
    table = {"plant": {"model": "tank_network", "N": 4, "parameter_set": "johansson_min_phase"},
             "operating_point": {"x": [12.4, 12.7, 1.8, 1.4]}, "sampling": {"ts": 1.0},
             "design": [{"name": "dkf", "method": "decentralized_kalman", "process_noise": 0.1}]}
    spec = parse_spec(table)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(SpecError, match="h3, h4") as exc:
            METHODS["decentralized_kalman"].design(spec, spec.designs[0])
    assert exc.value.key == "design[0].E"


@pytest.mark.parametrize("p0", [1e50, 1e100])
def test_sweeps_broken_by_round_off_keep_the_one_step_gains(p0):
    """P0 1e50 times R: I - K C is pure round-off at the first step, the sweeps then gave a
    cost of 1e18 .. 1e268 (against 12 for the one-step gains) or a P(k|k) that is not positive
    definite. The route keeps the one-step gains (never worse than its start), warns, and
    reports it; the one-step covariances are recomputed here from the gains (Joseph form)."""
    rng = np.random.default_rng(0)
    n, T = 4, 10
    A = [np.eye(n) + 0.05 * rng.standard_normal((n, n)) for _ in range(T)]
    C, Q, R = [np.eye(n)] * T, [0.01 * np.eye(n)] * T, [np.eye(n)] * T
    with pytest.warns(RuntimeWarning, match="kept the one-step gains"):
        res = finite_horizon_gains(A, C, Q, R, np.eye(n), p0 * np.eye(n))
    assert res.converged is False and res.cost <= res.one_step_cost
    P, cost = p0 * np.eye(n), 0.0
    for k in range(T):                      # one-step optimal gain with E = I, C = I: scalar KF
        K = np.diag(np.diag(P) / (np.diag(P) + 1.0))
        np.testing.assert_allclose(res.K[k], K, rtol=1e-12, atol=0)
        IKC = np.eye(n) - K
        Pf = IKC @ P @ IKC.T + K @ K.T
        cost += np.trace(Pf)
        P = A[k] @ Pf @ A[k].T + Q[k]
    assert res.cost == pytest.approx(cost, rel=1e-9)

