"""`Design.to_statespace()` (one implementation, `tanksynth.verify.statespace`) for the synthesis,
robust and Takagi-Sugeno designs of the examples.

Reference eigenvalues are recomputed here with numpy from the stored gains: ``A - B K``,
``A - L C``, the integral augmentation written out by hand, and for the PDC designs the
plant's Jacobian by central finite differences with the memberships at ``x0`` solved from it
(the TS model is exact, so ``J = sum_i mu_i A_i``), not from the tool's premise code.
"""

from __future__ import annotations

import itertools
import warnings
from pathlib import Path

import control
import numpy as np
import pytest

import tanksynth
from tanksynth.cli import main
from tanksynth.errors import ArtefactError, TanksynthWarning
from tanksynth.spec import load_spec

ROOT = Path(__file__).resolve().parents[2] / "examples"
NAMES = ["h1", "h2", "h3"]


pytestmark = pytest.mark.slow   # every test uses the designs of every state-space example


@pytest.fixture(scope="module")
def designed(tmp_path_factory) -> dict:
    out = {}
    for key in ("hinf", "robust", "ts_control"):
        d = tmp_path_factory.mktemp(key) / "out"
        assert main(["design", str(ROOT / f"three_tank_{key}.toml"), "-o", str(d)]) == 0
        out[key] = tanksynth.load(d)
    return out


def _eig(M) -> np.ndarray:
    return np.sort_complex(np.linalg.eigvals(np.asarray(M, dtype=float)))


def _poles(sys) -> np.ndarray:
    return np.sort_complex(np.asarray(control.poles(sys), dtype=complex))


@pytest.mark.parametrize("name", ["h2_controller", "hinf_controller", "multiobjective_disk"])
def test_synthesis_controllers(designed, name):
    d = designed["hinf"][name]
    g = d.gains
    sys = d.to_statespace("closed_loop")
    assert isinstance(sys, control.StateSpace) and sys.dt == 1.0
    assert sys.state_labels == NAMES and sys.input_labels == ["q1", "q2"]
    assert sys.output_labels == ["h1", "h2"]
    np.testing.assert_allclose(_poles(sys), _eig(g["Ad"] - g["Bd"] @ g["K"]), atol=1e-10)
    perf = d.to_statespace()     # default of an H2 / H-infinity design: w -> z
    assert (perf.ninputs, perf.noutputs) == (g["Bwd"].shape[1], g["Cz"].shape[0])
    np.testing.assert_allclose(_poles(perf), _eig(g["Ad"] - g["Bd"] @ g["K"]), atol=1e-10)
    np.testing.assert_allclose(perf.C, g["Cz"] - g["Dzu"] @ g["K"], atol=1e-12)
    # one naming convention: w_<state> (Bw = diag(1/A): one inflow per tank), z_<state>/z_<input>
    assert perf.input_labels == ["w_h1", "w_h2", "w_h3"]
    assert perf.output_labels == ["z_h1", "z_h2", "z_h3", "z_q1", "z_q2"]
    picks = [np.flatnonzero(row) for row in np.hstack([g["Cz"], g["Dzu"]])]
    assert [int(p[0]) for p in picks if len(p) == 1] == [0, 1, 2, 3, 4]
    loop = d.to_statespace("loop")    # L(z) = K (zI - A)^-1 B: open-loop poles
    np.testing.assert_allclose(_poles(loop), _eig(g["Ad"]), atol=1e-10)
    with pytest.raises(ArtefactError, match="state feedback"):
        d.to_statespace("error")


@pytest.mark.parametrize("name", ["h2_observer", "hinf_observer"])
def test_synthesis_observers(designed, name):
    d = designed["hinf"][name]
    g = d.gains
    err = d.to_statespace("error")
    assert err.dt == 1.0 and err.state_labels == NAMES
    assert err.input_labels == ["v_h1", "v_h2"] and err.output_labels == ["e_h1", "e_h2", "e_h3"]
    np.testing.assert_allclose(_poles(err), _eig(g["Ad"] - g["L"] @ g["C"]), atol=1e-10)
    np.testing.assert_allclose(err.B, -g["L"])
    perf = d.to_statespace()     # default: w, v -> z
    assert perf.ninputs == g["Bwd"].shape[1] + g["Dv"].shape[1]
    np.testing.assert_allclose(perf.B, np.hstack([g["Bwd"], -g["L"] @ g["Dv"]]))
    assert perf.input_labels == ["w_h1", "w_h2", "w_h3", "v_h1", "v_h2"]
    assert perf.output_labels == ["z_e_h1", "z_e_h2", "z_e_h3"]
    obs = d.to_statespace("observer")
    assert obs.output_labels == ["h1_hat", "h2_hat", "h3_hat"] and obs.input_labels == ["q1", "q2", "h1", "h2"]


