"""Linear three-state hydraulic model with a leak fault (seed 004).

Three tanks in cascade; the pump feeds tank 1, tank 1 drains into tank 2,
tank 2 into tank 3, tank 3 to the sump; tank 2 has a fault (leak) whose
coefficient ``delta_bar`` is zero when healthy::

    dx1/dt = -(delta1/psi1) x1 + u
    dx2/dt =  (delta1/psi1) x1 - (delta2/psi2 + delta_bar) x2
    dx3/dt =  (delta2/psi2) x2 - (delta3/psi3) x3
    y      =  x3 / psi3

With the seed's numbers (``psi = (2, 1, 2)``, ``delta = (1, 1.5, 1)``) this
gives ``A = [[-0.5, 0, 0], [0.5, -1.5 - delta_bar, 0], [0, 1.5, -0.5]]``,
``B = [1, 0, 0]'``, ``C = [0, 0, 0.5]`` and the healthy transfer function
``0.375 / (s^3 + 2.5 s^2 + 1.75 s + 0.375)`` printed in section III.
Everything is dimensionless.
"""

from __future__ import annotations

import sympy as sp

from tanksynth.plants.base import Assumption, Parameter, Plant, Quantity, Region

__all__ = ["hydraulic_fault"]


def hydraulic_fault() -> Plant:
    """Build the linear hydraulic fault model of seed 004.

    Returns
    -------
    Plant
        States ``x1, x2, x3`` (dimensionless tank contents), input ``u``
        (pump flow), output ``y = x3/psi3``. Parameters ``psi1..psi3``
        (tank capacities), ``delta1..delta3`` (outlet coefficients) and the
        fault ``delta_bar`` (leak of tank 2, 0 = healthy), all ``"1"``.
        Region: the box ``[0, 10]^3``.
    """
    params = (
        Parameter("psi1", 2.0, "1", "capacity (section) of tank 1", lower=0,
                  plausible=(1e-3, 1e3)),
        Parameter("psi2", 1.0, "1", "capacity (section) of tank 2", lower=0,
                  plausible=(1e-3, 1e3)),
        Parameter("psi3", 2.0, "1", "capacity (section) of tank 3", lower=0,
                  plausible=(1e-3, 1e3)),
        Parameter("delta1", 1.0, "1", "outlet coefficient of tank 1 (into tank 2)", lower=0,
                  plausible=(1e-3, 1e3)),
        Parameter("delta2", 1.5, "1", "outlet coefficient of tank 2 (into tank 3)", lower=0,
                  plausible=(1e-3, 1e3)),
        Parameter("delta3", 1.0, "1", "outlet coefficient of tank 3 (to the sump)", lower=0,
                  plausible=(1e-3, 1e3)),
        Parameter("delta_bar", 0.0, "1", "leak fault of tank 2 (0 = healthy)", lower=0,
                  inclusive=True, plausible=(0.0, 100.0)),
    )
    p = {prm.name: prm.symbol for prm in params}
    x1, x2, x3 = (sp.Symbol(n, real=True) for n in ("x1", "x2", "x3"))
    u = sp.Symbol("u", real=True)
    r1 = p["delta1"] / p["psi1"]
    r2 = p["delta2"] / p["psi2"]
    r3 = p["delta3"] / p["psi3"]
    f = sp.Matrix([
        -r1 * x1 + u,
        r1 * x1 - (r2 + p["delta_bar"]) * x2,
        r2 * x2 - r3 * x3,
    ])
    return Plant(
        name="hydraulic_fault",
        description="linear three-tank hydraulic cascade with a tank-2 leak fault (seed 004)",
        states=(Quantity("x1", "1", "content of tank 1"),
                Quantity("x2", "1", "content of tank 2 (faulty)"),
                Quantity("x3", "1", "content of tank 3 (measured)")),
        inputs=(Quantity("u", "1", "pump flow into tank 1"),),
        outputs=(Quantity("y", "1", "measured level of tank 3, x3/psi3"),),
        parameters=params,
        f=f,
        h=sp.Matrix([x3 / p["psi3"]]),
        region=Region(bounds=((0.0, 10.0),) * 3),
        input_bounds=(),
        assumptions=(
            Assumption(
                "the model section of seed 004 is missing from our copy; the mapping of psi_i, "
                "delta_i to the matrix entries (A[i,i] = -delta_i/psi_i, A[i+1,i] = "
                "delta_i/psi_i, fault -delta_bar x2, B = e1) is inferred from the printed matrices "
                "of section III and reproduces them and both printed transfer functions",
                kind="reconstructed", source="seed 004 section III"),
            Assumption(
                "output y = x3/psi3 (level of tank 3 when x is its content); y = (delta3/psi3) x3 "
                "(outflow of tank 3) gives the same C = [0 0 0.5] with the printed numbers "
                "(delta3 = 1), so the two are indistinguishable; x3/psi3 was chosen",
                kind="reconstructed", source="seed 004 section III"),
            Assumption(
                "the fault delta_bar is a leak: delta_bar >= 0, with 0 the healthy plant",
                kind="modelling", source="seed 004 section III"),
            Assumption(
                "no actuator range is given in seed 004: the input is unbounded (the seed's test "
                "input takes the values 2 and 1)",
                kind="omitted", source="seed 004 section IV"),
            Assumption(
                "operating region [0, 10] per state, covering the seed's initial states "
                "(1/4 < x_i(0) <= 4) and the steady state of u = 2 (x = (4, 4/3, 4))",
                kind="modelling", source="seed 004 sections III-IV"),
        ),
        source="seed 004 section III (numerical results)",
    )
