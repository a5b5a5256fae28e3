"""``--export law`` for the synthesis, robust and Takagi-Sugeno methods
(`tanksynth.artefacts.synthesis_laws`).

Every law is exported by ``tanksynth design --export law``, its generated C compiled with gcc
and evaluated, and compared on sampled states with what the method's verdict and campaign
runner simulate (`tanksynth.verify.simulations`, `tanksynth.verify.robust.campaign`,
`tanksynth.verify.takagi_sugeno.verdicts`, `tanksynth.verify.observer_lmi.verdicts`): the same control, and for the
observers the same next estimate (continuous-time fields integrated here with the verifier's
own rule: exact ZOH, RK4 with held premises, exponential Euler), to 1e-10 relative.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla

from tanksynth.artefacts.export import compile_law, load_compiled_law
from tanksynth.artefacts.io import read_artefact
from tanksynth.cli import main

pytestmark = [pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is needed to compile laws"),
              pytest.mark.slow]   # every test compiles the laws of designs made for the module

HEAD = """
[plant]
model = "three_tank"
outputs = "{outputs}"
[operating_point]
x = {{h1 = 0.40, h2 = 0.20, h3 = 0.30}}
"""

SYNTHESIS = 'title = "synthesis laws"' + HEAD.format(outputs="h1h2") + """
[sampling]
ts = 1.0
[[design]]
name = "h2sf"
method = "h2_state_feedback"
Bw = "inflows"
disturbance_std = 5e-6
[[design]]
name = "hinfsf_c"
method = "hinf_state_feedback"
time_domain = "continuous"
Bw = "inflows"
disturbance_std = 5e-6
[[design]]
name = "h2obs_c"
method = "h2_observer"
time_domain = "continuous"
disturbance_std = 5e-6
measurement_std = 1e-3
[[design]]
name = "hinfobs"
method = "hinf_observer"
disturbance_std = 5e-6
measurement_std = 1e-3
[[design]]
name = "mo_obs"
method = "multiobjective"
target = "observer"
objective = "h2"
disturbance_std = 5e-6
measurement_std = 1e-3
region = [{type = "disk", center = 0.5, radius = 0.45}]
"""

ROBUST = 'title = "robust laws"' + HEAD.format(outputs="all") + """
[sampling]
ts = 1.0
[[design]]
name = "rint"
method = "robust_state_feedback"
uncertain = {mu20 = "15%"}
integral = true
tracked = ["h1", "h2"]
region = [{type = "disk", center = 0.9, radius = 0.08}]
[[design]]
name = "rint_c"
method = "robust_state_feedback"
time_domain = "continuous"
uncertain = {mu20 = "15%"}
integral = true
tracked = ["h1", "h2"]
region = [{type = "half_plane", alpha = 0.01}, {type = "disk", center = 0.0, radius = 0.2}]
[[design]]
name = "rsf"
method = "robust_state_feedback"
uncertain = {mu20 = "15%"}
region = [{type = "disk", center = 0.93, radius = 0.06}]
[[design]]
name = "robs"
method = "robust_observer"
uncertain = {mu20 = "15%"}
region = [{type = "disk", center = 0.5, radius = 0.4}]
[[design]]
name = "robs_c"
method = "robust_observer"
time_domain = "continuous"
uncertain = {mu20 = "15%"}
region = [{type = "half_plane", alpha = 0.05}]
"""

TS = 'title = "TS laws"' + HEAD.format(outputs="all") + """
[[design]]
name = "pdc"
method = "ts_state_feedback"
domain = {h1 = [0.05, 0.62], h2 = [0.05, 0.62], h3 = [0.05, 0.62]}
decay_rate = 0.01
[[design]]
name = "pdc_meas"
method = "ts_output_feedback"
domain = {h1 = [0.05, 0.62], h2 = [0.05, 0.62], h3 = [0.05, 0.62]}
premises = "measured"
decay_rate = 0.01
[[design]]
name = "pdc_est"
method = "ts_output_feedback"
domain = {h1 = [0.05, 0.62], h2 = [0.05, 0.62], h3 = [0.05, 0.62]}
premises = "estimated"
orderings = true
ordering_gap = 0.07
region_margin = 0.002
"""

X_OP = np.array([0.40, 0.20, 0.30])
RNG = np.random.default_rng(16)
#: Sampled states around the operating point (m), and one at it.
STATES = np.vstack([X_OP, X_OP + RNG.uniform(-0.04, 0.04, size=(11, 3))])


def _design(root: Path, text: str) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    (root / "spec.toml").write_text(text, encoding="utf-8")
    assert main(["design", str(root / "spec.toml"), "-o", str(root / "out"), "--export", "law"]) == 0
    return root / "out"


@pytest.fixture(scope="module")
def syn(tmp_path_factory) -> Path:
    return _design(tmp_path_factory.mktemp("syn"), SYNTHESIS)


@pytest.fixture(scope="module")
def rob(tmp_path_factory) -> Path:
    return _design(tmp_path_factory.mktemp("rob"), ROBUST)


@pytest.fixture(scope="module")
def ts(tmp_path_factory) -> Path:
    return _design(tmp_path_factory.mktemp("ts"), TS)


def _load(out: Path, name: str):
    from tanksynth.methods import load_spec

    doc = read_artefact(out / f"{name}.json")
    doc["gains"] = {k: np.asarray(v, dtype=float) for k, v in doc["gains"].items()}
    return doc, load_spec(out / "spec.toml")


def _compiled(out: Path, name: str):
    lib = compile_law(out / f"{name}_law.c", out / f"{name}_law.so")
    return load_compiled_law(lib, f"{name}_law")


def _np(v) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(-1)


def _close(got, want, rel: float = 1e-10) -> None:
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    assert got.shape == want.shape
    scale = max(float(np.max(np.abs(want))), 1e-300)
    err = float(np.max(np.abs(got - want)))
    assert err <= rel * scale, f"largest difference {err:.3g} > {rel:g} x {scale:.3g}"


def _applied(spec, U: np.ndarray) -> np.ndarray:
    """The input the simulator applies: saturated to the pumps' range (`tanksynth.sim.simulate`)."""
    lim = np.asarray(spec.plant.input_limits, dtype=float)
    return np.minimum(np.maximum(U, lim[:, 0]), lim[:, 1])


