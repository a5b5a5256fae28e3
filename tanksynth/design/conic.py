"""Affine matrix expressions solved straight in Clarabel's conic form (robust, synthesis, placement LMIs).

The robust LMIs of `tanksynth.design.robust.polytopic` are small (a few 3 x 3 to 16 x 16
blocks per vertex, about twenty variables) and solved two or three times per
design. Through cvxpy, canonicalisation cost 0.1-0.2 s per problem (20-40
times Clarabel's own solve) and importing cvxpy 0.4-0.6 s (issue 15). This
module offers the few modelling operations those LMIs use -- variables,
products with constant matrices, ``kron`` with a constant, block matrices,
transposes, sums, ``<<``/``>>`` (positive semidefinite), ``<=``, the
Frobenius norm, maximise/minimise -- with the same spelling as cvxpy, so that
`tanksynth.design.robust.polytopic` builds its constraints once for either. An
expression is an array of shape ``shape + (N + 1,)``: its coefficient on each
of the ``N`` scalar variables of its `Model`, then its constant.

`Problem.solve` writes ``min c'x  s.t.  A x + s = b, s in K`` for Clarabel:
``<=`` in the nonnegative cone, a norm by its epigraph in a second-order
cone, ``M >> 0`` as the symmetric part of ``M`` in Clarabel's scaled upper
triangle (column-major, off-diagonal entries times ``sqrt 2``), the
formulation cvxpy hands to Clarabel for the same problem. The status strings
are cvxpy's (``"optimal"``, ``"infeasible"``, ...). Solutions are unchecked
here: the robust designs re-check every returned gain in numpy.
"""

from __future__ import annotations

import warnings
from typing import Any, Sequence

import clarabel
import numpy as np
import scipy.sparse as sps

__all__ = ["Model", "Expression", "Variable", "Problem", "Maximize", "Minimize", "kron", "bmat",
           "reshape", "trace", "norm", "solve_status", "cvxpy_solve_status", "modelling",
           "CLARABEL_STATUS", "ACCEPTED"]

#: Clarabel status -> cvxpy's status string (what every LMI route reports).
CLARABEL_STATUS = {"Solved": "optimal", "AlmostSolved": "optimal_inaccurate",
           "PrimalInfeasible": "infeasible", "DualInfeasible": "unbounded",
           "AlmostPrimalInfeasible": "infeasible_inaccurate",
           "AlmostDualInfeasible": "unbounded_inaccurate", "MaxIterations": "user_limit",
           "MaxTime": "user_limit"}
#: The statuses whose solution is read (and then re-checked in numpy).
ACCEPTED = ("optimal", "optimal_inaccurate")
_SQRT2 = float(np.sqrt(2.0))


class Model:
    """The scalar variables shared by the expressions of one design.

    Create every variable (`Model.variable`) before building expressions:
    an expression stores one coefficient per variable of the model.
    """

    def __init__(self) -> None:
        self.size = 0
        self.frozen = False
        self.values = np.full(0, np.nan)
        self._vars: list[Variable] = []

    def variable(self, shape: tuple[int, ...] = (), symmetric: bool = False,
                 nonneg: bool = False) -> "Variable":
        """A new variable (scalar, vector or matrix).

        Parameters
        ----------
        shape : tuple of int
            ``()`` for a scalar, ``(r, c)`` for a matrix (units of the caller).
        symmetric : bool
            A symmetric square matrix: its upper triangle is free.
        nonneg : bool
            A scalar constrained to be >= 0 in every problem that uses it.

        Returns
        -------
        Variable
        """
        if self.frozen:
            raise RuntimeError("create every variable before building expressions")
        var = Variable(self, tuple(shape), symmetric, nonneg)
        self._vars.append(var)
        return var

    def freeze(self) -> None:
        """Fix the number of variables (done by the first expression built)."""
        if not self.frozen:
            self.frozen = True
            self.values = np.full(self.size, np.nan)


