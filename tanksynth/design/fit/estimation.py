"""Grey-box estimation: the plant's free parameters and initial states from logged experiments.

`fit_parameters` minimises the simulation (output) error of the plant's sampled model
(`tanksynth.design.fit.model`: the simulator's own RK4 step, clipping and input saturation,
so a re-simulation with `tanksynth.sim` at the fitted values gives the fitted outputs) over
the free parameters (scaled to [0, 1] by their box) and each experiment's initial state,
by CasADi + IPOPT with multiple shooting (a node every ``shooting`` samples, continuity
constraints), from several starting points (the given start, then a seeded Latin
hypercube in the box). Each output is weighted by its noise level (estimated from the
data, re-estimated from the residuals once). Exact samples count by their error, censored
samples only where the model is inside the sensor limit (hinge), missing samples not at
all. The statistics (`tanksynth.design.fit.statistics`) come from the residual Jacobian of
the single-shooting map at the optimum.

IPOPT works on the lifted problem (each shooting interval carries its node state and its
own copy of the scaled parameters, equal by constraint) with a Gauss-Newton Hessian: the
gradient, the constraints' Jacobian and ``J_r^T J_r`` all come from one mapped evaluation of
every interval's block Jacobians per iterate.

Limits: the model steps over a hybrid plant's switching surface without locating it inside
the step (the simulator locates it), so for a hybrid plant a re-simulation may differ near
the crossings; only the simulation-error mode exists (``mode = "prediction"`` is refused).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import casadi as ca
import numpy as np
from scipy import stats
from scipy.stats import qmc

from tanksynth.design.fit.model import (FitModel, FreeParameterLike, direct_states, fit_model,
                                        quiet_solve)
from tanksynth.design.fit.problem import FitData, Intervals, fit_data, noise_guess
from tanksynth.design.fit.statistics import (WhitenessTest, fisher_covariance, hac_covariance,
                                             identifiable_note, profile_bound, t_interval,
                                             whiteness_test)
from tanksynth.errors import InfeasibleDesign, SpecError
from tanksynth.measurements.experiment import Experiment
from tanksynth.measurements.scores import fit_percent, rmse
from tanksynth.plants.base import Plant
from tanksynth.process import raise_if_interrupted

__all__ = ["FitResult", "fit_parameters", "SUBSTEPS", "FitOutOfTime"]

#: RK4 steps per sampling interval of the fit's model (the default of `tanksynth.sim.simulate`).
SUBSTEPS = 4

#: IPOPT return statuses counted as converged.
CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


class FitOutOfTime(InfeasibleDesign):
    """The fit's solves ran past its time bound (``max_time``): refused (exit 3)."""


class _Clock:
    """The fit's wall-clock bound, checked in every derivative evaluation (IPOPT then stops:
    its callbacks fail) and after every solve."""

    def __init__(self, max_time: float):
        self.max_time = float(max_time)
        self.deadline = time.monotonic() + self.max_time
        self.out = False

    def check(self) -> None:
        if self.out or time.monotonic() > self.deadline:
            self.out = True
            raise FitOutOfTime(f"the fit ran out of time (max_time = {self.max_time:g} s for all "
                               "its solves); raise max_time, give fewer starts, or decimate the "
                               "log / fit fewer or shorter files")


