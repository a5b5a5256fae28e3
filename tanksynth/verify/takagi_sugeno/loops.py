"""Closed loops of the Takagi-Sugeno PDC artefacts on the nonlinear plant (own numerics).

The PDC law (and its observer) rebuilt from the artefact, the set-point
switch, seeded samples of the certified region and the conditions a run
from it must meet: used by the verdict (`tanksynth.verify.takagi_sugeno.verdicts`,
`tanksynth.verify.takagi_sugeno.setpoint`) and by the campaign (`tanksynth.verify.takagi_sugeno.campaign`)
alike, so that both check the same things.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.plants.base import Plant
from tanksynth.sim.simulate import simulate
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain
from tanksynth.verify.observer_lmi.verdicts import TSObserver
from tanksynth.verify.traces import TraceRecorder
from tanksynth.verify.takagi_sugeno.model import RebuiltModel

__all__ = ["PDCLaw", "MeasuredPremiseObserver", "PlantObserverModel", "plant_ts_observer", "SwitchedLaw", "region_points", "simulate_region",
           "region_sample", "region_horizon", "region_conditions", "GROWTH_LIMIT", "FINAL_RATIO",
           "loop_setup"]


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
        KE = (mu @ self.K.reshape(len(self.K), -1)).reshape(len(mu), *self.K.shape[1:])  # sum_j mu_j K_j
        return self.model.u0 - (KE @ E[:, :, None])[:, :, 0]

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
        self._x: np.ndarray = np.empty((0, model.A.shape[1]))    # set by reset
        self._y: np.ndarray | None = None

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


class PlantObserverModel:
    """The model a `TSObserver` of a ``ts_output_feedback`` artefact runs on: the plant's own ``f``
    (the TS model at the estimate equals it) with the stored ``A0`` and ``C``.

    Parameters
    ----------
    plant : Plant
        The plant model.
    A0 : ndarray, shape (n, n)
        The observer's linear part (1/s).
    C : ndarray, shape (q, n)
        The output matrix (output units per state unit).
    """

    def __init__(self, plant: Plant, A0: np.ndarray, C: np.ndarray):
        self.plant, self.A0, self.C = plant, A0, C
        self.casadi_rhs = plant.compiled.f    # TSObserver steps a whole period in one call

    def rhs(self, X: np.ndarray, U: np.ndarray) -> np.ndarray:
        """``f(x, u)`` at M points: states (M, n), inputs (M, m) -> derivatives (M, n).

        Parameters
        ----------
        X, U : ndarray (M, n), ndarray (M, m)
            States (state units, m) and inputs (input units, m^3/s).
        """
        return np.asarray(self.plant.compiled.rhs(X, U), dtype=float)


def plant_ts_observer(doc: Mapping[str, Any], plant: Plant, C: np.ndarray, ts: float) -> TSObserver:
    """The single-gain TS observer of a ``ts_output_feedback`` artefact (its ``L`` and ``A0``).

    Parameters
    ----------
    doc : mapping
        The artefact (gains ``L`` (n, q) and ``A0`` (n, n)).
    plant : Plant
        The plant model.
    C : ndarray, shape (q, n)
        The output matrix of the rebuilt model.
    ts : float
        Sampling period [s].
    """
    n = plant.n
    return TSObserver(PlantObserverModel(plant, artefact_gain(doc, "A0").reshape(n, n), C),
                      artefact_gain(doc, "L"), ts)


def region_points(P: np.ndarray, c: float, count: int, seed: int | Sequence[int],
                  scale: float = 1.0) -> np.ndarray:
    """Seeded deviations: half on ``e' P e = scale^2 c``, half inside (radius uniform in (0, 1)).

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Lyapunov matrix (1 / (state units)^2).
    c : float
        Level ``c`` of ``e' P e <= c`` (dimensionless).
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


def loop_setup(doc: Mapping[str, Any], spec: Spec, prefix: str = "") -> dict:
    """Rebuilt model, gains ``K``, ``P``, rules ``r`` and the fastest closed-loop eigenvalue (1/s).

    Parameters
    ----------
    doc, spec, prefix : mapping, Spec, str
        The artefact, the spec and the prefix of the gain keys (``"sp_"``: set-point).
    """
    plant = spec.plant
    n, m = plant.n, plant.m
    model = RebuiltModel(plant, doc, prefix)
    r = model.A.shape[0]
    K = artefact_gain(doc, prefix + "K").reshape(r, m, n)
    P = artefact_gain(doc, prefix + "P").reshape(n, n)
    Acl = [model.A[i] - model.B @ K[j] for i in range(r) for j in range(r)]
    fast = max(float(np.max(np.abs(np.linalg.eigvals(M)))) for M in Acl)
    return dict(plant=plant, model=model, K=K, P=P, r=r, fastest=fast)


