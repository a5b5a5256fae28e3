"""Control laws: integral tracking with anti-windup, inverse dynamics, export and C codegen."""

from __future__ import annotations

import shutil
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import sympy as sp

from tanksynth.artefacts.export import compile_law, export_law, load_compiled_law
from tanksynth.design.laws.tracking import ServoScenario, _servo_step, servo_ise, tune_inverse_dynamics
from tanksynth.runtime.laws import (integral_tracking_law, inverse_dynamics_law, law_document,
                                    law_from_document, rename_law)
from tanksynth.design.laws.feedback_linearization import feedback_linearization
from tanksynth.errors import ArtefactError, DimensionError, SpecError
from tanksynth.plants import hybrid_three_tank, three_tank
from tanksynth.plants.hybrid_three_tank import LPH
from tanksynth.sim.integrate import casadi_step

X0_HYB = np.array([0.31918677, 0.3209075, 0.30968861])      # 100/100 lph equilibrium
needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not available")


@pytest.fixture(scope="module")
def hybrid():
    return hybrid_three_tank()


@pytest.fixture(scope="module")
def id_law(hybrid):
    return inverse_dynamics_law(hybrid, [0.5, 0.3])


# ------------------------------------------------------------ integral tracking
def simple_law(anti_windup="back_calculation", **kw):
    K1 = np.array([[2e-3, 3e-4, -5e-4], [3e-4, 2e-3, -5e-4]])
    K2 = np.array([[-9e-5, -3e-5], [-3e-5, -9e-5]])
    return integral_tracking_law(K1, K2, [0.4, 0.2, 0.3], [3.5e-5, 3.2e-5], np.eye(3)[:2], 1.0,
                                 [[0, 1.2e-4], [0, 1.2e-4]], anti_windup=anti_windup, **kw)


def test_integral_law_unsaturated_matches_equations():
    law = simple_law()
    x = np.array([0.41, 0.19, 0.31])
    z = np.array([0.1, -0.2])
    r = np.array([0.45, 0.2])
    u, zn = (np.asarray(v, dtype=float).reshape(-1) for v in law.law(x, z, r))
    v = law.u0 - law.K1 @ (x - law.x0) - law.K2 @ z
    np.testing.assert_allclose(u, v, rtol=1e-14)
    np.testing.assert_allclose(zn, z + 1.0 * (r - x[:2]), rtol=1e-14)
    assert law.K.shape == (2, 5)


def test_back_calculation_reconditions_the_integrator():
    law = simple_law()
    x = np.array([0.41, 0.19, 0.31])
    z = np.array([5.0, -3.0])                                # drives u1 above qmax, u2 below 0
    r = np.array([0.45, 0.2])
    u, zn = (np.asarray(v, dtype=float).reshape(-1) for v in law.law(x, z, r))
    np.testing.assert_array_equal(u, [1.2e-4, 0.0])
    # next unsaturated command at the same state = applied command - K2 ts e
    v_next = law.u0 - law.K1 @ (x - law.x0) - law.K2 @ zn
    np.testing.assert_allclose(v_next, u - law.K2 @ (r - x[:2]), rtol=1e-9, atol=1e-18)


def test_clamping_and_none():
    x = np.array([0.41, 0.19, 0.31])
    z = np.array([-5.0, 3.0])
    r = np.array([0.45, 0.2])
    _, zn = simple_law("clamping").law(x, z, r)
    np.testing.assert_array_equal(np.asarray(zn).reshape(-1), z)           # frozen
    _, zn = simple_law("none").law(x, z, r)
    np.testing.assert_allclose(np.asarray(zn).reshape(-1), z + (r - x[:2]))


@pytest.mark.parametrize("kwargs, error, match", [
    ({"anti_windup": "magic"}, SpecError, "anti_windup must be one of"),
    ({"aw_gain": 0.0}, SpecError, "aw_gain"),
    ({"aw_gain": 1.5}, SpecError, "aw_gain"),
])
def test_integral_law_bad_options(kwargs, error, match):
    with pytest.raises(error, match=match):
        simple_law(**kwargs)


