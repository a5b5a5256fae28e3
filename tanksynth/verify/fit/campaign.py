"""What Monte-Carlo campaigns run for the ``fit`` family: how far the fitted parameters'
uncertainty moves the plant's outputs.

A fit ships parameter values and their covariance. In a campaign each run draws the free
parameters from ``N(theta, covariance)`` (from its seed; clipped to the search box) and
simulates the scenario (its input schedule, or the operating input held; its disturbances and
noise) with those values and, with the same seed, at the fitted values; the metric is the RMS
difference of every output between the two (``output_spread_<output>``, output units): what the
estimation uncertainty alone means for the outputs. No refit is made.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant
from tanksynth.sim.metrics import Metric
from tanksynth.sim.scenarios import Scenario
from tanksynth.sim.simulate import simulate
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, operating_point

__all__ = ["FitRun", "fit_run"]


@dataclass(frozen=True)
class FitRun:
    """A fitted parameter vector and its covariance (a campaign run of kind ``"model"``).

    Attributes
    ----------
    names : tuple of str
        The free parameters.
    theta : ndarray, shape (k,)
        Fitted values (the parameters' units).
    covariance : ndarray, shape (k, k)
        Their covariance (the parameters' units squared).
    lower, upper : ndarray, shape (k,)
        The search box (draws are clipped to it).
    x0, u0 : ndarray
        The spec's operating point (state units, input units).
    description : str
    undetermined : ndarray of bool, shape (k,)
        Parameters the data do not determine (flags, dimensionless): drawn uniformly in their box (their covariance
        entries say nothing).
    kind : str
        ``"model"``.
    """

    names: tuple[str, ...]
    theta: np.ndarray
    covariance: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    x0: np.ndarray
    u0: np.ndarray
    description: str
    undetermined: np.ndarray | None = None
    kind: str = field(default="model", init=False)

    def draws(self, seeds: Sequence[int]) -> np.ndarray:
        """One parameter vector per seed, ``N(theta, covariance)`` clipped to the box (uniform in
        the box for a parameter the data do not determine).

        Parameters
        ----------
        seeds : sequence of int
            One per run.

        Returns
        -------
        ndarray, shape (M, k)
        """
        cov = 0.5 * (self.covariance + self.covariance.T)
        w, v = np.linalg.eigh(cov)
        root = v * np.sqrt(np.clip(w, 0.0, None))
        out = np.empty((len(seeds), self.theta.size))
        for i, s in enumerate(seeds):
            z = np.random.default_rng([int(s), 20261207]).standard_normal(self.theta.size)
            out[i] = np.clip(self.theta + root @ z, self.lower, self.upper)
            if self.undetermined is not None and np.any(self.undetermined):
                uniform = np.random.default_rng([int(s), 20261208]).uniform(self.lower, self.upper)
                out[i] = np.where(self.undetermined, uniform, out[i])
        return out

    def evaluate(self, sc: Scenario, plant: Plant, *, ts: float, seeds: Sequence[int],
                 substeps: int = 4) -> dict[str, Metric]:
        """Simulate the scenario at drawn and at fitted parameter values; the output spread.

        Parameters
        ----------
        sc : Scenario
        plant : Plant
            The spec's plant (the fitted values replace its free parameters here).
        ts : float
            Sampling period (s).
        seeds : sequence of int
            One per run.
        substeps : int
            RK4 steps per period.

        Returns
        -------
        dict of str to Metric
            ``output_spread_<output>`` per output (output units).
        """
        fitted = plant.with_parameters(dict(zip(self.names, map(float, self.theta))))
        setup = sc.setup(fitted, self.x0, self.u0, ts=ts)
        drawn = self.draws(seeds)
        base: dict[str, Any] = dict(setup.parameters or {})
        outputs = []
        for values in (None, drawn):
            params: dict[str, Any] = dict(base)
            if values is not None:
                params.update({nm: values[:, j] for j, nm in enumerate(self.names)})
            res = simulate(fitted, ts=ts, steps=setup.steps, x0=setup.x0, seeds=list(seeds),
                           controller=setup.controller, reference=setup.reference,
                           x_hat0=setup.x_hat0, u_init=setup.u_init,
                           process_std=setup.scenario.process_std,
                           measurement_std=setup.scenario.measurement_std, parameters=params or None,
                           changes=setup.changes, jumps=setup.jumps, substeps=substeps)
            outputs.append(np.asarray(res.y))
        diff = outputs[1] - outputs[0]
        out = {}
        for j, q in enumerate(plant.outputs):
            out[f"output_spread_{q.name}"] = Metric(
                f"output_spread_{q.name}", np.sqrt(np.mean(diff[:, :, j] ** 2, axis=1)), str(q.unit),
                f"RMS change of {q.name} when the fitted parameters are drawn from their covariance")
        return out


def fit_run(doc: Mapping[str, Any], spec: Spec) -> FitRun:
    """The fitted values and covariance of a ``fit`` artefact, for a campaign.

    Parameters
    ----------
    doc : mapping
        The artefact (gains as arrays).
    spec : Spec
        The validated spec.

    Returns
    -------
    FitRun
    """
    diag = doc.get("diagnostics") or {}
    names = diag.get("names")
    theta = artefact_gain(doc, "theta").reshape(-1)
    k = theta.size
    cov = artefact_gain(doc, "covariance")
    params = diag.get("parameters") or {}
    if not isinstance(names, list) or len(names) != k or cov.size != k * k \
            or not all(isinstance(params.get(n), Mapping) for n in names):
        raise ArtefactError(f"artefact '{doc['name']}': theta, covariance and diagnostics.parameters "
                            "do not match")
    lower = np.array([float(params[n].get("lower", -np.inf)) for n in names])
    upper = np.array([float(params[n].get("upper", np.inf)) for n in names])
    x0, u0 = operating_point(spec)
    unc = diag.get("uncertainty") if isinstance(diag.get("uncertainty"), Mapping) else None
    methods = unc.get("interval_method") if isinstance(unc, Mapping) else None
    undetermined = np.array([isinstance(methods, Mapping) and methods.get(n) == "unidentifiable"
                             for n in names], dtype=bool)
    return FitRun(tuple(map(str, names)), theta, cov.reshape(k, k), lower, upper, x0, u0,
                  "the plant simulated with the free parameters drawn from the fit's covariance "
                  "(uniform in the box where the data do not determine one) against the fitted "
                  "values, same inputs and noise: the outputs' spread", undetermined)
