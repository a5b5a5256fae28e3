"""Spec design method ``decentralized_kalman`` (seed 003, DECENTER).

A ``[[design]]`` table with ``method = "decentralized_kalman"`` designs the
decentralised Kalman gains of one window of ``window`` steps, starting at the
spec's operating point:

* the models come from `tanksynth.design.decentralized.gains.window_models`:
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
key already names the design method). The options, their defaults and units
are those of `tanksynth.spec.method_options.DecentralizedKalmanOptions`.

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

import warnings

import numpy as np

from tanksynth.analysis.blas import small_dense
from tanksynth.design.decentralized.gains import (centralized_gain, equicorrelated_intensity,
                                            finite_horizon_gains, one_step_gains, own_tank_pattern,
                                            window_models)
from tanksynth.design.matrices import symmetrized
from tanksynth.design.operating_point import equilibrium_at, sampling_period
from tanksynth.design.result import DesignMethod, DesignResult, options_of
from tanksynth.errors import DesignWarning, DimensionError, InfeasibleDesign, SpecError
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.method_options import DecentralizedKalmanOptions

__all__ = ["run_decentralized_kalman", "DECENTRALIZED_KALMAN"]


def _covariance(value: float | np.ndarray, size: int) -> np.ndarray:
    """A validated noise option as a matrix (a number is times the identity)."""
    return np.array(value, dtype=float) if isinstance(value, np.ndarray) else value * np.eye(size)


def run_decentralized_kalman(spec: Spec, design: DesignSpec) -> DesignResult:
    """Decentralised (sparse) Kalman gains over one window at the operating point.

    Parameters
    ----------
    spec : Spec
        Validated spec: plant, operating point ``x0`` (state units) and
        ``[sampling] ts`` (s).
    design : DesignSpec
        The ``[[design]]`` entry; its options
        (`tanksynth.spec.method_options.DecentralizedKalmanOptions`) were
        validated when the spec was parsed.

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
    # n x n products, factorisations and expm all through: one BLAS thread (at n = 128 OpenBLAS's
    # threads made each 128 x 128 Cholesky of the reference costs ~60 ms of waiting on the loaded
    # 2-core machine, 25 s of CPU for the design; issue 15)
    with small_dense():
        return _decentralized_kalman(spec, design)


def _decentralized_kalman(spec: Spec, design: DesignSpec) -> DesignResult:
    """`run_decentralized_kalman` (under one BLAS thread)."""
    plant = spec.plant
    ts = sampling_period(spec)
    o = options_of(design, spec, DecentralizedKalmanOptions)
    method, T, max_iter, relin, tol = (o.algorithm, o.window, o.max_iter, o.relinearize_every,
                                       o.tolerance)
    if isinstance(o.E, str):
        try:
            E = own_tank_pattern(plant)
        except DimensionError as exc:
            raise SpecError(str(exc), key=f"{design.key}.E") from None
    else:
        E = np.array(o.E)
    rho = o.process_noise_correlation
    if isinstance(o.process_noise, np.ndarray):
        Qc = np.array(o.process_noise)
    else:
        Qc = equicorrelated_intensity(plant.n, o.process_noise, rho)
    R = _covariance(o.measurement_noise, plant.q)
    P00 = _covariance(o.initial_covariance, plant.n)

    eq = equilibrium_at(plant, spec.x0, spec.given_u0)
    u = eq.u0 if o.input is None else np.array(o.input)
    models, x_pred = window_models(plant, spec.x0, np.tile(u, (T + 1, 1)), ts, Qc, R,
                                   relinearize_every=relin)
    A = [m.A for m in models[1:]]
    C = [m.C for m in models[1:]]
    Q = [m.Q for m in models[1:]]
    Rs = [m.R for m in models[1:]]
    P0_pred = symmetrized(models[0].A @ P00 @ models[0].A.T + models[0].Q)

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
        history: tuple[float, ...] = (cost_os,)
        cost, iterations, converged, status = cost_os, 0, True, "one_step"
    else:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = finite_horizon_gains(A, C, Q, Rs, E, P0_pred, method=method, tol=tol,
                                       max_iter=max_iter)
        for w in caught:  # non-convergence is about this design: say so as a design warning
            category = DesignWarning if issubclass(w.category, RuntimeWarning) else w.category
            warnings.warn(str(w.message), category, stacklevel=3)
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


DECENTRALIZED_KALMAN = DesignMethod("decentralized_kalman", run_decentralized_kalman,
                                    DecentralizedKalmanOptions)
