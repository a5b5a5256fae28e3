"""The observer LMI (28), full form, written straight into Clarabel's conic form.

`observer_lmi` solves one LMI once: cvxpy's canonicalisation (DPP compilation
of the Parameters, cone matrix stuffing) then costs 10-30 times Clarabel's own
solve (issue 15: 20-120 ms against 1-14 ms for N = 8 ... 64 with diagonal
``P`` and a decentralised gain). `ConicObserverLMI` builds the same scaled
problem as `tanksynth.design.observer_lmi.problem.ObserverLMIProblem` with
``form="full"`` (same variables, normalisation and objective) directly as
Clarabel's ``min c'x  s.t.  A x + s = b, s in K`` with sparse matrices, and
solves it with Clarabel. It is used for one-shot solves only; the ``psi``
sweep keeps the cvxpy problem compiled once with Parameters.

`ConicEliminatedLMI`: the eliminated form (``K`` recovered in closed form,
`ObserverLMIProblem`'s default without a gain pattern) with Clarabel, written
with the affine expressions of `tanksynth.design.conic` and rebuilt at
each solve (one-shot and ``psi`` sweep alike) when it is small enough for
dense expressions (`ELIMINATED_DENSE_LIMIT`); otherwise cvxpy as before.

Variables ``x = [p, qv, k, t]``: the free entries of the (block-diagonal)
symmetric ``P`` (upper triangle of each block, column-major), of ``Q``
(``q`` for ``Q = q I``), of ``K`` (the allowed entries of the gain pattern)
and the margin ``t``. Cones: nonnegative (``P_ii >= 1`` for 1 x 1 blocks,
``trace P <= kappa n``, ``t <= 1``), then the ``2n x 2n`` LMI
``-M(x) - t I >= 0`` and one ``P_b - I >= 0`` per block larger than 1 x 1, in
Clarabel's scaled upper-triangle vectorisation (off-diagonal entries times
``sqrt 2``). The raw solution is unchecked, as that of `ObserverLMIProblem`:
`observer_lmi` re-checks every returned gain in numpy.
"""

from __future__ import annotations

import time
from typing import Any, Sequence

import clarabel
import numpy as np
import scipy.sparse as sps

from tanksynth.analysis.blas import small_dense
from tanksynth.design import conic as rc
from tanksynth.design.conic import ACCEPTED, CLARABEL_STATUS
from tanksynth.design.matrices import real_matrix, symmetrized
from tanksynth.design.observer_lmi.problem import (ObserverLMIProblem, check_variant, checked_structure,
                                                   output_split, recovered_gain)
from tanksynth.errors import DimensionError, SpecError

__all__ = ["ConicObserverLMI", "ConicEliminatedLMI", "one_shot_problem", "sweep_problem", "eliminated_fits",
           "with_kappa", "ELIMINATED_DENSE_LIMIT"]

#: Largest ``(LMI size)^2 x (number of variables)`` for which the eliminated form is written
#: with the dense expressions of `tanksynth.design.conic` (8 bytes each: 64 MB);
#: larger eliminated problems keep cvxpy (`ObserverLMIProblem`).
ELIMINATED_DENSE_LIMIT = 8_000_000

_SQRT2 = float(np.sqrt(2.0))


