"""H2 / H-infinity / multi-objective LMI synthesis against independent references.

References are computed here: python-control ``lqr``/``dlqr``/``lqe``/``dlqe`` (Riccati),
python-control ``norm(..., method="scipy")``, an H-infinity state-feedback Riccati
bisection written in this file, and python-control ``hinfsyn`` where slycot is installed.
"""

from __future__ import annotations

import importlib.util

import control
import numpy as np
import pytest
import scipy.linalg as sla

from tanksynth.analysis.lmi_region import disk, half_plane
from tanksynth.design.synthesis.synthesize import (GeneralizedPlant, generalized_plant, h2_lmis, hinf_lmis,
                                        hinf_lmis_reduced,
                                        observer_plant, region_lmi, synthesize_observer,
                                        synthesize_state_feedback)
from tanksynth.errors import InfeasibleDesign, SpecError

RTOL = 1e-6


def pc_hinf(sys):
    """python-control's H-infinity norm (scipy method). Its Hamiltonian in 0.10.2 needs as many
    inputs as outputs, so the system is padded with zero inputs or outputs (same norm)."""
    A, B, C = sys.A, sys.B, sys.C
    p, m = C.shape[0], B.shape[1]
    if m < p:
        B = np.hstack([B, np.zeros((A.shape[0], p - m))])
    elif p < m:
        C = np.vstack([C, np.zeros((m - p, A.shape[0]))])
    k = max(p, m)
    return control.norm(control.ss(A, B, C, np.zeros((k, k)), sys.dt), "inf", tol=1e-10,
                        method="scipy", print_warning=False)


def _three_tank(discrete: bool):
    """Seed 000's three-tank linearised at (0.40, 0.20, 0.30) m, SI units, inflow disturbances."""
    from tanksynth.analysis.linearize import equilibrium_input, linearize
    from tanksynth.plants import three_tank

    plant = three_tank("h1h2")
    x0 = [0.40, 0.20, 0.30]
    eq = equilibrium_input(plant, x0)
    lin = linearize(plant, x0, eq.u0, ts=1.0 if discrete else None)
    A, B = (lin.Ad, lin.Bd) if discrete else (lin.F, lin.B)
    Bw_c = np.eye(3) / 0.0154 * 5e-6
    Bw = sla.expm(np.block([[lin.F, Bw_c], [np.zeros((3, 6))]]))[:3, 3:] if discrete else Bw_c
    Q = np.diag([1 / 0.62 ** 2] * 3)
    R = np.diag([1 / 1.2e-4 ** 2] * 2)
    return A, B, lin.C, Bw, Q, R


def _weights(Q, R):
    n, m = Q.shape[0], R.shape[0]
    Cz = np.vstack([sla.sqrtm(Q).real, np.zeros((m, n))])
    Dzu = np.vstack([np.zeros((n, m)), sla.sqrtm(R).real])
    return Cz, Dzu


@pytest.mark.parametrize("discrete", [False, True])
def test_h2_state_feedback_equals_lqr(discrete):
    A, B, _, Bw, Q, R = _three_tank(discrete)
    Cz, Dzu = _weights(Q, R)
    P = GeneralizedPlant(A, B, Bw, Cz, Dzu, "discrete" if discrete else "continuous",
                         1.0 if discrete else None)
    res = synthesize_state_feedback(P, objective="h2")
    K_ref, S, _ = (control.dlqr if discrete else control.lqr)(A, B, Q, R)
    h2_ref = np.sqrt(np.trace(Bw.T @ S @ Bw))
    assert res.h2 == pytest.approx(h2_ref, rel=RTOL)
    assert res.achieved_h2[0] == pytest.approx(h2_ref, rel=RTOL)
    # the cost matrix: the closed loop's observability Gramian of z is the Riccati solution
    Acl, Ccl = A - B @ res.gain_matrix, Cz - Dzu @ res.gain_matrix
    Wo = (sla.solve_discrete_lyapunov(Acl.T, Ccl.T @ Ccl) if discrete
          else sla.solve_continuous_lyapunov(Acl.T, -Ccl.T @ Ccl))
    assert np.linalg.norm(Wo - S) / np.linalg.norm(S) < 1e-4
    np.testing.assert_allclose(res.gain_matrix, K_ref, rtol=1e-3, atol=1e-3 * np.abs(K_ref).max())
    sysd = control.ss(Acl, Bw, Ccl, np.zeros((Ccl.shape[0], Bw.shape[1])), 1.0 if discrete else 0)
    assert control.norm(sysd, 2) == pytest.approx(h2_ref, rel=1e-5)


