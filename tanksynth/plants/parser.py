"""Whitelist parser: equation text -> sympy expression.

Spec text is never handed to ``eval``, ``sympify`` or ``parse_expr``. This
module tokenises the text itself and builds the sympy tree by recursive
descent over a small grammar::

    expr   := term (("+" | "-") term)*
    term   := unary (("*" | "/") unary)*
    unary  := ("+" | "-") unary | power
    power  := atom ("**" unary)?
    atom   := NUMBER | NAME | FUNC "(" expr ("," expr)* ")" | "(" expr ")"

with ``FUNC`` one of sqrt, abs, sign, exp, log, min, max, and ``NAME`` one of
the names the caller declares. Anything else is a `ParseError` naming the
offending token and its column.
"""

from __future__ import annotations

import math
import re
from fractions import Fraction
from typing import Mapping

import sympy as sp

from tanksynth.errors import ParseError

__all__ = ["parse_expression", "FUNCTIONS", "validate_name", "expression_limits", "MAX_NODES",
           "MAX_FUNCTION_NESTING", "MAX_DEGREE"]

#: Functions accepted in equations, with their arity (None: two or more).
FUNCTIONS: dict[str, int | None] = {
    "sqrt": 1, "abs": 1, "sign": 1, "exp": 1, "log": 1, "min": None, "max": None,
}

_MAX_LENGTH = 4_000           # characters per equation
_MAX_DEPTH = 200              # nesting of parentheses / unary operators
_MAX_EXPONENT = 64            # |numeric exponent|; larger powers are refused
_MAX_BITS = 4096              # numerator/denominator size of an exact constant
_MAX_DECIMAL_EXPONENT = 400   # |e| in a literal like 1e-5 (floats end near 1e308)
#: Largest parsed expression: tree nodes (sympy ``count_ops`` is at most this), nesting of
#: functions (``sqrt(exp(...))``), and degree bound (``(h1 + h2)**3`` has degree 3, a power
#: of a power multiplies: ``((h1 + 1)**64 + 1)**64`` has 4096). Beyond these, Jacobians,
#: Lie derivatives and determinants of the model grow past what symbolic analysis can do.
MAX_NODES = 2_000
MAX_FUNCTION_NESTING = 6
MAX_DEGREE = 64
_NAME_RE = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
_TOKEN_RE = re.compile(
    r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)"
    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*)"
    r"|(?P<op>\*\*|[-+*/(),]))"
)


def validate_name(name: object, key: str) -> str:
    """Check that a declared name is a plain identifier usable in equations.

    Parameters
    ----------
    name : object
        Candidate name (must be a str).
    key : str
        Spec key that declared it, for the error message.

    Returns
    -------
    str
        The name, unchanged.
    """
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise ParseError(
            f"invalid name {name!r}: expected a letter followed by letters, digits or '_'",
            key=key,
        )
    if name in FUNCTIONS:
        raise ParseError(f"name {name!r} is reserved for a function", key=key)
    return name


def _tokenise(text: str, key: str) -> list[tuple[str, str, int]]:
    tokens: list[tuple[str, str, int]] = []
    pos = 0
    while pos < len(text):
        if text[pos:].strip() == "":
            break
        m = _TOKEN_RE.match(text, pos)
        if m is None or m.end() == pos or m.lastgroup is None:
            col = pos + (len(text[pos:]) - len(text[pos:].lstrip()))
            raise ParseError(
                f"unexpected character {text[col]!r} at column {col + 1} in {text!r}; "
                "allowed: numbers, declared names, + - * / **, parentheses and "
                + ", ".join(FUNCTIONS),
                key=key,
            )
        kind = m.lastgroup
        tokens.append((kind, m.group(kind), m.start(kind)))
        pos = m.end()
    return tokens


