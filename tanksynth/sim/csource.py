"""C source of the plant's simulation kernel, translated from its generated numpy code.

`kernel_source` walks the Python syntax tree of the generated numpy source of
a plant (`tanksynth.sim.tape.NumpyModel.source`, its ``f`` and ``s``
functions) and writes the same statements in C: the same operations, in the
same order, on the same IEEE doubles (numpy's fast paths for ``x**2``,
``x**-1``, ``x**0.5`` written as numpy computes them; ``numpy.maximum`` and
``numpy.minimum`` propagating NaN like numpy's; ``numpy.select`` as nested
conditionals). Around it, the RK4 step of `tanksynth.sim.integrate`
(stage states clipped, ``x + ((2 k2 + k1) + 2 k3 + k4) h/6``, the end
state clipped, the hybrid mode bits compared across every step, the
clipping flags), written out as one straight-line block of C per run (the
four evaluations of ``f`` inlined, every value a local), in a loop over
blocks of `BLOCK` runs laid out one row per state, so that the C compiler
vectorises across runs (with AVX2 where the CPU has it); remaining runs
one at a time. Compiled with ``-ffp-contract=off`` (no fused multiply-add)
and without ``-ffast-math``, the kernel gives the numbers of the numpy code
bit for bit (tested). Building and loading: `tanksynth.sim.kernel` (compiler, flags
and cache: `tanksynth.native_cache`).
"""

from __future__ import annotations

import ast
from typing import Any

import numpy as np

__all__ = ["kernel_source", "BLOCK", "MAX_SUBSTEPS", "KERNEL_VERSION", "INLINE_LIMIT"]

#: Runs integrated together by the vectorised C loop.
BLOCK = 8
#: Largest number of RK4 steps per period the kernel handles (per-run flag bits).
MAX_SUBSTEPS = 64
#: Bumped whenever the generated C changes meaning (part of the cache key).
KERNEL_VERSION = "4"
#: Largest ``f`` (generated statements) written out inline in every RK4 stage; larger plants
#: call ``f`` as a function per stage (the compiler's time grows fast with straight-line code:
#: tank_network N = 64 took 12.6 s inline, 2.2 s as a function).
INLINE_LIMIT = 24


class _Unsupported(Exception):
    """The generated source uses a construct the C translation does not know."""


# ----------------------------------------------------------------------------- translation
def _c_float(v: float) -> str:
    if v != v:
        return "NAN"
    if v in (float("inf"), float("-inf")):
        return "INFINITY" if v > 0 else "(-INFINITY)"
    return f"{float(v).hex()}"    # exact (C99 hexadecimal literal)


_NUMPY_1 = {"sqrt": "sqrt", "exp": "exp", "log": "log", "abs": "fabs", "absolute": "fabs",
            "sin": "sin", "cos": "cos", "tan": "tan", "arctan": "atan", "tanh": "tanh"}
_NUMPY_CMP = {"less": "<", "less_equal": "<=", "greater": ">", "greater_equal": ">=",
              "equal": "==", "not_equal": "!="}
_AST_CMP = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}