def _io(law) -> tuple[list[str], list[str]]:
    return law.name_in(), law.name_out()


def test_every_method_exports_a_law(syn, rob, ts):
    for out, names in ((syn, ("h2sf", "hinfsf_c", "h2obs_c", "hinfobs", "mo_obs")),
                       (rob, ("rint", "rint_c", "rsf", "robs", "robs_c")),
                       (ts, ("pdc", "pdc_meas", "pdc_est"))):
        for name in names:
            for ext in (".casadi", ".c", ".h"):
                assert (out / f"{name}_law{ext}").is_file(), (name, ext)


# ------------------------------------------------------------------ state feedback
@pytest.mark.parametrize("name", ["h2sf", "hinfsf_c"])
def test_synthesis_state_feedback_is_the_verdicts(syn, name):
    from tanksynth.verify.common import operating_point
    from tanksynth.verify.simulations import StateFeedback
    from tanksynth.verify.synthesis.campaign import synthesis_run

    doc, spec = _load(syn, name)
    x0, u0 = operating_point(spec)
    verdict = StateFeedback(doc["gains"]["K"].reshape(2, 3), x0, u0)
    campaign = synthesis_run(doc, spec).controller
    law = _compiled(syn, name)
    assert _io(law) == (["x"], ["u"])
    for x in STATES:
        u = _np(law(x))
        _close(u, verdict(x[None], None, 0.0)[0])
        _close(u, campaign(x[None], None, 0.0)[0])
    np.testing.assert_array_equal(_np(law(X_OP)), u0)


