"""The plant's code translated to C: the same operations as the numpy code (every function the
custom-plant grammar allows), both C layouts (inline and per-stage f) bit for bit, and code it
cannot translate refused (never miscompiled)."""

import numpy as np
import pytest

import tanksynth.sim as sim
from tanksynth.plants import custom_plant, hybrid_three_tank, tank_network, three_tank
from tanksynth.sim import csource, kernel, tape


def _inputs(plant, M, N, seed):
    rng = np.random.default_rng(seed)
    hi = np.array([b if np.isfinite(b) else 1e-4 for _, b in plant.input_limits])
    top = np.where(np.isfinite(plant.state_bounds()[1]), plant.state_bounds()[1], 1.0)
    return rng.uniform(0.0, 1.0, (M, plant.n)) * top, rng.uniform(-0.1, 1.1, (N, M, plant.m)) * hi


def _fallback(monkeypatch, fn):
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "numpy")
    try:
        return fn()
    finally:
        monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "native")


def test_kernel_source_is_c_with_the_entry_point():
    src = csource.kernel_source(tape.numpy_model(three_tank()))
    assert "int tk_run(" in src and "#define NX 3" in src
    assert "sqrt(" in src and "copysign(" in src and "pow(" not in src


@pytest.mark.slow
@pytest.mark.parametrize("plant", [three_tank(), hybrid_three_tank(), tank_network(4)],
                         ids=["three_tank", "hybrid", "network"])
def test_inline_and_per_stage_layouts_give_the_same_numbers(cache, monkeypatch, plant):
    x0, U = _inputs(plant, 10, 80, 5)
    inline = sim.simulate_inputs(plant, x0, U, 1.0, substeps=3)
    assert len(csource._function_body(
        __import__("ast").parse(tape.numpy_model(plant).source), "f",
        ["r"] * (plant.n + plant.m), "cb", "pb", [f"o{i}" for i in range(plant.n)], "v_")) \
        <= csource.INLINE_LIMIT                               # these plants are written inline
    monkeypatch.setattr(csource, "INLINE_LIMIT", 0)
    tape.clear_cache()
    kernel.clear_cache()
    looped = sim.simulate_inputs(plant, x0, U, 1.0, substeps=3)
    assert inline.backend == looped.backend == "native"
    assert np.array_equal(inline.x, looped.x) and inline.events == looped.events
    assert (inline.clipped_low, inline.clipped_high) == (looped.clipped_low, looped.clipped_high)


def test_custom_plant_functions_translate_exactly(cache, monkeypatch):
    """exp, log, min, max, sign, abs, powers and division: native equals the numpy code."""
    plant = custom_plant({"model": "custom",
                          "states": {"a": {"unit": "m", "min": 0.0, "max": 2.0},
                                     "b": {"unit": "m", "min": 0.0, "max": 2.0}},
                          "inputs": {"q": {"unit": "m/s", "min": 0.0, "max": 1.0}},
                          "parameters": {"k": 0.7, "c": 0.3},
                          "equations": {"a": "q - k*sqrt(a) + c*min(a, b)**2 - exp(-a)*b**3",
                                        "b": "k*sign(a - b)*abs(a - b) + log(1 + b)/(2 + a)"
                                             " - max(b, c, 0.5*a)"},
                          "outputs": {"y": "a"}})
    x0, U = _inputs(plant, 10, 50, 8)
    native = sim.simulate_inputs(plant, x0 + 0.1, U, 0.5, substeps=4)
    fallback = _fallback(monkeypatch, lambda: sim.simulate_inputs(plant, x0 + 0.1, U, 0.5,
                                                                   substeps=4))
    assert native.backend == "native"
    assert np.max(np.abs(native.x - fallback.x)) < 1e-12   # exp/log: libm vs numpy, to rounding


def test_untranslatable_code_is_refused_not_miscompiled(cache):
    from dataclasses import replace

    model = tape.numpy_model(three_tank())
    odd = replace(model, source=model.source.replace("numpy.sqrt(r_1)", "numpy.arcsinh(r_1)"),
                  compiled={})
    assert kernel.native_kernel(odd) is None
    assert "numpy.arcsinh" in kernel.kernel_status()
