"""Rank conditions: Kalman, PBH, nonlinear (local) and symbolic observability.

Every check returns a frozen result carrying its evidence (singular values,
condition numbers, the modes or points where rank drops), so that reports
and the ``tanksynth check`` command show why a verdict was reached.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import casadi as ca
import numpy as np
import numpy.typing as npt
import sympy as sp

from tanksynth.errors import DimensionError, SpecError
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import compile_matrix, evaluate_points, to_casadi
from tanksynth.analysis.blas import small_dense
from tanksynth.analysis.budget import TooComplexError, run_within_budget
from tanksynth.analysis.symbolic import jacobian
# re-exported: the symbolic determinant lives in its own module (size), named from here as before
from tanksynth.analysis.rank_symbolic import SymbolicRank, symbolic_observability

__all__ = [
    "RankResult",
    "codistribution_matrix",
    "controllability_matrix",
    "observability_matrix",
    "controllability_rank",
    "observability_rank",
    "PBHMode",
    "PBHResult",
    "pbh_test",
    "NonlinearObservability",
    "nonlinear_observability",
    "DeterminantZeros",
    "observability_determinant_zeros",
    "SymbolicRank",
    "symbolic_observability",
]


def _matrix(value, name: str) -> np.ndarray:
    arr = np.atleast_2d(np.asarray(value, dtype=float))
    if arr.ndim != 2 or not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be a finite 2-D array")
    return arr


def controllability_matrix(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``[B, AB, ..., A^(n-1) B]``.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        State matrix (continuous [1/s] or discrete [-]).
    B : ndarray, shape (n, m)
        Input matrix.
    """
    A, B = _matrix(A, "A"), _matrix(B, "B")
    n = A.shape[0]
    if A.shape != (n, n) or B.shape[0] != n:
        raise DimensionError(f"A is {A.shape} and B is {B.shape}: expected (n, n) and (n, m)")
    blocks = [B]
    with small_dense():   # n products of n x n by n x m: threads only wait on a loaded machine
        for _ in range(n - 1):
            blocks.append(A @ blocks[-1])
    return np.hstack(blocks)


