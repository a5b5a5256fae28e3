"""Verdict of the TS PDC set-point change (tanksynth.verify.takagi_sugeno.setpoint) and the region campaign
runner (tanksynth.verify.takagi_sugeno.campaign)."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from tanksynth.methods import METHODS, load_spec
from tanksynth.sim.scenarios import scenario
from tanksynth.verify.takagi_sugeno.campaign import TsRegionRun, region_draws, ts_control_run
from tanksynth.verify.takagi_sugeno.verdicts import ts_control_verdict
from tanksynth.verify.takagi_sugeno.setpoint import max_on_ellipsoid, setpoint_checks
from tanksynth.verify.traces import TraceRecorder

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "three_tank_ts_control.toml"


@pytest.fixture(scope="module")
def pdc():
    spec = load_spec(EXAMPLE)
    entry = next(e for e in spec.designs if e.name == "pdc")
    res = METHODS[entry.method].design(spec, entry)
    doc = {"name": res.name, "method": res.method, "plant": res.plant,
           "gains": {k: np.asarray(v, float) for k, v in res.gains.items()},
           "diagnostics": res.diagnostics}
    return spec, doc


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_max_on_ellipsoid_against_dense_sampling(seed):
    rng = np.random.default_rng(seed)
    A, B = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    P1, P2 = A @ A.T + np.eye(3), B @ B.T + 0.3 * np.eye(3)
    d = rng.normal(size=3)
    U = rng.normal(size=(400_000, 3))
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    Z = np.linalg.solve(np.linalg.cholesky(P1).T, U.T).T * np.sqrt(2.0)
    sampled = np.max(np.einsum("mi,ij,mj->m", Z - d, P2, Z - d))
    exact = max_on_ellipsoid(P1, 2.0, P2, d)
    assert sampled <= exact * (1 + 1e-9)
    assert exact == pytest.approx(sampled, rel=1e-3)


def test_max_on_ellipsoid_hard_case():
    """Centre on an axis orthogonal to the top eigenvector: the maximiser fills that direction."""
    P2 = np.diag([1.0, 4.0])
    d = np.array([0.1, 0.0])          # orthogonal to the top eigenvector (0, 1)
    # on z1^2 + z2^2 = 1: (z1 - 0.1)^2 + 4 (1 - z1^2) = -3 z1^2 - 0.2 z1 + 4.01, largest at
    # z1 = -1/30: 4.01 + 0.01/3
    assert max_on_ellipsoid(np.eye(2), 1.0, P2, d) == pytest.approx(4.01 + 0.01 / 3, rel=1e-9)


@pytest.mark.slow
def test_setpoint_verdict_passes_and_records_the_runs(pdc):
    spec, doc = pdc
    rec = TraceRecorder()
    checks = {c.name: c for c in ts_control_verdict(doc, spec, trace=rec)}
    for name in ("setpoint_lmi_recheck", "setpoint_region_recheck", "setpoint_simulation"):
        assert checks[name].passed, (name, checks[name].detail)
    data = checks["setpoint_simulation"].data
    assert data["runs"] == 24 and data["left_domain"] == 0 and data["saturated"] == 0
    assert data["max_final_error"] <= 0.002 and data["max_switch_level"] <= 1
    arr = rec.trace["arrays"]
    assert arr["x"].shape[0] == 24                     # every region run kept for the figure
    assert arr["setpoint_x"].shape[0] == 12 and arr["setpoint_x"].shape[1] == arr["setpoint_t"].size
    assert np.allclose(arr["setpoint_x"][:, -1], doc["gains"]["sp_x_op"], atol=0.002)


@pytest.mark.slow
def test_tampered_setpoint_artefacts_fail(pdc):
    spec, doc = pdc
    wide = copy.deepcopy(doc)
    wide["gains"]["sp_switch_level"] = np.array([min(1.0, 1.5 * float(doc["gains"]["sp_switch_level"][0]))])
    region = {c.name: c for c in setpoint_checks(wide, spec)}["setpoint_region_recheck"]
    assert region.passed is False and region.data["switch_max_level"] > 1
    bad = copy.deepcopy(doc)
    bad["gains"]["sp_K"] = -np.asarray(doc["gains"]["sp_K"])
    checks = {c.name: c for c in setpoint_checks(bad, spec)}
    assert checks["setpoint_lmi_recheck"].passed is False
    assert checks["setpoint_simulation"].passed is False


@pytest.mark.slow
def test_region_draws_cover_boundary_and_interior(pdc):
    spec, doc = pdc
    P, c = doc["gains"]["P"], float(doc["gains"]["region_c"][0])
    E, eps = region_draws(doc, spec, list(range(40)), "servo")
    assert eps is None
    V = np.einsum("mi,ij,mj->m", E, P, E) / c
    on = np.isclose(V, (1 - 1e-6) ** 2, rtol=1e-9)
    assert on.any() and (~on).any() and np.all(V <= 1)
    E2, _ = region_draws(doc, spec, list(range(40)), "regulatory")
    assert not np.allclose(E, E2)                       # other scenario, other samples
    again, _ = region_draws(doc, spec, list(range(40)), "servo")
    assert np.array_equal(E, again)                     # seeded


@pytest.mark.slow
def test_campaign_run_judges_region_and_setpoint_like_the_verdict(pdc):
    spec, doc = pdc
    run = ts_control_run(doc, spec)
    assert isinstance(run, TsRegionRun) and run.kind == "controller"
    m = run.evaluate(scenario("servo"), spec.plant, ts=1.0, seeds=[11, 12, 13])
    for key in ("region_passed", "setpoint_passed"):
        assert np.all(m[key].values == 1.0), key
    assert np.all(m["setpoint_final_error"].values <= 0.002)
    assert "ise_h1" in m or any(k.startswith("ise_") for k in m)   # the scenario's metrics too
    # a destabilising gain is caught by the same conditions
    bad = copy.deepcopy(doc)
    bad["gains"]["K"] = -np.asarray(doc["gains"]["K"])
    mb = ts_control_run(bad, spec).evaluate(scenario("servo"), spec.plant, ts=1.0, seeds=[11, 12])
    assert np.all(mb["region_passed"].values == 0.0)
