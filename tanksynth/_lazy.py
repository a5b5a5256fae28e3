"""Lazy re-exports for package ``__init__`` modules (PEP 562).

``import tanksynth`` must not load cvxpy, python-control, CasADi or sympy: a
package lists the names it re-exports and the module each comes from, and the
module is imported on first attribute access.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any, Callable, Mapping

__all__ = ["lazy_exports"]


def lazy_exports(package: str, exports: Mapping[str, str]) -> tuple[Callable[[str], Any],
                                                                   Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for a package that re-exports names lazily.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    exports : mapping of str to str
        Exported name -> absolute name of the module that defines it.

    Returns
    -------
    (getattr, dir) : callables
        To assign to the package's ``__getattr__`` and ``__dir__``.
    """
    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        __import__(module)  # not importlib.import_module: `python -X importtime` does not see those
        value = getattr(sys.modules[module], name)
        globals_of = sys.modules[package].__dict__
        globals_of[name] = value  # later lookups skip __getattr__
        return value

    def __dir__() -> list[str]:
        return sorted(set(importlib.import_module(package).__dict__) | set(exports))

    return __getattr__, __dir__