def test_integral_law_bad_shapes():
    with pytest.raises(DimensionError, match="K2 has shape"):
        integral_tracking_law(np.zeros((2, 3)), np.zeros((3, 2)), np.zeros(3), np.zeros(2),
                              np.eye(3)[:2], 1.0)
    with pytest.raises(DimensionError, match="x0 has 2 entries"):
        integral_tracking_law(np.zeros((2, 3)), np.zeros((2, 2)), np.zeros(2), np.zeros(2),
                              np.eye(3)[:2], 1.0)
    with pytest.raises(SpecError, match="sampling period"):
        integral_tracking_law(np.zeros((2, 3)), np.zeros((2, 2)), np.zeros(3), np.zeros(2),
                              np.eye(3)[:2], 0.0)


# ---------------------------------------------------------------- inverse dynamics
def hybrid_flows(plant):
    """Q1..Q7 of notes/plants.md 1.3, written independently of the plant module."""
    p = plant.p
    h1, h2, h3 = plant.x
    g, h0 = p["g"], p["h0"]

    def link(k, dh):
        return k * sp.sign(dh) * sp.sqrt(2 * g * sp.Abs(dh))

    def middle(k, hi):
        z = sp.sign(sp.Max(hi, h0) - sp.Max(h3, h0))
        return z * k * sp.sqrt(2 * g * sp.Abs(sp.Max(hi, h0) - sp.Max(h3, h0)))

    Q1, Q2 = link(p["k1"], h1 - h3), link(p["k2"], h2 - h3)
    Q3, Q4 = middle(p["k3"], h1), middle(p["k4"], h2)
    Q5 = p["k5"] * sp.sqrt(2 * g * sp.Max(h1 - p["hd1"], 0))
    Q7 = p["k7"] * sp.sqrt(2 * g * sp.Max(h2 - p["hd2"], 0))
    return Q1, Q2, Q3, Q4, Q5, Q7


def test_inverse_dynamics_is_eq_46_47(hybrid, id_law):
    assert id_law.controlled == ("h1", "h2")
    Q1, Q2, Q3, Q4, Q5, Q7 = hybrid_flows(hybrid)
    A = hybrid.p["A"]
    h1, h2, _ = hybrid.x
    C1, C2 = id_law.gain_symbols
    h1sp, h2sp = id_law.setpoint_symbols
    expected = sp.Matrix([A * C1 * (h1sp - h1) + Q1 + Q3 + Q5, A * C2 * (h2sp - h2) + Q2 + Q4 + Q7])
    # numerically in all 8 modes (the Piecewise guard and z_i = sgn(...) agree), then saturation
    f_exp = sp.lambdify([hybrid.x, (h1sp, h2sp), (C1, C2)], expected.xreplace(hybrid.parameter_values),
                        "numpy")
    rng = np.random.default_rng(4)
    X = rng.uniform(0.0, 0.55, (400, 3))
    R = rng.uniform(0.0, 0.55, (400, 2))
    qmax = 240 * LPH
    for x, r in zip(X, R):
        ref = np.clip(np.asarray(f_exp(x, r, (0.5, 0.3)), dtype=float).reshape(-1), 0.0, qmax)
        got = np.asarray(id_law.law(x, r), dtype=float).reshape(-1)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * qmax)
    assert sp.simplify((id_law.expression[0] - id_law.expression[0].subs(C1, 0)) -
                       A * C1 * (h1sp - h1)) == 0


def test_inverse_dynamics_at_equilibrium_gives_100_lph(id_law):
    u = np.asarray(id_law.law(X0_HYB, X0_HYB[:2]), dtype=float).reshape(-1)
    np.testing.assert_allclose(u / LPH, [100.0, 100.0], rtol=1e-6)


