"""Symbolic observability rank: the factored determinant of ``[C; CA; ...]``.

Split from `tanksynth.analysis.rank` (which re-exports it): the parameter
sets and state surfaces on which the linearisation's observability matrix
drops rank, for reports and ``tanksynth check``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import sympy as sp

__all__ = ["SymbolicRank", "symbolic_observability"]


@dataclass(frozen=True)
class SymbolicRank:
    """Symbolic rank condition of an observability matrix.

    Attributes
    ----------
    matrix : sympy.Matrix
        ``O = [C; CA; ...; CA^(n-1)]``.
    blocks_used : int
        Minors are taken over the first ``blocks_used`` blocks ``C A^k``:
        the fewest that reach rank n generically (with ``C = I``, one).
    determinant : sympy.Expr
        ``det O`` factored (square case) or the gcd of the non-zero maximal
        minors (rank < n needs every minor to vanish).
    factors : tuple of sympy.Expr
        Non-constant factors: the rank drops where any of them vanishes.
    variables : tuple of sympy.Symbol
        Premise/state variables treated as varying.
    degenerate_parameters : tuple of dict
        Parameter values for which ``det O`` vanishes identically in the
        variables (the structure is unobservable whatever they are).
    null_direction : tuple of str
        When the determinant is identically zero: the states carrying (at
        least 10% of) the kernel of ``O`` at a generic point, i.e. the
        unobservable direction.
    """

    matrix: sp.Matrix
    blocks_used: int
    determinant: sp.Expr
    factors: tuple[sp.Expr, ...]
    variables: tuple[sp.Symbol, ...]
    degenerate_parameters: tuple[dict, ...] = field(default=())
    null_direction: tuple[str, ...] = field(default=())

    @property
    def identically_zero(self) -> bool:
        """``det O`` (every maximal minor) is zero for every parameter and variable value."""
        det = self.determinant
        if det == 0:
            return True
        # non-zero at one point: not identically zero (simplify only when that cannot tell)
        rng = np.random.default_rng(1)
        point = {s: sp.Rational(int(rng.integers(2, 97)), int(rng.integers(2, 97)))
                 for s in sorted(det.free_symbols, key=str)}
        try:
            value = complex(sp.N(det.xreplace(point)))
            if np.isfinite(value) and abs(value) > 1e-12:
                return False
        except (TypeError, ValueError, ZeroDivisionError):
            pass
        return bool(sp.simplify(det) == 0)

    def as_dict(self) -> dict:
        """JSON-friendly summary (expressions as strings)."""
        return {"determinant": str(self.determinant), "blocks_used": self.blocks_used, "factors": [str(f) for f in self.factors],
                "variables": [str(v) for v in self.variables],
                "degenerate_parameters": [{str(k): str(v) for k, v in d.items()}
                                          for d in self.degenerate_parameters],
                "identically_zero": self.identically_zero,
                "null_direction": list(self.null_direction)}


def symbolic_observability(A: sp.Matrix, C: sp.Matrix,
                           variables: Sequence[sp.Symbol] = (),
                           state_names: Sequence[str] | None = None,
                           search_degenerate: bool = True) -> SymbolicRank:
    """Factored determinant of the observability matrix and its conditions.

    Parameters
    ----------
    A : sympy.Matrix, shape (n, n)
        May depend on parameters and on varying ``variables`` (premise
        variables or states).
    C : sympy.Matrix, shape (q, n)
    variables : sequence of sympy.Symbol
        The symbols that vary; the remaining free symbols are parameters.
        ``degenerate_parameters`` lists the parameter sets on which the
        determinant (every maximal minor) vanishes for every value of the
        variables.
    state_names : sequence of str, optional
        Names of the columns, for the unobservable direction of an
        identically singular ``O``.
    search_degenerate : bool, optional
        Solve for ``degenerate_parameters`` (default True; the solve can take seconds when
        the determinant has several parameter factors).
    """
    A, C = sp.Matrix(A), sp.Matrix(C)
    n = A.shape[0]
    blocks = [C]
    for _ in range(n - 1):
        blocks.append(blocks[-1] * A)
    # Only the first blocks that reach rank n generically are needed: with
    # C = I the observability matrix is decided by C alone (1 minor, not 84).
    # Generic rank: at random rational values of every symbol.
    rng = np.random.default_rng(0)
    symbols = sorted(set().union(*(b.free_symbols for b in blocks)), key=str)
    point = {s: sp.Rational(int(rng.integers(2, 97)), int(rng.integers(2, 97))) for s in symbols}
    all_blocks = blocks
    for k in range(1, n + 1):
        if sp.Matrix.vstack(*blocks[:k]).xreplace(point).rank() == n:
            blocks = blocks[:k]
            break
    O = sp.Matrix.vstack(*blocks).applyfunc(sp.expand)
    O_full = sp.Matrix.vstack(*all_blocks).applyfunc(sp.expand)
    if O.shape[0] == n:
        det = sp.factor(O.det(method="berkowitz"))
        minors = [sp.expand(det)]
    else:
        from itertools import combinations

        minors = [sp.expand(O.extract(list(r), list(range(n))).det(method="berkowitz"))
                  for r in combinations(range(O.shape[0]), n)]
        minors = [mnr for mnr in minors if mnr != 0]
        det = sp.factor(sp.gcd_list(minors)) if minors else sp.Integer(0)
    numerator = sp.factor(sp.fraction(sp.together(det))[0])
    factors = []
    for fac in sp.Mul.make_args(numerator):
        if fac.is_Pow and fac.exp.is_positive:
            fac = fac.base
        if fac.free_symbols and fac not in factors:
            factors.append(fac)
    variables = tuple(variables)
    degenerate: list[dict] = []
    params = sorted(set().union(*(mnr.free_symbols for mnr in minors)) - set(variables), key=str) \
        if minors else []
    if minors and params and search_degenerate:
        try:
            coeffs = sorted({c for mnr in minors
                             for c in sp.Poly(sp.fraction(sp.together(mnr))[0], *variables).coeffs()},
                            key=str) if variables else minors
            sols = sp.solve(coeffs, params, dict=True)
        except sp.PolynomialError:
            # Not polynomial in the variables: only factors free of them can
            # vanish identically.
            sols = []
            if len(minors) == 1:
                for fac in factors:
                    if not fac.free_symbols & set(variables):
                        sols += sp.solve(fac, sorted(fac.free_symbols, key=str), dict=True)
        # A parameter set that kills the truncated matrix may leave the later
        # blocks with rank n: keep it only if the full matrix drops rank too.
        degenerate = [sol for sol in sols if sol and
                      O_full.xreplace(sol).xreplace(point).rank() < n]
    null: tuple[str, ...] = ()
    if det == 0:
        names = list(state_names) if state_names is not None else [f"x{i + 1}" for i in range(n)]
        kernel = O_full.xreplace(point).nullspace()
        if kernel:
            v = np.abs(np.array([float(sp.N(x)) for x in kernel[0]]))
            null = tuple(nm for nm, x in zip(names, v) if x >= 0.1 * v.max())
    return SymbolicRank(O_full, len(blocks), det, tuple(factors), variables, tuple(degenerate),
                        null)
