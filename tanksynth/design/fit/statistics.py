"""Statistics of a least-squares fit: Fisher information, intervals, identifiability, whiteness.

All from the residual Jacobian at the optimum (Gauss-Newton Fisher information ``J^T J`` of
residuals already divided by their noise level):

* `fisher_covariance`: covariance of the parameters ``s^2 [(J^T J)^-1]`` (the initial states
  eliminated as nuisance parameters), standard errors, correlation, and the rank test: a
  near-singular information in log-parameters means a combination of parameters the data
  cannot determine (`identifiable_note` names what is determined instead);
* `t_interval` and `profile_bound`: Wald (Student t) intervals, and the profile-likelihood
  bound found by root finding on a profile-cost callable where the Wald interval is not
  trusted;
* `hac_covariance`: the Newey-West (Bartlett-kernel, autocorrelation-consistent) sandwich
  covariance from the same Jacobian and the residuals, for residuals that are not white
  (`hac_lags` chooses the truncation lag);
* `whiteness_test`: normalised residual autocorrelation at lags 1..L against
  ``+-1.96/sqrt(N)`` and the Ljung-Box portmanteau statistic against its chi-square quantile.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Callable, Sequence

import numpy as np
from scipy import stats

from tanksynth.measurements.scores import WHITENESS_LAGS, WHITENESS_LEVEL, ljung_box

__all__ = ["FisherStatistics", "fisher_covariance", "HacStatistics", "hac_covariance", "hac_lags", "identifiable_note", "t_interval",
           "profile_bound", "WhitenessTest", "whiteness_test"]

#: Relative eigenvalue of the scaled Fisher information below which a direction is not identifiable.
RANK_TOL = 1e-8


@dataclass(frozen=True)
class FisherStatistics:
    """Covariance and rank of the parameters from the Fisher information.

    Attributes
    ----------
    covariance : ndarray, shape (k, k)
        Parameter covariance (parameter units squared); pseudo-inverse on the identifiable
        subspace when rank-deficient.
    stderr : ndarray, shape (k,)
        Standard errors (parameter units); ``inf`` for a parameter in an unidentifiable direction.
    correlation : ndarray, shape (k, k)
        Correlation matrix (NaN where a standard error is infinite).
    sigma2 : float
        Residual variance factor ``s^2 = r^T r / (N - K)`` of the weighted residuals (dimensionless).
    dof : int
        Degrees of freedom ``N - K`` (residuals minus all unknowns, initial states included).
    null_vectors : ndarray, shape (d, k)
        Unidentifiable directions in log-parameters (``d = 0`` when identifiable).
    eigenvalues : ndarray, shape (k,)
        Eigenvalues of the scaled Fisher information of the parameters (ascending, max 1;
        dimensionless).
    """

    covariance: np.ndarray
    stderr: np.ndarray
    correlation: np.ndarray
    sigma2: float
    dof: int
    null_vectors: np.ndarray
    eigenvalues: np.ndarray

    @property
    def identifiable(self) -> bool:
        """Every parameter is determined by the data (full-rank Fisher information)."""
        return self.null_vectors.shape[0] == 0


def _reduced(J: np.ndarray, theta: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parameter columns of ``J`` in equilibrated log-parameters, the nuisance columns
    projected out: ``(A (N, k), column norms (K,), parameter scale (k,))``."""
    K = J.shape[1]
    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(theta))):
        raise FloatingPointError("the residual Jacobian at the optimum is not finite")
    scale = np.where(np.abs(theta) > 0, np.abs(theta), 1.0)       # log-parameters for the theta
    col = np.linalg.norm(J, axis=0)
    col[:k] = np.linalg.norm(J[:, :k] * scale, axis=0)
    col = np.where(col > 0, col, 1.0)
    D = np.ones(K)
    D[:k] = scale
    Js = J * (D / col)                                            # equilibrated columns
    # the parameters' information with the nuisance unknowns eliminated: project J_theta on the
    # orthogonal complement of the nuisance columns (QR), then the SVD of what is left
    A, B = Js[:, :k], Js[:, k:]
    if B.shape[1]:
        Q, R = np.linalg.qr(B)
        keep = np.abs(np.diag(R)) > 1e-12 * max(1.0, float(np.max(np.abs(np.diag(R)), initial=0.0)))
        Q = Q[:, keep]
        A = A - Q @ (Q.T @ A)
    return A, col, scale