def test_inverse_dynamics_uses_the_estimate(id_law):
    x_true = X0_HYB
    x_hat = X0_HYB + np.array([0.01, -0.01, 0.005])          # any estimator's output
    u_true = np.asarray(id_law.law(x_true, X0_HYB[:2])).reshape(-1)
    u_hat = np.asarray(id_law.law(x_hat, X0_HYB[:2])).reshape(-1)
    assert np.all(np.abs(u_hat - u_true) > 1e-7)


def test_inverse_dynamics_first_order_loop(hybrid):
    """Continuous law, unsaturated step: h1 follows C1/(s + C1) (time constant within 2%)."""
    C = 0.05
    law = inverse_dynamics_law(hybrid, [C, C])
    step = casadi_step(hybrid, 0.5, law.law)                 # law evaluated at every RK4 stage
    r = X0_HYB[:2] + np.array([0.01, 0.0])
    x = X0_HYB.copy()
    ts = [0.0]
    xs = [x]
    for k in range(200):
        x, crossed = step(x, r)
        assert float(crossed) == 0.0                          # stays in mode (1, 1, 1)
        x = np.asarray(x, dtype=float).reshape(-1)
        xs.append(x)
        ts.append(0.5 * (k + 1))
    xs, ts = np.array(xs), np.array(ts)
    y = (xs[:, 0] - X0_HYB[0]) / 0.01
    tau = np.interp(1 - np.exp(-1), y, ts)
    assert abs(tau * C - 1) < 0.02
    assert np.max(np.abs(xs[:, 1] - X0_HYB[1])) < 0.01 * X0_HYB[1]
    u = np.array([np.asarray(law.law(v, r)).reshape(-1) for v in xs])
    assert np.all(u < 240 * LPH) and np.all(u > 0)           # not saturated: exact inversion


def test_inverse_dynamics_bad_input(hybrid):
    with pytest.raises(DimensionError, match="3 controlled states"):
        inverse_dynamics_law(hybrid, [0.1, 0.1], ["h1", "h2", "h3"])
    with pytest.raises(SpecError, match="unknown state"):
        inverse_dynamics_law(hybrid, [0.1, 0.1], ["h1", "h9"])
    with pytest.raises(SpecError, match=">= 0"):
        inverse_dynamics_law(hybrid, [0.1, -0.1])
    from tanksynth.errors import InfeasibleDesign
    with pytest.raises(InfeasibleDesign, match="singular everywhere"):
        inverse_dynamics_law(hybrid, [0.1, 0.1], ["h1", "h3"])


def test_servo_ise_batch_equals_single(hybrid, id_law):
    sc = ServoScenario(X0_HYB, X0_HYB[:2].copy(), np.array([0.04, 0.04]), 20.0, 60.0, 1.0, 5)
    batch = servo_ise(hybrid, id_law, sc, [[0.2, 0.3], [0.8, 0.9]])
    single = servo_ise(hybrid, id_law, sc, [[0.8, 0.9]])
    np.testing.assert_allclose(batch[1], single[0], rtol=1e-14)
    assert np.all(batch > 0)
    zero = servo_ise(hybrid, id_law, sc, [[0.0, 0.0]])           # no feedback: error stays 0.04 m
    np.testing.assert_allclose(zero[0], 0.04 ** 2 * 40.0, rtol=1e-3)


def test_servo_ise_over_the_horizon_equals_the_step_called_period_by_period(hybrid, id_law):
    """One ``mapaccum`` call over the horizon: the same numbers as calling the step each period."""
    sc = ServoScenario(X0_HYB, X0_HYB[:2].copy(), np.array([0.04, 0.04]), 20.0, 60.0, 1.0, 5)
    gains = np.array([[0.2, 0.3], [0.8, 0.9], [1.0, 1.0]])
    step = _servo_step(hybrid, id_law, sc)
    ref = np.zeros((len(gains), 2))
    for i, c in enumerate(gains):
        x = sc.x0.copy()
        for sp_k in sc.setpoints():
            x, inc, crossed = step(x, sp_k, c)
            ref[i] += np.asarray(inc, dtype=float).reshape(-1)
            assert float(crossed) == 0.0                              # no switching surface here
    np.testing.assert_array_equal(servo_ise(hybrid, id_law, sc, gains, step), ref)