class _Parser:
    def __init__(self, text: str, names: Mapping[str, sp.Expr], key: str):
        self.text = text
        self.names = names
        self.key = key
        self.tokens = _tokenise(text, key)
        self.i = 0
        self.depth = 0

    def error(self, message: str) -> ParseError:
        return ParseError(f"{message} in {self.text!r}", key=self.key)

    def peek(self) -> tuple[str, str, int] | None:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self) -> tuple[str, str, int]:
        tok = self.peek()
        if tok is None:
            raise self.error("unexpected end of expression")
        self.i += 1
        return tok

    def expect(self, op: str) -> None:
        tok = self.take()
        if tok[1] != op:
            raise self.error(f"expected {op!r} at column {tok[2] + 1}, found {tok[1]!r}")

    def enter(self) -> None:
        self.depth += 1
        if self.depth > _MAX_DEPTH:
            raise self.error(f"expression nested deeper than {_MAX_DEPTH} levels")

    def parse(self) -> sp.Expr:
        if not self.tokens:
            raise self.error("empty expression")
        expr = self.expr()
        tok = self.peek()
        if tok is not None:
            raise self.error(f"unexpected {tok[1]!r} at column {tok[2] + 1}")
        return expr

    def check_size(self, value: sp.Expr, col: int) -> sp.Expr:
        """Refuse exact constants too large to be a model coefficient.

        Looks at the numeric coefficient / constant term only (O(1)), which is
        where repeated ``*``, ``/``, ``+`` of numbers accumulate.
        """
        parts = [value]
        if value.is_Mul:
            parts = [value.as_coeff_Mul()[0]]
        elif value.is_Add:
            parts = [value.as_coeff_Add()[0]]
        for part in parts:
            if part.is_Rational and max(int(part.p).bit_length(), int(part.q).bit_length()) > _MAX_BITS:
                raise self.error(f"constant at column {col + 1} is too large "
                                 f"(more than {_MAX_BITS} bits)")
        return value

    def expr(self) -> sp.Expr:
        value = self.term()
        while (tok := self.peek()) is not None and tok[1] in "+-" and tok[0] == "op":
            self.take()
            rhs = self.term()
            value = value + rhs if tok[1] == "+" else value - rhs
            self.check_size(value, tok[2])
        return value

    def term(self) -> sp.Expr:
        value = self.unary()
        while (tok := self.peek()) is not None and tok[0] == "op" and tok[1] in ("*", "/"):
            self.take()
            rhs = self.unary()
            if tok[1] == "*":
                value = value * rhs
            else:
                if rhs == 0:
                    raise self.error(f"division by zero at column {tok[2] + 1}")
                value = value / rhs
            self.check_size(value, tok[2])
        return value

    def unary(self) -> sp.Expr:
        tok = self.peek()
        if tok is not None and tok[0] == "op" and tok[1] in "+-":
            self.take()
            self.enter()
            operand = self.unary()
            self.depth -= 1
            return -operand if tok[1] == "-" else operand
        return self.power()

    def power(self) -> sp.Expr:
        base = self.atom()
        tok = self.peek()
        if tok is not None and tok[1] == "**":
            self.take()
            self.enter()
            exponent = self.unary()
            self.depth -= 1
            if exponent.is_number:
                value = complex(exponent)
                if not math.isfinite(value.real) or abs(value) > _MAX_EXPONENT:
                    raise self.error(
                        f"exponent {exponent} at column {tok[2] + 1} is too large "
                        f"(|exponent| <= {_MAX_EXPONENT} expected)"
                    )
            if base == 0 and exponent.is_number and exponent.is_negative:
                raise self.error("zero raised to a negative power")
            if exponent.is_Rational:
                bits = max((max(int(r.p).bit_length(), int(r.q).bit_length())
                            for r in base.atoms(sp.Rational)), default=0)
                if bits * abs(exponent) > _MAX_BITS:
                    raise self.error(f"power at column {tok[2] + 1} gives a constant too large "
                                     f"(more than {_MAX_BITS} bits)")
            return self.check_size(base**exponent, tok[2])
        return base

    def atom(self) -> sp.Expr:
        kind, text, col = self.take()
        if kind == "num":
            if len(text) > 40:
                raise self.error(f"number {text[:20]}... at column {col + 1} is too long")
            exp10 = text.lower().partition("e")[2]
            if exp10 and abs(int(exp10)) > _MAX_DECIMAL_EXPONENT:
                raise self.error(f"number {text} at column {col + 1} is out of range")
            value = Fraction(text)
            as_float = float(value) if abs(value) < 1e300 else math.inf
            if not math.isfinite(as_float) or (value != 0 and abs(as_float) < 1e-300):
                raise self.error(f"number {text} at column {col + 1} is out of range")
            return sp.Rational(value.numerator, value.denominator)
        if kind == "name":
            nxt = self.peek()
            if nxt is not None and nxt[1] == "(":
                return self.call(text, col)
            if text in FUNCTIONS:
                raise self.error(f"function {text!r} at column {col + 1} needs arguments")
            if text not in self.names:
                raise self.error(
                    f"unknown name {text!r} at column {col + 1}; declared names are: "
                    + ", ".join(sorted(self.names))
                )
            return self.names[text]
        if text == "(":
            self.enter()
            value = self.expr()
            self.depth -= 1
            self.expect(")")
            return value
        raise self.error(f"unexpected {text!r} at column {col + 1}")

    def call(self, name: str, col: int) -> sp.Expr:
        if name not in FUNCTIONS:
            raise self.error(
                f"unknown function {name!r} at column {col + 1}; allowed: " + ", ".join(FUNCTIONS)
            )
        self.expect("(")
        self.enter()
        args = [self.expr()]
        while (tok := self.peek()) is not None and tok[1] == ",":
            self.take()
            args.append(self.expr())
        self.depth -= 1
        self.expect(")")
        arity = FUNCTIONS[name]
        if arity is not None and len(args) != arity:
            raise self.error(f"{name}() takes {arity} argument(s), got {len(args)}")
        if arity is None and len(args) < 2:
            raise self.error(f"{name}() takes at least 2 arguments, got {len(args)}")
        if name == "sqrt":
            return sp.sqrt(args[0])
        if name == "abs":
            return sp.Abs(args[0])
        if name == "sign":
            return sp.sign(args[0])
        if name == "exp":
            return sp.exp(args[0])
        if name == "log":
            return sp.log(args[0])
        if name == "min":
            return sp.Min(*args)
        return sp.Max(*args)


