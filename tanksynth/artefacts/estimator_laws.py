"""Estimator steps as standalone CasADi Functions for the estimators `export.derived_law` lacked.

Each builder returns a ``casadi.Function`` (SX, so it exports as C through
`tanksynth.artefacts.export.export_law`) that takes the estimator's state
and the new data and returns the next state: exactly the step the verdict
runs (same formulas, same constants, same order of prediction and
correction), so that a step of the generated C equals a step of the
runtime estimator to rounding.

==========================  =================================================  ==============================
method                      inputs                                             outputs
==========================  =================================================  ==============================
adaptive_kalman             x, P, Q, V, DX, filled, y, u                       x_next, P_next, Q_next, V_next,
                                                                               DX_next, filled_next
adaptive_scaling_kalman     x, P, phi, y, u                                    x_next, P_next, phi_next
consensus_filter            x, M, y (all sensors stacked), u                   x_next, M_next
narx                        x, x_past, y, u                                    x_next, x_past_next, x_pred,
                                                                               innovation
ts_observer                 x_hat, u, y (+ z: measured premises)               x_hat_next (x_hat_dot without
                                                                               ts), z, mu
decentralized_kalman        x_hat, u, y, k                                     x_hat_next, crossed
fault_detection             x_hat, u, y_prev, y, t                             x_hat_next, residual,
                                                                               threshold, alarm
==========================  =================================================  ==============================

Vectors are columns; matrices are CasADi's column-major ``casadi_real``
arrays in the C code (``P`` is symmetric). States, inputs and outputs are
in the plant's units (`tanksynth.artefacts.export.implementation_data`);
``u`` is always the input held over the period that ends at the new
measurement (`tanksynth.runtime.estimators.base`). The positive
definiteness checks of the runtime (which raise `CovarianceError`) are not
part of a law: an implementation should check its covariances itself.

The artefact keys each builder reads are read in one helper per method
(``_<method>_data``), so that a renaming of gain keys touches one place. The TS observer,
decentralised Kalman and fault-detector steps are built in `tanksynth.artefacts.observer_laws`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Mapping

import casadi as ca
import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.artefacts.export import sampling_period
from tanksynth.artefacts.observer_laws import (decentralized_step, fault_detection_step,
                                                ts_model_from_record, ts_observer_step)
from tanksynth.runtime.estimators.kernels import sx_spd_inverse

if TYPE_CHECKING:  # annotations only: each estimator's module loads with the law that needs it
    from tanksynth.runtime.estimators.adaptive import AdaptiveKalmanFilter, AdaptiveScalingKalmanFilter
    from tanksynth.runtime.estimators.consensus import ConsensusFilter
    from tanksynth.runtime.estimators.model import DiscreteModel
    from tanksynth.runtime.estimators.narx import NARXEstimator
    from tanksynth.spec import Spec
    from tanksynth.spec.method_options.base import MethodOptions

__all__ = ["ESTIMATOR_LAW_METHODS", "estimator_law", "adaptive_kalman_step",
           "adaptive_scaling_step", "consensus_step", "narx_step", "sx_psd_floor"]

#: Methods whose step `estimator_law` builds (dispatched from `export.derived_law`).
ESTIMATOR_LAW_METHODS = ("ts_observer", "adaptive_kalman", "adaptive_scaling_kalman",
                         "consensus_filter", "narx", "decentralized_kalman", "fault_detection")

#: Cyclic Jacobi sweeps of `sx_psd_floor` (quadratic convergence: 3 x 3 matrices converge to
#: rounding in 4-5 sweeps; the rest cost little).
JACOBI_SWEEPS = 12


def _sym(A: ca.SX) -> ca.SX:
    return 0.5 * (A + A.T)


def _linear(model: DiscreteModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``Ad, Bd, cd, C, dy`` of a linear filter's model (``x(k) = Ad x(k-1) + Bd u(k) + cd``,
    ``y = C x + dy``)."""
    if model.Ad is None or model.Bd is None or model.cd is None or model.C is None or model.dy is None:
        raise ArtefactError("the filter's model is not linear: no step of a linear filter to export")
    return model.Ad, model.Bd, model.cd, model.C, model.dy