def fisher_covariance(jacobian: np.ndarray, residuals: np.ndarray, theta: np.ndarray,
                      k: int) -> FisherStatistics:
    """Covariance, standard errors, correlation and rank from the residual Jacobian.

    Parameters
    ----------
    jacobian : ndarray, shape (N, K)
        d(weighted residual)/d(unknowns); the first ``k`` columns are the parameters
        (parameter units), the others nuisance unknowns (initial states).
    residuals : ndarray, shape (N,)
        Weighted residuals at the optimum (1).
    theta : ndarray, shape (k,)
        Parameter values at the optimum (parameter units, nonzero for the log scaling).
    k : int
        Number of parameters.

    Returns
    -------
    FisherStatistics
    """
    J = np.asarray(jacobian, dtype=float)
    N, K = J.shape
    dof = max(N - K, 1)
    s2 = float(residuals @ residuals) / dof
    A, col, scale = _reduced(J, theta, k)
    _, sv, Vt = np.linalg.svd(A, full_matrices=False)
    eig = (sv / sv[0]) ** 2 if sv.size and sv[0] > 0 else np.zeros(k)
    null = Vt[eig < RANK_TOL] / col[:k]                          # back to log-parameters
    null = null / np.linalg.norm(null, axis=1, keepdims=True) if null.size else null.reshape(0, k)
    good = eig >= RANK_TOL
    inv = (Vt[good].T / sv[good] ** 2) @ Vt[good] if np.any(good) else np.zeros((k, k))
    # back to parameter units: theta_i = scale_i / col_i * z_i
    T = scale / col[:k]
    cov = s2 * (T[:, None] * inv * T[None, :])
    var = np.diag(cov).copy()
    stderr = np.sqrt(np.maximum(var, 0.0))
    if null.shape[0]:
        involved = np.any(np.abs(null) > 1e-3, axis=0)
        stderr[involved] = np.inf
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(stderr, stderr)
    corr[~np.isfinite(corr)] = np.nan
    np.fill_diagonal(corr, np.where(np.isfinite(stderr), 1.0, np.nan))
    eig_sorted = np.sort(eig)
    return FisherStatistics(cov, stderr, corr, s2, dof, null, eig_sorted)


@dataclass(frozen=True)
class HacStatistics:
    """Autocorrelation-consistent (Newey-West, Bartlett kernel) covariance of the parameters.

    Attributes
    ----------
    covariance : ndarray, shape (k, k)
        Sandwich covariance ``B^-1 S B^-1`` (parameter units squared), ``B = A^T A`` the
        information and ``S`` the Bartlett-weighted long-run covariance of the scores.
    stderr : ndarray, shape (k,)
        Standard errors (parameter units); ``inf`` where the Fisher statistics say unidentifiable.
    correlation : ndarray, shape (k, k)
        Correlation matrix (1).
    lags : tuple of int
        Bartlett truncation lag of each experiment (samples).
    """

    covariance: np.ndarray
    stderr: np.ndarray
    correlation: np.ndarray
    lags: tuple[int, ...]