@dataclass(frozen=True)
class FitResult:
    """Outcome of `fit_parameters` (arrays read as given; values in parameter units).

    Attributes
    ----------
    names : tuple of str
        Free parameter names (the order of every array below).
    units : tuple of str
        Their units.
    values : ndarray, shape (k,)
        Estimates.
    stderr : ndarray, shape (k,)
        Standard errors (``inf`` for a parameter the data cannot determine).
    ci95 : ndarray, shape (k, 2)
        Confidence intervals at ``level`` (parameter units; named ci95 after the default level).
    interval_method : tuple of str
        How each interval was found: ``"wald"`` (Student t on the Fisher information),
        ``"hac"`` (Student t on the Newey-West covariance), ``"profile-hac"`` (profile with the
        threshold scaled by the HAC-to-Fisher variance ratio),
        ``"profile"`` (profile likelihood: the Wald interval was asymmetric or crossed the
        box) or ``"unidentifiable"`` (the box).
    correlation, covariance : ndarray, shape (k, k)
        Parameter correlation (1) and covariance (parameter units squared).
    x0 : ndarray, shape (E, n)
        Estimated initial state of each experiment (state units).
    covariance_method : str
        Which covariance ``stderr``, ``ci95``, ``covariance`` and ``correlation`` come from:
        ``"white"`` (Fisher information, white noise) when every output's residuals pass the
        whiteness test, ``"hac"`` (Newey-West sandwich) when one fails.
    covariance_note : str
        Why (the failed outputs with their Ljung-Box statistic and bound, the Bartlett lags).
    stderr_white, ci95_white, covariance_white : ndarray
        The white-noise (Fisher) standard errors (k,), Wald intervals (k, 2) (parameter units)
        and covariance (k, k) (parameter units squared).
    stderr_hac, covariance_hac : ndarray
        The autocorrelation-consistent standard errors (k,) (parameter units) and covariance
        (k, k) (parameter units squared).
    hac_lags : tuple of int
        Bartlett truncation lag per experiment (samples; `statistics.hac_lags`).
    converged : bool
        IPOPT converged for the kept optimum.
    at_bound : tuple of str
        Parameters at a face of their box (relative 1e-4 of the box).
    identifiable : bool
        Full-rank Fisher information.
    unidentifiable_note : str
        When not identifiable: the combination the data determine (e.g. ``mu13/A``).
    rmse, fit_percent : dict
        ``{experiment: {output: value}}``: RMSE (output units) and NRMSE fit (%) over the
        exact samples.
    whiteness : dict of str to WhitenessTest
        Residual autocorrelation test per output (pooled over the experiments).
    sigma : dict of str to float
        Noise level of each output estimated from the residuals (output units).
    weights : dict of str to float
        Weight ``1 / sigma`` each output's residuals had in the kept solve (1/output unit):
        the cost is ``sum (w_i residual)^2``.
    iterations : int
        IPOPT iterations of the kept solve.
    starts_tried : int
        Starting points solved (fewer than asked when `AGREE` starts agreed early).
    starts_agreeing : int
        Converged starts that reached the kept optimum (cost and values).
    cost : float
        ``sum of (residual / sigma)^2`` at the optimum (1).
    status : str
        IPOPT's return status of the kept solve.
    level : float
        Confidence level of ``ci95`` (dimensionless).
    dof : int
        Residual degrees of freedom.
    substeps : int
        RK4 steps per sampling interval of the model (simulate with the same).
    mode : str
        ``"simulation"``.
    experiments : tuple of str
        Experiment names, the rows of ``x0``.
    predicted : tuple of ndarray
        Model outputs (N_e, p_e) of each experiment at the optimum (its output columns).
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray
    stderr: np.ndarray
    ci95: np.ndarray
    interval_method: tuple[str, ...]
    correlation: np.ndarray
    covariance: np.ndarray
    x0: np.ndarray
    covariance_method: str
    covariance_note: str
    stderr_white: np.ndarray
    ci95_white: np.ndarray
    covariance_white: np.ndarray
    stderr_hac: np.ndarray
    covariance_hac: np.ndarray
    hac_lags: tuple[int, ...]
    converged: bool
    at_bound: tuple[str, ...]
    identifiable: bool
    unidentifiable_note: str
    rmse: dict[str, dict[str, float]]
    fit_percent: dict[str, dict[str, float]]
    whiteness: dict[str, WhitenessTest]
    sigma: dict[str, float]
    weights: dict[str, float]
    iterations: int
    starts_tried: int
    starts_agreeing: int
    cost: float
    status: str
    level: float
    dof: int
    substeps: int
    mode: str
    experiments: tuple[str, ...]
    predicted: tuple[np.ndarray, ...] = field(repr=False, default=())

    @property
    def parameters(self) -> dict[str, float]:
        """``{name: value}`` of the estimates."""
        return {nm: float(v) for nm, v in zip(self.names, self.values)}


class _Blocks:
    """Block derivatives of the lifted NLP, computed once per point and shared.

    Every interval's residuals and end state depend only on its own node state and parameter
    copy: one call of the mapped `Intervals.blocks` gives all their Jacobians, from which the
    objective's gradient, the constraints' Jacobian and the Gauss-Newton Hessian are
    assembled (numpy, fixed sparsity patterns).
    """

    def __init__(self, model: FitModel, res: Intervals):
        n, k = model.n, len(model.names)
        self.n, self.k, self.nz = n, k, n + k
        self.M = M = sum(res.intervals)
        self.mapped = res.blocks.map(M, "thread", 2)
        cat = lambda key: np.hstack([p[key] for p in res.packed])  # noqa: E731
        self.data = {key: cat(key) for key in ("U", "DT", "Y", "A", "B", "C", "Z")}
        self.lower = np.repeat(model.lower[:, None], M, axis=1)
        self.width = np.repeat((model.upper - model.lower)[:, None], M, axis=1)
        self.count = max(int(sum(res.counts)), 1)
        nz, nx = self.nz, self.nz * M
        # constraint rows: gaps of every interval that has a successor in its experiment, then
        # the parameter copies s_{m+1} - s_m
        self.gap_of: list[int] = []
        pos = 0
        for J in res.intervals:
            self.gap_of += list(range(pos, pos + J - 1))
            pos += J
        rows, cols, src = [], [], []          # src >= 0: index into vec(Jx); -1: -1, -2: +1
        row = 0
        for m in self.gap_of:
            for i in range(n):
                for j in range(nz):
                    rows.append(row + i)
                    cols.append(m * nz + j)
                    src.append(m * n * nz + j * n + i)      # Jx of m is (n, nz) column-major
                rows.append(row + i)
                cols.append((m + 1) * nz + i)
                src.append(-1)
            row += n
        for m in range(M - 1):
            for i in range(k):
                rows += [row + i, row + i]
                cols += [(m + 1) * nz + n + i, m * nz + n + i]
                src += [-2, -1]
            row += k
        self.ng = row
        self.jac_sp = ca.Sparsity.triplet(row, nx, rows, cols)
        self.jac_src = np.asarray(src)[np.lexsort((rows, cols))]     # column-major order
        hr, hc, hs = [], [], []
        for m in range(M):
            for j in range(nz):
                for i in range(j + 1):
                    hr.append(m * nz + i)
                    hc.append(m * nz + j)
                    hs.append(m * nz * nz + j * nz + i)
        self.hess_sp = ca.Sparsity.triplet(nx, nx, hr, hc)
        self.hess_src = np.asarray(hs)[np.lexsort((hr, hc))]
        self._key: bytes | None = None
        self._val: dict[str, np.ndarray] = {}

    def at(self, z: np.ndarray, w: np.ndarray) -> dict[str, np.ndarray]:
        """Values and block Jacobians at ``z`` (cached for the last point and weights)."""
        key = z.tobytes() + w.tobytes()
        if key == self._key:
            return self._val
        V = z.reshape(self.M, self.nz).T
        d = self.data
        out = self.mapped(V[:self.n], d["U"], d["DT"], V[self.n:], self.lower, self.width,
                          d["Y"], d["A"], d["B"], d["C"], d["Z"], np.repeat(w[:, None], self.M, axis=1))
        x_end = out[0].full()
        r = out[1].full()                                          # (qL, M)
        # the map's Jacobians are horizontal concatenations of (rows, nz) blocks: column m nz + j
        Jx = out[2].full().reshape(self.n, self.nz, self.M, order="F")
        Jr = out[3].full().reshape(r.shape[0], self.nz, self.M, order="F")
        # 0 * inf at a clipped level (the square root's slope at 0 times the clip's 0): the
        # derivative of the clipped branch is 0
        Jx = np.nan_to_num(Jx, nan=0.0, posinf=0.0, neginf=0.0)
        Jr = np.nan_to_num(Jr, nan=0.0, posinf=0.0, neginf=0.0)
        Jx = Jx.transpose(2, 0, 1)                                 # (M, n, nz)
        Jr = Jr.transpose(2, 0, 1)                                 # (M, qL, nz)
        gaps = [x_end[:, m] - V[:self.n, m + 1] for m in self.gap_of]
        eq = (V[self.n:, 1:] - V[self.n:, :-1]).T.ravel()
        g = np.concatenate(gaps + [eq]) if gaps else eq
        grad = np.einsum("mri,rm->mi", Jr, r).ravel() / self.count
        H = np.einsum("mri,mrj->mij", Jr, Jr) / self.count     # (M, nz, nz)
        jx_cm = Jx.transpose(0, 2, 1).ravel()                    # per m: (n, nz) column-major
        self._val = {"f": np.array([0.5 * float(np.sum(r * r)) / self.count]), "g": g,
                     "grad": grad, "jx": jx_cm, "H": H.transpose(0, 2, 1).ravel()}
        self._key = key
        return self._val

    def jac_values(self, v: dict[str, np.ndarray]) -> np.ndarray:
        """Nonzeros of the constraints' Jacobian (the order of ``jac_sp``)."""
        pool = np.concatenate([v["jx"], [-1.0, 1.0]])
        src = np.where(self.jac_src == -1, pool.size - 2, np.where(self.jac_src == -2, pool.size - 1,
                                                                  self.jac_src))
        return pool[src]