def test_robust_state_feedback_with_integral_action(designed):
    d = designed["robust"]["robust_integral"]
    g = d.gains
    A, B, K, ts = g["Ad"], g["Bd"], g["K"], 1.0
    C1 = np.array([[1.0, 0, 0], [0, 1.0, 0]])    # tracked h1, h2
    # z+ = z + ts (r - C1 x), u = -K [x; z]
    Aa = np.block([[A, np.zeros((3, 2))], [-ts * C1, np.eye(2)]])
    Ba = np.vstack([B, np.zeros((2, 2))])
    sys = d.to_statespace()
    assert sys.state_labels == NAMES + ["z_h1", "z_h2"] and sys.dt == 1.0
    assert sys.input_labels == ["r_h1", "r_h2"] and sys.output_labels == ["h1", "h2"]
    np.testing.assert_allclose(_poles(sys), _eig(Aa - Ba @ K), atol=1e-10)
    assert np.all(np.abs(_poles(sys) - 0.9) < 0.08)                 # the spec's disk
    np.testing.assert_allclose(control.dcgain(sys), np.eye(2), atol=1e-8)   # integral action
    vm = d.diagnostics["vertex_models"]
    for i in (0, len(vm["A"]) - 1):
        Ai, Bi = np.array(vm["A"][i]), np.array(vm["B"][i])
        Aai = np.block([[Ai, np.zeros((3, 2))], [-ts * C1, np.eye(2)]])
        Bai = np.vstack([Bi, np.zeros((2, 2))])
        vs = d.to_statespace(vertex=i)
        np.testing.assert_allclose(_poles(vs), _eig(Aai - Bai @ K), atol=1e-10)
        assert np.all(np.abs(_poles(vs) - 0.9) < 0.08)
    with pytest.raises(ArtefactError, match="vertex must be"):
        d.to_statespace(vertex=len(vm["A"]))
    with pytest.raises(ArtefactError, match="vertex= applies"):
        designed["hinf"]["hinf_controller"].to_statespace(vertex=0)


def test_robust_regulator_and_observer(designed):
    sat = designed["robust"]["robust_saturation"]
    g = sat.gains
    sys = sat.to_statespace()
    assert sys.state_labels == NAMES and sys.dt == 1.0
    np.testing.assert_allclose(_poles(sys), _eig(g["Ad"] - g["Bd"] @ g["K"]), atol=1e-10)
    obs = designed["robust"]["robust_observer"]
    g = obs.gains
    err = obs.to_statespace()
    np.testing.assert_allclose(_poles(err), _eig(g["Ad"] - g["L"] @ g["C"]), atol=1e-10)
    assert np.all(np.abs(_poles(err) - 0.5) < 0.4)
    vm = obs.diagnostics["vertex_models"]
    v = obs.to_statespace(vertex=2)
    np.testing.assert_allclose(_poles(v), _eig(np.array(vm["A"][2]) - g["L"] @ np.array(vm["C"][2])),
                               atol=1e-10)


def _jacobian(plant, x0, u0, h=1e-7) -> np.ndarray:
    n = x0.size
    J = np.zeros((n, n))
    for k in range(n):
        dx = np.zeros(n)
        dx[k] = h
        J[:, k] = (plant.compiled.rhs((x0 + dx)[None], u0[None])[0]
                   - plant.compiled.rhs((x0 - dx)[None], u0[None])[0]) / (2 * h)
    return J


def _memberships_from_jacobian(Ai: np.ndarray, J: np.ndarray) -> np.ndarray:
    """Solve ``J = sum_i mu_i A_i`` for the product memberships (vertex order: product((1, 2)), 1 = upper)."""
    p = int(round(np.log2(Ai.shape[0])))
    sigmas = list(itertools.product((1, 2), repeat=p))
    lower = Ai[sigmas.index((2,) * p)]
    M = np.array([(Ai[sigmas.index(tuple(1 if j == k else 2 for j in range(p)))] - lower).ravel()
                  for k in range(p)]).T
    F, *_ = np.linalg.lstsq(M, (J - lower).ravel(), rcond=None)
    np.testing.assert_allclose(M @ F, (J - lower).ravel(), atol=1e-6 * np.abs(J).max())
    return np.array([np.prod([F[k] if s == 1 else 1 - F[k] for k, s in enumerate(sig)]) for sig in sigmas])


@pytest.mark.parametrize("name", ["pdc", "pdc_output"])
def test_ts_pdc_local_linearisation(designed, name):
    d = designed["ts_control"][name]
    g = d.gains
    spec = load_spec(ROOT / "three_tank_ts_control.toml")
    J = _jacobian(spec.plant, g["x_op"], g["u_op"])
    mu = _memberships_from_jacobian(g["F"], J)
    K0 = np.einsum("i,ijk->jk", mu, g["K"])
    with pytest.warns(TanksynthWarning, match="linearisation at the operating point"):
        sys = d.to_statespace()
    assert sys.dt == 0 and sys.input_labels == ["q1", "q2"] and sys.output_labels == ["h1", "h2"]
    B = g["B"]
    if name == "pdc":
        assert sys.state_labels == NAMES
        expected = _eig(J - B @ K0)
    else:
        C = np.array([[1.0, 0, 0], [0, 1.0, 0]])
        L0 = g["L"] if g["L"].ndim == 2 else np.einsum("i,ijk->jk", mu, g["L"])
        assert sys.state_labels == NAMES + ["e_h1", "e_h2", "e_h3"]
        expected = np.sort_complex(np.concatenate([_eig(J - B @ K0), _eig(J - L0 @ C)]))
        with pytest.warns(TanksynthWarning):
            err = d.to_statespace("error")
        np.testing.assert_allclose(_poles(err), _eig(J - L0 @ C), atol=1e-6)
    np.testing.assert_allclose(_poles(sys), expected, atol=1e-6 * np.abs(expected).max())
    assert np.all(_poles(sys).real < 0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ArtefactError, match="linearisation at the operating point"):
            d.to_statespace("performance")


def test_wrong_system_names_only_the_systems_that_apply(designed):
    """A robust observer declares no disturbance channel: the hint must not offer
    'performance', which would then be refused too; an H-infinity observer's hint does."""
    with pytest.raises(ArtefactError, match=r"\(use 'error' or 'observer'\)"):
        designed["robust"]["robust_observer"].to_statespace("closed_loop")
    with pytest.raises(ArtefactError, match=r"\(use 'error', 'performance' or 'observer'\)"):
        designed["hinf"]["hinf_observer"].to_statespace("closed_loop")
