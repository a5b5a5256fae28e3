"""Spec design method ``fault_detection``: observer residual and threshold (seed 004 II-F).

The observer gain ``Psi`` comes from the canonical form in exact arithmetic, the threshold
bounds the output residual of the healthy plant (`tanksynth.design.fault.threshold`), and the
detection times of the declared fault are computed for the given initial states and input.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from tanksynth.design.fault.threshold import detection_time, fault_threshold
from tanksynth.design.operating_point import equilibrium_at
from tanksynth.design.result import DesignMethod, DesignResult, keyed_call, options_of
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options import FaultDetectionOptions

__all__ = ["run_fault_detection", "FAULT_DETECTION"]

#: Spec option named in a `SpecError` the threshold or detection step raises, by its key.
_OPTION_OF = {"gain": "poles", "input_schedule": "input"}


def run_fault_detection(spec: Spec, design: DesignSpec) -> DesignResult:
    """Observer gain, residual threshold and detection times (seed 004 section II-F).

    The threshold bounds the output residual of the healthy plant for every
    initial level in ``(lower, upper]`` (`tanksynth.design.fault.threshold.fault_threshold`);
    the detection times of the declared fault ``delta_bar`` from ``t_fault``
    are computed for each of ``initial_states`` (default: the operating
    point) under ``input`` (default: the equilibrium input, held) and stored
    in the diagnostics. Options:
    `tanksynth.spec.method_options.FaultDetectionOptions`.

    Gains: ``Psi`` (observer gain), ``Gamma_d`` (``A - Psi C``, 1/s) and the
    threshold's ``threshold_coefficients`` (output units) and
    ``threshold_rates`` (1/s).

    Parameters
    ----------
    spec : Spec
        The validated spec (plant, operating point, sampling).
    design : DesignSpec
        This ``[[design]]`` entry (method and options).
    """
    o = options_of(design, spec, FaultDetectionOptions)
    poles = [p.real if p.imag == 0 else p for p in o.poles]
    plant = spec.plant
    healthy = plant.with_parameters({"delta_bar": 0.0}) if "delta_bar" in plant.p else plant
    th = keyed_call(design, fault_threshold, _OPTION_OF, plant=healthy, poles=poles,
                    bounds=tuple(o.bounds))
    gains = {"Psi": np.array(th.Psi.evalf(17), dtype=float),
             "Gamma_d": np.array(th.Gamma_d.evalf(17), dtype=float),
             "threshold_coefficients": np.array([float(c) for c, _ in th.terms]),
             "threshold_rates": np.array([float(sp.re(lam)) for _, lam in th.terms])}
    starts = [np.array(spec.x0, dtype=float)] if o.initial_states is None else \
        [np.array(x, dtype=float) for x in o.initial_states]
    pieces = [[float(v) for v in p] for p in o.input] if o.input is not None else \
        [[0.0, *equilibrium_at(healthy, spec.x0, spec.given_u0).u0.tolist()]]
    detections = [keyed_call(design, detection_time, _OPTION_OF, th=th, x0=x, delta_bar=o.delta_bar,
                             t_fault=o.t_fault, conservative=o.conservative, plant=healthy,
                             input_schedule=[(p[0], p[1:]) for p in pieces]) for x in starts]
    diag = {"threshold": th.as_dict(), "delta_bar": o.delta_bar, "t_fault": o.t_fault,
            "conservative": o.conservative, "input": pieces,
            "initial_states": [x.tolist() for x in starts],
            "detection_times": [r.t_detect for r in detections],
            "detections": [{"x0": r.x0.tolist(), "t_detect": r.t_detect,
                            "false_alarm_before_fault": r.false_alarm} for r in detections],
            "notes": ["the fault size delta_bar is the spec's (declared, not printed in the paper)",
                      "a start from which the fault is not detected within 3 s of its onset, under "
                      "the spec's input schedule, has no detection time (null in the artefact's "
                      "detection times)"]}
    latex = {"threshold": sp.latex(th.expression),
             "threshold_conservative": sp.latex(th.conservative)}
    return DesignResult(design.name, "fault_detection", plant.name, gains, diag, latex)


FAULT_DETECTION = DesignMethod("fault_detection", run_fault_detection, FaultDetectionOptions)