@pytest.mark.parametrize("discrete", [False, True])
def test_h2_observer_equals_kalman(discrete):
    A, _, C, Bw, Q, _ = _three_tank(discrete)
    Dv = np.diag([1e-3, 1e-3])
    Cz = sla.sqrtm(Q).real
    res = synthesize_observer(A, C, Bw, Dv, Cz, domain="discrete" if discrete else "continuous",
                              dt=1.0 if discrete else None, objective="h2")
    Qn, Rn = np.eye(3), Dv @ Dv
    if discrete:
        L_ref, P, _ = control.dlqe(A, Bw, C, Qn, Rn)
        # python-control's dlqe gives the predictor gain A P C' (C P C' + R)^-1, P the one-step
        # prediction covariance: the same observer form as the LMI's
        np.testing.assert_allclose(L_ref, A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + Rn), rtol=1e-9)
    else:
        L_ref, P, _ = control.lqe(A, Bw, C, Qn, Rn)
    h2_ref = np.sqrt(np.trace(Cz @ P @ Cz.T))
    assert res.h2 == pytest.approx(h2_ref, rel=RTOL)
    assert res.achieved_h2[0] == pytest.approx(h2_ref, rel=RTOL)
    np.testing.assert_allclose(res.gain_matrix, L_ref, rtol=1e-3, atol=1e-3 * np.abs(L_ref).max())


def _hinf_riccati_optimum(A, B, Bw, Q, R, lo, hi, rtol=1e-7):
    """Smallest gamma with a stabilising X >= 0 of the H-infinity state-feedback ARE (bisection).

    A'X + XA + X (Bw Bw'/g^2 - B R^-1 B') X + Q = 0 (continuous, Cz'Dzu = 0).
    """
    n = A.shape[0]

    def ok(g):
        G = B @ np.linalg.solve(R, B.T) - Bw @ Bw.T / g ** 2
        H = np.block([[A, -G], [-Q, -A.T]])
        lam, V = np.linalg.eig(H)
        if np.any(np.abs(lam.real) < 1e-10 * np.maximum(1, np.abs(lam))):
            return False
        stable = V[:, lam.real < 0]
        if stable.shape[1] != n:
            return False
        X1, X2 = stable[:n], stable[n:]
        if np.linalg.cond(X1) > 1e12:
            return False
        X = np.real(X2 @ np.linalg.inv(X1))
        X = 0.5 * (X + X.T)
        return bool(np.linalg.eigvalsh(X)[0] >= -1e-9 * np.abs(X).max())

    assert ok(hi) and not ok(lo)
    while hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi


def test_hinf_state_feedback_gamma_against_norm_and_riccati_optimum():
    A, B, _, Bw, Q, R = _three_tank(False)
    Cz, Dzu = _weights(Q, R)
    res = synthesize_state_feedback(GeneralizedPlant(A, B, Bw, Cz, Dzu), objective="hinf",
                                    backoff=1e-3)
    K = res.gain_matrix
    sys_cl = control.ss(A - B @ K, Bw, Cz - Dzu @ K, np.zeros((Cz.shape[0], 3)))
    norm = pc_hinf(sys_cl)
    assert norm == pytest.approx(res.achieved_hinf[0], rel=1e-6)
    assert norm <= res.gamma * (1 + 1e-6)
    assert res.gamma <= res.gamma_optimum * (1 + 1e-3) * (1 + 1e-9)
    opt = _hinf_riccati_optimum(A, B, Bw, Q, R, 0.3 * res.gamma_optimum, 3 * res.gamma_optimum)
    assert res.gamma_optimum == pytest.approx(opt, rel=1e-4)
    assert norm == pytest.approx(opt, rel=2e-3)


