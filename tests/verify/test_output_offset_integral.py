"""Integral action tracks the MEASURED output ``y = h(x)``, offsets included.

A three-tank whose h1 sensor reads 3 mm high, ``y1 = h1 + b1`` (b1 = 0.003 m): the integrators
must integrate ``y_r - y`` (here ``y_r - y_op - C1 (x - x_op)`` with ``y_op = h(x_op)``, the same
for this affine ``h``), so that the loop settles with ``y1`` at its set-point, i.e. ``h1`` at
``r1 - b1``. Integrating ``y_r - C1 x`` instead (C1 = [1 0 0] here, the offset dropped) drove h1
to ``r1`` and left ``y1`` 3 mm above its set-point.

The references are hand derived: at a steady state of the plant with mu13 = mu32, tank 3's
inflow equals its outflow, ``sqrt(h1 - h3) = sqrt(h3 - h2)``, so ``h3 = (h1 + h2) / 2``.
"""

from __future__ import annotations

import shutil

import casadi as ca
import numpy as np
import pytest

from tanksynth.artefacts.export import compile_law, load_compiled_law
from tanksynth.artefacts.io import read_artefact
from tanksynth.cli import main
from tanksynth.methods import parse_spec_text, verify_directory
from tanksynth.sim.simulate import run_seeds, simulate
from tanksynth.verify.batch_call import CasadiIntegralLaw

B1 = 0.003          # m, offset of the h1 sensor
TS = 2.0            # s

SPEC = f"""
title = "three-tank whose h1 sensor reads 3 mm high"
[plant]
model = "custom"
name = "three_tank_offset"
orderings = ["h1 > h3", "h3 > h2"]
[plant.states]
h1 = {{unit = "m", min = 0.0, max = 0.62}}
h2 = {{unit = "m", min = 0.0, max = 0.62}}
h3 = {{unit = "m", min = 0.0, max = 0.62}}
[plant.inputs]
q1 = {{unit = "m^3/s", min = 0.0, max = 1.2e-4}}
q2 = {{unit = "m^3/s", min = 0.0, max = 1.2e-4}}
[plant.parameters]
A = {{value = 0.0154, unit = "m^2"}}
Phi = {{value = 5e-5, unit = "m^2"}}
g = {{value = 9.81, unit = "m/s^2"}}
mu13 = {{value = 0.5}}
mu32 = {{value = 0.5}}
mu20 = {{value = 0.675}}
b1 = {{value = {B1}, unit = "m"}}
[plant.equations]
h1 = "(q1 - mu13*Phi*sign(h1 - h3)*sqrt(2*g*abs(h1 - h3)))/A"
h2 = "(q2 + mu32*Phi*sign(h3 - h2)*sqrt(2*g*abs(h3 - h2)) - mu20*Phi*sqrt(2*g*h2))/A"
h3 = "(mu13*Phi*sign(h1 - h3)*sqrt(2*g*abs(h1 - h3)) - mu32*Phi*sign(h3 - h2)*sqrt(2*g*abs(h3 - h2)))/A"
[plant.outputs]
y1 = {{expr = "h1 + b1", unit = "m"}}
y2 = {{expr = "h2", unit = "m"}}
[operating_point]
x = {{h1 = 0.40, h2 = 0.20, h3 = 0.30}}
[sampling]
ts = {TS}
[[design]]
name = "pp"
method = "pole_placement"
target = "state_feedback"
integral = true
tracked = ["y1", "y2"]
poles = [0.93, 0.94, 0.95, 0.92, 0.91]
[[design]]
name = "robust"
method = "robust_state_feedback"
uncertain = {{mu20 = "5%"}}
integral = true
tracked = ["y1", "y2"]
region = [{{type = "disk", center = 0.9, radius = 0.05}}]
[[design]]
name = "it"
method = "integral_tracking"
tracked = ["y1", "y2"]
poles = [0.93, 0.94, 0.95, 0.92, 0.91]
"""

X_OP = np.array([0.40, 0.20, 0.30])
NAMES = ("pp", "robust", "it")


def _h(x: np.ndarray) -> np.ndarray:
    """The sensors by hand: y1 = h1 + b1, y2 = h2 (m)."""
    return np.array([x[0] + B1, x[1]])


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    d = tmp_path_factory.mktemp("offset")
    (d / "spec.toml").write_text(SPEC, encoding="utf-8")
    assert main(["design", str(d / "spec.toml"), "-o", str(d / "out"), "--export", "law"]) == 0
    return d / "out"


