"""The whitelist equation parser: accepted grammar, exact numbers, and refusals."""

from __future__ import annotations

import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tanksynth.errors import ParseError, SpecError
from tanksynth.plants.parser import FUNCTIONS, parse_expression, validate_name

x = sp.Symbol("x", real=True)
y = sp.Symbol("y", real=True)
A = sp.Symbol("A", positive=True)
NAMES = {"x": x, "y": y, "A": A}
KEY = "plant.equations.h1"


def parse(text: str) -> sp.Expr:
    return parse_expression(text, NAMES, KEY)


# ------------------------------------------------------------------- accepted
@pytest.mark.parametrize("text,expected", [
    ("0.5", sp.Rational(1, 2)),
    ("1e-5", sp.Rational(1, 100000)),
    ("2.5E+2", sp.Integer(250)),
    (".25", sp.Rational(1, 4)),
    ("0.0154", sp.Rational(77, 5000)),
    ("-2**2", sp.Integer(-4)),
    ("(-2)**2", sp.Integer(4)),
    ("2**3**2", sp.Integer(512)),
    ("2**-1", sp.Rational(1, 2)),
    ("1-2-3", sp.Integer(-4)),
    ("8/4/2", sp.Integer(1)),
    ("2+3*4", sp.Integer(14)),
    ("(2+3)*4", sp.Integer(20)),
    ("--x", x),
    ("+x", x),
    ("x - y*2", x - 2 * y),
    ("(x - A*sqrt(2*9.81*x))/A", (x - A * sp.sqrt(sp.Rational(981, 50) * x)) / A),
    ("sqrt(x)", sp.sqrt(x)),
    ("abs(x - y)", sp.Abs(x - y)),
    ("sign(x - y)", sp.sign(x - y)),
    ("exp(-x)", sp.exp(-x)),
    ("log(A)", sp.log(A)),
    ("min(x, y)", sp.Min(x, y)),
    ("max(x, y, 0)", sp.Max(x, y, 0)),
    ("x**0.5", sp.sqrt(x)),
    ("  x\t+\ny ", x + y),
])
def test_accepted(text, expected):
    out = parse(text)
    assert out == expected
    assert sp.simplify(out - expected) == 0


def test_numbers_are_exact_rationals():
    out = parse("0.1 + 0.2")
    assert out == sp.Rational(3, 10)           # not 0.30000000000000004
    assert not parse("1e-5 * x").atoms(sp.Float)
    assert not parse("9.81 * sqrt(x)").atoms(sp.Float)


def test_precedence_tree_shapes():
    # unary minus binds looser than **: -x**2 == -(x**2)
    assert parse("-x**2") == -(x**2)
    # ** is right associative
    assert parse("x**y**2") == x ** (y**2)
    assert parse("x**y**2") != (x**y) ** 2
    # * and / are left associative
    assert parse("x/y*A") == (x / y) * A


def test_functions_list_is_the_whitelist():
    assert set(FUNCTIONS) == {"sqrt", "abs", "sign", "exp", "log", "min", "max"}


# ------------------------------------------------------------------- refused
@pytest.mark.parametrize("text,token", [
    ("z + 1", "'z'"),                                  # unknown name
    ("__import__('os')", "character \"'\" at column 12"),  # the quote is no token at all
    ("__import__", "__import__"),                      # name-shaped, unknown
    ("os.system('ls')", "'.'"),                        # attribute access
    ("x.real", "'.'"),
    ("a.b", "'.'"),
    ("lambda: 1", "':'"),
    ("lambda", "lambda"),
    ("x[0]", "'['"),
    ("'abc'", "\"'\""),
    ('"x"', "'\"'"),
    ("2**1000", "1000"),
    ("10**10**10", "10000000000"),
    ("x**99999", "99999"),
    ("2**-65", "-65"),
    ("", "empty"),
    ("   ", "empty"),
    ("(x + 1", "end of expression"),
    ("x + 1)", "')'"),
    ("x +", "end of expression"),
    ("x y", "'y'"),
    ("* x", "'*'"),
    ("x // y", "'/'"),
    ("x ^ y", "'^'"),
    ("x % y", "'%'"),
    ("x == y", "'='"),
    ("x; y", "';'"),
    ("sin(x)", "sin"),                                # not whitelisted
    ("eval(x)", "eval"),
    ("sqrt", "sqrt"),                                  # function without call
    ("sqrt(x, y)", "sqrt"),
    ("max(x)", "max"),
    ("1/0", "division by zero"),
    ("x/(y - y)", "division by zero"),
    ("0**-1", "zero"),
    ("1e999", "1e999"),
    ("1" * 41, "too long"),
])
def test_refused(text, token):
    with pytest.raises(ParseError) as info:
        parse(text)
    msg = str(info.value)
    assert info.value.key == KEY
    assert KEY in msg
    assert token in msg
    assert isinstance(info.value, SpecError)


