"""Hybrid three-tank system with threshold pipes (seed 002).

Autonomous hybrid system (AHS) of Vellayikot & Vaidyan: three tanks of equal
section, tank 3 in the middle; two bottom links (valves k1, k2), two middle
links at the height ``h0`` (valves k3, k4) and three drains (k5, k6, k7).
Equations (1)-(12) of the paper could not be read; the model below is the
reconstruction of ``notes/plants.md`` section 1.3 (COSY / Sim3Tanks
physics, valves frozen at the hand settings of seed 002 Table 1)::

    A dh1/dt = Q1in - Q1 - Q3 - Q5                                  (1)
    A dh2/dt = Q2in - Q2 - Q4 - Q7                                  (2)
    A dh3/dt = Q1 + Q2 + Q3 + Q4 - Q6                               (3)
    Q1 = k1 sgn(h1 - h3) sqrt(2 g |h1 - h3|)                        (4)
    Q2 = k2 sgn(h2 - h3) sqrt(2 g |h2 - h3|)                        (5)
    Q3 = z1 k3 sqrt(2 g |max(h1, h0) - max(h3, h0)|)                (6)
    Q4 = z2 k4 sqrt(2 g |max(h2, h0) - max(h3, h0)|)                (7)
    Q5 = k5 sqrt(2 g max(h1 - hd1, 0))                              (8)
    Q6 = k6 sqrt(2 g max(h3 - hz, 0))                               (9)
    Q7 = k7 sqrt(2 g max(h2 - hd2, 0))                              (10)
    z1 = sgn(max(h1, h0) - max(h3, h0))                             (11)
    z2 = sgn(max(h2, h0) - max(h3, h0))                             (12)

In the code, ``Q3`` and ``Q4`` are written as 0 when both levels are at or
below ``h0`` (where ``z = 0``): same values, but automatic differentiation
then gives a finite Jacobian in that mode instead of ``0 * inf = NaN``.

The discrete mode is the bit triple ``(a, b, c) = ([h1 > h0], [h2 > h0],
[h3 > h0])``; `mode_vector_field` gives the smooth vector field of one mode
(for per-mode Jacobians in an EKF). Valve coefficients ``k`` are in m^2
(discharge coefficient folded in), so ``Q = k sqrt(2 g dh)`` is in m^3/s.
"""

from __future__ import annotations

import math
from typing import Sequence

import sympy as sp

from tanksynth.errors import SpecError
from tanksynth.plants.base import Assumption, HybridModes, Parameter, Plant, Quantity, Region

__all__ = ["hybrid_three_tank", "mode_vector_field", "LPH"]

#: One litre per hour in m^3/s.
LPH = 1e-3 / 3600.0

_QMAX = 240 * LPH          # rated pump flow, 240 lph = 6.6667e-5 m^3/s
_HMAX = 0.55               # overflow height (m)
_SOURCE = "seed 002 (Vellayikot & Vaidyan, JEET 2016), Tables 1-2"


def _parameters() -> tuple[Parameter, ...]:
    return (
        Parameter("A", math.pi * 0.15 ** 2 / 4, "m^2",
                  "tank cross-section, pi D^2/4 with D = 0.15 m (all three tanks)", lower=0,
                  plausible=(1e-4, 1.0)),
        Parameter("k1", 2.6363e-5, "m^2", "bottom link T1-T3 (valve 1) discharge coefficient",
                  lower=0, plausible=(1e-8, 1e-2)),
        Parameter("k2", 2.4891e-5, "m^2", "bottom link T2-T3 (valve 2) discharge coefficient",
                  lower=0, plausible=(1e-8, 1e-2)),
        Parameter("k3", 3.7984e-5, "m^2", "middle link T1-T3 at h0 (valve 3) discharge coefficient",
                  lower=0, plausible=(1e-8, 1e-2)),
        Parameter("k4", 3.4316e-5, "m^2", "middle link T2-T3 at h0 (valve 4) discharge coefficient",
                  lower=0, plausible=(1e-8, 1e-2)),
        Parameter("k5", 0.0, "m^2",
                  "T1 drain (valve 5) discharge coefficient; 0 = closed", lower=0, inclusive=True,
                  plausible=(0.0, 1e-2)),
        Parameter("k6", 2.2538e-5, "m^2", "T3 drain (valve 6) discharge coefficient", lower=0,
                  plausible=(1e-8, 1e-2)),
        Parameter("k7", 0.0, "m^2",
                  "T2 drain (valve 7) discharge coefficient; 0 = closed", lower=0, inclusive=True,
                  plausible=(0.0, 1e-2)),
        Parameter("h0", 0.30, "m", "height of the middle pipes (switching threshold)",
                  lower=0, upper=_HMAX),
        Parameter("hd1", 0.0, "m", "height of the T1 drain above the tank bottom",
                  lower=0, inclusive=True, upper=_HMAX),
        Parameter("hd2", 0.0, "m", "height of the T2 drain above the tank bottom",
                  lower=0, inclusive=True, upper=_HMAX),
        Parameter("hz", 0.0, "m", "height of the T3 drain above the tank bottom",
                  lower=0, inclusive=True, upper=_HMAX),
        Parameter("g", 9.81, "m/s^2", "gravity", lower=0, plausible=(9.7, 9.9)),
        Parameter("hmax", _HMAX, "m", "overflow height (tank height 0.60 m)", lower=0, upper=0.60),
        Parameter("Qmax", _QMAX, "m^3/s", "rated pump flow (240 lph at 5 V)", lower=0,
                  plausible=(1e-6, 1e-2)),
    )


