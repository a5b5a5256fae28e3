"""Default disturbance size of the H2 / H-infinity designs (``disturbance_std = "auto"``).

The old default (1 disturbance unit: 1 m^3/s on the SI three-tank, 8,333 times its pumps) gave a
warning and a deadbeat-like observer (error eigenvalues ~1e-8). "auto" scales each inflow to 10 %
of the pumps' authority, in the plant's own units (m^3/s for three_tank, cm^3/s for tank_network).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tanksynth.artefacts.io import artefact_document
from tanksynth.errors import DesignWarning, SpecError
from tanksynth.methods import METHODS, parse_spec_text
from tanksynth.verify.synthesis.verdicts import synthesis_verdict

THREE_TANK = """
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
"""
TANK_NETWORK = """
[plant]
model = "tank_network"
N = 8
[operating_point]
x = [21.70591608, 22.54471524, 21.70591608, 22.54471524, 9.04293578, 5.08665138, 9.04293578, 5.08665138]
u = [4.0, 4.0, 4.0, 4.0]
[sampling]
ts = 1.0
"""
PLANTS = {"three_tank": THREE_TANK, "tank_network": TANK_NETWORK}


def _spec(plant: str, method: str, extra: str = ""):
    return parse_spec_text(PLANTS[plant] + f'[[design]]\nname = "d"\nmethod = "{method}"\n' + extra)


def _design(spec):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = METHODS[spec.designs[0].method].design(spec, spec.designs[0])
    return res, [str(w.message) for w in caught if issubclass(w.category, DesignWarning)]


def _expected_auto_std(spec) -> np.ndarray:
    """10 % of the largest level rate a pump gives at full range, as an inflow into each tank.

    Built from the plant's parameters (not the tool's Jacobian): three_tank's pumps are inflows
    of at most qmax into tanks of area A; tank_network's pump j sends gamma_j k_j u_j to its lower
    tank and (1 - gamma_j) k_j u_j to an upper tank, u_j in [0, usat].
    """
    p = {q.name: float(q.value) for q in spec.plant.parameters}
    if spec.plant.name == "three_tank":
        return np.full(3, 0.1 * p["qmax"])   # B = 1/A per pump, Bw = 1/A per inflow
    N = spec.plant.n
    half = N // 2
    rates = []
    for j in range(1, half + 1):
        lower = j
        upper = half + 1 if j == half else half + j + 1
        rates.append(p[f"gamma{j}"] * p[f"k{j}"] * p["usat"] / p[f"A{lower}"])
        rates.append((1 - p[f"gamma{j}"]) * p[f"k{j}"] * p["usat"] / p[f"A{upper}"])
    return np.array([0.1 * max(rates) * p[f"A{i}"] for i in range(1, N + 1)])


@pytest.mark.parametrize("plant", ["three_tank", "tank_network"])
@pytest.mark.parametrize("method", ["hinf_observer", "h2_observer"])
def test_default_observer_is_sized_by_the_pumps_and_not_deadbeat(plant, method):
    spec = _spec(plant, method)
    res, warned = _design(spec)
    assert not [w for w in warned if "faster than the pumps" in w]
    std = np.asarray(res.diagnostics["disturbances"]["disturbance_std"])
    np.testing.assert_allclose(std, _expected_auto_std(spec), rtol=1e-9)
    if plant == "three_tank":   # 10 % of the 1.2e-4 m^3/s pump
        np.testing.assert_allclose(std, 1.2e-5, rtol=1e-9)
    A, C, L = (np.asarray(res.gains[k], float) for k in ("Ad", "C", "L"))
    err = np.abs(np.linalg.eigvals(A - L @ C))
    rho_open = np.max(np.abs(np.linalg.eigvals(A)))
    # Non-degenerate: the old default put error eigenvalues at ~1e-8 (the estimate copies the
    # noisy measurement). A sane filter is stable, faster than the plant's slowest mode (else
    # the output injection does nothing) but not deadbeat: every error mode keeps |z| > 1e-3
    # and the slowest one a time constant of at least ts / ln(10) = 0.43 s (|z| >= 0.1).
    assert np.all(err > 1e-3), err
    assert 0.1 <= err.max() < rho_open, (err, rho_open)
    checks = synthesis_verdict(artefact_document(res, spec.sha256), spec)
    assert not {c.name: c.detail for c in checks if c.passed is not True}


def test_user_disturbance_std_is_kept_and_an_absurd_one_warns_in_plant_units():
    res, warned = _design(_spec("three_tank", "hinf_observer", "disturbance_std = 5e-6\n"))
    assert res.diagnostics["disturbances"]["disturbance_std"] == [5e-6] * 3 and not warned
    res, warned = _design(_spec("three_tank", "hinf_observer", 'disturbance_std = "auto"\n'))
    np.testing.assert_allclose(res.diagnostics["disturbances"]["disturbance_std"], 1.2e-5)
    spec = _spec("tank_network", "h2_observer", "disturbance_std = 1e4\n")
    _, warned = _design(spec)
    hit = [w for w in warned if "faster than the pumps" in w]
    # 1e4 cm^3/s into a 28 cm^2 tank against 0.7 x 3.33 x 10 / 28 cm/s from a pump: 1e4 / 23.31
    ratio = 1e4 / (0.7 * 3.33 * 10.0)
    assert hit and f"{ratio:.3g} times" in hit[0] and "cm^3/s" in hit[0]


def test_a_misspelt_auto_is_refused_with_its_key():
    with pytest.raises(SpecError, match="disturbance_std"):
        _spec("three_tank", "h2_observer", 'disturbance_std = "autp"\n')


ROBUST = THREE_TANK.replace('outputs = "h1h2"', 'outputs = "all"')


@pytest.mark.parametrize("method, region, gamma", [
    ("robust_observer", '[{type = "disk", center = 0.5, radius = 0.4}]', 0.005),
    ("robust_state_feedback", '[{type = "disk", center = 0.9, radius = 0.08}]', 0.02)])
def test_robust_hinf_channel_defaults_to_pump_sized_disturbances(method, region, gamma):
    """With gamma and no Bw: B diag(0.1 range) (state feedback) or 0.1 max|B| range I (observer).

    Three-tank: B = [I2; 0] / A per m^3/s, range qmax, so both are 0.1 qmax / A (m/s) per unit
    w; the old defaults (B, I: 1 m^3/s or 1 m/s) made gamma a number in units no pump reaches.
    """
    from tanksynth.verify.robust.verdicts import robust_observer_verdict, robust_state_feedback_verdict

    spec = parse_spec_text(ROBUST + f'[[design]]\nname = "d"\nmethod = "{method}"\n'
                           f'uncertain = {{mu13 = "15%"}}\nregion = {region}\ngamma = {gamma}\n')
    p = {q.name: float(q.value) for q in spec.plant.parameters}
    s = 0.1 * p["qmax"] / p["A"]
    want = s * (np.eye(3) if method == "robust_observer" else np.eye(3)[:, :2])
    np.testing.assert_allclose(spec.designs[0].config.Bw, want, rtol=1e-9)
    res = METHODS[method].design(spec, spec.designs[0])
    verdict = robust_observer_verdict if method == "robust_observer" else robust_state_feedback_verdict
    checks = {c.name: c for c in verdict(artefact_document(res, spec.sha256), spec)}
    assert not {k: c.detail for k, c in checks.items() if c.passed is not True}
    assert "vertex_hinf" in checks
    # without gamma the channel is unused and Bw stays unset (None: the old per-vertex default)
    spec = parse_spec_text(ROBUST + f'[[design]]\nname = "d"\nmethod = "{method}"\nregion = {region}\n')
    assert spec.designs[0].config.Bw is None