def test_servo_ise_symbolic_step_agrees_with_the_numeric_simulator(hybrid, id_law):
    """Same scheme, same clipping, same saturation: the CasADi step and the batch simulator."""
    sc = ServoScenario(X0_HYB, X0_HYB[:2].copy(), np.array([0.04, 0.04]), 20.0, 60.0, 1.0, 5)
    gains = [[0.2, 0.3], [0.8, 0.9], [1.0, 1.0], [0.0, 0.0]]
    symbolic = servo_ise(hybrid, id_law, sc, gains)
    numeric = servo_ise(hybrid, id_law, sc, gains, numeric=True)
    np.testing.assert_allclose(symbolic, numeric, rtol=1e-13)      # measured: 2.3e-15
    assert not np.array_equal(symbolic, numeric)                   # two evaluations, not one


def test_servo_ise_hands_switching_runs_to_the_numeric_integrator(hybrid, id_law):
    """A set-point step down through h0 = 0.30 m: the symbolic step flags the crossing and the
    flagged runs are simulated by the batch simulator, which locates it."""
    sc = ServoScenario(X0_HYB, X0_HYB[:2].copy(), np.array([-0.06, -0.06]), 20.0, 80.0, 1.0, 5)
    gains = np.array([[0.2, 0.3], [0.8, 0.9], [0.0, 0.0]])
    step = _servo_step(hybrid, id_law, sc).map(3, "serial")
    x, crossed = np.tile(X0_HYB[:, None], (1, 3)), np.zeros(3, dtype=bool)
    for sp_k in sc.setpoints():
        x, _, c = step(x, np.tile(sp_k[:, None], (1, 3)), gains.T)
        crossed |= np.asarray(c).reshape(-1) > 0
    assert crossed.tolist() == [True, True, False]                 # no feedback: no crossing
    got = servo_ise(hybrid, id_law, sc, gains)
    numeric = servo_ise(hybrid, id_law, sc, gains, numeric=True)
    np.testing.assert_array_equal(got[crossed], numeric[crossed])
    np.testing.assert_allclose(got[~crossed], numeric[~crossed], rtol=1e-13)


def test_tuning_small_scenario(hybrid):
    sc = ServoScenario(X0_HYB, X0_HYB[:2].copy(), np.array([0.02, 0.0]), 10.0, 60.0, 1.0, 5)
    law, tun = tune_inverse_dynamics(hybrid, sc, grid=[0.02, 0.05, 0.1], bounds=(0.0, 0.1))
    assert np.all((tun.C >= 0) & (tun.C <= 0.1))
    assert tun.ise <= tun.grid_ise.min() + 1e-15
    assert tun.ise == pytest.approx(tun.ise_outputs.sum())
    np.testing.assert_array_equal(law.C, tun.C)
    assert tun.evaluations == 9 + sum(r["evaluations"] for r in tun.refinement)
    with pytest.raises(SpecError, match="grid"):
        tune_inverse_dynamics(hybrid, sc, grid=[0.5, 2.0])


# ------------------------------------------------------------------------ export
def check_codegen(law: ca.Function, tmp_path: Path, name: str, sampler, count: int = 1000) -> float:
    exp = export_law(law, tmp_path, name)
    assert exp.function == name
    assert {p.name for p in tmp_path.iterdir()} >= {f"{name}.casadi", f"{name}.c", f"{name}.h"}
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]       # no temp left
    lib = compile_law(exp.c_source)
    c_law = load_compiled_law(lib, name)
    loaded = ca.Function.load(str(exp.casadi))
    rng = np.random.default_rng(2024)
    worst = 0.0
    for _ in range(count):
        args = sampler(rng)
        ref = [np.asarray(v, dtype=float).reshape(-1) for v in law.call(args)]
        got = [np.asarray(v, dtype=float).reshape(-1) for v in c_law.call(args)]
        again = [np.asarray(v, dtype=float).reshape(-1) for v in loaded.call(args)]
        for a, b, c in zip(ref, got, again):
            np.testing.assert_array_equal(c, a)
            assert np.all(np.isfinite(b))
            err = np.abs(b - a) / np.maximum(np.abs(a), 1e-300)
            err[(a == 0) & (b == 0)] = 0.0
            worst = max(worst, float(err.max()))
    assert worst <= 1e-12
    return worst