def _triu(m: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the upper triangle of an ``m x m`` matrix, column by column."""
    c, r = np.tril_indices(m)           # (c, r) row-major lower = (r, c) column-major upper
    return r, c


def _sym_entries(n: int, blocks: list[list[int]] | None, first: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list]:
    """Entries of a symmetric (block-diagonal) matrix with free variables from ``first`` on.

    Returns ``(i, j, var)`` listing both ``(i, j)`` and ``(j, i)`` of every
    off-diagonal variable, the diagonal variables and the blocks as ``(first
    variable, size)``. The variables of a block are its upper triangle,
    column-major (Clarabel's order), blocks of one size numbered together.
    """
    blocks = [list(range(n))] if blocks is None else blocks
    by_size: dict[int, list[list[int]]] = {}
    for b in blocks:
        by_size.setdefault(len(b), []).append(b)
    ii, jj, vv, diag, layout = [], [], [], [], []
    m = first
    for d, group in by_size.items():
        r, c = _triu(d)
        B = np.asarray(group, dtype=int)                      # (blocks, d)
        ids = m + np.arange(B.shape[0] * r.size).reshape(B.shape[0], r.size)
        bi, bj = B[:, r].ravel(), B[:, c].ravel()
        var, off = ids.ravel(), np.tile(r != c, B.shape[0])
        ii += [bi, bj[off]]
        jj += [bj, bi[off]]
        vv += [var, var[off]]
        diag.append(ids[:, r == c].ravel())
        layout += [(int(ids[k, 0]), d) for k in range(B.shape[0])]
        m += ids.size
    return (np.concatenate(ii), np.concatenate(jj), np.concatenate(vv), np.concatenate(diag),
            layout)


def _times(i: np.ndarray, k: np.ndarray, var: np.ndarray, coef: np.ndarray, B: sps.csr_matrix
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Entries ``(i, j, var, coef B[k, j])`` of ``E B`` for entries ``(i, k, var, coef)`` of ``E``."""
    start = B.indptr[k]
    cnt = B.indptr[k + 1] - start
    rep = np.repeat(np.arange(i.size), cnt)
    pos = np.repeat(start - (np.cumsum(cnt) - cnt), cnt) + np.arange(int(cnt.sum()))
    return i[rep], B.indices[pos], var[rep], coef[rep] * B.data[pos]


def _svec_rows(i: np.ndarray, j: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of ``svec((M + M') / 2)`` and values for entries ``(i, j, value)`` of ``M``."""
    r, c = np.minimum(i, j), np.maximum(i, j)
    return c * (c + 1) // 2 + r, np.where(i == j, value, value * (_SQRT2 / 2))


class ConicObserverLMI:
    """Scaled observer LMI (28), full form, as Clarabel data (no cvxpy).

    Same problem, variables and attributes as
    `tanksynth.design.observer_lmi.problem.ObserverLMIProblem` with ``form="full"``
    and ``solver="CLARABEL"`` (``A0`` enters as data, not as a Parameter:
    the problem is rebuilt, cheaply, for every `solve`).

    Parameters
    ----------
    n : int
        Number of states.
    C : array_like, shape (q, n)
        Output matrix (rows are normalised internally).
    variant : {"qI", "full"}
    kappa : float
        Conditioning bound: ``P >= I``, ``trace P <= kappa n`` (> 1).
    blocks : sequence of sequence of int, optional
        Partition of the states: ``P`` and ``Q`` are block-diagonal.
    pattern : array_like of 0/1, shape (n, q), optional
        Allowed non-zero entries of ``L`` (needs ``blocks``).
    margin : float
        Kept for the interface of `ObserverLMIProblem` (dimensionless; the full form has no
        gain recovery).
    solver_options : mapping, optional
        Clarabel settings for every solve.
    """

    solver = "CLARABEL"
    form = "full"
    fixed_P = False

    def __init__(self, n: int, C: Any, variant: str = "qI", kappa: float = 1e4,
                 blocks: Sequence[Sequence[int]] | None = None, pattern: Any = None, *,
                 margin: float = 1e-6, solver_options: dict | None = None):
        check_variant(variant)
        C = real_matrix(C, "C")
        if C.shape[1] != n:
            raise DimensionError(f"C has {C.shape[1]} columns, expected n = {n}")
        if not (np.isfinite(kappa) and kappa > 1):
            raise SpecError(f"kappa must be a number > 1, got {kappa!r}", key="kappa")
        row = np.linalg.norm(C, axis=1)
        if np.any(row == 0):
            raise DimensionError("C has a zero row (an output that measures nothing)")
        self.n, self.q, self.variant, self.kappa = n, C.shape[0], variant, float(kappa)
        self.C = C
        self.output_scale = 1.0 / row
        self.Cs = C * self.output_scale[:, None]
        self.blocks, self.mask = checked_structure(n, self.q, blocks, pattern)
        self.A0_pattern = np.ones((n, n), dtype=bool)
        self.margin = float(margin)
        self.solver_options = dict(solver_options or {})
        self.stats: dict = {}

    def time_scale(self, A0: np.ndarray, psi: float) -> float:
        """The time scale ``omega`` (1/s), as `ObserverLMIProblem.time_scale`.

        Parameters
        ----------
        A0 : ndarray, shape (n, n)
            1/s.
        psi : float
            1/s.
        """
        with small_dense():
            w = float(np.linalg.norm(A0, 2))
        return w if w > 0 else (psi if psi > 0 else 1.0)

    def _data(self, As: np.ndarray, t2: float) -> tuple:
        """Clarabel data ``(P, c, A, b, cones, layout)`` of the scaled problem."""
        n, q = self.n, self.q
        pi, pj, pv, pdiag, pblocks = _sym_entries(n, self.blocks, 0)
        iq = int(pv.max()) + 1
        if self.variant == "qI":
            qi = qj = np.arange(n)
            qv = np.full(n, iq)
            ik = iq + 1
        else:
            qi, qj, qv, _, _ = _sym_entries(n, self.blocks, iq)
            ik = int(qv.max()) + 1
        kflat = (np.arange(n * q) if self.mask is None else
                 np.flatnonzero(self.mask.ravel(order="F")))
        ka, ko = kflat % n, kflat // n
        kv = ik + np.arange(kflat.size)
        it = ik + kflat.size
        nv = it + 1
        one = np.ones
        # Entries (i, j, var, coef) of M(x) = [[X, P], [P, -Q]]; the svec map takes the
        # symmetric part, so A'P + P A -> 2 P A, C'K' + K C -> 2 K C, P twice in block (1, 2).
        parts = [
            _times(pi, pj, pv, 2.0 * one(pi.size), sps.csr_matrix(As)),
            (qi, qj, qv, np.full(qi.size, t2)),
            _times(ka, ko, kv, -2.0 * one(ka.size), sps.csr_matrix(self.Cs)),
            (pi, pj + n, pv, 2.0 * one(pi.size)),
            (qi + n, qj + n, qv, -one(qi.size)),
            (np.arange(2 * n), np.arange(2 * n), np.full(2 * n, it), one(2 * n)),   # t I
        ]
        mi, mj, mv, mc = (np.concatenate(z) for z in zip(*parts))
        lrow, lval = _svec_rows(mi, mj, mc)
        # Nonnegative rows: p_ii >= 1 (1 x 1 blocks), trace P <= kappa n, t <= 1.
        singles = np.array([f for f, d in pblocks if d == 1], dtype=int)
        ns = singles.size
        rows: list[Any] = [np.arange(ns), np.full(pdiag.size, ns), [ns + 1]]
        cols: list[Any] = [singles, pdiag, [it]]
        vals: list[Any] = [-one(ns), one(pdiag.size), [1.0]]
        bs: list[Any] = [-one(ns), [self.kappa * n, 1.0]]
        nn = ns + 2
        lmi_size = n * (2 * n + 1)
        rows.append(nn + lrow)
        cols.append(mv)
        vals.append(lval)
        bs.append(np.zeros(lmi_size))
        cones = [clarabel.NonnegativeConeT(nn), clarabel.PSDTriangleConeT(2 * n)]
        row = nn + lmi_size
        for first, d in pblocks:                       # P_b - I >= 0 for blocks larger than 1
            if d == 1:
                continue
            r, c = _triu(d)
            k = r.size
            rows.append(row + np.arange(k))
            cols.append(first + np.arange(k))
            vals.append(-np.where(r == c, 1.0, _SQRT2))
            bs.append(-(r == c).astype(float))
            cones.append(clarabel.PSDTriangleConeT(d))
            row += k
        Amat = sps.csc_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                      np.concatenate(cols).astype(int))),
                              shape=(row, nv))
        c = np.zeros(nv)
        c[it] = -1.0
        layout = {"P": (pi, pj, pv), "Q": (qi, qj, qv), "K": (ka, ko, kv), "it": it}
        return sps.csc_matrix((nv, nv)), c, Amat, np.concatenate(bs), cones, layout

    def _scaled(self, A0: Any, psi: float, omega: float | None) -> tuple[float, np.ndarray, float]:
        """Checked ``A0``/``psi`` and the scaled data ``(omega, A0 / omega, (psi / omega)^2)``."""
        A0 = real_matrix(A0, "A0")
        if A0.shape != (self.n, self.n):
            raise DimensionError(f"A0 has shape {A0.shape}, expected ({self.n}, {self.n})")
        if not (np.isfinite(psi) and psi >= 0):
            raise SpecError(f"psi must be a finite number >= 0, got {psi!r}", key="psi")
        w = float(omega) if omega is not None else self.time_scale(A0, psi)
        return w, A0 / w, (psi / w) ** 2

    def solve(self, A0: np.ndarray, psi: float, omega: float | None = None, *,
              margin: float | None = None, solver_options: dict | None = None) -> dict:
        """Solve the scaled problem; the raw (unchecked) solution, as `ObserverLMIProblem.solve`.

        Parameters
        ----------
        A0 : ndarray, shape (n, n)
            Mean vertex matrix (1/s).
        psi : float
            Lipschitz constant (1/s), >= 0.
        omega : float, optional
            Time scale (1/s); default `time_scale`.
        margin : float, optional
            Unused (interface of `ObserverLMIProblem.solve`).
        solver_options : mapping, optional
            Clarabel settings for this solve (over the problem's).

        Returns
        -------
        dict
            ``status``, ``t`` (``-inf`` on failure) and when solved ``P``,
            ``Q``, ``K``, ``L`` in original units, ``omega``, ``solve_time``
            (s, problem build included).
        """
        start = time.perf_counter()
        w, As, t2 = self._scaled(A0, psi, omega)
        Pobj, c, Amat, b, cones, lay = self._data(As, t2)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        for key, value in {**self.solver_options, **(solver_options or {})}.items():
            try:
                setattr(settings, key, value)
            except (AttributeError, TypeError) as exc:
                raise SpecError(f"Clarabel setting {key!r} = {value!r} refused: {exc}",
                                key="solver_options") from None
        try:
            sol = clarabel.DefaultSolver(Pobj, c, Amat, b, cones, settings).solve()
        except BaseException as exc:  # the Rust solver raises PanicException (a BaseException)
            if isinstance(exc, (KeyboardInterrupt, SystemExit)):
                raise
            return {"status": f"solver_error: {exc}", "t": -np.inf, "omega": w,
                    "solve_time": time.perf_counter() - start}
        status = CLARABEL_STATUS.get(str(sol.status), "solver_error")
        self.stats = {"num_iters": int(sol.iterations), "solve_time": float(sol.solve_time),
                      "status": str(sol.status)}
        out: dict = {"status": status, "omega": w}
        x = np.asarray(sol.x, dtype=float)
        if status not in ACCEPTED or x.size == 0 or not np.all(np.isfinite(x)):
            out.update({"t": -np.inf, "solve_time": time.perf_counter() - start})
            return out
        n, q = self.n, self.q
        P, Qs, Ks = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, q))
        for M, key in ((P, "P"), (Qs, "Q"), (Ks, "K")):
            i, j, v = lay[key]
            M[i, j] = x[v]
        K = w * Ks * self.output_scale[None, :]
        try:
            L = np.linalg.solve(P, K)
        except np.linalg.LinAlgError:
            L = np.linalg.lstsq(P, K, rcond=None)[0]
        out.update({"t": float(x[lay["it"]]), "P": P, "Q": Qs / w, "K": K, "L": L,
                    "solve_time": time.perf_counter() - start})
        return out


