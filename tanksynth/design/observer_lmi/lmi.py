"""Observer LMI of seed 001 eq. (28), solved with cvxpy + Clarabel and re-checked.

The error ``e = x - xhat`` of the observer ``dxhat/dt = A0 xhat + f(xhat, u) +
L (y - C xhat)`` obeys ``de/dt = (A0 - L C) e + Delta`` with ``|Delta| <= psi
|e|``. It converges exponentially if there are ``P = P' > 0``, ``Q = Q' > 0``
and ``K`` with::

    [ A0' P + P A0 - C' K' - K C + psi^2 Q    P ]
    [ P                                      -Q ]  <  0,       L = P^-1 K.

Two variants are offered (notes/plants.md section 4.2):

``"qI"`` (default, safe)
    ``Q = q I``. The Lipschitz step ``Delta' Q Delta <= psi^2 e' Q e``
    follows from the Euclidean bound ``|Delta| <= psi |e|`` only in this case.
``"full"`` (as printed in seed 001)
    ``Q`` a full symmetric matrix. Then ``psi`` must be a Lipschitz constant
    in the ``Q``-weighted norm, which the Euclidean bound does not give; the
    diagnostics say so. With ``(A0, C)`` observable this variant is feasible
    for every ``psi`` once the conditioning bound ``kappa`` is large enough,
    so "maximise psi" only measures ``kappa``.

Conditioning bound (`tanksynth.design.lmi_checks`): when a refused LMI has ``trace P`` at
``kappa n`` the bound, not the plant, limits the margin; `observer_lmi` then retries with
``kappa`` times ``KAPPA_STEP`` up to ``kappa_max`` and, if still refused, says
the bound is active and names the option. `maximise_psi` reports
``bounded_by_kappa`` whenever the bound is active at ``psi_max`` (both
variants).

Numerics (DESIGN.md): the problem is scaled before solving (time scale
``omega``: ``A0/omega``, ``psi/omega``; output rows of ``C`` normalised), the
homogeneous LMI is normalised by ``P >= I``, ``trace P <= kappa n`` and the strict
inequality is replaced by ``LMI <= -t I`` with ``t`` maximised; the design is
accepted only if ``t >= margin``. Every returned ``(P, Q, K)`` is then
re-checked in numpy in the original units (eigenvalues of the LMI blocks,
``P > 0``, ``Q > 0``, ``Re eig(A0 - L C) < -psi``); a failed check raises
`InfeasibleDesign` whatever the solver said.

The scaled problem compiled once with cvxpy Parameters (structure, ``K``
eliminated by the projection lemma, sparse ``A0``) is
`tanksynth.design.observer_lmi.problem.ObserverLMIProblem` (SCS, and eliminated
problems too large for dense expressions); with Clarabel a full-form LMI
solved once is built as conic data directly and the eliminated form is
rebuilt at each solve without cvxpy (`tanksynth.design.observer_lmi.conic_form`, one-shot
and ``psi`` sweep alike); the Kalman observability test is skipped
when ``C`` alone has rank ``n``. None of this touches the re-check: every gain
is checked against the full ``2n x 2n`` block matrix of eq. (28).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

# Module import (not names), so that a test may replace the rank functions.
from tanksynth.analysis import rank as _rank
from tanksynth.analysis.blas import small_dense
from tanksynth.design.bisection import bisect_feasible
from tanksynth.design.lmi_checks import KAPPA_STEP, LMICheck, kappa_active
from tanksynth.design.matrices import real_matrix, symmetrized
from tanksynth.design.observer_lmi.conic_form import (ConicObserverLMI, one_shot_problem, sweep_problem,
                                                      with_kappa)
from tanksynth.design.observer_lmi.problem import FORMS, VARIANTS, ObserverLMIProblem, check_variant
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError, UnobservableError

__all__ = [
    "VARIANTS",
    "FORMS",
    "ObserverLMIResult",
    "ObserverLMIProblem",
    "observer_lmi",
    "check_observer_lmi",
    "PsiSearch",
    "maximise_psi",
]


@dataclass(frozen=True)
class ObserverLMIResult:
    """A solved and re-checked observer LMI (seed 001 eq. 28).

    Attributes
    ----------
    L : ndarray, shape (n, q)
        Observer gain ``P^-1 K`` (1/s per output unit, times state unit).
    P : ndarray, shape (n, n)
        Lyapunov matrix (normalised so that ``P >= I``, ``trace P <= kappa n``).
    Q : ndarray, shape (n, n)
        ``Q`` of eq. (28), in the original time units (``q I`` for the safe
        variant).
    K : ndarray, shape (n, q)
        LMI variable ``K = P L``.
    psi : float
        Lipschitz constant used (1/s).
    variant : str
        ``"qI"`` or ``"full"``.
    margin : float
        Required strictness margin ``t`` (scaled problem).
    achieved_margin : float
        Optimal ``t`` returned by the solver (scaled problem). With ``K``
        eliminated this is the optimum of the eliminated LMI, equal to that
        of eq. (28); the recovered gain is built for the margin
        ``structure["gain_margin"]`` (``>= margin``), and ``lmi_eigenvalues``
        show the margin the returned matrices reach. Dimensionless (normalised).
    kappa : float
        Conditioning bound ``trace P <= kappa n``.
    solver, status : str
        Solver name and its final status.
    solve_time : float
        Wall time of the solve (s).
    checks : tuple of LMICheck
        The independent re-check (all passed, or the design was refused).
    lmi_eigenvalues : ndarray
        Eigenvalues of the re-computed block matrix, scaled back to the
        normalised problem (should all be <= -margin); dimensionless.
    error_eigenvalues : ndarray
        Eigenvalues of ``A0 - L C`` (1/s); real parts < ``-psi``.
    condition_P : float
        Condition number of ``P``.
    scaling : dict
        Time scale ``omega`` (1/s) and output row scales applied before
        solving.
    structure : dict
        ``{"P": "dense"}`` or the block partition and gain pattern used;
        also the LMI ``form`` (``"full"`` or ``"eliminated"``), how ``K``
        was obtained and whether the ``A0`` Parameter is sparse.
    """

    L: np.ndarray
    P: np.ndarray
    Q: np.ndarray
    K: np.ndarray
    psi: float
    variant: str
    margin: float
    achieved_margin: float
    kappa: float
    solver: str
    status: str
    solve_time: float
    checks: tuple[LMICheck, ...]
    lmi_eigenvalues: np.ndarray
    error_eigenvalues: np.ndarray
    condition_P: float
    scaling: dict
    structure: dict = field(default_factory=lambda: {"P": "dense"})

    def as_dict(self) -> dict:
        """JSON-friendly diagnostics (no gains)."""
        return {
            "psi": self.psi, "variant": self.variant,
            "Q_form": "Q = q I (Euclidean Lipschitz bound valid)" if self.variant == "qI" else
                      "full Q as printed in seed 001 (psi must be a Q-norm Lipschitz constant)",
            "margin": self.margin, "achieved_margin": self.achieved_margin, "kappa": self.kappa,
            "solver": self.solver, "status": self.status, "solve_time_s": self.solve_time,
            "checks": [c.as_dict() for c in self.checks],
            "lmi_eigenvalues": self.lmi_eigenvalues.tolist(),
            "lmi_max_eigenvalue": float(np.max(self.lmi_eigenvalues)),
            "error_eigenvalues": [[float(v.real), float(v.imag)] for v in self.error_eigenvalues],
            "error_max_real_part": float(np.max(self.error_eigenvalues.real)),
            "condition_P": self.condition_P, "scaling": self.scaling, "structure": self.structure,
        }


def check_observer_lmi(A0: Any, C: Any, psi: float, P: Any, Q: Any, K: Any, margin: float,
                       omega: float, tolerance: float = 0.5
                       ) -> tuple[tuple[LMICheck, ...], np.ndarray, np.ndarray]:
    """Independent numpy re-check of an observer LMI solution.

    Re-computes the block matrix of eq. (28) from ``A0, C, psi, P, Q, K`` in
    the original units, scales it back to the normalised problem with the
    congruence ``D = diag(omega^-1/2 I, omega^1/2 I)`` and checks its
    eigenvalues; also ``P > 0``, ``Q > 0`` and that ``A0 - L C`` has every
    eigenvalue with real part below ``-psi`` (a consequence of the LMI).

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        1/s.
    C : array_like, shape (q, n)
    psi : float
        1/s.
    P, Q : array_like, shape (n, n)
        The Lyapunov matrix (normalised, ``P >= I``: dimensionless) and ``Q`` of
        eq. (28) (s: ``psi^2 Q`` has the units of ``A0' P``).
    K : array_like, shape (n, q)
    margin : float
        Required margin of the normalised LMI (``<= -margin``).
    omega : float
        Time scale (1/s) used when solving.
    tolerance : float
        Fraction of ``margin`` granted to solver round-off: the largest
        normalised eigenvalue must be ``<= -(1 - tolerance) margin`` (dimensionless).

    Returns
    -------
    checks : tuple of LMICheck
    lmi_eigenvalues : ndarray, shape (2n,)
        Of the normalised block matrix.
    error_eigenvalues : ndarray, shape (n,)
        Of ``A0 - P^-1 K C`` (1/s).
    """
    A0, C, P, Q, K = (real_matrix(v, nm) for v, nm in ((A0, "A0"), (C, "C"), (P, "P"), (Q, "Q"), (K, "K")))
    n = A0.shape[0]
    if P.shape != (n, n) or Q.shape != (n, n) or K.shape != (n, C.shape[0]) or C.shape[1] != n:
        raise DimensionError("shapes of A0, C, P, Q, K do not match")
    X = A0.T @ P + P @ A0 - C.T @ K.T - K @ C + psi ** 2 * Q
    M = symmetrized(np.block([[X, P], [P, -Q]]))
    d = np.concatenate([np.full(n, omega ** -0.5), np.full(n, omega ** 0.5)])
    Mn = M * d[:, None] * d[None, :]
    eig = np.linalg.eigvalsh(Mn)
    eig_raw = float(np.max(np.linalg.eigvalsh(M)))
    L = np.linalg.solve(P, K)
    err = np.linalg.eigvals(A0 - L @ C)
    pmin = float(np.min(np.linalg.eigvalsh(symmetrized(P))))
    qmin = float(np.min(np.linalg.eigvalsh(symmetrized(Q))))
    need = -(1.0 - tolerance) * margin
    checks = (
        LMICheck("observer LMI block matrix, normalised (max eigenvalue <= -(1-tol) margin)",
                 float(eig.max()), need, bool(eig.max() <= need), "normalised"),
        LMICheck("observer LMI block matrix, original units (max eigenvalue < 0)",
                 eig_raw, 0.0, bool(eig_raw < 0), "original units"),
        LMICheck("P > 0 (min eigenvalue)", pmin, 0.0, bool(pmin > 0), ""),
        LMICheck("Q > 0 (min eigenvalue)", qmin, 0.0, bool(qmin > 0), "s"),
        LMICheck("A0 - L C decay faster than psi (max real part < -psi)",
                 float(np.max(err.real)), -psi, bool(np.max(err.real) < -psi), "1/s"),
    )
    return checks, eig, err


def _refuse_unobservable(A0: np.ndarray, C: np.ndarray) -> None:
    """Refuse an unobservable ``(A0, C)`` before solving, naming the modes (PBH).

    When ``C`` alone has rank ``n`` (every state measured, e.g. ``C = I``) the
    pair is observable whatever ``A0`` is, and the Kalman test (an SVD of the
    ``(n q) x n`` observability matrix, the slowest step of a large network
    design after the solver) is skipped.
    """
    n = A0.shape[0]
    if C.shape[0] >= n:
        nz = C != 0
        if np.all(nz.sum(axis=1) == 1) and np.unique(np.argmax(nz, axis=1)).size == n:
            return                          # every state measured by its own row: rank C = n
        with small_dense():
            if np.linalg.matrix_rank(C) == n:
                return
    rank = _rank.observability_rank(A0, C)
    if not rank.full:
        pbh = _rank.pbh_test(A0, C=C)
        modes = "; ".join(f"eigenvalue {m.eigenvalue:.4g} in states {list(m.states)}" for m in pbh.modes)
        raise UnobservableError(f"(A0, C) is not observable (rank {rank.rank} < {rank.n}); "
                                f"unobservable modes: {modes or 'not isolated by PBH'}; the "
                                "observer LMI cannot be solved")


def observer_lmi(A0: Any, C: Any, psi: float, *, variant: str = "qI", margin: float = 1e-6,
                 kappa: float = 1e4, blocks: Sequence[Sequence[int]] | None = None,
                 pattern: Any = None, solver: str = "CLARABEL",
                 problem: ObserverLMIProblem | None = None, form: str = "auto",
                 solver_options: dict | None = None,
                 kappa_max: float | None = None) -> ObserverLMIResult:
    """Solve the observer LMI (28) for a given ``psi`` and re-check the result.

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        Mean of the TS vertex matrices (1/s).
    C : array_like, shape (q, n)
        Output matrix (output unit per state unit).
    psi : float
        Lipschitz constant of ``Delta`` (1/s), >= 0.
    variant : {"qI", "full"}
        ``Q = q I`` (safe) or a full ``Q`` (as printed in seed 001).
    margin : float
        Strictness margin of the normalised problem (> 0).
    kappa : float
        Conditioning bound: ``P >= I``, ``trace P <= kappa n``.
    blocks : sequence of sequence of int, optional
        Block-diagonal ``P`` (and ``Q``) structure.
    pattern : array_like, shape (n, q), optional
        0/1 allowed entries of ``L`` (decentralised gain); dimensionless.
    solver : {"CLARABEL", "SCS"}
    problem : ObserverLMIProblem, optional
        A compiled problem to reuse (must match ``C``, variant, structure);
        its ``margin`` (target of the recovered gain) is set to ``margin``.
    form : {"auto", "full", "eliminated"}
        LMI form (`ObserverLMIProblem`); ``"auto"`` eliminates ``K`` unless
        a gain pattern is given. Ignored when ``problem`` is given.
    solver_options : mapping, optional
        Solver options (e.g. Clarabel tolerances) for this solve.
    kappa_max : float, optional
        When the margin is missed with ``trace P`` at ``kappa n``, retry with
        ``kappa`` times `KAPPA_STEP` up to ``kappa_max`` (default: no retry).

    Returns
    -------
    ObserverLMIResult

    Raises
    ------
    UnobservableError
        ``(A0, C)`` not observable (named modes), before solving.
    InfeasibleDesign
        Solver failure, margin not reached, or the independent re-check
        fails; the message gives the solver status, the achieved margin and
        the failed check.
    """
    A0 = real_matrix(A0, "A0")
    C = real_matrix(C, "C")
    n = A0.shape[0]
    if A0.shape != (n, n):
        raise DimensionError(f"A0 must be square, got shape {A0.shape}")
    if C.shape[1] != n:
        raise DimensionError(f"C has {C.shape[1]} columns, expected n = {n}")
    if not (isinstance(margin, (int, float)) and np.isfinite(margin) and 0 < margin < 1):
        raise SpecError(f"margin must be a number in (0, 1), got {margin!r}", key="margin")
    check_variant(variant)
    _refuse_unobservable(A0, C)
    prob = problem or one_shot_problem(A0, C, variant, kappa, blocks, pattern, solver, form, margin)
    prob.margin = float(margin)
    ceiling = prob.kappa if kappa_max is None else max(float(kappa_max), prob.kappa)
    tries: list[dict] = []
    while True:
        raw = prob.solve(A0, float(psi)) if solver_options is None else \
            prob.solve(A0, float(psi), solver_options=solver_options)
        active = kappa_active(raw["P"], prob.kappa) if "P" in raw else None
        tries.append({"kappa": prob.kappa, "t": raw["t"], "status": raw["status"],
                      "bound_active": active})
        if raw["t"] >= margin or active is False or prob.kappa >= ceiling:
            break
        prob = with_kappa(prob, min(prob.kappa * KAPPA_STEP, ceiling), margin)
    res = _accept(A0, C, float(psi), raw, prob, float(margin), variant, tries)
    return res


def _accept(A0: np.ndarray, C: np.ndarray, psi: float, raw: dict,
            prob: ObserverLMIProblem | ConicObserverLMI,
            margin: float, variant: str, tries: list | None = None) -> ObserverLMIResult:
    """Margin test and independent re-check of a raw solution; the result or `InfeasibleDesign`."""
    n = A0.shape[0]
    structure = ({"P": "dense"} if prob.blocks is None else
                 {"P": "block-diagonal", "blocks": prob.blocks,
                  "L_pattern": None if prob.mask is None else prob.mask.astype(int).tolist(),
                  "note": "structured P/L is more conservative than a dense P"})
    structure["form"] = prob.form
    if prob.form == "eliminated":
        structure["K"] = ("eliminated by the projection lemma (LMI of size 2n - rank C), "
                          "recovered in closed form")
        if "t_K" in raw:
            structure["gain_margin"] = raw["t_K"]
            structure["eliminated_lmi_margin"] = raw["t_P"]
    else:
        structure["K"] = "LMI variable"
    conic = isinstance(prob, ConicObserverLMI)
    nnz = int(np.count_nonzero(A0 if conic else prob.A0_pattern))
    structure["A0_parameter"] = (
        f"none: eliminated form rebuilt for Clarabel at each solve, no cvxpy (A0 as dense data, "
        f"{nnz} of {n * n} entries non-zero)" if conic and prob.form == "eliminated" else
        f"none: solved once, conic data built directly for Clarabel (A0 sparse data, {nnz} of "
        f"{n * n} entries)" if conic else
        "dense" if nnz == n * n else f"sparse, {nnz} of {n * n} entries (A0_pattern)")
    where = (f"solver {prob.solver} status {raw['status']}, achieved margin t = {raw['t']:.3g} "
             f"(required {margin:.3g}), psi = {psi:.6g} 1/s, variant {variant}, kappa = {prob.kappa:g}")
    if raw["t"] == -np.inf:
        raise InfeasibleDesign(f"observer LMI (28) not solved: {where}")
    if raw["t"] < margin:
        if "P" in raw and kappa_active(raw["P"], prob.kappa):
            tried = ", ".join(f"{tr['kappa']:g}" for tr in (tries or [{"kappa": prob.kappa}]))
            raise InfeasibleDesign(
                f"observer LMI (28) infeasible with the required margin within the conditioning "
                f"bound: {where}; the bound trace P <= kappa n is active at the optimum (trace P = "
                f"{float(np.trace(raw['P'])):.4g}, tried kappa = {tried}): raise the option "
                "'kappa_max' (or 'kappa') to allow a worse-conditioned P")
        raise InfeasibleDesign(
            f"observer LMI (28) infeasible with the required margin: {where}; the optimum of "
            "max t s.t. LMI <= -t I, P >= I, trace P <= kappa n certifies that no larger margin "
            "exists (the bound on P is not active)")
    with small_dense():          # 2n x 2n eigenvalues: one BLAS thread (tanksynth.analysis.blas)
        checks, eig, err = check_observer_lmi(A0, C, psi, raw["P"], raw["Q"], raw["K"], margin,
                                              raw["omega"])
        condition = float(np.linalg.cond(raw["P"]))
    failed = [c for c in checks if not c.passed]
    if failed:
        worst = "; ".join(f"{c.name}: {c.value:.4g} vs limit {c.limit:.4g}" for c in failed)
        raise InfeasibleDesign(f"observer LMI (28) solution fails the independent re-check ({worst}); "
                               f"{where}")
    return ObserverLMIResult(
        L=raw["L"], P=raw["P"], Q=raw["Q"], K=raw["K"], psi=float(psi), variant=variant,
        margin=float(margin), achieved_margin=raw["t"], kappa=prob.kappa, solver=prob.solver,
        status=raw["status"], solve_time=raw["solve_time"], checks=checks, lmi_eigenvalues=eig,
        error_eigenvalues=err, condition_P=condition,
        scaling={"omega_per_s": raw["omega"], "time_scaling": "A0/omega, psi/omega",
                 "output_row_scale": prob.output_scale.tolist(),
                 "normalisation": "P >= I, trace P <= kappa n",
                 "kappa_active": kappa_active(raw["P"], prob.kappa),
                 "trace_P_over_kappa_n": float(np.trace(raw["P"]) / (prob.kappa * n)),
                 "kappa_tries": list(tries or [])},
        structure=structure)


@dataclass(frozen=True)
class PsiSearch:
    """Result of "maximise psi" (quasi-convex search by bisection).

    Attributes
    ----------
    psi_max : float
        Largest ``psi`` (1/s) found feasible with the margin and re-check.
    psi_infeasible : float
        Smallest ``psi`` found infeasible (``inf`` if never).
    history : list of (float, bool)
        Every ``psi`` tried and whether it was feasible.
    result : ObserverLMIResult
        The re-checked design at ``psi_max``.
    bounded_by_kappa : bool
        True when ``psi_max`` is limited by the conditioning bound: the
        full-``Q`` variant (its maximum always grows with ``kappa``) or, for
        either variant, ``trace P = kappa n`` at ``psi_max`` (`kappa_active`).
    kappa_active : bool
        The bound ``trace P <= kappa n`` is active at ``psi_max``.
    """

    psi_max: float
    psi_infeasible: float
    history: list
    result: ObserverLMIResult
    bounded_by_kappa: bool
    kappa_active: bool = False

    def as_dict(self) -> dict:
        """JSON-friendly summary."""
        return {"psi_max": self.psi_max, "psi_infeasible": self.psi_infeasible,
                "trials": [[p, ok] for p, ok in self.history],
                "bounded_by_kappa": self.bounded_by_kappa, "kappa_active": self.kappa_active,
                "kappa": self.result.kappa,
                "note": ("psi_max grows with kappa: raise the option 'kappa' for a larger psi "
                         "(with a worse-conditioned P)") if self.bounded_by_kappa else
                        "the bound trace P <= kappa n is not active at psi_max",
                "method": "bisection on feasibility (LMI margin reached and independent re-check "
                          "passed; psi monotone); problem compiled once with cvxpy Parameters"}


def maximise_psi(A0: Any, C: Any, *, variant: str = "qI", margin: float = 1e-6, kappa: float = 1e4,
                 rtol: float = 1e-3, blocks: Sequence[Sequence[int]] | None = None,
                 pattern: Any = None, solver: str = "CLARABEL",
                 problem: ObserverLMIProblem | None = None, form: str = "auto",
                 solver_options: dict | None = None) -> PsiSearch:
    """Largest ``psi`` for which the observer LMI (28) is feasible.

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        1/s.
    C : array_like, shape (q, n)
    variant : {"qI", "full"}
    margin, kappa : float
        As in `observer_lmi`.
    rtol : float
        Relative accuracy of ``psi_max``.
    blocks, pattern, solver, problem, form, solver_options
        As in `observer_lmi`.

    Returns
    -------
    PsiSearch

    Raises
    ------
    UnobservableError
        ``(A0, C)`` not observable.
    InfeasibleDesign
        No design at ``psi = 0`` reaches the margin and passes the re-check.

    Notes
    -----
    A trial ``psi`` counts as feasible only if the solver reaches the
    margin *and* the design passes the independent re-check; the design of
    the last feasible trial is returned (not solved again). With ``C`` of
    rank ``n`` (every state measured) ``psi`` is unbounded in theory (any
    decay rate is reachable); the search then stops where the numbers
    break down or after the doublings of `bisect_feasible`.
    """
    A0 = real_matrix(A0, "A0")
    C = real_matrix(C, "C")
    if A0.shape != (A0.shape[0], A0.shape[0]) or C.shape[1] != A0.shape[0]:
        raise DimensionError(f"A0 is {A0.shape} and C is {C.shape}: expected (n, n) and (q, n)")
    if not (isinstance(margin, (int, float)) and np.isfinite(margin) and 0 < margin < 1):
        raise SpecError(f"margin must be a number in (0, 1), got {margin!r}", key="margin")
    check_variant(variant)
    _refuse_unobservable(A0, C)
    prob = problem or sweep_problem(A0, C, variant, kappa, blocks, pattern, solver, form, margin)
    prob.margin = float(margin)
    omega = prob.time_scale(A0, 0.0)
    extra: dict[str, Any] = {} if solver_options is None else {"solver_options": solver_options}

    designs: dict[float, ObserverLMIResult] = {}
    refused: list[str] = []

    def feasible(psi: float) -> bool:
        # Feasible = margin reached and the independent re-check passed: psi_max is a
        # checked design (kept, not solved again), never only a solver's claim.
        raw = prob.solve(A0, psi, omega, **extra)
        if raw["t"] < margin:
            refused.append(f"status {raw['status']}, achieved margin {raw['t']:.3g} < {margin:.3g}")
            return False
        try:
            designs[float(psi)] = _accept(A0, C, float(psi), raw, prob, float(margin), variant)
        except InfeasibleDesign as exc:
            refused.append(str(exc))
            return False
        return True

    if not feasible(0.0):
        reason = refused[-1].removeprefix("observer LMI (28) ")
        raise InfeasibleDesign(f"observer LMI (28) infeasible even with psi = 0: {reason}")
    lo, hi, history = bisect_feasible(feasible, start=1e-2 * omega, rtol=rtol)
    best = designs[lo]
    active = kappa_active(best.P, prob.kappa)
    return PsiSearch(lo, hi, history, best, variant == "full" or active, active)
