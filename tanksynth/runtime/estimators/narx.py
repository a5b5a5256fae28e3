"""NARX neural state estimator (seed 002 section 3.3, Table 3): the shipped forward pass.

The correction step of the EKF is replaced by a NARX network (eq. 41-45)::

    x(k|k-1) = F(x(k-1), u(k))                                  (42)
    gamma(k) = y(k) - h(x(k|k-1))                               (43)-(44)
    x(k)     = NN( [x(k|k-1), gamma(k)], x(k-1), ..., x(k-d) )  (45)

with the exogenous input ``X(k) = [x(k|k-1), gamma(k)]`` (``n + q`` = 4
inputs for the hybrid three-tank), no input delays, ``d`` output feedback
delays (2), one hidden layer of ``tanh`` neurons (5), a linear output layer
(``n`` = 3 outputs): Table 3. Inputs and outputs are standardised with the
training data's mean and standard deviation (stored in the tuning).

This module holds what the artefact ships and the loop runs: the weights
(`NARXTuning`), the forward pass and the estimator kernel (`NARXEstimator`),
and the layout of the network's open-loop regressors (`open_loop_regressors`). The
training (data generation through the simulator, Levenberg-Marquardt) is
design work: `tanksynth.design.estimators.narx_training`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import casadi as ca
import numpy as np

from tanksynth.errors import DimensionError, SpecError
from tanksynth.plants.base import Plant
from tanksynth.runtime.estimators.base import DiscreteModel, KernelEstimator, discrete_model
from tanksynth.runtime.estimators.tuning import (as_matrix, as_vector, positive_float, positive_int,
                                                 require_tuning, set_fields)

__all__ = ["NARXTuning", "NARXEstimator", "forward_pass", "open_loop_regressors"]


@dataclass(frozen=True, eq=False)
class NARXTuning:
    """Weights and normalisation of the NARX estimator: the artefact.

    Attributes
    ----------
    W1 : ndarray, shape (H, n + q + d n)
        Hidden-layer weights (on standardised inputs).
    b1 : ndarray, shape (H,)
    W2 : ndarray, shape (n, H)
        Linear output layer (standardised outputs).
    b2 : ndarray, shape (n,)
    in_mean, in_scale : ndarray, shape (n + q + d n,)
        Input standardisation (state/output units).
    out_mean, out_scale : ndarray, shape (n,)
        Output standardisation (state units).
    x0 : ndarray, shape (n,)
        Initial estimate (also the initial delayed outputs), in state units.
    ts : float
        Sampling period (s).
    delays : int
        Output feedback delays ``d`` (Table 3: 2).
    substeps : int
        Runge-Kutta steps of the prediction model per period.
    clip : bool
        Clamp predictions and estimates to the plant's region box.
    """

    W1: np.ndarray
    b1: np.ndarray
    W2: np.ndarray
    b2: np.ndarray
    in_mean: np.ndarray
    in_scale: np.ndarray
    out_mean: np.ndarray
    out_scale: np.ndarray
    x0: np.ndarray
    ts: float
    delays: int = 2
    substeps: int = 1
    clip: bool = False

    def __post_init__(self) -> None:
        set_fields(self, W1=as_matrix(self.W1, "W1"), W2=as_matrix(self.W2, "W2"))
        H, nin = self.W1.shape
        n = self.W2.shape[0]
        set_fields(self, b1=as_vector(self.b1, "b1", H), b2=as_vector(self.b2, "b2", n))
        if self.W2.shape != (n, H):
            raise DimensionError(f"W2 must be (n, {H}), got {self.W2.shape}")
        set_fields(self, in_mean=as_vector(self.in_mean, "in_mean", nin),
                   in_scale=as_vector(self.in_scale, "in_scale", nin),
                   out_mean=as_vector(self.out_mean, "out_mean", n),
                   out_scale=as_vector(self.out_scale, "out_scale", n))
        if not (np.all(self.in_scale > 0) and np.all(self.out_scale > 0)):
            raise SpecError("in_scale and out_scale must be > 0", key="in_scale")
        set_fields(self, x0=as_vector(self.x0, "x0", n), ts=positive_float(self.ts, "ts"),
                   delays=positive_int(self.delays, "delays"),
                   substeps=positive_int(self.substeps, "substeps"))
        if nin - (1 + self.delays) * n < 1:
            raise DimensionError(f"W1 has {nin} inputs: expected n + q + d n with q >= 1 "
                                 f"(n = {n}, d = {self.delays})")

    @property
    def hidden(self) -> int:
        """Number of hidden neurons."""
        return self.W1.shape[0]

    @property
    def n_outputs(self) -> int:
        """Number of measured outputs ``q`` the network takes."""
        return self.W1.shape[1] - (1 + self.delays) * self.W2.shape[0]

    def parameters(self) -> np.ndarray:
        """All weights as one vector ``[W1 (row-major), b1, W2 (row-major), b2]``."""
        return np.concatenate([self.W1.ravel(), self.b1, self.W2.ravel(), self.b2])

    def gains(self) -> dict[str, np.ndarray]:
        """Weights and normalisation for the artefact; the initial
        estimate ``x0`` is stored as ``x_hat0``."""
        return {"W1": self.W1, "b1": self.b1, "W2": self.W2, "b2": self.b2,
                "in_mean": self.in_mean, "in_scale": self.in_scale, "out_mean": self.out_mean,
                "out_scale": self.out_scale, "x_hat0": self.x0, "delays": np.array([float(self.delays)])}


def forward_pass(params: Sequence[np.ndarray], Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The network on standardised inputs, in numpy: the kernel's eq. 45 without the scaling.

    Parameters
    ----------
    params : sequence of ndarray
        ``(W1 (H, nin), b1 (H,), W2 (n, H), b2 (n,))``, as in `NARXTuning` (dimensionless:
        standardised units).
    Z : ndarray, shape (N, nin)
        Standardised inputs, one sample per row.

    Returns
    -------
    outputs : ndarray, shape (N, n)
        Standardised outputs (linear layer).
    hidden : ndarray, shape (N, H)
        ``tanh`` activations of the hidden layer.
    """
    W1, b1, W2, b2 = params
    A = np.tanh(Z @ W1.T + b1)
    return A @ W2.T + b2, A


