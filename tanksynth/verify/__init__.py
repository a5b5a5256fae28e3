"""Verification stage: one verdict module per method family, the runner, Dask campaigns.

A verdict never imports the design stage: it re-derives what it checks from
the artefact with its own numerics and runs the estimator or law the artefact
ships (through `tanksynth.runtime`) on the nonlinear plant (`tanksynth.sim`).
Which verdict belongs to which method is the method table's business
(`tanksynth.methods`).
"""

from __future__ import annotations

from tanksynth.verify.runner import Verdict, VerdictFn, load_directory, verify_directory

__all__ = ["Verdict", "VerdictFn", "load_directory", "verify_directory"]