class ConicEliminatedLMI(ConicObserverLMI):
    """Scaled observer LMI (28), eliminated form, solved by Clarabel without cvxpy.

    The problem `tanksynth.design.observer_lmi.problem.ObserverLMIProblem` builds with
    ``form="eliminated"`` and ``solver="CLARABEL"`` (same variables,
    normalisation, objective and closed-form gain recovery), written with the
    affine expressions of `tanksynth.design.conic` and rebuilt, cheaply,
    at every `solve` (the ``psi`` sweep included). Dense expressions: meant for
    problems under `ELIMINATED_DENSE_LIMIT` (see `eliminated_fits`).

    Parameters
    ----------
    n : int
        Number of states.
    C : array_like, shape (q, n)
        Output matrix (rows are normalised internally).
    variant : {"qI", "full"}
    kappa : float
        Conditioning bound: ``P >= I``, ``trace P <= kappa n`` (> 1).
    blocks : sequence of sequence of int, optional
        Partition of the states: ``P`` and ``Q`` are block-diagonal.
    pattern : array_like of bool, shape (n, q), optional
        Allowed non-zeros of the gain (dimensionless 0/1); the eliminated form needs None (a
        full gain).
    margin : float
        Margin the recovered gain is built for (dimensionless, normalised LMI).
    solver_options : mapping, optional
        Clarabel settings for every solve.
    """

    form = "eliminated"

    def __init__(self, n: int, C: Any, variant: str = "qI", kappa: float = 1e4,
                 blocks: Sequence[Sequence[int]] | None = None, pattern: Any = None, *,
                 margin: float = 1e-6, solver_options: dict | None = None):
        super().__init__(n, C, variant, kappa, blocks, pattern, margin=margin,
                         solver_options=solver_options)
        if self.mask is not None:
            raise SpecError("the eliminated form needs a free gain K: a gain pattern needs "
                            "form='full'", key="form")
        self.V1, self.V2, self._W = output_split(self.Cs)
        self.fixed_P = self.V2.shape[1] == 0

    def _parts(self, m: rc.Model) -> list:
        """``(block, variable)`` of a symmetric (block-diagonal) matrix, assembled by `_assemble`."""
        return [(b, m.variable((len(b), len(b)), symmetric=True) if len(b) > 1 else m.variable())
                for b in ([list(range(self.n))] if self.blocks is None else self.blocks)]

    def _assemble(self, m: rc.Model, parts: list) -> rc.Expression:
        n = self.n
        data = np.zeros((n, n, m.size + 1))
        for b, v in parts:
            idx = np.asarray(b)
            data[np.ix_(idx, idx)] = v.data.reshape(len(b), len(b), m.size + 1)
        return rc.Expression(m, data)

    def solve(self, A0: np.ndarray, psi: float, omega: float | None = None, *,
              margin: float | None = None, solver_options: dict | None = None) -> dict:
        """Solve the scaled problem; the raw (unchecked) solution, as `ObserverLMIProblem.solve`.

        Parameters
        ----------
        A0 : ndarray, shape (n, n)
            Mean vertex matrix (1/s).
        psi : float
            Lipschitz constant (1/s), >= 0.
        omega : float, optional
            Time scale (1/s); default `time_scale`.
        margin : float, optional
            Margin the recovered gain is built for; default the problem's
            ``margin``. Dimensionless (normalised LMI).
        solver_options : mapping, optional
            Clarabel settings for this solve (over the problem's).

        Returns
        -------
        dict
            ``status``, ``t`` (``-inf`` on failure) and when solved ``P``,
            ``Q``, ``K``, ``L`` in original units, ``omega``, ``t_P``,
            ``t_K``, ``solve_time`` (s, problem build included).
        """
        n = self.n
        start = time.perf_counter()
        w, As, t2 = self._scaled(A0, psi, omega)
        I, V2 = np.eye(n), self.V2
        # Variables in ObserverLMIProblem's order: t, P (unless fixed), Q.
        m = rc.Model()
        t = m.variable()
        p_parts = None if self.fixed_P else self._parts(m)
        qv: Any = m.variable() if self.variant == "qI" else None
        q_parts = None if qv is not None else self._parts(m)
        m.freeze()
        cons = []
        P = None
        if p_parts is not None:
            P = self._assemble(m, p_parts)
            for b, v in p_parts:            # P >= I per block (a linear bound for 1 x 1 blocks)
                cons.append(v >= 1.0 if len(b) == 1 else v >> np.eye(len(b)))
        Q = qv * I if qv is not None else self._assemble(m, q_parts or [])
        if V2.shape[1] == 0:
            cons.insert(0, qv >= t if qv is not None else symmetrized(Q) >> t * I)
        else:
            PV2 = P @ V2
            Ys = As @ V2
            X22 = Ys.T @ PV2 + V2.T @ P @ Ys + t2 * (V2.T @ Q @ V2)
            M = rc.bmat([[X22, PV2.T], [PV2, -Q]])
            cons.insert(0, symmetrized(M) << -t * np.eye(n + V2.shape[1]))
        if P is not None:
            cons.append(rc.trace(P) <= self.kappa * n)
        cons.append(t <= 1.0)
        prob = rc.Problem(rc.Maximize(t), cons)
        settings = {**self.solver_options, **(solver_options or {})}
        try:
            prob.solve("CLARABEL", **settings)
        except (AttributeError, TypeError) as exc:
            raise SpecError(f"Clarabel setting refused: {exc}", key="solver_options") from None
        except BaseException as exc:  # the Rust solver raises PanicException (a BaseException)
            if isinstance(exc, (KeyboardInterrupt, SystemExit)):
                raise
            return {"status": f"solver_error: {exc}", "t": -np.inf, "omega": w,
                    "solve_time": time.perf_counter() - start}
        status = str(prob.status)
        out: dict = {"status": status, "omega": w}
        if status not in ACCEPTED or t.value is None:
            out.update({"t": -np.inf, "solve_time": time.perf_counter() - start})
            return out
        Pv = I if P is None else symmetrized(np.asarray(P.value, dtype=float))
        Qs = float(qv.value) * I if qv is not None else symmetrized(np.asarray(Q.value, dtype=float))
        with small_dense():
            Ks, t_P, t_K = recovered_gain(self.V1, self.V2, self._W, As, t2, Pv, Qs,
                                          self.margin if margin is None else float(margin))
        K = w * Ks * self.output_scale[None, :]
        L = np.linalg.solve(Pv, K)
        out.update({"t": float(t.value), "P": Pv, "Q": Qs / w, "K": K, "L": L, "t_P": t_P,
                    "t_K": t_K, "solve_time": time.perf_counter() - start})
        return out