@pytest.mark.parametrize("discrete", [False, True])
def test_hinf_observer_norm_agrees_with_python_control(discrete):
    A, _, C, Bw, Q, _ = _three_tank(discrete)
    Dv = np.diag([1e-3, 1e-3])
    Cz = sla.sqrtm(Q).real
    res = synthesize_observer(A, C, Bw, Dv, Cz, domain="discrete" if discrete else "continuous",
                              dt=1.0 if discrete else None, objective="hinf", backoff=1e-3)
    L = res.gain_matrix
    Bcl = np.hstack([Bw, -L @ Dv])
    err = control.ss(A - L @ C, Bcl, Cz, np.zeros((3, 5)), 1.0 if discrete else 0)
    norm = pc_hinf(err)
    assert norm == pytest.approx(res.achieved_hinf[0], rel=1e-6)
    assert norm <= res.gamma * (1 + 1e-6)
    # H-infinity optimal is not H2 optimal, and vice versa
    h2 = synthesize_observer(A, C, Bw, Dv, Cz, domain=err.isdtime() and "discrete" or "continuous",
                             dt=1.0 if discrete else None, objective="h2")
    assert h2.achieved_hinf[0] >= norm * (1 - 1e-6)
    assert res.achieved_h2[0] >= h2.h2 * (1 - 1e-6)


@pytest.mark.skipif(importlib.util.find_spec("slycot") is None, reason="python-control hinfsyn needs slycot")
def test_hinf_state_feedback_optimum_against_hinfsyn():  # pragma: no cover - needs slycot
    A, B, _, Bw, Q, R = _three_tank(False)
    Cz, Dzu = _weights(Q, R)
    res = synthesize_state_feedback(GeneralizedPlant(A, B, Bw, Cz, Dzu), objective="hinf")
    # state feedback as output feedback with y = x plus a tiny measurement noise channel
    n, m, nw = 3, 2, 3
    eps = 1e-6
    Bfull = np.hstack([Bw, np.zeros((n, n)), B])
    Cfull = np.vstack([Cz, np.eye(n)])
    D = np.zeros((Cz.shape[0] + n, nw + n + m))
    D[:Cz.shape[0], nw + n:] = Dzu
    D[Cz.shape[0]:, nw:nw + n] = eps * np.eye(n)
    P = control.ss(A, Bfull, Cfull, D)
    _, _, gam, _ = control.hinfsyn(P, n, m)
    assert res.gamma_optimum <= gam * (1 + 1e-3)
    assert res.gamma_optimum == pytest.approx(gam, rel=1e-2)


def test_multiobjective_region_and_common_lyapunov_conservatism():
    A, B, _, Bw, Q, R = _three_tank(True)
    Cz, Dzu = _weights(Q, R)
    P = GeneralizedPlant(A, B, Bw, Cz, Dzu, "discrete", 1.0)
    free = synthesize_state_feedback(P, objective="hinf")
    region = disk(0.85, 0.1)           # forces faster poles than the H-infinity optimum has
    assert any(region.margin(z) <= 0 for z in free.closed_loop_eigenvalues[0])
    res = synthesize_state_feedback(P, objective="hinf", region=region, backoff=1e-3)
    eig = np.linalg.eigvals(A - B @ res.gain_matrix)
    assert all(region.margin(z) > 0 for z in eig)
    assert res.gamma >= free.gamma_optimum
    assert res.achieved_hinf[0] <= res.gamma * (1 + 1e-6)
    # the returned X certifies the region in numpy
    M = region_lmi(region, P, res.X, res.gain_matrix @ res.X)
    assert np.linalg.eigvalsh(M).max() < 0
    # H2 bound together with the region
    both = synthesize_state_feedback(P, objective="h2", region=region, hinf_bound=2 * res.gamma)
    assert both.achieved_hinf[0] <= 2 * res.gamma * (1 + 1e-6)
    assert both.achieved_h2[0] <= both.h2 * (1 + 1e-6)