def _joseph(P: ca.SX, K: ca.SX, H: np.ndarray | ca.SX, R: np.ndarray) -> ca.SX:
    """``sym((I - K H) P (I - K H)' + K R K')`` (the runtime's `joseph_update`)."""
    IKH = ca.SX.eye(P.shape[0]) - K @ ca.SX(H)
    return _sym(IKH @ P @ IKH.T + K @ ca.DM(R) @ K.T)


def _gain(P: ca.SX, H: np.ndarray, R: np.ndarray) -> ca.SX:
    """``P H' (H P H' + R)^-1`` with the innovation covariance symmetrised (the runtime's gain)."""
    Hd = ca.DM(H)
    S = _sym(Hd @ P @ Hd.T + ca.DM(R))
    return P @ Hd.T @ sx_spd_inverse(S)[0]


def sx_psd_floor(A: ca.SX, floor: float, sweeps: int = JACOBI_SWEEPS) -> ca.SX:
    """``V diag(max(w, floor)) V'`` of a symmetric ``A = V diag(w) V'`` as an SX expression.

    The eigen-decomposition is a fixed number of cyclic Jacobi sweeps (no
    branching on data: a zero off-diagonal entry gives the identity
    rotation), so the expression can be generated as C. The result is a
    continuous function of ``A`` and equals numpy's ``eigh`` route to
    rounding, repeated eigenvalues included.

    Parameters
    ----------
    A : casadi.SX, shape (n, n)
        Symmetric matrix (e.g. a covariance, state units^2).
    floor : float
        Lower clip of the eigenvalues (same units as ``A``).
    sweeps : int
        Jacobi sweeps.

    Returns
    -------
    casadi.SX, shape (n, n)
        Symmetrised ``V diag(max(w, floor)) V'``.
    """
    n = A.shape[0]
    a = [[A[i, j] for j in range(n)] for i in range(n)]
    v = [[ca.SX(1.0 if i == j else 0.0) for j in range(n)] for i in range(n)]
    for _ in range(int(sweeps)):
        for p in range(n - 1):
            for q in range(p + 1, n):
                apq = a[p][q]
                zero = apq == 0
                theta = (a[q][q] - a[p][p]) / (2.0 * ca.if_else(zero, 1.0, apq))
                t = ca.sign(theta) / (ca.fabs(theta) + ca.sqrt(theta * theta + 1.0))
                t = ca.if_else(zero, 0.0, ca.if_else(theta == 0, 1.0, t))
                c = 1.0 / ca.sqrt(t * t + 1.0)
                s = t * c
                # A <- J' A J with the rotation J in the (p, q) plane
                for k in range(n):
                    akp, akq = a[k][p], a[k][q]
                    a[k][p], a[k][q] = c * akp - s * akq, s * akp + c * akq
                for k in range(n):
                    apk, aqk = a[p][k], a[q][k]
                    a[p][k], a[q][k] = c * apk - s * aqk, s * apk + c * aqk
                for k in range(n):
                    vkp, vkq = v[k][p], v[k][q]
                    v[k][p], v[k][q] = c * vkp - s * vkq, s * vkp + c * vkq
    V = ca.SX(n, n)
    for i in range(n):
        for j in range(n):
            V[i, j] = v[i][j]
    w = ca.vertcat(*[ca.fmax(a[i][i], float(floor)) for i in range(n)])
    return _sym(V @ ca.diag(w) @ V.T)


