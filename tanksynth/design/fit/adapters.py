"""Design adapters of the ``fit`` family: ``fit``.

Scaffolded by scripts/add_method.py.
"""

from __future__ import annotations

import numpy as np

from tanksynth.design.result import DesignMethod, DesignResult, options_of
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options.fit import FitOptions

__all__ = ["run_fit", "FIT"]


def run_fit(spec: Spec, design: DesignSpec) -> DesignResult:
    """Design ``fit``: a skeleton that designs nothing yet.

    TODO(fit): compute the method's gains from the validated options; record in the
    diagnostics what the verdict re-derives and the report states.

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).

    Returns
    -------
    DesignResult
        Until the design is written, one gain: ``x_op``, the operating point (state units).
    """
    options = options_of(design, spec, FitOptions)
    plant = spec.plant
    gains = {"x_op": np.array(spec.x0, dtype=float)}
    diagnostics = {"scaffold": "design not written yet (skeleton of scripts/add_method.py)",
                   "example_option": options.example_option}
    return DesignResult(design.name, "fit", plant.name, gains, diagnostics)


FIT = DesignMethod("fit", run_fit, FitOptions)
