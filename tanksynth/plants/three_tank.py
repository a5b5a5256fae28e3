"""DTS200 three-tank system (seeds 000 and 001).

Tank 3 sits in the middle; pumps feed tanks 1 and 2; the only outflow
leaves tank 2. Torricelli flows keep ``sgn``/``abs`` in the general model::

    A dh1/dt = q1 - q13
    A dh2/dt = q2 + q32 - q20
    A dh3/dt = q13 - q32
    q13 = mu13 Phi sgn(h1 - h3) sqrt(2 g |h1 - h3|)
    q32 = mu32 Phi sgn(h3 - h2) sqrt(2 g |h3 - h2|)
    q20 = mu20 Phi sqrt(2 g h2)

Default parameters: seed 000 Table I. On the default region the flow
directions ``h1 > h3 > h2`` hold, which makes the model smooth.
"""

from __future__ import annotations

import sympy as sp

from tanksynth.plants.base import Assumption, Parameter, Plant, Quantity, Region

__all__ = ["three_tank"]


def three_tank(outputs: str = "all") -> Plant:
    """Build the DTS200 three-tank plant.

    Parameters
    ----------
    outputs : {"all", "h1h2", "h1"}
        Measured levels: all three (seed 000, ``C = I3``), tanks 1 and 2
        (seed 001, eq. 18) or tank 1 only (seed 001, ``C = [1 0 0]``).

    Returns
    -------
    Plant
        States ``h1, h2, h3`` (m), inputs ``q1, q2`` (m^3/s).
    """
    choices = {"all": ("h1", "h2", "h3"), "h1h2": ("h1", "h2"), "h1": ("h1",)}
    if outputs not in choices:
        from tanksynth.errors import SpecError

        raise SpecError(f"unknown output set {outputs!r}; expected one of {list(choices)}",
                        key="plant.outputs")
    h1, h2, h3 = (sp.Symbol(n, real=True) for n in ("h1", "h2", "h3"))
    q1, q2 = (sp.Symbol(n, real=True) for n in ("q1", "q2"))
    params = (
        # plausible: laboratory three-tank rigs (DTS200-like), a unit slip leaves these ranges
        Parameter("A", 0.0154, "m^2", "tank cross-section", lower=0, plausible=(1e-4, 1.0)),
        Parameter("Phi", 5e-5, "m^2", "pipe cross-section", lower=0, plausible=(1e-7, 1e-2)),
        Parameter("mu13", 0.5, "1", "outflow coefficient T1-T3", lower=0, upper=1,
                  plausible=(0.05, 1.0)),
        Parameter("mu32", 0.5, "1", "outflow coefficient T3-T2", lower=0, upper=1,
                  plausible=(0.05, 1.0)),
        Parameter("mu20", 0.675, "1", "outflow coefficient T2 outlet", lower=0, upper=1,
                  plausible=(0.05, 1.0)),
        Parameter("g", 9.81, "m/s^2", "gravity", lower=0, plausible=(9.7, 9.9)),
        Parameter("qmax", 1.2e-4, "m^3/s", "pump capacity", lower=0, plausible=(1e-6, 1e-2)),
        Parameter("hmax", 0.62, "m", "tank height", lower=0, plausible=(0.05, 5.0)),
    )
    sym = {prm.name: prm.symbol for prm in params}
    A, Phi, mu13, mu32, mu20, g = (sym[n] for n in ("A", "Phi", "mu13", "mu32", "mu20", "g"))
    q13 = mu13 * Phi * sp.sign(h1 - h3) * sp.sqrt(2 * g * sp.Abs(h1 - h3))
    q32 = mu32 * Phi * sp.sign(h3 - h2) * sp.sqrt(2 * g * sp.Abs(h3 - h2))
    q20 = mu20 * Phi * sp.sqrt(2 * g * h2)
    f = sp.Matrix([(q1 - q13) / A, (q2 + q32 - q20) / A, (q13 - q32) / A])
    states = {"h1": h1, "h2": h2, "h3": h3}
    h = sp.Matrix([states[nm] for nm in choices[outputs]])
    hmax = 0.62
    return Plant(
        name="three_tank",
        description="DTS200 three-tank system, outflow from tank 2 (seeds 000, 001)",
        states=(Quantity("h1", "m", "level of tank 1"), Quantity("h2", "m", "level of tank 2"),
                Quantity("h3", "m", "level of tank 3 (middle)")),
        inputs=(Quantity("q1", "m^3/s", "pump 1 flow into tank 1"),
                Quantity("q2", "m^3/s", "pump 2 flow into tank 2")),
        outputs=tuple(Quantity(nm, "m", f"measured level {nm}") for nm in choices[outputs]),
        parameters=params,
        f=f,
        h=h,
        region=Region(bounds=((0.0, hmax),) * 3, orderings=((h1, h3), (h3, h2))),
        input_bounds=((0.0, "qmax"), (0.0, "qmax")),
        assumptions=(
            Assumption("flow directions h1 > h3 > h2 on the operating region: sgn/abs resolve and "
                       "the model is smooth there", kind="flow_direction", source="seed 000 II-A"),
            Assumption("Torricelli outflow with constant outflow coefficients; incompressible water",
                       kind="modelling", source="seed 000 II-A model"),
        ),
        source="seed 000 Table I; Amira DTS200",
        options=(("outputs", outputs),),
    )
