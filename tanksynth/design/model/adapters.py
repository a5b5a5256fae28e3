"""Spec design methods built on the symbolic core (``linearize``)."""

from __future__ import annotations

import numpy as np
import sympy as sp

from tanksynth.analysis.linearize import symbolic_jacobians
from tanksynth.analysis.rank import controllability_rank, observability_rank, pbh_test
from tanksynth.design.matrices import complex_pairs
from tanksynth.design.operating_point import as_levels, discrete_pair, equilibrium_at, linearized_at
from tanksynth.design.result import DesignMethod, DesignResult, options_of
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options import LinearizeOptions

__all__ = ["run_linearize", "LINEARIZE"]


def run_linearize(spec: Spec, design: DesignSpec) -> DesignResult:
    """Linearise at the operating point and discretise with ZOH.

    Gains: ``F``, ``B`` (continuous), ``Ad``, ``Bd`` (exact ZOH, period
    ``ts``), ``C``, the operating point ``x_op``, ``u_op`` (the equilibrium
    input computed from the model, not the one written in the spec, whose
    residual is reported).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    options_of(design, spec, LinearizeOptions)  # no option; refuses a spec without ts
    plant = spec.plant
    eq = equilibrium_at(plant, spec.x0, spec.given_u0)
    lin = linearized_at(plant, spec.x0, eq.u0, ts=spec.ts)
    Ad, Bd = discrete_pair(lin)
    names = [s.name for s in plant.states]
    ranks = {
        "controllability": controllability_rank(lin.F, lin.B).as_dict(),
        "observability": observability_rank(lin.F, lin.C).as_dict(),
        "controllability_discrete": controllability_rank(Ad, Bd).as_dict(),
        "observability_discrete": observability_rank(Ad, lin.C).as_dict(),
        "pbh_controllability": pbh_test(lin.F, B=lin.B, state_names=names).as_dict(),
        "pbh_observability": pbh_test(lin.F, C=lin.C, state_names=names).as_dict(),
    }
    latex = {}
    if plant.n <= 6:
        F_sym, B_sym, _ = symbolic_jacobians(plant)
        latex = {"F": sp.latex(F_sym), "B": sp.latex(B_sym)}
    smooth_here = not plant.region.violations(as_levels(spec.x0), plant.x)
    diagnostics = {
        "equilibrium": eq.as_dict(),
        "eigenvalues_F": complex_pairs(lin.eigenvalues),
        "eigenvalues_Ad": complex_pairs(np.linalg.eigvals(Ad)),
        "ts": spec.ts,
        "rank": ranks,
        "smooth_form_valid": smooth_here,
        "assumptions": [a.text for a in plant.assumptions],
    }
    gains = {"F": lin.F, "B": lin.B, "Ad": Ad, "Bd": Bd, "C": lin.C,
             "x_op": lin.x0, "u_op": lin.u0}
    return DesignResult(design.name, "linearize", plant.name, gains, diagnostics, latex)


LINEARIZE = DesignMethod("linearize", run_linearize, LinearizeOptions)