class _Derivative(ca.Callback):
    """One derivative function of the lifted NLP for IPOPT (``grad_f``, ``jac_g`` or
    ``hess_lag``), read off the shared `_Blocks`."""

    def __init__(self, kind: str, blocks: _Blocks, nx: int, q: int, clock: _Clock):
        ca.Callback.__init__(self)
        self.kind, self.b, self.nx, self.q, self.clock = kind, blocks, nx, q, clock
        self.construct(f"fit_{kind}", {})

    def get_n_in(self) -> int:  # noqa: D102
        return 4 if self.kind == "hess" else 2

    def get_n_out(self) -> int:  # noqa: D102
        return 1 if self.kind == "hess" else 2

    def get_name_in(self, i: int) -> str:  # noqa: D102
        return ("x", "p", "lam_f", "lam_g")[i]

    def get_name_out(self, i: int) -> str:  # noqa: D102
        names = {"grad": ("f", "grad_f_x"), "jac": ("g", "jac_g_x"), "hess": ("triu_hess_gamma_x_x",)}
        return names[self.kind][i]

    def get_sparsity_in(self, i: int) -> ca.Sparsity:  # noqa: D102
        return ca.Sparsity.dense((self.nx, self.q, 1, self.b.ng)[i], 1)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:  # noqa: D102
        if self.kind == "hess":
            return self.b.hess_sp
        if self.kind == "jac":
            return ca.Sparsity.dense(self.b.ng, 1) if i == 0 else self.b.jac_sp
        return ca.Sparsity.dense(1, 1) if i == 0 else ca.Sparsity.dense(self.nx, 1)

    def eval(self, arg: Any) -> Any:  # noqa: D102
        # interrupted (the signal's exception, raised in an earlier call, was swallowed by
        # CasADi): every evaluation fails at once, so IPOPT stops; `_Solver.solve` re-raises
        raise_if_interrupted()
        self.clock.check()   # out of time: the same (`_Solver.solve` raises `FitOutOfTime`)
        z = np.asarray(arg[0], dtype=float).ravel()
        w = np.asarray(arg[1], dtype=float).ravel()
        v = self.b.at(z, w)
        if self.kind == "grad":
            return [ca.DM(v["f"]), ca.DM(v["grad"])]
        if self.kind == "jac":
            return [ca.DM(v["g"]), ca.DM(self.b.jac_sp, self.b.jac_values(v))]
        lam_f = float(np.asarray(arg[2]).ravel()[0])
        return [ca.DM(self.b.hess_sp, lam_f * v["H"][self.b.hess_src])]


