"""Verdict of ``ts_state_feedback`` and ``ts_output_feedback`` (Takagi-Sugeno PDC), own numerics.

Nothing here imports the design code it judges. From the artefact and the
plant it re-derives:

``ts_model_recheck``
    the premises ``z_k = (n_k(x) - n_k(x0)) / (a_k . (x - x0))`` recomputed
    from the plant's atoms, the stored vertices ``A_i`` (gain ``F``) rebuilt from them
    and the stored bounds, and ``sum_i mu_i (A_i e + B v)`` compared with
    the plant's ``f(x, u)`` at seeded points of the domain (exactness,
    memberships in ``[0, 1]``);
``lmi_recheck``
    the PDC conditions of the recorded relaxation, ``sum w_ij (He(P (A_i -
    B K_j)) + 2 alpha P) < 0`` (eigvalsh), ``P > 0``;
``region_recheck``
    ``c = min(faces g_l^2 / (G_l P^-1 G_l'), pumps margin_j^2 / (k_ij P^-1
    k_ij'))`` recomputed and compared with the stored ``region_c``; the ball
    of radius ``region_margin`` inside;
``region_simulation``
    the nonlinear plant (`tanksynth.sim.simulate`) in closed loop with the
    PDC law (premises from the state, or the estimate / the measurements)
    from seeded points on and inside the region's boundary: every run stays
    in the domain, never asks the pumps for more than they give, its
    Lyapunov function does not grow and it converges.
"""

from __future__ import annotations

import itertools
from typing import Any, Mapping

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.analysis.takagi_sugeno import quasi_lpv
from tanksynth.verify.closed_loops import ClosedLoop, sampling_period
from tanksynth.verify.common import artefact_gain, fmt, guard, option
from tanksynth.verify.traces import TraceRecorder

__all__ = ["RebuiltModel", "rebuild_model", "pdc_conditions", "region_level", "PDCLaw",
           "MeasuredPremiseObserver", "region_points", "simulate_region", "ts_control_verdict",
           "ts_control_run"]


class RebuiltModel:
    """The deviation TS model rebuilt from the plant and the artefact (independent numerics).

    Parameters
    ----------
    plant : Plant
    doc : mapping
        The artefact.
    """

    def __init__(self, plant: Any, doc: Mapping[str, Any]):
        self.plant = plant
        self.q = quasi_lpv(plant)
        n, m = plant.n, plant.m
        self.x0 = artefact_gain(doc, "x_op").reshape(n)
        self.u0 = artefact_gain(doc, "u_op").reshape(m)
        self.forms = artefact_gain(doc, "forms").reshape(-1, n)
        self.lower = artefact_gain(doc, "z_lower")
        self.upper = artefact_gain(doc, "z_upper")
        self.B = self.q.B
        self.C = self.q.C
        p = self.forms.shape[0]
        self.sigmas = list(itertools.product((1, 2), repeat=p))
        self.A = np.array([self.q.A_lin + sum(np.outer(self.q.incidence[:, k], self.forms[k])
                                              * (self.upper[k] if s == 1 else self.lower[k])
                                              for k, s in enumerate(sig)) for sig in self.sigmas])
        self.at0 = self.q.atom_values(self.x0[None, :])[0]
        h = 1e-6
        d = self.forms / np.sum(self.forms ** 2, axis=1, keepdims=True)
        self.slope0 = np.array([(self.q.atom_values((self.x0 + h * d[k])[None, :])[0, k]
                                 - self.q.atom_values((self.x0 - h * d[k])[None, :])[0, k]) / (2 * h)
                                for k in range(p)])
        dom = ((doc.get("diagnostics") or {}).get("ts_model") or {}).get("domain") or {}
        self.lo_box = np.asarray(dom.get("lower", [b[0] for b in plant.region.bounds]), dtype=float)
        self.hi_box = np.asarray(dom.get("upper", [b[1] for b in plant.region.bounds]), dtype=float)
        ineq = dom.get("inequalities") or []
        self.G = np.array([r["G"] for r in ineq], dtype=float).reshape(len(ineq), n)
        self.g = np.array([r["g"] for r in ineq], dtype=float)

    def inside(self, X: np.ndarray, tol: float = 0.0) -> np.ndarray:
        """Rows of ``X`` in the domain (box and orderings), with a tolerance (state units).

        Parameters
        ----------
        X, tol : ndarray (M, n), float
            States and tolerance (state units, m).
        """
        X = np.atleast_2d(X)
        ok = np.all((X >= self.lo_box - tol) & (X <= self.hi_box + tol), axis=-1)
        if self.G.size:
            ok &= np.all(X @ self.G.T >= self.g - tol, axis=-1)
        return ok

    def faces(self) -> tuple[np.ndarray, np.ndarray]:
        """``G e <= g`` in deviation coordinates."""
        n = self.x0.size
        G = np.vstack([np.eye(n), -np.eye(n), -self.G])
        g = np.concatenate([self.hi_box - self.x0, self.x0 - self.lo_box, self.G @ self.x0 - self.g])
        return G, g

    def memberships(self, X: np.ndarray) -> np.ndarray:
        """``mu_i`` at M points (premises recomputed from the plant's atoms).

        Parameters
        ----------
        X : ndarray, shape (M, n)
            States (state units, m).
        """
        X = np.atleast_2d(np.asarray(X, dtype=float))
        dt = (X - self.x0) @ self.forms.T
        with np.errstate(divide="ignore", invalid="ignore"):
            Z = (self.q.atom_values(X) - self.at0) / dt
        Z = np.where(np.abs(dt) < 1e-12, self.slope0, Z)
        F1 = (Z - self.lower) / (self.upper - self.lower)
        mu = np.ones((X.shape[0], len(self.sigmas)))
        for i, sig in enumerate(self.sigmas):
            for k, s in enumerate(sig):
                mu[:, i] *= F1[:, k] if s == 1 else 1.0 - F1[:, k]
        return mu


