"""Symbolic observability rank per hybrid mode and per coupled block, against hand derivations.

* A two-tank plant whose tank 1 drains into tank 2 only through a pipe at height h0, tank 2
  measured: below h0 tank 1 is cut off (rank 1, h1 unobservable); above it
  ``F = [[-c1, 0], [c1, -c2]]``, ``C = [0, 1]``, ``det O = -c1`` (rank 2).
* The hybrid three-tank (seed 002), only h3 measured. In mode (0, 0, 0) (no middle pipe
  conducts) ``F = [[-c1, 0, c1], [0, -c2, c2], [c1, c2, -(c1 + c2 + c6)]]`` with
  ``c_i = k_i g / (A sqrt(2 g |dh_i|))``, ``C = [0, 0, 1]``: expanding ``det [C; CF; CF^2]``
  along its first row gives ``c1 c2 (c1 - c2)``, zero where ``k1 sqrt(h3 - h2) = k2 sqrt(h3 - h1)``
  (tanks 1 and 2 look alike from tank 3). In mode (1, 1, 1) the middle pipes add to the bottom
  links: the same with ``k1 + k3``, ``k2 + k4`` and the heads ``h1 - h3``, ``h2 - h3``.
* The 40-tank network (seed 003): upper tank ``20 + i`` drains into lower tank ``i`` only and
  every tank is measured: 20 decoupled pairs, each with ``C = I`` (rank 2 from C alone).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from tanksynth.analysis.checks import rank_conditions
from tanksynth.analysis.rank_structured import (coupled_blocks, frozen_at, mode_cells,
                                                numeric_observability_rank)
from tanksynth.analysis.symbolic import jacobian
from tanksynth.plants import hybrid_three_tank
from tanksynth.plants.base import HybridModes, Parameter, Plant, Quantity, Region


def _two_tank() -> Plant:
    h1, h2, u = sp.Symbol("h1", real=True), sp.Symbol("h2", real=True), sp.Symbol("u", real=True)
    prm = (Parameter("A", 0.01, "m^2", "section", lower=0), Parameter("k1", 1e-5, "m^2", "pipe", lower=0),
           Parameter("k2", 2e-5, "m^2", "drain", lower=0), Parameter("h0", 0.3, "m", "pipe height", lower=0),
           Parameter("g", 9.81, "m/s^2", "gravity", lower=0))
    A, k1, k2, h0, g = (p.symbol for p in prm)
    q1 = k1 * sp.sqrt(2 * g * sp.Max(h1 - h0, 0))
    f = sp.Matrix([(u - q1) / A, (q1 - k2 * sp.sqrt(2 * g * h2)) / A])
    return Plant(name="two_tank_threshold", description="two tanks, pipe at h0", states=(
        Quantity("h1", "m", "tank 1"), Quantity("h2", "m", "tank 2")), inputs=(Quantity("u", "m^3/s", "pump"),),
        outputs=(Quantity("y", "m", "h2"),), parameters=prm, f=f, h=sp.Matrix([h2]),
        region=Region(bounds=((0.0, 0.6), (0.0, 0.6))), hybrid=HybridModes(("a",), (h1 - h0,)))


def _symbolic(checks):
    return next(c for c in checks if c.name == "symbolic_observability")


def test_frozen_at_picks_the_active_branch():
    x, y, c = sp.symbols("x y c", real=True)
    expr = sp.Matrix([sp.Max(x, c) + sp.sign(x - y) * sp.sqrt(sp.Abs(x - y)),
                      sp.Piecewise((x, x > c), (0, True)) + sp.Min(x, y)])
    at = frozen_at(expr, {x: 0.5, y: 0.7, c: 0.3})
    assert sp.simplify(at[0] - (x - sp.sqrt(y - x))) == 0
    assert sp.simplify(at[1] - 2 * x) == 0
    at = frozen_at(expr, {x: 0.1, y: 0.0, c: 0.3})
    assert sp.simplify(at[0] - (c + sp.sqrt(x - y))) == 0
    assert sp.simplify(at[1] - y) == 0


def test_two_tank_modes_by_hand():
    plant = _two_tank()
    h1, h2 = plant.x
    vals = {p.name: p.value for p in plant.parameters}
    chk = _symbolic(rank_conditions(plant, [0.5, 0.2], samples=200))
    modes = {tuple(m["mode"]): m for m in chk.data["hybrid_modes"]}
    assert set(modes) == {(0,), (1,)}
    assert modes[(0,)]["rank"] == 1 and modes[(0,)]["identically_zero"]
    assert "h1" in modes[(0,)]["null_direction"]
    assert modes[(1,)]["rank"] == 2 and not modes[(1,)]["identically_zero"]
    assert "rank 2 in 1/2 modes" in chk.detail
    # mode 1 at (0.5, 0.2): the frozen Jacobian is the hand one and det O = -c1
    pt = {h1: 0.5, h2: 0.2, **plant.parameter_values}
    F = np.array(jacobian(frozen_at(plant.f, pt), plant.x).xreplace(pt), dtype=float)
    c1 = vals["k1"] * vals["g"] / (vals["A"] * np.sqrt(2 * vals["g"] * (0.5 - vals["h0"])))
    c2 = vals["k2"] * vals["g"] / (vals["A"] * np.sqrt(2 * vals["g"] * 0.2))
    np.testing.assert_allclose(F, [[-c1, 0], [c1, -c2]], rtol=1e-12)
    O = np.vstack([[0.0, 1.0], np.array([0.0, 1.0]) @ F])
    assert np.linalg.det(O) == pytest.approx(-c1, rel=1e-12)
    factors = [sp.sympify(f) for f in modes[(1,)]["factors"]]
    assert any(f.free_symbols >= {sp.Symbol("k1")} for f in factors)


@pytest.mark.slow
def test_seed002_mode_000_and_111_by_hand():
    plant = hybrid_three_tank()
    v = {p.name: p.value for p in plant.parameters}
    x_op = np.array([0.31918677, 0.3209075, 0.30968861])
    chk = _symbolic(rank_conditions(plant, x_op, ts=1.0, samples=200))
    modes = {tuple(m["mode"]): m for m in chk.data["hybrid_modes"]}
    assert len(modes) == 8 and all(m["rank"] == 3 for m in modes.values())
    assert np.allclose(modes[(1, 1, 1)]["point"], x_op)        # the operating point's own mode
    k1, k2, k3, k4 = sp.symbols("k1 k2 k3 k4", positive=True)
    h1, h2, h3 = sp.symbols("h1 h2 h3", real=True)

    def has_factor(mode, hand):
        fs = [sp.sympify(f, locals={"h1": h1, "h2": h2, "h3": h3, "k1": k1, "k2": k2, "k3": k3, "k4": k4})
              for f in modes[mode]["factors"]]
        return any(sp.simplify(f - hand) == 0 or sp.simplify(f + hand) == 0 for f in fs)

    assert has_factor((0, 0, 0), k1 * sp.sqrt(h3 - h2) - k2 * sp.sqrt(h3 - h1))
    assert has_factor((1, 1, 1), (k1 + k3) * sp.sqrt(h2 - h3) - (k2 + k4) * sp.sqrt(h1 - h3))
    # numerically: det O of the frozen field at a mode-(0, 0, 0) point is c1 c2 (c1 - c2)
    x = np.array([0.10, 0.05, 0.20])
    pt = {**dict(zip(plant.x, x)), **plant.parameter_values}
    F = np.array(jacobian(frozen_at(plant.f, pt), plant.x).xreplace(pt), dtype=float)
    C = np.array([[0.0, 0.0, 1.0]])
    c1 = v["k1"] * v["g"] / (v["A"] * np.sqrt(2 * v["g"] * (x[2] - x[0])))
    c2 = v["k2"] * v["g"] / (v["A"] * np.sqrt(2 * v["g"] * (x[2] - x[1])))
    O = np.vstack([C, C @ F, C @ F @ F])
    assert np.linalg.det(O) == pytest.approx(c1 * c2 * (c1 - c2), rel=1e-9)
    # on the factor's zero set (c1 = c2) the mode's rank drops to 2
    h3v = 0.25
    h2v = 0.05
    h1v = h3v - (v["k1"] / v["k2"]) ** 2 * (h3v - h2v)
    pt = {**dict(zip(plant.x, (h1v, h2v, h3v))), **plant.parameter_values}
    F = np.array(jacobian(frozen_at(plant.f, pt), plant.x).xreplace(pt), dtype=float)
    assert numeric_observability_rank(F, C) == 2


def test_mode_cells_prefers_the_operating_point():
    plant = _two_tank()
    pts = plant.region.sample(50, plant.x, seed=1)
    cells = mode_cells(plant.hybrid.switching, plant.x, plant.parameter_values, pts, prefer=[0.45, 0.1])
    assert [b for b, _ in cells] == [(0,), (1,)]
    np.testing.assert_allclose(cells[1][1], [0.45, 0.1])
    assert cells[0][1][0] < 0.3


def test_coupled_blocks_by_hand():
    a, b, c = sp.symbols("a b c")
    F = sp.Matrix([[a, 0, 0, 0], [0, b, 0, c], [0, 0, a, 0], [0, 0, 0, b]])
    C = sp.Matrix([[1, 0, 1, 0]])
    assert coupled_blocks(F, C) == [[0, 2], [1, 3]]


def test_seed003_per_pair():
    from tanksynth.methods import load_spec

    spec = load_spec("examples/seed003_tank_network.toml")
    chk = _symbolic(rank_conditions(spec.plant, spec.x0, ts=1.0, samples=50))
    blocks = chk.data["blocks"]
    assert chk.data["rank"] == 40 and len(blocks) == 20
    assert [b["states"] for b in blocks] == [[f"h{i}", f"h{20 + i}"] for i in range(1, 21)]
    assert all(b["rank"] == 2 and b["blocks_used"] == 1 and not b["factors"] for b in blocks)
    # the pairs are the first one with their own symbols (A_i, a_i, a_{20+i}, ...): their
    # determinant is taken once per form (at most 2: symbols sorted by name may order one pair
    # differently, which only costs one more determinant)
    firsts = [b for b in blocks if "same_form_as" not in b]
    assert blocks[0] in firsts and len(firsts) <= 2
    assert all(b["same_form_as"] in [f["states"] for f in firsts] for b in blocks if b not in firsts)
    assert any(f"{k} distinct block form(s)" in chk.detail for k in (1, 2))
