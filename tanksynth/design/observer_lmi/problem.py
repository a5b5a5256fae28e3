"""The scaled observer LMI of seed 001 eq. (28), compiled once with cvxpy.

`ObserverLMIProblem` is the problem `tanksynth.design.observer_lmi.lmi.observer_lmi` and
`tanksynth.design.observer_lmi.lmi.maximise_psi` solve; the acceptance test and the
independent numpy re-check are in `tanksynth.design.observer_lmi.lmi`.

Structured designs for tank networks: ``blocks`` makes ``P`` (and ``Q``)
block-diagonal and ``pattern`` restricts the non-zero entries of ``L``
(decentralised observer). Structure makes the LMI more conservative.

Scale (issue 3 section 6; `ObserverLMIProblem`): a free gain ``K`` is
eliminated by the projection lemma, which leaves an LMI of size ``2n - rank
C`` with the same optimal margin, and recovered in closed form (with ``C = I``
the LMI is just ``Q >= t I``); the ``A0`` Parameter covers only the non-zero
entries of ``A0``, so a network's sparsity reaches Clarabel's chordal
decomposition; block-diagonal ``P`` and ``Q`` are one vector variable each.
The raw solution returned by `ObserverLMIProblem.solve` is unchecked.
"""

from __future__ import annotations

import time
import warnings
from typing import TYPE_CHECKING, Any, Callable, Sequence

import clarabel
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps

from tanksynth.analysis.blas import small_dense
from tanksynth.design.conic import ACCEPTED
from tanksynth.design.lmi_checks import check_solver
from tanksynth.design.matrices import real_matrix, symmetrized
from tanksynth.errors import DimensionError, SpecError

if TYPE_CHECKING:
    import cvxpy as cp

__all__ = [
    "VARIANTS",
    "FORMS",
    "ObserverLMIProblem",
    "check_variant",
    "checked_structure",
    "output_split",
    "recovered_gain",
]

#: Variants of the ``Q`` matrix of eq. (28).
VARIANTS = ("qI", "full")
#: Forms of the LMI: ``K`` kept as a variable, or eliminated (projection lemma).
FORMS = ("auto", "full", "eliminated")


def check_variant(variant: str) -> None:
    """Refuse a ``Q`` variant outside `VARIANTS` (`SpecError` keyed ``variant``).

    Parameters
    ----------
    variant : str
        ``"qI"`` or ``"full"``.
    """
    if variant not in VARIANTS:
        raise SpecError(f"unknown LMI variant {variant!r}; expected one of {list(VARIANTS)}",
                        key="variant")


def checked_structure(n: int, q: int, blocks: Sequence[Sequence[int]] | None,
                      pattern: Any) -> tuple[list[list[int]] | None, np.ndarray | None]:
    """The block partition of ``P`` and the gain pattern of ``L``, checked together.

    Parameters
    ----------
    n : int
        Number of states.
    q : int
        Number of outputs.
    blocks : sequence of sequence of int, optional
        A partition of the state indices ``0 .. n-1``: ``P`` (and ``Q``) block-diagonal.
    pattern : array_like of 0/1, shape (n, q), optional
        Allowed non-zero entries of ``L`` (dimensionless); needs ``blocks``, with the same
        allowed outputs for every state of a block (``L = P^-1 K`` mixes a block's rows).

    Returns
    -------
    blocks : list of list of int or None
        Each block sorted.
    mask : ndarray of bool, shape (n, q), or None
        The pattern.

    Raises
    ------
    DimensionError
        Not a partition, a pattern of another shape or not 0/1, a pattern without blocks, or
        rows of a block with different patterns.
    """
    partition = None if blocks is None else [sorted(int(i) for i in b) for b in blocks]
    if partition is not None:
        flat = sorted(i for b in partition for i in b)
        if flat != list(range(n)) or any(not b for b in partition):
            raise DimensionError(f"blocks must partition the state indices 0..{n - 1}, got {partition}")
    mask = None
    if pattern is not None:
        mask = np.asarray(pattern, dtype=float)
        if mask.shape != (n, q) or not np.all(np.isin(mask, (0.0, 1.0))):
            raise DimensionError(f"pattern must be a 0/1 array of shape ({n}, {q}), got shape "
                                 f"{mask.shape}")
        mask = mask.astype(bool)
        if partition is not None:
            for b in partition:
                if not np.all(mask[b] == mask[b[0]]):
                    raise DimensionError(
                        f"pattern rows differ inside block {b}: with a block-diagonal P, L = P^-1 K "
                        "mixes the rows of a block, so the allowed outputs must be the same for "
                        "every state of a block")
        elif not mask.all():
            raise DimensionError("a gain pattern needs a block partition of P (blocks=...): with a "
                                 "dense P, L = P^-1 K is dense whatever the pattern of K")
    return partition, mask