def test_robust_state_feedback_is_the_campaigns(rob):
    from tanksynth.verify.robust.campaign import robust_state_feedback_run

    doc, spec = _load(rob, "rsf")
    run = robust_state_feedback_run(doc, spec)
    law = _compiled(rob, "rsf")
    for x in STATES:
        _close(_np(law(x)), run.controller(x[None], None, 0.0)[0])
    # the nominal equilibrium input at the operating point (the parameters are unknown to the law)
    np.testing.assert_array_equal(_np(law(X_OP)), doc["gains"]["u_op"])


@pytest.mark.parametrize("name", ["rint", "rint_c"])
def test_robust_integral_action_is_the_verdicts(rob, name):
    from tanksynth.verify.robust.campaign import robust_state_feedback_run

    doc, spec = _load(rob, name)
    controller = robust_state_feedback_run(doc, spec).controller   # IntegralStateFeedback, ts = 1 s
    law = _compiled(rob, name)
    assert _io(law) == (["x", "z", "y_r"], ["u", "z_dot" if name.endswith("_c") else "z_next"])
    controller.reset(len(STATES))
    Z = RNG.uniform(-0.05, 0.05, size=(len(STATES), 2))
    R = X_OP[:2] + RNG.uniform(-0.02, 0.02, size=(len(STATES), 2))
    controller.z = Z.copy()
    U = controller(STATES, R, 0.0)
    lo, hi = np.asarray(spec.plant.input_limits, dtype=float).T
    for k, x in enumerate(STATES):
        u, z_new = (_np(v) for v in law(x, Z[k], R[k]))
        _close(u, np.clip(U[k], lo, hi))        # clipped as the plant the verdict simulates clips it
        # discrete: z + ts (r - C1 x); continuous: the verdict's Euler step of z_dot over ts = 1 s
        _close(Z[k] + z_new if name.endswith("_c") else z_new, controller.z[k])
    # hand-written: z moves by ts (y_r - (h1, h2))
    _, z_new = law(STATES[3], Z[3], R[3])
    expected = (R[3] - STATES[3, :2]) if name.endswith("_c") else Z[3] + (R[3] - STATES[3, :2])
    np.testing.assert_allclose(_np(z_new), expected, rtol=1e-13, atol=1e-16)


# ------------------------------------------------------------------------ observers
def _measurements(plant, X: np.ndarray) -> np.ndarray:
    return np.asarray(plant.compiled.output(X), dtype=float)


@pytest.mark.parametrize("out_name", [("syn", "hinfobs"), ("syn", "mo_obs"), ("rob", "robs")])
def test_discrete_observer_step_is_the_runtime_observer(request, out_name):
    from tanksynth.verify.common import operating_point
    from tanksynth.verify.simulations import luenberger_estimator

    out = request.getfixturevalue(out_name[0])
    doc, spec = _load(out, out_name[1])
    plant = spec.plant
    x0, u0 = operating_point(spec)
    est = luenberger_estimator(plant, doc["gains"]["L"].reshape(3, plant.q), x0, u0, 1.0, "predictor")
    law = _compiled(out, out_name[1])
    assert _io(law) == (["x_hat", "u", "y"], ["x_hat_next"])
    M = len(STATES)
    U1 = u0 + RNG.uniform(-5e-6, 5e-6, size=(M, 2))
    U2 = u0 + RNG.uniform(-5e-6, 5e-6, size=(M, 2))
    Y1 = _measurements(plant, STATES + RNG.uniform(-0.01, 0.01, size=(M, 3)))
    est.reset(STATES.copy())
    X1 = est.step(Y1, U1).copy()          # first sample: no earlier measurement, open loop
    X2 = est.step(Y1, U2)                 # predictor: uses the measurement taken with X1
    for k in range(M):
        _close(_np(law(X1[k], U2[k], Y1[k])), X2[k])
    # the operating point is a fixed point
    np.testing.assert_allclose(_np(law(x0, u0, _measurements(plant, x0[None])[0])), x0, atol=1e-14)