class _Expr:
    """Python expression (the generated numpy source) -> C expression on doubles."""

    def __init__(self, env: dict[str, str]):
        self.env = env

    def __call__(self, node: ast.AST) -> str:
        method = getattr(self, "_" + type(node).__name__, None)
        if method is None:
            raise _Unsupported(type(node).__name__)
        return method(node)

    def _Name(self, node: ast.Name) -> str:
        if node.id not in self.env:
            raise _Unsupported(f"name {node.id}")
        return self.env[node.id]

    def _Constant(self, node: ast.Constant) -> str:
        if isinstance(node.value, bool):
            return "1.0" if node.value else "0.0"
        if isinstance(node.value, (int, float)):
            return _c_float(float(node.value))
        raise _Unsupported(f"constant {node.value!r}")

    def _UnaryOp(self, node: ast.UnaryOp) -> str:
        if isinstance(node.op, ast.USub):
            return f"(-{self(node.operand)})"
        if isinstance(node.op, ast.UAdd):
            return self(node.operand)
        if isinstance(node.op, ast.Not):
            return f"((double)({self(node.operand)} == 0.0))"
        raise _Unsupported(type(node.op).__name__)

    def _BinOp(self, node: ast.BinOp) -> str:
        a, b = self(node.left), self(node.right)
        ops = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
        if type(node.op) in ops:
            return f"({a} {ops[type(node.op)]} {b})"
        if isinstance(node.op, ast.Pow):
            # numpy's fast paths for a scalar exponent (square, reciprocal, sqrt), else pow
            e = node.right
            val = None
            if isinstance(e, ast.Constant) and isinstance(e.value, (int, float)):
                val = float(e.value)
            elif (isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.USub)
                  and isinstance(e.operand, ast.Constant)
                  and isinstance(e.operand.value, (int, float))):
                val = -float(e.operand.value)
            if val == 2.0:
                return f"({a} * {a})"
            if val == 1.0:
                return a
            if val == -1.0:
                return f"(1.0 / {a})"
            if val == 0.5:
                return f"sqrt({a})"
            if val == 0.0:
                return "1.0"
            return f"pow({a}, {b})"
        raise _Unsupported(type(node.op).__name__)

    def _Compare(self, node: ast.Compare) -> str:
        if len(node.ops) != 1 or type(node.ops[0]) not in _AST_CMP:
            raise _Unsupported("chained comparison")
        return (f"((double)({self(node.left)} {_AST_CMP[type(node.ops[0])]} "
                f"{self(node.comparators[0])}))")

    def _Attribute(self, node: ast.Attribute) -> str:
        if isinstance(node.value, ast.Name) and node.value.id == "numpy":
            consts = {"pi": np.pi, "e": np.e, "nan": np.nan, "inf": np.inf}
            if node.attr in consts:
                return _c_float(consts[node.attr])
        raise _Unsupported(f"attribute {ast.unparse(node)}")

    def _Call(self, node: ast.Call) -> str:
        fn = node.func
        name = None
        if isinstance(fn, ast.Name) and fn.id == "abs":
            name = "abs"
        elif isinstance(fn, ast.Attribute) and isinstance(fn.value, ast.Name) and fn.value.id == "numpy":
            name = fn.attr
        elif (isinstance(fn, ast.Attribute) and fn.attr == "reduce"
              and isinstance(fn.value, ast.Attribute) and isinstance(fn.value.value, ast.Name)
              and fn.value.value.id == "numpy"):
            op = {"logical_or": "|", "logical_and": "&"}.get(fn.value.attr)
            if op is None or len(node.args) != 1 or not isinstance(node.args[0], (ast.Tuple, ast.List)):
                raise _Unsupported(ast.unparse(node))
            parts = [f"({self(a)} != 0.0)" for a in node.args[0].elts]
            return f"((double)({f' {op} '.join(parts)}))"
        if name is None:
            raise _Unsupported(ast.unparse(fn))
        if name == "select":
            return self._select(node)
        args = [self(a) for a in node.args]
        if name in _NUMPY_1 and len(args) == 1:
            return f"{_NUMPY_1[name]}({args[0]})"
        if name == "copysign" and len(args) == 2:
            return f"copysign({args[0]}, {args[1]})"
        if name == "maximum" and len(args) == 2:
            return f"tk_max({args[0]}, {args[1]})"
        if name == "minimum" and len(args) == 2:
            return f"tk_min({args[0]}, {args[1]})"
        if name == "sign" and len(args) == 1:
            return f"tk_sign({args[0]})"
        if name == "heaviside" and len(args) == 2:
            return f"tk_heaviside({args[0]}, {args[1]})"
        if name in _NUMPY_CMP and len(args) == 2:
            return f"((double)({args[0]} {_NUMPY_CMP[name]} {args[1]}))"
        if name in ("logical_or", "logical_and") and len(args) == 2:
            op = "|" if name == "logical_or" else "&"
            return f"((double)(({args[0]} != 0.0) {op} ({args[1]} != 0.0)))"
        if name == "logical_not" and len(args) == 1:
            return f"((double)({args[0]} == 0.0))"
        raise _Unsupported(f"numpy.{name}")

    def _select(self, node: ast.Call) -> str:
        """``numpy.select(conds, values, default)`` as nested conditionals (first true wins)."""
        if len(node.args) != 2:
            raise _Unsupported("select")
        conds, values = node.args
        if not (isinstance(conds, ast.List) and isinstance(values, ast.List)):
            raise _Unsupported("select")
        default = next((k.value for k in node.keywords if k.arg == "default"), None)
        out = self(default) if default is not None else "NAN"
        for cond, value in reversed(list(zip(conds.elts, values.elts))):
            out = f"(({self(cond)} != 0.0) ? {self(value)} : {out})"
        return out