def rebuild_model(plant: Any, doc: Mapping[str, Any]) -> RebuiltModel:
    """`RebuiltModel` of an artefact.

    Parameters
    ----------
    plant, doc : Plant, mapping
        The plant model and the artefact.
    """
    return RebuiltModel(plant, doc)


def _weights(relaxation: str, r: int) -> list[dict]:
    if relaxation == "all_pairs":
        return [{(i, j): 1.0} for i in range(r) for j in range(r)]
    out = [{(i, i): 1.0} for i in range(r)]
    for i in range(r):
        for j in range(i + 1, r):
            if relaxation == "vertex":
                out.append({(i, j): 1.0, (j, i): 1.0})
            elif relaxation == "tuan":
                out.append({(i, i): 2.0 / (r - 1), (i, j): 1.0, (j, i): 1.0})
                out.append({(j, j): 2.0 / (r - 1), (i, j): 1.0, (j, i): 1.0})
            else:
                raise ValueError(f"unknown relaxation {relaxation!r}")
    return out


def pdc_conditions(P: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray, alpha: float,
                   relaxation: str) -> np.ndarray:
    """Largest eigenvalue of every PDC condition matrix (must all be < 0).

    Parameters
    ----------
    P, A, B, K : ndarray (n, n), (r, n, n), (n, m), (r, m, n)
        Lyapunov matrix, vertex matrices [1/s], input matrix, vertex gains (input per state unit).
    alpha, relaxation : float, str
        Decay rate [1/s]; ``"vertex"``, ``"tuan"`` or ``"all_pairs"``.
    """
    r = A.shape[0]
    He = {}
    out = []
    for cond in _weights(relaxation, r):
        S = np.zeros_like(P)
        for (i, j), w in cond.items():
            if (i, j) not in He:
                M = P @ A[i] - P @ B @ K[j]
                He[i, j] = M + M.T + 2 * alpha * P
            S += w * He[i, j]
        out.append(np.linalg.eigvalsh(0.5 * (S + S.T))[-1])
    return np.array(out)