def hybrid_three_tank() -> Plant:
    """Build the hybrid three-tank plant (autonomous hybrid system).

    Returns
    -------
    Plant
        States ``h1, h2, h3`` (m; tank 3 in the middle), inputs ``Q1in,
        Q2in`` (pump flows, m^3/s, range 0-240 lph), output ``y = h3`` (m).
        Hybrid modes: bits ``(a, b, c)`` of the switching functions
        ``(h1 - h0, h2 - h0, h3 - h0)``. Region: the box ``[0, 0.55]^3`` m
        (no flow-direction orderings: the flows change direction inside
        the region, so ``f`` keeps its ``sgn``/``abs``/``max``).
    """
    params = _parameters()
    p = {prm.name: prm.symbol for prm in params}
    h1, h2, h3 = (sp.Symbol(n, real=True) for n in ("h1", "h2", "h3"))
    q1in, q2in = (sp.Symbol(n, real=True) for n in ("Q1in", "Q2in"))
    A, g, h0 = p["A"], p["g"], p["h0"]

    def link(k: sp.Expr, dh: sp.Expr) -> sp.Expr:
        """Torricelli flow through a link, signed by the head difference."""
        return k * sp.sign(dh) * sp.sqrt(2 * g * sp.Abs(dh))

    def drain(k: sp.Expr, h: sp.Expr, hd: sp.Expr) -> sp.Expr:
        return k * sp.sqrt(2 * g * sp.Max(h - hd, 0))

    def middle(k: sp.Expr, hi: sp.Expr) -> sp.Expr:
        """Middle-pipe flow T_i -> T3, z k sqrt(2 g |max(hi, h0) - max(h3, h0)|).

        Written as 0 when both levels are at or below h0 (z = 0), so that
        automatic differentiation does not evaluate sqrt'(0) * 0 = NaN in
        that whole mode; the value is the same as the plain formula.
        """
        return sp.Piecewise((link(k, sp.Max(hi, h0) - sp.Max(h3, h0)), (hi > h0) | (h3 > h0)),
                            (0, True))

    Q1 = link(p["k1"], h1 - h3)                                   # (4)
    Q2 = link(p["k2"], h2 - h3)                                   # (5)
    Q3 = middle(p["k3"], h1)                                      # (6), (11)
    Q4 = middle(p["k4"], h2)                                      # (7), (12)
    Q5 = drain(p["k5"], h1, p["hd1"])                             # (8)
    Q6 = drain(p["k6"], h3, p["hz"])                              # (9)
    Q7 = drain(p["k7"], h2, p["hd2"])                             # (10)
    f = sp.Matrix([
        (q1in - Q1 - Q3 - Q5) / A,                                # (1)
        (q2in - Q2 - Q4 - Q7) / A,                                # (2)
        (Q1 + Q2 + Q3 + Q4 - Q6) / A,                             # (3)
    ])
    return Plant(
        name="hybrid_three_tank",
        description="hybrid three-tank AHS with middle pipes at h0, only h3 measured (seed 002)",
        states=(Quantity("h1", "m", "level of tank 1"),
                Quantity("h2", "m", "level of tank 2"),
                Quantity("h3", "m", "level of tank 3 (middle, measured)")),
        inputs=(Quantity("Q1in", "m^3/s", "pump 1 flow into tank 1"),
                Quantity("Q2in", "m^3/s", "pump 2 flow into tank 2")),
        outputs=(Quantity("y", "m", "measured level h3"),),
        parameters=params,
        f=f,
        h=sp.Matrix([h3]),
        region=Region(bounds=((0.0, _HMAX),) * 3),
        input_bounds=((0.0, "Qmax"), (0.0, "Qmax")),
        assumptions=(
            Assumption(
                "equations (1)-(12) of the paper are not in our copy; the model is reconstructed "
                "from the rig description (7 hand valves, middle pipes at h0, Tables 1-2) with the "
                "COSY/Sim3Tanks threshold-pipe physics: Q = k sgn(dh) sqrt(2 g |dh|), "
                "z_i = sgn(max(h_i, h0) - max(h3, h0)), drains k sqrt(2 g max(h - hd, 0))",
                kind="reconstructed", source="COSY / Sim3Tanks three-tank benchmark physics"),
            Assumption(
                "hd1, hd2 (drain heights of T1, T2) are not published: default 0 m; irrelevant "
                "while valves 5 and 7 are closed (k5 = k7 = 0)",
                kind="omitted", source="seed 002 (not given)"),
            Assumption(
                "hz (drain height of T3) is not published: default 0 m (bottom outlet as in "
                "COSY/Sim3Tanks); it shifts the T3 equilibrium one-for-one",
                kind="omitted", source="seed 002 (not given)"),
            Assumption(
                "pump law not published: the inputs are the pump flows themselves, assumed linear "
                "in the 0-5 V command, Q = (V/5) 240 lph (48 lph per volt), saturated to 0-240 lph",
                kind="omitted", source="seed 002 Table 2 (pump law not given)"),
            Assumption(
                "sampling time not published: 1 s recommended (time constants are minutes); set "
                "it in the spec's [sampling] table",
                kind="omitted", source="seed 002 (not given)"),
            Assumption(
                "process/measurement noise covariances and the initial covariance are not "
                "published: chosen per design and declared in the spec",
                kind="omitted", source="seed 002 (not given)"),
            Assumption(
                "levels are clipped to [0, 0.55] m (overflow height) by the simulator; the model "
                "itself has no overflow term",
                kind="modelling", source="seed 002 Table 2"),
            Assumption(
                "sgn(x) sqrt(|x|) is continuous but not differentiable at x = 0 (equal levels, or a "
                "level at h0); an EKF should freeze the mode (mode_vector_field) and regularise "
                "the derivative near zero heads",
                kind="modelling", source="seed 002 section 3"),
        ),
        hybrid=HybridModes(names=("a", "b", "c"), switching=(h1 - h0, h2 - h0, h3 - h0)),
        source=_SOURCE,
    )