@pytest.mark.parametrize("out_name", [("syn", "h2obs_c"), ("rob", "robs_c")])
def test_continuous_observer_field_integrates_to_the_runtime_observer(request, out_name):
    from tanksynth.verify.common import operating_point
    from tanksynth.verify.simulations import luenberger_estimator

    out = request.getfixturevalue(out_name[0])
    doc, spec = _load(out, out_name[1])
    plant = spec.plant
    n, m, q = plant.n, plant.m, plant.q
    x0, u0 = operating_point(spec)
    ts = 2.0
    est = luenberger_estimator(plant, doc["gains"]["L"].reshape(n, q), x0, u0, ts, "continuous")
    law = _compiled(out, out_name[1])
    assert _io(law) == (["x_hat", "u", "y"], ["x_hat_dot"])

    def field(x, u, y):
        return _np(law(x, u, y))

    # the field is affine in (x_hat, u, y): its matrices by unit differences (exact up to rounding)
    base = field(np.zeros(n), np.zeros(m), np.zeros(q))
    J = np.column_stack([field(*np.split(e, [n, n + m])) - base for e in np.eye(n + m + q)])
    M = len(STATES)
    U = u0 + RNG.uniform(-5e-6, 5e-6, size=(M, m))
    Y = _measurements(plant, STATES + RNG.uniform(-0.01, 0.01, size=(M, n)))
    est.reset(STATES.copy())
    X1 = est.step(Y, U).copy()
    X2 = est.step(Y, U)                   # exact ZOH of F - L C with u and the sample y held
    for k in range(M):
        aug = np.zeros((n + 1, n + 1))
        aug[:n, :n] = J[:, :n]
        aug[:n, n] = J[:, n:n + m] @ U[k] + J[:, n + m:] @ Y[k] + base
        E = sla.expm(aug * ts)
        _close(E[:n, :n] @ X1[k] + E[:n, n], X2[k])
    np.testing.assert_allclose(field(x0, u0, _measurements(plant, x0[None])[0]), 0.0, atol=1e-15)


# ------------------------------------------------------------------- Takagi-Sugeno
def test_pdc_state_feedback_is_the_verdicts_law(ts):
    from tanksynth.verify.takagi_sugeno.campaign import ts_control_run
    from tanksynth.verify.takagi_sugeno.verdicts import region_points

    doc, spec = _load(ts, "pdc")
    g = doc["gains"]
    pdc = ts_control_run(doc, spec).controller           # PDCLaw: the verdict's and the campaign's
    law = _compiled(ts, "pdc")
    assert _io(law) == (["x"], ["u"])
    # inside the certified region the pumps are not saturated: the law is the PDC itself
    inside = X_OP + region_points(g["P"], float(g["region_c"][0]), 16, 3) * (1 - 1e-6)
    # on premise singularities: the operating point, and x - x0 along (1, 1, 1), where
    # h1 - h3 and h3 - h2 keep their operating values (slopes at x0 used)
    special = np.array([X_OP, X_OP + 0.01, X_OP - 0.003])
    lim = np.asarray(spec.plant.input_limits, dtype=float)
    for x in np.vstack([inside, special]):
        want = pdc(x[None], None, 0.0)[0]
        assert np.all((want > lim[:, 0]) & (want < lim[:, 1]))
        _close(_np(law(x)), want)
    np.testing.assert_array_equal(_np(law(X_OP)), g["u_op"])
    # across the domain some inputs saturate: the law gives what the simulator applies
    box = RNG.uniform(0.06, 0.61, size=(40, 3))
    saturated = 0
    for x in box:
        raw = pdc(x[None], None, 0.0)[0]
        saturated += int(np.any((raw < lim[:, 0]) | (raw > lim[:, 1])))
        _close(_np(law(x)), _applied(spec, raw))
    assert saturated > 0


