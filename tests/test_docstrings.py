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
