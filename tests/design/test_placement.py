"""Pole placement: integral action (seed 000), canonical form (seed 004), the spec methods.

The LMI-region and exact routes are tested in test_placement_lmi.py and
test_placement_exact.py, the regions in tests/analysis/test_lmi_region.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from tanksynth.design.placement import canonical as placement
from tanksynth.methods import METHODS
from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.design.placement.canonical import (canonical_observer, integral_augmentation, place_observer,
                                        pole_errors)
from tanksynth.errors import DimensionError, SpecError, UnobservableError
from tanksynth.methods import load_spec, parse_spec_text

ROOT = Path(__file__).resolve().parents[2]
SEED000 = ROOT / "examples" / "seed000_pole_placement.toml"
SEED000_POLES = [0.92, 0.97, 0.90, 0.95, 0.94]
SEED000_K = 1e-4 * np.array([[21.6, 3, -5, -0.95, -0.32], [2.9, 19, -4, -0.30, -0.91]])

# seed 004, section III: healthy A, B, C
A004 = sp.Matrix([[sp.Rational(-1, 2), 0, 0], [sp.Rational(1, 2), sp.Rational(-3, 2), 0],
                  [0, sp.Rational(3, 2), sp.Rational(-1, 2)]])
C004 = sp.Matrix([[0, 0, sp.Rational(1, 2)]])
GAMMA_D_PRINTED = np.array([[-0.5, 0.0, -855.0], [0.5, -1.5, -169.667], [0.0, 1.5, -41.5]])


# -------------------------------------------------------- seed 000 (integral)
def test_seed000_integral_lmi_disk():
    spec = load_spec(SEED000)
    design = next(d for d in spec.designs if d.method == "lmi_placement")
    res = METHODS[design.method].design(spec, design)
    A = np.array(res.diagnostics["integral"]["augmented_A"])
    lin = linearize(spec.plant, spec.x0, equilibrium_input(spec.plant, spec.x0).u0, ts=spec.ts)
    B = np.vstack([lin.Bd, np.zeros((2, 2))])
    lam = np.linalg.eigvals(A - B @ res.gains["K"])
    assert np.all(np.abs(lam) < 0.97) and np.all(np.abs(lam - 0.9) < 0.08)
    assert res.gains["K1"].shape == (2, 3) and res.gains["K2"].shape == (2, 2)


def test_integral_augmentation_structure():
    Ad, Bd = np.eye(3) * 0.9, np.ones((3, 2))
    aug = integral_augmentation(Ad, Bd, np.eye(3)[:2], 1.0)
    assert aug.A.shape == (5, 5) and aug.n == 3 and aug.p == 2
    np.testing.assert_array_equal(aug.A[3:, :3], -np.eye(3)[:2])
    np.testing.assert_array_equal(aug.Br[3:], np.eye(2))
    with pytest.raises(DimensionError):
        integral_augmentation(Ad, Bd, np.eye(3), 1.0)            # p = 3 > m = 2
    with pytest.raises(SpecError):
        integral_augmentation(Ad, Bd, np.eye(3)[:2], 0.0)


def test_seed000_poles_and_gain_beside_the_paper():
    spec = load_spec(SEED000)
    design = next(d for d in spec.designs if d.method == "pole_placement")
    res = METHODS[design.method].design(spec, design)
    place = res.diagnostics["placement"]
    assert place["max_pole_error"] < 1e-9
    achieved = sorted(z[0] for z in place["achieved"])
    np.testing.assert_allclose(achieved, sorted(SEED000_POLES), atol=1e-9)
    K = res.gains["K"]
    np.testing.assert_array_equal(K, np.hstack([res.gains["K1"], res.gains["K2"]]))
    # the paper's K is printed beside ours; it is close (Tits-Yang vs the paper's routine,
    # printed digits) but not equal, and it misplaces the poles on the derived model
    ref = res.diagnostics["reference_gain"]
    np.testing.assert_allclose(ref["reference"], SEED000_K)
    assert 0.01 < ref["relative_difference"] < 0.1
    assert 1e-3 < ref["reference_max_pole_error"] < 0.05
    # independent check: the augmented closed loop has exactly the requested eigenvalues
    lin = linearize(spec.plant, spec.x0, equilibrium_input(spec.plant, spec.x0).u0, ts=1.0)
    aug = integral_augmentation(lin.Ad, lin.Bd, np.eye(3)[:2], 1.0)
    lam = np.sort(np.linalg.eigvals(aug.A - aug.B @ K).real)
    np.testing.assert_allclose(lam, sorted(SEED000_POLES), atol=1e-9)


# ------------------------------------------------------------- seed 004 (canonical)
def test_seed004_canonical_form_is_exact():
    co = canonical_observer(A004, C004, [-5, -8, -10])
    assert co.Q_O == sp.Matrix([[0, 0, sp.Rational(1, 2)], [0, sp.Rational(3, 4), sp.Rational(-1, 4)],
                                [sp.Rational(3, 8), sp.Rational(-3, 2), sp.Rational(1, 8)]])
    assert co.Q_O_bar == sp.Matrix([[0, 0, 1], [0, 1, sp.Rational(-5, 2)],
                                    [1, sp.Rational(-5, 2), sp.Rational(9, 2)]])
    assert co.Delta == sp.Matrix([[sp.Rational(8, 3), sp.Rational(-4, 3), sp.Rational(2, 3)],
                                  [0, sp.Rational(4, 3), sp.Rational(-8, 3)], [0, 0, 2]])
    assert co.char_coefficients == (sp.Rational(3, 8), sp.Rational(7, 4), sp.Rational(5, 2))
    assert co.desired_coefficients == (400, 170, 23)
    assert list(co.Psi_o) == [sp.Rational(3197, 8), sp.Rational(673, 4), sp.Rational(41, 2)]
    assert list(co.Psi) == [855, sp.Rational(509, 3), 41]          # printed (855, 169.667, 41)
    assert co.exact
    s = sp.Symbol("s")
    assert sp.factor(co.Gamma_d.charpoly(s).as_expr()) == (s + 5) * (s + 8) * (s + 10)


def test_seed004_both_routes_agree():
    co = canonical_observer(A004, C004, [-5, -8, -10])
    pl = place_observer(np.array(A004, dtype=float), np.array(C004, dtype=float), [-5, -8, -10])
    np.testing.assert_allclose(pl.gain_matrix, co.L, rtol=1e-9)
    np.testing.assert_allclose(co.L.ravel(), [855, 169.6666667, 41], rtol=1e-9)


def test_seed004_printed_gamma_d_is_an_erratum():
    """Printed Gamma_d = A - Psi [0 0 1] (C_o instead of C = [0 0 1/2]): wrong eigenvalues."""
    co = canonical_observer(A004, C004, [-5, -8, -10])
    derived = np.array(co.Gamma_d, dtype=float)
    np.testing.assert_allclose(derived[:, 2], [-427.5, -84.8333333, -21.0], rtol=1e-7)
    _, err_printed = pole_errors([-5, -8, -10], np.linalg.eigvals(GAMMA_D_PRINTED))
    assert err_printed > 1.0
    A = np.array(A004, dtype=float)
    np.testing.assert_allclose(A - co.L @ np.array([[0, 0, 1.0]]), GAMMA_D_PRINTED, atol=1e-3)


def test_seed004_through_a_spec():
    text = (ROOT / "examples" / "seed004_fault_detection.toml").read_text()
    text += ('\n[[design]]\nname = "canonical"\nmethod = "canonical_observer"\n'
             'poles = [-5.0, -8.0, -10.0]\nreference_gain = [[855.0], [169.667], [41.0]]\n'
             'reference_closed_loop = [[-0.5, 0.0, -855.0], [0.5, -1.5, -169.667], '
             '[0.0, 1.5, -41.5]]\n')
    spec = parse_spec_text(text)
    design = spec.designs[-1]
    res = METHODS["canonical_observer"].design(spec, design)
    d = res.diagnostics
    assert d["canonical_form"]["Psi"] == ["855", "509/3", "41"]
    assert d["max_pole_error"] < 1e-9
    assert d["place_cross_check"]["max_abs_difference"] < 1e-8
    assert d["reference_gain"]["max_abs_difference"] < 1e-3
    assert d["reference_closed_loop"]["reference_max_pole_error"] > 1.0
    assert res.gains["L"].shape == (3, 1)


def test_canonical_input_errors():
    with pytest.raises(DimensionError, match="single output"):
        canonical_observer(A004, sp.eye(3)[:2, :], [-1, -2, -3])
    with pytest.raises(DimensionError):
        canonical_observer(A004, C004, [-1, -2])
    with pytest.raises(UnobservableError):
        canonical_observer(np.diag([-1.0, -2.0, -3.0]), [[1.0, 1.0, 0.0]], [-1, -2, -3])
    with pytest.raises(SpecError, match="conjugate"):
        canonical_observer(A004, C004, [-1, -2 + 1j, -2 + 2j])


def test_spec_options_are_validated():
    base = SEED000.read_text().split("[[design]]")[0]

    def run(extra):
        spec = parse_spec_text(base + "[[design]]\nname = \"x\"\n" + extra)
        d = spec.designs[0]
        return METHODS[d.method].design(spec, d)

    with pytest.raises(SpecError, match=r"design\[0\]\.poles"):
        run('method = "pole_placement"\ntarget = "state_feedback"\npoles = ["a", 1.0, 2.0]\n')
    with pytest.raises(SpecError, match="unknown option"):
        run('method = "pole_placement"\ntarget = "state_feedback"\npoles = [0.9, 0.9, 0.9]\nspeed = 1\n')
    with pytest.raises(SpecError, match=r"design\[0\]\.tracked"):
        run('method = "pole_placement"\ntarget = "state_feedback"\npoles = [0.9, 0.91, 0.92, 0.93, 0.94]\nintegral = true\n'
            'tracked = ["h9"]\n')
    with pytest.raises(SpecError, match=r"design\[0\]\.region\[0\]\.type"):
        run('method = "lmi_placement"\ntarget = "observer"\nregion = [{type = "ellipse"}]\n')
    with pytest.raises(SpecError, match="stability domain"):
        run('method = "lmi_placement"\ntarget = "observer"\nregion = [{type = "half_plane", alpha = 0.1}]\n')
    with pytest.raises(SpecError, match=r"design\[0\]\.reference_gain"):
        run('method = "pole_placement"\ntarget = "state_feedback"\npoles = [0.9, 0.91, 0.92]\nreference_gain = [[1.0]]\n')
    with pytest.raises(SpecError, match="single output"):
        run('method = "canonical_observer"\npoles = [-1.0, -2.0, -3.0]\n')


def test_module_exports():
    for name in placement.__all__:
        assert hasattr(placement, name)