def test_infeasible_bound_is_refused_with_the_achievable_optimum():
    A, B, _, Bw, Q, R = _three_tank(True)
    Cz, Dzu = _weights(Q, R)
    P = GeneralizedPlant(A, B, Bw, Cz, Dzu, "discrete", 1.0)
    best = synthesize_state_feedback(P, objective="hinf").gamma_optimum
    with pytest.raises(InfeasibleDesign, match="the smallest the same LMIs admit") as exc:
        synthesize_state_feedback(P, objective="h2", hinf_bound=0.5 * best, region=disk(0.9, 0.08))
    assert "||T_zw||_inf <=" in str(exc.value)


def test_common_lyapunov_over_vertices_meets_the_bound_at_every_vertex():
    A, B, _, Bw, Q, R = _three_tank(False)
    Cz, Dzu = _weights(Q, R)
    models = [GeneralizedPlant(A * s, B, Bw, Cz, Dzu) for s in (0.85, 1.15)]
    res = synthesize_state_feedback(models, objective="hinf", region=half_plane(0.005), backoff=1e-3)
    assert len(res.achieved_hinf) == 2
    for Pm in models:
        Acl, Bcl, Ccl = Pm.closed_loop(res.gain_matrix)
        sysm = control.ss(Acl, Bcl, Ccl, np.zeros((Ccl.shape[0], 3)))
        assert pc_hinf(sysm) \
            <= res.gamma * (1 + 1e-6)
        assert np.max(np.linalg.eigvals(Acl).real) < -0.005


def test_statespace_input_and_lmi_blocks_in_numpy():
    A, B, _, Bw, Q, R = _three_tank(False)
    Cz, Dzu = _weights(Q, R)
    sysP = control.ss(A, np.hstack([Bw, B]), Cz, np.hstack([np.zeros((5, 3)), Dzu]))
    Pss = generalized_plant(sysP, ncon=2)
    Pm = GeneralizedPlant(A, B, Bw, Cz, Dzu)
    a = synthesize_state_feedback(Pss, objective="h2")
    b = synthesize_state_feedback(Pm, objective="h2")
    np.testing.assert_array_equal(a.gain_matrix, b.gain_matrix)
    # the numpy evaluation of the blocks: the LQR closed loop's Gramian with a little slack
    K, _, _ = control.lqr(A, B, Q, R)
    Acl = A - B @ K
    X = sla.solve_continuous_lyapunov(Acl, -Bw @ Bw.T) * 1.01
    Ccl = Cz - Dzu @ K
    W = Ccl @ X @ Ccl.T + 1e-6 * np.eye(5)
    assert all(np.linalg.eigvalsh(M).max() < 0 for M in h2_lmis(Pm, X, K @ X, W))
    g = 1.5 * pc_hinf(control.ss(Acl, Bw, Ccl, np.zeros((5, 3))))
    assert hinf_lmis(Pm, X, K @ X, g)[0].shape == (3 + 3 + 5,) * 2
    # bounded real lemma at the solver's optimum, recomputed in numpy in original units
    res = synthesize_state_feedback(Pm, objective="hinf", backoff=1e-2, route="lmi")
    assert res.route == "lmi"
    # X = T Xs T' of the scaled problem's reduced lemma (variable gamma X, mu = gamma^2); in
    # original units (w = cw ws, zs = cz z, tau = omega t) it holds for omega / cw^2 times it
    Xh = res.X * res.scaling["time_scale"] / res.scaling["disturbance_scale"] ** 2
    M = hinf_lmis_reduced(Pm, Xh, res.gain_matrix @ Xh, res.gamma ** 2)[0]
    assert np.linalg.eigvalsh(M).max() < 0
    # and the full lemma in X = (gamma X) / gamma
    M = hinf_lmis(Pm, Xh / res.gamma, res.gain_matrix @ Xh / res.gamma, res.gamma)[0]
    assert np.linalg.eigvalsh(M).max() < 0
    # the Riccati route's X = gamma^2 P^-1 satisfies the reduced lemma in original units with
    # equality (the central gain): largest eigenvalue zero up to rounding
    ric = synthesize_state_feedback(Pm, objective="hinf", backoff=1e-2)
    assert ric.route == "riccati"
    M = hinf_lmis_reduced(Pm, ric.X, ric.gain_matrix @ ric.X, ric.gamma ** 2)[0]
    e = np.linalg.eigvalsh(M)
    assert e.max() <= 1e-8 * np.abs(e).max()


