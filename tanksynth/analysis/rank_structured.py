"""Symbolic observability rank where one determinant cannot be taken: per mode, per coupled block.

Two structures let the symbolic rank test of `tanksynth.analysis.rank_symbolic` reach plants
it cannot take whole:

* **hybrid switching** (threshold pipes): inside one mode every ``max``/``min``/``Piecewise``
  of the model picks one branch, so each mode's vector field is a smooth system of its own.
  `mode_cells` picks one region point per mode (bits of the switching functions) and
  `frozen_at` replaces every non-smooth term by the branch active there (``sign``, ``abs``,
  ``max``, ``min``, ``Piecewise``, ``Heaviside``). The smooth field of that cell (mode and
  flow directions of the point) is then differentiated symbolically. For a Torricelli link
  ``sgn(dh) sqrt(2 g |dh|)`` the derivative ``g / sqrt(2 g |dh|)`` is the same for either flow
  direction, so the cell's rank is the mode's rank.
* **decoupled blocks** (a network of tank pairs): when ``df/dx`` and ``dh/dx`` couple the states
  only inside groups (`coupled_blocks`: connected components of the coupling graph), the
  observability matrix is block diagonal after a permutation and its rank is the sum of the
  blocks' ranks, each decided by a small determinant.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import numpy.typing as npt
import sympy as sp

__all__ = ["frozen_at", "mode_cells", "coupled_blocks", "numeric_observability_rank"]

_BRANCHING = (sp.sign, sp.Abs, sp.Max, sp.Min, sp.Piecewise, sp.Heaviside)


def _value(expr: sp.Expr, point: Mapping[sp.Symbol, sp.Expr]) -> float:
    return float(sp.N(expr.xreplace(point)))


def frozen_at(exprs: sp.Matrix, point: Mapping[sp.Symbol, float]) -> sp.Matrix:
    """The branch of every non-smooth term that is active at ``point``, kept symbolic.

    Innermost terms first: ``sign(e)`` becomes ``+1``/``-1`` and ``Abs(e)`` becomes ``e`` or
    ``-e`` by the sign of ``e`` at the point; ``Max``/``Min`` the argument that is largest /
    smallest there; ``Piecewise`` the first branch whose condition holds; ``Heaviside(e)``
    ``1`` or ``0``. Only the choice is numeric: the result keeps every state and parameter
    symbol.

    Parameters
    ----------
    exprs : sympy.Matrix
        Expressions in states, inputs and parameters.
    point : mapping of sympy.Symbol to float
        Values of every symbol a branch depends on (states in their unit, e.g. m; parameters
        in theirs). A branch argument that is exactly 0 at the point takes the ``+`` branch.

    Returns
    -------
    sympy.Matrix
        Same shape, without the functions listed above (where the point decides them).
    """
    pt = {s: sp.Float(v) if not isinstance(v, sp.Basic) else v for s, v in point.items()}

    def freeze(e: sp.Basic) -> sp.Basic:
        if not e.args or not e.has(*_BRANCHING):
            return e
        if isinstance(e, sp.Piecewise):
            for expr, cond in e.args:
                held = cond if isinstance(cond, bool) else cond.xreplace(pt)
                if held in (True, sp.true):
                    return freeze(expr)
            return e
        args = [freeze(a) for a in e.args]
        if isinstance(e, sp.sign):
            return sp.Integer(-1 if _value(args[0], pt) < 0 else 1)
        if isinstance(e, sp.Abs):
            return -args[0] if _value(args[0], pt) < 0 else args[0]
        if isinstance(e, sp.Heaviside):
            return sp.Integer(0 if _value(args[0], pt) < 0 else 1)
        if isinstance(e, (sp.Max, sp.Min)):
            vals = [_value(a, pt) for a in args]
            i = int(np.argmax(vals) if isinstance(e, sp.Max) else np.argmin(vals))
            return args[i]
        return e.func(*args)

    return sp.Matrix(exprs).applyfunc(freeze)


def mode_cells(switching: Sequence[sp.Expr], states: Sequence[sp.Symbol],
               parameters: Mapping[sp.Symbol, sp.Expr], points: npt.ArrayLike,
               prefer: npt.ArrayLike | None = None) -> list[tuple[tuple[int, ...], np.ndarray]]:
    """One representative point per hybrid mode found among ``points``.

    The mode of a point is the tuple of bits ``[s_j(x) > 0]``. The representative of a mode is
    ``prefer`` (e.g. the operating point) when it lies in that mode, else the sampled point of
    that mode farthest from every switching surface (largest ``min_j |s_j(x)|``), so that its
    flow directions are those of the mode's bulk.

    Parameters
    ----------
    switching : sequence of sympy.Expr
        Switching functions ``s_j`` in the state and parameter symbols.
    states : sequence of sympy.Symbol
        State symbols, in the column order of ``points``.
    parameters : mapping of sympy.Symbol to sympy.Expr
        Parameter values.
    points : array_like, shape (M, n)
        Region points (state units).
    prefer : array_like, shape (n,), optional
        A point taken as its mode's representative when it is in the region's sample set's
        modes.

    Returns
    -------
    list of (tuple of int, ndarray)
        ``(bits, point)`` sorted by bits; modes no point reached are absent.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    funcs = [sp.lambdify(list(states), s.xreplace(dict(parameters)), "numpy")
             for s in switching]
    vals = np.column_stack([np.broadcast_to(np.asarray(fn(*pts.T), dtype=float), (len(pts),))
                            for fn in funcs]) if funcs else np.zeros((len(pts), 0))
    bits = (vals > 0).astype(int)
    margin = np.min(np.abs(vals), axis=1) if funcs else np.zeros(len(pts))
    out: dict[tuple[int, ...], np.ndarray] = {}
    for key in sorted({tuple(int(b) for b in row) for row in bits}):
        rows = np.flatnonzero(np.all(bits == np.asarray(key), axis=1))
        out[key] = pts[rows[int(np.argmax(margin[rows]))]]
    if prefer is not None:
        p = np.asarray(prefer, dtype=float)
        pv = np.array([float(fn(*p)) for fn in funcs])
        if np.all(np.abs(pv) > 0):
            out[tuple(int(v > 0) for v in pv)] = p
    return sorted(out.items())


