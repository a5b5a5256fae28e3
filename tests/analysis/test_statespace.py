"""State-space interop: LinearModel.to_statespace, statespace_matrices and the system norms."""

from __future__ import annotations

import control
import numpy as np
import pytest

from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.analysis.statespace import h2_norm, hinf_below, hinf_norm, statespace_matrices
from tanksynth.errors import SpecError
from tanksynth.plants import three_tank


def _model(ts=None):
    plant = three_tank("h1h2")
    x0 = [0.40, 0.20, 0.30]
    return linearize(plant, x0, equilibrium_input(plant, x0).u0, ts=ts)


def test_to_statespace_continuous_and_discrete_with_names_and_dt():
    lin = _model(ts=1.0)
    c = lin.to_statespace(discrete=False)
    d = lin.to_statespace()
    assert c.dt == 0 and d.dt == 1.0
    np.testing.assert_array_equal(c.A, lin.F)
    np.testing.assert_array_equal(d.A, lin.Ad)
    np.testing.assert_array_equal(d.B, lin.Bd)
    assert c.state_labels == ["h1", "h2", "h3"]
    assert c.input_labels == ["q1", "q2"] and c.output_labels == ["h1", "h2"]
    # python-control's own ZOH of the continuous model is the stored discretisation
    np.testing.assert_allclose(control.c2d(c, 1.0, "zoh").A, lin.Ad, rtol=1e-10)
    with pytest.raises(SpecError):
        _model().to_statespace(discrete=True)


def test_statespace_matrices_accepts_statespace_or_matrices():
    sys = control.ss([[-1.0]], [[2.0]], [[3.0]], [[0.5]], 0.1)
    A, B, C, D, dt = statespace_matrices(sys)
    assert (A[0, 0], B[0, 0], C[0, 0], D[0, 0], dt) == (-1.0, 2.0, 3.0, 0.5, 0.1)
    A, B, C, D, dt = statespace_matrices([[-1.0]], [[2.0]], [[3.0]])
    assert D.shape == (1, 1) and D[0, 0] == 0 and dt is None


@pytest.mark.parametrize("dt", [0, 1.0])
def test_norms_against_python_control(dt):
    rng = np.random.default_rng(3)
    for _ in range(5):
        A = rng.standard_normal((4, 4))
        A = A - (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(4) if dt == 0 else \
            0.9 * A / np.max(np.abs(np.linalg.eigvals(A)))
        B, C = rng.standard_normal((4, 2)), rng.standard_normal((2, 4))
        sys = control.ss(A, B, C, np.zeros((2, 2)), dt)
        assert h2_norm(sys) == pytest.approx(control.norm(sys, 2), rel=1e-8)
        ref = control.norm(sys, "inf", tol=1e-10, method="scipy", print_warning=False)
        g = hinf_norm(sys)
        assert g == pytest.approx(ref, rel=1e-6)
        assert hinf_below(1.001 * g, sys) and not hinf_below(0.999 * g, sys)
    unstable = control.ss([[0.1]], [[1.0]], [[1.0]], [[0.0]])
    assert h2_norm(unstable) == np.inf and hinf_norm(unstable) == np.inf


def test_model_names_is_the_naming_rule():
    from tanksynth.analysis.statespace import model_names

    assert model_names("continuous") == {"A": "F", "B": "B", "Bw": "Bw", "C": "C"}
    assert model_names("discrete") == {"A": "Ad", "B": "Bd", "Bw": "Bwd", "C": "C"}
    model_names("discrete")["A"] = "changed"          # a copy: the table stays
    assert model_names("discrete")["A"] == "Ad"
    with pytest.raises(ValueError, match="time_domain"):
        model_names("z")
