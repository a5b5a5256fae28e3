"""State-space interop and system norms: python-control ``StateSpace`` in, numpy out.

`statespace_matrices`
    ``(A, B, C, D, dt)`` from a `control.StateSpace` or from matrices: every
    matrix-level function of the synthesis designs accepts either.
`h2_norm`
    from the controllability Gramian (Lyapunov or Stein equation).
`hinf_norm`, `hinf_below`
    H-infinity norm by bisection on the Hamiltonian test (discrete-time
    systems through the bilinear map ``z = (1 + s) / (1 - s)``, which keeps
    the norm).
`to_statespace`
    a `control.StateSpace` with names and ``dt`` from matrices.
`model_names`
    the artefact gain names of a linear model's matrices in a time domain
    (the naming rule: ``F, B, Bw`` continuous, ``Ad, Bd, Bwd`` discrete).
`GAIN_NAMES`, `undocumented_gains`
    the one table of every artefact gain name (docs/artefacts.md) and its check.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import scipy.linalg as sla

from tanksynth.errors import DimensionError

__all__ = ["statespace_matrices", "to_statespace", "h2_norm", "hinf_norm", "hinf_below",
           "MODEL_NAMES", "model_names", "GAIN_NAMES", "undocumented_gains"]

#: Artefact gain names of a linear model ``x' = A x + B u + Bw w`` (continuous time) or
#: ``x[k+1] = A x[k] + B u[k] + Bw w[k]`` (discrete time), by time domain. ``C`` is ``C`` in
#: both. An operating point is ``x_op, u_op``; an estimator's initial estimate ``x_hat0``.
MODEL_NAMES: dict[str, dict[str, str]] = {
    "continuous": {"A": "F", "B": "B", "Bw": "Bw", "C": "C"},
    "discrete": {"A": "Ad", "B": "Bd", "Bw": "Bwd", "C": "C"},
}


def _mat(value: Any, name: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    try:
        arr = np.atleast_2d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a real matrix") from None
    if arr.ndim != 2 or not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be a finite 2-D matrix")
    if (rows is not None and arr.shape[0] != rows) or (cols is not None and arr.shape[1] != cols):
        raise DimensionError(f"{name} has shape {arr.shape}, expected ({rows if rows is not None else '*'}, "
                             f"{cols if cols is not None else '*'})")
    return arr


def to_statespace(A: Any, B: Any, C: Any, D: Any = None, dt: float | None = None, *,
                  states: Sequence[str] | None = None, inputs: Sequence[str] | None = None,
                  outputs: Sequence[str] | None = None, name: str | None = None) -> Any:
    """A `control.StateSpace` from matrices, with signal names and sampling period.

    Parameters
    ----------
    A, B, C : array_like
    D : array_like, optional
        Zeros by default.
    dt : float, optional
        Sampling period (s); None (or 0) for continuous time.
    states, inputs, outputs : sequence of str, optional
        Signal names (python-control ``states``, ``inputs``, ``outputs``).
    name : str, optional
        System name.

    Returns
    -------
    control.StateSpace
    """
    import control

    A, B, C, D, _ = statespace_matrices(A, B, C, D)
    kw: dict[str, Any] = {}
    for key, value in (("states", states), ("inputs", inputs), ("outputs", outputs), ("name", name)):
        if value is not None:
            kw[key] = list(value) if key != "name" else str(value)
    return control.ss(A, B, C, D, 0 if dt is None else float(dt), **kw)


def statespace_matrices(sys_or_A: Any, B: Any = None, C: Any = None, D: Any = None,
                        dt: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                          np.ndarray, float | None]:
    """``(A, B, C, D, dt)`` from a `control.StateSpace` or from matrices.

    Parameters
    ----------
    sys_or_A : control.StateSpace or array_like
        A python-control state-space system (its ``dt``: 0 or None for
        continuous time, the period in s otherwise), or ``A``.
    B, C, D : array_like, optional
        With matrices: ``D`` defaults to zeros.
    dt : float, optional
        Sampling period (s) with matrices; None for continuous time.

    Returns
    -------
    tuple
        ``A, B, C, D`` as float arrays and ``dt`` (None in continuous time).
    """
    if hasattr(sys_or_A, "A") and hasattr(sys_or_A, "B") and hasattr(sys_or_A, "dt"):
        s = sys_or_A
        sdt = s.dt if s.dt not in (0, None) else None
        sdt = None if sdt is True else sdt
        return (np.asarray(s.A, float), np.asarray(s.B, float), np.asarray(s.C, float),
                np.asarray(s.D, float), None if sdt is None else float(sdt))
    A = _mat(sys_or_A, "A")
    Bm = _mat(B, "B", A.shape[0])
    Cm = _mat(C, "C", None, A.shape[0])
    Dm = np.zeros((Cm.shape[0], Bm.shape[1])) if D is None else _mat(D, "D", Cm.shape[0], Bm.shape[1])
    return A, Bm, Cm, Dm, dt


def h2_norm(sys_or_A: Any, B: Any = None, C: Any = None, D: Any = None,
            dt: float | None = None) -> float:
    """H2 norm from the controllability Gramian (inf if unstable or, continuous, ``D != 0``).

    Parameters
    ----------
    sys_or_A : control.StateSpace or array_like
        See `statespace_matrices`.
    B, C, D : array_like, optional
    dt : float, optional
        Sampling period (s); None for continuous time.

    Returns
    -------
    float
        Output unit per input unit (times s^-1/2 in continuous time).
    """
    A, B, C, D, dt = statespace_matrices(sys_or_A, B, C, D, dt)
    eig = np.linalg.eigvals(A)
    if dt is None:
        if np.max(eig.real) >= 0 or np.any(D != 0):
            return float("inf")
        G = sla.solve_continuous_lyapunov(A, -B @ B.T)
        return float(np.sqrt(max(np.trace(C @ G @ C.T), 0.0)))
    if np.max(np.abs(eig)) >= 1:
        return float("inf")
    G = sla.solve_discrete_lyapunov(A, B @ B.T)
    return float(np.sqrt(max(np.trace(C @ G @ C.T) + np.trace(D @ D.T), 0.0)))


def _to_continuous(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray):
    """Bilinear map z = (1 + s)/(1 - s): same H-infinity norm, stable iff stable."""
    n = A.shape[0]
    Minv = np.linalg.inv(np.eye(n) + A)
    return (Minv @ (A - np.eye(n)), np.sqrt(2.0) * Minv @ B, np.sqrt(2.0) * C @ Minv,
            D - C @ Minv @ B)


def _imaginary_eigenvalue(A, B, C, D, gamma: float) -> bool:
    """True if the Hamiltonian at ``gamma`` has an eigenvalue on the imaginary axis (norm >= gamma)."""
    R = gamma ** 2 * np.eye(D.shape[1]) - D.T @ D
    if np.min(np.linalg.eigvalsh(R)) <= 0:
        return True
    Ri = np.linalg.inv(R)
    Ab = A + B @ Ri @ D.T @ C
    H = np.block([[Ab, B @ Ri @ B.T],
                  [-C.T @ (np.eye(C.shape[0]) + D @ Ri @ D.T) @ C, -Ab.T]])
    lam = np.linalg.eigvals(H)
    return bool(np.any(np.abs(lam.real) <= 1e-9 * np.maximum(1.0, np.abs(lam))))


def _continuous_form(sys_or_A, B, C, D, dt):
    A, B, C, D, dt = statespace_matrices(sys_or_A, B, C, D, dt)
    eig = np.linalg.eigvals(A)
    stable = bool(np.max(np.abs(eig)) < 1) if dt is not None else bool(np.max(eig.real) < 0)
    if dt is not None and stable:
        A, B, C, D = _to_continuous(A, B, C, D)
    return A, B, C, D, stable


def hinf_below(gamma: float, sys_or_A: Any, B: Any = None, C: Any = None, D: Any = None,
               dt: float | None = None) -> bool:
    """True if the system is stable and its H-infinity norm is below ``gamma`` (Hamiltonian test).

    Discrete-time systems are mapped by the bilinear transform (same norm).

    Parameters
    ----------
    gamma : float
        Bound to test, in output units per disturbance unit.
    sys_or_A : control.StateSpace or array_like, shape (n, n)
        The system, or its state matrix (continuous [1/s] or discrete [-]).
    B, C, D : array_like, optional
        Input, output and feedthrough matrices when ``sys_or_A`` is a matrix (``D`` defaults to zeros).
    dt : float or None, optional
        Sampling period [s] of a discrete system given by matrices; None: continuous time.
    """
    A, B, C, D, stable = _continuous_form(sys_or_A, B, C, D, dt)
    return stable and not _imaginary_eigenvalue(A, B, C, D, float(gamma))


def hinf_norm(sys_or_A: Any, B: Any = None, C: Any = None, D: Any = None,
              dt: float | None = None, rtol: float = 1e-9) -> float:
    """H-infinity norm by bisection on the Hamiltonian test (inf if unstable).

    Parameters
    ----------
    sys_or_A : control.StateSpace or array_like
        See `statespace_matrices`.
    B, C, D : array_like, optional
    dt : float, optional
        Sampling period (s); None for continuous time.
    rtol : float
        Relative width of the final bracket.

    Returns
    -------
    float
        The upper end of the bracket (output unit per input unit).
    """
    A, B, C, D, stable = _continuous_form(sys_or_A, B, C, D, dt)
    if not stable:
        return float("inf")
    lo = float(np.linalg.norm(D, 2))
    g0 = C @ np.linalg.solve(-A, B) + D
    lo = max(lo, float(np.linalg.norm(g0, 2)))
    hi = max(2.0 * lo, 1e-300)
    if hi <= 1e-300:
        hi = 1.0
    while _imaginary_eigenvalue(A, B, C, D, hi):
        lo, hi = hi, 2.0 * hi
        if not np.isfinite(hi):
            return float("inf")
    for _ in range(200):
        if hi - lo <= rtol * hi:
            break
        mid = 0.5 * (lo + hi)
        if _imaginary_eigenvalue(A, B, C, D, mid):
            lo = mid
        else:
            hi = mid
    return float(hi)




def model_names(time_domain: str) -> dict[str, str]:
    """Artefact gain names of a linear model's matrices in ``time_domain``.

    The one naming rule of the artefacts: the state matrix is ``F``
    (continuous time, 1/s) or ``Ad`` (discrete time, dimensionless), the
    input matrix ``B`` or ``Bd``, the disturbance matrix ``Bw`` or ``Bwd``;
    the output matrix is ``C`` in both.

    Parameters
    ----------
    time_domain : {"continuous", "discrete"}
        The model's time domain.

    Returns
    -------
    dict of str to str
        Role (``"A"``, ``"B"``, ``"Bw"``, ``"C"``) -> gain name.

    Raises
    ------
    ValueError
        ``time_domain`` is neither ``"continuous"`` nor ``"discrete"``.
    """
    try:
        return dict(MODEL_NAMES[time_domain])
    except (KeyError, TypeError):
        raise ValueError(f"time_domain must be 'continuous' or 'discrete', got {time_domain!r}") from None


#: The one naming table of the artefacts' gains, name(s) -> meaning; the artefacts page's
#: table is generated from it (`tanksynth.docgen`) and tests/artefacts/test_naming.py checks
#: that every gain of every example is named here. ``<k>`` stands for an index 0, 1, ...;
#: ``sp_<name>`` for any other name of the table.
GAIN_NAMES: dict[tuple[str, ...], str] = {
    ("F", "B", "C", "Bw"): "continuous-time model `x' = F x + B u + Bw w`, `y = C x` (deviations from "
                           "`x_op`, `u_op`); the Takagi-Sugeno PDC designs store their vertex matrices "
                           "as `F` (r x n x n) and `B`",
    ("Ad", "Bd", "C", "Bwd"): "discrete-time model `x[k+1] = Ad x[k] + Bd u[k] + Bwd w[k]` (ZOH at `ts`)",
    ("x_op", "u_op"): "the operating point a controller, observer or linearisation is built around "
                      "(`u_op` the equilibrium input; never `x0`, `u0`)",
    ("x_hat0",): "an estimator's initial estimate: the spec's estimator option `x0` is stored as "
                 "`x_hat0`",
    ("K",): "controller gain, `u = u_op - K (x - x_op)` (Takagi-Sugeno: one per rule, r x m x n; "
            "`feedback_linearization`: the outer-loop coefficients)",
    ("K1", "K2", "Br"): "integral action: `K = [K1 K2]` on the state and the integrators, `Br` the "
                        "reference input matrix of the augmented model",
    ("Kaw", "C1"): "`integral_tracking`: anti-windup (back-calculation) gain, the tracked outputs' "
                   "rows of `C`",
    ("K_ss", "P_ss"): "`kalman`: steady-state Kalman gain (textbook `K`) and Riccati solution",
    ("K_<k>", "E", "P0_pred", "P_diag", "x_pred"): "`decentralized_kalman`: Kalman gain of window step "
                                                   "k + 1 (n x q), its sparsity pattern `E`, "
                                                   "`P(1|0)`, the diagonals of `P(k|k)` and the "
                                                   "predicted estimates over the window",
    ("L",): "observer gain, `x_hat' = ... + L (y - C x_hat)` (Takagi-Sugeno measured premises: one per "
            "rule)",
    ("Psi", "Gamma_d", "threshold_coefficients", "threshold_rates"):
        "`fault_detection`: observer gain `Psi` (the paper's name), `Gamma_d = A - Psi C` (1/s) and "
        "the adaptive threshold's coefficients (output units) and rates (1/s)",
    ("Q", "R", "P0"): "process and measurement noise covariances, initial error covariance "
                      "(`ts_observer`, `ts_output_feedback`: `Q` is the observer LMI's Lipschitz "
                      "weighting matrix)",
    ("Q0", "q_floor", "window"): "`adaptive_kalman`: initial `Q`, its floor and the estimation window "
                                 "(samples)",
    ("G", "abc", "phi0"): "process noise input matrix (`adaptive_scaling_kalman`, "
                          "`consensus_filter`); the scaling law's `a, b, c` and initial scaling",
    ("R<k>", "C<k>"): "`consensus_filter`: sensor node k's measurement noise covariance and output rows",
    ("alpha", "beta", "kappa", "redraw"): "`ukf` sigma-point parameters and redraw flag "
                                          "(`ts_output_feedback`: `beta` weighs the observer term "
                                          "`eps' Po eps` of its Lyapunov function)",
    ("W1", "b1", "W2", "b2", "in_mean", "in_scale", "out_mean", "out_scale", "delays",
     "training_inputs", "training_targets", "ekf_Q", "ekf_R", "ekf_P0"):
        "`narx`: network weights and biases, input/output normalisation, delays, the training set "
        "and the tuning of the EKF that produced its targets",
    ("theta", "covariance", "x_init"): "`fit`: the fitted free parameters (the order of "
                                        "`diagnostics.names`, their units), their covariance and "
                                        "each experiment's fitted initial state (E x n, state units)",
    ("P",): "Lyapunov matrix, `V = x' P x` of the closed loop or `e' P e` of the observer error "
            "(`lmi_placement`, robust and Takagi-Sugeno designs)",
    ("Po",): "`ts_output_feedback`: Lyapunov matrix of the observer error",
    ("X",): "LMI variable of the H2/Hinf/multiobjective synthesis (`K = Y X^-1`): `X = P^-1` for a "
            "state feedback, `X = P` for an observer (solved as the dual)",
    ("Cz", "Dzu", "Dv"): "H2/Hinf performance output `z = Cz x + Dzu u`; `Dv` the measurement noise "
                         "input of the observer problem",
    ("Lambda_op", "Lambda0_op"): "`feedback_linearization`: decoupling matrix `Lambda(x)` and drift "
                                 "`Lambda_0(x)` at `x_op` (the report keeps the paper's symbols)",
    ("A0", "B0"): "Takagi-Sugeno models: the affine part, the paper's names",
    ("forms", "z_lower", "z_upper", "region_c", "semi_axes", "axes"):
        "Takagi-Sugeno PDC: the premises' linear forms and bounds, the certified region's level "
        "`V <= region_c`, its semi-axes (m) and axes",
    ("sp_<name>", "sp_switch_level"): "Takagi-Sugeno set-point stage: `<name>` of the design about the "
                                      "second operating point, and the switching level",
    ("input_limits",): "the input range the law saturates to (input units); `inverse_dynamics` stores "
                       "its law's gain as `C` (1/s, the paper's name), not an output matrix",
}


def undocumented_gains(names: Sequence[str]) -> list[str]:
    """The names in ``names`` that `GAIN_NAMES` does not document.

    Parameters
    ----------
    names : sequence of str
        Gain names of an artefact.

    Returns
    -------
    list of str
        In the order given; ``<k>`` in a table name matches a decimal index,
        ``sp_<name>`` the prefix ``sp_`` on a documented name.
    """
    import re

    exact = {n for row in GAIN_NAMES for n in row if "<" not in n}
    patterns = [re.compile(re.escape(n).replace(re.escape("<k>"), r"\d+") + r"\Z")
                for row in GAIN_NAMES for n in row if "<k>" in n]

    def known(name: str) -> bool:
        if name in exact or any(p.match(name) for p in patterns):
            return True
        return name.startswith("sp_") and known(name[3:])

    return [n for n in names if not known(n)]