def coupled_blocks(F: sp.Matrix, C: sp.Matrix) -> list[list[int]]:
    """Groups of states coupled by ``df/dx`` or by a common output.

    States ``i`` and ``j`` are coupled when ``F[i, j]`` or ``F[j, i]`` is not identically zero,
    or when one output depends on both. The groups are the connected components of that
    graph: after permuting the states group by group, ``F`` and ``C`` are block diagonal and
    the rank of ``[C; C F; ...]`` is the sum of the groups' ranks.

    Parameters
    ----------
    F : sympy.Matrix, shape (n, n)
        Symbolic ``df/dx``.
    C : sympy.Matrix, shape (q, n)
        Symbolic ``dh/dx``.

    Returns
    -------
    list of list of int
        State indices of each group, each sorted; groups ordered by their first state.
    """
    n = F.shape[0]
    parent = list(range(n))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def join(i: int, j: int) -> None:
        ri, rj = root(i), root(j)
        if ri != rj:
            parent[max(ri, rj)] = min(ri, rj)

    for i in range(n):
        for j in range(n):
            if i != j and F[i, j] != 0:
                join(i, j)
    for r in range(C.shape[0]):
        cols = [j for j in range(n) if C[r, j] != 0]
        for j in cols[1:]:
            join(cols[0], j)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    return sorted(groups.values(), key=lambda g: g[0])


def numeric_observability_rank(F: npt.ArrayLike, C: npt.ArrayLike, rtol: float = 1e-9) -> int:
    """Rank of ``[C; C F; ...; C F^(n-1)]`` with each block scaled to unit norm.

    Parameters
    ----------
    F : array_like, shape (n, n)
        Jacobian ``df/dx`` at a point (1/s).
    C : array_like, shape (q, n)
        Output Jacobian (output unit per state unit).
    rtol : float
        Singular values below ``rtol`` times the largest count as zero.
    """
    F, C = np.asarray(F, dtype=float), np.asarray(C, dtype=float)
    n = F.shape[0]
    blocks, blk = [], C
    for _ in range(n):
        nrm = np.linalg.norm(blk)
        blocks.append(blk / nrm if nrm > 0 else blk)
        blk = blk @ F
    s = np.linalg.svd(np.vstack(blocks), compute_uv=False)
    return int(np.sum(s > rtol * s[0])) if s.size and s[0] > 0 else 0