class Expression:
    """An affine expression ``const + sum_k x_k coef_k`` of one `Model`'s variables.

    Parameters
    ----------
    model : Model
        The model whose variables the expression uses.
    data : ndarray, shape ``shape + (N + 1,)``
        Coefficient of each of the model's ``N`` variables, then the constant
        (units of the expression per unit of the variable).
    """

    __array_ufunc__ = None          # numpy defers ``ndarray @ expr`` to ``expr.__rmatmul__``

    def __init__(self, model: Model, data: np.ndarray):
        self.model = model
        self.data = data

    # ---------------------------------------------------------------- helpers
    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of the expression."""
        return self.data.shape[:-1]

    def _lift(self, other: Any) -> np.ndarray:
        if isinstance(other, Expression):
            return other.data
        c = np.asarray(other, dtype=float)
        out = np.zeros(c.shape + (self.model.size + 1,))
        out[..., -1] = c
        return out

    def _new(self, data: np.ndarray) -> "Expression":
        return Expression(self.model, data)

    @property
    def value(self) -> Any:
        """Value at the model's last solution (None when a variable it uses has none)."""
        coef = self.data[..., :-1]
        used = np.any(coef.reshape(-1, coef.shape[-1]) != 0, axis=0)
        vals = self.model.values
        if vals.size != used.size or not np.all(np.isfinite(vals[used])):
            return None
        out = coef @ np.where(used, vals, 0.0) + self.data[..., -1]
        return float(out) if out.ndim == 0 else out

    # ------------------------------------------------------------- arithmetic
    def __add__(self, other: Any) -> "Expression":
        return self._new(self.data + self._lift(other))

    __radd__ = __add__

    def __sub__(self, other: Any) -> "Expression":
        return self._new(self.data - self._lift(other))

    def __rsub__(self, other: Any) -> "Expression":
        return self._new(self._lift(other) - self.data)

    def __neg__(self) -> "Expression":
        return self._new(-self.data)

    def __mul__(self, other: Any) -> "Expression":
        if isinstance(other, Expression):
            raise TypeError("product of two expressions is not affine")
        c = np.asarray(other, dtype=float)
        return self._new(c[..., None] * self.data)

    __rmul__ = __mul__

    def __truediv__(self, other: Any) -> "Expression":
        return self * (1.0 / float(other))

    def __matmul__(self, other: Any) -> "Expression":
        if isinstance(other, Expression):
            raise TypeError("product of two expressions is not affine")
        c = np.asarray(other, dtype=float)
        return self._new(np.einsum("ijv,jk->ikv", self.data, c))

    def __rmatmul__(self, other: Any) -> "Expression":
        c = np.asarray(other, dtype=float)
        return self._new(np.einsum("ij,jkv->ikv", c, self.data))

    @property
    def T(self) -> "Expression":
        """Transpose."""
        return self._new(np.swapaxes(self.data, 0, 1))

    def __getitem__(self, key: Any) -> "Expression":
        return self._new(self.data[key])

    # ------------------------------------------------------------ constraints
    def __lshift__(self, other: Any) -> "Constraint":
        return Constraint("psd", self._lift(other) - self.data, self.model)

    def __rshift__(self, other: Any) -> "Constraint":
        return Constraint("psd", self.data - self._lift(other), self.model)

    def __le__(self, other: Any) -> "Constraint":
        return Constraint("nonneg", self._lift(other) - self.data, self.model)

    def __ge__(self, other: Any) -> "Constraint":
        return Constraint("nonneg", self.data - self._lift(other), self.model)


class Variable(Expression):
    """A variable of a `Model` (an `Expression` whose coefficients select its entries).

    Parameters
    ----------
    model : Model
        The model it belongs to.
    shape : tuple of int
        ``()`` or ``(r, c)``.
    symmetric : bool
        Symmetric square matrix (its upper triangle is free).
    nonneg : bool
        Constrained ``>= 0`` in every problem that uses it.
    """

    def __init__(self, model: Model, shape: tuple[int, ...], symmetric: bool, nonneg: bool):
        self.nonneg = nonneg
        self._spec = (shape, symmetric)
        first = model.size
        if symmetric:
            n = shape[0]
            count = n * (n + 1) // 2
        else:
            count = int(np.prod(shape, dtype=int)) if shape else 1
        model.size += count
        self._range = (first, first + count)
        self._model = model
        Expression.__init__(self, model, np.zeros(0))

    #: The selection of the variable's entries, built once the model is frozen.
    _data: np.ndarray | None = None

    @property
    def data(self) -> np.ndarray:   # built once the model is frozen
        model = self._model
        model.freeze()
        cached = self._data
        if cached is None or cached.shape[-1] != model.size + 1:
            shape, symmetric = self._spec
            first, _ = self._range
            out = np.zeros(shape + (model.size + 1,))
            if symmetric:
                k = first
                for j in range(shape[0]):
                    for i in range(j + 1):
                        out[i, j, k] = out[j, i, k] = 1.0
                        k += 1
            elif shape == ():
                out[first] = 1.0
            else:
                idx = np.arange(int(np.prod(shape))).reshape(shape)
                out.reshape(-1, model.size + 1)[np.arange(idx.size), first + idx.ravel()] = 1.0
            self._data = cached = out
        return cached

    @data.setter
    def data(self, value: np.ndarray) -> None:
        self._data = None