# ------------------------------------------------------------------ linear-model Kalman filters
def adaptive_kalman_step(name: str, est: AdaptiveKalmanFilter) -> ca.Function:
    """One step of the adaptive-Q Kalman filter (seed 000 eq. 29-37) with its innovation window.

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    est : AdaptiveKalmanFilter
        The runtime filter (`tanksynth.runtime.estimators.adaptive`): its linear
        model, ``R``, window ``W``, form and ``q_floor`` are built in.

    Returns
    -------
    casadi.Function
        ``x_next, P_next, Q_next, V_next, DX_next, filled_next = step(x, P, Q,
        V, DX, filled, y, u)``: ``x`` (n, state units) and ``P`` (n x n, state
        units^2) the estimate and covariance ``x(k-1|k-1)``, ``P(k-1|k-1)``;
        ``Q`` (n x n, state units^2) the current process noise covariance
        (start: ``Q0``); ``V`` (W x q, output units) and ``DX`` (W x n, state
        units) the last ``W`` innovations ``v_i`` and corrections ``K_i v_i``,
        newest in row 0 (start: zeros); ``filled`` the number of valid rows
        (start: 0); ``y`` (q) the new measurement, ``u`` (m) the input held
        over the period. ``Q`` is adapted (eq. 36, or 37 with ``form =
        "steady_state"``, eigenvalues clipped at ``q_floor`` by `sx_psd_floor`)
        once the window is full, as in the runtime.
    """
    tun = est.tuning
    Ad, Bd, cd, C, dy = _linear(est.model)
    n, q, m, W = est.n, est.q, est.m, int(tun.window)
    x, P, Q = ca.SX.sym("x", n), ca.SX.sym("P", n, n), ca.SX.sym("Q", n, n)
    V, DX = ca.SX.sym("V", W, q), ca.SX.sym("DX", W, n)
    filled, y, u = ca.SX.sym("filled"), ca.SX.sym("y", q), ca.SX.sym("u", m)
    F, H = ca.DM(Ad), ca.DM(C)
    xp = F @ x + ca.DM(Bd) @ u + ca.DM(cd)                                # (30)
    Pp = _sym(F @ P @ F.T + Q)                                           # (31)
    K = _gain(Pp, C, tun.R)                                              # (32)
    v = y - (H @ xp + ca.DM(dy))                                         # innovation (35)
    dx = K @ v
    x_new = xp + dx                                                      # (33)
    P_new = _joseph(Pp, K, C, tun.R)                                     # (34)
    V_new = ca.vertcat(v.T, V[:W - 1, :]) if W > 1 else v.T
    DX_new = ca.vertcat(dx.T, DX[:W - 1, :]) if W > 1 else dx.T
    filled_new = ca.fmin(filled + 1, W)
    if tun.form == "full":                                               # (36)
        Qh = DX_new.T @ DX_new / W + P_new - F @ P @ F.T
    else:                                                                # (37)
        Qh = K @ (V_new.T @ V_new / W) @ K.T
    Q_adapted = sx_psd_floor(_sym(Qh), tun.q_floor)
    Q_new = ca.if_else(filled_new >= W, Q_adapted, Q)
    return ca.Function(name, [x, P, Q, V, DX, filled, y, u],
                       [x_new, P_new, Q_new, V_new, DX_new, filled_new],
                       ["x", "P", "Q", "V", "DX", "filled", "y", "u"],
                       ["x_next", "P_next", "Q_next", "V_next", "DX_next", "filled_next"])


