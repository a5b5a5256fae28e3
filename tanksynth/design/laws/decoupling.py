"""Input-output decoupling analysis of a square plant (seed 000, section II-C).

For a square control-affine plant ``dx/dt = f0(x) + G(x) u``, ``y = h(x)``
(``q = m``) the relative degrees ``theta_i`` (eq. 19), the decoupling matrix
``Lambda(x)`` (eq. 22) and ``Lambda_0(x)`` (eq. 23) come from the symbolic
core (`tanksynth.analysis.symbolic.relative_degree`) on the plant's smooth form
(``sgn``/``abs`` resolved on the operating region). The law (eq. 24)::

    u = alpha(x) + beta(x) zeta,   alpha = -Lambda^-1 Lambda_0,   beta = Lambda^-1

`decoupling_analysis` checks, before `tanksynth.design.laws.feedback_linearization`
gives a law:

* ``q = m`` (otherwise `DimensionError`, naming the outputs and inputs);
* every relative degree exists (`InfeasibleDesign` if an output does not
  depend on the inputs at any order up to ``n``, or if its row of
  ``Lambda`` vanishes somewhere on the region, naming the point);
* ``rank Lambda(x) = m`` on the region (`InfeasibleDesign` naming where it
  drops: identically, at a grid point, or on a surface where ``det Lambda``
  changes sign, located by bisection);
* the zero dynamics (dimension ``n - sum theta_i``) are stable: eigenvalues of
  their Jacobian on a grid of the region (`InfeasibleDesign` naming the worst
  point unless the user overrides).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import casadi as ca
import numpy as np
import sympy as sp

from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError, TanksynthError
from tanksynth.analysis.region import batch_eval, region_points
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import compile_matrix
from tanksynth.analysis.symbolic import RelativeDegree, control_affine, lie_derivatives, relative_degree

__all__ = [
    "RANK_TOL",
    "select_outputs",
    "point_text",
    "simplify_if_small",
    "ZeroDynamics",
    "Decoupling",
    "decoupling_analysis",
]

#: Relative tolerance on ``sigma_min / sigma_max`` below which ``Lambda(x)`` is singular.
RANK_TOL = 1e-9


# --------------------------------------------------------------------- helpers
def point_text(x: np.ndarray, names: Sequence[str]) -> str:
    """A point of the region as the messages name it: ``(h1 = 0.3, h2 = 0.2)``.

    Parameters
    ----------
    x : ndarray, shape (n,)
        The point (state units).
    names : sequence of str
        The state names.

    Returns
    -------
    str
    """
    return "(" + ", ".join(f"{nm} = {v:.6g}" for nm, v in zip(names, np.asarray(x, float))) + ")"


def select_outputs(plant: Plant, outputs: Sequence[str] | None) -> tuple[sp.Matrix, tuple[str, ...]]:
    """Output map of the chosen outputs.

    Parameters
    ----------
    plant : Plant
    outputs : sequence of str or None
        Names of plant outputs (or, failing that, of states: ``y = x_j``).
        None: all the plant's outputs.

    Returns
    -------
    h : sympy.Matrix, shape (q, 1)
        In state and parameter symbols.
    names : tuple of str

    Raises
    ------
    SpecError
        Unknown name.
    """
    out_names = [s.name for s in plant.outputs]
    state_names = [s.name for s in plant.states]
    if outputs is None:
        return sp.Matrix(plant.h), tuple(out_names)
    rows, names = [], []
    for nm in outputs:
        if nm in out_names:
            rows.append(plant.h[out_names.index(nm)])
        elif nm in state_names:
            rows.append(plant.x[state_names.index(nm)])
        else:
            raise SpecError(f"unknown output {nm!r}; expected outputs {out_names} or states {state_names}",
                            key="tracked")
        names.append(nm)
    if len(set(names)) != len(names):
        raise SpecError(f"outputs listed twice: {names}", key="tracked")
    return sp.Matrix(rows), tuple(names)


def simplify_if_small(expr: Any, limit: int = 400) -> Any:
    """``sympy.simplify`` when the expression is small (keeps the analysis fast).

    Parameters
    ----------
    expr : sympy.Expr
        The expression.
    limit : int
        Largest ``sympy.count_ops`` simplified; a larger expression is returned as is.

    Returns
    -------
    sympy.Expr
    """
    if sp.count_ops(expr) <= limit:
        return sp.simplify(expr)
    return expr


# ------------------------------------------------------------------ data types
@dataclass(frozen=True)
class ZeroDynamics:
    """Internal (zero) dynamics of the decoupled plant.

    With ``zeta = 0`` and the outputs held (``y_i^(k) = 0`` for ``1 <= k <
    theta_i``), the remaining ``d = n - sum theta_i`` coordinates ``eta``
    (a subset of the states) evolve by ``d eta/dt = E (f0 + G alpha)(x)``.

    Attributes
    ----------
    dimension : int
        ``n - sum theta_i``.
    coordinates : tuple of str
        States used as internal coordinates ``eta``.
    expressions : sympy.Matrix, shape (d, 1)
        ``d eta/dt`` in state and parameter symbols (outputs frozen).
    points : ndarray, shape (M, n)
        Grid points of the region (on the zero-output manifold) where the
        Jacobian was evaluated.
    eigenvalues : ndarray, shape (M, d)
        Eigenvalues of the zero-dynamics Jacobian at each point (1/s).
    max_real : float
        Largest real part over the points (1/s); ``-inf`` when ``d = 0``.
    worst_point : ndarray or None
        Point of ``max_real``.
    stable : bool
        ``max_real < 0`` (every frozen Jacobian Hurwitz on the grid; a local
        test on the grid, exact for ``d = 1`` along each line of frozen
        outputs when it holds everywhere).
    skipped : int
        Points dropped (non-finite Jacobian or off the manifold).
    """

    dimension: int
    coordinates: tuple[str, ...]
    expressions: sp.Matrix
    points: np.ndarray
    eigenvalues: np.ndarray
    max_real: float
    worst_point: np.ndarray | None
    stable: bool
    skipped: int = 0

    def as_dict(self, state_names: Sequence[str]) -> dict:
        """JSON-friendly summary (eigenvalue range, worst point).

        Parameters
        ----------
        state_names : sequence of str
            Names of the plant's states (to name the worst point).
        """
        ev = self.eigenvalues.reshape(-1) if self.eigenvalues.size else np.array([])
        out: dict[str, Any] = {
            "dimension": self.dimension, "coordinates": list(self.coordinates),
            "expressions": [str(e) for e in self.expressions],
            "points": int(len(self.points)), "skipped_points": int(self.skipped),
            "stable": self.stable,
            "max_real_part": self.max_real if math.isfinite(self.max_real) else None,
        }
        if ev.size:
            out["min_real_part"] = float(np.min(ev.real))
            out["max_abs_imag"] = float(np.max(np.abs(ev.imag)))
            if self.worst_point is not None:
                out["worst_point"] = dict(zip(state_names, map(float, self.worst_point)))
        return out


@dataclass(frozen=True)
class Decoupling:
    """Relative degrees, decoupling matrices and their checks on the region.

    Attributes
    ----------
    plant : str
    outputs : tuple of str
        Decoupled outputs (``q = m`` of them).
    degrees : tuple of int
        ``theta_i``.
    Lambda, Lambda0 : sympy.Matrix
        ``Lambda(x)`` (m x m) and ``Lambda_0(x)`` (m x 1), in state and
        parameter symbols, from the smooth model.
    alpha, beta : sympy.Matrix
        ``-Lambda^-1 Lambda_0`` (input units) and ``Lambda^-1``.
    h : sympy.Matrix
        Output map of the decoupled outputs.
    lie : tuple of sympy.Matrix
        Per output, ``[h_i, L_f h_i, ..., L_f^(theta_i - 1) h_i]`` (smooth
        model, symbolic parameters).
    zero_dynamics : ZeroDynamics
    rank_check : dict
        Points tested, smallest ``sigma_min/sigma_max`` of ``Lambda`` and
        where, the sign of ``det Lambda``.
    """

    plant: str
    outputs: tuple[str, ...]
    degrees: tuple[int, ...]
    Lambda: sp.Matrix
    Lambda0: sp.Matrix
    alpha: sp.Matrix
    beta: sp.Matrix
    h: sp.Matrix
    lie: tuple[sp.Matrix, ...]
    zero_dynamics: ZeroDynamics
    rank_check: dict = field(default_factory=dict)

    @property
    def total(self) -> int:
        """``sum theta_i``."""
        return sum(self.degrees)

    def latex(self) -> dict[str, str]:
        """LaTeX fragments of ``Lambda``, ``Lambda_0``, ``alpha``, ``beta`` and the zero dynamics."""
        out = {"Lambda": sp.latex(self.Lambda), "Lambda0": sp.latex(self.Lambda0),
               "alpha": sp.latex(self.alpha), "beta": sp.latex(self.beta),
               "degrees": ", ".join(rf"\vartheta_{{{i + 1}}} = {d}" for i, d in enumerate(self.degrees))}
        if self.zero_dynamics.dimension:
            out["zero_dynamics"] = sp.latex(self.zero_dynamics.expressions)
        return out


# ------------------------------------------------------------------- analysis
def _square_or_raise(plant: Plant, names: Sequence[str]) -> None:
    q, m = len(names), plant.m
    inputs = [s.name for s in plant.inputs]
    if q > m:
        raise DimensionError(
            f"more outputs than inputs: {q} outputs {list(names)} but only {m} inputs {inputs}; "
            f"exact decoupling needs q = m (structural, at every point of the state space): "
            f"choose {m} outputs to decouple (option 'tracked')")
    if q < m:
        raise DimensionError(
            f"fewer outputs than inputs: {q} outputs {list(names)} for {m} inputs {inputs}; "
            f"the decoupling matrix would be {q} x {m}, not invertible: choose {m} outputs "
            "(option 'tracked')")


def _relative_degree(plant: Plant, h: sp.Matrix, names: Sequence[str]) -> RelativeDegree:
    try:
        return relative_degree(plant.f_smooth, h, plant.x, plant.u)
    except TanksynthError as exc:
        text = str(exc)
        if "relative degree" in text:
            raise InfeasibleDesign(
                f"{text}; this holds identically, i.e. everywhere in the state space (the whole "
                f"operating region of plant '{plant.name}' included): output(s) {list(names)} "
                "cannot be decoupled") from None
        raise InfeasibleDesign(f"cannot compute relative degrees of plant '{plant.name}': {text}") from None


def _first_sign_change(values: np.ndarray, points: np.ndarray) -> tuple[int, int] | None:
    pos = np.flatnonzero(values > 0)
    neg = np.flatnonzero(values < 0)
    if not len(pos) or not len(neg):
        return None
    # Closest pair (one of each sign): the singular surface lies between them.
    best, pair = np.inf, None
    for i in pos[:400]:
        d = np.linalg.norm(points[neg[:400]] - points[i], axis=1)
        j = int(np.argmin(d))
        if d[j] < best:
            best, pair = d[j], (int(i), int(neg[j]))
    return pair


def _check_rank(plant: Plant, dec_num: sp.Matrix, names: Sequence[str], degrees: Sequence[int],
                Lambda_sym: sp.Matrix, points: np.ndarray) -> dict:
    """Raise `InfeasibleDesign` where ``rank Lambda < m``; return the evidence otherwise."""
    m = plant.m
    states = [s.name for s in plant.states]
    det_sym = simplify_if_small(Lambda_sym.det()) if m <= 4 else None
    if det_sym is not None and det_sym == 0:
        raise InfeasibleDesign(
            f"not decouplable: det Lambda(x) = 0 identically (rank Lambda < m = {m} everywhere in "
            f"the state space, the whole operating region included); Lambda = {Lambda_sym.tolist()} "
            f"for outputs {list(names)}")
    fn = compile_matrix("Lambda", dec_num, [plant.x], ["x"])
    L = batch_eval(fn, points)[0]                               # (M, m, m)
    finite = np.all(np.isfinite(L), axis=(1, 2))
    if not np.all(finite):
        k = int(np.flatnonzero(~finite)[0])
        raise InfeasibleDesign(f"Lambda(x) is not finite at x = {point_text(points[k], states)} on the "
                               f"operating region (outputs {list(names)})")
    # A row that vanishes: the relative degree of that output is not defined there.
    row = np.linalg.norm(L, axis=2)                         # (M, m)
    scale = np.max(row, axis=0)
    for i in range(m):
        bad = np.flatnonzero(row[:, i] <= RANK_TOL * scale[i])
        if len(bad):
            k = int(bad[0])
            raise InfeasibleDesign(
                f"relative degree of output {names[i]} is not defined at x = "
                f"{point_text(points[k], states)}: "
                f"L_g L_f^{degrees[i] - 1} h vanishes there although it is not identically zero "
                f"({len(bad)} of {len(points)} region points); not decouplable there")
    sv = np.linalg.svd(L, compute_uv=False)                 # (M, m)
    ratio = sv[:, -1] / sv[:, 0]
    k = int(np.argmin(ratio))
    if ratio[k] <= RANK_TOL:
        raise InfeasibleDesign(
            f"not decouplable: rank Lambda(x) < m = {m} at x = {point_text(points[k], states)} "
            f"(sigma_min/sigma_max = {ratio[k]:.3g}; {int(np.sum(ratio <= RANK_TOL))} of "
            f"{len(points)} region points)")
    det = np.linalg.det(L)
    pair = _first_sign_change(det, points)
    if pair is not None:
        a, b = points[pair[0]], points[pair[1]]
        detf = lambda x: float(np.linalg.det(np.asarray(fn(x), dtype=float)))  # noqa: E731
        lo, hi = 0.0, 1.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if np.sign(detf(a + mid * (b - a))) == np.sign(det[pair[0]]):
                lo = mid
            else:
                hi = mid
        x_star = a + 0.5 * (lo + hi) * (b - a)
        raise InfeasibleDesign(
            f"not decouplable on the whole region: det Lambda(x) changes sign, so rank Lambda < "
            f"m = {m} on a surface through x = {point_text(x_star, states)} (between region points "
            f"{point_text(a, states)} and {point_text(b, states)})"
            + (f"; det Lambda = {det_sym}" if det_sym is not None else ""))
    return {"points": int(len(points)), "min_sigma_ratio": float(ratio[k]),
            "min_sigma_ratio_at": dict(zip(states, map(float, points[k]))),
            "det_sign": int(np.sign(det[0])),
            "det_symbolic": None if det_sym is None else str(det_sym)}


def _internal_coordinates(dphi: np.ndarray, count: int) -> list[int]:
    """States completing the rows of ``dPhi`` to a basis (least involved first)."""
    n = dphi.shape[1]
    order = np.argsort(np.linalg.norm(dphi, axis=0), kind="stable")
    chosen: list[int] = []
    base = dphi.copy()
    for j in order:
        trial = np.vstack([base, np.eye(n)[j]])
        if np.linalg.matrix_rank(trial, tol=1e-10 * max(1.0, np.abs(trial).max())) == trial.shape[0]:
            chosen.append(int(j))
            base = trial
            if len(chosen) == count:
                break
    return chosen


def _zero_dynamics(plant: Plant, rd_num: RelativeDegree, lie_num: Sequence[sp.Matrix],
                   alpha_sym: sp.Matrix, f0_sym: sp.Matrix, G_sym: sp.Matrix,
                   points: np.ndarray) -> ZeroDynamics:
    n, r = plant.n, rd_num.total
    d = n - r
    if d == 0:
        return ZeroDynamics(0, (), sp.zeros(0, 1), np.empty((0, n)), np.empty((0, 0)), -math.inf,
                            None, True, 0)
    vals = plant.parameter_values
    f0n, Gn = f0_sym.xreplace(vals), G_sym.xreplace(vals)
    alpha_n = alpha_sym.xreplace(vals)
    fcl = f0n + Gn * alpha_n
    phi = sp.Matrix.vstack(*lie_num)                       # (r, 1)
    # derivative components (k >= 1) must vanish on the zero-output manifold
    offsets = np.cumsum([0, *rd_num.degrees])
    deriv_rows = [int(offsets[i] + k) for i, theta in enumerate(rd_num.degrees) for k in range(1, theta)]
    xs = ca.SX.sym("x", n)
    fcl_fn = compile_matrix("fcl", fcl, [plant.x], ["x"])
    phi_fn = compile_matrix("phi", phi, [plant.x], ["x"])
    f_x = fcl_fn(xs)
    p_x = phi_fn(xs)
    funcs = ca.Function("zd", [xs], [ca.jacobian(f_x, xs), ca.jacobian(p_x, xs), p_x])
    # Project the points on the manifold {L_f^k h_i = 0, 1 <= k < theta_i} (Gauss-Newton).
    pts = np.array(points, dtype=float)
    ok = np.ones(len(pts), dtype=bool)
    if deriv_rows:
        lo = np.array([b[0] for b in plant.region.bounds])
        hi = np.array([b[1] for b in plant.region.bounds])
        for k in range(len(pts)):
            x = pts[k].copy()
            for _ in range(30):
                _, Jp, pv = (np.asarray(v, dtype=float) for v in funcs(x))
                res = pv.reshape(-1)[deriv_rows]
                if np.all(np.abs(res) <= 1e-12 * (1 + np.abs(pv).max())):
                    break
                step = np.linalg.lstsq(Jp[deriv_rows], res, rcond=None)[0]
                x = x - step
            _, _, pv = (np.asarray(v, dtype=float) for v in funcs(x))
            res = pv.reshape(-1)[deriv_rows]
            good = (np.all(np.isfinite(x)) and np.all(np.abs(res) <= 1e-9 * (1 + np.abs(pv).max()))
                    and np.all(x >= lo) and np.all(x <= hi) and not plant.region.violations(x, plant.x))
            ok[k] = bool(good)
            pts[k] = x
    pts = pts[ok]
    if not len(pts):
        raise InfeasibleDesign("zero dynamics: no grid point of the region lies on (or projects onto) "
                               "the zero-output manifold; cannot check their stability")
    Jf, Jp, _ = batch_eval(funcs, pts)
    coords = _internal_coordinates(Jp[0], d)
    E = np.eye(n)[coords]
    eigs, keep = [], []
    for k in range(len(pts)):
        M = np.vstack([Jp[k], E])
        if not (np.all(np.isfinite(M)) and np.all(np.isfinite(Jf[k]))):
            continue
        try:
            T = np.linalg.solve(M, np.vstack([np.zeros((r, d)), np.eye(d)]))
        except np.linalg.LinAlgError:
            continue
        eigs.append(np.linalg.eigvals(E @ Jf[k] @ T))
        keep.append(k)
    if not keep:
        raise InfeasibleDesign("zero dynamics: the Jacobian is not finite at any grid point")
    ev = np.array(eigs)
    kept = pts[keep]
    worst = int(np.argmax(ev.real.max(axis=1)))
    max_real = float(ev.real.max())
    closed = f0_sym + G_sym * alpha_sym
    zd_expr = sp.Matrix([simplify_if_small(closed[j]) for j in coords])
    return ZeroDynamics(d, tuple(plant.states[j].name for j in coords), zd_expr, kept, ev, max_real,
                        kept[worst], bool(max_real < 0), int(len(points) - len(kept)))


def decoupling_analysis(plant: Plant, outputs: Sequence[str] | None = None, *, per_axis: int = 11,
                        samples: int = 400, seed: int = 0, margin: float = 0.02) -> Decoupling:
    """Relative degrees, ``Lambda``, ``Lambda_0``, ``alpha``, ``beta`` and the zero dynamics.

    Parameters
    ----------
    plant : Plant
        Control-affine in its inputs.
    outputs : sequence of str, optional
        Outputs to decouple (plant outputs or state names); default all
        outputs. There must be as many as inputs.
    per_axis, samples, seed, margin
        Region points for the rank and zero-dynamics checks (see
        `region_points`).

    Returns
    -------
    Decoupling
        The zero dynamics are analysed but not judged: `feedback_linearization`
        refuses unstable ones.

    Raises
    ------
    DimensionError
        More (or fewer) outputs than inputs.
    InfeasibleDesign
        Relative degree undefined (identically, or at a point of the
        region), or ``rank Lambda < m`` somewhere on the region (the message
        names where).
    """
    h, names = select_outputs(plant, outputs)
    _square_or_raise(plant, names)
    rd = _relative_degree(plant, h, names)
    f0, G = control_affine(plant.f_smooth, plant.u)
    lie = tuple(sp.Matrix(lie_derivatives(sp.Matrix([h[i]]), f0, plant.x, theta))
                for i, theta in enumerate(rd.degrees))
    Lambda = rd.decoupling
    Lambda0 = rd.drift
    pts = region_points(plant, per_axis, samples, seed, margin)
    vals = plant.parameter_values
    rank = _check_rank(plant, Lambda.xreplace(vals), names, rd.degrees, Lambda, pts)
    beta = Lambda.inv(method="LU").applyfunc(simplify_if_small)
    alpha = (-beta * Lambda0).applyfunc(simplify_if_small)
    rd_num = RelativeDegree(rd.degrees, Lambda.xreplace(vals), Lambda0.xreplace(vals))
    lie_num = [L.xreplace(vals) for L in lie]
    zd = _zero_dynamics(plant, rd_num, lie_num, alpha, f0, G, pts)
    return Decoupling(plant.name, names, rd.degrees, Lambda, Lambda0, alpha, beta, h, lie, zd, rank)