def region_level(P: np.ndarray, K: np.ndarray, G: np.ndarray, g: np.ndarray,
                 margins: np.ndarray | None, extra: np.ndarray | None = None,
                 estimate_faces: bool = False) -> float:
    """Closed-form ``c`` of the certified region (see the module docstring).

    Parameters
    ----------
    P, K, G, g : ndarray
        Lyapunov matrix, vertex gains (input per state unit), faces ``G e <= g`` (state units).
    margins, extra, estimate_faces : ndarray or None, ndarray or None, bool
        Input margins (input units; None: none), added to ``P^-1`` (observer), faces on the estimate too.
    """
    Pi = np.linalg.inv(0.5 * (P + P.T))
    Pk = Pi if extra is None else Pi + extra
    vals = [g[l] ** 2 / (G[l] @ Pi @ G[l]) for l in range(len(g))]
    if estimate_faces:
        vals += [g[l] ** 2 / (G[l] @ Pk @ G[l]) for l in range(len(g))]
    if margins is not None:
        vals += [margins[j] ** 2 / (K[i, j] @ Pk @ K[i, j]) for i in range(K.shape[0])
                 for j in range(len(margins)) if K[i, j] @ Pk @ K[i, j] > 0]
    return float(min(vals))


class PDCLaw:
    """``u = u0 - sum_j mu_j K_j (x_hat - x0)`` (a batch `ControlLaw`).

    ``premise_source`` (optional) is an object whose ``premise_states()``
    gives the states the premises are computed from (measured premises).

    Parameters
    ----------
    model, K, premise_source : RebuiltModel, ndarray (r, m, n), object or None
        Rebuilt TS model; vertex gains (input per state unit); gives ``premise_states()`` (None: estimate).
    """

    def __init__(self, model: RebuiltModel, K: np.ndarray, premise_source: Any = None):
        self.model, self.K, self.source = model, K, premise_source

    def raw(self, x_hat: np.ndarray, xz: np.ndarray | None = None) -> np.ndarray:
        """Unsaturated input (M, m).

        Parameters
        ----------
        x_hat, xz : ndarray (M, n), ndarray (M, n) or None
            Estimates and premise states (state units, m; None: ``x_hat``).
        """
        mu = self.model.memberships(x_hat if xz is None else xz)
        E = x_hat - self.model.x0
        return self.model.u0 - np.einsum("mj,jan,mn->ma", mu, self.K, E)

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m)."""
        xz = self.source.premise_states() if self.source is not None else None
        return self.raw(x_hat, xz)


class MeasuredPremiseObserver:
    """PDC observer with measured premises (a `BatchEstimator`), RK4 with held ``y``, ``u``.

    ``dx_hat/dt = sum_i mu_i(z) (A_i (x_hat - x0) + B (u - u0)) + sum_j mu_j(z) L_j (y - C x_hat)``
    with ``z`` from the measured states.

    Parameters
    ----------
    model, L : RebuiltModel, ndarray (r, n, q)
        Rebuilt TS model; vertex gains (state units per output unit and s).
    ts, substeps : float, int
        Sampling period [s]; RK4 steps per period.
    """

    def __init__(self, model: RebuiltModel, L: np.ndarray, ts: float, substeps: int):
        self.m, self.L, self.h, self.sub = model, L, ts / substeps, substeps
        self.rows = [int(np.flatnonzero(r)[0]) for r in model.C]
        self._x = self._y = None

    def reset(self, x_hat0: np.ndarray) -> None:
        """Initial estimates (M, n).

        Parameters
        ----------
        x_hat0 : ndarray, shape (M, n)
            Initial estimates (state units, m).
        """
        self._x, self._y = np.array(x_hat0, dtype=float), None

    def premise_states(self) -> np.ndarray:
        """The estimate with its measured entries replaced by the measurements."""
        X = self._x.copy()
        if self._y is not None:
            X[:, self.rows] = self._y
        return X

    def step(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Measurement (M, q), previous input (M, m) -> estimate (M, n).

        Parameters
        ----------
        y, u : ndarray (M, q), ndarray (M, m)
            Measurements (output units, m) and previous inputs (input units, m^3/s).
        """
        if self._y is not None:
            mu = self.m.memberships(self.premise_states())
            Lm = np.einsum("mj,jnq->mnq", mu, self.L)
            Am = np.einsum("mi,ink->mnk", mu, self.m.A)
            y0 = self._y

            def f(x: np.ndarray) -> np.ndarray:
                return (np.einsum("mnk,mk->mn", Am, x - self.m.x0) + (u - self.m.u0) @ self.m.B.T
                        + np.einsum("mnq,mq->mn", Lm, y0 - x @ self.m.C.T))

            x = self._x
            for _ in range(self.sub):
                k1 = f(x)
                k2 = f(x + 0.5 * self.h * k1)
                k3 = f(x + 0.5 * self.h * k2)
                k4 = f(x + self.h * k3)
                x = x + self.h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            self._x = x
        self._y = np.array(y, dtype=float)
        return self._x