def eliminated_fits(n: int, C: np.ndarray, variant: str, blocks: Any) -> bool:
    """Whether the eliminated LMI is small enough for `ConicEliminatedLMI` (dense expressions).

    Parameters
    ----------
    n : int
    C : ndarray, shape (q, n)
    variant : {"qI", "full"}
    blocks : sequence of sequence of int or None

    Returns
    -------
    bool
        ``(LMI size)^2 x (number of variables) <= ELIMINATED_DENSE_LIMIT``.
    """
    rank = int(np.linalg.matrix_rank(np.atleast_2d(np.asarray(C, dtype=float))))
    r2 = n - rank
    sym = sum(len(b) * (len(b) + 1) // 2 for b in (blocks or [list(range(n))]))
    nvars = (sym if r2 > 0 else 0) + (1 if variant == "qI" else sym) + 1
    size = n + r2 if r2 > 0 else (1 if variant == "qI" else n)
    return size * size * (nvars + 1) <= ELIMINATED_DENSE_LIMIT


def sweep_problem(A0: np.ndarray | None, C: np.ndarray, variant: str, kappa: float,
                  blocks: Sequence[Sequence[int]] | None, pattern: Any, solver: str, form: str,
                  margin: float) -> ObserverLMIProblem | ConicObserverLMI:
    """The problem `maximise_psi` solves at every trial ``psi``.

    With Clarabel, the eliminated form of a problem under
    `ELIMINATED_DENSE_LIMIT` is rebuilt at each trial without cvxpy
    (`ConicEliminatedLMI`: milliseconds); otherwise the cvxpy problem compiled
    once with Parameters (`ObserverLMIProblem`).

    Parameters
    ----------
    A0 : ndarray, shape (n, n), or None
        1/s (its non-zeros give the cvxpy problem's ``A0_pattern``); None:
        ``A0`` not known yet (several ``A0`` solved with one problem), dense
        pattern.
    C : ndarray, shape (q, n)
    variant, kappa, blocks, pattern, solver, form, margin
        As in `tanksynth.design.observer_lmi.lmi.maximise_psi`.

    Returns
    -------
    ObserverLMIProblem or ConicEliminatedLMI
    """
    C = np.atleast_2d(np.asarray(C, dtype=float))
    n = C.shape[1] if A0 is None else A0.shape[0]
    if solver == "CLARABEL" and (form == "eliminated" or (form == "auto" and pattern is None)) \
            and eliminated_fits(n, C, variant, blocks):
        return ConicEliminatedLMI(n, C, variant, kappa, blocks, pattern, margin=margin)
    return ObserverLMIProblem(n, C, variant, kappa, blocks, pattern, solver,
                              A0_pattern=None if A0 is None else A0 != 0, form=form, margin=margin)


def one_shot_problem(A0: np.ndarray, C: np.ndarray, variant: str, kappa: float,
                     blocks: Sequence[Sequence[int]] | None, pattern: Any, solver: str, form: str,
                     margin: float) -> ObserverLMIProblem | ConicObserverLMI:
    """The problem `observer_lmi` solves once.

    The full form with Clarabel (a gain pattern, or ``form="full"``) is built
    directly as conic data (`ConicObserverLMI`): cvxpy's compilation of a
    Parameter problem costs 10-30 times the solve and pays off only when the
    problem is solved again. The eliminated form (gain recovered in closed
    form) is `sweep_problem`'s choice; SCS keeps `ObserverLMIProblem`.

    Parameters
    ----------
    A0 : ndarray, shape (n, n)
        1/s (its non-zeros give ``A0_pattern``).
    C : ndarray, shape (q, n)
    variant, kappa, blocks, pattern, solver, form, margin
        As in `tanksynth.design.observer_lmi.lmi.observer_lmi`.

    Returns
    -------
    ObserverLMIProblem or ConicObserverLMI
    """
    n = A0.shape[0]
    if solver == "CLARABEL" and (form == "full" or (form == "auto" and pattern is not None)):
        return ConicObserverLMI(n, C, variant, kappa, blocks, pattern, margin=margin)
    return sweep_problem(A0, C, variant, kappa, blocks, pattern, solver, form, margin)


def with_kappa(prob: ObserverLMIProblem | ConicObserverLMI, kappa: float,
               margin: float) -> ObserverLMIProblem | ConicObserverLMI:
    """The same problem with another conditioning bound ``kappa`` (the retry of `observer_lmi`).

    Parameters
    ----------
    prob : ObserverLMIProblem or ConicObserverLMI
    kappa : float
        New bound (> 1).
    margin : float
        Margin the recovered gain is built for (dimensionless, normalised LMI).

    Returns
    -------
    ObserverLMIProblem or ConicObserverLMI
    """
    if isinstance(prob, ConicEliminatedLMI):
        return ConicEliminatedLMI(prob.n, prob.C, prob.variant, kappa, prob.blocks, None,
                                  margin=margin, solver_options=prob.solver_options)
    if isinstance(prob, ConicObserverLMI):
        return ConicObserverLMI(prob.n, prob.C, prob.variant, kappa, prob.blocks, prob.mask,
                                margin=margin, solver_options=prob.solver_options)
    return ObserverLMIProblem(prob.n, prob.C, prob.variant, kappa, prob.blocks, prob.mask, prob.solver,
                              A0_pattern=prob.A0_pattern, form=prob.form, margin=margin,
                              solver_options=prob.solver_options)