def parse_expression(text: object, names: Mapping[str, sp.Expr], key: str) -> sp.Expr:
    """Parse one equation right-hand side into a sympy expression.

    Parameters
    ----------
    text : object
        Equation text (must be a str), e.g. ``"(q1 - a*sqrt(2*g*h1))/A"``.
    names : mapping of str to sympy expression
        The declared names (states, inputs, parameters) and their symbols.
    key : str
        Spec key holding the text, used in error messages.

    Returns
    -------
    sympy.Expr
        The parsed expression; numbers are exact rationals.

    Raises
    ------
    ParseError
        On any token or construct outside the grammar, unknown names,
        exponents larger than 64 in magnitude, or over-long input.
    """
    if not isinstance(text, str):
        raise ParseError(f"expected an equation as a string, got {type(text).__name__}", key=key)
    if len(text) > _MAX_LENGTH:
        raise ParseError(f"equation longer than {_MAX_LENGTH} characters", key=key)
    try:
        expr = _Parser(text, names, key).parse()
    except RecursionError:
        raise ParseError(f"expression nested too deeply in {text[:40]!r}...", key=key) from None
    except (ValueError, OverflowError) as exc:
        if isinstance(exc, ParseError):
            raise
        # sympy/int arithmetic refusing a constant (e.g. the int-to-str digit limit)
        raise ParseError(f"expression {text[:40]!r} cannot be evaluated exactly: {exc}",
                         key=key) from None
    problem = expression_limits(expr)
    if problem:
        raise ParseError(f"expression {text[:40]!r}{'...' if len(text) > 40 else ''} is too complex "
                         f"for symbolic analysis: {problem}", key=key)
    if expr.has(sp.zoo, sp.oo, sp.S.NegativeInfinity, sp.nan, sp.I) or any(
            p.base.is_number and p.base.is_negative and not p.exp.is_integer
            for p in expr.atoms(sp.Pow)):
        raise ParseError(f"expression {text[:40]!r} is not finite and real ({expr}); e.g. log(0), "
                         "sqrt of a negative constant", key=key)
    return expr


def expression_limits(expr: sp.Basic) -> str:
    """Why ``expr`` is too large for the symbolic analysis, or ``""`` when it is not.

    Measured on the tree as parsed, without expanding anything: at most
    `MAX_NODES` nodes, functions nested at most `MAX_FUNCTION_NESTING` deep,
    and a degree bound at most `MAX_DEGREE` (sum over a product, maximum
    over a sum, times ``|exponent|`` for a power; a function of ``g`` counts
    as ``g``). Cost: one pass over the tree, stopping at `MAX_NODES`.

    Parameters
    ----------
    expr : sympy.Basic

    Returns
    -------
    str
        The first limit exceeded, in words; empty if none.
    """
    nodes = 0
    for _ in sp.preorder_traversal(expr):
        nodes += 1
        if nodes > MAX_NODES:
            return f"more than {MAX_NODES} operations and symbols"
    nesting = _function_nesting(expr)
    if nesting > MAX_FUNCTION_NESTING:
        return f"functions nested {nesting} deep (at most {MAX_FUNCTION_NESTING})"
    degree = _degree_bound(expr)
    if degree > MAX_DEGREE:
        return f"degree bound {degree:g} (at most {MAX_DEGREE}); write the model without " \
               "powers of powers"
    return ""


def _function_nesting(expr: sp.Basic) -> int:
    if expr.is_Atom:
        return 0
    inner = max((_function_nesting(a) for a in expr.args), default=0)
    is_function = isinstance(expr, (sp.Function, sp.Abs, sp.sign, sp.exp, sp.log, sp.Min, sp.Max)) or (
        expr.is_Pow and not expr.exp.is_Integer)
    return inner + 1 if is_function else inner


def _degree_bound(expr: sp.Basic) -> float:
    if expr.is_Symbol:
        return 1.0
    if expr.is_Atom:
        return 0.0
    if expr.is_Pow:
        base = _degree_bound(expr.base)
        if expr.exp.is_number:
            return base * max(1.0, abs(float(expr.exp)))
        return max(1.0, base) * max(1.0, _degree_bound(expr.exp))
    degrees = [_degree_bound(a) for a in expr.args]
    if expr.is_Mul:
        return float(sum(degrees))
    return float(max(degrees, default=0.0))