class _PlantModel:
    """What `TSObserver` needs: the TS model at the estimate equals the plant's ``f``."""

    def __init__(self, plant: Any, A0: np.ndarray, C: np.ndarray):
        self.plant, self.A0, self.C = plant, A0, C

    def rhs(self, X: np.ndarray, U: np.ndarray) -> np.ndarray:
        return self.plant.compiled.rhs(X, U)


def region_points(P: np.ndarray, c: float, count: int, seed: int,
                  scale: float = 1.0) -> np.ndarray:
    """Seeded deviations: half on ``e' P e = scale^2 c``, half inside (radius uniform in (0, 1)).

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Lyapunov matrix of the deviation ``e`` (in 1 / (state units)^2 when ``c`` is
        dimensionless).
    c : float
        Level of ``e' P e <= c`` (the units of ``e' P e``).
    count : int
        Number of points.
    seed : int
        Random seed.
    scale : float
        Boundary radius factor (dimensionless).
    """
    rng = np.random.default_rng(seed)
    n = P.shape[0]
    U = rng.normal(size=(count, n))
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    Lc = np.linalg.cholesky(0.5 * (P + P.T))
    E = np.linalg.solve(Lc.T, U.T).T * np.sqrt(c) * scale
    radius = np.ones(count)
    radius[count // 2:] = rng.uniform(0.05, 1.0, size=count - count // 2)
    return E * radius[:, None]


def _sim_setup(doc: Mapping[str, Any], spec: Any) -> dict:
    plant = spec.plant
    n, m = plant.n, plant.m
    model = RebuiltModel(plant, doc)
    r = model.A.shape[0]
    K = artefact_gain(doc, "K").reshape(r, m, n)
    P = artefact_gain(doc, "P").reshape(n, n)
    Acl = [model.A[i] - model.B @ K[j] for i in range(r) for j in range(r)]
    fast = max(float(np.max(np.abs(np.linalg.eigvals(M)))) for M in Acl)
    return dict(plant=plant, model=model, K=K, P=P, r=r, fastest=fast)


def simulate_region(doc: Mapping[str, Any], spec: Any, E0: np.ndarray, *, horizon: float,
                    eps0: np.ndarray | None = None, trace: TraceRecorder | None = None,
                    ts: float | None = None) -> dict:
    """Closed-loop runs from ``x0 + E0`` (estimate ``x0 + E0 - eps0``): per-run flags and ``V``.

    Parameters
    ----------
    doc, spec, E0, eps0 : mapping, Spec, ndarray (M, n), ndarray (M, n) or None
        Artefact, spec, initial deviations and estimation errors (state units, m).
    horizon, ts, trace : float, float or None, TraceRecorder or None
        Simulated time [s], sampling period [s] (None: the spec's), recorder of the runs.

    Returns
    -------
    dict
        ``left_domain``, ``saturated`` (bool per run), ``V`` (M, N + 1) of
        ``e' P e`` (plus ``beta eps' Po eps`` with an observer), ``t``, ``x``.
    """
    from tanksynth.sim.simulate import simulate

    s = _sim_setup(doc, spec)
    plant, model, K, P = s["plant"], s["model"], s["K"], s["P"]
    n = plant.n
    if ts is None:
        ts = float(min(1.0, 0.05 / max(s["fastest"], 1e-9)))
    estimator, law, Po, beta = None, PDCLaw(model, K), None, 0.0
    x_start = model.x0 + E0
    xh0 = x_start if eps0 is None else x_start - eps0
    if doc["method"] == "ts_output_feedback":
        L = artefact_gain(doc, "L")
        Po = artefact_gain(doc, "Po").reshape(n, n)
        beta = float(artefact_gain(doc, "beta")[0])
        if L.ndim == 3:
            sub = int(np.ceil(ts * max(float(np.max(np.abs(np.linalg.eigvals(model.A[i] - L[j] @ model.C))))
                                       for i in range(s["r"]) for j in range(s["r"])) / 0.5)) + 1
            estimator = MeasuredPremiseObserver(model, L, ts, sub)
            law = PDCLaw(model, K, estimator)
        else:
            from tanksynth.verify.ts_observer import TSObserver

            A0 = artefact_gain(doc, "A0").reshape(n, n)
            estimator = TSObserver(_PlantModel(plant, A0, model.C), L, ts)
    steps = int(np.ceil(horizon / ts))
    res = simulate(plant, ts=ts, steps=steps, x0=x_start, seeds=np.arange(len(E0)), controller=law,
                   estimator=estimator, x_hat0=xh0, u_init=np.broadcast_to(model.u0, (len(E0), plant.m)))
    X, XH = np.asarray(res.x), np.asarray(res.x_hat)
    E = X - model.x0
    V = np.einsum("mkn,nl,mkl->mk", E, P, E)
    if Po is not None:
        Eps = X - XH
        V = V + beta * np.einsum("mkn,nl,mkl->mk", Eps, Po, Eps)
    left = ~np.all(model.inside(X.reshape(-1, n), 1e-9).reshape(X.shape[:2]), axis=1)
    flat = XH.reshape(-1, n)
    if isinstance(estimator, MeasuredPremiseObserver):
        XZ = flat.copy()
        XZ[:, estimator.rows] = X.reshape(-1, n)[:, estimator.rows]
        U = law.raw(flat, XZ)
    else:
        U = law.raw(flat)
    lim = np.asarray(plant.input_limits, dtype=float).reshape(plant.m, 2)
    tol = 1e-9 * (lim[:, 1] - lim[:, 0])
    within = np.all((U >= lim[:, 0] - tol) & (U <= lim[:, 1] + tol), axis=1)
    sat = ~np.all(within.reshape(X.shape[:2]), axis=1)
    if trace is not None:
        trace.record(res, plant, scenario="certified region", check="region_simulation",
                     estimator=estimator is not None)
    return {"left_domain": left, "saturated": sat, "V": V, "t": np.asarray(res.t), "x": X, "ts": ts}


def ts_control_verdict(doc: Mapping[str, Any], spec: Any, *,
                       trace: TraceRecorder | None = None) -> list[Check]:
    """Verdict of a ``ts_state_feedback`` / ``ts_output_feedback`` artefact (see the module).

    Parameters
    ----------
    doc, spec, trace : mapping, Spec, TraceRecorder or None
        The artefact, the validated spec and a recorder of the simulated runs.
    """
    plant = spec.plant
    n, m = plant.n, plant.m
    diag = doc.get("diagnostics") or {}
    checks: list[Check] = []

    def model_checks() -> list[Check]:
        s = _sim_setup(doc, spec)
        model = s["model"]
        stored = artefact_gain(doc, "F").reshape(model.A.shape)
        d = float(np.max(np.abs(stored - model.A)) / max(np.max(np.abs(model.A)), 1e-300))
        X = np.random.default_rng(int(option(doc, spec, "seed", 0)) + 7).uniform(
            model.lo_box, model.hi_box, size=(4000, n))
        X = X[model.inside(X)]
        lim = np.asarray(plant.input_limits, dtype=float).reshape(m, 2)
        U = np.random.default_rng(3).uniform(np.where(np.isfinite(lim[:, 0]), lim[:, 0], -1),
                                             np.where(np.isfinite(lim[:, 1]), lim[:, 1], 1),
                                             size=(len(X), m))
        mu = model.memberships(X)
        ts_rhs = np.einsum("mi,inj,mj->mn", mu, model.A, X - model.x0) + (U - model.u0) @ model.B.T
        f = plant.compiled.rhs(X, U)
        err = float(np.max(np.abs(ts_rhs - f)) / max(np.max(np.abs(f)), 1e-300))
        ok = d <= 1e-9 and err <= 1e-8 and mu.min() >= -1e-12
        return [Check("ts_model_recheck", bool(ok),
                      f"vertices rebuilt from the plant's atoms and the stored premise forms/bounds: "
                      f"relative difference {d:.3g}; TS model vs f(x, u) at {len(X)} seeded domain "
                      f"points: relative error {err:.3g}, smallest membership {mu.min():.3g}",
                      {"vertex_difference": d, "max_relative_error": err,
                       "min_membership": float(mu.min())})]

    def lmi_checks() -> list[Check]:
        s = _sim_setup(doc, spec)
        rel = str(diag.get("relaxation", ""))
        alpha = float((diag.get("lmi") or {}).get("alpha", option(doc, spec, "decay_rate", 0.0)))
        lam = pdc_conditions(s["P"], s["model"].A, s["model"].B, s["K"], alpha, rel)
        pmin = float(np.linalg.eigvalsh(s["P"])[0])
        out = [Check("lmi_recheck", bool(lam.max() < 0 and pmin > 0),
                     f"{len(lam)} PDC conditions ({rel}) sum w_ij (He(P (A_i - B K_j)) + 2 alpha P) "
                     f"with alpha = {alpha:g} 1/s, recomputed in numpy: largest eigenvalue "
                     f"{lam.max():.4g} (must be < 0); smallest eigenvalue of P {pmin:.4g}",
                     {"max_eigenvalue": float(lam.max()), "count": int(lam.size)})]
        if doc["method"] == "ts_output_feedback":
            out += _observer_checks(doc, s)
        return out

    def region_checks() -> list[Check]:
        s = _sim_setup(doc, spec)
        G, g = s["model"].faces()
        margins = diag.get("input_margins")
        margins = None if margins is None else np.asarray(margins, float)
        extra, est = None, False
        if doc["method"] == "ts_output_feedback":
            Po = artefact_gain(doc, "Po").reshape(n, n)
            extra = np.linalg.inv(Po) / float(artefact_gain(doc, "beta")[0])
            est = diag.get("premises") == "estimated"
        c = region_level(s["P"], s["K"], G, g, margins, extra, est)
        stored = float(artefact_gain(doc, "region_c")[0])
        inner = float(np.sqrt(c / np.linalg.eigvalsh(s["P"])[-1]))
        need = float(option(doc, spec, "region_margin", 0.01))
        ok = abs(c - stored) <= 1e-6 * max(c, 1e-300) and inner >= need
        return [Check("region_recheck", bool(ok),
                      f"level c = {c:.6g} re-derived in closed form (domain faces, pump margins) vs "
                      f"stored {stored:.6g}; inner radius {inner:.4g} (region_margin {need:g}); "
                      f"largest deviations {fmt(np.sqrt(c * np.diag(np.linalg.inv(s['P']))))}",
                      {"c": c, "stored_c": stored, "inner_radius": inner})]

    def sim_checks() -> list[Check]:
        s = _sim_setup(doc, spec)
        c = float(artefact_gain(doc, "region_c")[0])
        count = int(option(doc, spec, "verify_points", 24))
        seed = int(option(doc, spec, "seed", 0))
        E0 = region_points(s["P"], c, count, seed) * (1 - 1e-6)
        eps0 = None
        decay = float(diag.get("decay_rate", 0.0))
        if doc["method"] == "ts_output_feedback":
            Po = artefact_gain(doc, "Po").reshape(n, n)
            beta = float(artefact_gain(doc, "beta")[0])
            E0 = E0 * np.sqrt(0.5)          # half the budget to e, half to eps (odd runs)
            eps0 = region_points(Po * beta, 0.5 * c, count, seed + 1) * (1 - 1e-6)
            eps0[::2] = 0.0
            decay = min(decay, float((diag.get("composite") or {}).get("controller_decay", decay)))
        horizon = float(min(max(4.0 / max(decay, 1e-9), 100.0), 4000.0))
        out = simulate_region(doc, spec, E0, horizon=horizon, eps0=eps0, trace=trace)
        V = out["V"]
        grow = float(np.max(np.diff(V, axis=1) / np.maximum(V[:, :-1], 1e-300) *
                            (V[:, :-1] > 1e-10 * c)))
        final = float(np.max(V[:, -1] / np.maximum(V[:, 0], 1e-300)))
        left, sat = int(out["left_domain"].sum()), int(out["saturated"].sum())
        ok = left == 0 and sat == 0 and final <= 0.1 and grow <= 1e-3
        return [Check("region_simulation", bool(ok),
                      f"{len(E0)} closed-loop runs of the nonlinear plant from seeded points on and "
                      f"inside the certified region (sampled at {out['ts']:.3g} s for {horizon:.4g} s): "
                      f"{left} left the TS domain, {sat} asked for pump flows outside the limits, "
                      f"largest relative growth of V per sample {grow:.3g} (<= 1e-3), largest "
                      f"V(T)/V(0) {final:.3g} (<= 0.1)",
                      {"runs": len(E0), "left_domain": left, "saturated": sat, "max_growth": grow,
                       "max_final_ratio": final, "ts": out["ts"], "horizon": horizon})]

    for name, fn in (("ts_model_recheck", model_checks), ("lmi_recheck", lmi_checks),
                     ("region_recheck", region_checks), ("region_simulation", sim_checks)):
        checks += guard(name, fn)
    return checks


def _observer_checks(doc: Mapping[str, Any], s: dict) -> list[Check]:
    diag = doc.get("diagnostics") or {}
    n = s["P"].shape[0]
    model = s["model"]
    Po = artefact_gain(doc, "Po").reshape(n, n)
    L = artefact_gain(doc, "L")
    if L.ndim == 3:
        obs = diag.get("observer") or {}
        rel = str(obs.get("relaxation", ""))
        alpha = float((obs.get("lmi") or {}).get("alpha", 0.0))
        # Lyapunov for A_i - L_j C with Po: the dual conditions on (A_i', C', L_j') with P = Po^-1
        # are congruent to these.
        r = model.A.shape[0]
        lam = []
        for cond in _weights(rel, r):
            S = np.zeros((n, n))
            for (i, j), w in cond.items():
                M = Po @ (model.A[i] - L[j] @ model.C)
                S += w * (M + M.T + 2 * alpha * Po)
            lam.append(np.linalg.eigvalsh(0.5 * (S + S.T))[-1])
        lam = np.array(lam)
        return [Check("observer_lmi_recheck", bool(lam.max() < 0),
                      f"{lam.size} PDC observer conditions ({rel}) on Po, L_j with alpha = {alpha:g} "
                      f"1/s: largest eigenvalue {lam.max():.4g} (< 0)", {"max_eigenvalue": float(lam.max())})]
    Q = artefact_gain(doc, "Q").reshape(n, n)
    A0 = artefact_gain(doc, "A0").reshape(n, n)
    psi = float((diag.get("observer") or {}).get("psi", np.nan))
    Gm = Po @ (A0 - L @ model.C)
    blk = np.block([[Gm + Gm.T + psi ** 2 * Q, Po], [Po, -Q]])
    lam = float(np.linalg.eigvalsh(0.5 * (blk + blk.T))[-1])
    dA = float(np.max(np.abs(A0 - model.A.mean(axis=0))))
    return [Check("observer_lmi_recheck", bool(np.isfinite(psi) and lam < 0 and dA <= 1e-9),
                  f"LMI (28) [[He(Po (A0 - L C)) + psi^2 Q, Po], [Po, -Q]] with psi = {psi:.4g} 1/s: "
                  f"largest eigenvalue {lam:.4g} (< 0); stored A0 vs the mean rebuilt vertex: {dA:.3g}",
                  {"max_eigenvalue": lam, "psi": psi})]


def ts_control_run(doc: Mapping[str, Any], spec: Any) -> ClosedLoop:
    """Campaign runner: the PDC law (and its observer) in closed loop (`ClosedLoop`).

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    s = _sim_setup(doc, spec)
    ts = sampling_period(spec)
    model = s["model"]
    n = spec.plant.n
    factory = None
    law = PDCLaw(model, s["K"])
    if doc["method"] == "ts_output_feedback":
        L = artefact_gain(doc, "L")
        if L.ndim == 3:
            shared = MeasuredPremiseObserver(model, L, ts, 64)
            law = PDCLaw(model, s["K"], shared)     # the law reads the observer's measured premises
            factory = lambda: shared  # noqa: E731
        else:
            from tanksynth.verify.ts_observer import TSObserver

            A0 = artefact_gain(doc, "A0").reshape(n, n)
            factory = lambda: TSObserver(_PlantModel(spec.plant, A0, model.C), L, ts)  # noqa: E731
    outputs = [s_.name for s_ in spec.plant.outputs]
    states = [s_.name for s_ in spec.plant.states]
    tracked = tuple(states.index(o) for o in outputs if o in states)
    return ClosedLoop(law, factory, model.x0.copy(), model.u0.copy(), tracked,
                      f"Takagi-Sugeno PDC ({doc['method']}) regulating to x0 = {fmt(model.x0)} "
                      "(set-point changes are ignored: the PDC is designed for one operating point)")