def adaptive_scaling_step(name: str, est: AdaptiveScalingKalmanFilter) -> ca.Function:
    """One step of the adaptive-scaling Kalman filter (seed 004 eq. 30-41).

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    est : AdaptiveScalingKalmanFilter
        The runtime filter: linear model, ``G Q G'``, ``R``, ``a, b, c`` and
        ``phi0`` are built in.

    Returns
    -------
    casadi.Function
        ``x_next, P_next, phi_next = step(x, P, phi, y, u)``: estimate (n,
        state units), covariance (n x n, state units^2) and process-noise
        scaling ``phi_(k-1)`` (dimensionless, start ``phi0``); ``y`` (q) the new
        measurement, ``u`` (m) the held input.
    """
    tun = est.tuning
    Ad, Bd, cd, Cm, dy = _linear(est.model)
    n, q, m = est.n, est.q, est.m
    x, P, phi = ca.SX.sym("x", n), ca.SX.sym("P", n, n), ca.SX.sym("phi")
    y, u = ca.SX.sym("y", q), ca.SX.sym("u", m)
    A, C = ca.DM(Ad), ca.DM(Cm)
    xp = A @ x + ca.DM(Bd) @ u + ca.DM(cd)                                # (30)
    v = y - (C @ xp + ca.DM(dy))
    APA = A @ P @ A.T
    tr_beta = ca.trace(C @ APA @ C.T + ca.DM(tun.R))                      # (34b)
    match = (ca.dot(v, v) - tr_beta) / est.output_noise_trace
    phi_new = ca.fmax(tun.a * tun.phi0 + tun.b * phi + tun.c * match, 0.0)   # (36)-(38)
    Pp = _sym(APA + phi_new * ca.DM(est.state_noise_covariance))        # (32)
    K = _gain(Pp, Cm, tun.R)                                             # (39)
    x_new = xp + K @ v                                                   # (40)
    P_new = _joseph(Pp, K, Cm, tun.R)                                    # (41)
    return ca.Function(name, [x, P, phi, y, u], [x_new, P_new, phi_new],
                       ["x", "P", "phi", "y", "u"], ["x_next", "P_next", "phi_next"])


def consensus_step(name: str, est: ConsensusFilter) -> ca.Function:
    """One step of the consensus filter (seed 004 eq. 42-51) over all its sensors.

    The runtime takes the consensus sums as exact, so the network's step is
    the centralised information-form update on the stacked measurements:
    that is what this Function computes (one call per sample on a fusion
    node, or on every node once the consensus on ``H`` and ``z`` has
    converged). A node's own contribution is ``C_i' R_i^-1 (y_i - d_i) / N``.

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    est : ConsensusFilter
        The runtime filter: linear model, ``C_i``, ``R_i``, ``G Q G'`` built in.

    Returns
    -------
    casadi.Function
        ``x_next, M_next = step(x, M, y, u)``: estimate (n, state units) and
        central posterior covariance ``M`` (n x n, state units^2, start
        ``P0``); ``y`` the measurements of the ``N`` sensors stacked (sensor 0
        first, ``sum q_i`` entries, output units); ``u`` (m) the held input.
    """
    tun = est.tuning
    Ad, Bd, cd, _, _ = _linear(est.model)
    n, m, N = est.n, est.m, tun.sensors
    x, Mc = ca.SX.sym("x", n), ca.SX.sym("M", n, n)
    y, u = ca.SX.sym("y", est.q), ca.SX.sym("u", m)
    A, Hm, Z = ca.DM(Ad), ca.DM(est.information_matrix), ca.DM(est.information_gain)
    xbar = A @ x + ca.DM(Bd) @ u + ca.DM(cd)                              # (51)
    P = _sym(A @ Mc @ A.T + ca.DM(est.state_noise_covariance))          # (50)
    info = _sym(sx_spd_inverse(N * P)[0] + Hm)                           # (44)
    Pcal = _sym(sx_spd_inverse(info)[0])
    z = Z @ (y - ca.DM(est.stacked_offset))                              # (48)
    x_new = xbar + Pcal @ (z - Hm @ xbar)                                # (49)
    M_new = _joseph(P, Pcal @ Z, est.stacked_C, est.stacked_R)
    return ca.Function(name, [x, Mc, y, u], [x_new, M_new], ["x", "M", "y", "u"],
                       ["x_next", "M_next"])