class Constraint:
    """``data >= 0`` entrywise (``nonneg``) or ``sym(data) >> 0`` (``psd``); ``data`` affine."""

    def __init__(self, kind: str, data: np.ndarray, model: Model):
        self.kind = kind
        self.data = data
        self.model = model

    def rows(self) -> tuple[np.ndarray, Any]:
        """``(G, cone)``: the cone's entries ``s = G @ [x; 1]`` and the Clarabel cone."""
        D = self.data
        if self.kind == "nonneg":
            G = D.reshape(-1, D.shape[-1])
            return G, clarabel.NonnegativeConeT(G.shape[0])
        if self.kind == "soc":
            return D, clarabel.SecondOrderConeT(D.shape[0])
        k = D.shape[0]
        if D.ndim != 3 or D.shape[1] != k:
            raise ValueError(f"a semidefinite constraint needs a square matrix, got {D.shape[:-1]}")
        S = 0.5 * (D + np.swapaxes(D, 0, 1))
        c, r = np.tril_indices(k)                 # upper triangle, column-major
        scale = np.where(r == c, 1.0, _SQRT2)
        return S[r, c] * scale[:, None], clarabel.PSDTriangleConeT(k)


class Maximize:
    """Objective: maximise a scalar expression.

    Parameters
    ----------
    expr : Expression
        Scalar.
    """

    def __init__(self, expr: Expression):
        self.sign, self.expr = -1.0, expr


class Minimize:
    """Objective: minimise a scalar expression or a `norm`.

    Parameters
    ----------
    expr : Expression or the result of `norm`
        Scalar.
    """

    def __init__(self, expr: Any):
        self.sign, self.expr = 1.0, expr


class _Norm:
    def __init__(self, expr: Expression, epigraph: Variable):
        self.expr, self.epigraph = expr, epigraph


def norm(expr: Expression, kind: str = "fro", *, epigraph: Variable) -> _Norm:
    """Frobenius norm of ``expr``, to minimise through the scalar ``epigraph`` variable.

    Parameters
    ----------
    expr : Expression
    kind : {"fro"}
    epigraph : Variable
        A scalar variable of the model, ``>= ||expr||_F`` (second-order cone).

    Returns
    -------
    object
        For `Minimize`.
    """
    if kind != "fro":
        raise ValueError(f"only the Frobenius norm is supported, got {kind!r}")
    return _Norm(expr, epigraph)


def kron(a: Any, b: Expression) -> Expression:
    """``kron(a, b)`` for a constant matrix ``a`` and an expression ``b``.

    Parameters
    ----------
    a : array_like, shape (p, q)
        Constant (dimensionless).
    b : Expression, shape (r, c)

    Returns
    -------
    Expression, shape (p r, q c)
    """
    a = np.asarray(a, dtype=float)
    p, q = a.shape
    r, c = b.shape
    d = np.einsum("ij,abv->iajbv", a, b.data).reshape(p * r, q * c, b.data.shape[-1])
    return Expression(b.model, d)


def bmat(blocks: Sequence[Sequence[Any]]) -> Expression:
    """Block matrix of expressions and constant matrices (cvxpy's ``bmat``).

    Parameters
    ----------
    blocks : sequence of sequence of Expression or array_like
        Rows of blocks (at least one an `Expression`), sizes compatible.

    Returns
    -------
    Expression
    """
    model = next(e.model for row in blocks for e in row if isinstance(e, Expression))
    model.freeze()
    size = model.size + 1

    def lift(e: Any) -> np.ndarray:
        if isinstance(e, Expression):
            return e.data
        c = np.atleast_2d(np.asarray(e, dtype=float))
        out = np.zeros(c.shape + (size,))
        out[..., -1] = c
        return out

    return Expression(model, np.concatenate([np.concatenate([lift(e) for e in row], axis=1)
                                             for row in blocks], axis=0))


