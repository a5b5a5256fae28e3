"""Spec design method ``decentralized_kalman`` (seed 003, DECENTER).

A ``[[design]]`` table with ``method = "decentralized_kalman"`` designs the
decentralised Kalman gains of one window of ``window`` steps, starting at the
spec's operating point:

* the models come from `tanksynth.design.decentralized.window_models`:
  ``input`` (default: the operating point's equilibrium input) is held over
  the window, the trajectory it predicts from ``x0`` is relinearised every
  ``relinearize_every`` steps (for the N-tank network at the equilibrium of
  the predicted lower-tank levels, DECENTER's scheme), ZOH with
  ``[sampling] ts`` and Van Loan process noise;
* ``P(1|0) = A_0 P(0|0) A_0' + Q_0`` with ``P(0|0) = initial_covariance``;
* the gains ``K(1) .. K(T)`` come from `finite_horizon_gains` (``algorithm
  = "casadi"`` or ``"iterative"``) or `one_step_gains` step by step
  (``algorithm = "one_step"``).

The route is chosen by ``algorithm`` (the ``[[design]]`` table's ``method``
key already names the design method).

Options
-------
=============================  ===============================================
``algorithm``                  ``"casadi"`` (default), ``"iterative"``,
                               ``"one_step"``
``window``                     steps ``T >= 1`` (default 40)
``E``                          ``"own_tank"`` (default: each state uses the
                               outputs measuring it alone) or an explicit
                               n x q matrix of 0/1
``tolerance``                  relative tolerance (default 1e-6)
``max_iter``                   iteration limit (default 100)
``process_noise``              required: intensity ``Qc`` (squared state unit
                               per s), a number ``q`` or an n x n matrix
``process_noise_correlation``  ``rho`` in [0, 1) for a number ``q``: ``Qc = q
                               ((1 - rho) I + rho 1 1')`` (default 0)
``measurement_noise``          ``R`` (squared output unit), a number (times
                               I) or a q x q matrix (default 1)
``initial_covariance``         ``P(0|0)`` (squared state unit), a number
                               (times I) or an n x n matrix (default 10)
``input``                      input held over the window (input units),
                               default the equilibrium input
``relinearize_every``          steps between linearisations (default 10)
=============================  ===============================================

Artefact gains (every one a 1-D or 2-D float array, so that the JSON, .npz,
.mat and C-header exports all take them):

* ``K_0 .. K_{T-1}``: ``K_j`` is the gain of window step ``j + 1`` (state
  unit per output unit), ``xhat(j+1|j+1) = xhat(j+1|j) + K_j (y(j+1) -
  yhat(j+1|j))``; entries outside ``E`` are exactly 0;
* ``E`` (n x q, 0/1), ``P0_pred`` (``P(1|0)``, n x n), ``P_diag`` (T x n,
  the diagonals of ``P(k|k)``: variances of the estimation errors, squared
  state unit), ``x_pred`` ((T+1) x n, the predicted trajectory the models
  were linearised along).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError
from tanksynth.design.decentralized import (centralized_gain, equicorrelated_intensity, finite_horizon_gains,
                            one_step_gains, own_tank_pattern, window_models)
from tanksynth.analysis.linearize import equilibrium_input
from tanksynth.design.result import DesignMethod, DesignResult

__all__ = ["run_decentralized_kalman", "DECENTRALIZED_METHODS"]

#: Values of the ``algorithm`` option.
DECENTRALIZED_METHODS = ("casadi", "iterative", "one_step")

_NUM = (int, float)


def _key(design: Any, opt: str) -> str:
    return f"{design.key}.{opt}"


def _number(value: Any, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, _NUM):
        raise SpecError(f"expected a number, got {type(value).__name__} {value!r}", key=key)
    out = float(value)
    if not np.isfinite(out):
        raise SpecError(f"expected a finite number, got {value!r}", key=key)
    return out


def _matrix(value: Any, key: str, shape: tuple[int, int]) -> np.ndarray:
    if not isinstance(value, list) or not value or not all(isinstance(r, list) for r in value):
        raise SpecError(f"expected a number or a {shape[0]} x {shape[1]} matrix (a list of rows)",
                        key=key)
    rows = [[_number(v, f"{key}[{i}][{j}]") for j, v in enumerate(r)] for i, r in enumerate(value)]
    if len(rows) != shape[0] or any(len(r) != shape[1] for r in rows):
        raise SpecError(f"expected a {shape[0]} x {shape[1]} matrix, got {len(rows)} rows of "
                        f"lengths {sorted({len(r) for r in rows})}", key=key)
    return np.array(rows, dtype=float)


def _covariance(design: Any, opt: str, default: float | None, size: int, *, allow_zero: bool,
                what: str) -> np.ndarray:
    key = _key(design, opt)
    value = design.options.get(opt, default)
    if isinstance(value, list):
        M = _matrix(value, key, (size, size))
        if np.max(np.abs(M - M.T)) > 1e-12 * max(1.0, np.max(np.abs(M))):
            raise SpecError(f"{what} must be symmetric", key=key)
        low = float(np.linalg.eigvalsh(0.5 * (M + M.T))[0])
        if low < 0 or (not allow_zero and low <= 0):
            raise SpecError(f"{what} must be positive {'semi' if allow_zero else ''}definite "
                            f"(smallest eigenvalue {low:.3g})", key=key)
        return 0.5 * (M + M.T)
    v = _number(value, key)
    if v < 0 or (not allow_zero and v <= 0):
        raise SpecError(f"{what} must be {'>= 0' if allow_zero else '> 0'}, got {v}", key=key)
    return v * np.eye(size)


def _positive_int(design: Any, opt: str, default: int) -> int:
    value = design.options.get(opt, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise SpecError(f"expected an integer >= 1, got {value!r}", key=_key(design, opt))
    return value


def _pattern(design: Any, plant: Any) -> np.ndarray:
    key = _key(design, "E")
    value = design.options.get("E", "own_tank")
    if isinstance(value, str):
        if value not in ("own_tank", "own tank"):
            raise SpecError(f"expected \"own_tank\" or an explicit {plant.n} x {plant.q} matrix of "
                            f"0/1, got {value!r}", key=key)
        try:
            return own_tank_pattern(plant)
        except DimensionError as exc:
            raise SpecError(str(exc), key=key) from None
    E = _matrix(value, key, (plant.n, plant.q))
    if not np.all((E == 0) | (E == 1)):
        raise SpecError("E entries must be 0 (gain entry fixed at 0) or 1 (free)", key=key)
    if not E.any():
        raise SpecError("E has no free entry: every gain would be 0", key=key)
    return E


def run_decentralized_kalman(spec: Any, design: Any) -> DesignResult:
    """Decentralised (sparse) Kalman gains over one window at the operating point.

    Parameters
    ----------
    spec : Spec
        Validated spec: plant, operating point ``x0`` (state units) and
        ``[sampling] ts`` (s).
    design : DesignSpec
        The ``[[design]]`` entry (options in the module docstring).

    Returns
    -------
    DesignResult
        Gains ``K_0 .. K_{T-1}``, ``E``, ``P0_pred``, ``P_diag``, ``x_pred``;
        diagnostics with the costs of the one-step, finite-horizon and
        centralised gains on the same window, convergence and the noise
        declarations.

    Raises
    ------
    SpecError
        Invalid option values (the key names the option).
    InfeasibleDesign
        A covariance lost positive definiteness.
    """
    plant = spec.plant
    ts = spec.ts
    o = design.options
    method = o.get("algorithm", "casadi")
    if method not in DECENTRALIZED_METHODS:
        raise SpecError(f"expected one of {list(DECENTRALIZED_METHODS)}, got {method!r}",
                        key=_key(design, "algorithm"))
    T = _positive_int(design, "window", 40)
    max_iter = _positive_int(design, "max_iter", 100)
    relin = _positive_int(design, "relinearize_every", 10)
    tol = _number(o.get("tolerance", 1e-6), _key(design, "tolerance"))
    if not tol > 0:
        raise SpecError(f"expected a number > 0, got {tol}", key=_key(design, "tolerance"))
    E = _pattern(design, plant)

    qkey = _key(design, "process_noise")
    rho = _number(o.get("process_noise_correlation", 0.0), _key(design, "process_noise_correlation"))
    if isinstance(o.get("process_noise"), list):
        if "process_noise_correlation" in o:
            raise SpecError("process_noise_correlation only applies to a scalar process_noise",
                            key=_key(design, "process_noise_correlation"))
        Qc = _covariance(design, "process_noise", None, plant.n, allow_zero=True,
                         what="process_noise")
    else:
        q = _number(o.get("process_noise"), qkey)
        if q < 0:
            raise SpecError(f"process_noise must be >= 0, got {q}", key=qkey)
        if not 0 <= rho < 1:
            raise SpecError(f"expected a correlation in [0, 1), got {rho}",
                            key=_key(design, "process_noise_correlation"))
        Qc = equicorrelated_intensity(plant.n, q, rho)
    R = _covariance(design, "measurement_noise", 1.0, plant.q, allow_zero=False,
                    what="measurement_noise")
    P00 = _covariance(design, "initial_covariance", 10.0, plant.n, allow_zero=False,
                      what="initial_covariance")

    eq = equilibrium_input(plant, spec.x0, spec.given_u0)
    if "input" in o:
        ukey = _key(design, "input")
        raw = o["input"]
        if not isinstance(raw, list) or len(raw) != plant.m:
            raise SpecError(f"expected a list of {plant.m} inputs "
                            f"({', '.join(s.name for s in plant.inputs)})", key=ukey)
        u = np.array([_number(v, f"{ukey}[{i}]") for i, v in enumerate(raw)])
    else:
        u = eq.u0
    models, x_pred = window_models(plant, spec.x0, np.tile(u, (T + 1, 1)), ts, Qc, R,
                                   relinearize_every=relin)
    A = [m.A for m in models[1:]]
    C = [m.C for m in models[1:]]
    Q = [m.Q for m in models[1:]]
    Rs = [m.R for m in models[1:]]
    P0_pred = models[0].A @ P00 @ models[0].A.T + models[0].Q
    P0_pred = 0.5 * (P0_pred + P0_pred.T)

    # Reference costs on the same window: one-step and centralised gains.
    K_os, P_os = [], []
    Pp = P0_pred
    for k in range(T):
        st = one_step_gains(A[k], C[k], Q[k], Rs[k], E, Pp)
        K_os.append(st.K)
        P_os.append(st.P_filt)
        Pp = st.P_pred_next
    cost_os = float(sum(np.trace(P) for P in P_os))
    cost_c = 0.0
    Pp = P0_pred
    for k in range(T):
        st = centralized_gain(A[k], C[k], Q[k], Rs[k], Pp)
        cost_c += st.cost
        Pp = st.P_pred_next

    if method == "one_step":
        K, P = K_os, P_os
        cost, iterations, converged, status, history = cost_os, 0, True, "one_step", (cost_os,)
    else:
        res = finite_horizon_gains(A, C, Q, Rs, E, P0_pred, method=method, tol=tol,
                                   max_iter=max_iter)
        K, P = res.K, res.P
        cost, iterations, converged, status = res.cost, res.iterations, res.converged, res.status
        history = res.history
    mask = E != 0
    if any(np.any(k_[~mask] != 0) for k_ in K):  # pragma: no cover - guarded by construction
        raise InfeasibleDesign("a gain has a nonzero entry outside the sparsity pattern E")

    gains: dict[str, np.ndarray] = {f"K_{j}": K[j] for j in range(T)}
    gains.update({"E": E.astype(float), "P0_pred": P0_pred,
                  "P_diag": np.array([np.diag(Pk) for Pk in P]), "x_pred": x_pred[: T + 1]})
    diagnostics = {
        "algorithm": method,
        "window": T,
        "gain_layout": ("K_j is the gain of window step j+1 (j = 0..T-1), shape (n, q); "
                        "P(1|0) = P0_pred; P_diag[j] = diag P(j+1|j+1)"),
        "cost": cost,
        "one_step_cost": cost_os,
        "centralized_cost": cost_c,
        "improvement_over_one_step": (cost_os - cost) / cost_os,
        "gap_to_centralized": (cost - cost_c) / cost_c,
        "converged": converged,
        "iterations": iterations,
        "status": status,
        "cost_history": list(history),
        "tolerance": tol,
        "max_iter": max_iter,
        "free_entries": int(mask.sum()),
        "masked_entries_exactly_zero": True,
        "E": E.tolist(),
        "ts": ts,
        "relinearize_every": relin,
        "linearization_scheme": models[0].scheme,
        "input": u.tolist(),
        "equilibrium_input": eq.u0.tolist(),
        "noise": {
            "process_noise_intensity": Qc.tolist() if plant.n <= 8 else
            {"diagonal": float(Qc[0, 0]), "correlation": rho},
            "measurement_noise": np.diag(R).tolist(),
            "initial_covariance_trace": float(np.trace(P00)),
            "discretisation": "Van Loan (exact for white noise of intensity Qc held over ts)",
        },
        "assumptions": [
            "process noise: continuous white noise of intensity Qc, discretised exactly (Van "
            "Loan) at every linearisation; the seed does not publish DECENTER's dense Q",
            "the window's models follow the trajectory predicted from the operating point under "
            "the window input (DECENTER's 'propagated' finite-horizon scheme)",
            *[a.text for a in plant.assumptions],
        ],
    }
    latex = {
        "costs": ("\\begin{tabular}{lr}\\hline gains & $\\sum_k \\mathrm{tr}\\,P(k|k)$\\\\\\hline "
                  f"centralised & {cost_c:.6g}\\\\ one-step & {cost_os:.6g}\\\\ "
                  f"{'finite-horizon' if method != 'one_step' else 'selected'} & {cost:.6g}\\\\"
                  "\\hline\\end{tabular}"),
    }
    return DesignResult(design.name, "decentralized_kalman", plant.name, gains, diagnostics, latex)


DECENTRALIZED_KALMAN = DesignMethod("decentralized_kalman", run_decentralized_kalman, options={
    "algorithm": (str, "casadi"),
    "window": (int, 40),
    "E": ((str, list), "own_tank"),
    "tolerance": (_NUM, 1e-6),
    "max_iter": (int, 100),
    "process_noise": ((int, float, list), None),
    "process_noise_correlation": (_NUM, 0.0),
    "measurement_noise": ((int, float, list), 1.0),
    "initial_covariance": ((int, float, list), 10.0),
    "input": (list, None),
    "relinearize_every": (int, 10),
}, required=("process_noise",), needs_sampling=True)
