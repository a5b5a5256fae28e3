"""tanksynth: observer and controller synthesis for multi-tank hydraulic plants.

The pipeline runs one way: spec (TOML) -> plant (sympy) -> analysis -> design
-> artefacts -> verify -> report; `tanksynth.methods` is the one table of the
design methods. ``tanksynth.design(plant, method, x0=..., ts=..., **options)``
designs from Python objects through the same spec validation (`tanksynth.api`)
and returns what ``tanksynth.load`` gives; ``.verify()`` verifies it. The most used names are re-exported here and load on first
use (``import tanksynth`` itself loads none of the numerical libraries).
"""

from __future__ import annotations

from typing import Any

from tanksynth._lazy import lazy_exports as _lazy_exports

_EXPORTS = {
    **dict.fromkeys(["read_artefact", "write_artefact"], "tanksynth.artefacts.io"),
    **dict.fromkeys(["discretize_zoh", "equilibrium_input", "linearize"], "tanksynth.analysis.linearize"),
    **dict.fromkeys(["lie_derivative", "relative_degree"], "tanksynth.analysis.symbolic"),
    "DesignResult": "tanksynth.design.result",
    **dict.fromkeys(["ArtefactError", "DimensionError", "InfeasibleDesign", "ParseError", "RegionError",
                     "SpecError", "TanksynthError", "UncontrollableError", "UnobservableError"],
                    "tanksynth.errors"),
    **dict.fromkeys(["Plant", "builtin_plant", "custom_plant", "hybrid_three_tank", "hydraulic_fault",
                     "tank_network", "three_tank"], "tanksynth.plants"),
    **dict.fromkeys(["load_spec", "parse_spec", "parse_spec_text", "verify_directory",
                     "write_report"], "tanksynth.methods"),
    "Spec": "tanksynth.spec",
    **dict.fromkeys(["load", "Design", "Results", "as_complex"], "tanksynth.loading"),
    "Verdict": "tanksynth.verify.runner",
    "Check": "tanksynth.analysis.checks",
    **dict.fromkeys(["spec_document", "spec_text"], "tanksynth.api"),
    **dict.fromkeys(["controllability_rank", "nonlinear_observability", "observability_rank",
                     "pbh_test", "symbolic_observability"], "tanksynth.analysis.rank"),
}

_lazy_getattr, __dir__ = _lazy_exports(__name__, _EXPORTS)


def __getattr__(name: str) -> Any:
    """``__version__`` (read from the installed metadata on first use: importlib.metadata
    costs ~25 ms, issue 15) and the lazy re-exports."""
    if name == "__version__":
        from importlib import metadata

        try:
            version = metadata.version("tanksynth")
        except metadata.PackageNotFoundError:  # pragma: no cover - source tree without install
            version = "0+unknown"
        globals()["__version__"] = version
        return version
    if name == "design":  # the design stage's package, callable as `tanksynth.api.design`
        __import__("tanksynth.design")
        return globals()["design"]
    return _lazy_getattr(name)


def clear_cache(disk: bool = False) -> dict[str, int]:
    """Empty every cache tanksynth keeps in this process (and, with ``disk``, on disk).

    The caches are: compiled numpy models of plants (`tanksynth.sim.tape`); loaded native
    kernels of the simulator (`tanksynth.sim.kernel`) and of the estimators, and per-plant
    model pieces (`tanksynth.runtime.cache`); domain samples, LP ranges, premise bounds and
    lambdified functions of the TS analysis (`tanksynth.analysis.quasi_lpv`); parsed specs of
    result directories (`tanksynth.verify.runner`) and of campaign tasks
    (`tanksynth.verify.campaign`). The compiled kernels live on disk under the one cache root
    (`tanksynth.native_cache.cache_root`: ``$TANKSYNTH_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/tanksynth``, else ``~/.cache/tanksynth``), in ``sim/`` and ``kernels/``
    (the estimators' in ``$TANKSYNTH_CACHE`` when it is set); ``disk=True`` deletes them.
    Everything is rebuilt on demand; results do not change.

    Parameters
    ----------
    disk : bool
        Also delete the compiled kernels on disk (the simulator's and the estimators').

    Returns
    -------
    dict
        What was dropped, by cache.
    """
    from tanksynth.runtime.cache import clear_cache as _runtime
    from tanksynth.sim.tape import clear_cache as _sim
    from tanksynth.sim.kernel import clear_cache as _sim_kernels
    from tanksynth.verify import campaign, runner

    from tanksynth.analysis.quasi_lpv import clear_cache as _analysis

    dropped = {"sim_models": _sim(), "result_specs": runner.clear_cache(),
               "analysis_samples": _analysis()}
    dropped.update(_runtime(disk=disk))
    sim_native = _sim_kernels(disk)
    dropped.update(sim_native_loaded=sim_native["loaded"], sim_native_files=sim_native["files"])
    dropped["campaign_specs"] = campaign.clear_cache()
    return dropped


__all__ = ["__version__", "clear_cache", "design", *_EXPORTS]