def trace(expr: Expression) -> Expression:
    """Trace of a square matrix expression (cvxpy's ``trace``).

    Parameters
    ----------
    expr : Expression, shape (k, k)

    Returns
    -------
    Expression
        Scalar.
    """
    d = expr.data
    if d.ndim != 3 or d.shape[0] != d.shape[1]:
        raise ValueError(f"trace needs a square matrix, got shape {d.shape[:-1]}")
    return Expression(expr.model, np.einsum("iiv->v", d))


def reshape(expr: Expression, shape: tuple[int, ...], order: str = "F") -> Expression:
    """Reshape (column-major by default, as cvxpy's).

    Parameters
    ----------
    expr : Expression
    shape : tuple of int
    order : {"F", "C"}

    Returns
    -------
    Expression
    """
    d = expr.data
    if order == "F":
        lead = d.ndim - 1
        flat = np.transpose(d, tuple(reversed(range(lead))) + (lead,)).reshape(-1, d.shape[-1])
        out = flat.reshape(tuple(reversed(shape)) + (d.shape[-1],))
        out = np.transpose(out, tuple(reversed(range(len(shape)))) + (len(shape),))
    else:
        out = d.reshape(tuple(shape) + (d.shape[-1],))
    return Expression(expr.model, np.ascontiguousarray(out))


class Problem:
    """An objective and constraints over one `Model`, solved by Clarabel.

    Parameters
    ----------
    objective : Maximize or Minimize
    constraints : sequence of Constraint
        From ``<<``, ``>>``, ``<=``, ``>=`` on expressions.
    """

    def __init__(self, objective: Any, constraints: Sequence[Constraint]):
        self.objective = objective
        self.constraints = list(constraints)
        self.status: str | None = None

    def _model(self) -> Model:
        expr = self.objective.expr
        if isinstance(expr, _Norm):
            return expr.expr.model
        if isinstance(expr, Expression):
            return expr.model
        if not self.constraints:
            raise ValueError("a problem with a constant objective needs constraints")
        return self.constraints[0].model          # constant objective: a feasibility problem

    def _data(self) -> tuple:
        obj = self.objective
        model = self._model()
        model.freeze()
        N = model.size
        cons = list(self.constraints)
        c = np.zeros(N + 1)
        if isinstance(obj.expr, _Norm):
            e, t = obj.expr.expr, obj.expr.epigraph
            cons.append(Constraint("soc", np.vstack([t.data[None], e.data.reshape(-1, N + 1)]),
                                   model))
            c += t.data
        elif isinstance(obj.expr, Expression):
            c += obj.sign * obj.expr.data
        else:
            c[N] = obj.sign * float(obj.expr)
        used = c[:N] != 0
        for k in cons:
            used |= np.any(k.data.reshape(-1, N + 1)[:, :N] != 0, axis=0)
        for var in model._vars:
            lo, hi = var._range
            if var.nonneg and np.any(used[lo:hi]):
                cons.append(var >= 0.0)
        Gs, cones = [], []
        for k in cons:
            G, cone = k.rows()
            Gs.append(G)
            cones.append(cone)
        G = np.vstack(Gs)
        cols = np.flatnonzero(used)
        # s = G[:, cols] x + G[:, N] in K  <=>  A x + s = b, A = -G[:, cols], b = G[:, N]
        A = sps.csc_matrix(-G[:, cols])
        b = G[:, N].copy()
        return sps.csc_matrix((cols.size, cols.size)), c[cols], A, b, cones, cols

    def solve(self, solver: str = "CLARABEL", **settings: Any) -> float | None:
        """Solve with Clarabel; set the variables' values and `status` (cvxpy's strings).

        Parameters
        ----------
        solver : {"CLARABEL"}
        **settings
            Clarabel settings.

        Returns
        -------
        float or None
            The optimal objective value (None when not solved).
        """
        if solver != "CLARABEL":
            raise ValueError(f"the conic route solves with Clarabel only, got {solver!r}")
        P, c, A, b, cones, cols = self._data()
        opts = clarabel.DefaultSettings()
        opts.verbose = False
        for key, value in settings.items():
            setattr(opts, key, value)
        model = self._model()
        sol = clarabel.DefaultSolver(P, c, A, b, cones, opts).solve()
        self.status = CLARABEL_STATUS.get(str(sol.status), "solver_error")
        x = np.asarray(sol.x, dtype=float)
        model.values = np.full(model.size, np.nan)
        if self.status in ACCEPTED and x.size == cols.size \
                and np.all(np.isfinite(x)):
            model.values[cols] = x
            return float(c @ x)
        return None