def test_pdc_output_feedback_measured_premises(ts):
    from tanksynth.verify.common import sampling_period
    from tanksynth.verify.takagi_sugeno.campaign import ts_control_run

    doc, spec = _load(ts, "pdc_meas")
    plant = spec.plant
    assert doc["gains"]["L"].ndim == 3
    run = ts_control_run(doc, spec)
    est = run.estimator_factory()                       # MeasuredPremiseObserver, 64 RK4 substeps
    law = _compiled(ts, "pdc_meas")
    assert _io(law) == (["x_hat", "u_applied", "y"], ["u", "x_hat_dot"])
    M = len(STATES)
    XH = STATES + RNG.uniform(-0.005, 0.005, size=(M, 3))
    Y = _measurements(plant, STATES)
    U = np.asarray(doc["gains"]["u_op"]) + RNG.uniform(-5e-6, 5e-6, size=(M, 2))
    est.reset(XH.copy())
    est.step(Y, U)                                       # stores y (premises from it)
    U_law = _applied(spec, run.controller(XH.copy(), None, 0.0))   # PDC, measured premises
    for k in range(M):
        _close(_np(law(XH[k], U[k], Y[k])[0]), U_law[k])
    X2 = est.step(Y, U)                                  # one period with y and u held
    h = sampling_period(spec) / 64
    for k in range(M):
        x = XH[k].copy()

        def f(v):
            return _np(law(v, U[k], Y[k])[1])

        for _ in range(64):
            k1 = f(x)
            k2 = f(x + 0.5 * h * k1)
            k3 = f(x + 0.5 * h * k2)
            k4 = f(x + h * k3)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        _close(x, X2[k])


def test_pdc_output_feedback_estimated_premises(ts):
    from tanksynth.verify.common import sampling_period
    from tanksynth.verify.takagi_sugeno.campaign import ts_control_run

    doc, spec = _load(ts, "pdc_est")
    plant = spec.plant
    g = doc["gains"]
    L, A0 = g["L"].reshape(3, 3), g["A0"].reshape(3, 3)
    run = ts_control_run(doc, spec)
    est = run.estimator_factory()                       # TSObserver: exponential Euler, 8 substeps
    law = _compiled(ts, "pdc_est")
    M = len(STATES)
    XH = STATES + RNG.uniform(-0.003, 0.003, size=(M, 3))
    Y = _measurements(plant, STATES)
    U = np.asarray(g["u_op"]) + RNG.uniform(-5e-6, 5e-6, size=(M, 2))
    U_law = _applied(spec, run.controller(XH.copy(), None, 0.0))   # premises at the estimate
    for k in range(M):
        _close(_np(law(XH[k], U[k], Y[k])[0]), U_law[k])
    est.reset(XH.copy())
    est.step(Y, U)
    X2 = est.step(Y, U)
    # the verifier's rule from the field: x+ = Phi x + Gamma (field(x) - (A0 - L C) x)
    sub = 8
    C = np.eye(3)
    Ao = A0 - L @ C
    aug = np.zeros((6, 6))
    aug[:3, :3], aug[:3, 3:] = Ao, np.eye(3)
    E = sla.expm(aug * sampling_period(spec) / sub)
    Phi, Gam = E[:3, :3], E[:3, 3:]
    for k in range(M):
        x = XH[k].copy()
        for _ in range(sub):
            x = Phi @ x + Gam @ (_np(law(x, U[k], Y[k])[1]) - Ao @ x)
        _close(x, X2[k])
    # the field is the plant's f at the estimate plus the correction (hand check at one point)
    f = _np(plant.compiled.rhs(XH[2][None], U[2][None]))
    _close(_np(law(XH[2], U[2], Y[2])[1]), f + L @ (Y[2] - XH[2]))
