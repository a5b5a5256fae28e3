"""tanksynth.papers.seed000: the printed values are self-consistent and evaluate as printed."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from tanksynth.papers import seed000 as paper
from tanksynth.plants import three_tank


def test_table_I_is_the_plant_default():
    plant = three_tank()
    assert {k: plant.parameter(k).value for k in paper.TABLE_I} == paper.TABLE_I


def test_u0_text_and_numbers_agree():
    assert tuple(float(t) for t in paper.U0_TEXT) == paper.U0
    assert paper.Y0[0] > paper.Y0[2] > paper.Y0[1] > 0          # the flow directions of eq. (8)


def test_printed_F_evaluates_eq8_as_printed():
    F, B = paper.printed_F(paper.TABLE_I, paper.Y0)
    p = paper.TABLE_I
    t13 = p["mu13"] * p["Phi"] * math.sqrt(2 * p["g"]) / (2 * p["A"] * math.sqrt(0.1))
    assert F[0, 0] == pytest.approx(-t13) and F[0, 2] == pytest.approx(t13)
    assert F[2, 0] == pytest.approx(-t13)                         # the printed sign
    assert F[0, 1] == F[1, 0] == 0.0
    np.testing.assert_allclose(B, [[1 / p["A"], 0], [0, 1 / p["A"]], [0, 0]])
    # the same matrix from the fractions, symbolically
    t = sp.symbols("t13 t32 t20")
    M = sp.Matrix(paper.F_in_fractions(*t))
    assert M[2, 2] == t[0] - t[1] and M[1, 1] == -t[0] - t[2]


def test_errata_notes_name_the_printed_entries():
    assert set(paper.F_FORMULA_ERRATA) == set(paper.F_PRINTED_LATEX) == {(2, 2), (3, 1), (3, 3)}
    assert all(v.count("$") % 2 == 0 for v in paper.F_FORMULA_ERRATA.values())


def test_gain_and_poles_shapes():
    assert paper.K.shape == (2, 5) and len(paper.POLES) == 5
    assert paper.K[0, 0] == pytest.approx(21.6e-4)
    assert all(0 < p < 1 for p in paper.POLES)                    # discrete-time, stable


def test_printed_law_is_lambda0():
    law = paper.printed_law(paper.TABLE_I, paper.Y0)
    np.testing.assert_array_equal(law["alpha"], law["Lambda0"])   # the erratum, as printed
    np.testing.assert_allclose(law["beta"] @ law["Lambda"], np.eye(2))
    assert set(paper.LAW_PRINTED_LATEX) == {"alpha", "beta", "Lambda", "Lambda0"}
    assert "Lambda_0" in paper.LAW_NOTE
