"""Campaign runner of the Takagi-Sugeno PDC designs: the scenarios, and the certified region sampled.

``tanksynth verify DIR --runs N`` gives every (artefact, scenario) ``N``
runs on Dask (`tanksynth.verify.campaign`). A TS PDC run does two things:

* the scenario in closed loop from the operating point, as for any
  controller (`ClosedLoop.evaluate`: ``ise_<y>``, ``offset_<y>``, ...);
* a run of the certificate: the nominal plant from a point of the certified
  region drawn from the run's seed and the scenario's name (so that the
  ``N x scenarios`` runs are distinct samples of the region): on its
  boundary or inside it (a seeded coin), with an estimation error sharing
  the level for the output feedback, exactly as the verdict samples it
  (`tanksynth.verify.takagi_sugeno.loops.region_sample`). It is judged by the
  verdict's conditions (`region_conditions`): ``region_left_domain``,
  ``region_saturated``, ``region_max_growth``, ``region_final_ratio`` and
  ``region_passed``; with a set-point change, a second run from the same
  point switches to the law about ``x_op2`` after the dwell time
  (`setpoint_conditions`):
  ``setpoint_left_domain``, ``setpoint_saturated``,
  ``setpoint_switch_level``, ``setpoint_final_error``, ``setpoint_passed``.

The certificate covers the nominal plant only: the scenario's disturbances
act on the scenario metrics, not on the region runs.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant
from tanksynth.sim.metrics import Metric
from tanksynth.sim.scenarios import Scenario
from tanksynth.sim.simulate import BatchEstimator
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, fmt, sampling_period
from tanksynth.verify.laws.campaign import ClosedLoop
from tanksynth.verify.takagi_sugeno.loops import (MeasuredPremiseObserver, PDCLaw, loop_setup,
                                                  plant_ts_observer, region_conditions,
                                                  region_horizon, region_sample, simulate_region)
from tanksynth.verify.takagi_sugeno.setpoint import (PREFIX, setpoint_conditions,
                                                     setpoint_settle_time, switch_runs)

__all__ = ["TsRegionRun", "ts_control_run", "region_draws"]


def region_draws(doc: Mapping[str, Any], spec: Spec, seeds: Sequence[int],
                 scenario: str) -> tuple[np.ndarray, np.ndarray | None]:
    """One point of the certified region per run, drawn from its seed and the scenario's name.

    Run ``r`` takes row ``k`` (``default_rng([seed_r, crc32(scenario), 9])``,
    a fair coin: 0 on the boundary, 1 inside) of ``region_sample(doc, spec,
    2, [seed_r, crc32(scenario)])``.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    seeds : sequence of int
        One per run.
    scenario : str
        Scenario name.

    Returns
    -------
    (ndarray (M, n), ndarray (M, n) or None)
        Deviations from the operating point and estimation errors (state units, m).
    """
    tag = zlib.crc32(scenario.encode("utf-8"))
    E, eps = [], []
    for s in seeds:
        k = int(np.random.default_rng([int(s), tag, 9]).integers(2))
        e0, ep = region_sample(doc, spec, 2, [int(s), tag])
        E.append(e0[k])
        eps.append(None if ep is None else ep[k])
    return np.array(E), (None if eps[0] is None else np.array(eps))


@dataclass(frozen=True)
class TsRegionRun(ClosedLoop):
    """A TS PDC artefact in the campaign: the scenario, plus a run from the certified region.

    Attributes
    ----------
    controller, estimator_factory, x_op, u_op, tracked, description
        As in `ClosedLoop` (the PDC law, its observer, the operating point
        (state units, m), its input (input units), the tracked states, one line).
    doc : mapping
        The artefact (gains as arrays).
    spec : Spec
        The validated spec.
    """

    doc: Mapping[str, Any] = field(default_factory=dict)
    spec: Spec | None = None

    def evaluate(self, sc: Scenario, plant: Plant, *, ts: float, seeds: Sequence[int],
                 substeps: int = 4) -> dict[str, Metric]:
        """The scenario's closed-loop metrics and the certificate's (see the module).

        Parameters
        ----------
        sc, plant : Scenario, Plant
            The scenario and the plant model.
        ts, seeds, substeps : float, sequence of int, int
            Sampling period [s], one seed per run, RK4 steps per period.
        """
        metrics = ClosedLoop.evaluate(self, sc, plant, ts=ts, seeds=seeds, substeps=substeps)
        doc, spec = self.doc, self.spec
        if spec is None:
            raise ArtefactError("a TS region run needs the spec it was built from (ts_control_run "
                                "gives it)")
        E0, eps0 = region_draws(doc, spec, seeds, sc.name)
        c = float(artefact_gain(doc, "region_c")[0])
        out = simulate_region(doc, spec, E0, eps0=eps0, horizon=region_horizon(doc))
        cond = region_conditions(out, c)
        if "sp_K" in doc["gains"]:
            n = plant.n
            dwell = switch_runs(doc, spec, 2, 0)["dwell"]
            settle = setpoint_settle_time(doc, n)
            dwell = dwell if np.isfinite(dwell) else region_horizon(doc)
            out2 = simulate_region(doc, spec, E0, eps0=eps0, horizon=dwell + settle, switch_at=dwell)
            x2 = artefact_gain(doc, PREFIX + "x_op").reshape(n)
            c2 = float(artefact_gain(doc, PREFIX + "region_c")[0])
            tol = float(((doc.get("diagnostics") or {}).get("setpoint") or {}).get("tolerance", 0.002))
            sp = setpoint_conditions(out2, x2, c2, tol)
            for key, unit, what in (("left_domain", "1", "the run left the TS domain (1) or not"),
                                    ("saturated", "1", "the law asked a pump for more than it gives"),
                                    ("switch_level", "1", "V2 / c2 at the switch (<= 1 certified)"),
                                    ("final_error", "m", "largest distance to x_op2 at the end"),
                                    ("passed", "1", "every set-point condition of the verdict holds")):
                metrics[f"setpoint_{key}"] = Metric(f"setpoint_{key}", np.asarray(sp[key], float),
                                                    unit, what)
        for key, unit, what in (("left_domain", "1", "the run left the TS domain (1) or not"),
                                ("saturated", "1", "the law asked a pump for more than it gives"),
                                ("max_growth", "1", "largest relative growth of V per sample"),
                                ("final_ratio", "1", "V(T) / V(0)"),
                                ("passed", "1", "every region condition of the verdict holds")):
            metrics[f"region_{key}"] = Metric(f"region_{key}", np.asarray(cond[key], float), unit, what)
        return metrics


def ts_control_run(doc: Mapping[str, Any], spec: Spec) -> ClosedLoop:
    """Campaign runner of ``ts_state_feedback`` / ``ts_output_feedback``: a `ClosedLoop` that also
    samples the certified region (`TsRegionRun`).

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    s = loop_setup(doc, spec)
    ts = sampling_period(spec)
    model = s["model"]
    factory: Callable[[], BatchEstimator] | None = None
    law = PDCLaw(model, s["K"])
    if doc["method"] == "ts_output_feedback":
        L = artefact_gain(doc, "L")
        if L.ndim == 3:
            shared = MeasuredPremiseObserver(model, L, ts, 64)
            law = PDCLaw(model, s["K"], shared)     # the law reads the observer's measured premises
            factory = lambda: shared  # noqa: E731
        else:
            factory = lambda: plant_ts_observer(doc, spec.plant, model.C, ts)  # noqa: E731
    outputs = [s_.name for s_ in spec.plant.outputs]
    states = [s_.name for s_ in spec.plant.states]
    tracked = tuple(states.index(o) for o in outputs if o in states)
    return TsRegionRun(law, factory, model.x0.copy(), model.u0.copy(), tracked,
                       f"Takagi-Sugeno PDC ({doc['method']}) regulating to x0 = {fmt(model.x0)} in "
                       "the scenario (its set-point changes are ignored); region_* (and setpoint_*) "
                       "metrics: a run of the nominal plant from a seeded point of the certified "
                       "region, judged as the verdict judges it", doc=doc, spec=spec)
