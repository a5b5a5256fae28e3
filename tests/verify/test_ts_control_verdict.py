"""Verdict of the Takagi-Sugeno PDC controllers (tanksynth.verify.takagi_sugeno.verdicts)."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from tanksynth.methods import METHODS, load_spec
from tanksynth.verify.takagi_sugeno.campaign import ts_control_run
from tanksynth.verify.takagi_sugeno.verdicts import (rebuild_model, region_level, region_points,
                                                     simulate_region, ts_control_verdict)

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "three_tank_ts_control.toml"


pytestmark = pytest.mark.slow   # every test uses the TS controller designs and their closed-loop verdicts


def _doc(result):
    return {"name": result.name, "method": result.method, "plant": result.plant,
            "gains": {k: np.asarray(v).tolist() for k, v in result.gains.items()},
            "diagnostics": result.diagnostics}


@pytest.fixture(scope="module")
def designed():
    spec = load_spec(EXAMPLE)
    docs = {e.name: _doc(METHODS[e.method].design(spec, e)) for e in spec.designs}
    return spec, docs


def _by_name(checks):
    return {c.name: c for c in checks}


def test_state_feedback_verdict_passes(designed):
    spec, docs = designed
    checks = _by_name(ts_control_verdict(docs["pdc"], spec))
    for name in ("ts_model_recheck", "lmi_recheck", "region_recheck", "region_simulation"):
        assert checks[name].passed, (name, checks[name].detail)
    assert checks["region_simulation"].data["runs"] == 24


def test_output_feedback_verdict_passes(designed):
    spec, docs = designed
    checks = _by_name(ts_control_verdict(docs["pdc_output"], spec))
    assert all(c.passed for c in checks.values()), [(c.name, c.detail) for c in checks.values()]
    assert "observer_lmi_recheck" in checks


def test_wrong_gain_fails_the_lmi_recheck(designed):
    spec, docs = designed
    doc = copy.deepcopy(docs["pdc"])
    K = -np.asarray(doc["gains"]["K"])
    doc["gains"]["K"] = K.tolist()
    checks = _by_name(ts_control_verdict(doc, spec))
    assert checks["lmi_recheck"].passed is False
    assert checks["region_simulation"].passed is False


def test_edited_region_level_fails(designed):
    spec, docs = designed
    doc = copy.deepcopy(docs["pdc"])
    doc["gains"]["region_c"] = [2.0 * doc["gains"]["region_c"][0]]
    assert _by_name(ts_control_verdict(doc, spec))["region_recheck"].passed is False


def test_region_level_by_hand(designed):
    """c of a box-only region: the smallest (distance to a face)^2 / (P^-1)_ii and pump term."""
    spec, docs = designed
    doc = docs["pdc"]
    P = np.asarray(doc["gains"]["P"])
    K = np.asarray(doc["gains"]["K"])
    x0 = np.asarray(doc["gains"]["x_op"])
    Pi = np.linalg.inv(P)
    d = np.minimum(0.62 - x0, x0 - 0.05)
    margins = np.asarray(doc["diagnostics"]["input_margins"])
    by_hand = min(min(d[i] ** 2 / Pi[i, i] for i in range(3)),
                  min(margins[j] ** 2 / (K[i, j] @ Pi @ K[i, j]) for i in range(8) for j in range(2)))
    model = rebuild_model(spec.plant, doc)
    G, g = model.faces()
    assert region_level(P, K, G, g, margins) == pytest.approx(by_hand, rel=1e-12)


def test_inside_stays_outside_may_leave(designed):
    """From inside the certified region no run leaves the domain or saturates; from points far
    outside it (but inside the domain) the certificate does not hold, and some do."""
    spec, docs = designed
    doc = docs["pdc"]
    P = np.asarray(doc["gains"]["P"])
    c = float(doc["gains"]["region_c"][0])
    inside = region_points(P, c, 6, seed=3) * 0.95
    out = simulate_region(doc, spec, inside, horizon=300.0)
    assert not out["left_domain"].any() and not out["saturated"].any()
    # corners of the domain box: outside the region (it is inscribed in the box)
    x0 = np.asarray(doc["gains"]["x_op"])
    corners = np.array([[0.6, 0.06, 0.06], [0.06, 0.6, 0.6], [0.6, 0.6, 0.06]]) - x0
    assert np.all(np.einsum("mi,ij,mj->m", corners, P, corners) > c)
    far = simulate_region(doc, spec, corners, horizon=300.0)
    assert (far["left_domain"] | far["saturated"]).any()


def test_campaign_runner_is_a_closed_loop(designed):
    spec, docs = designed
    loop = ts_control_run(docs["pdc"], spec)
    assert loop.kind == "controller"
    x = np.asarray(docs["pdc"]["gains"]["x_op"])[None, :]
    u = loop.controller(x, np.zeros((1, 2)), 0.0)
    assert np.allclose(u, np.asarray(docs["pdc"]["gains"]["u_op"]))


def test_measured_premises_verdict_passes(tmp_path):
    """Every level measured: the PDC observer path (separation), re-checked and simulated."""
    text = EXAMPLE.read_text(encoding="utf-8").replace('outputs = "h1h2"', 'outputs = "all"')
    path = tmp_path / "all.toml"
    path.write_text(text, encoding="utf-8")
    spec = load_spec(path)
    entry = next(e for e in spec.designs if e.name == "pdc_output")
    doc = _doc(METHODS[entry.method].design(spec, entry))
    assert doc["diagnostics"]["premises"] == "measured"
    checks = _by_name(ts_control_verdict(doc, spec))
    assert all(c.passed for c in checks.values()), [(c.name, c.detail) for c in checks.values()]
    bad = copy.deepcopy(doc)
    bad["gains"]["L"] = (-np.asarray(doc["gains"]["L"])).tolist()
    assert _by_name(ts_control_verdict(bad, spec))["observer_lmi_recheck"].passed is False



def test_memberships_rebuild_the_plant_and_the_vertex_products(designed):
    """The rebuilt memberships (all vertices at once, issue 15) are the products
    ``prod_k F_k^(sigma_ik)`` taken vertex by vertex, sum to 1, and weight the vertex matrices
    into the plant's exact deviation dynamics ``f(x, u0) - f(x0, u0)``."""
    spec, docs = designed
    for name in ("pdc", "pdc_output"):
        model = rebuild_model(spec.plant, docs[name])
        X = model.x0 + np.random.default_rng(4).uniform(-0.1, 0.1, size=(50, 3))
        X[0] = model.x0                                   # the secants' removable point
        X = X[model.inside(X)]
        mu = model.memberships(X)
        # first partitions by hand: secant slope of each atom from x0 along its form
        e = X - model.x0
        dt = e @ model.forms.T
        at = model.q.atom_values(X) - model.q.atom_values(model.x0[None, :])
        Z = np.where(np.abs(dt) < 1e-12, model.slope0, at / np.where(dt == 0, 1.0, dt))
        F1 = (Z - model.lower) / (model.upper - model.lower)
        ref = np.ones_like(mu)
        for i, sig in enumerate(model.sigmas):
            for k, s in enumerate(sig):
                ref[:, i] = ref[:, i] * (F1[:, k] if s == 1 else 1.0 - F1[:, k])
        np.testing.assert_array_equal(mu, ref)
        np.testing.assert_allclose(mu.sum(axis=1), 1.0, rtol=0, atol=1e-12)
        u0 = np.tile(model.u0, (len(X), 1))
        rhs = spec.plant.compiled.rhs
        f = np.asarray(rhs(X, u0)) - np.asarray(rhs(np.tile(model.x0, (len(X), 1)), u0))
        np.testing.assert_allclose(np.einsum("mi,ink,mk->mn", mu, model.A, e), f,
                                   rtol=0, atol=1e-9 * np.abs(f).max())


def test_pdc_law_is_the_membership_weighted_gain(designed):
    """``u = u0 - sum_j mu_j K_j (x_hat - x0)``, premises at ``x_hat`` or at given states
    (the law's batched products against a loop over runs and rules)."""
    from tanksynth.verify.takagi_sugeno.loops import PDCLaw

    spec, docs = designed
    doc = docs["pdc"]
    model = rebuild_model(spec.plant, doc)
    K = np.asarray(doc["gains"]["K"]).reshape(len(model.sigmas), 2, 3)
    law = PDCLaw(model, K)
    rng = np.random.default_rng(7)
    X = model.x0 + rng.uniform(-0.05, 0.05, size=(9, 3))
    XZ = model.x0 + rng.uniform(-0.05, 0.05, size=(9, 3))
    for premises in (None, XZ):
        mu = model.memberships(X if premises is None else premises)
        ref = np.array([model.u0 - sum(mu[m, j] * (K[j] @ (X[m] - model.x0)) for j in range(len(K)))
                        for m in range(len(X))])
        np.testing.assert_allclose(law.raw(X, premises), ref, rtol=1e-13, atol=1e-20)
    np.testing.assert_allclose(law(X, None, 0.0), law.raw(X), rtol=0, atol=0)