def observability_matrix(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``[C; CA; ...; C A^(n-1)]``.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        State matrix (continuous [1/s] or discrete [-]).
    C : ndarray, shape (q, n)
        Output matrix.
    """
    A, C = _matrix(A, "A"), _matrix(C, "C")
    n = A.shape[0]
    if A.shape != (n, n) or C.shape[1] != n:
        raise DimensionError(f"A is {A.shape} and C is {C.shape}: expected (n, n) and (q, n)")
    blocks = [C]
    with small_dense():
        for _ in range(n - 1):
            blocks.append(blocks[-1] @ A)
    return np.vstack(blocks)


@dataclass(frozen=True)
class RankResult:
    """Numerical rank of a Kalman matrix, with its evidence.

    The rank is decided on the leading blocks of the Kalman matrix, ``[B, AB,
    ..., A^(k-1) B]`` (``[C; CA; ...; C A^(k-1)]``), for ``k = 1, 2, 4, ...``
    up to ``n``: the first ``k`` whose blocks have rank ``n`` settles it (more
    columns span no less, so the full matrix has rank ``n`` too), and every
    number below is then of those ``k`` blocks. With ``rank C = n`` (every
    state measured) that is ``C`` alone; a rank-deficient pair ends at ``k =
    n``, the full matrix.

    Attributes
    ----------
    kind : str
        ``"controllability"`` or ``"observability"``.
    rank, n : int
        Numerical rank and the full rank expected.
    singular_values : ndarray
        Of the ``blocks`` leading blocks (a lower bound, entry by entry, of
        the full matrix's: appending blocks never lowers a singular value).
    tolerance : float
        Singular values above it count: ``max(shape) eps s_max`` of the
        leading blocks.
    condition_number : float
        ``s_max / s_min`` over the first ``n`` singular values (inf if rank
        deficient): large values mean the verdict is fragile.
    matrix : ndarray
        The leading blocks the numbers are of.
    blocks : int or None
        How many blocks ``k`` (None: all ``n``, as a result built by hand).
    """

    kind: str
    rank: int
    n: int
    singular_values: np.ndarray
    tolerance: float
    condition_number: float
    matrix: np.ndarray
    blocks: int | None = None

    @property
    def full(self) -> bool:
        """True when the rank equals the state dimension."""
        return self.rank == self.n

    def as_dict(self) -> dict:
        """JSON-friendly summary."""
        return {"kind": self.kind, "rank": self.rank, "n": self.n, "full": self.full,
                "singular_values": self.singular_values.tolist(), "tolerance": self.tolerance,
                "condition_number": self.condition_number,
                "blocks": self.n if self.blocks is None else self.blocks}


def _rank(kind: str, M: np.ndarray, n: int, tol: float | None, blocks: int) -> RankResult:
    with small_dense():    # a threaded BLAS makes this SVD ~100x slower on a loaded small machine
        s = np.linalg.svd(M, compute_uv=False)
    if tol is None:
        tol = max(M.shape) * np.finfo(float).eps * (s[0] if s.size else 0.0)
    rank = int(np.sum(s > tol))
    top = s[:n]
    cond = float(top[0] / top[-1]) if top.size == n and top[-1] > tol else float("inf")
    return RankResult(kind, rank, n, s, float(tol), cond, M, blocks)


def _leading_rank(kind: str, A: np.ndarray, first: np.ndarray, tol: float | None) -> RankResult:
    """Rank of the leading ``k = 1, 2, 4, ..., n`` Kalman blocks (``first`` is ``B`` or ``C``).

    Stops at the first ``k`` with rank ``n``: one SVD of ``C`` when ``rank C
    = n``, of ``[B, AB]`` when ``B`` and ``AB`` already span the states,
    instead of the ``(n q) x n`` matrix (65,536 x 256 for a 256-tank network
    measured everywhere). The blocks are the products of
    `controllability_matrix` / `observability_matrix`, built once each.
    """
    n = A.shape[0]
    blocks, k = [first], 1
    while True:
        with small_dense():   # n x n by n x m products: threads only wait on a loaded machine
            while len(blocks) < k:
                blocks.append(A @ blocks[-1] if kind == "controllability" else blocks[-1] @ A)
        M = np.hstack(blocks) if kind == "controllability" else np.vstack(blocks)
        res = _rank(kind, M, n, tol, k)
        if res.full or k >= n:
            return res
        k = min(2 * k, n)


def controllability_rank(A: np.ndarray, B: np.ndarray, tol: float | None = None) -> RankResult:
    """Kalman controllability rank of ``(A, B)`` by SVD of its leading blocks.

    ``[B, AB, ..., A^(k-1) B]`` for ``k = 1, 2, 4, ...`` up to ``n``: the
    first with rank ``n`` decides (see `RankResult`); a deficient pair is
    judged on the full ``n x (n m)`` matrix.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    tol : float, optional
        Singular-value threshold; default ``max(shape) eps s_max`` of the
        blocks judged.
    """
    A, B = _matrix(A, "A"), _matrix(B, "B")
    n = A.shape[0]
    if A.shape != (n, n) or B.shape[0] != n:
        raise DimensionError(f"A is {A.shape} and B is {B.shape}: expected (n, n) and (n, m)")
    return _leading_rank("controllability", A, B, tol)


def observability_rank(A: np.ndarray, C: np.ndarray, tol: float | None = None) -> RankResult:
    """Kalman observability rank of ``(A, C)`` by SVD of its leading blocks.

    ``[C; CA; ...; C A^(k-1)]`` for ``k = 1, 2, 4, ...`` up to ``n``: the
    first with rank ``n`` decides (see `RankResult`), ``C`` alone when every
    state is measured; a deficient pair is judged on the full ``(n q) x n``
    matrix.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    C : ndarray, shape (q, n)
    tol : float, optional
        Singular-value threshold; default ``max(shape) eps s_max`` of the
        blocks judged.
    """
    A, C = _matrix(A, "A"), _matrix(C, "C")
    n = A.shape[0]
    if A.shape != (n, n) or C.shape[1] != n:
        raise DimensionError(f"A is {A.shape} and C is {C.shape}: expected (n, n) and (q, n)")
    return _leading_rank("observability", A, C, tol)


@dataclass(frozen=True)
class PBHMode:
    """A mode that fails the PBH test.

    Attributes
    ----------
    eigenvalue : complex
    direction : ndarray
        Right eigenvector with ``C v = 0`` (unobservable) or left
        eigenvector with ``w' B = 0`` (uncontrollable).
    states : tuple of str
        States carrying at least 10% of the direction's largest entry.
    smallest_singular_value : float
        Of ``[lambda I - A; C]`` (or ``[lambda I - A, B]``).
    """

    eigenvalue: complex
    direction: np.ndarray
    states: tuple[str, ...]
    smallest_singular_value: float


@dataclass(frozen=True)
class PBHResult:
    """Popov-Belevitch-Hautus test over every eigenvalue of ``A``.

    Parameters
    ----------
    kind : {"controllability", "observability"}
        Which property was tested.
    modes : tuple of PBHMode
        The failing modes (empty when the test passes).
    tolerance : float
        Smallest singular value counted as nonzero.
    """

    kind: str
    modes: tuple[PBHMode, ...]
    tolerance: float

    @property
    def passed(self) -> bool:
        """True when no mode fails."""
        return not self.modes

    def as_dict(self) -> dict:
        """JSON-friendly summary naming the failing modes and their states."""
        return {"kind": self.kind, "passed": self.passed, "tolerance": self.tolerance,
                "modes": [{"eigenvalue": [m.eigenvalue.real, m.eigenvalue.imag],
                           "states": list(m.states),
                           "smallest_singular_value": m.smallest_singular_value} for m in self.modes]}


def pbh_test(A: np.ndarray, B: np.ndarray | None = None, C: np.ndarray | None = None,
             state_names: Sequence[str] | None = None, tol: float | None = None) -> PBHResult:
    """PBH test: which modes are unobservable (give ``C``) or uncontrollable (give ``B``).

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m), optional
    C : ndarray, shape (q, n), optional
        Exactly one of ``B`` and ``C``.
    state_names : sequence of str, optional
        Names used to say where a failing mode lives.
    tol : float, optional
        Threshold on the smallest singular value of the PBH pencil;
        default ``1e-9 (1 + ||A||)``.
    """
    if (B is None) == (C is None):
        raise DimensionError("give exactly one of B (controllability) and C (observability)")
    A = _matrix(A, "A")
    n = A.shape[0]
    names = list(state_names) if state_names is not None else [f"x{i + 1}" for i in range(n)]
    with small_dense():
        threshold = float(tol) if tol is not None else float(1e-9 * (1.0 + np.linalg.norm(A, 2)))
        eigenvalues = np.linalg.eigvals(A)
    kind = "observability" if C is not None else "controllability"
    modes = []
    for lam in np.unique(np.round(eigenvalues, 12)):
        # singular values first; the vectors only for a failing mode (a full SVD of a
        # 2n x n pencil per eigenvalue costs 3-4x more, and the BLAS runs on one thread)
        if C is not None:
            pencil = np.vstack([lam * np.eye(n) - A, _matrix(C, "C")])
        else:
            pencil = np.hstack([lam * np.eye(n) - A, _matrix(B, "B")])
        with small_dense():
            s = np.linalg.svd(pencil, compute_uv=False)
        smin = float(s[min(n, len(s)) - 1]) if len(s) >= n else 0.0
        if smin <= threshold:
            with small_dense():
                if C is not None:
                    _, s, vh = np.linalg.svd(pencil)
                    direction = vh[-1].conj()
                else:
                    u, s, _ = np.linalg.svd(pencil)
                    direction = u[:, -1]
            mag = np.abs(direction)
            states = tuple(nm for nm, v in zip(names, mag) if v >= 0.1 * mag.max())
            modes.append(PBHMode(complex(lam), direction, states, smin))
    return PBHResult(kind, tuple(modes), threshold)


@dataclass(frozen=True)
class NonlinearObservability:
    """Rank of the observability codistribution over sampled region points.

    Attributes
    ----------
    orders : int
        Lie derivatives used: ``d(L_f^k h)`` for ``k < orders`` (the
        search stops early once the rank is full at every point).
    ranks : ndarray of int, shape (M,)
        Rank at each point.
    points : ndarray, shape (M, n)
    smallest_singular_values : ndarray, shape (M,)
        n-th singular value of the (row-scaled) codistribution matrix.
    n : int
    input_value : ndarray
        Constant input at which ``f`` was evaluated.
    drop_directions : ndarray, shape (k, n)
        At each of the first (at most 10) drop points, the unit state
        direction the codistribution does not see (right singular vector of
        the smallest singular value): the unobservable direction there.
    state_names : tuple of str
    undefined_points : int
        Sampled points left out because a Lie derivative is not finite there
        (a kink of ``sqrt``/``abs``/``max``); 0 normally.
    """

    orders: int
    ranks: np.ndarray
    points: np.ndarray
    smallest_singular_values: np.ndarray
    n: int
    input_value: np.ndarray
    drop_directions: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    state_names: tuple[str, ...] = ()
    undefined_points: int = 0

    def unobservable_states(self) -> list[str]:
        """States carrying at least 10% of the first drop point's unobservable direction."""
        if not self.drop_directions.size:
            return []
        v = np.abs(self.drop_directions[0])
        names = self.state_names or tuple(f"x{i + 1}" for i in range(self.n))
        return [nm for nm, x in zip(names, v) if x >= 0.1 * v.max()]

    @property
    def full(self) -> bool:
        """Full rank at every sampled point."""
        return bool(np.all(self.ranks == self.n))

    @property
    def drop_points(self) -> np.ndarray:
        """Points where the rank is below n."""
        return self.points[self.ranks < self.n]

    def as_dict(self) -> dict:
        """JSON-friendly summary (at most 10 drop points listed)."""
        return {"full": self.full, "n": self.n, "orders": self.orders, "points": int(len(self.ranks)),
                "min_rank": int(self.ranks.min()), "input": self.input_value.tolist(),
                "min_smallest_singular_value": float(self.smallest_singular_values.min()),
                "drop_points": self.drop_points[:10].tolist(),
                "drop_directions": self.drop_directions.tolist(),
                "unobservable_states": self.unobservable_states(),
                "undefined_points": self.undefined_points}


def nonlinear_observability(plant: Plant, points: np.ndarray | None = None, count: int = 200,
                            seed: int = 0, u: npt.ArrayLike | None = None,
                            rtol: float = 1e-9) -> NonlinearObservability:
    """Local observability rank ``rank d(L_f^k h), k = 0..n-1`` over the region.

    The model (``f`` on the region, at the constant input, and ``h``) is
    translated to CasADi once and the Lie derivatives are built there, one
    order at a time, by algorithmic differentiation: ``d(L_f^k h) =
    jacobian(L_f^k h, x)``, ``L_f^(k+1) h = d(L_f^k h) f``. The same values
    as differentiating the sympy expressions and compiling them (to
    rounding; the non-smooth conventions agree: ``d|z| = sign z``, ``d sign
    = 0`` as the compiled ``DiracDelta``, ``d max`` 1/2 at a tie as the
    compiled ``Heaviside``), at a fraction of the cost on hybrid models
    (sympy's product rule through ``Piecewise``/``Max`` terms took 0.2-0.3 s
    for the three-tank orders 1-2). Each new block is evaluated at every
    point; the search stops at the first order that gives full rank
    everywhere.

    Parameters
    ----------
    plant : Plant
    points : ndarray, shape (M, n), optional
        Where to check; default ``count`` seeded samples of the region
        (kept 1% away from its faces).
    count, seed : int
        Sampling of the region when ``points`` is not given.
    u : array_like, shape (m,), optional
        Constant input for ``f``; default the middle of the input bounds.
    rtol : float
        Singular values below ``rtol * s_max`` (rows scaled to unit norm)
        count as zero.

    Raises
    ------
    SpecError
        A given point where a Lie derivative is not finite (a kink of
        ``sqrt``/``abs``/``max``: no rank is defined there); sampled points
        there are left out.
    """
    given = points is not None
    if points is None:
        points = plant.region.sample(count, plant.x, seed=seed, margin=0.01)
    points = np.atleast_2d(np.asarray(points, dtype=float))
    if u is None:
        u = [0.5 * (lo + hi) if np.isfinite(lo) and np.isfinite(hi) else 0.0
             for lo, hi in plant.input_limits]
    u_value = np.asarray(u, dtype=float).reshape(plant.m)
    M = len(points)
    undefined = 0
    names = tuple(st.name for st in plant.states)
    # f at the constant input (numbers for u, as the check uses it), h, in CasADi once
    f = plant.f_smooth_numeric.xreplace({s: sp.Float(v) for s, v in zip(plant.u, u_value)})
    xs, us = ca.SX.sym("x", plant.n), ca.SX.sym("u", plant.m)
    symbols = dict(zip(plant.x, ca.vertsplit(xs)))
    cache: dict = {}
    fx = ca.vertcat(*[to_casadi(e, symbols, cache) for e in f])
    L = ca.vertcat(*[to_casadi(e, symbols, cache) for e in plant.h_numeric])
    blocks = []
    for k in range(plant.n):
        # one order at a time: only the new block d(L_f^k h) is built and evaluated
        grad = ca.jacobian(L, xs)
        fn = ca.Function("codist", [xs, us], [grad], ["x", "u"], ["out"])
        blocks.append(_evaluate(fn, grad.shape[0], plant.n, points, u_value))
        finite = np.all(np.isfinite(blocks[-1].reshape(len(points), -1)), axis=1)
        if not np.all(finite):
            # a kink of sqrt/abs/max where a derivative is infinite: no rank is defined there
            bad = points[np.flatnonzero(~finite)[0]]
            if given or np.all(~finite):
                raise SpecError(f"the Lie derivatives of the outputs (order {k}) are not finite at "
                                f"x = {np.array2string(bad, precision=6)} (a kink of sqrt/abs/max in the "
                                "model): check the rank at points off it", key="points")
            points, blocks = points[finite], [b[finite] for b in blocks]
            undefined += int(np.sum(~finite))
            M = len(points)
        vals = np.concatenate(blocks, axis=1)
        # Rows scaled to unit norm (zero rows stay zero): SI models mix 1e-5 and 1e2.
        norms = np.linalg.norm(vals, axis=2, keepdims=True)
        scaled = np.divide(vals, norms, out=np.zeros_like(vals), where=norms > 0)
        s = np.linalg.svd(scaled, compute_uv=False)
        ranks = np.sum(s > rtol * s[:, :1], axis=1)
        smin = s[:, plant.n - 1] if s.shape[1] >= plant.n else np.zeros(M)
        if np.all(ranks == plant.n):
            return NonlinearObservability(k + 1, ranks, points, smin, plant.n, u_value,
                                          np.zeros((0, plant.n)), names, undefined)
        L = ca.mtimes(grad, fx)
    drops = np.flatnonzero(ranks < plant.n)[:10]
    dirs = np.array([np.linalg.svd(scaled[i])[2][-1] for i in drops]).reshape(-1, plant.n)
    return NonlinearObservability(plant.n, ranks, points, smin, plant.n, u_value, dirs, names,
                                  undefined)


def codistribution_matrix(f: sp.Matrix, h: sp.Matrix, x: sp.Matrix, orders: int) -> sp.Matrix:
    """The symbolic ``d(L_f^k h), k < orders`` (rows stacked), for the budgeted step.

    Parameters
    ----------
    f, h : sympy.Matrix
        The vector field (state units per s) and the outputs.
    x : sympy.Matrix
        The states.
    orders : int
        Lie derivatives used.
    """
    L = h
    rows: list[sp.Matrix] = []
    for k in range(orders):
        grad = jacobian(L, x)
        rows.append(grad)
        if k + 1 < orders:
            L = grad * f
    return sp.Matrix.vstack(*rows)


def _codistribution(plant: Plant, orders: int):
    """Compiled ``d(L_f^k h), k < orders`` (rows stacked) and its symbolic matrix; the symbolic
    Lie derivatives run under the symbolic budget (`TooComplexError` past it)."""
    D = run_within_budget(codistribution_matrix, plant.f_smooth_numeric, plant.h_numeric,
                          plant.x, orders, what="the symbolic observability codistribution")
    return compile_matrix("codist", D, [plant.x, plant.u], ["x", "u"]), D


def _evaluate(fn, rows: int, n: int, points: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Codistribution at every point, shape (M, rows, n)."""
    return evaluate_points(fn, points, np.repeat(u[None, :], len(points), axis=0))


@dataclass(frozen=True)
class DeterminantZeros:
    """Where the square observability codistribution's determinant vanishes in the region.

    Attributes
    ----------
    searched : bool
        False when the codistribution is not square (no scalar determinant).
    segments : int
        Segments between sampled points searched for a sign change.
    zeros : ndarray, shape (k, n)
        Points of the region (found by root finding along the segments) where
        the determinant is zero: the rank drops there.
    reason : str
        Why not searched, or how.
    """

    searched: bool
    segments: int
    zeros: np.ndarray
    reason: str

    @property
    def meets_region(self) -> bool:
        """True when a zero of the determinant was found inside the region."""
        return bool(self.zeros.size)

    def as_dict(self) -> dict:
        """JSON-friendly summary (at most 10 zeros)."""
        return {"searched": self.searched, "segments": self.segments,
                "meets_region": self.meets_region, "zeros": self.zeros[:10].tolist(),
                "reason": self.reason}


def observability_determinant_zeros(plant: Plant, result: NonlinearObservability,
                                    max_zeros: int = 10) -> DeterminantZeros:
    """Search the zero set of ``det d(L_f^k h)`` in the region along sampled segments.

    Sampled points can all have full rank while the (analytic) determinant
    vanishes on a surface between them. For a square codistribution (``q
    orders = n``) its determinant is evaluated at the points of ``result``;
    every segment between consecutive points and from each point to the
    centroid whose end values differ in sign holds a zero, located by
    `scipy.optimize.brentq` (kept if it lies in the region and the
    determinant is small there, not a singularity). Only for smooth models:
    with non-smooth terms left on the region the search is not done.

    Parameters
    ----------
    plant : Plant
    result : NonlinearObservability
        The sampled check (its points, orders and input).
    max_zeros : int
        Stop after this many zeros.

    Returns
    -------
    DeterminantZeros
    """
    orders, n = result.orders, plant.n
    nonsmooth = (sp.Abs, sp.sign, sp.Max, sp.Min, sp.Heaviside, sp.DiracDelta, sp.Piecewise)
    if plant.f_smooth.has(*nonsmooth) or plant.h.has(*nonsmooth):
        return DeterminantZeros(False, 0, np.zeros((0, n)),
                                "the model keeps non-smooth terms on the region (hybrid switching or "
                                "undetermined flow directions): the determinant is not analytic")
    try:
        fn, D = _codistribution(plant, orders)
    except TooComplexError as exc:
        return DeterminantZeros(False, 0, np.zeros((0, n)), exc.detail)
    if D.shape[0] != n:
        return DeterminantZeros(False, 0, np.zeros((0, n)),
                                f"the codistribution is {D.shape[0]} x {n} (not square): no scalar "
                                "determinant to search")
    pts = result.points
    u = result.input_value

    def det_at(X: np.ndarray) -> np.ndarray:
        return np.linalg.det(_evaluate(fn, n, n, np.atleast_2d(X), u))

    d = det_at(pts)
    centre = pts.mean(axis=0)
    pairs = [(pts[i], pts[i + 1], d[i], d[i + 1]) for i in range(len(pts) - 1)]
    dc = float(det_at(centre)[0])
    pairs += [(pts[i], centre, d[i], dc) for i in range(len(pts))]
    zeros: list[np.ndarray] = []
    for a, b, da, db in pairs:
        if len(zeros) >= max_zeros:
            break
        if not (np.isfinite(da) and np.isfinite(db)) or da * db >= 0:
            continue
        g = lambda t: float(det_at(a + t * (b - a))[0])  # noqa: E731
        from scipy.optimize import brentq  # deferred to a sign change: scipy.optimize ~0.15 s

        t0 = brentq(g, 0.0, 1.0, xtol=1e-12)
        z = a + t0 * (b - a)
        # a sign change through a singularity (a square root at an equal-level boundary) is
        # not a zero: keep the point only if the determinant is small there
        if abs(g(t0)) > 1e-6 * max(abs(da), abs(db)):
            continue
        if not plant.region.violations(z, plant.x):
            zeros.append(z)
    return DeterminantZeros(True, len(pairs), np.array(zeros).reshape(-1, n),
                            f"sign changes of det along {len(pairs)} segments (consecutive sampled "
                            "points and each point to the centroid), zeros located by brentq")
