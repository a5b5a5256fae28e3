"""The deviation TS model of a PDC artefact rebuilt from the plant, its LMI/region formulas, and
the check that the stored vertices are the rebuilt ones (`model_recheck`).

Own numerics for the verdict of ``ts_state_feedback`` / ``ts_output_feedback``
(`tanksynth.verify.takagi_sugeno.verdicts`): nothing here imports the design code.
"""

from __future__ import annotations

import itertools
from typing import Any, Mapping

import numpy as np

from tanksynth.analysis.checks import Check
from tanksynth.analysis.takagi_sugeno import quasi_lpv
from tanksynth.plants.base import Plant
from tanksynth.spec import Spec
from tanksynth.verify.common import artefact_gain, fmt, option

__all__ = ["RebuiltModel", "rebuild_model", "pdc_conditions", "region_level", "condition_weights",
           "model_recheck"]


class RebuiltModel:
    """The deviation TS model rebuilt from the plant and the artefact (independent numerics).

    Parameters
    ----------
    plant : Plant
    doc : mapping
        The artefact.
    prefix : str, optional
        Prefix of the gain keys (``"sp_"``: the model about the set-point).
    """

    def __init__(self, plant: Plant, doc: Mapping[str, Any], prefix: str = ""):
        self.plant = plant
        self.q = quasi_lpv(plant)
        n, m = plant.n, plant.m
        self.x0 = artefact_gain(doc, prefix + "x_op").reshape(n)
        self.u0 = artefact_gain(doc, prefix + "u_op").reshape(m)
        self.forms = artefact_gain(doc, prefix + "forms").reshape(-1, n)
        self.lower = artefact_gain(doc, prefix + "z_lower")
        self.upper = artefact_gain(doc, prefix + "z_upper")
        self.B = self.q.B
        self.C = self.q.C
        p = self.forms.shape[0]
        self.sigmas = list(itertools.product((1, 2), repeat=p))
        # column of each vertex's factors in the table [F^1, F^2] (M, 2p) of `memberships`
        self._s = np.array(self.sigmas, dtype=int).reshape(len(self.sigmas), p) - 1
        self._factor = np.arange(p) + p * self._s
        self._width = self.upper - self.lower
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
        F1 = (Z - self.lower) / self._width
        # mu_i = prod_k F_k^(sigma_ik), the factors taken for all vertices at once and
        # multiplied in the order k = 1 ... p (the same products as one vertex at a time)
        if not self._s.shape[1]:
            return np.ones((X.shape[0], 1))
        G = np.take(np.concatenate([F1, 1.0 - F1], axis=1), self._factor, axis=1)   # (M, r, p)
        mu = G[:, :, 0].copy()
        for k in range(1, G.shape[2]):
            mu *= G[:, :, k]
        return mu


def rebuild_model(plant: Plant, doc: Mapping[str, Any], prefix: str = "") -> RebuiltModel:
    """`RebuiltModel` of an artefact.

    Parameters
    ----------
    plant, doc, prefix : Plant, mapping, str
        The plant model, the artefact and the prefix of its gain keys (``"sp_"``: set-point).
    """
    return RebuiltModel(plant, doc, prefix)


def condition_weights(relaxation: str, r: int) -> list[dict]:
    """The PDC conditions as weights ``{(i, j): w}`` of ``He(P (A_i - B K_j))`` (one dict each).

    Parameters
    ----------
    relaxation, r : str, int
        ``"vertex"``, ``"tuan"`` or ``"all_pairs"``; number of rules.
    """
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
    for cond in condition_weights(relaxation, r):
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


def model_recheck(doc: Mapping[str, Any], spec: Spec, prefix: str = "",
                  name: str = "ts_model_recheck") -> Check:
    """The stored vertices against those rebuilt from the plant; the TS model against ``f(x, u)``.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    prefix, name : str
        Prefix of the gain keys (``"sp_"``: the model about the set-point); name of the check.
    """
    plant = spec.plant
    n, m = plant.n, plant.m
    model = rebuild_model(plant, doc, prefix)
    stored = artefact_gain(doc, prefix + "F").reshape(model.A.shape)
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
    f0 = float(np.max(np.abs(plant.compiled.rhs(model.x0[None, :], model.u0[None, :]))))
    scale = float(np.max(np.abs(model.B @ model.u0))) or 1.0
    ok = d <= 1e-9 and err <= 1e-8 and mu.min() >= -1e-12 and f0 <= 1e-6 * scale
    return Check(name, bool(ok),
                 f"operating point {fmt(model.x0)}: |f(x_op, u_op)| = {f0:.3g} (an equilibrium); "
                 f"vertices rebuilt from the plant's atoms and the stored premise forms/bounds: "
                 f"relative difference {d:.3g}; TS model vs f(x, u) at {len(X)} seeded domain "
                 f"points: relative error {err:.3g}, smallest membership {mu.min():.3g}",
                 {"vertex_difference": d, "max_relative_error": err,
                  "min_membership": float(mu.min()), "equilibrium_residual": f0})