class SwitchedLaw:
    """Law ``first`` before ``t_switch`` (s), ``second`` from then on (a batch `ControlLaw`).

    Parameters
    ----------
    first, second : PDCLaw
        The laws about the first and the second operating point.
    t_switch : float
        Switching time [s] (0: ``second`` only).
    """

    def __init__(self, first: PDCLaw, second: PDCLaw, t_switch: float):
        self.first, self.second, self.t_switch = first, second, float(t_switch)

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m)."""
        return (self.second if t >= self.t_switch - 1e-9 else self.first)(x_hat, reference, t)


def _estimator(doc: Mapping[str, Any], plant: Plant, model: RebuiltModel, r: int, ts: float) -> Any:
    """The observer of a ``ts_output_feedback`` artefact (about the first operating point)."""
    L = artefact_gain(doc, "L")
    if L.ndim == 3:
        sub = int(np.ceil(ts * max(float(np.max(np.abs(np.linalg.eigvals(model.A[i] - L[j] @ model.C))))
                                   for i in range(r) for j in range(r)) / 0.5)) + 1
        return MeasuredPremiseObserver(model, L, ts, sub)
    return plant_ts_observer(doc, plant, model.C, ts)


def simulate_region(doc: Mapping[str, Any], spec: Spec, E0: np.ndarray, *, horizon: float,
                    eps0: np.ndarray | None = None, trace: TraceRecorder | None = None,
                    ts: float | None = None, switch_at: float | None = None,
                    scenario: str = "certified region", check: str = "region_simulation") -> dict:
    """Closed-loop runs from ``x0 + E0`` (estimate ``x0 + E0 - eps0``): per-run flags and ``V``.

    With ``switch_at`` (s), the law about the set-point (gain keys ``sp_``)
    replaces the first one from that time on (0: from the start); ``V`` is
    then the Lyapunov function of the law acting at each sample, about its
    own operating point. The observer (output feedback) is the first
    design's whatever the set-point.

    Parameters
    ----------
    doc, spec, E0, eps0 : mapping, Spec, ndarray (M, n), ndarray (M, n) or None
        Artefact, spec, initial deviations from the first operating point and
        estimation errors (state units, m).
    horizon, ts, trace : float, float or None, TraceRecorder or None
        Simulated time [s], sampling period [s] (None: resolving the closed
        loops), recorder of the runs.
    switch_at : float or None
        Time of the set-point change [s]; None: none.
    scenario, check : str
        Names recorded with the trace.

    Returns
    -------
    dict
        ``left_domain``, ``saturated`` (bool per run), ``V`` (M, N + 1) of
        ``e' P e`` (plus ``beta eps' Po eps`` with an observer), ``t``, ``x``,
        ``ts``, ``switch`` (first sample of the second law, or None).
    """
    plant = spec.plant
    n = plant.n
    stages = [loop_setup(doc, spec)] + ([loop_setup(doc, spec, "sp_")] if switch_at is not None else [])
    if ts is None:
        ts = float(min(1.0, 0.05 / max(max(st["fastest"] for st in stages), 1e-9)))
    of = doc["method"] == "ts_output_feedback"
    s1 = stages[0]
    estimator = _estimator(doc, plant, s1["model"], s1["r"], ts) if of else None
    source = estimator if isinstance(estimator, MeasuredPremiseObserver) else None
    laws = [PDCLaw(st["model"], st["K"], source) for st in stages]
    law = laws[0] if switch_at is None else SwitchedLaw(laws[0], laws[1], switch_at)
    x_start = s1["model"].x0 + E0
    xh0 = x_start if eps0 is None else x_start - eps0
    steps = int(np.ceil(horizon / ts))
    u_init = stages[-1 if switch_at is not None and switch_at <= 0 else 0]["model"].u0
    res = simulate(plant, ts=ts, steps=steps, x0=x_start, seeds=np.arange(len(E0)), controller=law,
                   estimator=estimator, x_hat0=xh0, u_init=np.broadcast_to(u_init, (len(E0), plant.m)))
    X, XH = np.asarray(res.x), np.asarray(res.x_hat)
    t = np.asarray(res.t)
    k_sw = None if switch_at is None else int(np.searchsorted(t, switch_at - 1e-9))
    V = np.zeros(X.shape[:2])
    U = np.zeros((X.shape[0] * X.shape[1], plant.m))
    for k, (st, lw) in enumerate(zip(stages, laws)):
        part = np.arange(X.shape[1]) < k_sw if (k == 0 and k_sw is not None) else (
            np.arange(X.shape[1]) >= (k_sw or 0))
        E = X - st["model"].x0
        Vk = np.einsum("mkn,nl,mkl->mk", E, st["P"], E)
        if of:
            Po = artefact_gain(doc, "Po").reshape(n, n)
            Eps = X - XH
            Vk = Vk + float(artefact_gain(doc, ("sp_" if k else "") + "beta")[0]) * \
                np.einsum("mkn,nl,mkl->mk", Eps, Po, Eps)
        V[:, part] = Vk[:, part]
        flat = XH.reshape(-1, n)
        XZ = None
        if source is not None:
            XZ = flat.copy()
            XZ[:, source.rows] = X.reshape(-1, n)[:, source.rows]
        rows = np.broadcast_to(part, X.shape[:2]).reshape(-1)
        U[rows] = lw.raw(flat[rows], None if XZ is None else XZ[rows])
    left = ~np.all(s1["model"].inside(X.reshape(-1, n), 1e-9).reshape(X.shape[:2]), axis=1)
    lim = np.asarray(plant.input_limits, dtype=float).reshape(plant.m, 2)
    tol = 1e-9 * (lim[:, 1] - lim[:, 0])
    within = np.all((U >= lim[:, 0] - tol) & (U <= lim[:, 1] + tol), axis=1)
    sat = ~np.all(within.reshape(X.shape[:2]), axis=1)
    if trace is not None:
        trace.record(res, plant, scenario=scenario, check=check, estimator=estimator is not None,
                     runs=len(E0))
    return {"left_domain": left, "saturated": sat, "V": V, "t": t, "x": X, "ts": ts, "switch": k_sw,
            "result": res}


#: Largest relative growth of ``V`` per sample and largest ``V(T)/V(0)`` a region run may show.
GROWTH_LIMIT, FINAL_RATIO = 1e-3, 0.1


def region_sample(doc: Mapping[str, Any], spec: Spec, count: int, seed: Any) -> tuple[np.ndarray, Any]:
    """Seeded initial deviations on and inside the certified region (and estimation errors).

    Half the points on the boundary ``V = c`` (scaled by ``1 - 1e-6``), half
    inside; with an observer, even runs start with ``eps = 0`` and odd runs
    share the level between ``e`` and ``eps``.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    count : int
        Number of runs.
    seed : int or sequence of int
        Seed of `numpy.random.default_rng`.

    Returns
    -------
    (ndarray (count, n), ndarray (count, n) or None)
        Deviations from the operating point and estimation errors (state units, m).
    """
    n = spec.plant.n
    P = artefact_gain(doc, "P").reshape(n, n)
    c = float(artefact_gain(doc, "region_c")[0])
    E0 = region_points(P, c, count, seed) * (1 - 1e-6)
    if doc["method"] != "ts_output_feedback":
        return E0, None
    Po = artefact_gain(doc, "Po").reshape(n, n)
    beta = float(artefact_gain(doc, "beta")[0])
    sub = seed + 1 if isinstance(seed, (int, np.integer)) else [*seed, 1]
    eps0 = region_points(Po * beta, 0.5 * c, count, sub) * (1 - 1e-6)
    eps0[::2] = 0.0
    E0 = E0 * np.sqrt(0.5)
    E0[::2] *= np.sqrt(2.0)          # eps = 0: the whole level to e
    return E0, eps0


def region_horizon(doc: Mapping[str, Any]) -> float:
    """Simulated time of a region run: ``4 / decay`` within [100, 4000] s (the certified decay).

    Parameters
    ----------
    doc : mapping
        The artefact.
    """
    diag = doc.get("diagnostics") or {}
    decay = float(diag.get("decay_rate", 0.0))
    if doc["method"] == "ts_output_feedback":
        decay = min(decay, float((diag.get("composite") or {}).get("controller_decay", decay)))
    return float(min(max(4.0 / max(decay, 1e-9), 100.0), 4000.0))


def region_conditions(out: Mapping[str, Any], c: float) -> dict:
    """Per-run conditions of region runs (`simulate_region`): what the certificate promises.

    Parameters
    ----------
    out : mapping
        `simulate_region` output.
    c : float
        Level of the certified region (dimensionless: the units of ``e' P e``).

    Returns
    -------
    dict of ndarray
        ``max_growth`` (largest relative growth of ``V`` per sample),
        ``final_ratio`` (``V(T)/V(0)``), ``left_domain``, ``saturated``,
        ``passed`` (none of them beyond `GROWTH_LIMIT`, `FINAL_RATIO`).
    """
    V = out["V"]
    grow = np.max(np.diff(V, axis=1) / np.maximum(V[:, :-1], 1e-300) * (V[:, :-1] > 1e-10 * c), axis=1)
    final = V[:, -1] / np.maximum(V[:, 0], 1e-300)
    ok = ~out["left_domain"] & ~out["saturated"] & (grow <= GROWTH_LIMIT) & (final <= FINAL_RATIO)
    return {"max_growth": grow, "final_ratio": final, "left_domain": out["left_domain"],
            "saturated": out["saturated"], "passed": ok}
