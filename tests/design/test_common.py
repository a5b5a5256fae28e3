"""The design stage's common modules: matrix helpers, LMI checks, the operating point, keyed calls."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tanksynth.design.lmi_checks import KAPPA_ACTIVE, SOLVERS, check_solver, kappa_active
from tanksynth.design.matrices import complex_pairs, matrix_pair, real_matrix, symmetrized
from tanksynth.design.operating_point import (discrete_pair, equilibrium_at, linearized_at,
                                              sampling_period, time_domain_of)
from tanksynth.design.result import keyed_call
from tanksynth.errors import DimensionError, SpecError
from tanksynth.methods import parse_spec_text

SPEC = ('[plant]\nmodel = "three_tank"\n\n[operating_point]\nx = [0.4, 0.2, 0.3]\n\n'
        '[sampling]\nts = 1.0\n\n[[design]]\nname = "lin"\nmethod = "linearize"\n')


def test_real_matrix_refuses_what_is_not_a_finite_matrix():
    assert real_matrix([1.0, 2.0], "v").shape == (1, 2)
    with pytest.raises(DimensionError, match="A must be a real 2-D array"):
        real_matrix([["a"]], "A")
    with pytest.raises(DimensionError, match="must be 2-D"):
        real_matrix(np.zeros((2, 2, 2)), "A")
    with pytest.raises(DimensionError, match="A has non-finite entries"):
        real_matrix([[np.nan]], "A")


def test_matrix_pair_checks_the_shapes_together():
    A, B = matrix_pair(np.eye(2), [[1.0], [0.0]])
    assert A.shape == (2, 2) and B.shape == (2, 1)
    with pytest.raises(DimensionError, match="A must be square"):
        matrix_pair(np.ones((2, 3)), np.ones((2, 1)))
    with pytest.raises(DimensionError, match="C' has 3 rows, expected n = 2"):
        matrix_pair(np.eye(2), np.ones((3, 1)), "C'")


def test_symmetrized_and_complex_pairs():
    M = np.array([[1.0, 2.0], [4.0, 3.0]])
    np.testing.assert_array_equal(symmetrized(M), [[1.0, 3.0], [3.0, 3.0]])
    assert complex_pairs([1 + 0j, -1 - 2j, -1 + 2j]) == [[-1.0, -2.0], [-1.0, 2.0], [1.0, 0.0]]


def test_the_conditioning_bound_of_both_normalisations():
    P = np.diag([1.0, 19.98])          # trace P = 20.98 >= KAPPA_ACTIVE kappa n = 19.98 (kappa 10)
    assert KAPPA_ACTIVE == 1.0 - 1e-3
    assert kappa_active(P, 10.0) and not kappa_active(P, 11.0)
    X = np.diag([1.0, 9.995])
    assert kappa_active(X, 10.0, bound="eigenvalue") and not kappa_active(X, 10.1, bound="eigenvalue")
    with pytest.raises(ValueError, match="bound"):
        kappa_active(X, 10.0, bound="norm")


def test_check_solver_names_the_solvers():
    for solver in SOLVERS:
        check_solver(solver)
    with pytest.raises(SpecError, match="unknown solver 'MOSEK'") as info:
        check_solver("MOSEK")
    assert info.value.key == "solver"


def test_keyed_call_names_the_spec_option():
    design = parse_spec_text(SPEC).designs[0]

    def refuses(**kwargs):
        raise SpecError("a + b + c must be 1", key=kwargs["which"])

    with pytest.raises(SpecError) as info:
        keyed_call(design, refuses, {"a": "abc"}, which="a")
    assert info.value.key == f"{design.key}.abc"
    with pytest.raises(SpecError) as info:
        keyed_call(design, refuses, {"a": "abc"}, which="Q")
    assert info.value.key == f"{design.key}.Q"
    assert keyed_call(design, dict, {}, x=1) == {"x": 1}


def test_operating_point_helpers():
    spec = parse_spec_text(SPEC)
    eq = equilibrium_at(spec.plant, spec.x0, spec.given_u0)
    lin = linearized_at(spec.plant, spec.x0, eq.u0, ts=spec.ts)
    Ad, Bd = discrete_pair(lin)
    assert Ad is lin.Ad and Bd is lin.Bd
    with pytest.raises(ValueError, match="not discretised"):
        discrete_pair(linearized_at(spec.plant, spec.x0, eq.u0))
    assert sampling_period(spec) == 1.0
    with pytest.raises(SpecError, match="sampling period") as info:
        sampling_period(dataclasses.replace(spec, ts=None))
    assert info.value.key == "sampling.ts"
    assert time_domain_of(dataclasses.make_dataclass("O", [("time_domain", str)])("discrete")) == "discrete"
    with pytest.raises(SpecError, match="no time domain"):
        time_domain_of(dataclasses.make_dataclass("O", [("time_domain", object)])(None))
