"""Linear models of a plant for the decentralised Kalman gains (seed 003, DECENTER).

The window of `tanksynth.design.decentralized.gains.finite_horizon_gains` needs
discrete models ``(A_k, C_k, Q_k, R_k)`` and a sparsity pattern:

==========================  ==================================================
`own_tank_pattern`          pattern "own tank" (each state corrected by the
                            outputs measuring it alone)
`equicorrelated_intensity`  dense process-noise intensity
`discretize_noise`          Van Loan: exact ``(A_d, Q_d)`` of ``(F, Qc)``
`linear_model`              discrete affine model of a plant at a point
                            (DECENTER's lower-tank-equilibrium scheme for the
                            N-tank network)
`window_models`             models along a predicted trajectory, relinearised
                            every ``relinearize_every`` steps
==========================  ==================================================

The checks of the matrices given (shape, symmetric, positive (semi)definite) are
`tanksynth.design.decentralized.validation`.

Units: covariances are in the squared state unit (cm^2 for the tank
network), ``R`` in the squared output unit, process-noise intensities
``Qc`` in squared state unit per second, gains in state unit per output unit
(cm/cm for the tank network, i.e. dimensionless).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla

from tanksynth.analysis.linearize import discretize_zoh
from tanksynth.design.decentralized.validation import (checked_matrix, positive_definite,
                                                       positive_semidefinite)
from tanksynth.design.matrices import symmetrized
from tanksynth.errors import DimensionError, RegionError, SpecError
from tanksynth.plants.base import Plant

__all__ = [
    "DiscreteModel",
    "own_tank_pattern",
    "equicorrelated_intensity",
    "discretize_noise",
    "lower_tank_equilibrium",
    "linear_model",
    "window_models",
]


# ============================================================ sparsity patterns
def own_tank_pattern(plant: Plant) -> np.ndarray:
    """Sparsity pattern "own tank": state ``i`` uses only the outputs measuring it alone.

    ``E[i, j] = 1`` when output ``j`` depends on state ``i`` only (its row of
    ``dh/dx`` has a single nonzero entry, in column ``i``), at a point inside
    the operating region. For the N-tank network (``y = h``) this is the
    identity (each tank runs a local filter on its own level, DECENTER's
    ``E = I``).

    Parameters
    ----------
    plant : Plant

    Returns
    -------
    ndarray of float, shape (n, q)
        0/1 pattern.

    Raises
    ------
    DimensionError
        A state is measured by no output of its own: it would have no free
        gain entry (name the states; give ``E`` explicitly instead).
    """
    lo = np.array([b[0] for b in plant.region.bounds], dtype=float)
    hi = np.array([b[1] for b in plant.region.bounds], dtype=float)
    mid = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi),
                   np.where(np.isfinite(lo), lo + 1.0, np.where(np.isfinite(hi), hi - 1.0, 0.0)))
    H = np.asarray(plant.compiled.jac_h(mid), dtype=float).reshape(plant.q, plant.n)
    E = np.zeros((plant.n, plant.q))
    for j in range(plant.q):
        nz = np.flatnonzero(H[j] != 0)
        if len(nz) == 1:
            E[nz[0], j] = 1.0
    missing = [plant.states[i].name for i in range(plant.n) if not E[i].any()]
    if missing:
        raise DimensionError("E = 'own_tank' needs every state measured by an output of its own; "
                             f"no output measures {', '.join(missing)} alone, so these states would "
                             "have no free gain entry: give E explicitly")
    return E


# ============================================================ noise and models
def equicorrelated_intensity(n: int, intensity: float, correlation: float = 0.0) -> np.ndarray:
    """Dense process-noise intensity ``q ((1 - rho) I + rho 1 1')``.

    Parameters
    ----------
    n : int
        Number of states.
    intensity : float
        Diagonal ``q`` (squared state unit per s), ``q >= 0``.
    correlation : float
        Correlation ``rho`` between any two states' noises, ``0 <= rho < 1``
        (positive definite for ``q > 0``).

    Returns
    -------
    ndarray, shape (n, n)
        Intensity ``Qc`` (squared state unit per s).

    Raises
    ------
    DimensionError
        ``n`` not a positive integer.
    SpecError
        ``q < 0`` or ``rho`` outside [0, 1).
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise DimensionError(f"n must be a positive integer, got {n!r}")
    q, rho = float(intensity), float(correlation)
    if not (np.isfinite(q) and q >= 0):
        raise SpecError(f"process-noise intensity must be >= 0, got {intensity!r}", key="process_noise")
    if not (np.isfinite(rho) and 0 <= rho < 1):
        raise SpecError(f"correlation must be in [0, 1), got {correlation!r}",
                        key="process_noise_correlation")
    return q * ((1 - rho) * np.eye(n) + rho * np.ones((n, n)))


def discretize_noise(F: Any, Qc: Any, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of ``dx = F x dt + dw``, ``E[dw dw'] = Qc dt`` (Van Loan, 1978).

    ``Q_d = int_0^ts exp(F s) Qc exp(F' s) ds``, read off one matrix
    exponential of ``[[-F, Qc], [0, F']] ts``: with ``[[., G12], [0, G22]]``
    the result, ``A_d = G22'`` and ``Q_d = A_d G12`` (symmetrised).

    Parameters
    ----------
    F : array_like, shape (n, n)
        Continuous-time state matrix (1/s).
    Qc : array_like, shape (n, n)
        Process-noise intensity, positive semidefinite (squared state unit
        per s); for noise entering through ``G`` pass ``G Qc G'``.
    ts : float
        Sampling period (s), > 0.

    Returns
    -------
    A_d : ndarray, shape (n, n)
        ``exp(F ts)``.
    Q_d : ndarray, shape (n, n)
        Discrete process-noise covariance (squared state unit).
    """
    F = checked_matrix(F, "F")
    n = F.shape[0]
    if F.shape != (n, n):
        raise DimensionError(f"F must be square, got shape {F.shape}")
    Qc = positive_semidefinite(checked_matrix(Qc, "Qc", (n, n)), "Qc")
    if isinstance(ts, bool) or not isinstance(ts, (int, float)) or not (np.isfinite(ts) and ts > 0):
        raise SpecError(f"sampling period must be a positive number of seconds, got {ts!r}",
                        key="sampling.ts")
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = Qc
    M[n:, n:] = F.T
    G = sla.expm(M * ts)
    Ad = G[n:, n:].T
    return Ad, symmetrized(Ad @ G[:n, n:])


@dataclass(frozen=True, eq=False)
class DiscreteModel:
    """Discrete affine model about a linearisation point.

    ``x(k+1) = x_lin + A (x(k) - x_lin) + B (u(k) - u_lin) + d + w``,
    ``y(k) = y_lin + C (x(k) - x_lin) + v``.

    Attributes
    ----------
    A : ndarray, shape (n, n)
        ``exp(F ts)``.
    B : ndarray, shape (n, m)
        ZOH input matrix (state unit per input unit).
    C : ndarray, shape (o, n)
        Output Jacobian.
    Q : ndarray, shape (n, n)
        Van Loan process-noise covariance (squared state unit).
    R : ndarray, shape (o, o)
        Measurement-noise covariance (squared output unit).
    x_lin, u_lin, y_lin : ndarray
        Linearisation point and its output.
    d : ndarray, shape (n,)
        ZOH integral of ``f(x_lin, u_lin)`` (zero at an equilibrium).
    ts : float
        Sampling period (s).
    scheme : str
        ``"lower_tank_equilibrium"`` or ``"jacobian"``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    x_lin: np.ndarray
    u_lin: np.ndarray
    y_lin: np.ndarray
    d: np.ndarray
    ts: float
    scheme: str

    def predict(self, x: Any, u: Any) -> np.ndarray:
        """One-step prediction of the mean (state unit).

        Parameters
        ----------
        x : array_like, shape (n,)
            State (state unit).
        u : array_like, shape (m,)
            Input held over the period (input unit).
        """
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        return self.x_lin + self.A @ (x - self.x_lin) + self.B @ (u - self.u_lin) + self.d

    def output(self, x: Any) -> np.ndarray:
        """Predicted output at ``x`` (output unit).

        Parameters
        ----------
        x : array_like, shape (n,)
            State (state unit).
        """
        return self.y_lin + self.C @ (np.asarray(x, dtype=float) - self.x_lin)


def _is_tank_network(plant: Plant) -> bool:
    return plant.name == "tank_network" and plant.option("N") is not None


def lower_tank_equilibrium(plant: Plant, lower_levels: Any) -> tuple[np.ndarray, np.ndarray]:
    """Equilibrium of the N-tank network for given lower-tank levels.

    With ``s_i = sqrt(2 g h_i)``, the balances of the network are linear in
    the pump commands: lower tank ``i`` needs ``a_i s_i = (1 - gamma_p) k_p
    u_p + gamma_i k_i u_i`` (``p`` the pump feeding the upper tank that
    drains into ``i``), which fixes ``u``; each upper tank then sits at
    ``h = ((1 - gamma_p) k_p u_p / a)^2 / (2 g)``. DECENTER's
    ``computeEquilibriumLevels``, derived from the model rather than from
    its symbolic-toolbox tables.

    Parameters
    ----------
    plant : Plant
        A `tank_network` plant (any parameter set).
    lower_levels : array_like, shape (N/2,)
        Levels of tanks 1..N/2 (cm), > 0.

    Returns
    -------
    x_eq : ndarray, shape (N,)
        Levels (cm).
    u_eq : ndarray, shape (N/2,)
        Pump commands (V).

    Raises
    ------
    SpecError
        The plant is not a tank network.
    RegionError
        Non-positive lower levels, or levels that no nonnegative pump
        commands hold.
    """
    if not _is_tank_network(plant):
        raise SpecError(f"lower_tank_equilibrium needs a tank_network plant, got '{plant.name}'",
                        key="plant.model")
    N = plant.n
    half = N // 2
    hl = np.asarray(lower_levels, dtype=float).reshape(-1)
    if hl.size != half:
        raise DimensionError(f"lower_levels has {hl.size} entries, expected N/2 = {half}")
    if not np.all(np.isfinite(hl)) or np.any(hl <= 0):
        raise RegionError(f"lower-tank levels must be positive, got {hl.tolist()}",
                          key="lower_levels")
    val = {p.name: p.value for p in plant.parameters}
    g = val["g"]
    a = np.array([val[f"a{i}"] for i in range(1, N + 1)])
    gam = np.array([val[f"gamma{j}"] for j in range(1, half + 1)])
    kp = np.array([val[f"k{j}"] for j in range(1, half + 1)])
    # pump feeding upper tank half+i (0-based i): pump half-1 for i = 0, else i-1
    feeder = np.array([half - 1] + list(range(half - 1)))
    M = np.diag(gam * kp)
    M[np.arange(half), feeder] += (1 - gam[feeder]) * kp[feeder]
    u = np.linalg.solve(M, a[:half] * np.sqrt(2 * g * hl))
    upper_flow = (1 - gam[feeder]) * kp[feeder] * u[feeder]
    if np.any(u < 0) or np.any(upper_flow < 0):
        raise RegionError(f"no equilibrium with nonnegative pump commands holds the lower tanks at "
                          f"{np.round(hl, 4).tolist()} cm (pumps would need {np.round(u, 4).tolist()} V)",
                          key="lower_levels")
    hu = (upper_flow / a[half:]) ** 2 / (2 * g)
    return np.concatenate([hl, hu]), u


def linear_model(plant: Plant, x: Any, u: Any, ts: float, Qc: Any, R: Any, *,
                 scheme: str = "auto") -> DiscreteModel:
    """Discrete affine model of a plant about ``x`` (ZOH, Van Loan noise).

    Parameters
    ----------
    plant : Plant
    x : array_like, shape (n,)
        Current (estimated or predicted) state (state unit).
    u : array_like, shape (m,)
        Current input (input unit); used by the ``"jacobian"`` scheme.
    ts : float
        Sampling period (s).
    Qc : array_like, shape (n, n)
        Process-noise intensity (squared state unit per s).
    R : array_like, shape (o, o)
        Measurement-noise covariance (squared output unit).
    scheme : {"auto", "lower_tank_equilibrium", "jacobian"}
        ``"lower_tank_equilibrium"``: DECENTER's ``getDiscreteDynamics``,
        linearise at the equilibrium whose lower-tank levels are those of
        ``x`` (`lower_tank_equilibrium`; tank network only, ``d = 0``).
        ``"jacobian"``: linearise at ``(x, u)`` itself, the drift
        ``f(x, u)`` kept as the ZOH offset ``d``. ``"auto"`` picks the first
        for a tank network, the second otherwise.

    Returns
    -------
    DiscreteModel

    Raises
    ------
    DimensionError, SpecError, RegionError
        Bad shapes, bad ``ts``/noise matrices, a point where the model is
        not differentiable (e.g. an empty tank under Torricelli's law).
    """
    if scheme not in ("auto", "lower_tank_equilibrium", "jacobian"):
        raise SpecError(f"scheme must be 'auto', 'lower_tank_equilibrium' or 'jacobian', got "
                        f"{scheme!r}", key="scheme")
    if scheme == "auto":
        scheme = "lower_tank_equilibrium" if _is_tank_network(plant) else "jacobian"
    xv = np.asarray(x, dtype=float).reshape(-1)
    uv = np.asarray(u, dtype=float).reshape(-1)
    if xv.size != plant.n or uv.size != plant.m:
        raise DimensionError(f"x has {xv.size} entries and u {uv.size}, expected {plant.n} and "
                             f"{plant.m}")
    comp = plant.compiled
    if scheme == "lower_tank_equilibrium":
        x_lin, u_lin = lower_tank_equilibrium(plant, xv[: plant.n // 2])
    else:
        x_lin, u_lin = xv, uv
    F, B = comp.jacobians(x_lin[None], u_lin[None])
    F, B = F[0], B[0]
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(B))):
        raise RegionError(f"the model is not differentiable at {np.round(x_lin, 6).tolist()} "
                          "(an empty tank?)", key="x")
    f0 = np.zeros(plant.n) if scheme == "lower_tank_equilibrium" else comp.rhs(x_lin[None], u_lin[None])[0]
    Ad, BD = discretize_zoh(F, np.column_stack([B, f0]), ts)
    _, Qd = discretize_noise(F, Qc, ts)
    C = np.asarray(comp.jac_h(x_lin), dtype=float).reshape(plant.q, plant.n)
    y_lin = np.asarray(comp.h(x_lin), dtype=float).reshape(-1)
    Rm = positive_definite(checked_matrix(R, "R", (plant.q, plant.q)), "R")
    return DiscreteModel(Ad, BD[:, : plant.m], C, Qd, Rm, x_lin, u_lin, y_lin, BD[:, plant.m],
                         float(ts), scheme)


def window_models(plant: Plant, x_start: Any, inputs: Any, ts: float, Qc: Any, R: Any, *,
                  relinearize_every: int = 10, scheme: str = "auto"
                  ) -> tuple[list[DiscreteModel], np.ndarray]:
    """Models along the trajectory predicted from ``x_start`` (DECENTER's FH window).

    ``model_k`` is linearised at the predicted ``x(k)`` when ``k`` is a
    multiple of ``relinearize_every`` and repeated otherwise; ``x(k+1) =
    model_k.predict(x(k), u(k))``.

    Parameters
    ----------
    plant : Plant
    x_start : array_like, shape (n,)
        State at step 0 (state unit), e.g. the last filtered estimate.
    inputs : array_like, shape (T, m)
        ``u(0) .. u(T-1)`` (input unit), ``u(k)`` held over ``[k, k+1)``.
    ts : float
        Sampling period (s).
    Qc, R : array_like
        Process-noise intensity (squared state unit per s) and
        measurement-noise covariance (squared output unit).
    relinearize_every : int
        Steps between linearisations (DECENTER's ``dTlin``), >= 1.
    scheme : str
        See `linear_model`.

    Returns
    -------
    models : list of DiscreteModel, length T
    x_pred : ndarray, shape (T + 1, n)
        Predicted states ``x(0) .. x(T)``.
    """
    if (isinstance(relinearize_every, bool) or not isinstance(relinearize_every, (int, np.integer))
            or relinearize_every < 1):
        raise SpecError(f"relinearize_every must be an integer >= 1, got {relinearize_every!r}",
                        key="relinearize_every")
    U = np.asarray(inputs, dtype=float)
    if U.ndim != 2 or U.shape[1] != plant.m or U.shape[0] < 1:
        raise DimensionError(f"inputs must have shape (T, m) with T >= 1 and m = {plant.m}, got "
                             f"{U.shape}")
    x = np.asarray(x_start, dtype=float).reshape(-1)
    if x.size != plant.n:
        raise DimensionError(f"x_start has {x.size} entries, expected {plant.n}")
    models: list[DiscreteModel] = []
    xs = [x]
    for k in range(U.shape[0]):
        if k % relinearize_every == 0:
            model = linear_model(plant, xs[-1], U[k], ts, Qc, R, scheme=scheme)
        models.append(model)
        xs.append(model.predict(xs[-1], U[k]))
    return models, np.array(xs)
