"""Public API hygiene: explicit __all__, docstrings on everything public."""

import importlib
import inspect
import pkgutil

import pytest

import tanksynth

MODULES = sorted(
    name for _, name, _ in pkgutil.walk_packages(tanksynth.__path__, prefix="tanksynth.")
    if not name.endswith("__main__")
)


@pytest.mark.parametrize("name", MODULES)
def test_module_has_all_and_docstrings(name):
    module = importlib.import_module(name)
    assert module.__doc__, f"{name} has no module docstring"
    if name.endswith(".data"):
        return
    assert hasattr(module, "__all__"), f"{name} has no __all__"
    for item in module.__all__:
        obj = getattr(module, item)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            assert inspect.getdoc(obj), f"{name}.{item} has no docstring"


def test_top_level_all_resolves():
    for item in tanksynth.__all__:
        assert hasattr(tanksynth, item), item


def test_errors_subclass_builtins():
    from tanksynth import errors

    assert issubclass(errors.SpecError, ValueError)
    assert issubclass(errors.InfeasibleDesign, RuntimeError)
    assert issubclass(errors.ParseError, errors.SpecError)
    for item in errors.__all__:
        assert issubclass(getattr(errors, item), errors.TanksynthError)
