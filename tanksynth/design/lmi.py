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

Numerics (DESIGN.md): the problem is scaled before solving (time scale
``omega``: ``A0/omega``, ``psi/omega``; output rows of ``C`` normalised), the
homogeneous LMI is normalised by ``P >= I``, ``trace P <= kappa n`` and the strict
inequality is replaced by ``LMI <= -t I`` with ``t`` maximised; the design is
accepted only if ``t >= margin``. Every returned ``(P, Q, K)`` is then
re-checked in numpy in the original units (eigenvalues of the LMI blocks,
``P > 0``, ``Q > 0``, ``Re eig(A0 - L C) < -psi``); a failed check raises
`InfeasibleDesign` whatever the solver said.

Structured designs for tank networks: ``blocks`` makes ``P`` (and ``Q``)
block-diagonal and ``pattern`` restricts the non-zero entries of ``L``
(decentralised observer). Structure makes the LMI more conservative.

Scale (issue 3 section 6; `ObserverLMIProblem`): a free gain ``K`` is
eliminated by the projection lemma, which leaves an LMI of size ``2n - rank
C`` with the same optimal margin, and recovered in closed form (with ``C = I``
the LMI is just ``Q >= t I``); the ``A0`` Parameter covers only the non-zero
entries of ``A0``, so a network's sparsity reaches Clarabel's chordal
decomposition; block-diagonal ``P`` and ``Q`` are one vector variable each;
the Kalman observability test is skipped when ``C`` alone has rank ``n``.
None of this touches the re-check: every gain is checked against the full
``2n x 2n`` block matrix of eq. (28).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import cvxpy as cp
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps

from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError, UnobservableError
# Module import (not names): tanksynth.analysis.rank imports tanksynth.design, so
# this module may be loaded while verify.rank is still initialising.
from tanksynth.analysis import rank as _rank

__all__ = [
    "SOLVERS",
    "VARIANTS",
    "FORMS",
    "LMICheck",
    "ObserverLMIResult",
    "ObserverLMIProblem",
    "observer_lmi",
    "check_observer_lmi",
    "PsiSearch",
    "maximise_psi",
    "bisect_feasible",
]

#: Solvers accepted for the LMIs (Clarabel is the default, SCS for comparisons).
SOLVERS = ("CLARABEL", "SCS")
#: Variants of the ``Q`` matrix of eq. (28).
VARIANTS = ("qI", "full")
#: Forms of the LMI: ``K`` kept as a variable, or eliminated (projection lemma).
FORMS = ("auto", "full", "eliminated")

_ACCEPTED = ("optimal", "optimal_inaccurate")


def _matrix(value: Any, name: str) -> np.ndarray:
    try:
        arr = np.atleast_2d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a real 2-D array") from None
    if arr.ndim != 2:
        raise DimensionError(f"{name} must be 2-D, got {arr.ndim} dimensions")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} has non-finite entries")
    return arr


def _sym(M: np.ndarray) -> np.ndarray:
    return 0.5 * (M + M.T)


@dataclass(frozen=True)
class LMICheck:
    """One item of the independent numpy re-check.

    Attributes
    ----------
    name : str
        What was checked (``"LMI (28) block matrix"``, ``"P > 0"``, ...).
    value : float
        The checked quantity (a largest or smallest eigenvalue, or a real
        part), in the units given by ``unit``.
    limit : float
        The bound it had to satisfy.
    passed : bool
    unit : str
        Units/normalisation of ``value``.
    """

    name: str
    value: float
    limit: float
    passed: bool
    unit: str = ""

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"name": self.name, "value": self.value, "limit": self.limit,
                "passed": self.passed, "unit": self.unit}


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
        show the margin the returned matrices reach.
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
        normalised problem (should all be <= -margin).
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


def _check_variant(variant: str) -> None:
    if variant not in VARIANTS:
        raise SpecError(f"unknown LMI variant {variant!r}; expected one of {list(VARIANTS)}",
                        key="variant")


def _check_solver(solver: str) -> None:
    if solver not in SOLVERS:
        raise SpecError(f"unknown solver {solver!r}; expected one of {list(SOLVERS)}", key="solver")