def test_the_recorded_operating_outputs_include_the_offset(out):
    """The artefacts record y_op = h(x_op) of the tracked outputs, not C1 x_op."""
    for name in ("pp", "robust"):
        integ = read_artefact(out / f"{name}.json")["diagnostics"]["integral"]
        np.testing.assert_allclose(integ["y_op"], _h(X_OP), rtol=0, atol=1e-15)
    np.testing.assert_allclose(read_artefact(out / "it.json")["diagnostics"]["y0"], _h(X_OP),
                               rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", NAMES)
def test_exported_law_integrates_the_measured_output_error(out, name):
    """The serialised law and the compiled C: z_next = z + ts (y_r - h(x)) at any x."""
    x, z, yr = np.array([0.41, 0.195, 0.305]), np.array([0.01, -0.02]), np.array([0.42, 0.21])
    expected = z + TS * (yr - _h(x))
    laws = [ca.Function.load(str(out / f"{name}_law.casadi"))]
    if shutil.which("gcc") is not None:
        lib = compile_law(out / f"{name}_law.c", out / f"{name}_law.so")
        laws.append(load_compiled_law(lib, f"{name}_law"))
    for law in laws:
        u, z_next = law(x, z, yr)
        if name == "it":   # back-calculation anti-windup: only while an input saturates
            lim = np.array([[0.0, 1.2e-4]] * 2)
            assert np.all((np.asarray(u).ravel() > lim[:, 0]) & (np.asarray(u).ravel() < lim[:, 1]))
        np.testing.assert_allclose(np.asarray(z_next, dtype=float).ravel(), expected, rtol=1e-12, atol=1e-15)
    header = (out / f"{name}_law.h").read_text(encoding="utf-8")
    statement = "y_r - y0 - C1 (x - x_op)" if name == "it" else "y_r - y_op - C1 (x - x_op)"
    assert statement in header[:header.index("*/")]


@pytest.mark.parametrize("name", NAMES)
def test_closed_loop_settles_with_the_output_at_its_reference(out, name):
    """The exported law on the nonlinear plant: y1 -> r1, so h1 -> r1 - b1 (not r1)."""
    spec = parse_spec_text(SPEC)
    r = np.array([0.41, 0.21])                  # set-points of y1, y2 (m)
    law = CasadiIntegralLaw(ca.Function.load(str(out / f"{name}_law.casadi")))
    doc = read_artefact(out / f"{name}.json")
    u0 = np.asarray(doc["gains"]["u_op"], dtype=float)
    steps = 1500
    res = simulate(spec.plant, ts=TS, steps=steps, x0=X_OP, seeds=run_seeds(0, 1), controller=law,
                   reference=np.tile(r, (steps + 1, 1)), u_init=u0)
    h1, h2 = r[0] - B1, r[1]
    expected = np.array([h1, h2, (h1 + h2) / 2])        # tank 3 balanced (mu13 = mu32)
    np.testing.assert_allclose(res.x[0, -1], expected, rtol=0, atol=2e-6)
    np.testing.assert_allclose(res.y[0, -1], r, rtol=0, atol=2e-6)


def test_verdicts_pass_on_the_offset_plant(out):
    """The servo checks and the robust Monte Carlo judge y against its set-points: they pass."""
    verdicts = {v.name: v for v in verify_directory(out)}
    for name, check in (("pp", "servo_tracking"), ("it", "servo_tracking"), ("robust", "monte_carlo")):
        c = next(c for c in verdicts[name].checks if c.name == check)
        assert c.passed, (name, c.detail)


@pytest.mark.parametrize("name", NAMES)
def test_campaign_loop_holds_the_levels_at_their_set_points(out, name, runners):
    """The campaign's scenarios move LEVEL set-points: the loop hands the law the outputs they
    give (y1 = r1 + b1), so the levels, not the sensors' readings, settle on the set-points."""
    from tanksynth.sim.scenarios import scenario
    from tanksynth.verify.laws.campaign import closed_loop_for

    spec = parse_spec_text(SPEC)
    doc = read_artefact(out / f"{name}.json")
    loop = closed_loop_for(doc, spec, runners[doc["method"]])
    assert loop.tracked == (0, 1)
    metrics = loop.evaluate(scenario("servo"), spec.plant, ts=TS, seeds=run_seeds(0, 1))
    offsets = {k: float(np.max(np.abs(m.values))) for k, m in metrics.items() if k.startswith("offset_")}
    assert len(offsets) == 2                         # offset_h1 (y1 is not h1) and offset_y2 (= h2)
    assert max(offsets.values()) < 3e-4, offsets     # the 3 mm offset is not left on h1