def solve_status(problem: Problem, solver: str, **settings: Any) -> str:
    """Solve ``problem`` and return the status, never raising on a solver failure.

    Parameters
    ----------
    problem : Problem
    solver : str
        ``"CLARABEL"``.
    **settings
        Clarabel settings.

    Returns
    -------
    str
        cvxpy's status string, or ``"solver_error (<message>)"``.
    """
    try:
        problem.solve(solver, **settings)
    except BaseException as exc:  # the Rust solver raises PanicException (a BaseException)
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        problem.status = f"solver_error ({' '.join(str(exc).split())[:200]})"
    return str(problem.status)


def cvxpy_solve_status(problem: Any, solver: str, **settings: Any) -> str:
    """Solve a cvxpy ``problem`` and return cvxpy's status, never raising on a solver failure.

    The status is only a hint: every design re-checks its returned matrices
    with numpy. cvxpy's UserWarnings ("solution may be inaccurate") are
    silenced because the status and the re-check say the same.

    Parameters
    ----------
    problem : cvxpy.Problem
        The LMI problem.
    solver : str
        A cvxpy solver name (``"CLARABEL"``, ``"SCS"``).
    **settings
        Solver settings passed to ``problem.solve``.

    Returns
    -------
    str
        ``problem.status``, or ``"solver_error (<message>)"`` (one line, at most 200 characters).
    """
    import cvxpy as cp      # here, not at module level: the direct Clarabel routes never pay it

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver=solver, **settings)
    except cp.error.SolverError as exc:
        return f"solver_error ({' '.join(str(exc).split())[:200]})"
    return str(problem.status)


class _Conic:
    """`robust`'s modelling calls on this module (Clarabel, no cvxpy)."""

    def __init__(self) -> None:
        self.model = Model()
        self._epigraph: Variable | None = None
        self.kron, self.bmat, self.reshape, self.trace = kron, bmat, reshape, trace
        self.Problem, self.Maximize, self.Minimize = Problem, Maximize, Minimize
        self.solve_status = solve_status

    def variable(self, shape: tuple[int, ...] = (), symmetric: bool = False,
                 nonneg: bool = False) -> Variable:
        return self.model.variable(shape, symmetric, nonneg)

    def reserve_norm(self) -> None:
        """Allocate the epigraph variable of `norm_fro` (before any expression)."""
        self._epigraph = self.model.variable(())

    def norm_fro(self, expr: Expression) -> _Norm:
        if self._epigraph is None:
            raise RuntimeError("call reserve_norm() before building expressions")
        return norm(expr, "fro", epigraph=self._epigraph)


class _Cvxpy:
    """The same calls on cvxpy (the SCS route, and any solver but Clarabel)."""

    def __init__(self) -> None:
        import cvxpy as cp      # here: cvxpy's import costs seconds, the Clarabel route avoids it

        self.cp = cp
        self.kron, self.bmat, self.reshape, self.trace = cp.kron, cp.bmat, cp.reshape, cp.trace
        self.Problem, self.Maximize, self.Minimize = cp.Problem, cp.Maximize, cp.Minimize
        self.solve_status = cvxpy_solve_status

    def variable(self, shape: tuple[int, ...] = (), symmetric: bool = False,
                 nonneg: bool = False) -> Any:
        return self.cp.Variable(shape, symmetric=symmetric, nonneg=nonneg)

    def reserve_norm(self) -> None:
        """Nothing to reserve in cvxpy."""

    def norm_fro(self, expr: Any) -> Any:
        return self.cp.norm(expr, "fro")


def modelling(solver: str) -> Any:
    """The modelling calls for ``solver``: Clarabel's conic form directly, cvxpy otherwise.

    Parameters
    ----------
    solver : str
        ``"CLARABEL"`` (this module) or another cvxpy solver name (``"SCS"``).

    Returns
    -------
    object
        ``variable``, ``kron``, ``bmat``, ``reshape``, ``trace``, ``norm_fro``,
        ``reserve_norm``, ``Problem``, ``Maximize``, ``Minimize``,
        ``solve_status``.
    """
    return _Conic() if solver == "CLARABEL" else _Cvxpy()