def _structure(n: int, q: int, blocks: Sequence[Sequence[int]] | None,
               pattern: Any) -> tuple[list[list[int]] | None, np.ndarray | None]:
    if blocks is not None:
        blocks = [sorted(int(i) for i in b) for b in blocks]
        flat = sorted(i for b in blocks for i in b)
        if flat != list(range(n)) or any(not b for b in blocks):
            raise DimensionError(f"blocks must partition the state indices 0..{n - 1}, got {blocks}")
    mask = None
    if pattern is not None:
        mask = np.asarray(pattern, dtype=float)
        if mask.shape != (n, q) or not np.all(np.isin(mask, (0.0, 1.0))):
            raise DimensionError(f"pattern must be a 0/1 array of shape ({n}, {q}), got shape "
                                 f"{mask.shape}")
        mask = mask.astype(bool)
        if blocks is not None:
            for b in blocks:
                if not np.all(mask[b] == mask[b[0]]):
                    raise DimensionError(
                        f"pattern rows differ inside block {b}: with a block-diagonal P, L = P^-1 K "
                        "mixes the rows of a block, so the allowed outputs must be the same for "
                        "every state of a block")
        elif not mask.all():
            raise DimensionError("a gain pattern needs a block partition of P (blocks=...): with a "
                                 "dense P, L = P^-1 K is dense whatever the pattern of K")
    return blocks, mask


def _sparse_parameter(pattern: np.ndarray, name: str) -> tuple[Any, Callable[[np.ndarray], None]]:
    """A cvxpy Parameter over the ``True`` entries of ``pattern`` only.

    Returns the matrix expression and a setter taking the full matrix. With a
    full ``(n, n)`` Parameter cvxpy must treat every entry of ``A0' P`` as
    potentially non-zero; over the pattern the LMI keeps the network's
    sparsity, which Clarabel's chordal decomposition exploits.
    """
    shape = pattern.shape
    idx = np.flatnonzero(pattern.ravel(order="F"))
    if idx.size == pattern.size:
        par = cp.Parameter(shape, name=name)

        def set_full(M: np.ndarray) -> None:
            par.value = M

        return par, set_full
    if idx.size == 0:
        return np.zeros(shape), lambda M: None
    par = cp.Parameter(idx.size, name=f"{name}_entries")
    S = sps.csc_matrix((np.ones(idx.size), (idx, np.arange(idx.size))), shape=(pattern.size, idx.size))
    expr = cp.reshape(S @ par, shape, order="F")

    def set_entries(M: np.ndarray) -> None:
        par.value = M.ravel(order="F")[idx]

    return expr, set_entries


