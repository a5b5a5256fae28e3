"""Verification stage: one verdict module per method family, the runner, Dask campaigns, and the
replay of estimators, observers and detectors on logged data (`tanksynth.verify.replay`).

A verdict never imports the design stage: it re-derives what it checks from
the artefact with its own numerics and runs the estimator or law the artefact
ships (through `tanksynth.runtime`) on the nonlinear plant (`tanksynth.sim`).
Which verdict belongs to which method is the method table's business
(`tanksynth.methods`).
"""

from __future__ import annotations

from tanksynth._lazy import lazy_exports as _lazy_exports

#: Re-exported name -> its module, imported on first use (PEP 562): importing the package
#: loads none of its modules' dependencies (issue 15).
_EXPORTS = {
    **dict.fromkeys(["Verdict", "VerdictFn", "load_directory", "verify_directory"],
                    "tanksynth.verify.runner"),
}

__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)

__all__ = ["Verdict", "VerdictFn", "load_directory", "verify_directory"]