class NARXEstimator(KernelEstimator):
    """NARX neural state estimator (seed 002 eq. 42-45).

    Parameters
    ----------
    plant : Plant
    tuning : NARXTuning
    runs : int, optional
    backend : {"auto", "native", "vm"}
    model : DiscreteModel, optional
        A model to use instead of the tuning's.

    Notes
    -----
    The kernel state is ``[x(k-1), x(k-2), ..., x(k-d)]``; ``extra`` holds
    the innovation ``gamma(k)`` (q) and the prediction ``x(k|k-1)`` (n).
    There is no covariance; only finiteness of the estimate is checked.
    """

    method = "narx"
    check_names = ()

    def __init__(self, plant: Plant, tuning: NARXTuning, runs: int | None = None,
                 backend: str = "auto", *, model: DiscreteModel | None = None):
        require_tuning(self, tuning, NARXTuning)
        if tuning.W2.shape[0] != plant.n or tuning.n_outputs != plant.q:
            raise DimensionError(f"the network has {tuning.W2.shape[0]} outputs and takes "
                                 f"{tuning.n_outputs} measurements; plant '{plant.name}' has "
                                 f"n = {plant.n}, q = {plant.q}")
        if model is None:
            model = discrete_model(plant, tuning.ts, substeps=tuning.substeps, clip=tuning.clip)
        super().__init__(plant, tuning, model, runs, backend)

    def _sizes(self) -> tuple[int, int, int]:
        t = self.tuning
        return t.hidden, t.W1.shape[1], t.delays

    def _build(self) -> ca.Function:
        mdl = self.model
        n, m, q = self.n, self.m, self.q
        H, nin, d = self._sizes()
        S = ca.SX.sym("state", d * n)
        y = ca.SX.sym("y", q)
        u = ca.SX.sym("u", m)
        npar = H * nin + H + n * H + n + 2 * nin + 2 * n
        p = ca.SX.sym("params", npar)
        i = 0

        def take(rows: int, cols: int) -> ca.SX:
            nonlocal i
            block = p[i:i + rows * cols]
            i += rows * cols
            return ca.reshape(block, cols, rows).T          # row-major blocks
        W1, b1, W2, b2 = take(H, nin), take(H, 1), take(n, H), take(n, 1)
        mu_in, sd_in, mu_out, sd_out = take(nin, 1), take(nin, 1), take(n, 1), take(n, 1)
        past = [S[j * n:(j + 1) * n] for j in range(d)]
        xp = mdl.predict_sx(past[0], u)                     # (42)
        gam = y - mdl.output_sx(xp)                         # (43)-(44)
        inp = ca.vertcat(xp, gam, *past)
        z = (inp - mu_in) / sd_in
        hid = ca.tanh(W1 @ z + b1)
        xn = mdl.clip_sx(mu_out + sd_out * (W2 @ hid + b2))    # (45)
        new = ca.vertcat(xn, *past[:-1])
        return ca.Function("narx_step", [S, y, u, p],
                           [ca.densify(new), ca.densify(ca.sum1(xn)),
                            ca.densify(ca.vertcat(gam, xp))],
                           ["state", "y", "u", "params"], ["state_new", "checks", "extra"])

    def _params(self) -> np.ndarray:
        t = self.tuning
        return np.concatenate([t.parameters(), t.in_mean, t.in_scale, t.out_mean, t.out_scale])

    def _initial_state(self, X0: np.ndarray) -> np.ndarray:
        return np.tile(X0, (1, self.tuning.delays))


def open_loop_regressors(data: dict[str, np.ndarray], x0: np.ndarray, delays: int,
                         target: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Open-loop (teacher-forced) inputs, targets and priors of the network; samples ordered
    (step, run).

    The inputs are laid out as the kernel reads them: ``[x(k|k-1), gamma(k), x(k-1), ...,
    x(k-d)]`` with the delayed estimates taken from the data (the target states).

    Parameters
    ----------
    data : dict of ndarray
        Logged runs, each (steps, runs, .): ``prior`` (x(k|k-1), state units), ``innovation``
        (gamma(k), output units), ``x_ekf`` (EKF estimates) and ``x`` (true states, one more
        step), in state units.
    x0 : ndarray, shape (n,)
        The initial estimate standing for the delayed states before the first step (state units).
    delays : int
        Output feedback delays d.
    target : {"ekf", "true"}
        Train towards the EKF's estimates or the true states.

    Returns
    -------
    inputs : ndarray, shape (steps runs, n + q + d n)
        Regressors (state and output units).
    targets : ndarray, shape (steps runs, n)
        Target states (state units).
    priors : ndarray, shape (steps runs, n)
        Predictions x(k|k-1) (state units).
    """
    est = data["x_ekf"] if target == "ekf" else data["x"][1:]
    steps, runs, n = est.shape
    past = [np.concatenate([np.broadcast_to(x0, (j + 1, runs, n)), est[:steps - j - 1]])
            for j in range(delays)]
    inputs = np.concatenate([data["prior"], data["innovation"], *past], axis=2)
    return (inputs.reshape(steps * runs, -1), est.reshape(steps * runs, n),
            data["prior"].reshape(steps * runs, n))
