"""The ``estimators`` family's problem statements (``kalman``, ``ekf``, ``ukf``,
``adaptive_kalman``, ``adaptive_scaling_kalman``, ``consensus_filter``, ``luenberger``, ``narx``).

Each is the estimator in one sentence (`estimator_statement`); the Kalman-type filters add the
stochastic model they are optimal for (`NOISE_MODEL`). None reads the diagnostics.
"""

from __future__ import annotations

from tanksynth.reports.statements.common import Statement, problem_statement

__all__ = ["NOISE_MODEL", "estimator_statement", "kalman_statement", "ekf_statement", "ukf_statement",
           "adaptive_kalman_statement", "adaptive_scaling_kalman_statement", "consensus_filter_statement",
           "luenberger_statement", "narx_statement"]

#: The stochastic model of the Kalman-type filters, and how they update their covariance.
NOISE_MODEL = (r" State $x(k+1) = F(x(k), u(k)) + w(k)$, $y(k) = h(x(k)) + v(k)$ with "
               r"$w \sim \mathcal{N}(0, Q)$, $v \sim \mathcal{N}(0, R)$, $x(0) \sim \mathcal{N}(\hat x_0, P_0)$; "
               r"covariance updates in Joseph form, symmetrised.")


def estimator_statement(method: str, estimator: str, model: str = NOISE_MODEL) -> Statement:
    """The statement of an estimator: what it is, then the model it estimates on.

    Parameters
    ----------
    method : str
        The method's name.
    estimator : str
        The estimator in one sentence (LaTeX text mode).
    model : str, optional
        The model sentence (default `NOISE_MODEL`; empty for a deterministic estimator).

    Returns
    -------
    callable
        ``statement(diag) -> Tex``.
    """
    return problem_statement(method, __name__, estimator + model)


kalman_statement = estimator_statement(
    "kalman", r"Kalman filter on the exact ZOH linearisation $(A_d, B_d, C)$ at the "
              r"operating point: the minimum-variance linear estimator.")
ekf_statement = estimator_statement(
    "ekf", r"Extended Kalman filter: the nonlinear model is propagated and its "
           r"Jacobians at the current estimate give the gain.")
ukf_statement = estimator_statement(
    "ukf", r"Unscented Kalman filter: $2n+1$ sigma points (weights from "
           r"$\alpha, \beta, \kappa$) propagated through the nonlinear model.")
adaptive_kalman_statement = estimator_statement(
    "adaptive_kalman", r"Adaptive Kalman filter: $Q$ re-estimated from the innovations "
                       r"$\nu_k$ over a sliding window of length $\Psi$.")
adaptive_scaling_kalman_statement = estimator_statement(
    "adaptive_scaling_kalman", r"Adaptive-scaling Kalman filter: the process noise is scaled by "
                               r"$\varphi_k$ solved from $\nu_k^\top \nu_k = \mathrm{tr}(\beta) + \varphi_k "
                               r"\mathrm{tr}(C G Q G^\top C^\top)$.")
consensus_filter_statement = estimator_statement(
    "consensus_filter", r"Information-form consensus filter: $N$ redundant sensors fuse "
                        r"$\sum_i C^\top R_i^{-1} C$ and $\sum_i C^\top R_i^{-1} y_i$.")
luenberger_statement = estimator_statement(
    "luenberger", r"Luenberger observer $\hat x(k+1) = A_d \hat x(k) + B_d u(k) + L\big(y(k) - C\hat x(k)\big)$ "
                  r"(or its continuous form), $L$ given or placing the eigenvalues of $A - LC$.", model="")
narx_statement = estimator_statement(
    "narx", r"NARX estimator: a one-hidden-layer network maps delayed measurements and inputs to the "
            r"state, trained by Levenberg-Marquardt on EKF-labelled data to minimise "
            r"$\sum_k \|\hat x_k - x_k^{\mathrm{EKF}}\|^2$.", model="")