def test_observer_dual_has_the_error_system_norms():
    A, _, C, Bw, Q, _ = _three_tank(True)
    Dv = np.diag([1e-3, 2e-3])
    Cz = np.eye(3)
    D = observer_plant(A, C, Bw, Dv, Cz, "discrete", 1.0)
    L = np.array([[0.3, 0.0], [0.0, 0.3], [0.1, 0.1]])
    Acl, Bcl, Ccl = D.closed_loop(L.T)
    err = control.ss(A - L @ C, np.hstack([Bw, -L @ Dv]), Cz, 0 * np.zeros((3, 5)), 1.0)
    dual = control.ss(Acl, Bcl, Ccl, np.zeros((Ccl.shape[0], Bcl.shape[1])), 1.0)
    assert control.norm(dual, 2) == pytest.approx(control.norm(err, 2), rel=1e-9)


def test_bad_options_are_named():
    A, B, _, Bw, Q, R = _three_tank(False)
    Cz, Dzu = _weights(Q, R)
    P = GeneralizedPlant(A, B, Bw, Cz, Dzu)
    with pytest.raises(SpecError) as exc:
        synthesize_state_feedback(P, objective="h3")
    assert exc.value.key == "objective"
    with pytest.raises(SpecError) as exc:
        synthesize_state_feedback(P, objective="hinf", region=disk(0.9, 0.08))
    assert exc.value.key == "region"