def _sparse_parameter(pattern: np.ndarray, name: str) -> tuple[Any, Callable[[np.ndarray], None]]:
    """A cvxpy Parameter over the ``True`` entries of ``pattern`` only.

    Returns the matrix expression and a setter taking the full matrix. With a
    full ``(n, n)`` Parameter cvxpy must treat every entry of ``A0' P`` as
    potentially non-zero; over the pattern the LMI keeps the network's
    sparsity, which Clarabel's chordal decomposition exploits.
    """
    import cvxpy as cp      # here: cvxpy's import costs seconds and the Clarabel routes never need it

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
    import cvxpy as cp      # here: cvxpy's import costs seconds and the Clarabel routes never need it

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
        cons.append(symmetrized(Mb) >> np.eye(d))
    return M, cons, cp.sum(v[np.array(diag)])


def output_split(Cs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal bases of the row space ``V1`` and null space ``V2`` of ``Cs``.

    Also ``W = pinv(Cs V1)``, so that ``G V1' = (G W) Cs`` for any ``G``. When
    every output measures one state (``C`` a row selection), ``V1`` and ``V2``
    are columns of the identity (the eliminated LMI keeps the sparsity);
    otherwise they come from the SVD of ``Cs``.

    Parameters
    ----------
    Cs : ndarray, shape (q, n)
        Output matrix with normalised rows (dimensionless).

    Returns
    -------
    V1 : ndarray, shape (n, r)
    V2 : ndarray, shape (n, n - r)
    W : ndarray, shape (r, q)
        ``pinv(Cs V1)``.
    """
    with small_dense():
        return _split(Cs)


def _split(Cs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
        then recovered in closed form (`recovered_gain`) for the margin
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
        (`observer_lmi` sets it to its own ``margin``); dimensionless (normalised LMI).
    solver_options : mapping, optional
        Options passed to the solver at every solve (e.g. Clarabel's
        ``tol_gap_abs``); `solve` may override them per call.
    """

    def __init__(self, n: int, C: Any, variant: str = "qI", kappa: float = 1e4,
                 blocks: Sequence[Sequence[int]] | None = None, pattern: Any = None,
                 solver: str = "CLARABEL", *, A0_pattern: Any = None, form: str = "auto",
                 margin: float = 1e-6, solver_options: dict | None = None):
        import cvxpy as cp      # here: only the cvxpy route builds this class (conic_form does not)

        check_variant(variant)
        check_solver(solver)
        if form not in FORMS:
            raise SpecError(f"unknown LMI form {form!r}; expected one of {list(FORMS)}", key="form")
        C = real_matrix(C, "C")
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
        self.blocks, self.mask = checked_structure(n, q, blocks, pattern)
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
        # With C of full column rank the eliminated LMI does not contain P (it is Q >= t I):
        # any P >= I with trace P <= kappa n will do, P = I, and no n x n cone is built for it.
        self.fixed_P = form == "eliminated" and output_split(Cs)[1].shape[1] == 0
        P: Any = None            # cvxpy expressions (or None: P fixed at I)
        p_cons: list = []
        p_trace: Any = None
        if not self.fixed_P:
            P, p_cons, p_trace = _symmetric(n, self.blocks, "P")
        self.P = P
        if variant == "qI":
            self.qv = cp.Variable(name="q")
            Q = self.qv * I
        else:
            Q, _, _ = _symmetric(n, self.blocks, "Q")
            self.qv = Q
        self.Q = Q
        self.Kv: Any = None      # the gain variable of the full form (None: eliminated)
        self.K: Any = None
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
            lmi = [symmetrized(M) << -self.t * np.eye(2 * n)]
        else:
            self.V1, self.V2, self._W = output_split(Cs)
            V2 = self.V2
            # The A0 Parameter enters as Y = A0 V2 only (pattern of A0_pattern V2).
            ypat = (self.A0_pattern.astype(float) @ (V2 != 0).astype(float)) != 0
            self.A0s, self._set_Y = _sparse_parameter(ypat, "A0V2_scaled")
            self._set_A0 = lambda A: self._set_Y(A @ V2)
            if V2.shape[1] == 0:
                lmi = [self.qv >= self.t] if variant == "qI" else \
                      [symmetrized(Q) >> self.t * I]
            else:
                PV2 = P @ V2
                X22 = self.A0s.T @ PV2 + V2.T @ P @ self.A0s + self.t2 * (V2.T @ Q @ V2)
                M = cp.bmat([[X22, PV2.T], [PV2, -Q]])
                lmi = [symmetrized(M) << -self.t * np.eye(n + V2.shape[1])]
        # Normalisation of the homogeneous LMI: P >= I and trace(P) <= kappa n (a linear
        # conditioning bound, cond(P) <= kappa n; cheaper than a second PSD cone P <= kappa I).
        cons = lmi + p_cons + ([] if p_trace is None else [p_trace <= self.kappa * n])
        cons.append(self.t <= 1.0)
        self.problem = cp.Problem(cp.Maximize(self.t), cons)

    def time_scale(self, A0: np.ndarray, psi: float) -> float:
        """The time scale ``omega`` (1/s) used to normalise ``A0`` and ``psi``.

        Parameters
        ----------
        A0 : ndarray, shape (n, n)
            Linear part of the observer error dynamics [1/s].
        psi : float
            Lipschitz bound of the remainder [1/s].
        """
        with small_dense():
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
            default the problem's ``margin``. Dimensionless (normalised LMI).
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
        A0 = real_matrix(A0, "A0")
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
        import cvxpy as cp      # here: only the cvxpy route solves with this class (issue 15)

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
        if status not in ACCEPTED or self.t.value is None:
            out["t"] = -np.inf
            out["solve_time"] = time.perf_counter() - start
            return out
        P = np.eye(self.n) if self.P is None else symmetrized(np.asarray(self.P.value, dtype=float))
        Qs = np.asarray(self.Q.value, dtype=float)
        Qs = symmetrized(np.atleast_2d(Qs)) if Qs.ndim == 2 else float(Qs) * np.eye(self.n)
        if self.form == "full":
            Ks = np.asarray(self.K.value, dtype=float).reshape(self.n, self.q)
        else:
            with small_dense():
                Ks, t_P, t_K = recovered_gain(self.V1, self.V2, self._W, As, t2, P, Qs,
                                              self.margin if margin is None else float(margin))
            out.update({"t_P": t_P, "t_K": t_K})
        # Back to original units: Q = Qs / omega, K = omega Ks S_y (see module notes).
        K = w * Ks * self.output_scale[None, :]
        Q = Qs / w
        L = np.linalg.solve(P, K)
        out.update({"t": float(self.t.value), "P": P, "Q": Q, "K": K, "L": L,
                    "solve_time": time.perf_counter() - start})
        return out


def recovered_gain(V1: np.ndarray, V2: np.ndarray, W: np.ndarray, As: np.ndarray, t2: float,
                   P: np.ndarray, Qs: np.ndarray, margin: float) -> tuple[np.ndarray, float, float]:
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

    Parameters
    ----------
    V1, V2 : ndarray, shape (n, r) and (n, n - r)
        Orthonormal bases of the row space and null space of ``Cs`` (`output_split`).
    W : ndarray, shape (r, q)
        ``pinv(Cs V1)`` (`output_split`).
    As : ndarray, shape (n, n)
        State matrix in scaled units (``A0 / omega``, dimensionless).
    t2 : float
        Slack of the eliminated block (scaled units).
    P, Qs : ndarray, shape (n, n)
        Solved Lyapunov matrix and scaled ``Q``.
    margin : float
        Strictness margin of the block condition (scaled units).

    Returns
    -------
    K : ndarray, shape (n, q)
        Scaled gain variable (``P L`` in the scaled units of the problem).
    t_P : float
        Margin of ``(P, Q)`` in the eliminated LMI (``-`` its largest
        eigenvalue, recomputed here); scaled units.
    t_K : float
        Margin the gain is built for: ``min(1, t_P - (t_P - margin) / 10)``
        when ``t_P > margin`` (else below ``t_P``; the design is then
        refused); scaled units.
    """
    X0 = As.T @ P + P @ As + t2 * Qs
    S0 = symmetrized(np.block([[V2.T @ X0 @ V2, V2.T @ P], [P @ V2, -Qs]]))
    t_P = float(-np.max(np.linalg.eigvalsh(S0)))
    if t_P > margin:
        t_K = min(1.0, t_P - 0.1 * (t_P - margin))
    else:
        t_K = t_P - 0.5 * abs(t_P) - 1e-12
    Qt = Qs - t_K * np.eye(P.shape[0])                 # positive definite (block of S0)
    try:
        PQP = P @ sla.cho_solve(sla.cho_factor(Qt), P)
    except np.linalg.LinAlgError:
        PQP = P @ np.linalg.lstsq(Qt, P, rcond=None)[0]
    Y = symmetrized(X0 + PQP)
    YV1 = Y @ V1
    G = V2 @ (V2.T @ YV1) + 0.5 * V1 @ (V1.T @ YV1) + t_K * V1
    return G @ W, t_P, t_K
