"""The caches of the runtime, in one place (no hidden state).

``tanksynth.runtime`` keeps two caches:

* native estimator kernels (`tanksynth.runtime.estimators.kernels`, the
  family ``kernels`` of the one native-compile cache, `tanksynth.native_cache`):
  shared libraries compiled from the kernels' generated C, on disk in
  `tanksynth.runtime.estimators.kernels.cache_dir` (``$TANKSYNTH_CACHE``,
  else ``$TANKSYNTH_CACHE_DIR/kernels``, else
  ``$XDG_CACHE_HOME/tanksynth/kernels``, else ``~/.cache/tanksynth/kernels``)
  and, once loaded, in memory;
* per-plant compiled pieces of the estimators' sampled models (the
  regularised Jacobian Function, the affinity test), in memory, dropped with
  the plant (`tanksynth.runtime.estimators.model`).

`clear_cache` empties both (and, with ``disk=True``, deletes the compiled
libraries); `cache_info` reports their sizes. Clearing never changes a
result: everything is rebuilt on demand, bit for bit.
"""

from __future__ import annotations

from tanksynth.runtime.estimators import kernels, model

__all__ = ["clear_cache", "cache_info"]


def clear_cache(disk: bool = False) -> dict[str, int]:
    """Empty the runtime's caches.

    Parameters
    ----------
    disk : bool
        Also delete the compiled native kernels on disk.

    Returns
    -------
    dict
        ``native_loaded`` (kernels forgotten), ``native_files`` (libraries
        deleted), ``plants`` (plants whose compiled model pieces were dropped).
    """
    native = kernels.clear_cache(disk)
    return {"native_loaded": native["loaded"], "native_files": native["files"],
            "plants": model.clear_cache()}


def cache_info() -> dict[str, object]:
    """Sizes of the caches: native kernels loaded and on disk (with the directory), plants."""
    info = kernels.cache_info()
    return {"native_loaded": info["loaded"], "native_files": info["files"],
            "native_directory": info["directory"], "plants": model.cached_plants()}