def _function_body(tree: ast.Module, name: str, rows: list[str], consts: str, params: str,
                   out: list[str], prefix: str) -> list[str]:
    """C statements (one lane ``j``) of the generated function ``name``.

    ``rows`` are the C names of the function's row inputs, ``out`` those of
    its outputs (declared here), ``prefix`` makes its locals unique.
    """
    fn = next((f for f in tree.body if isinstance(f, ast.FunctionDef) and f.name == name), None)
    if fn is None:
        raise _Unsupported(f"no function {name}")
    env: dict[str, str] = {}
    expr = _Expr(env)
    lines = []
    for stmt in fn.body:
        if isinstance(stmt, ast.Return):
            continue
        if not (isinstance(stmt, ast.Assign) and len(stmt.targets) == 1):
            raise _Unsupported(type(stmt).__name__)
        target, value = stmt.targets[0], stmt.value
        if isinstance(value, ast.Subscript) and isinstance(value.value, ast.Name) \
                and value.value.id in ("rows", "c", "p") and isinstance(target, ast.Name):
            idx = value.slice.value if isinstance(value.slice, ast.Constant) else None
            if not isinstance(idx, int):
                raise _Unsupported("subscript")
            src = value.value.id
            env[target.id] = (rows[idx] if src == "rows" else
                              f"{consts}[{idx}][j]" if src == "c" else f"{params}[{idx}][j]")
            continue
        if isinstance(target, ast.Name):
            var = f"{prefix}{target.id}"
            lines.append(f"const double {var} = {expr(value)};")
            env[target.id] = var
        elif (isinstance(target, ast.Subscript) and isinstance(target.value, ast.Name)
              and target.value.id == "out" and isinstance(target.slice, ast.Constant)
              and isinstance(target.slice.value, int)):
            name = out[int(target.slice.value)]
            decl = "" if "[" in name else "const double "       # array element or new local
            lines.append(f"{decl}{name} = {expr(value)};")
        else:
            raise _Unsupported("assignment target")
    return lines


_PRELUDE = r"""
#include <math.h>
#include <stdint.h>
#include <string.h>

/* numpy.maximum / numpy.minimum (NaN propagates) */
static inline double tk_max(double a, double b) { return (a >= b || a != a) ? a : b; }
static inline double tk_min(double a, double b) { return (a <= b || a != a) ? a : b; }
static inline double tk_sign(double a) { return a > 0 ? 1.0 : (a < 0 ? -1.0 : a); }
static inline double tk_heaviside(double a, double h0) {
    return a > 0 ? 1.0 : (a < 0 ? 0.0 : (a == 0 ? h0 : a));
}
"""

_STEPS_INLINE = r"""
/* S RK4 steps of the runs r0 .. r0+{B}-1, one straight-line step per run (vectorised
   across the {B} runs); x, u, c, p one row per state/input/constant/parameter. */
static void tk_steps_{B}(int S, double h, double (*restrict x)[{B}],
                         const double (*restrict ub)[{B}], const double (*restrict cb)[{B}],
                         const double (*restrict pb)[{B}], const double *restrict lo,
                         const double *restrict hi, uint64_t *restrict lowf,
                         uint64_t *restrict highf, int *restrict crossed) {
    const double half = 0.5 * h, h6 = h / 6.0;
    for (int s = 0; s < S; s++) {
        for (int j = 0; j < {B}; j++) {
{STEP}
        }
    }
}

"""