def mode_vector_field(plant: Plant, mode: Sequence[int]) -> sp.Matrix:
    """The vector field of the hybrid three-tank with its mode frozen.

    Each ``max(h_i, h0)`` of equations (6)-(7), (11)-(12) is replaced by
    ``h_i`` if the mode bit of tank ``i`` is 1 (level above the middle pipe)
    and by ``h0`` otherwise (and the guard ``h_i > h0 or h3 > h0`` of the
    middle-pipe flows is resolved). ``sgn`` and ``abs`` are kept, so within a mode
    the field is smooth away from equal heads; its Jacobian is what an EKF
    uses for that mode (seed 002 section 3).

    Parameters
    ----------
    plant : Plant
        A plant built by `hybrid_three_tank` (possibly with overridden
        parameter values).
    mode : tuple of int
        Bits ``(a, b, c)`` in {0, 1}, e.g. from ``plant.mode_of``.

    Returns
    -------
    sympy.Matrix, shape (3, 1)
        ``f(x, u)`` of that mode in state, input and parameter symbols
        (substitute values with ``.xreplace(plant.parameter_values)``).

    Raises
    ------
    SpecError
        ``mode`` is not three bits, or the plant is not a hybrid three-tank.
    """
    bits = tuple(mode)
    if len(bits) != 3 or any(isinstance(b, bool) or b not in (0, 1) for b in bits):
        raise SpecError(f"mode must be three bits (a, b, c) in {{0, 1}}, got {mode!r}", key="mode")
    if plant.name != "hybrid_three_tank" or plant.n != 3 or "h0" not in plant.p:
        raise SpecError(f"mode_vector_field needs a hybrid_three_tank plant, got {plant.name!r}",
                        key="plant.model")
    h0 = plant.p["h0"]
    table: dict[sp.Basic, sp.Basic] = {}
    for hi, bit in zip(plant.x, bits):
        table[sp.Max(hi, h0)] = hi if bit else h0
        above = hi > h0
        table[above] = table[above.canonical] = sp.true if bit else sp.false  # Or canonicalises
    f = plant.f.xreplace(table)
    left = [e for e in f.atoms(sp.Max, sp.Piecewise) if e.has(h0)]
    if left:
        raise SpecError(f"could not freeze the mode: {left} remain", key="plant.model")
    return f
