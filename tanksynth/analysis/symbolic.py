"""Symbolic core: Jacobians, Lie derivatives, relative degree, decoupling.

Symbolic work happens once per plant; numeric evaluation goes through the
compiled CasADi functions (`tanksynth.plants.compile`). Jacobians use the
sparsity of the model: an entry is differentiated only when the variable
appears in the expression, which keeps the N-tank network cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import sympy as sp

from tanksynth.analysis.budget import SYMBOLIC_SECONDS, TooComplexError, run_within_budget
from tanksynth.errors import DimensionError, TanksynthError

__all__ = [
    "SYMBOLIC_SECONDS",
    "TooComplexError",
    "jacobian",
    "jacobian_by_form",
    "canonical_form",
    "form_symbol",
    "control_affine",
    "lie_derivative",
    "lie_derivatives",
    "RelativeDegree",
    "relative_degree",
]


def jacobian(exprs: sp.Matrix, variables: Sequence[sp.Symbol]) -> sp.Matrix:
    """Jacobian of a column of expressions, differentiating only where needed.

    Parameters
    ----------
    exprs : sympy.Matrix, shape (k, 1)
    variables : sequence of sympy.Symbol, length n

    Returns
    -------
    sympy.Matrix, shape (k, n)
    """
    exprs = sp.Matrix(exprs)
    if exprs.shape[1] != 1:
        raise DimensionError(f"jacobian expects a column, got shape {exprs.shape}")
    index = {v: j for j, v in enumerate(variables)}
    out = sp.zeros(exprs.shape[0], len(variables))
    for i, e in enumerate(exprs):
        for s in e.free_symbols:
            j = index.get(s)
            if j is not None:
                out[i, j] = sp.diff(e, s)
    return out


def canonical_form(expr: sp.Expr, index: dict) -> tuple[sp.Expr, dict, tuple]:
    """``expr`` with its variables renamed ``_tanksynth_form_0, ...`` (in the order of ``index``).

    Rows of a plant built from repeated parts (one tank type, another
    instance) then share one renamed form, and work on it (derivatives,
    expansion, compilation) is done once per form (`jacobian_by_form`,
    `tanksynth.analysis.quasi_lpv.FormEvaluator`).

    Parameters
    ----------
    expr : sympy.Expr
        An expression of (some of) the variables.
    index : dict
        Variable (sympy.Symbol) -> its position; symbols not in it are left as they are.

    Returns
    -------
    form : sympy.Expr
        ``expr`` with its k-th own variable replaced by `form_symbol` ``(k, variable)``.
    back : dict
        Form symbol -> the variable it stands for.
    own : tuple of sympy.Symbol
        The variables of ``expr``, in the order of ``index``.
    """
    own = sorted((s for s in expr.free_symbols if s in index), key=index.__getitem__)
    forward = {s: form_symbol(k, s) for k, s in enumerate(own)}
    return expr.xreplace(forward), {v: s for s, v in forward.items()}, tuple(own)


def form_symbol(k: int, like: sp.Symbol) -> sp.Symbol:
    """The k-th variable of a renamed form (`canonical_form`), with the assumptions of ``like``.

    Parameters
    ----------
    k : int
        Position of the variable in the form.
    like : sympy.Symbol
        The variable it stands for (its assumptions: real, positive, ...).
    """
    return sp.Symbol(f"_tanksynth_form_{k}", **like.assumptions0)


def jacobian_by_form(exprs: sp.Matrix, variables: Sequence[sp.Symbol],
                     memo: dict | None = None) -> sp.Matrix:
    """`jacobian`, differentiating each distinct form of a row once (see `canonical_form`).

    The same matrix as `jacobian`: a row's derivatives are those of its
    renamed form with the variables put back. For a network of ``n`` tanks of
    a few types, a few forms are differentiated instead of ``n`` rows.

    Parameters
    ----------
    exprs : sympy.Matrix, shape (k, 1)
    variables : sequence of sympy.Symbol, length n
    memo : dict, optional
        Derivatives of the forms already seen (shared between calls).

    Returns
    -------
    sympy.Matrix, shape (k, n)
    """
    exprs = sp.Matrix(exprs)
    if exprs.shape[1] != 1:
        raise DimensionError(f"jacobian expects a column, got shape {exprs.shape}")
    index = {v: j for j, v in enumerate(variables)}
    memo = {} if memo is None else memo
    out = sp.zeros(exprs.shape[0], len(variables))
    for i, e in enumerate(exprs):
        form, back, own = canonical_form(e, index)
        if form not in memo:
            memo[form] = tuple(sp.diff(form, form_symbol(k, s)) for k, s in enumerate(own))
        for s, d in zip(own, memo[form]):
            out[i, index[s]] = d.xreplace(back)
    return out


def control_affine(f: sp.Matrix, u: Sequence[sp.Symbol]) -> tuple[sp.Matrix, sp.Matrix]:
    """Split ``f(x, u) = f0(x) + G(x) u``.

    Parameters
    ----------
    f : sympy.Matrix, shape (n, 1)
        The vector field ``dx/dt = f(x, u)``.
    u : sequence of sympy.Symbol, length m
        The input symbols.

    Returns
    -------
    f0 : sympy.Matrix, shape (n, 1)
    G : sympy.Matrix, shape (n, m)

    Raises
    ------
    TanksynthError
        If ``f`` is not affine in ``u``.
    """
    G = jacobian(f, u)
    if any(s in G.free_symbols for s in u):
        raise TanksynthError("the model is not affine in its inputs (df/du depends on u)")
    f0 = f.xreplace({s: 0 for s in u})
    return f0, G


def lie_derivative(h: sp.Matrix, field: sp.Matrix, x: Sequence[sp.Symbol], order: int = 1) -> sp.Matrix:
    """``L_field^order h`` for a column of scalar functions ``h``.

    Parameters
    ----------
    h : sympy.Matrix, shape (q, 1)
    field : sympy.Matrix, shape (n, 1)
    x : sequence of sympy.Symbol, length n
    order : int, >= 0

    Returns
    -------
    sympy.Matrix, shape (q, 1)
    """
    if order < 0:
        raise ValueError("order must be >= 0")
    out = sp.Matrix(h)
    for _ in range(order):
        out = jacobian(out, x) * field
    return out


def lie_derivatives(h: sp.Matrix, field: sp.Matrix, x: Sequence[sp.Symbol], count: int) -> list[sp.Matrix]:
    """``[L^0 h, L^1 h, ..., L^(count-1) h]`` along ``field``.

    Parameters
    ----------
    h : sympy.Matrix, shape (q, 1)
        The scalar functions (outputs) to differentiate.
    field : sympy.Matrix, shape (n, 1)
        The vector field along which they are differentiated.
    x : sequence of sympy.Symbol, length n
        The state symbols.
    count : int
        How many derivatives, ``L^0 h`` included (>= 1).

    Returns
    -------
    list of sympy.Matrix, each shape (q, 1)
    """
    out = [sp.Matrix(h)]
    for _ in range(count - 1):
        out.append(jacobian(out[-1], x) * field)
    return out


@dataclass(frozen=True)
class RelativeDegree:
    """Relative degrees and decoupling matrices of a square control-affine plant.

    Attributes
    ----------
    degrees : tuple of int
        ``theta_i``: smallest k with ``L_g L_f^(k-1) h_i`` not identically 0.
    decoupling : sympy.Matrix, shape (q, m)
        ``Lambda(x)``, row i = ``L_g L_f^(theta_i - 1) h_i``.
    drift : sympy.Matrix, shape (q, 1)
        ``Lambda_0(x)``, row i = ``L_f^theta_i h_i``.
    """

    degrees: tuple[int, ...]
    decoupling: sp.Matrix
    drift: sp.Matrix

    @property
    def total(self) -> int:
        """Sum of the relative degrees (dimension of the linearised part)."""
        return sum(self.degrees)


def relative_degree(f: sp.Matrix, h: sp.Matrix, x: Sequence[sp.Symbol],
                    u: Sequence[sp.Symbol]) -> RelativeDegree:
    """Relative degree vector and decoupling matrix (seed 000 eq. 19-23).

    Parameters
    ----------
    f : sympy.Matrix, shape (n, 1)
        Control-affine vector field ``f0(x) + G(x) u`` (use the smooth form
        on the operating region).
    h : sympy.Matrix, shape (q, 1)
    x, u : sequences of sympy.Symbol

    Raises
    ------
    TanksynthError
        If an output does not depend on the inputs at any order up to n.
    TooComplexError
        The Lie derivatives or their simplification exceed `SYMBOLIC_SECONDS`.
    """
    return run_within_budget(_relative_degree, f, h, tuple(x), tuple(u),
                             what="the relative degree (Lie derivatives, simplification)")


def _relative_degree(f: sp.Matrix, h: sp.Matrix, x: Sequence[sp.Symbol],
                     u: Sequence[sp.Symbol]) -> RelativeDegree:
    f0, G = control_affine(sp.Matrix(f), u)
    n = len(x)
    degrees, rows, drift = [], [], []
    for i in range(h.shape[0]):
        Lk = sp.Matrix([h[i]])
        for k in range(1, n + 1):
            grad = jacobian(Lk, x)
            LgL = sp.simplify(grad * G)
            if any(e != 0 for e in LgL):
                degrees.append(k)
                rows.append(LgL)
                drift.append(sp.simplify((grad * f0)[0]))
                break
            Lk = grad * f0
        else:
            raise TanksynthError(
                f"relative degree of output {i + 1} ({h[i]}) is undefined: it does not depend "
                f"on the inputs at any order up to n = {n}"
            )
    return RelativeDegree(tuple(degrees), sp.Matrix.vstack(*rows), sp.Matrix(drift))