_STEPS_LOOPED = r"""
static void tk_f_{B}(const double (*restrict xs)[{B}], const double (*restrict ub)[{B}],
                     const double (*restrict cb)[{B}], const double (*restrict pb)[{B}],
                     double (*restrict out)[{B}]) {
    for (int j = 0; j < {B}; j++) {
{F}
    }
}

static void tk_s_{B}(const double (*restrict xs)[{B}], const double (*restrict cb)[{B}],
                     const double (*restrict pb)[{B}], double (*restrict out)[{B}]) {
    for (int j = 0; j < {B}; j++) {
{S}
    }
}

/* S RK4 steps of the runs r0 .. r0+{B}-1, stage by stage (f called on {B} runs at a time). */
static void tk_steps_{B}(int S, double h, double (*restrict x)[{B}],
                         const double (*restrict ub)[{B}], const double (*restrict cb)[{B}],
                         const double (*restrict pb)[{B}], const double *restrict lo,
                         const double *restrict hi, uint64_t *restrict lowf,
                         uint64_t *restrict highf, int *restrict crossed) {
    double st[NX][{B}], k1[NX][{B}], k2[NX][{B}], k3[NX][{B}], k4[NX][{B}], x1[NX][{B}],
           s0[NSA][{B}], s1[NSA][{B}];
    const double half = 0.5 * h, h6 = h / 6.0;
    (void)s0; (void)s1; (void)crossed;
#define TK_F(src, dst) tk_f_{B}((const double (*)[{B}])src, ub, cb, pb, dst)
    for (int s = 0; s < S; s++) {
        for (int i = 0; i < NX; i++) for (int j = 0; j < {B}; j++)
            st[i][j] = tk_min(tk_max(x[i][j], lo[i]), hi[i]);
        TK_F(st, k1);
        for (int i = 0; i < NX; i++) for (int j = 0; j < {B}; j++)
            st[i][j] = tk_min(tk_max(k1[i][j] * half + x[i][j], lo[i]), hi[i]);
        TK_F(st, k2);
        for (int i = 0; i < NX; i++) for (int j = 0; j < {B}; j++)
            st[i][j] = tk_min(tk_max(k2[i][j] * half + x[i][j], lo[i]), hi[i]);
        TK_F(st, k3);
        for (int i = 0; i < NX; i++) for (int j = 0; j < {B}; j++)
            st[i][j] = tk_min(tk_max(k3[i][j] * h + x[i][j], lo[i]), hi[i]);
        TK_F(st, k4);
        for (int i = 0; i < NX; i++) for (int j = 0; j < {B}; j++)
            x1[i][j] = x[i][j] + (((k2[i][j] * 2.0 + k1[i][j]) + k3[i][j] * 2.0) + k4[i][j]) * h6;
#if NS > 0
        tk_s_{B}((const double (*)[{B}])x, cb, pb, s0);
        tk_s_{B}((const double (*)[{B}])x1, cb, pb, s1);
        for (int i = 0; i < NS; i++) for (int j = 0; j < {B}; j++)
            crossed[j] |= (s0[i][j] > 0) != (s1[i][j] > 0);
#endif
        for (int i = 0; i < NX; i++) for (int j = 0; j < {B}; j++) {
            lowf[j] |= (uint64_t)(x1[i][j] < lo[i]) << s;
            highf[j] |= (uint64_t)(x1[i][j] > hi[i]) << s;
            x[i][j] = tk_min(tk_max(x1[i][j], lo[i]), hi[i]);
        }
    }
#undef TK_F
}
"""

