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
    for item in errors.__all__:   # every error, and the one warning class
        assert issubclass(getattr(errors, item), (errors.TanksynthError, errors.TanksynthWarning))


def test_clear_cache_empties_every_cache_and_results_do_not_change():
    from tanksynth.plants import three_tank
    from tanksynth.sim import run_seeds, simulate
    from tanksynth.sim.tape import cache_info

    plant = three_tank()
    kwargs = dict(ts=1.0, steps=20, x0=[0.4, 0.2, 0.3], seeds=run_seeds(0, 2), u_init=[3e-5, 3e-5])
    before = simulate(plant, **kwargs).x
    assert cache_info()["models"] >= 1
    dropped = tanksynth.clear_cache()
    assert dropped["sim_models"] >= 1 and cache_info()["models"] == 0
    assert set(dropped) >= {"sim_models", "result_specs", "campaign_specs"}
    assert (simulate(plant, **kwargs).x == before).all()          # rebuilt on demand, same numbers
