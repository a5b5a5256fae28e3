"""Fault detectors in Monte-Carlo campaigns: detection delay and false alarms.

A ``fault_detection`` artefact ships an observer gain ``Psi`` and a
threshold ``sum_i c_i exp(lambda_i t)`` (``|c_i|`` when conservative,
seed 004 eq. 54-55) on the output residual. In a campaign the residual
observer `tanksynth.verify.fault.verdicts.ResidualObserver` (the healthy model, ``Psi`` from the artefact)
runs on the simulated measurements of each scenario twice with the same
seeds: as the scenario is (with its faults) and without its parameter
changes (the fault-free twin). An alarm is raised at a sample when
``max_j |y_j - h_j(x_hat)|`` exceeds the threshold at that time (``t`` from
the start of the run, where the observer starts).

Metrics (`tanksynth.sim.metrics.detection_metrics`): ``detection_delay``
(scenarios with a fault), ``false_alarm_rate`` and ``first_false_alarm``
(the fault-free twin), and the observer's computation time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant
from tanksynth.sim.metrics import Metric, detection_metrics, timing_metrics
from tanksynth.sim.scenarios import Scenario, run_scenario
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, design_options, operating_point

from tanksynth.verify.fault.verdicts import ResidualObserver

__all__ = ["DetectorRun", "fault_detection_run"]


@dataclass(frozen=True)
class DetectorRun:
    """A residual test on faulty and fault-free runs (a campaign run of kind ``"detector"``).

    Attributes
    ----------
    Psi : ndarray, shape (n, q)
        Observer gain (1/s).
    coefficients, rates : ndarray, shape (k,)
        Threshold ``sum_i c_i exp(rate_i t)`` (output units, 1/s).
    conservative : bool
        Use ``|c_i|`` (eq. 55).
    x_op, u_op : ndarray
        Operating point (initial plant state, held input), in state and input units.
    description : str
    kind : str
        ``"detector"``.
    """

    Psi: np.ndarray
    coefficients: np.ndarray
    rates: np.ndarray
    conservative: bool
    x_op: np.ndarray
    u_op: np.ndarray
    description: str
    kind: str = field(default="detector", init=False)

    def threshold(self, t: np.ndarray) -> np.ndarray:
        """The threshold at times ``t`` (s from the observer's start), output units.

        Parameters
        ----------
        t : ndarray
            Times from the observer's start [s].
        """
        c = np.abs(self.coefficients) if self.conservative else self.coefficients
        return np.sum(c[:, None] * np.exp(self.rates[:, None] * np.asarray(t, float)[None, :]), axis=0)

    def evaluate(self, sc: Scenario, plant: Plant, *, ts: float, seeds: Sequence[int],
                 substeps: int = 4) -> dict[str, Metric]:
        """Run the residual test on the scenario and on its fault-free twin.

        Parameters
        ----------
        sc : Scenario
        plant : Plant
        ts : float
            Sampling period (s).
        seeds : sequence of int
            One per run; both variants use the same noise.
        substeps : int
            RK4 steps per period (plant and observer).

        Returns
        -------
        dict of str to Metric
            ``detection_delay`` (when the scenario has a fault),
            ``false_alarm_rate``, ``first_false_alarm``, ``estimator_time``.
        """
        setup = sc.setup(plant, self.x_op, self.u_op, ts=ts)
        obs = ResidualObserver(plant, self.Psi, ts, substeps)

        def residual(s: Any) -> tuple[np.ndarray, Any]:
            res = run_scenario(s, plant, ts=ts, seeds=list(seeds), estimator=obs, substeps=substeps)
            M, N1, n = res.x_hat.shape
            yhat = obs.output(res.x_hat.reshape(M * N1, n)).reshape(M, N1, -1)
            return np.max(np.abs(res.y - yhat), axis=2), res

        healthy, res = residual(setup.without_faults())
        faulty = residual(setup)[0] if setup.changes else healthy
        out = detection_metrics(res.t, faulty, self.threshold(res.t), healthy, setup.fault_sample)
        out.update(timing_metrics(res, estimator=True, controller=False))
        return out


def fault_detection_run(doc: Mapping[str, Any], spec: Spec) -> DetectorRun:
    """The residual test of a ``fault_detection`` artefact (stored ``Psi`` and threshold).

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.

    Raises
    ------
    ArtefactError
        ``Psi`` is not (n, q), or the threshold's coefficients and rates differ in number.
    """
    plant = spec.plant
    Psi = artefact_gain(doc, "Psi")
    if Psi.size != plant.n * plant.q:
        raise ArtefactError(f"artefact '{doc['name']}': Psi has {Psi.size} entries, expected "
                            f"{plant.n} x {plant.q}")
    coef = artefact_gain(doc, "threshold_coefficients").reshape(-1)
    rates = artefact_gain(doc, "threshold_rates").reshape(-1)
    if coef.size != rates.size or coef.size == 0:
        raise ArtefactError(f"artefact '{doc['name']}': threshold has {coef.size} coefficients and "
                            f"{rates.size} rates")
    diag = doc.get("diagnostics") or {}
    conservative = diag.get("conservative") if isinstance(diag, Mapping) else None
    if not isinstance(conservative, bool):
        conservative = bool(design_options(doc, spec).get("conservative", True))
    x_op, u_op = operating_point(spec)
    what = ("the sum of |c_i| exp(lambda_i t) over the error modes i, conservative" if conservative
            else "the sum of c_i exp(lambda_i t) over the error modes i")
    return DetectorRun(Psi.reshape(plant.n, plant.q), coef, rates, conservative, x_op, u_op,
                       f"residual test: observer with the artefact's Psi on the nominal model, fed "
                       f"the noisy measurements of {', '.join(o.name for o in plant.outputs)}; "
                       f"alarm when max |y - h(x_hat)| exceeds the stored threshold ({what}); run "
                       "with the scenario's faults and without them (same seeds); plant driven by "
                       "the scenario's input schedule or the operating input held")