class _Solver:
    """The multiple-shooting NLP, built once and solved from several points."""

    def __init__(self, model: FitModel, res: Intervals, max_iter: int, clock: _Clock):
        self.model, self.res, self.clock = model, res, clock
        k, n = len(model.names), model.n
        self.k, self.n = k, n
        self.J = list(res.intervals)
        M = sum(self.J)
        self.M = M
        # lifted: every interval carries its node state and its own copy of the scaled
        # parameters (equal by constraint), so every derivative is block-sparse
        V = ca.MX.sym("V", n + k, M)
        s = V[n:, :]
        theta = ca.repmat(ca.DM(model.lower), 1, M) + ca.repmat(ca.DM(model.upper - model.lower), 1, M) * s
        nodes_sym, pos = [], 0
        for J in self.J:
            nodes_sym.append(V[:n, pos:pos + J])
            pos += J
        w = ca.MX.sym("w", model.q)
        r, g = res.nlp(theta, nodes_sym, w)
        if M > 1:
            g = ca.vertcat(g, ca.vec(s[:, 1:] - s[:, :-1]))
        self.count = max(int(sum(res.counts)), 1)
        obj = 0.5 * ca.sumsqr(r) / self.count
        opts: dict[str, Any] = {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
                "show_eval_warnings": False, "ipopt.max_iter": int(max_iter), "ipopt.tol": 1e-9,
                "ipopt.acceptable_tol": 1e-6, "ipopt.acceptable_iter": 3,
                "ipopt.mu_strategy": "adaptive"}
        z = ca.vec(V)
        # Gauss-Newton Hessian of the Lagrangian (J_r^T J_r of the residuals; the constraints'
        # and the residuals' curvature left out: exact at a zero-residual fit, positive
        # semi-definite), the constraints' Jacobian and the gradient all from one evaluation
        # of the intervals' block Jacobians per point
        self.blocks = _Blocks(model, res)
        nx = (n + k) * M
        self._callbacks = [_Derivative(kind, self.blocks, nx, model.q, clock) for kind in ("grad", "jac", "hess")]
        opts["grad_f"], opts["jac_g"], opts["hess_lag"] = self._callbacks
        problem: dict[str, Any] = {"x": z, "f": obj, "g": g, "p": w}
        self.solver = ca.nlpsol("fit", "ipopt", problem, opts)
        lo_x = np.where(np.isfinite(model.state_lower), model.state_lower, -np.inf)
        hi_x = np.where(np.isfinite(model.state_upper), model.state_upper, np.inf)
        self.lbx = np.tile(np.concatenate([lo_x, np.zeros(k)]), M)
        self.ubx = np.tile(np.concatenate([hi_x, np.ones(k)]), M)

    def theta(self, s: np.ndarray) -> np.ndarray:
        return self.model.lower + (self.model.upper - self.model.lower) * s

    def scaled(self, theta: np.ndarray) -> np.ndarray:
        return (np.asarray(theta) - self.model.lower) / (self.model.upper - self.model.lower)

    def pack(self, s: np.ndarray, S: Sequence[np.ndarray]) -> np.ndarray:
        """The NLP's vector from scaled parameters (k,) and node states (n, J_e) per experiment."""
        nodes_all = np.hstack(list(S))
        return np.vstack([nodes_all, np.repeat(np.asarray(s)[:, None], self.M, axis=1)]).T.ravel()

    def solve(self, z0: np.ndarray, w: np.ndarray, fix: tuple[int, float] | None = None,
              lam: np.ndarray | None = None) -> dict[str, Any]:
        lbx, ubx = self.lbx.copy(), self.ubx.copy()
        if fix is not None:
            lbx[self.n + fix[0]] = ubx[self.n + fix[0]] = fix[1]   # the copies follow (equal)
        z0 = np.clip(z0, lbx, ubx)
        args: dict[str, Any] = dict(x0=z0, p=w, lbx=lbx, ubx=ubx, lbg=0.0, ubg=0.0)
        if lam is not None:
            args["lam_g0"] = lam
        try:
            sol = quiet_solve(self.solver, **args)
        finally:
            raise_if_interrupted()  # IPOPT stopped on an interruption: no other start runs
        self.clock.check()
        st = self.solver.stats()
        return {"z": np.asarray(sol["x"]).ravel(), "f": float(sol["f"]) * 2 * self.count,
                "lam": np.asarray(sol["lam_g"]).ravel(), "status": str(st["return_status"]),
                "iterations": int(st["iter_count"])}

    def split(self, z: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """Scaled parameters (k,) (the first interval's copy) and the node states (n, J) of
        each experiment."""
        V = z.reshape(self.M, self.n + self.k).T
        out, pos = [], 0
        for J in self.J:
            out.append(V[:self.n, pos:pos + J])
            pos += J
        return V[self.n:, 0].copy(), out


def _initial_nodes(model: FitModel, res: Intervals, single: "_Single", theta: np.ndarray,
                   w: np.ndarray) -> list[np.ndarray]:
    """Node states of a start: the model simulated at ``theta`` from a data-based initial state,
    with every directly measured state replaced by its measurement at the node."""
    direct = direct_states(model, theta)
    out = []
    mid = np.where(np.isfinite(model.state_lower) & np.isfinite(model.state_upper),
                   0.5 * (model.state_lower + model.state_upper),
                   np.where(np.isfinite(model.state_lower), model.state_lower, 0.0))
    L = res.length
    for e, d in enumerate(res.data):
        x0 = mid.copy()
        meas = _measured(d, direct)
        for i, series in meas.items():
            ok = np.flatnonzero(np.isfinite(series))
            if ok.size:
                x0[i] = series[ok[0]]
        x0 = np.clip(x0, model.state_lower, model.state_upper)
        S = single.nodes(theta, x0, e, w)
        idx = np.arange(res.intervals[e]) * L
        for i, series in meas.items():
            vals = series[idx]
            S[i] = np.where(np.isfinite(vals), vals, S[i])
        out.append(np.clip(S, model.state_lower[:, None], model.state_upper[:, None]))
    return out


def _measured(d: FitData, direct: Mapping[int, tuple[int, float, float]]) -> dict[int, np.ndarray]:
    """State index -> the state read off its exact measurements in ``d`` (``(y - b) / a``;
    NaN elsewhere)."""
    out = {}
    for j, col in enumerate(d.columns):
        if col in direct:
            i, a, b = direct[col]
            out[i] = np.where(d.exact[:, j], (d.y[:, j] - b) / a, np.nan)
    return out


class _Single:
    """Single-shooting functions: outputs, residuals and their Jacobian (all experiments)."""

    def __init__(self, model: FitModel, res: Intervals):
        k, n, E = len(model.names), model.n, len(res.data)
        theta, X0, w = ca.MX.sym("theta", k), ca.MX.sym("x0", n, E), ca.MX.sym("w", model.q)
        rs, ys = [], []
        for e in range(E):
            r, Y = res.single(e, X0[:, e], theta, w)
            rs.append(r)
            ys.append(Y)
        self.rows = np.concatenate([res.flags(e) for e in range(E)])
        r = ca.vertcat(*rs)
        z = ca.vertcat(theta, ca.vec(X0))
        self.residuals = ca.Function("r", [theta, X0, w], [r])
        self.jacobian = ca.Function("jr", [theta, X0, w], [r, ca.jacobian(r, z)])
        self.outputs = ca.Function("y", [theta, X0], [ca.substitute(y, w, ca.DM.ones(model.q)) for y in ys])
        x0 = ca.MX.sym("x0e", n)
        self._nodes = {}
        for e, J in enumerate(res.intervals):
            acc = res.function.mapaccum(f"n{e}", J)
            p = res.packed[e]
            xe = acc(x0, p["U"], p["DT"], ca.repmat(theta, 1, J), p["Y"], p["A"], p["B"], p["C"],
                     p["Z"], ca.repmat(w, 1, J))[0]
            self._nodes[e] = ca.Function(f"nodes{e}", [theta, x0, w], [ca.horzcat(x0, xe[:, :J - 1])])

    def nodes(self, theta: np.ndarray, x0: np.ndarray, e: int, w: np.ndarray) -> np.ndarray:
        """States at the shooting nodes of experiment ``e`` (n, J) simulated from ``x0``."""
        return np.asarray(self._nodes[e](theta, x0, w))

    def predicted(self, theta: np.ndarray, X0: np.ndarray) -> list[np.ndarray]:
        """Model outputs (N_e, q) of every experiment."""
        outs = self.outputs(theta, X0)
        outs = outs if isinstance(outs, (list, tuple)) else [outs]
        return [np.asarray(Y).T for Y in outs]

    def stats(self, theta: np.ndarray, X0: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted residuals and their Jacobian, sample rows only."""
        r, J = self.jacobian(theta, X0, w)
        return np.asarray(r).ravel()[self.rows], np.asarray(J)[self.rows]

    def cost(self, theta: np.ndarray, X0: np.ndarray, w: np.ndarray) -> float:
        r = np.asarray(self.residuals(theta, X0, w)).ravel()
        return float(r @ r)


def fit_parameters(plant: Plant, free: Sequence[FreeParameterLike], experiments: Sequence[Experiment],
                   *, ts_substeps: int | None = None, starts: int = 8, seed: int = 0,
                   mode: str = "simulation", shooting: int = 20, level: float = 0.95,
                   max_iter: int = 500, max_time: float = 600.0) -> FitResult:
    """Fit the free parameters and each experiment's initial state to logged experiments.

    Parameters
    ----------
    plant : Plant
        The plant, fixed parameters at their values.
    free : sequence of FreeParameterLike
        Parameters to estimate: ``name``, ``start``, ``lower``, ``upper`` (parameter unit),
        ``unit`` (e.g. `tanksynth.spec.FreeParameter`).
    experiments : sequence of Experiment
        Logged runs, fitted jointly (each with its own initial state).
    ts_substeps : int, optional
        RK4 steps per sampling interval (default `SUBSTEPS`, the simulator's default);
        re-simulate with the same (`FitResult.substeps`).
    starts : int
        Most starting points (the given start, then a Latin hypercube in the box), >= 1,
        solved in that order; the multi-start stops early once `AGREE` (3) converged starts
        reach the best optimum found (parameters within 1e-3 of their box, cost within 1e-6
        relative).
    seed : int
        Seed of the Latin hypercube.
    mode : str
        ``"simulation"`` (output error). ``"prediction"`` is not available yet (refused).
    shooting : int
        Samples per multiple-shooting interval (>= 1).
    level : float
        Confidence level of the intervals, in (0, 1) (dimensionless).
    max_iter : int
        IPOPT iteration limit per start.
    max_time : float
        Wall-clock time all the solves may take (s, > 0), from the NLP's construction on.

    Returns
    -------
    FitResult
        ``converged`` False (with ``status``) when IPOPT did not converge: the caller decides.

    Raises
    ------
    SpecError
        Bad free parameters, options or data (an experiment that does not match the plant).
    FitOutOfTime
        The solves ran past ``max_time``.
    """
    if mode != "simulation":
        raise SpecError(f"fit mode {mode!r} is not available: only 'simulation' (output error) is "
                        "implemented; the one-step-ahead prediction-error mode is not",
                        key="design.mode")
    for key, val, lo in (("starts", starts, 1), ("shooting", shooting, 1), ("max_iter", max_iter, 1)):
        if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < lo:
            raise SpecError(f"{key} must be an integer >= {lo}, got {val!r}", key=f"design.{key}")
    if not 0.0 < float(level) < 1.0:
        raise SpecError(f"level must lie in (0, 1), got {level!r}", key="design.level")
    if not (np.isfinite(max_time) and max_time > 0):
        raise SpecError(f"max_time must be a positive number of seconds, got {max_time!r}",
                        key="design.max_time")
    if not experiments:
        raise SpecError("no experiment to fit", key="design.data")
    names_seen = [e.name for e in experiments]
    if len(set(names_seen)) != len(names_seen):
        raise SpecError(f"experiment names must be unique, got {names_seen}", key="design.data")
    model = fit_model(plant, free, SUBSTEPS if ts_substeps is None else ts_substeps)
    data = [fit_data(plant, e) for e in experiments]
    for d in data:
        if not (d.exact.any() or d.low.any() or d.high.any()):
            raise SpecError(f"experiment {d.name}: no output sample to fit", key="design.data")
    res = Intervals(model, data, int(shooting))
    single = _Single(model, res)
    solver = _Solver(model, res, int(max_iter), _Clock(max_time))
    k = len(model.names)
    w = 1.0 / noise_guess(data, res.outputs)

    # starting points: the given start, then a seeded Latin hypercube of the scaled box
    points = [solver.scaled(model.start)]
    if starts > 1:
        points += list(qmc.LatinHypercube(d=k, seed=int(seed)).random(int(starts) - 1))
    runs: list[dict[str, Any]] = []
    for s0 in points:
        S0 = _initial_nodes(model, res, single, solver.theta(s0), w)
        z0 = solver.pack(s0, S0)
        runs.append(solver.solve(z0, w))
        if _settled(solver, runs):
            break
    ok = [r for r in runs if r["status"] in CONVERGED]
    if not ok and all(r["status"] == "Invalid_Number_Detected" for r in runs):
        theta, X0 = _unpack(solver, runs[0]["z"])
        _require_finite(model, single, theta, X0, w, "from every start (IPOPT: "
                        "Invalid_Number_Detected)", force=True)
    pool = ok or runs
    best = min(pool, key=lambda r: r["f"] if np.isfinite(r["f"]) else np.inf)
    # noise levels from the residuals; re-weight once when they differ from the data's guess
    theta, X0 = _unpack(solver, best["z"])
    sigma = _sigma(single, res, theta, X0)
    if np.count_nonzero(res.counts) > 1 and np.max(np.abs(np.log(sigma * w))[res.counts > 0]) > np.log(1.2):
        w = 1.0 / sigma
        again = solver.solve(best["z"], w, lam=best["lam"])
        if again["status"] in CONVERGED or best["status"] not in CONVERGED:
            best = again
            theta, X0 = _unpack(solver, best["z"])
            sigma = _sigma(single, res, theta, X0)
    kept = solver.split(best["z"])[0]
    agreeing = sum(1 for r in ok if np.allclose(solver.split(r["z"])[0], kept, atol=1e-3, rtol=0.0))
    return _finish(plant, model, res, single, solver, best, w, sigma, float(level), len(runs),
                   agreeing)


#: Converged starts that must reach the best optimum before the multi-start stops early.
AGREE = 3


def _settled(solver: _Solver, runs: Sequence[dict[str, Any]]) -> bool:
    """Early stop of the multi-start: `AGREE` converged starts reached the best optimum found
    so far (scaled parameters within 1e-3 of the box, cost within 1e-6 relative)."""
    ok = [r for r in runs if r["status"] in CONVERGED and np.isfinite(r["f"])]
    if len(ok) < AGREE:
        return False
    best = min(ok, key=lambda r: r["f"])
    kept = solver.split(best["z"])[0]
    same = [r for r in ok if abs(r["f"] - best["f"]) <= 1e-6 * max(abs(best["f"]), 1e-300)
            and np.allclose(solver.split(r["z"])[0], kept, atol=1e-3, rtol=0.0)]
    return len(same) >= AGREE


def _unpack(solver: _Solver, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s, S = solver.split(z)
    return solver.theta(s), np.column_stack([x[:, 0] for x in S])


def _sigma(single: _Single, res: Intervals, theta: np.ndarray, X0: np.ndarray) -> np.ndarray:
    """Noise level per output: RMS of its unweighted residuals over the samples (floored; 1
    for an output without data)."""
    r = np.asarray(single.residuals(theta, X0, np.ones(res.model.q))).ravel()[single.rows]
    flags = np.concatenate([np.asarray(res.flags(e)) for e in range(len(res.data))])
    which = np.tile(np.arange(res.model.q), flags.size // res.model.q)[flags]
    out = np.ones(res.model.q)
    for i in range(res.model.q):
        v = r[which == i]
        if v.size:
            out[i] = max(float(np.sqrt(np.mean(v ** 2))), 1e-12)
    return out


def _finish(plant: Plant, model: FitModel, res: Intervals, single: _Single, solver: _Solver,
            best: dict[str, Any], w: np.ndarray, sigma: np.ndarray, level: float, tried: int,
            agreeing: int) -> FitResult:
    """Statistics at the kept optimum and the result."""
    k = len(model.names)
    theta, X0 = _unpack(solver, best["z"])
    r, Jr = single.stats(theta, X0, w)
    _require_finite(model, single, theta, X0, w, "at the optimum")
    # 0 * inf at a clipped level (a square root's slope at 0 times the clip's 0): the clipped
    # branch's derivative is 0, as in the solver's blocks
    Jr = np.nan_to_num(Jr, nan=0.0, posinf=0.0, neginf=0.0)
    fisher = fisher_covariance(Jr, r, theta, k)
    predicted_all = single.predicted(theta, X0)
    predicted = tuple(Yh[:, list(d.columns)] for d, Yh in zip(res.data, predicted_all))
    names = [nm for nm in model.output_names if any(nm in d.output_names for d in res.data)]
    series: dict[str, list[np.ndarray]] = {nm: [] for nm in names}
    for d, Yh in zip(res.data, predicted):
        for j, nm in enumerate(d.output_names):
            series[nm].append(np.where(d.exact[:, j], d.y[:, j], np.nan) - Yh[:, j])
    white = {nm: whiteness_test(series[nm]) for nm in names}
    # residuals not white: the Fisher (white-noise) covariance understates the spread; the
    # Newey-West sandwich takes the residuals' autocorrelation into account
    flags = [np.flatnonzero(np.asarray(res.flags(e))) for e in range(len(res.data))]
    exp_id = np.concatenate([np.full(f.size, e) for e, f in enumerate(flags)])
    sample = np.concatenate([f // model.q for f in flags])
    hac = hac_covariance(Jr, r, theta, k, exp_id, sample, fisher)
    failed = [nm for nm in names if not white[nm].passed]
    use_hac = bool(failed)
    stderr = hac.stderr if use_hac else fisher.stderr
    covariance = hac.covariance if use_hac else fisher.covariance
    correlation = hac.correlation if use_hac else fisher.correlation
    if use_hac:
        note = ("residuals not white (" + ", ".join(
            f"{nm} Q = {white[nm].statistic:.3g} > {white[nm].bound:.3g}" for nm in failed)
            + "): intervals from the autocorrelation-consistent (Newey-West) covariance, "
            f"Bartlett lags {', '.join(map(str, hac.lags))}")
    else:
        note = "residuals white: intervals from the Fisher information (white noise)"
    ci_white = t_interval(theta, fisher.stderr, fisher.dof, level)
    ci = t_interval(theta, stderr, fisher.dof, level)
    methods = ["hac" if use_hac else "wald"] * k
    q = float(stats.t.ppf(0.5 + level / 2.0, fisher.dof))
    cost = float(r @ r)
    involved = np.isinf(fisher.stderr)
    for i in range(k):
        if involved[i]:
            ci[i] = ci_white[i] = (model.lower[i], model.upper[i])
            methods[i] = "unidentifiable"
            continue
        half = q * stderr[i]
        # the profile's excess is in white-noise units: its threshold scales with the variance
        # ratio, so that a quadratic cost gives the Wald (or HAC-Wald) half-width
        target = (half / fisher.stderr[i]) ** 2 if fisher.stderr[i] > 0 else q * q
        crosses = ci[i, 0] < model.lower[i] or ci[i, 1] > model.upper[i]
        if crosses or not _quadratic(single, fisher, theta, X0, w, i, half, cost, target):
            excess = _profile(solver, single, best, w, i, cost, fisher.sigma2)
            lo, _ = profile_bound(excess, theta[i], -half, model.lower[i], target)
            hi, _ = profile_bound(excess, theta[i], half, model.upper[i], target)
            ci[i] = (lo, hi)
            methods[i] = "profile-hac" if use_hac else "profile"
    width = model.upper - model.lower
    at_bound = tuple(nm for nm, v, lo, hi, wd in zip(model.names, theta, model.lower, model.upper, width)
                     if v - lo <= 1e-4 * wd or hi - v <= 1e-4 * wd)
    rm: dict[str, dict[str, float]] = {}
    fp: dict[str, dict[str, float]] = {}
    for d, Yh in zip(res.data, predicted):   # the scores the verdict recomputes (one definition)
        r, f = rmse(d.y, Yh, d.exact), fit_percent(d.y, Yh, d.exact)
        rm[d.name] = {nm: float(r[j]) for j, nm in enumerate(d.output_names)}
        fp[d.name] = {nm: float(f[j]) for j, nm in enumerate(d.output_names)}
    units = {prm.name: prm.unit for prm in plant.parameters}
    return FitResult(
        names=model.names, units=tuple(units[nm] for nm in model.names), values=theta,
        stderr=stderr, ci95=ci, interval_method=tuple(methods),
        correlation=correlation, covariance=covariance, x0=X0.T.copy(),
        covariance_method="hac" if use_hac else "white", covariance_note=note,
        stderr_white=fisher.stderr, ci95_white=ci_white, covariance_white=fisher.covariance,
        stderr_hac=hac.stderr, covariance_hac=hac.covariance, hac_lags=hac.lags,
        converged=best["status"] in CONVERGED, at_bound=at_bound,
        identifiable=fisher.identifiable,
        unidentifiable_note=identifiable_note(model.names, fisher.null_vectors),
        rmse=rm, fit_percent=fp, whiteness=white,
        sigma={nm: float(sigma[model.output_names.index(nm)]) for nm in names},
        weights={nm: float(w[model.output_names.index(nm)]) for nm in names},
        iterations=best["iterations"], starts_tried=tried, starts_agreeing=agreeing, cost=cost,
        status=best["status"], level=level, dof=fisher.dof, substeps=model.substeps,
        mode="simulation", experiments=tuple(d.name for d in res.data), predicted=predicted)


def _require_finite(model: FitModel, single: _Single, theta: np.ndarray, X0: np.ndarray,
                    w: np.ndarray, where: str, force: bool = False) -> None:
    """Refuse (`InfeasibleDesign`, exit 3) a model whose residuals are not finite (or any
    case when ``force``), naming the outputs."""
    full = np.asarray(single.residuals(theta, X0, w)).ravel()
    bad = ~np.isfinite(full) & single.rows
    if not (force or np.any(bad) or not np.all(np.isfinite(theta))):
        return
    which = sorted({model.output_names[int(j) % model.q] for j in np.flatnonzero(bad)})
    raise InfeasibleDesign(
        f"the model evaluates to non-finite values {where}: {int(np.count_nonzero(bad))} "
        "predicted sample(s) NaN/inf" + (f" (output(s) {', '.join(which)})" if which else "")
        + ", e.g. a square root of a negative level difference or a division by zero; write the "
        "model so that it is finite on the whole state box (e.g. sign(h1 - h3)*sqrt(abs(h1 - h3)))")


def _quadratic(single: _Single, fisher: Any, theta: np.ndarray, X0: np.ndarray, w: np.ndarray,
               i: int, half: float, cost: float, target: float) -> bool:
    """The cost along the linearised profile path at the Wald bounds is close to the quadratic model.

    Moving ``theta_i`` by ``+-half`` and the other parameters by the conditional mean
    (``cov[:, i] / cov[i, i]``; the initial states re-fitted by one Gauss-Newton step), the
    excess ``(cost - optimum) / s^2`` of a model linear in the parameters is ``target``
    exactly: within 20 % on both sides, the Wald interval stands.
    """
    cov = fisher.covariance
    if not (np.isfinite(cov[i, i]) and cov[i, i] > 0):
        return False
    k = len(theta)
    for sign in (-1.0, 1.0):
        th = theta + sign * half * cov[:, i] / cov[i, i]
        r, J = single.stats(th, X0, w)
        Jx = J[:, k:]
        x0 = X0
        if Jx.shape[1]:
            dx, *_ = np.linalg.lstsq(Jx, -r, rcond=None)
            x0 = X0 + dx.reshape(X0.shape[1], X0.shape[0]).T
        excess = (single.cost(th, x0, w) - cost) / fisher.sigma2
        if not (0.8 * target <= excess <= 1.25 * target):
            return False
    return True


def _profile(solver: _Solver, single: _Single, best: dict[str, Any], w: np.ndarray, i: int,
             cost: float, sigma2: float) -> Any:
    """``theta_i -> (profile cost - cost) / s^2``: re-optimised with ``theta_i`` fixed."""
    lo, width = solver.model.lower[i], solver.model.upper[i] - solver.model.lower[i]

    def excess(value: float) -> float:
        sol = solver.solve(best["z"], w, fix=(i, (value - lo) / width), lam=best["lam"])
        theta, X0 = _unpack(solver, sol["z"])
        return (single.cost(theta, X0, w) - cost) / sigma2

    return excess