def narx_step(name: str, est: NARXEstimator) -> ca.Function:
    """One step of the NARX estimator (seed 002 eq. 42-45): the trained network with its delays.

    Parameters
    ----------
    name : str
        Function name (a C identifier).
    est : NARXEstimator
        The runtime estimator: its CasADi kernel and weights are built in.

    Returns
    -------
    casadi.Function
        ``x_next, x_past_next, x_pred, innovation = step(x, x_past, y, u)``:
        ``x`` = ``x(k-1)`` (n, state units), ``x_past`` = ``[x(k-2); ...;
        x(k-d)]`` (``(d - 1) n``, the network's output delays; start: ``x0``
        repeated), ``y`` (q) the new measurement, ``u`` (m) the held input;
        ``x_pred`` the model prediction ``x(k|k-1)`` and ``innovation`` ``y -
        h(x_pred)`` (the network's exogenous inputs).
    """
    kernel = est.step_kernel
    n, d = est.n, int(est.tuning.delays)
    x, past = ca.SX.sym("x", n), ca.SX.sym("x_past", (d - 1) * n)
    y, u = ca.SX.sym("y", est.q), ca.SX.sym("u", est.m)
    params = ca.DM(est.kernel_parameters)
    new, _, extra = kernel(ca.vertcat(x, past), y, u, params)
    q = est.q
    return ca.Function(name, [x, past, y, u], [new[:n], new[n:], extra[q:], extra[:q]],
                       ["x", "x_past", "y", "u"], ["x_next", "x_past_next", "x_pred", "innovation"])


# ------------------------------------------------------------------ continuous-time observers


# ------------------------------------------------------------------ artefact -> law
def _vec(gains: Mapping[str, Any], key: str) -> np.ndarray:
    if key not in gains:
        raise ArtefactError(f"the artefact has no gain '{key}' needed to export the law")
    return np.asarray(gains[key], dtype=float)


def _initial_and_op(gains: Mapping[str, Any]) -> tuple[np.ndarray, Any]:
    """Initial estimate and operating point of a linear-filter artefact (the one place for keys)."""
    op = (_vec(gains, "x_op"), _vec(gains, "u_op")) if "x_op" in gains and "u_op" in gains else None
    return _vec(gains, "x_hat0").reshape(-1), op


def _adaptive_kalman_data(gains: Mapping[str, Any], spec: Spec, options: MethodOptions | None
                          ) -> AdaptiveKalmanFilter:
    from tanksynth.runtime.estimators.adaptive import AdaptiveKalmanFilter, AdaptiveKalmanTuning

    x0, op = _initial_and_op(gains)
    tuning = AdaptiveKalmanTuning(Q0=_vec(gains, "Q0"), R=_vec(gains, "R"), P0=_vec(gains, "P0"),
                                  x0=x0, ts=sampling_period(spec, "adaptive_kalman"),
                                  window=int(round(float(_vec(gains, "window").ravel()[0]))),
                                  q_floor=float(_vec(gains, "q_floor").ravel()[0]),
                                  form=getattr(options, "form", "full"), operating_point=op)
    return AdaptiveKalmanFilter(spec.plant, tuning)


def _adaptive_scaling_data(gains: Mapping[str, Any], spec: Spec, options: MethodOptions | None
                           ) -> AdaptiveScalingKalmanFilter:
    from tanksynth.runtime.estimators.adaptive import AdaptiveScalingKalmanFilter, AdaptiveScalingTuning

    x0, op = _initial_and_op(gains)
    a, b, c = (float(v) for v in _vec(gains, "abc").ravel())
    tuning = AdaptiveScalingTuning(Q=np.atleast_2d(_vec(gains, "Q")), R=_vec(gains, "R"),
                                   P0=_vec(gains, "P0"), x0=x0, a=a, b=b, c=c,
                                   ts=sampling_period(spec, "adaptive_scaling_kalman"),
                                   G=_vec(gains, "G"), phi0=float(_vec(gains, "phi0").ravel()[0]),
                                   operating_point=op)
    return AdaptiveScalingKalmanFilter(spec.plant, tuning)


