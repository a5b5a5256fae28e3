"""What runs in the loop and gets exported: estimators and control laws.

Caches (native kernels, per-plant model pieces) are described in
`tanksynth.runtime.cache`; `clear_cache` and `cache_info` are re-exported
here (loaded on first use).
"""

from __future__ import annotations

from tanksynth._lazy import lazy_exports as _lazy_exports

_EXPORTS = dict.fromkeys(["clear_cache", "cache_info"], "tanksynth.runtime.cache")

__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)

__all__ = list(_EXPORTS)
