"""The deviation TS model of a PDC artefact rebuilt from the plant, and its LMI/region formulas.

Own numerics for the verdict of ``ts_state_feedback`` / ``ts_output_feedback``
(`tanksynth.verify.takagi_sugeno.verdicts`): nothing here imports the design code.
"""

from __future__ import annotations

import itertools
from typing import Any, Mapping

import numpy as np

from tanksynth.analysis.takagi_sugeno import quasi_lpv
from tanksynth.verify.common import artefact_gain

__all__ = ["RebuiltModel", "rebuild_model", "pdc_conditions", "region_level", "condition_weights"]


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

    def __init__(self, plant: Any, doc: Mapping[str, Any], prefix: str = ""):
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


def rebuild_model(plant: Any, doc: Mapping[str, Any], prefix: str = "") -> RebuiltModel:
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
