"""Every public function documents every parameter in its numpydoc ``Parameters`` section.

As python-control's docstring test does: for each module of the package, each public
function and each public method of a public class (public: in the module's ``__all__``
and defined there), every name of the signature (``*args`` / ``**kwargs`` included, ``self``
and ``cls`` not) must be an entry of ``Parameters`` (or ``Other Parameters``); a class's
constructor parameters may be documented in the class's ``Parameters`` or ``Attributes``
section. A property, or a function without parameters, passes. An override (``from_table`` of
each Options class) inherits the Parameters of the nearest base-class method of the same name.
A parameter whose name starts
with ``_`` (a dataclass field such as ``_cache``, a private keyword such as ``_dual``) is an
implementation detail, not part of the public signature: it is not checked. Nor is the
constructor of a ``typing.Protocol`` (an interface that is never instantiated; its methods are).

Known exceptions are listed in ``tests/docstring_exceptions.txt`` (``module.qualname:
missing, names``): the list may only shrink. An entry that no longer fails is an error too,
so that fixed docstrings leave the list.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import pytest

import tanksynth
from tanksynth.spec.method_options.base import numpydoc_section

EXCEPTIONS = Path(__file__).with_name("docstring_exceptions.txt")


def _modules() -> list[str]:
    return ["tanksynth", *sorted(m.name for m in pkgutil.walk_packages(tanksynth.__path__, "tanksynth.")
                                 if not m.name.endswith("__main__"))]


def _documented(doc: str | None, *sections: str) -> set[str]:
    out: set[str] = set()
    for section in sections:
        out |= set(numpydoc_section(doc, section))
    return out


def _parameters(fn) -> list[str]:
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return []
    return [p.name for p in sig.parameters.values()
            if p.name not in ("self", "cls") and not p.name.startswith("_")]


def _missing(fn, doc: str | None, sections=("Parameters", "Other Parameters")) -> list[str]:
    documented = _documented(doc, *sections)
    return [name for name in _parameters(fn) if name not in documented]


def _public_objects(module_name: str):
    module = importlib.import_module(module_name)
    for name in getattr(module, "__all__", ()):
        obj = getattr(module, name, None)
        if getattr(obj, "__module__", None) != module_name:
            continue   # re-exported: checked where it is defined
        if inspect.isclass(obj):
            yield f"{module_name}.{name}", obj, "class"
            for attr, member in vars(obj).items():
                if attr.startswith("_"):
                    continue
                if isinstance(member, (staticmethod, classmethod)):
                    member = member.__func__
                if inspect.isfunction(member):
                    yield f"{module_name}.{name}.{attr}", member, _inherited_doc(obj, attr)
        elif inspect.isfunction(obj):
            yield f"{module_name}.{name}", obj, "function"


def _inherited_doc(cls, attr: str) -> str:
    """The docstring an override inherits: the nearest base class's method of the same name whose
    docstring has a ``Parameters`` section (an intermediate override saying only "See
    `MethodOptions.from_table`" passes its base's entries on)."""
    for base in cls.__mro__[1:]:
        member = vars(base).get(attr)
        if isinstance(member, (staticmethod, classmethod)):
            member = member.__func__
        if inspect.isfunction(member) and numpydoc_section(member.__doc__, "Parameters"):
            return member.__doc__
    return ""


def undocumented() -> dict[str, list[str]]:
    """``qualified name -> undocumented parameters`` over the package."""
    out: dict[str, list[str]] = {}
    for module_name in _modules():
        for qualname, obj, kind in _public_objects(module_name):
            if kind == "class":
                init = obj.__init__
                if getattr(obj, "_is_protocol", False) or not inspect.isfunction(init):
                    continue   # a builtin constructor (object, Exception): nothing to document
                missing = _missing(init, obj.__doc__, ("Parameters", "Other Parameters", "Attributes"))
                missing = [m for m in missing if m not in _documented(init.__doc__, "Parameters")]
            else:
                missing = _missing(obj, obj.__doc__)
                if kind not in ("function", "method") and missing:
                    # an override documents only what differs: the base method's entries count
                    # when its signature has the same names (``from_table`` of every Options)
                    missing = [m for m in missing if m not in _documented(kind, "Parameters")]
            if missing:
                out[qualname] = missing
    return out


def _exceptions() -> dict[str, list[str]]:
    out = {}
    for line in EXCEPTIONS.read_text(encoding="utf-8").splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            name, _, params = line.partition(":")
            out[name.strip()] = [p.strip() for p in params.split(",") if p.strip()]
    return out


@pytest.fixture(scope="module")
def found() -> dict[str, list[str]]:
    return undocumented()


def test_every_public_parameter_is_documented(found):
    known = _exceptions()
    new = {k: v for k, v in found.items() if not set(v) <= set(known.get(k, []))}
    assert not new, ("undocumented parameters (add them to the numpydoc Parameters section):\n"
                     + "\n".join(f"  {k}: {', '.join(v)}" for k, v in sorted(new.items())))


def test_exception_list_only_shrinks(found):
    stale = {k: v for k, v in _exceptions().items() if not set(v) & set(found.get(k, []))}
    assert not stale, ("these are documented now: remove them from "
                       f"{EXCEPTIONS.name}:\n" + "\n".join(f"  {k}" for k in sorted(stale)))


def test_the_checker_catches_an_undocumented_parameter():
    def f(a, b, *args, **kwargs):
        """Do.

        Parameters
        ----------
        a, b : float
            Two numbers (m).
        *args
            More.
        """

    assert _missing(f, f.__doc__) == ["kwargs"]


def test_the_checker_skips_private_parameters():
    def g(a, _cache=None):
        """Do.

        Parameters
        ----------
        a : float
            A length (m).
        """

    assert _missing(g, g.__doc__) == []


# --- Units in the text -------------------------------------------------------------------------
# As python-control asks for units in its docstrings: an entry (Parameters, Other Parameters,
# Returns, Yields; a class's Attributes) that documents a physical quantity states its unit. The
# rule is mechanical:
#   * an entry is PHYSICAL when its name is one of PHYSICAL_NAMES and its type is numeric
#     (float, int, complex, array, number; or no type given), or its description mentions a
#     PHYSICAL_WORDS quantity and its type is a real/complex number or array (not int: counts);
#   * a physical entry must contain a UNIT token in its type or description: a unit in brackets,
#     after a comma or colon or after "in" (``(s)``, ``(m^3/s)``, ``(1/s in continuous time)``,
#     ``in s``, ``, m``), a unit word (``seconds``, ``metres``, ``radians``, ``degrees``,
#     ``samples``, ``steps``, ``bytes``, ``percent``), ``dimensionless`` / ``unitless`` / ``(-)``,
#     or "unit(s)" naming a frame (``state units``, ``squared output unit``, ``units of ...``;
#     not "unit circle", "unit disk", "unit vector").
# No exception list: an entry the rule flags is fixed by stating its unit (``dimensionless``
# when it has none).

#: Names that denote a physical quantity in this package (times, operating points, noise
#: covariances and weights, poles, decay rates, bounds...).
PHYSICAL_NAMES = frozenset({
    "ts", "t", "dt", "t0", "t_final", "t_end", "tf", "duration", "horizon",
    "x0", "u0", "x_op", "u_op", "x_hat0", "y0",
    "Q", "R", "Qc", "P0", "poles", "alpha", "psi", "gamma",
})
PHYSICAL_WORDS = re.compile(
    r"\b(time|time-?steps?|period|levels?|flows?|rate|gains?|covariances?|poles?|frequency|"
    r"frequencies|eigenvalues?|variance|height|area|volume|duration|horizon|delay|bandwidth|"
    r"decay|standard deviation|operating point|intensity)\b", re.I)
_NUMERIC_TYPE = re.compile(r"float|ndarray|array|complex|number|real", re.I)
_NUMERIC_OR_INT_TYPE = re.compile(r"float|ndarray|array|complex|number|real|\bint\b", re.I)
_UNIT_ATOM = r"(?:s|ms|min|h|m|cm|mm|V|Hz|rad|deg|kg|Pa|l)(?:\^-?[\d/]+)?"
#: A unit word: "seconds", "dimensionless", "state units", "units of ..."...
UNIT_WORD = re.compile(
    r"(?i:\b(?:dimensionless|unitless|seconds?|metres?|meters?|radians?|degrees?|bytes|samples|"
    r"steps|percent)\b)"
    r"|(?i:\bunits?\b)(?!\s*(?:circle|disk|disc|vector|matrix|ball|norm|-norm))"
    r"|\(-\)")
#: A unit word, or a unit symbol after a bracket, comma, colon or "in" and not followed by a
#: dimension's "x" or "+" (``(m x m)``, ``(N + 1, n)`` are sizes, not metres or newtons).
UNIT_TOKEN = re.compile(
    UNIT_WORD.pattern
    + rf"|(?:^|[(\[,:;]|\bin)\s*(?:1/)?{_UNIT_ATOM}(?:\s*[*/]\s*{_UNIT_ATOM})*"
    r"(?=[)\],;.]|$|\s+(?![x+*-]\s))")

_UNIT_SECTIONS = ("Parameters", "Other Parameters", "Returns", "Yields")


def _entries(obj, is_class: bool):
    """``(section, name, type, description)`` of every documented entry of ``obj``."""
    for section in _UNIT_SECTIONS + (("Attributes",) if is_class else ()):
        for name, (typ, text) in numpydoc_section(obj.__doc__, section).items():
            if section in ("Returns", "Yields") and not typ:   # an unnamed return: "float"
                name, typ = "", name
            yield section, name, typ, text


def is_physical(name: str, typ: str, text: str) -> bool:
    """The entry documents a physical quantity (see the rule above)."""
    if name in PHYSICAL_NAMES and (not typ or _NUMERIC_OR_INT_TYPE.search(typ)):
        return True
    return bool(PHYSICAL_WORDS.search(text)) and (not typ or bool(_NUMERIC_TYPE.search(typ)))


def has_unit(typ: str, text: str) -> bool:
    """The type or description states a unit (see the rule above)."""
    return bool(UNIT_TOKEN.search(text) or UNIT_WORD.search(typ))   # a type's "(m, n)" is a shape


def missing_units() -> dict[str, list[str]]:
    """``qualified name -> ["Section 'name' (type): description", ...]`` of the physical entries
    without a unit, over the package's public functions, methods and classes."""
    out: dict[str, list[str]] = {}
    for module_name in _modules():
        for qualname, obj, kind in _public_objects(module_name):
            for section, name, typ, text in _entries(obj, kind == "class"):
                if is_physical(name, typ, text) and not has_unit(typ, text):
                    what = f"'{name}' ({typ})" if name else f"({typ})"
                    out.setdefault(qualname, []).append(f"{section} {what}: {text[:90]!r}")
    return out


def test_every_physical_quantity_states_its_unit():
    found = missing_units()
    assert not found, (
        "documented physical quantities without a unit (write it in the description: (s), (m), "
        "(m^3/s), (1/s), (state units), (dimensionless)...):\n"
        + "\n".join(f"  {k}: {entry}" for k, v in sorted(found.items()) for entry in v))


@pytest.mark.parametrize("name, typ, text, physical, unit", [
    ("ts", "float", "Sampling period (s).", True, True),
    ("ts", "float", "Sampling period.", True, False),
    ("ts", "float", "Sampling period in s (> 0).", True, True),
    ("poles", "array_like of complex", "Closed-loop poles (1/s in continuous time).", True, True),
    ("poles", "array_like of complex", "Discrete-time poles inside the unit circle.", True, False),
    ("poles", "array_like of complex", "Discrete-time poles (z-plane, dimensionless).", True, True),
    ("Q", "ndarray", "Process-noise covariance (squared state units).", True, True),
    ("x0", "ndarray", "Operating point.", True, False),
    ("level", "int", "Heading level.", False, False),          # an int count: not physical
    ("name", "str", "The time domain.", False, False),         # a string: not physical
    ("seconds", "float", "Wall time of the build.", True, False),
    ("seconds", "float", "Wall time of the build (s).", True, True),
    ("flow", "float", "Pump flow, m^3/s.", True, True),
    ("weights", "ndarray", "Mean and covariance weights (dimensionless).", True, True),
    ("R", "ndarray, shape (m, m)", "Input weight (m x m, positive definite).", True, False),
    ("jumps", "ndarray, shape (N + 1, n)", "Known level changes at each sample.", True, False),
])
def test_the_unit_rule(name, typ, text, physical, unit):
    """The rule on entries it must flag and must pass."""
    assert is_physical(name, typ, text) is physical
    assert has_unit(typ, text) is unit
