"""Compile a plant's sympy model once into CasADi functions.

`to_casadi` walks a sympy tree and rebuilds it in CasADi SX (no string
round trip, no lambdify). `compile_plant` builds, once per plant, the
functions the estimators, the simulator and the rank checks evaluate:
``f(x, u)``, ``h(x)`` and their Jacobians, with a batch form over many
points at once. `rk4_step` is the toolbox's one Runge-Kutta step, written
once for numpy arrays and CasADi expressions alike: the simulator
(`tanksynth.sim`) and the estimators' prediction models
(`tanksynth.runtime.estimators`) both discretise the plant with it (it lives
here, below both, because those two layers must not import each other).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

import casadi as ca
import numpy as np
import sympy as sp

from tanksynth.errors import TanksynthError

if TYPE_CHECKING:  # the plant's module imports this one on first use (Plant.compiled)
    from tanksynth.plants.base import Plant

__all__ = ["to_casadi", "CompiledPlant", "compile_plant", "compile_matrix", "rk4_step",
           "evaluate_map", "evaluate_points"]


def rk4_step(rhs: Callable[..., Any], x: Any, h: Any, clip: Callable[[Any], Any] | None = None,
             t: Any = None) -> Any:
    """One classical Runge-Kutta (RK4) step of ``dx/dt = rhs(x)``: the toolbox's one scheme.

    ``k1 = rhs(c(x))``, ``k2 = rhs(c(x + h/2 k1))``, ``k3 = rhs(c(x + h/2 k2))``,
    ``k4 = rhs(c(x + h k3))``, ``x + h/6 (k1 + 2 k2 + 2 k3 + k4)``, with every
    stage state passed through ``c = clip`` before the vector field is
    evaluated (so that Torricelli's square root never sees a level below
    the plant's bounds, `Plant.state_bounds`). The end state is returned
    unclipped: the caller clips it (after locating switching surfaces, in
    `tanksynth.sim`). Written with ``+``, ``*`` only, so it runs on numpy
    arrays (a batch, shape (M, n), with ``h`` a float or an (M, 1) column)
    and on CasADi SX/MX expressions alike.

    Parameters
    ----------
    rhs : callable
        ``x -> dx/dt`` (the input is bound by the caller: held, or a law
        evaluated at every stage).
    x : ndarray or casadi.SX
        State at the start of the step (state units).
    h : float or ndarray
        Step (s).
    clip : callable, optional
        Clipping of the stage states (identity when None).
    t : float, optional
        Time at the start of the step (s), for a time-varying field: then
        ``rhs(x, t_stage)`` is called with ``t_stage = t, t + h/2, t + h/2,
        t + h``.

    Returns
    -------
    Same type as ``x``: the state after ``h`` seconds, before clipping.
    """
    c = clip if clip is not None else (lambda v: v)
    if t is None:
        f = lambda v, _s: rhs(v)  # noqa: E731
    else:
        f = lambda v, s: rhs(v, t + s * h)  # noqa: E731
    k1 = f(c(x), 0.0)
    k2 = f(c(x + 0.5 * h * k1), 0.5)
    k3 = f(c(x + 0.5 * h * k2), 0.5)
    k4 = f(c(x + h * k3), 1.0)
    return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def to_casadi(expr: sp.Expr, symbols: Mapping[sp.Symbol, ca.SX], _cache: dict | None = None) -> ca.SX:
    """Translate a sympy expression into a CasADi SX expression.

    Parameters
    ----------
    expr : sympy.Expr
        Expression in the symbols of ``symbols`` (parameters substituted).
    symbols : mapping of sympy.Symbol to casadi.SX
        The CasADi scalar standing for each free symbol.

    Returns
    -------
    casadi.SX
        Scalar expression. ``DiracDelta`` (from differentiating ``sign``)
        evaluates to 0: it only differs from 0 on a set of measure zero.
    """
    cache = {} if _cache is None else _cache
    if expr in cache:
        return cache[expr]

    def rec(e: sp.Expr) -> ca.SX:
        return to_casadi(e, symbols, cache)

    if expr.is_Symbol:
        if expr not in symbols:
            raise TanksynthError(f"cannot compile: free symbol {expr} has no value")
        out = symbols[expr]
    elif expr.is_Number or expr is sp.pi or expr is sp.E:
        out = ca.SX(float(expr))
    elif expr.is_Add:
        out = rec(expr.args[0])
        for a in expr.args[1:]:
            out = out + rec(a)
    elif expr.is_Mul:
        out = rec(expr.args[0])
        for a in expr.args[1:]:
            out = out * rec(a)
    elif expr.is_Pow:
        base, exponent = expr.args
        b = rec(base)
        if exponent == sp.Rational(1, 2):
            out = ca.sqrt(b)
        elif exponent == -sp.Rational(1, 2):
            out = 1 / ca.sqrt(b)
        elif exponent.is_Integer:
            k = int(exponent)
            out = ca.constpow(b, k) if k >= 0 else 1 / ca.constpow(b, -k)
        elif exponent.is_number:
            out = ca.power(b, float(exponent))
        else:
            out = ca.power(b, rec(exponent))
    elif isinstance(expr, sp.Abs):
        out = ca.fabs(rec(expr.args[0]))
    elif isinstance(expr, sp.sign):
        out = ca.sign(rec(expr.args[0]))
    elif isinstance(expr, sp.exp):
        out = ca.exp(rec(expr.args[0]))
    elif isinstance(expr, sp.log):
        out = ca.log(rec(expr.args[0]))
    elif isinstance(expr, sp.Max):
        out = rec(expr.args[0])
        for a in expr.args[1:]:
            out = ca.fmax(out, rec(a))
    elif isinstance(expr, sp.Min):
        out = rec(expr.args[0])
        for a in expr.args[1:]:
            out = ca.fmin(out, rec(a))
    elif isinstance(expr, sp.Heaviside):
        a = rec(expr.args[0])
        out = ca.if_else(a > 0, 1, ca.if_else(a < 0, 0, 0.5))
    elif isinstance(expr, sp.DiracDelta):
        out = ca.SX(0.0)
    elif isinstance(expr, sp.Piecewise):
        out = ca.SX(np.nan)
        for value, cond in reversed(expr.args):
            out = ca.if_else(rec(cond), rec(value), out) if cond is not sp.true else rec(value)
    elif isinstance(expr, (sp.StrictGreaterThan, sp.GreaterThan, sp.StrictLessThan, sp.LessThan)):
        lhs, rhs = rec(expr.lhs), rec(expr.rhs)
        out = {sp.StrictGreaterThan: lhs > rhs, sp.GreaterThan: lhs >= rhs,
               sp.StrictLessThan: lhs < rhs, sp.LessThan: lhs <= rhs}[type(expr)]
    elif isinstance(expr, (sp.Eq, sp.Ne)):
        lhs, rhs = rec(expr.lhs), rec(expr.rhs)
        out = lhs == rhs if isinstance(expr, sp.Eq) else lhs != rhs
    elif isinstance(expr, sp.Not):
        out = ca.logic_not(rec(expr.args[0]))
    elif expr is sp.true or expr is sp.false:
        out = ca.SX(1.0 if expr is sp.true else 0.0)
    elif isinstance(expr, (sp.And, sp.Or)):
        parts = [rec(a) for a in expr.args]
        out = parts[0]
        for p in parts[1:]:
            out = ca.logic_and(out, p) if isinstance(expr, sp.And) else ca.logic_or(out, p)
    else:
        raise TanksynthError(f"cannot compile {type(expr).__name__} in {expr}")
    cache[expr] = out
    return out


def compile_matrix(name: str, matrix: sp.Matrix, inputs: Sequence[Sequence[sp.Symbol]],
                   input_names: Sequence[str]) -> ca.Function:
    """Compile a sympy matrix into a CasADi Function of vector arguments.

    Parameters
    ----------
    name : str
        Name of the Function.
    matrix : sympy.Matrix
        The expression matrix.
    inputs : sequence of sequence of sympy.Symbol
        The symbols of each vector argument.
    input_names : sequence of str
        Names of the arguments.
    """
    args = [ca.SX.sym(nm, len(syms)) for nm, syms in zip(input_names, inputs)]
    symbols = {}
    for arg, syms in zip(args, inputs):
        for i, s in enumerate(syms):
            symbols[s] = arg[i]
    cache: dict = {}
    rows, cols = matrix.shape
    out = ca.SX.zeros(rows, cols)
    for i in range(rows):
        for j in range(cols):
            entry = matrix[i, j]
            if entry != 0:
                out[i, j] = to_casadi(entry, symbols, cache)
    return ca.Function(name, args, [out], list(input_names), ["out"])


@dataclass
class CompiledPlant:
    """Numeric functions of one plant, compiled once.

    Attributes
    ----------
    f : casadi.Function
        ``f(x, u) -> dx/dt`` (general model, parameters substituted).
    h : casadi.Function
        ``h(x) -> y``.
    jac_x, jac_u : casadi.Function
        ``df/dx (x, u)`` (n x n) and ``df/du (x, u)`` (n x m), by AD.
    jac_h : casadi.Function
        ``dh/dx (x)`` (q x n).
    switching : casadi.Function or None
        Hybrid switching functions ``s(x)`` (k), when the plant has modes.
    n, m, q : int
        Numbers of states, inputs and outputs.
    """

    n: int
    m: int
    q: int
    f: ca.Function
    h: ca.Function
    jac_x: ca.Function
    jac_u: ca.Function
    jac_h: ca.Function
    switching: ca.Function | None = None
    _maps: dict[tuple[str, int], ca.Function] = field(default_factory=dict, repr=False)

    def _batch(self, fn: ca.Function, *arrays: np.ndarray, matrix: bool = False) -> np.ndarray:
        points = [np.atleast_2d(np.asarray(a, dtype=float)) for a in arrays]
        count = points[0].shape[0]
        key = (fn.name(), count)
        if key not in self._maps:
            self._maps[key] = fn.map(count, "serial")
        out = evaluate_map(self._maps[key], *points)
        return out if matrix else out[:, :, 0]

    def rhs(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``f`` at M points: ``x`` (M, n), ``u`` (M, m) -> (M, n).

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        u : ndarray, shape (M, m)
            Inputs (input units, m^3/s).
        """
        return self._batch(self.f, x, u)

    def output(self, x: np.ndarray) -> np.ndarray:
        """``h`` at M points: (M, n) -> (M, q).

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        """
        return self._batch(self.h, x)

    def jacobians(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``df/dx`` (M, n, n) and ``df/du`` (M, n, m) at M points.

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        u : ndarray, shape (M, m)
            Inputs (input units, m^3/s).
        """
        return (self._batch(self.jac_x, x, u, matrix=True),
                self._batch(self.jac_u, x, u, matrix=True))

    def modes(self, x: np.ndarray) -> np.ndarray:
        """Hybrid mode bits ``[s_j(x) > 0]`` at M points: (M, n) -> (M, k) ints.

        Parameters
        ----------
        x : ndarray, shape (M, n)
            States (state units, m).
        """
        if self.switching is None:
            raise TanksynthError("the plant has no hybrid modes")
        return (self._batch(self.switching, x) > 0).astype(int)


def _buffer(fn: ca.Function) -> tuple[Any, Callable[[], Any]]:
    """``fn.buffer()``: the buffer (``set_arg(i, memoryview)``, ``set_res(i, memoryview)``) and
    the call that evaluates into it.

    CasADi's stubs give ``set_arg``/``set_res`` the C++ signature (pointer, size); the Python
    binding takes one buffer object, hence the buffer typed as Any.
    """
    buf, run = fn.buffer()
    return buf, run


def evaluate_map(mapped: ca.Function, *arrays: np.ndarray) -> np.ndarray:
    """Evaluate a mapped Function at M points straight into numpy (no ``DM`` round trip).

    Converting a ``casadi.DM`` result to numpy goes through a Python list of its elements
    (about 0.2 us per entry: 0.15 s for the 200 Jacobians of a 64-tank network); the
    Function's buffer interface writes the output's non-zeros into a numpy array instead.

    Parameters
    ----------
    mapped : casadi.Function
        ``fn.map(M, ...)`` of a Function with vector arguments and one (rows x cols) output.
    *arrays : ndarray, shape (M, k_i)
        Argument i at each of the M points (row j = point j).

    Returns
    -------
    ndarray, shape (M, rows, cols)
        The output at each point.
    """
    count = arrays[0].shape[0]
    sparsity = mapped.sparsity_out(0)
    rows, total = sparsity.shape
    cols = total // count if count else 0
    args = [np.ascontiguousarray(a, dtype=float) for a in arrays]  # (M, k) C = (k, M) column-major
    shapes_ok = all(mapped.sparsity_in(i).is_dense() and mapped.size_in(i) == (a.shape[1], count)
                    for i, a in enumerate(args))
    if not shapes_ok or count == 0 or any(a.size == 0 for a in args):
        out = np.asarray(mapped(*[a.T for a in args]), dtype=float)
        return out.reshape(rows, count, cols).transpose(1, 0, 2)
    buf, run = _buffer(mapped)
    for i, a in enumerate(args):
        buf.set_arg(i, a.data)
    nz = np.empty(sparsity.nnz())
    if nz.size:
        buf.set_res(0, nz.data)
        run()
    if sparsity.is_dense():
        flat = nz
    else:
        flat = np.zeros(rows * total)
        flat[np.asarray(sparsity.row(), dtype=np.intp)
             + rows * np.asarray(sparsity.get_col(), dtype=np.intp)] = nz
    # column-major (rows, M * cols): flat index = r + rows * (j * cols + c)
    return flat.reshape(count, cols, rows).transpose(0, 2, 1)


def evaluate_points(fn: ca.Function, *arrays: np.ndarray) -> np.ndarray:
    """Evaluate a Function point by point through its buffer interface (no ``map``).

    For a one-off evaluation at a few hundred points this beats ``fn.map(M)``: building the
    map of an SX Function costs about 0.3-0.5 s for a 64 x 64 codistribution, a call through
    the buffer a few microseconds.

    Parameters
    ----------
    fn : casadi.Function
        A Function of vector arguments with one (rows x cols) output.
    *arrays : ndarray, shape (M, k_i)
        Argument i at each of the M points (row j = point j).

    Returns
    -------
    ndarray, shape (M, rows, cols)
        The output at each point.
    """
    args = [np.ascontiguousarray(a, dtype=float) for a in arrays]
    count = args[0].shape[0]
    sparsity = fn.sparsity_out(0)
    rows, cols = sparsity.shape
    nz = np.zeros((count, sparsity.nnz()))
    if not all(fn.sparsity_in(i).is_dense() and fn.size_in(i) == (a.shape[1], 1)
               for i, a in enumerate(args)):
        return evaluate_map(fn.map(count, "serial"), *arrays)
    if nz.shape[1] and count:
        buf, run = _buffer(fn)
        rows_j = [np.ascontiguousarray(a) for a in args]
        for j in range(count):
            for i, a in enumerate(rows_j):
                if a.shape[1]:
                    buf.set_arg(i, a[j].data)
            buf.set_res(0, nz[j].data)
            run()
    out = np.zeros((count, cols * rows))
    if sparsity.is_dense():
        out = nz
    else:
        out[:, np.asarray(sparsity.row(), dtype=np.intp)
            + rows * np.asarray(sparsity.get_col(), dtype=np.intp)] = nz
    return out.reshape(count, cols, rows).transpose(0, 2, 1)


def compile_plant(plant: Plant) -> CompiledPlant:
    """Compile a `Plant` (parameters substituted) into a `CompiledPlant`.

    Parameters
    ----------
    plant : Plant
        The plant model.
    """
    f = compile_matrix("f", plant.f_numeric, [plant.x, plant.u], ["x", "u"])
    h = compile_matrix("h", plant.h_numeric, [plant.x], ["x"])
    xs = ca.SX.sym("x", plant.n)
    us = ca.SX.sym("u", plant.m)
    fx = f(xs, us)
    jac_x = ca.Function("jac_x", [xs, us], [ca.jacobian(fx, xs)], ["x", "u"], ["out"])
    jac_u = ca.Function("jac_u", [xs, us], [ca.jacobian(fx, us)], ["x", "u"], ["out"])
    jac_h = ca.Function("jac_h", [xs], [ca.jacobian(h(xs), xs)], ["x"], ["out"])
    switching = None
    if plant.hybrid is not None:
        s = sp.Matrix(plant.hybrid.switching).xreplace(plant.parameter_values)
        switching = compile_matrix("switching", s, [plant.x], ["x"])
    return CompiledPlant(plant.n, plant.m, plant.q, f, h, jac_x, jac_u, jac_h, switching)