_BLOCK = r"""
/* Runs r0 .. r0+{B}-1 over periods start[r] .. N-1 (see tk_run). */
static void tk_block_{B}(long r0, long N, int S, double h, const double *x0,
        const double *U, long uN, long uM, const double *C, long cM, const double *P, long pM,
        const double *lo, const double *hi, const int64_t *start, double *X, long xN, long xM,
        int64_t *stop, uint8_t *low, uint8_t *high) {
    double x[NX][{B}], xp[NX][{B}], ub[NUA][{B}], cb[NCA][{B}], pb[NPA][{B}];
    long k0[{B}], kmin = N;
    for (int j = 0; j < {B}; j++) {
        long r = r0 + j;
        k0[j] = start ? (long)start[r] : 0;
        if (k0[j] < kmin) kmin = k0[j];
        for (int i = 0; i < NX; i++) x[i][j] = x0[r * NX + i];
        for (int i = 0; i < NC; i++) cb[i][j] = C[r * cM + i];
        for (int i = 0; i < NP; i++) pb[i][j] = P[r * pM + i];
    }
    for (long k = kmin; k < N; k++) {
        uint64_t lowf[{B}], highf[{B}];
        int crossed[{B}];
        for (int j = 0; j < {B}; j++) {
            lowf[j] = 0; highf[j] = 0; crossed[j] = 0;
            const double *u = U + k * uN + (r0 + j) * uM;
            for (int i = 0; i < NU; i++) ub[i][j] = u[i];
        }
        memcpy(xp, x, sizeof(x));
        tk_steps_{B}(S, h, x, (const double (*)[{B}])ub, (const double (*)[{B}])cb,
                     (const double (*)[{B}])pb, lo, hi, lowf, highf, crossed);
        for (int j = 0; j < {B}; j++) {
            if (k < k0[j] || stop[r0 + j] >= 0) {        /* not started, or stopped */
                for (int i = 0; i < NX; i++) x[i][j] = xp[i][j];
                continue;
            }
            if (crossed[j]) {
                stop[r0 + j] = k;
                for (int i = 0; i < NX; i++) x[i][j] = xp[i][j];
                continue;
            }
            double *out = X + k * xN + (r0 + j) * xM;
            for (int i = 0; i < NX; i++) out[i] = x[i][j];
            for (int s = 0; s < S; s++) {
                low[k * S + s] |= (uint8_t)((lowf[j] >> s) & 1u);
                high[k * S + s] |= (uint8_t)((highf[j] >> s) & 1u);
            }
        }
    }
}
"""

_ENTRY = r"""
/* M runs over N periods of S RK4 steps of h seconds, inputs held per period.
   x0 (M, NX); input of run r in period k: U[k uN + r uM + 0..NU-1]; constants of run r:
   C[r cM + 0..NC-1]; parameters P[r pM + ...]; bounds lo, hi (NX); start (M) first period of
   each run (NULL: 0); X: end state of period k of run r at X[k xN + r xM + 0..NX-1];
   stop (M, set to -1 by the caller): first period whose hybrid mode changed (state left at its
   start, not written); low/high (N, S) OR-ed over the runs that completed the period. */
int tk_run(long M, long N, int S, double h, const double *x0,
           const double *U, long uN, long uM, const double *C, long cM, const double *P, long pM,
           const double *lo, const double *hi, const int64_t *start, double *X, long xN, long xM,
           int64_t *stop, uint8_t *low, uint8_t *high) {
    if (S < 1 || S > 64) return 1;
    long r = 0;
    for (; r + {BLOCK} <= M; r += {BLOCK})
        tk_block_{BLOCK}(r, N, S, h, x0, U, uN, uM, C, cM, P, pM, lo, hi, start, X, xN, xM, stop, low, high);
    for (; r < M; r++)
        tk_block_1(r, N, S, h, x0, U, uN, uM, C, cM, P, pM, lo, hi, start, X, xN, xM, stop, low, high);
    return 0;
}
"""