def _consensus_data(gains: Mapping[str, Any], spec: Spec, options: MethodOptions | None) -> ConsensusFilter:
    from tanksynth.runtime.estimators.consensus import ConsensusFilter, ConsensusTuning

    x0, op = _initial_and_op(gains)
    N = 0
    while f"R{N}" in gains:
        N += 1
    Cs = tuple(_vec(gains, f"C{i}") for i in range(N)) if "C0" in gains else None
    tuning = ConsensusTuning(Q=np.atleast_2d(_vec(gains, "Q")),
                             R=tuple(np.atleast_2d(_vec(gains, f"R{i}")) for i in range(N)),
                             P0=_vec(gains, "P0"), x0=x0, C=Cs, G=_vec(gains, "G"),
                             ts=sampling_period(spec, "consensus_filter"), operating_point=op)
    return ConsensusFilter(spec.plant, tuning)


def _narx_data(gains: Mapping[str, Any], spec: Spec, options: MethodOptions | None) -> NARXEstimator:
    from tanksynth.runtime.estimators.narx import NARXEstimator, NARXTuning

    n = spec.plant.n
    W1 = np.atleast_2d(_vec(gains, "W1"))
    H = W1.shape[0]
    tuning = NARXTuning(W1, _vec(gains, "b1").reshape(H), _vec(gains, "W2").reshape(n, H),
                        _vec(gains, "b2").reshape(n), _vec(gains, "in_mean").reshape(-1),
                        _vec(gains, "in_scale").reshape(-1), _vec(gains, "out_mean").reshape(n),
                        _vec(gains, "out_scale").reshape(n), x0=_vec(gains, "x_hat0").reshape(n),
                        ts=sampling_period(spec, "narx"),
                        delays=int(round(float(_vec(gains, "delays").ravel()[0]))),
                        substeps=int(getattr(options, "substeps", 1)),
                        clip=bool(getattr(options, "clip", False)))
    return NARXEstimator(spec.plant, tuning, backend="vm")


def estimator_law(gains: Mapping[str, np.ndarray], diagnostics: Mapping[str, Any], method: str,
                  spec: Spec, options: MethodOptions | None, name: str) -> ca.Function | None:
    """The step of an estimator in `ESTIMATOR_LAW_METHODS`, from its artefact.

    Parameters
    ----------
    gains : mapping of str to ndarray
        The design's gains (in the plant's units).
    diagnostics : mapping
        Its diagnostics (``ts_model`` of a TS observer).
    method : str
        Its method.
    spec : Spec
        The spec it was designed from (plant, sampling period ``ts`` in s).
    options : MethodOptions
        Its validated options (``form``, ``substeps``, ``clip``, ``conservative``).
    name : str
        Function name (a C identifier).

    Returns
    -------
    casadi.Function or None
        The builder's Function (see the module table); None for another method.
    """
    n, q = spec.plant.n, spec.plant.q
    if method == "adaptive_kalman":
        return adaptive_kalman_step(name, _adaptive_kalman_data(gains, spec, options))
    if method == "adaptive_scaling_kalman":
        return adaptive_scaling_step(name, _adaptive_scaling_data(gains, spec, options))
    if method == "consensus_filter":
        return consensus_step(name, _consensus_data(gains, spec, options))
    if method == "narx":
        return narx_step(name, _narx_data(gains, spec, options))
    if method == "ts_observer":
        record = diagnostics.get("ts_model") if isinstance(diagnostics, Mapping) else None
        model = ts_model_from_record(spec.plant, record if isinstance(record, Mapping) else {})
        return ts_observer_step(name, model, _vec(gains, "L").reshape(n, q),
                                None if spec.ts is None else float(spec.ts))
    if method == "decentralized_kalman":
        Ks: list[np.ndarray] = []
        while f"K_{len(Ks)}" in gains:
            Ks.append(_vec(gains, f"K_{len(Ks)}").reshape(n, q))
        return decentralized_step(name, spec.plant, Ks, sampling_period(spec, method))
    if method == "fault_detection":
        return fault_detection_step(name, spec.plant, _vec(gains, "Psi"),
                                    _vec(gains, "threshold_coefficients"),
                                    _vec(gains, "threshold_rates"), sampling_period(spec, method),
                                    conservative=bool(getattr(options, "conservative", True)))
    return None
