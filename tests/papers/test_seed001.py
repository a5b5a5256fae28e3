"""tanksynth.papers.seed001: the printed formulas and the Sec. IV design."""

from __future__ import annotations

import numpy as np
import sympy as sp

from tanksynth.papers import seed001 as paper


def test_symbols_and_matrix_shapes():
    (z1, z2, z3), lam, gam = paper.symbols()
    A = paper.A_eq10()
    assert A.shape == (3, 3)
    assert A.free_symbols == {z1, z2, z3, *lam, *gam}
    # water leaving one tank enters another, except tank 2's outflow z2 h2: the rows sum to
    # [0, -z2, 0]
    assert sp.expand(A[0, :] + A[1, :] + A[2, :]) == sp.Matrix([[0, -z2, 0]])


def test_O1_first_rows_are_C_and_CA():
    O = paper.O1()
    A = paper.A_eq10()
    assert O[0, :] == sp.Matrix([[1, 0, 0]])
    assert O[1, :] == A[0, :]


def test_printed_determinant_is_a_polynomial_in_z1_squared():
    (z1, z2, z3), _, _ = paper.symbols()
    det = sp.expand(paper.det_O1())
    assert sp.expand(det / z1**2).free_symbols.isdisjoint({z1})


def test_design_values():
    assert len(paper.LAMBDA) == len(paper.GAMMA) == 3
    assert paper.L.shape == (3, 2) and paper.PSI == 0.506 and paper.G == 9.82
    np.testing.assert_allclose(paper.L[2], [-0.0008, 0.0012])
    assert set(paper.O12_entries()) == {(3, 2), (5, 1), (5, 2), (5, 3), (6, 1), (6, 2), (6, 3)}
    names = {str(s) for group in paper.symbols()[1:] for s in group}
    assert all(set(d) <= names for d in paper.RANK_CLAIM + paper.TWO_OUTPUT_CLAIM)