def hac_lags(scores: np.ndarray) -> int:
    """Bartlett truncation lag of one experiment's score series (samples).

    Andrews' (1991) AR(1) plug-in rule: fit ``g_t = rho_a g_{t-1} + e_t`` to each score
    component ``a`` (``rho_a`` clipped to +-0.97), ``alpha = sum 4 rho^2 s^4 / ((1 - rho)^6
    (1 + rho)^2) / sum s^4 / (1 - rho)^4`` and ``L = floor(1.1447 (alpha T)^(1/3))``, at
    least the Newey-West rule ``floor(4 (T/100)^(2/9))`` and at most ``T/4``.

    Parameters
    ----------
    scores : ndarray, shape (T, k)
        Score contributions per sample, in time order (dimensionless).

    Returns
    -------
    int
    """
    G = np.asarray(scores, dtype=float)
    T = G.shape[0]
    if T < 4:
        return 0
    floor_nw = int(np.floor(4.0 * (T / 100.0) ** (2.0 / 9.0)))
    num = den = 0.0
    for a in range(G.shape[1]):
        x0, x1 = G[:-1, a], G[1:, a]
        ss = float(x0 @ x0)
        if ss <= 0:
            continue
        rho = float(np.clip((x0 @ x1) / ss, -0.97, 0.97))
        s2 = float(np.mean((x1 - rho * x0) ** 2))
        num += 4.0 * rho ** 2 * s2 ** 2 / ((1 - rho) ** 6 * (1 + rho) ** 2)
        den += s2 ** 2 / (1 - rho) ** 4
    alpha = num / den if den > 0 else 0.0
    L = int(np.floor(1.1447 * (alpha * T) ** (1.0 / 3.0)))
    return int(min(max(L, floor_nw), T // 4))


def hac_covariance(jacobian: np.ndarray, residuals: np.ndarray, theta: np.ndarray, k: int,
                   experiment: np.ndarray, sample: np.ndarray, fisher: FisherStatistics,
                   lags: Sequence[int] | None = None) -> HacStatistics:
    """Newey-West (Bartlett-kernel HAC) sandwich covariance of the parameters.

    The scores ``g_t = sum_rows(t) a_row r_row`` (``A`` the parameter columns of the Jacobian
    with the nuisance unknowns projected out, as in `fisher_covariance`; the rows of one
    sample summed over the outputs) are taken per experiment, in time order, with missing
    samples as zeros; ``S = sum_e sum_{|l| <= L_e} (1 - |l|/(L_e + 1)) Gamma_e(l)``,
    ``Gamma_e(l) = sum_t g_t g_{t-l}^T``, and the covariance is
    ``N/(N - K) B^+ S B^+`` (``B = A^T A``, pseudo-inverse on the identifiable subspace).
    With ``L = 0`` and white residuals it tends to the Fisher covariance.

    Parameters
    ----------
    jacobian : ndarray, shape (N, K)
        d(weighted residual)/d(unknowns), parameters first (as `fisher_covariance`).
    residuals : ndarray, shape (N,)
        Weighted residuals at the optimum (1).
    theta : ndarray, shape (k,)
        Parameter values (parameter units).
    k : int
        Number of parameters.
    experiment, sample : ndarray of int, shape (N,)
        Experiment index and sample index (within the experiment) of each residual row.
    fisher : FisherStatistics
        The Fisher statistics of the same point (its identifiable subspace is kept).
    lags : sequence of int, optional
        Truncation lag per experiment (default: `hac_lags` of its scores).

    Returns
    -------
    HacStatistics
    """
    J = np.asarray(jacobian, dtype=float)
    r = np.asarray(residuals, dtype=float)
    N, K = J.shape
    A, col, scale = _reduced(J, theta, k)
    _, sv, Vt = np.linalg.svd(A, full_matrices=False)
    eig = (sv / sv[0]) ** 2 if sv.size and sv[0] > 0 else np.zeros(k)
    good = eig >= RANK_TOL
    inv = (Vt[good].T / sv[good] ** 2) @ Vt[good] if np.any(good) else np.zeros((k, k))
    contrib = A * r[:, None]
    exp_idx, smp = np.asarray(experiment, dtype=int), np.asarray(sample, dtype=int)
    S = np.zeros((k, k))
    used = []
    for e_i, e in enumerate(np.unique(exp_idx)):
        rows = exp_idx == e
        G = np.zeros((int(smp[rows].max()) + 1, k))
        np.add.at(G, smp[rows], contrib[rows])
        L = hac_lags(G) if lags is None else int(lags[e_i])
        L = max(0, min(L, G.shape[0] - 1))
        used.append(L)
        S += G.T @ G
        for lag in range(1, L + 1):
            Gam = G[lag:].T @ G[:-lag]
            S += (1.0 - lag / (L + 1.0)) * (Gam + Gam.T)
    T = scale / col[:k]
    cov_z = inv @ S @ inv * (N / max(N - K, 1))
    cov = T[:, None] * cov_z * T[None, :]
    stderr = np.sqrt(np.maximum(np.diag(cov), 0.0))
    stderr = np.where(np.isinf(fisher.stderr), np.inf, stderr)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(stderr, stderr)
    corr[~np.isfinite(corr)] = np.nan
    np.fill_diagonal(corr, np.where(np.isfinite(stderr), 1.0, np.nan))
    return HacStatistics(cov, stderr, corr, tuple(used))


def _exponent(v: float) -> Fraction:
    return Fraction(v).limit_denominator(6)


def identifiable_note(names: Sequence[str], null_vectors: np.ndarray) -> str:
    """Say which parameter combination the data determine, from the null directions.

    A null direction ``v`` in log-parameters means that scaling the parameters by
    ``exp(c v_i)`` leaves the outputs unchanged: only combinations ``prod theta_i^w_i`` with
    ``w . v = 0`` are determined. For one direction, the note names, for each parameter
    involved, its ratio (or product) with a reference parameter, e.g. ``mu13/A`` when
    ``A`` and ``mu13`` scale together, ``a*b`` when they scale inversely.

    Parameters
    ----------
    names : sequence of str
        Parameter names.
    null_vectors : ndarray, shape (d, k)
        Unidentifiable directions in log-parameters.

    Returns
    -------
    str
        One sentence; empty when ``d = 0``.
    """
    if null_vectors.shape[0] == 0:
        return ""
    sentences = []
    for v in null_vectors:
        involved = [i for i in range(len(names)) if abs(v[i]) > 1e-3]
        top = max(abs(v[i]) for i in involved)
        ref = min(i for i in involved if abs(v[i]) >= (1 - 1e-3) * top)   # ties: the first
        ratios = {i: _exponent(v[i] / v[ref]) for i in involved}   # v normalised: ref = 1
        combos = []
        for i in involved:
            if i == ref:
                continue
            # theta_i^a theta_ref^b with a v_i + b v_ref = 0: a = 1, b = -v_i / v_ref, scaled to
            # integers (a^2*b rather than a*b^1/2)
            b = -ratios[i]
            combos.append(_monomial((i, names[i], Fraction(b.denominator)),
                                    (ref, names[ref], b * b.denominator)))
        moved = ", ".join(f"{names[i]}^{ratios[i]}" if ratios[i] != 1 else names[i] for i in involved)
        if combos:
            sentences.append(f"the data cannot separate {', '.join(names[i] for i in involved)} "
                             f"(changing them together as {moved} leaves the outputs unchanged): "
                             f"only {', '.join(combos)} {'is' if len(combos) == 1 else 'are'} "
                             "identifiable")
        else:
            sentences.append(f"the data do not determine {names[ref]} (the outputs do not depend "
                             "on it)")
    return "; ".join(sentences)


def _power(name: str, e: Fraction) -> str:
    e = abs(e)
    return name if e == 1 else f"{name}^{e}"


def _monomial(first: tuple[int, str, Fraction], second: tuple[int, str, Fraction]) -> str:
    """``a^ea * b^eb`` (each ``(index, name, exponent)``) as a product (in parameter order) or
    a ratio; ``ea > 0``."""
    (ia, a, ea), (ib, b, eb) = first, second
    if eb == 0:
        return _power(a, ea)
    if eb < 0:
        return f"{_power(a, ea)}/{_power(b, eb)}"
    pair = sorted([(ia, _power(a, ea)), (ib, _power(b, eb))])
    return f"{pair[0][1]}*{pair[1][1]}"


def t_interval(value: np.ndarray, stderr: np.ndarray, dof: int, level: float) -> np.ndarray:
    """Wald intervals ``value +- t_{(1+level)/2, dof} stderr``.

    Parameters
    ----------
    value, stderr : ndarray, shape (k,)
        Estimates and standard errors (parameter units).
    dof : int
        Degrees of freedom of the residual variance.
    level : float
        Confidence level in (0, 1) (dimensionless).

    Returns
    -------
    ndarray, shape (k, 2)
    """
    q = float(stats.t.ppf(0.5 + level / 2.0, dof))
    return np.column_stack([value - q * stderr, value + q * stderr])


def profile_bound(excess: Callable[[float], float], value: float, step: float, limit: float,
                  target: float, tol: float = 1e-3, max_eval: int = 30) -> tuple[float, bool]:
    """One side of a profile-likelihood interval: where the profile cost excess reaches ``target``.

    Parameters
    ----------
    excess : callable
        ``theta_i -> (profile cost - optimum) / s^2`` (1): the other unknowns re-optimised
        with ``theta_i`` fixed.
    value : float
        The estimate (excess 0 there).
    step : float
        First trial offset (signed: the side searched), e.g. the Wald half-width.
    limit : float
        The box face on that side: the bound stops there.
    target : float
        Excess that defines the interval (``t^2`` or the chi-square quantile).
    tol : float
        Relative tolerance on the bound, as a fraction of ``|step|``.
    max_eval : int
        Largest number of profile evaluations.

    Returns
    -------
    bound : float
        The profile bound (parameter units).
    closed : bool
        False when the excess stays below ``target`` up to the box face (the bound is the face).
    """
    lo_x, lo_f = value, 0.0
    x = value + step
    evals = 0
    while True:                                   # bracket: grow the step up to the face
        if (x - limit) * np.sign(step) >= 0:
            x = limit
        fx = excess(x)
        evals += 1
        if fx >= target:
            break
        if x == limit or evals >= max_eval:
            return float(x), False
        lo_x, lo_f = x, fx
        x = value + 2.0 * (x - value)
    hi_x, hi_f = x, fx
    while evals < max_eval and abs(hi_x - lo_x) > tol * abs(step):
        # secant safeguarded by bisection, on sqrt(excess) (close to linear in theta)
        a, b = np.sqrt(max(lo_f, 0.0)), np.sqrt(max(hi_f, 0.0))
        frac = (np.sqrt(target) - a) / (b - a) if b > a else 0.5
        frac = min(max(frac, 0.1), 0.9)
        x = lo_x + frac * (hi_x - lo_x)
        fx = excess(x)
        evals += 1
        if fx >= target:
            hi_x, hi_f = x, fx
        else:
            lo_x, lo_f = x, fx
    a, b = np.sqrt(max(lo_f, 0.0)), np.sqrt(max(hi_f, 0.0))
    frac = (np.sqrt(target) - a) / (b - a) if b > a else 0.5
    return float(lo_x + min(max(frac, 0.0), 1.0) * (hi_x - lo_x)), True


@dataclass(frozen=True)
class WhitenessTest:
    """Residual whiteness of one output.

    Attributes
    ----------
    autocorrelation : ndarray, shape (L,)
        Normalised autocorrelation at lags 1..L (1).
    band : float
        ``1.96 / sqrt(N)``: the 95 % band of a white sequence (1).
    outside : int
        Lags whose autocorrelation lies outside the band.
    statistic : float
        Ljung-Box ``Q = N (N + 2) sum r_l^2 / (N - l)`` (1).
    bound : float
        Its 95 % chi-square quantile with L degrees of freedom (1).
    passed : bool
        ``statistic <= bound``.
    samples : int
        Residual pairs at lag 0 (N).
    """

    autocorrelation: np.ndarray
    band: float
    outside: int
    statistic: float
    bound: float
    passed: bool
    samples: int


def whiteness_test(series: Sequence[np.ndarray], lags: int = WHITENESS_LAGS,
                   level: float = WHITENESS_LEVEL) -> WhitenessTest:
    """Autocorrelation whiteness test of residual sequences (one per experiment, NaN = missing).

    The Ljung-Box statistic of `tanksynth.measurements.scores.ljung_box` (pooled over the
    experiments, 20 lags, 95 % chi-square bound: the fit verdict recomputes the same).

    Parameters
    ----------
    series : sequence of ndarray, shape (N_e,)
        Residuals of one output per experiment (output units), NaN where not exact.
    lags : int
        Largest lag L.
    level : float
        Level of the chi-square bound (dimensionless).

    Returns
    -------
    WhitenessTest
    """
    acf, q, bound, _, n0 = ljung_box(series, lags, level)
    band = 1.96 / np.sqrt(max(n0, 1))
    return WhitenessTest(acf, float(band), int(np.sum(np.abs(acf) > band)), q, bound,
                         bool(q <= bound), n0)
