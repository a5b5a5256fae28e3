"""Model artefacts in Monte-Carlo campaigns: prediction error against the nonlinear plant.

A ``linearize`` artefact ships the discrete linear model ``x_{k+1} - x0 =
Ad (x_k - x0) + Bd (u_k - u0)`` at its operating point. In a campaign the
nonlinear plant follows the scenario (its input schedule or ``u0`` held;
its disturbances, mismatch, faults and noise) and the model predicts, from
the same applied inputs:

``prediction_rmse_<state>``
    free run from the initial state, with the scenario's known level jumps
    added (RMS error over the run);
``one_step_rmse_<state>``
    ``x_{k+1}`` from the simulated ``x_k`` (RMS error over the run; a jump
    at sample ``k + 1`` is added to the prediction).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant
from tanksynth.sim.metrics import Metric, prediction_metrics
from tanksynth.sim.scenarios import Scenario, run_scenario
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain

__all__ = ["ModelRun", "linear_predictions", "linearize_run"]


def linear_predictions(Ad: np.ndarray, Bd: np.ndarray, x0: np.ndarray, u0: np.ndarray,
                       x: np.ndarray, u: np.ndarray, jumps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Free-run and one-step predictions of a discrete linear model.

    Parameters
    ----------
    Ad, Bd : ndarray, shape (n, n), (n, m)
    x0, u0 : ndarray
        Operating point of the model (state and input units).
    x : ndarray, shape (M, N + 1, n)
        Simulated states (the free run starts at ``x[:, 0]``).
    u : ndarray, shape (M, N, m)
        Applied inputs.
    jumps : ndarray, shape (N + 1, n)
        Known level changes added at each sample (state units).

    Returns
    -------
    free_run : ndarray, shape (M, N + 1, n)
    one_step : ndarray, shape (M, N, n)
    """
    du = u - u0
    free = np.empty_like(x)
    z = x[:, 0] - x0
    free[:, 0] = x[:, 0]
    for k in range(u.shape[1]):
        z = z @ Ad.T + du[:, k] @ Bd.T + jumps[k + 1]
        free[:, k + 1] = x0 + z
    one = x0 + (x[:, :-1] - x0) @ Ad.T + du @ Bd.T + jumps[None, 1:]
    return free, one


@dataclass(frozen=True)
class ModelRun:
    """A discrete linear model against the nonlinear plant (a campaign run of kind ``"model"``).

    Attributes
    ----------
    Ad, Bd : ndarray
        The artefact's discrete model.
    x0, u0 : ndarray
        Its operating point (state units, input units).
    ts : float
        Its sampling period (s).
    description : str
    kind : str
        ``"model"``.
    """

    Ad: np.ndarray
    Bd: np.ndarray
    x0: np.ndarray
    u0: np.ndarray
    ts: float
    description: str
    kind: str = field(default="model", init=False)

    def evaluate(self, sc: Scenario, plant: Plant, *, ts: float, seeds: Sequence[int],
                 substeps: int = 4) -> dict[str, Metric]:
        """Simulate the scenario and compare the model's predictions with it.

        Parameters
        ----------
        sc : Scenario
        plant : Plant
        ts : float
            Sampling period (s); must be the model's.
        seeds : sequence of int
            One per run (process and measurement noise).
        substeps : int
            RK4 steps per period of the nonlinear plant.

        Returns
        -------
        dict of str to Metric
            ``prediction_rmse_<state>`` and ``one_step_rmse_<state>``.

        Raises
        ------
        ArtefactError
            The campaign's sampling period differs from the model's.
        """
        if abs(float(ts) - self.ts) > 1e-12 * max(1.0, self.ts):
            raise ArtefactError(f"the model is discretised at ts = {self.ts:g} s; the campaign "
                                f"samples at {ts:g} s")
        setup = sc.setup(plant, self.x0, self.u0, ts=ts)
        at_rest = np.array_equal(np.asarray(setup.x0, dtype=float), np.asarray(self.x0, dtype=float))
        if (at_rest and sc.process_std == 0 and not sc.jumps and not sc.faults
                and sc.parameter_factor == 1.0 and sc.input_schedule is None):
            return {"not_applicable": Metric(
                "not_applicable", np.ones(len(seeds)), "1",
                f"scenario {sc.name!r} leaves the plant at rest at the operating point (no input "
                "change, no noise, no disturbance): the model's error is zero by construction, so "
                "no RMSE is reported")}
        res = run_scenario(setup, plant, ts=ts, seeds=list(seeds), substeps=substeps)
        jumps = np.zeros((setup.steps + 1, plant.n))
        for j in setup.jumps:
            jumps[j.sample] += np.asarray(j.delta, dtype=float)
        free, one = linear_predictions(self.Ad, self.Bd, self.x0, self.u0, np.asarray(res.x),
                                       np.asarray(res.u), jumps)
        return prediction_metrics(plant, np.asarray(res.x), free, one)


def linearize_run(doc: Mapping[str, Any], spec: Spec) -> ModelRun:
    """The discrete model ``Ad, Bd`` at ``x0, u0`` of a ``linearize`` artefact.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    plant = spec.plant
    n, m = plant.n, plant.m
    Ad, Bd = artefact_gain(doc, "Ad"), artefact_gain(doc, "Bd")
    if Ad.size != n * n or Bd.size != n * m:
        raise ArtefactError(f"artefact '{doc['name']}': Ad, Bd have {Ad.size}, {Bd.size} entries, "
                            f"expected {n} x {n}, {n} x {m}")
    diag = doc.get("diagnostics") or {}
    ts = diag.get("ts", spec.ts) if isinstance(diag, Mapping) else spec.ts
    if not isinstance(ts, (int, float)) or not ts > 0:
        raise ArtefactError(f"artefact '{doc['name']}': no sampling period in its diagnostics")
    x0, u0 = artefact_gain(doc, "x_op").reshape(n), artefact_gain(doc, "u_op").reshape(m)
    return ModelRun(Ad.reshape(n, n), Bd.reshape(n, m), x0, u0, float(ts),
                    f"the artefact's discrete linear model (ZOH, ts = {float(ts):g} s) at x_op = ["
                    + ", ".join(f"{v:.4g}" for v in x0) + "] predicting the nonlinear plant from "
                    "the same inputs (the scenario's input schedule or u_op held), free run and one "
                    "step ahead")
