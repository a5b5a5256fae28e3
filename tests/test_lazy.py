"""Lazy re-exports (`tanksynth._lazy`): packages load their modules on first use, correctly."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import tanksynth

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = sorted(name for _, name, ispkg in pkgutil.walk_packages(tanksynth.__path__, prefix="tanksynth.")
                  if ispkg)
LAZY = [name for name in ["tanksynth", *PACKAGES] if hasattr(importlib.import_module(name), "_EXPORTS")]


def test_the_packages_are_lazy():
    assert {"tanksynth", "tanksynth.analysis", "tanksynth.artefacts", "tanksynth.reports",
            "tanksynth.sim", "tanksynth.verify", "tanksynth.runtime.estimators",
            "tanksynth.spec.method_options"} <= set(LAZY)


@pytest.mark.parametrize("name", LAZY)
def test_no_lazy_name_is_also_a_module(name):
    """A lazily exported name equal to a submodule's would read as the module once that module
    is imported (``from tanksynth.sim import simulate``): such names are imported eagerly."""
    package = importlib.import_module(name)
    modules = {info.name for info in pkgutil.iter_modules(package.__path__)}
    assert sorted(set(package._EXPORTS) & modules) == []
    for export, module in package._EXPORTS.items():
        obj = getattr(package, export)
        assert not inspect.ismodule(obj), export
        assert getattr(importlib.import_module(module), export) is obj, export
    assert set(package._EXPORTS) <= set(package.__all__)


@pytest.mark.parametrize("name", ["tanksynth.artefacts", "tanksynth.reports", "tanksynth.verify",
                                  "tanksynth.runtime.estimators", "tanksynth.methods", "tanksynth.cli"])
def test_importing_a_package_loads_no_numerical_library(name):
    """Fresh interpreter: the package alone pulls in none of the heavy libraries (issue 15)."""
    heavy = ("sympy", "scipy", "casadi", "cvxpy", "control", "matplotlib", "jinja2")
    code = f"import sys, {name}; print(sorted(k for k in {heavy!r} if k in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.strip()
    assert out == "[]", f"{name} imports {out}"


def test_the_report_stack_does_not_load_scipy_stats():
    """Issue 29: the report worker imports the report stack (`tanksynth.verify.replay` among it) on
    every `tanksynth run`; scipy.stats (0.3-0.5 s of imports) loads only where a chi-square
    quantile is computed (replay checks, the whiteness test)."""
    code = ("import sys, tanksynth.reports.writer, tanksynth.verify.replay, "
            "tanksynth.measurements.scores, tanksynth.report_worker\n"
            "print('scipy.stats' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.strip()
    assert out == "False"