def _tank_network_plant(N):
    """tank_network(N) at every pump 4 V, inflow disturbances, Bryson weights (as the benchmark)."""
    from scipy.optimize import fsolve

    from tanksynth.analysis.linearize import linearize
    from tanksynth.plants.tank_network import tank_network
    from tanksynth.spec.method_options.synthesis import (bryson_input_weight, bryson_state_weight,
                                                         inflow_matrix)

    plant = tank_network(N)
    u0 = np.full(plant.m, 4.0)
    rhs = plant.compiled.rhs
    guess = np.concatenate([np.full(N // 2, 22.0), np.full(N // 2, 7.0)])
    x0 = fsolve(lambda x: rhs(np.maximum(x, 1e-6)[None], u0[None])[0], guess, xtol=1e-12)
    lin = linearize(plant, x0, u0)
    Q, R = bryson_state_weight(plant), bryson_input_weight(plant)
    Cz, Dzu = _weights(Q, R)
    return lin.F, lin.B, lin.C, inflow_matrix(plant), Q, R, Cz, Dzu


def _route_cases():
    A, B, C, Bw, Q, R = _three_tank(False)
    Cz, Dzu = _weights(Q, R)
    yield "three_tank", GeneralizedPlant(A, B, Bw, Cz, Dzu)
    A, B, C, Bw, Q, R = _three_tank(True)
    yield "three_tank_discrete", GeneralizedPlant(A, B, Bw, Cz, Dzu, "discrete", 1.0)
    yield "three_tank_observer", observer_plant(A, C, Bw, np.diag([1e-3, 2e-3]), sla.sqrtm(Q).real,
                                                "discrete", 1.0)
    A, B, C, Bw, Q, R, Cz, Dzu = _tank_network_plant(8)
    yield "tank_network_8", GeneralizedPlant(A, B, Bw, Cz, Dzu)


@pytest.mark.parametrize("case", ["three_tank", "three_tank_discrete", "three_tank_observer",
                                  "tank_network_8"])
def test_riccati_and_lmi_routes_give_the_same_optimum(case):
    """N = 3 and 8: H2 optimum within 1e-6, H-infinity optimum within 1e-6 (relative)."""
    P = dict(_route_cases())[case]
    ric = synthesize_state_feedback(P, objective="hinf", backoff=0.0)
    lmi = synthesize_state_feedback(P, objective="hinf", backoff=0.0, route="lmi")
    assert (ric.route, lmi.route) == ("riccati", "lmi")
    assert ric.gamma_optimum == pytest.approx(lmi.gamma_optimum, rel=1e-6)
    # each gain reaches its claim (checked here with python-control's norm)
    dt = P.dt if P.domain == "discrete" else 0
    for res in (ric, lmi):
        Acl, Bcl, Ccl = P.closed_loop(res.gain_matrix)
        assert pc_hinf(control.ss(Acl, Bcl, Ccl, np.zeros((Ccl.shape[0], Bcl.shape[1])), dt)) \
            <= res.gamma * (1 + 1e-6)
    ric2 = synthesize_state_feedback(P, objective="h2")
    lmi2 = synthesize_state_feedback(P, objective="h2", route="lmi")
    assert (ric2.route, lmi2.route) == ("riccati", "lmi")
    assert ric2.h2 == pytest.approx(lmi2.h2, rel=1e-6)
    assert ric2.achieved_h2[0] == pytest.approx(lmi2.achieved_h2[0], rel=1e-6)


def test_riccati_backoff_gives_the_central_gain_above_the_optimum():
    P = dict(_route_cases())["three_tank"]
    res = synthesize_state_feedback(P, objective="hinf", backoff=1e-3)
    assert res.gamma == pytest.approx(res.gamma_optimum * (1 + 1e-3), rel=1e-12)
    assert res.gamma_optimum <= res.achieved_hinf[0] * (1 + 1e-6) <= res.gamma * (1 + 2e-6)
    assert res.scaling["gamma_bracket"][0] <= res.gamma_optimum


def test_route_choice_and_refusal():
    A, B, _, Bw, Q, R = _three_tank(True)
    Cz, Dzu = _weights(Q, R)
    P = GeneralizedPlant(A, B, Bw, Cz, Dzu, "discrete", 1.0)
    with pytest.raises(SpecError) as exc:
        synthesize_state_feedback(P, objective="hinf", region=disk(0.9, 0.08), route="riccati")
    assert exc.value.key == "route" and "pole region" in str(exc.value)
    with pytest.raises(SpecError) as exc:
        synthesize_state_feedback(P, objective="hinf", route="newton")
    assert exc.value.key == "route"
    res = synthesize_state_feedback(P, objective="hinf", region=disk(0.9, 0.08))
    assert res.route == "lmi" and "pole region" in res.scaling["route_note"]
    # Dzu' Dzu singular (one input unweighted): auto falls back to the LMIs
    Dzu1 = Dzu.copy()
    Dzu1[:, 1] = 0.0
    res = synthesize_state_feedback(GeneralizedPlant(A, B, Bw, Cz, Dzu1, "discrete", 1.0),
                                    objective="h2", hinf_bound=None, route="auto")
    assert res.route == "lmi" and "singular" in res.scaling["route_note"]


def test_spec_route_option_reaches_the_design():
    """The example's hinf_state_feedback entry: route "auto" (Riccati) and "lmi" agree; bad route named."""
    import dataclasses
    from pathlib import Path

    from tanksynth.errors import TanksynthError
    from tanksynth.methods import design, load_spec

    spec = load_spec(Path(__file__).resolve().parents[2] / "examples" / "three_tank_hinf.toml")
    entry = next(d for d in spec.designs if d.method == "hinf_state_feedback")
    auto = design(spec, entry)
    lmi = design(spec, dataclasses.replace(entry, options={**entry.options, "route": "lmi"}))
    assert (auto.diagnostics["route"], lmi.diagnostics["route"]) == ("riccati", "lmi")
    a, b = auto.diagnostics["synthesis"], lmi.diagnostics["synthesis"]
    assert a["gamma_lmi_optimum"] == pytest.approx(b["gamma_lmi_optimum"], rel=1e-5)
    with pytest.raises(TanksynthError, match="route"):
        design(spec, dataclasses.replace(entry, options={**entry.options, "route": "newton"}))


_WARN_SPEC = """
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "hinf"
method = "hinf_state_feedback"
"""


@pytest.mark.parametrize("std, warned", [(None, False), (5e-6, False), (1.0, True)])
def test_disturbances_far_beyond_the_pumps_are_warned(std, warned):
    """disturbance_std = 1 m^3/s with Bw = "inflows" is 8,333 x the 1.2e-4 m^3/s pump (the
    default "auto" is 10 % of it)."""
    import warnings as _w

    from tanksynth.errors import DesignWarning
    from tanksynth.methods import METHODS, parse_spec_text

    text = _WARN_SPEC + ("" if std is None else f"disturbance_std = {std}\n")
    spec = parse_spec_text(text)
    with _w.catch_warnings(record=True) as caught:
        _w.simplefilter("always")
        res = METHODS["hinf_state_feedback"].design(spec, spec.designs[0])
    lines = [str(w.message) for w in caught if issubclass(w.category, DesignWarning)]
    hit = [line for line in lines if "faster than the pumps" in line]
    assert bool(hit) is warned
    assert bool([line for line in res.diagnostics.get("warnings", []) if "faster than the pumps" in line]) is warned
    if warned:  # B = 1/A per pump, range 1.2e-4: ratio (1/A) / (1.2e-4/A) = 8333
        assert "8.33e+03 times" in hit[0] and "m^3/s" in hit[0]


# ------------------------------------------------ direct Clarabel route vs hand-written cvxpy
def _small_plant():
    """A 3-state plant with an unstable mode, entries of order one (no scaling needed)."""
    A = np.array([[0.5, 1.0, 0.0], [0.0, -1.0, 1.0], [1.0, 0.0, -2.0]])
    B = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    Bw = 0.5 * np.eye(3)
    Cz = np.vstack([np.eye(3), np.zeros((2, 3))])
    Dzu = np.vstack([np.zeros((3, 2)), 0.3 * np.eye(2)])
    return A, B, Bw, Cz, Dzu


def _cvxpy_optimum(objective: str, region, eps: float = 1e-9) -> float:
    """min ||T_zw|| over K with eig(A - BK) in ``region``, written here in cvxpy (Clarabel)."""
    import cvxpy as cp

    A, B, Bw, Cz, Dzu = _small_plant()
    n, m, nw, nz = 3, 2, 3, 5
    X, Y = cp.Variable((n, n), symmetric=True), cp.Variable((m, n))
    AX, CX = A @ X - B @ Y, Cz @ X - Dzu @ Y
    cons = [X >> eps * np.eye(n)]
    L, M = region.L, region.M
    R = cp.kron(L, X) + cp.kron(M, AX) + cp.kron(M.T, AX.T)
    cons.append(0.5 * (R + R.T) << -eps * np.eye(R.shape[0]))
    if objective == "h2":
        W = cp.Variable((nz, nz), symmetric=True)
        cons += [AX + AX.T + Bw @ Bw.T << -eps * np.eye(n),
                 cp.bmat([[W, CX], [CX.T, X]]) >> eps * np.eye(nz + n)]
        prob = cp.Problem(cp.Minimize(cp.trace(W)), cons)
        prob.solve(solver="CLARABEL")
        return float(np.sqrt(prob.value))
    g = cp.Variable()
    brl = cp.bmat([[AX + AX.T, Bw, CX.T], [Bw.T, -g * np.eye(nw), np.zeros((nw, nz))],
                   [CX, np.zeros((nz, nw)), -g * np.eye(nz)]])
    cons.append(0.5 * (brl + brl.T) << -eps * np.eye(n + nw + nz))
    prob = cp.Problem(cp.Minimize(g), cons)
    prob.solve(solver="CLARABEL")
    return float(prob.value)


@pytest.mark.parametrize("objective", ["h2", "hinf"])
def test_direct_clarabel_route_meets_a_hand_written_cvxpy_problem(objective):
    """The LMIs written straight in Clarabel's conic form (no cvxpy) reach the optimum a plain
    cvxpy formulation of the same problem reaches (H2: h2 LMIs + region; H-infinity: the
    reduced bounded real lemma + region against the full one here)."""
    region = half_plane(0.8)
    res = synthesize_state_feedback(GeneralizedPlant(*_small_plant()), objective=objective,
                                    region=region)
    assert res.solver == "CLARABEL" and res.route == "lmi"
    got = res.h2_optimum if objective == "h2" else res.gamma_optimum
    ref = _cvxpy_optimum(objective, region)
    assert got == pytest.approx(ref, rel=1e-5)
    assert np.all(np.real(res.closed_loop_eigenvalues[0]) < -0.8)


def test_scs_route_through_cvxpy_meets_the_clarabel_route():
    """solver = "SCS" still builds the same LMIs in cvxpy: same optimum to SCS's accuracy (with a
    margin SCS can resolve: at 1e-9 its first-order solution misses the strict LMIs)."""
    region = half_plane(0.8)
    a = synthesize_state_feedback(GeneralizedPlant(*_small_plant()), objective="hinf", region=region,
                                  margin=1e-3)
    b = synthesize_state_feedback(GeneralizedPlant(*_small_plant()), objective="hinf", region=region,
                                  solver="SCS", margin=1e-3)
    assert b.solver == "SCS"
    assert b.gamma_optimum == pytest.approx(a.gamma_optimum, rel=1e-3)


def test_bound_just_below_the_optimum_is_refused_on_the_certificate_with_distinct_digits():
    """Issue 30 item 16: a bound 1.5e-6 (relative) below the LMI optimum is refused because it is
    below the smallest bound the same LMIs admit (not on a solver status), and the two numbers
    are printed with the digits that tell them apart."""
    import re

    A, B, _, Bw, Q, R = _three_tank(True)
    Cz, Dzu = _weights(Q, R)
    P = GeneralizedPlant(A, B, Bw, Cz, Dzu, "discrete", 1.0)
    region = disk(0.9, 0.08)
    free = synthesize_state_feedback(P, objective="hinf", region=region)
    best = free.gamma_optimum
    # independent: python-control's norm of that closed loop never exceeds the LMI optimum
    Acl, Bcl, Ccl = P.closed_loop(free.gain_matrix)
    achieved = pc_hinf(control.ss(Acl, Bcl, Ccl, 0, 1.0))
    assert achieved <= best * (1 + 1e-6)
    requested = best * (1 - 1.5e-6)
    assert f"{requested:.6g}" == f"{best:.6g}"          # the old message printed them identically
    with pytest.raises(InfeasibleDesign) as exc:
        synthesize_state_feedback(P, objective="hinf", hinf_bound=requested, region=region)
    text = str(exc.value)
    found = re.search(r"requested H-infinity bound ([0-9.e+-]+) is below ([0-9.e+-]+), the smallest", text)
    assert found, text
    asked, least = found.groups()
    assert asked != least and float(asked) < float(least)
    assert float(asked) == pytest.approx(requested, rel=10 ** -(len(asked.replace("0.", "")) - 1))
    assert float(least) == pytest.approx(best, rel=1e-6) and float(least) >= achieved * (1 - 1e-6)


def test_empty_region_is_refused_before_solving_naming_s_in_continuous_time():
    """Issue 30 item 16: Re s < -0.5 and |s - 0.3| < 0.1 do not intersect: refused as an empty
    region (bad input), whatever the plant, in the s-plane's letter."""
    from tanksynth.design.placement.regions import lmi_state_feedback

    A, B, _, Bw, Q, R = _three_tank(False)
    Cz, Dzu = _weights(Q, R)
    empty = half_plane(0.5) & disk(0.3, 0.1)
    with pytest.raises(SpecError, match="empty") as exc:
        lmi_state_feedback(A, B, empty, domain="continuous")
    assert "Re s < -0.5" in str(exc.value) and "|s - 0.3| < 0.1" in str(exc.value)
    assert " z" not in str(exc.value)
    P = GeneralizedPlant(A, B, Bw, Cz, Dzu, "continuous", None)
    with pytest.raises(SpecError, match="empty"):
        synthesize_state_feedback(P, objective="hinf", region=empty)