@pytest.mark.slow
@needs_gcc
def test_codegen_feedback_linearization_law(tmp_path):
    plant = three_tank(outputs="h1h2")
    fl = feedback_linearization(plant, None, poles=[-0.05, -0.05], per_axis=5, samples=50)
    sampler = lambda rng: [rng.uniform(0.0, 0.62, 3), rng.uniform(0.0, 0.62, 2)]  # noqa: E731
    check_codegen(fl.law, tmp_path, "fl_three_tank", sampler)


@needs_gcc
def test_codegen_inverse_dynamics_law(tmp_path, id_law):
    sampler = lambda rng: [rng.uniform(0.0, 0.55, 3), rng.uniform(0.0, 0.55, 2)]  # noqa: E731
    check_codegen(id_law.law, tmp_path, "inverse_dynamics", sampler)


@pytest.mark.slow
@needs_gcc
def test_codegen_integral_tracking_law(tmp_path):
    sampler = lambda rng: [rng.uniform(0.0, 0.62, 3), rng.uniform(-3, 3, 2),  # noqa: E731
                           rng.uniform(0.0, 0.62, 2)]
    check_codegen(simple_law().law, tmp_path, "integral_tracking", sampler)


def test_law_document_round_trip_and_tamper(id_law):
    doc = law_document(rename_law(id_law.law, "my law"))
    assert doc["function"] == "my_law"
    assert [i["name"] for i in doc["inputs"]] == ["x_hat", "h_sp"]
    back = law_from_document(doc)
    x, r = X0_HYB, X0_HYB[:2] + 0.01
    np.testing.assert_array_equal(np.asarray(back(x, r)), np.asarray(id_law.law(x, r)))
    text = doc["casadi_serialized"]
    bad = dict(doc, casadi_serialized=text[:100] + ("b" if text[100] != "b" else "c") + text[101:])
    with pytest.raises(ArtefactError, match="sha256"):
        law_from_document(bad)
    with pytest.raises(ArtefactError, match="no 'casadi_serialized'"):
        law_from_document({})


def test_export_failure_leaves_nothing(tmp_path, id_law, monkeypatch):
    def broken(self, *args):
        raise RuntimeError("disk full")

    monkeypatch.setattr(ca.CodeGenerator, "generate", broken)
    with pytest.raises(RuntimeError, match="disk full"):
        export_law(id_law.law, tmp_path, "law")
    assert list(tmp_path.iterdir()) == []


def test_compile_errors(tmp_path):
    src = tmp_path / "x.c"
    src.write_text("this is not C\n")
    with pytest.raises(ArtefactError, match="compiling"):
        compile_law(src)
    with pytest.raises(ArtefactError, match="not found"):
        compile_law(src, compiler="no-such-compiler-xyz")
    with pytest.raises(ArtefactError, match="not found"):
        load_compiled_law(tmp_path / "missing.so", "f")


def test_export_into_a_directory_named_like_the_law(tmp_path, id_law):
    # CasADi refuses an output prefix containing "<name>.c"; the export must not care.
    target = tmp_path / "idlaw.cases"
    exp = export_law(id_law.law, target, "idlaw")
    assert sorted(p.name for p in target.iterdir()) == ["idlaw.c", "idlaw.casadi", "idlaw.h"]
    assert exp.c_source.read_text().strip()