def kernel_source(model: Any) -> str:
    """The C source of a plant's period kernel (see the module notes).

    Parameters
    ----------
    model : tanksynth.sim.tape.NumpyModel
        The plant's generated numpy code.

    Returns
    -------
    str
        C99 source defining ``tk_run``.

    Raises
    ------
    ValueError
        The generated source uses a construct the translation does not support
        (the caller falls back to the numpy code).
    """
    tree = ast.parse(model.source)
    n, m, k = model.n, model.m, model.k
    try:
        rows = [f"xs[{i}][j]" for i in range(n)] + [f"ub[{i}][j]" for i in range(m)]
        f_lines = _function_body(tree, "f", rows, "cb", "pb", [f"out[{i}][j]" for i in range(n)],
                                 "v_")
        s_lines = (_function_body(tree, "s", rows[:n], "cb", "pb",
                                  [f"out[{i}][j]" for i in range(k)], "v_") if k else [])
    except _Unsupported as exc:
        raise ValueError(f"cannot translate the plant's code to C: {exc}") from None
    head = [f"/* tanksynth simulation kernel v{KERNEL_VERSION} */",
            f"#define NX {n}", f"#define NU {m}", f"#define NC {model.n_constants}",
            f"#define NP {len(model.parameter_names)}", f"#define NS {k}",
            "/* array sizes (at least 1) */",
            f"#define NUA {max(m, 1)}", f"#define NCA {max(model.n_constants, 1)}",
            f"#define NPA {max(len(model.parameter_names), 1)}", f"#define NSA {max(k, 1)}"]
    text = "\n".join(head) + _PRELUDE
    if len(f_lines) > INLINE_LIMIT:
        # large plants: f as a function called per stage (compile time grows with the code)
        pad = " " * 8
        steps = _STEPS_LOOPED.replace("{F}", "\n".join(pad + ln for ln in f_lines) or pad + ";")
        steps = steps.replace("{S}", "\n".join(pad + ln for ln in s_lines) or pad + "(void)out;")
        for B in (BLOCK, 1):
            text += steps.replace("{B}", str(B)) + _BLOCK.replace("{B}", str(B))
        return text + _ENTRY.replace("{BLOCK}", str(BLOCK))
    us = [f"ub[{i}][j]" for i in range(m)]
    clip = lambda v, i: f"tk_min(tk_max({v}, lo[{i}]), hi[{i}])"  # noqa: E731
    step = [f"const double x_{i} = x[{i}][j];" for i in range(n)]
    try:
        # RK4 of the integrator: stages clipped, x + ((2 k2 + k1) + 2 k3 + k4) h/6
        for st, (prev, w) in enumerate(((None, None), ("k1", "half"), ("k2", "half"),
                                        ("k3", "h")), start=1):
            step += [f"const double s{st}_{i} = "
                     + clip(f"x_{i}" if prev is None else f"{prev}_{i} * {w} + x_{i}", i) + ";"
                     for i in range(n)]
            step += _function_body(tree, "f", [f"s{st}_{i}" for i in range(n)] + us, "cb", "pb",
                                   [f"k{st}_{i}" for i in range(n)], f"f{st}_")
        step += [f"const double e_{i} = x_{i} + (((k2_{i} * 2.0 + k1_{i}) + k3_{i} * 2.0) + "
                 f"k4_{i}) * h6;" for i in range(n)]
        if k:
            for tag, src in (("a", "x"), ("b", "e")):
                step += _function_body(tree, "s", [f"{src}_{i}" for i in range(n)], "cb", "pb",
                                       [f"w{tag}_{i}" for i in range(k)], f"s{tag}_")
            step.append("crossed[j] |= " + " | ".join(f"((wa_{i} > 0) != (wb_{i} > 0))"
                                                       for i in range(k)) + ";")
    except _Unsupported as exc:
        raise ValueError(f"cannot translate the plant's code to C: {exc}") from None
    step.append("lowf[j] |= (uint64_t)(" + " | ".join(f"(e_{i} < lo[{i}])" for i in range(n))
                + ") << s;")
    step.append("highf[j] |= (uint64_t)(" + " | ".join(f"(e_{i} > hi[{i}])" for i in range(n))
                + ") << s;")
    step += [f"x[{i}][j] = " + clip(f"e_{i}", i) + ";" for i in range(n)]
    pad = " " * 12
    body = "\n".join(pad + ln for ln in step)
    for B in (BLOCK, 1):
        text += (_STEPS_INLINE.replace("{STEP}", body) + _BLOCK).replace("{B}", str(B))
    return text + _ENTRY.replace("{BLOCK}", str(BLOCK))