def test_overlong_input_refused():
    with pytest.raises(ParseError, match="longer than"):
        parse("x+" * 10_001 + "x")


@pytest.mark.parametrize("text", [
    "(" * 1000 + "x" + ")" * 1000,
    "-" * 1000 + "x",
    "sqrt(" * 500 + "x" + ")" * 500,
    "x" + "**x" * 500,
])
def test_deep_nesting_refused(text):
    # refused by the depth limit; its speed (< 0.5 s) is a floor of benchmarks/limits.py
    with pytest.raises(ParseError, match="nested"):
        parse(text)


@pytest.mark.parametrize("text,match", [
    ("1e9999999", "out of range"),                 # Fraction would build 10**9999999 (~7 s)
    ("1e-9999999", "out of range"),
    ("((2**64)**64)**64", "more than 4096 bits"),  # exact constant with 262144 bits
    ("(1.000000000000000000000000000000000001**64)**64", "more than 4096 bits"),
    ("*".join(["1e300"] * 2000), "longer than"),   # product of many in-range constants
    ("2**exp(exp(exp(exp(10))))", "cannot be evaluated exactly"),
])
def test_huge_constants_refused(text, match):
    # refused by the limit the message names; the speed of the refusal (< 0.5 s) is a floor
    # of benchmarks/limits.py
    with pytest.raises(ParseError, match=match):
        parse(text)


@pytest.mark.parametrize("text", ["log(0)", "sqrt(-1)", "(-8)**(1/3)", "x + log(0)"])
def test_non_real_constants_refused(text):
    with pytest.raises(ParseError, match="finite and real"):
        parse(text)


def test_non_string_refused():
    for value in (1.5, None, ["x"], {"x": 1}, b"x"):
        with pytest.raises(ParseError) as info:
            parse_expression(value, NAMES, KEY)
        assert info.value.key == KEY


def test_error_names_column():
    with pytest.raises(ParseError, match="column 5"):
        parse("x + zz")


# ------------------------------------------------------------------- names
def test_validate_name():
    assert validate_name("h1", "k") == "h1"
    for bad in ("1h", "_x", "a.b", "", "a b", "sqrt", "max", 3, None, "é"):
        with pytest.raises(ParseError) as info:
            validate_name(bad, "plant.states.bad")
        assert info.value.key == "plant.states.bad"


# --------------------------------------------------------------- properties
# No per-example deadline (a loaded machine missed 500 ms): the parse time of such texts,
# < 0.5 s each, is a floor of benchmarks/limits.py.
@pytest.mark.slow
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text())
def test_any_text_parses_or_raises_parse_error(text):
    try:
        out = parse(text)
    except ParseError as exc:
        assert exc.key == KEY
        assert str(exc)
    else:
        assert isinstance(out, sp.Basic)
        assert out.free_symbols <= {x, y, A}


_alphabet = st.sampled_from(list("xyA0123456789.eE+-*/() ,") + ["**", "sqrt(", "abs(", "sign(",
                                                               "exp(", "log(", "min(", "max("])


@pytest.mark.slow
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_alphabet, max_size=40).map("".join))
def test_grammar_shaped_text_parses_or_raises_parse_error(text):
    try:
        out = parse(text)
    except ParseError as exc:
        assert exc.key == KEY
    else:
        assert out.free_symbols <= {x, y, A}
        assert not out.has(sp.zoo, sp.nan, sp.I)