def _symmetric(n: int, blocks: list[list[int]] | None, name: str) -> tuple[Any, list, Any]:
    """A symmetric, possibly block-diagonal, matrix variable.

    Returns ``(matrix expression, constraints "matrix >= I", trace)``. A
    block-diagonal matrix is one vector variable mapped through a sparse
    matrix (one cvxpy expression, not a sum of ``E Pb E'`` over the blocks,
    whose compile time grows with the number of blocks); ``>= I`` is imposed
    per block, as a linear bound for 1x1 blocks.
    """
    if blocks is None:
        V = cp.Variable((n, n), symmetric=True, name=name)
        return V, [V >> np.eye(n)], cp.trace(V)
    rows, cols, diag, singles = [], [], [], []
    local: list[tuple[int, int, list[int], list[int]]] = []     # (offset, size, rows, cols)
    m = 0
    for b in blocks:
        d, first, lr, lc = len(b), m, [], []
        for i in range(d):
            for j in range(i, d):
                for a, c in {(i, j), (j, i)}:
                    rows.append(b[a] + n * b[c])
                    cols.append(m)
                    lr.append(a + d * c)
                    lc.append(m - first)
                if i == j:
                    diag.append(m)
                m += 1
        if d == 1:
            singles.append(first)
        else:
            local.append((first, d, lr, lc))
    v = cp.Variable(m, name=f"{name}_entries")
    S = sps.csc_matrix((np.ones(len(rows)), (rows, cols)), shape=(n * n, m))
    M = cp.reshape(S @ v, (n, n), order="F")
    cons: list = []
    if singles:
        cons.append(v[np.array(singles)] >= 1.0)
    for first, d, lr, lc in local:
        Sb = sps.csc_matrix((np.ones(len(lr)), (lr, lc)), shape=(d * d, d * (d + 1) // 2))
        Mb = cp.reshape(Sb @ v[first:first + d * (d + 1) // 2], (d, d), order="F")
        cons.append(0.5 * (Mb + Mb.T) >> np.eye(d))
    return M, cons, cp.sum(v[np.array(diag)])


def _output_split(Cs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal bases of the row space ``V1`` and null space ``V2`` of ``Cs``.

    Also ``W = pinv(Cs V1)``, so that ``G V1' = (G W) Cs`` for any ``G``. When
    every output measures one state (``C`` a row selection), ``V1`` and ``V2``
    are columns of the identity (the eliminated LMI keeps the sparsity);
    otherwise they come from the SVD of ``Cs``.
    """
    q, n = Cs.shape
    nz = Cs != 0
    eye = np.eye(n)
    if np.all(nz.sum(axis=1) == 1):
        seen = sorted(set(int(j) for j in np.argmax(nz, axis=1)))
        V1, V2 = eye[:, seen], eye[:, [j for j in range(n) if j not in set(seen)]]
    else:
        _, s, vh = np.linalg.svd(Cs)
        r = int(np.sum(s > max(Cs.shape) * np.finfo(float).eps * s[0]))
        V1, V2 = vh[:r].T, vh[r:].T
    return V1, V2, np.linalg.pinv(Cs @ V1)


class ObserverLMIProblem:
    """The scaled observer LMI compiled once (cvxpy Parameters for ``A0`` and ``psi``).

    Re-solving with another ``A0`` or ``psi`` (bisection on ``psi``, search
    over weightings) does not recompile the problem.

    Two forms of the same LMI (``form``):

    ``"full"``
        Eq. (28) as printed, a ``2n x 2n`` LMI in ``P``, ``Q``, ``K``.
    ``"eliminated"``
        ``K`` eliminated by the projection lemma (Gahinet and Apkarian
        1994). With ``V1``, ``V2`` orthonormal bases of the row space and the
        null space of ``C`` (rank ``r``), a ``K`` exists for a margin ``t``
        iff ``Q > t I`` and, with ``X0 = A0' P + P A0 + psi^2 Q``::

            [ V2' X0 V2   V2' P ]
            [ P V2         -Q   ]  <=  -t I        (size 2n - r)

        so the optimal margin ``t*`` is that of eq. (28) itself. ``K`` is
        then recovered in closed form (`recover_gain`) for the margin
        ``t_K = min(1, (t_P + margin) / 2)``, where ``t_P`` is the margin
        the returned ``P``, ``Q`` reach in the eliminated LMI (recomputed in
        numpy): half-way between the required and the reached margin, so
        the gain stays bounded. With ``C = I`` (every state measured) the
        eliminated LMI is just ``Q >= t I``. This needs ``K`` free: a gain
        pattern needs the full form.
    ``"auto"`` (default)
        ``"eliminated"`` when ``K`` is free (no ``pattern``), else ``"full"``.

    Parameters
    ----------
    n : int
        Number of states.
    C : array_like, shape (q, n)
        Output matrix (fixed; rows are normalised internally).
    variant : {"qI", "full"}
    kappa : float
        Conditioning bound: ``P >= I``, ``trace P <= kappa n`` (> 1).
    blocks : sequence of sequence of int, optional
        Partition of the states: ``P`` and ``Q`` are block-diagonal.
    pattern : array_like of 0/1, shape (n, q), optional
        Allowed non-zero entries of ``L`` (needs ``blocks``).
    solver : {"CLARABEL", "SCS"}
    A0_pattern : array_like of bool, shape (n, n), optional
        Entries of ``A0`` that may be non-zero (default: all). The
        Parameter covers only these entries, so the LMI keeps the sparsity
        of the network (a full Parameter makes every entry of ``A0' P``
        potentially non-zero); `solve` refuses an ``A0`` with a non-zero
        outside the pattern. `observer_lmi` and `maximise_psi` pass
        ``A0 != 0``.
    form : {"auto", "full", "eliminated"}
    margin : float
        Margin the recovered gain of the eliminated form is built for
        (`observer_lmi` sets it to its own ``margin``).
    solver_options : mapping, optional
        Options passed to the solver at every solve (e.g. Clarabel's
        ``tol_gap_abs``); `solve` may override them per call.
    """

    def __init__(self, n: int, C: Any, variant: str = "qI", kappa: float = 1e4,
                 blocks: Sequence[Sequence[int]] | None = None, pattern: Any = None,
                 solver: str = "CLARABEL", *, A0_pattern: Any = None, form: str = "auto",
                 margin: float = 1e-6, solver_options: dict | None = None):
        _check_variant(variant)
        _check_solver(solver)
        if form not in FORMS:
            raise SpecError(f"unknown LMI form {form!r}; expected one of {list(FORMS)}", key="form")
        C = _matrix(C, "C")
        if C.shape[1] != n:
            raise DimensionError(f"C has {C.shape[1]} columns, expected n = {n}")
        if not (np.isfinite(kappa) and kappa > 1):
            raise SpecError(f"kappa must be a number > 1, got {kappa!r}", key="kappa")
        q = C.shape[0]
        row = np.linalg.norm(C, axis=1)
        if np.any(row == 0):
            raise DimensionError("C has a zero row (an output that measures nothing)")
        self.n, self.q, self.variant, self.kappa, self.solver = n, q, variant, float(kappa), solver
        self.C = C
        self.output_scale = 1.0 / row
        Cs = C * self.output_scale[:, None]
        self.Cs = Cs
        self.blocks, self.mask = _structure(n, q, blocks, pattern)
        if A0_pattern is None:
            self.A0_pattern = np.ones((n, n), dtype=bool)
        else:
            self.A0_pattern = np.asarray(A0_pattern, dtype=bool)
            if self.A0_pattern.shape != (n, n):
                raise DimensionError(f"A0_pattern has shape {self.A0_pattern.shape}, expected "
                                     f"({n}, {n})")
        if form == "auto":
            form = "eliminated" if self.mask is None else "full"
        if form == "eliminated" and self.mask is not None:
            raise SpecError("the eliminated form needs a free gain K: a gain pattern needs "
                            "form='full'", key="form")
        self.form = form
        self.margin = float(margin)
        self.solver_options = dict(solver_options or {})
        self._options_used: set[str] = set()
        self.t2 = cp.Parameter(nonneg=True, name="psi2_scaled")
        self.t = cp.Variable(name="t")
        I = np.eye(n)
        P, p_cons, p_trace = _symmetric(n, self.blocks, "P")
        self.P = P
        if variant == "qI":
            self.qv = cp.Variable(name="q")
            Q = self.qv * I
        else:
            Q, _, _ = _symmetric(n, self.blocks, "Q")
            self.qv = Q
        self.Q = Q
        if form == "full":
            self.A0s, self._set_A0 = _sparse_parameter(self.A0_pattern, "A0_scaled")
            if self.mask is None:
                self.Kv = cp.Variable((n, q), name="K")
                K = self.Kv
            else:
                idx = np.flatnonzero(self.mask.ravel(order="F"))
                S = sps.csc_matrix((np.ones(idx.size), (idx, np.arange(idx.size))),
                                   shape=(n * q, idx.size))
                self.Kv = cp.Variable(idx.size, name="K_entries")
                K = cp.reshape(S @ self.Kv, (n, q), order="F")
            self.K = K
            X = self.A0s.T @ P + P @ self.A0s - Cs.T @ K.T - K @ Cs + self.t2 * Q
            M = cp.bmat([[X, P], [P, -Q]])
            lmi = [0.5 * (M + M.T) << -self.t * np.eye(2 * n)]
        else:
            self.V1, self.V2, self._W = _output_split(Cs)
            V2 = self.V2
            self.Kv = self.K = None
            # The A0 Parameter enters as Y = A0 V2 only (pattern of A0_pattern V2).
            ypat = (self.A0_pattern.astype(float) @ (V2 != 0).astype(float)) != 0
            self.A0s, self._set_Y = _sparse_parameter(ypat, "A0V2_scaled")
            self._set_A0 = lambda A: self._set_Y(A @ V2)
            if V2.shape[1] == 0:
                lmi = [self.qv >= self.t] if variant == "qI" else \
                      [0.5 * (Q + Q.T) >> self.t * I]
            else:
                PV2 = P @ V2
                X22 = self.A0s.T @ PV2 + V2.T @ P @ self.A0s + self.t2 * (V2.T @ Q @ V2)
                M = cp.bmat([[X22, PV2.T], [PV2, -Q]])
                lmi = [0.5 * (M + M.T) << -self.t * np.eye(n + V2.shape[1])]
        # Normalisation of the homogeneous LMI: P >= I and trace(P) <= kappa n (a linear
        # conditioning bound, cond(P) <= kappa n; cheaper than a second PSD cone P <= kappa I).
        cons = lmi + p_cons + [p_trace <= self.kappa * n, self.t <= 1.0]
        self.problem = cp.Problem(cp.Maximize(self.t), cons)

    def time_scale(self, A0: np.ndarray, psi: float) -> float:
        """The time scale ``omega`` (1/s) used to normalise ``A0`` and ``psi``."""
        w = max(float(np.linalg.norm(A0, 2)), 0.0)
        return w if w > 0 else (psi if psi > 0 else 1.0)

    def _options(self, override: dict | None) -> dict:
        """Solver options for one solve.

        cvxpy may keep the Clarabel solver of a problem between solves
        (when Clarabel allows a data update) and then updates only the
        settings it is given, so an option set once could stick: every
        option used before and not given now is reset to its Clarabel
        default.
        """
        opts = {**self.solver_options, **(override or {})}
        if self.solver == "CLARABEL":
            stale = self._options_used - set(opts)
            if stale:
                import clarabel

                defaults = clarabel.DefaultSettings()
                opts.update({k: getattr(defaults, k) for k in stale})
        self._options_used |= set(opts)
        return opts

    def solve(self, A0: np.ndarray, psi: float, omega: float | None = None, *,
              margin: float | None = None, solver_options: dict | None = None) -> dict:
        """Solve the scaled problem; return the raw (unchecked) solution.

        Parameters
        ----------
        A0 : ndarray, shape (n, n)
            Mean vertex matrix (1/s); zero outside ``A0_pattern``.
        psi : float
            Lipschitz constant (1/s), >= 0.
        omega : float, optional
            Time scale (1/s); default `time_scale`.
        margin : float, optional
            Margin the recovered gain is built for (eliminated form);
            default the problem's ``margin``.
        solver_options : mapping, optional
            Solver options for this solve (over the problem's).

        Returns
        -------
        dict
            ``status``, ``t`` (optimal margin of eq. 28, ``-inf`` on
            failure), and when solved ``P``, ``Q``, ``K``, ``L`` in original
            units, ``omega``, ``solve_time`` (solver and gain recovery, s);
            for the eliminated form also ``t_P`` (margin of the returned
            ``P``, ``Q`` in the eliminated LMI) and ``t_K`` (margin the
            gain was built for).
        """
        A0 = _matrix(A0, "A0")
        if A0.shape != (self.n, self.n):
            raise DimensionError(f"A0 has shape {A0.shape}, expected ({self.n}, {self.n})")
        outside = (A0 != 0) & ~self.A0_pattern
        if outside.any():
            i, j = np.argwhere(outside)[0]
            raise DimensionError(f"A0 has {int(outside.sum())} non-zero entries outside the "
                                 f"A0_pattern the problem was compiled for (first at ({i}, {j})); "
                                 "build the problem with a wider A0_pattern")
        if not (np.isfinite(psi) and psi >= 0):
            raise SpecError(f"psi must be a finite number >= 0, got {psi!r}", key="psi")
        w = float(omega) if omega is not None else self.time_scale(A0, psi)
        As, t2 = A0 / w, (psi / w) ** 2
        self._set_A0(As)
        self.t2.value = t2
        opts = self._options(solver_options)
        start = time.perf_counter()
        try:
            with warnings.catch_warnings():
                # "Solution may be inaccurate": the status says so and the re-check decides.
                warnings.simplefilter("ignore", UserWarning)
                self.problem.solve(solver=self.solver, **opts)
            status = str(self.problem.status)
        except cp.error.SolverError as exc:
            return {"status": f"solver_error: {exc}", "t": -np.inf, "omega": w,
                    "solve_time": time.perf_counter() - start}
        out: dict = {"status": status, "omega": w}
        if status not in _ACCEPTED or self.t.value is None:
            out["t"] = -np.inf
            out["solve_time"] = time.perf_counter() - start
            return out
        P = _sym(np.asarray(self.P.value, dtype=float))
        Qs = np.asarray(self.Q.value, dtype=float)
        Qs = _sym(np.atleast_2d(Qs)) if Qs.ndim == 2 else float(Qs) * np.eye(self.n)
        if self.form == "full":
            Ks = np.asarray(self.K.value, dtype=float).reshape(self.n, self.q)
        else:
            Ks, t_P, t_K = self.recover_gain(As, t2, P, Qs,
                                             self.margin if margin is None else float(margin))
            out.update({"t_P": t_P, "t_K": t_K})
        # Back to original units: Q = Qs / omega, K = omega Ks S_y (see module notes).
        K = w * Ks * self.output_scale[None, :]
        Q = Qs / w
        L = np.linalg.solve(P, K)
        out.update({"t": float(self.t.value), "P": P, "Q": Q, "K": K, "L": L,
                    "solve_time": time.perf_counter() - start})
        return out

    def recover_gain(self, As: np.ndarray, t2: float, P: np.ndarray, Qs: np.ndarray,
                     margin: float) -> tuple[np.ndarray, float, float]:
        """Closed-form ``K`` for given ``P``, ``Q`` (eliminated form, scaled units).

        In the coordinates ``T = diag([V1 V2], I)`` the block matrix of eq.
        (28) plus ``t I`` reads, with ``a`` the ``r`` measured directions,
        ``b`` the unmeasured ones, ``c`` the second block row and ``H = [Ha;
        Hb] = V' K Cs V1``::

            [ Naa - Ha - Ha'   Nab - Hb'   Nac ]
            [ Nba - Hb         Nbb         Nbc ]
            [ Nca              Ncb         Ncc ]

        ``Ncc = t I - Q < 0``. Its Schur complement is ``Z - [Ha + Ha', Hb';
        Hb, 0]`` with ``Z = V' Y V + t I``, ``Y = X0 + P (Q - t I)^-1 P``.
        ``Hb = Zba`` and ``Ha = Zaa / 2 + t I / 2`` leave ``diag(-t I, Zbb)``,
        and ``Zbb < 0`` is the eliminated LMI at margin ``t``: the whole
        matrix is negative definite, i.e. eq. (28) holds with a margin above
        ``t``. So ``K Cs V1 = G = (V2 V2' + V1 V1' / 2) Y V1 + t V1`` and
        ``K = G pinv(Cs V1)``. The gain does not grow as ``t`` approaches
        the margin ``t_P`` of ``(P, Q)`` (only ``Q - t I`` is inverted).

        Returns
        -------
        K : ndarray, shape (n, q)
            Scaled gain variable.
        t_P : float
            Margin of ``(P, Q)`` in the eliminated LMI (``-`` its largest
            eigenvalue, recomputed here).
        t_K : float
            Margin the gain is built for: ``min(1, t_P - (t_P - margin) / 10)``
            when ``t_P > margin`` (else below ``t_P``; the design is then
            refused).
        """
        V1, V2 = self.V1, self.V2
        X0 = As.T @ P + P @ As + t2 * Qs
        S0 = _sym(np.block([[V2.T @ X0 @ V2, V2.T @ P], [P @ V2, -Qs]]))
        t_P = float(-np.max(np.linalg.eigvalsh(S0)))
        if t_P > margin:
            t_K = min(1.0, t_P - 0.1 * (t_P - margin))
        else:
            t_K = t_P - 0.5 * abs(t_P) - 1e-12
        Qt = Qs - t_K * np.eye(self.n)                       # positive definite (block of S0)
        try:
            PQP = P @ sla.cho_solve(sla.cho_factor(Qt), P)
        except np.linalg.LinAlgError:
            PQP = P @ np.linalg.lstsq(Qt, P, rcond=None)[0]
        Y = _sym(X0 + PQP)
        YV1 = Y @ V1
        G = V2 @ (V2.T @ YV1) + 0.5 * V1 @ (V1.T @ YV1) + t_K * V1
        return G @ self._W, t_P, t_K


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
    K : array_like, shape (n, q)
    margin : float
        Required margin of the normalised LMI (``<= -margin``).
    omega : float
        Time scale (1/s) used when solving.
    tolerance : float
        Fraction of ``margin`` granted to solver round-off: the largest
        normalised eigenvalue must be ``<= -(1 - tolerance) margin``.

    Returns
    -------
    checks : tuple of LMICheck
    lmi_eigenvalues : ndarray, shape (2n,)
        Of the normalised block matrix.
    error_eigenvalues : ndarray, shape (n,)
        Of ``A0 - P^-1 K C`` (1/s).
    """
    A0, C, P, Q, K = (_matrix(v, nm) for v, nm in ((A0, "A0"), (C, "C"), (P, "P"), (Q, "Q"), (K, "K")))
    n = A0.shape[0]
    if P.shape != (n, n) or Q.shape != (n, n) or K.shape != (n, C.shape[0]) or C.shape[1] != n:
        raise DimensionError("shapes of A0, C, P, Q, K do not match")
    X = A0.T @ P + P @ A0 - C.T @ K.T - K @ C + psi ** 2 * Q
    M = _sym(np.block([[X, P], [P, -Q]]))
    d = np.concatenate([np.full(n, omega ** -0.5), np.full(n, omega ** 0.5)])
    Mn = M * d[:, None] * d[None, :]
    eig = np.linalg.eigvalsh(Mn)
    eig_raw = float(np.max(np.linalg.eigvalsh(M)))
    L = np.linalg.solve(P, K)
    err = np.linalg.eigvals(A0 - L @ C)
    pmin = float(np.min(np.linalg.eigvalsh(_sym(P))))
    qmin = float(np.min(np.linalg.eigvalsh(_sym(Q))))
    need = -(1.0 - tolerance) * margin
    checks = (
        LMICheck("LMI (28) block matrix, normalised (max eigenvalue <= -(1-tol) margin)",
                 float(eig.max()), need, bool(eig.max() <= need), "normalised"),
        LMICheck("LMI (28) block matrix, original units (max eigenvalue < 0)",
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
    if C.shape[0] >= n and np.linalg.matrix_rank(C) == n:
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
                 solver_options: dict | None = None) -> ObserverLMIResult:
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
        0/1 allowed entries of ``L`` (decentralised gain).
    solver : {"CLARABEL", "SCS"}
    problem : ObserverLMIProblem, optional
        A compiled problem to reuse (must match ``C``, variant, structure);
        its ``margin`` (target of the recovered gain) is set to ``margin``.
    form : {"auto", "full", "eliminated"}
        LMI form (`ObserverLMIProblem`); ``"auto"`` eliminates ``K`` unless
        a gain pattern is given. Ignored when ``problem`` is given.
    solver_options : mapping, optional
        Solver options (e.g. Clarabel tolerances) for this solve.

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
    A0 = _matrix(A0, "A0")
    C = _matrix(C, "C")
    n = A0.shape[0]
    if A0.shape != (n, n):
        raise DimensionError(f"A0 must be square, got shape {A0.shape}")
    if C.shape[1] != n:
        raise DimensionError(f"C has {C.shape[1]} columns, expected n = {n}")
    if not (isinstance(margin, (int, float)) and np.isfinite(margin) and 0 < margin < 1):
        raise SpecError(f"margin must be a number in (0, 1), got {margin!r}", key="margin")
    _check_variant(variant)
    _refuse_unobservable(A0, C)
    prob = problem or ObserverLMIProblem(n, C, variant, kappa, blocks, pattern, solver,
                                         A0_pattern=A0 != 0, form=form, margin=margin)
    prob.margin = float(margin)
    raw = prob.solve(A0, float(psi)) if solver_options is None else \
        prob.solve(A0, float(psi), solver_options=solver_options)
    return _accept(A0, C, float(psi), raw, prob, float(margin), variant)


def _accept(A0: np.ndarray, C: np.ndarray, psi: float, raw: dict, prob: ObserverLMIProblem,
            margin: float, variant: str) -> ObserverLMIResult:
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
    nnz = int(np.count_nonzero(prob.A0_pattern))
    structure["A0_parameter"] = ("dense" if nnz == n * n else
                                 f"sparse, {nnz} of {n * n} entries (A0_pattern)")
    where = (f"solver {prob.solver} status {raw['status']}, achieved margin t = {raw['t']:.3g} "
             f"(required {margin:.3g}), psi = {psi:.6g} 1/s, variant {variant}, kappa = {prob.kappa:g}")
    if raw["t"] == -np.inf:
        raise InfeasibleDesign(f"observer LMI (28) not solved: {where}")
    if raw["t"] < margin:
        raise InfeasibleDesign(
            f"observer LMI (28) infeasible with the required margin: {where}; the optimum of "
            "max t s.t. LMI <= -t I, P >= I, trace P <= kappa n certifies that no larger margin "
            "exists")
    checks, eig, err = check_observer_lmi(A0, C, psi, raw["P"], raw["Q"], raw["K"], margin, raw["omega"])
    failed = [c for c in checks if not c.passed]
    if failed:
        worst = "; ".join(f"{c.name}: {c.value:.4g} vs limit {c.limit:.4g}" for c in failed)
        raise InfeasibleDesign(f"observer LMI (28) solution fails the independent re-check ({worst}); "
                               f"{where}")
    return ObserverLMIResult(
        L=raw["L"], P=raw["P"], Q=raw["Q"], K=raw["K"], psi=float(psi), variant=variant,
        margin=float(margin), achieved_margin=raw["t"], kappa=prob.kappa, solver=prob.solver,
        status=raw["status"], solve_time=raw["solve_time"], checks=checks, lmi_eigenvalues=eig,
        error_eigenvalues=err, condition_P=float(np.linalg.cond(raw["P"])),
        scaling={"omega_per_s": raw["omega"], "time_scaling": "A0/omega, psi/omega",
                 "output_row_scale": prob.output_scale.tolist(),
                 "normalisation": "P >= I, trace P <= kappa n"},
        structure=structure)


def bisect_feasible(feasible: Callable[[float], bool], start: float, rtol: float = 1e-3,
                    max_doublings: int = 40, max_steps: int = 60) -> tuple[float, float, list]:
    """Largest ``x >= 0`` with ``feasible(x)`` for a monotone predicate.

    Feasibility must be monotone (feasible at ``x`` implies feasible below
    ``x``), which holds for ``psi`` in eq. (28): the ``psi^2 Q`` term only
    grows. The bracket is found by doubling from ``start``.

    Parameters
    ----------
    feasible : callable
        ``feasible(x) -> bool``.
    start : float
        First trial value (> 0).
    rtol : float
        Relative width of the final bracket.
    max_doublings, max_steps : int
        Limits of the bracketing and of the bisection.

    Returns
    -------
    lo : float
        Largest value found feasible (0.0 if only 0 is).
    hi : float
        Smallest value found infeasible (``inf`` if none found).
    history : list of (float, bool)
        Every trial.
    """
    history: list = []

    def test(x: float) -> bool:
        ok = bool(feasible(x))
        history.append((float(x), ok))
        return ok

    lo, hi = 0.0, float(start)
    for _ in range(max_doublings):
        if test(hi):
            lo, hi = hi, 2.0 * hi
        else:
            break
    else:
        return lo, float("inf"), history
    for _ in range(max_steps):
        if hi - lo <= rtol * hi:
            break
        mid = 0.5 * (lo + hi)
        if test(mid):
            lo = mid
        else:
            hi = mid
    return lo, hi, history


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
        True for the full-``Q`` variant: its maximum grows with ``kappa``.
    """

    psi_max: float
    psi_infeasible: float
    history: list
    result: ObserverLMIResult
    bounded_by_kappa: bool

    def as_dict(self) -> dict:
        """JSON-friendly summary."""
        return {"psi_max": self.psi_max, "psi_infeasible": self.psi_infeasible,
                "trials": [[p, ok] for p, ok in self.history],
                "bounded_by_kappa": self.bounded_by_kappa,
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
    A0 = _matrix(A0, "A0")
    C = _matrix(C, "C")
    if A0.shape != (A0.shape[0], A0.shape[0]) or C.shape[1] != A0.shape[0]:
        raise DimensionError(f"A0 is {A0.shape} and C is {C.shape}: expected (n, n) and (q, n)")
    if not (isinstance(margin, (int, float)) and np.isfinite(margin) and 0 < margin < 1):
        raise SpecError(f"margin must be a number in (0, 1), got {margin!r}", key="margin")
    _check_variant(variant)
    _refuse_unobservable(A0, C)
    prob = problem or ObserverLMIProblem(A0.shape[0], C, variant, kappa, blocks, pattern, solver,
                                         A0_pattern=A0 != 0, form=form, margin=margin)
    prob.margin = float(margin)
    omega = prob.time_scale(A0, 0.0)
    extra = {} if solver_options is None else {"solver_options": solver_options}

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
        raise InfeasibleDesign(f"observer LMI (28) infeasible even with psi = 0: {refused[-1]}")
    lo, hi, history = bisect_feasible(feasible, start=1e-2 * omega, rtol=rtol)
    return PsiSearch(lo, hi, history, designs[lo], variant == "full")
