"""Vertex models of a box of uncertain plant parameters (`tanksynth.design.robust.polytopic`).

Vertex models
    `vertex_models` linearises the plant at the operating LEVELS ``x0`` at
    every corner of a box of uncertain parameters (2^k corners), each corner
    with its own equilibrium input ``u0(p)`` (the input that holds that plant
    at ``x0``: the operating point is re-trimmed per vertex; the levels are
    kept). For a model affine in ``u`` (the tank plants) the Jacobians do not
    depend on ``u0``, so re-trimming changes no matrix; it records how far the
    pumps' operating flow moves (a state feedback without integral action,
    which applies the nominal ``u0``, settles with an offset there).
    `polytope_check` measures whether the models of the box lie in the convex
    hull of the vertex models (exact for models multi-affine in the
    parameters, e.g. the outflow coefficients in continuous time; an
    approximation for a tank area, which enters as ``1/A``, and for ZOH
    models): the verdict samples the box independently.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from tanksynth.analysis.linearize import discretize_zoh
from tanksynth.design.operating_point import equilibrium_at, linearized_at
from tanksynth.errors import SpecError
from tanksynth.plants.base import Plant

__all__ = ["VertexModels", "vertex_models", "box_corners", "polytope_check", "augment_integral"]


def box_corners(box: Sequence[tuple[str, float, float]]) -> np.ndarray:
    """The 2^k corners of a parameter box, shape (2^k, k) (first parameter varying slowest).

    Parameters
    ----------
    box : sequence of (name, low, high)
        In each parameter's unit.
    """
    if not box:
        return np.zeros((1, 0))
    return np.array(list(itertools.product(*[(lo, hi) for _, lo, hi in box])), dtype=float)



@dataclass(frozen=True)
class VertexModels:
    """Linearisations at the operating levels for parameter values (vertices or samples).

    Attributes
    ----------
    names : tuple of str
        Uncertain parameters.
    values : ndarray, shape (V, k)
        Their values at each model (parameter units).
    A, B, C : ndarray, shapes (V, n, n), (V, n, m), (V, q, n)
        Continuous (1/s, ...) or ZOH (dimensionless) matrices.
    Bw : ndarray, shape (V, n, nw)
        Disturbance input matrix, discretised with ``B`` in discrete time (state
        units per disturbance unit, per s in continuous time).
    u0 : ndarray, shape (V, m)
        Each model's equilibrium input at ``x0`` (input units).
    balanced : ndarray of bool, shape (V,)
        Whether ``u0`` balances the model exactly.
    x0 : ndarray, shape (n,)
        Operating levels (state units).
    domain : str
    ts : float or None
        s.
    """

    names: tuple[str, ...]
    values: np.ndarray
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Bw: np.ndarray
    u0: np.ndarray
    balanced: np.ndarray
    x0: np.ndarray
    domain: str
    ts: float | None

    @property
    def count(self) -> int:
        """Number of models V."""
        return int(self.A.shape[0])

    def as_dict(self) -> dict:
        """JSON-friendly form (parameter values, equilibrium inputs, matrices)."""
        return {"parameters": list(self.names), "values": self.values.tolist(),
                "u0": self.u0.tolist(), "balanced": self.balanced.tolist(),
                "A": self.A.tolist(), "B": self.B.tolist(), "C": self.C.tolist(),
                "operating_point": "levels x0 kept; equilibrium input re-trimmed per vertex",
                "domain": self.domain, "ts": self.ts}



def vertex_models(plant: Plant, x0: ArrayLike, box: Sequence[tuple[str, float, float]],
                  domain: str, ts: float | None = None, *, values: np.ndarray | None = None,
                  Bw: np.ndarray | str = "inputs") -> VertexModels:
    """Linearise ``plant`` at the levels ``x0`` at every corner of ``box`` (or at ``values``).

    Parameters
    ----------
    plant : Plant
        With its nominal parameters (the spec's overrides applied).
    x0 : array_like, length n
        Operating levels (state units), kept at every vertex.
    box : sequence of (name, low, high)
        Uncertain parameters; empty: the nominal model only.
    domain : {"continuous", "discrete"}
    ts : float, optional
        Sampling period (s), required in discrete time.
    values : ndarray, shape (V, k), optional
        Parameter values to linearise at instead of the corners.
    Bw : ndarray (n, nw), "inputs" or "identity"
        Continuous-time disturbance input matrix (state units per s per
        disturbance unit): given, each model's ``B``, or the identity.

    Returns
    -------
    VertexModels

    Raises
    ------
    SpecError
        A parameter value the plant refuses (named), a discrete domain without ``ts``.
    """
    if domain not in ("continuous", "discrete"):
        raise SpecError(f"domain must be 'continuous' or 'discrete', got {domain!r}", key="time_domain")
    if domain == "discrete" and ts is None:
        raise SpecError("a discrete-time design needs a sampling period", key="sampling.ts")
    names = tuple(b[0] for b in box)
    vals = box_corners(box) if values is None else np.atleast_2d(np.asarray(values, dtype=float))
    levels = np.asarray(x0, dtype=float).reshape(-1)
    As, Bs, Cs, Ws, U, ok = [], [], [], [], [], []
    for row in vals:
        pl = plant.with_parameters(dict(zip(names, map(float, row))), key="uncertain") if names else plant
        eq = equilibrium_at(pl, levels)
        lin = linearized_at(pl, levels, eq.u0)
        W = lin.B if isinstance(Bw, str) and Bw == "inputs" else (
            np.eye(plant.n) if isinstance(Bw, str) else np.asarray(Bw, dtype=float))
        A, B = lin.F, lin.B
        if domain == "discrete" and ts is not None:     # (refused above without ts)
            Ad, BB = discretize_zoh(lin.F, np.hstack([lin.B, W]), float(ts))
            A, B, W = Ad, BB[:, :plant.m], BB[:, plant.m:]
        As.append(A)
        Bs.append(B)
        Cs.append(lin.C)
        Ws.append(W)
        U.append(eq.u0)
        ok.append(eq.is_equilibrium)
    return VertexModels(names, vals, np.array(As), np.array(Bs), np.array(Cs), np.array(Ws),
                        np.array(U), np.array(ok, dtype=bool), levels, domain,
                        None if ts is None else float(ts))



def polytope_check(plant: Plant, x0: ArrayLike, box: Sequence[tuple[str, float, float]],
                   vertices: VertexModels, samples: int = 32, seed: int = 0) -> dict:
    """How far the models inside the box are from the multilinear interpolation of the vertices.

    A model multi-affine in the parameters equals the multilinear
    interpolation of its vertex models (then every model of the box lies in
    their convex hull and the vertex certificate covers the box); the
    largest relative difference over ``samples`` uniform draws measures
    how far from that the plant is.

    Parameters
    ----------
    plant : Plant
        The plant model.
    x0 : array_like
        Operating levels (state units, m).
    box : sequence of (str, float, float)
        Uncertain parameters: name, lower and upper value (parameter units).
    vertices : VertexModels
        The vertex models of the box.
    samples : int, optional
        Number of uniform draws inside the box.
    seed : int, optional
        Seed of the random draws.

    Returns
    -------
    dict
        ``max_relative_interpolation_error``, ``samples``, ``exact`` (below 1e-9).
    """
    if not box:
        return {"samples": 0, "max_relative_interpolation_error": 0.0, "exact": True,
                "note": "no uncertain parameter: the nominal model only"}
    rng = np.random.default_rng(seed)
    lo = np.array([b[1] for b in box])
    hi = np.array([b[2] for b in box])
    frac = rng.random((samples, len(box)))
    pts = lo + frac * (hi - lo)
    inside = vertex_models(plant, x0, box, vertices.domain, vertices.ts, values=pts)
    corners = itertools.product(*[(0, 1)] * len(box))
    weights = np.ones((samples, vertices.count))
    for j, bits in enumerate(corners):
        for i, b in enumerate(bits):
            weights[:, j] *= frac[:, i] if b else 1 - frac[:, i]
    worst = 0.0
    for name in ("A", "B"):
        true = getattr(inside, name)
        interp = np.einsum("sv,vij->sij", weights, getattr(vertices, name))
        scale = max(float(np.max(np.abs(getattr(vertices, name)))), 1e-300)
        worst = max(worst, float(np.max(np.abs(true - interp))) / scale)
    return {"samples": int(samples), "seed": int(seed), "max_relative_interpolation_error": worst,
            "exact": bool(worst < 1e-9),
            "note": ("the models are multi-affine in the parameters: the vertex polytope contains "
                     "every model of the box" if worst < 1e-9 else
                     "the models are not multi-affine in the parameters (e.g. 1/A, or a ZOH "
                     "model): the vertex polytope approximates the box; the verdict samples it")}



def augment_integral(A: np.ndarray, B: np.ndarray, C1: np.ndarray, domain: str,
                     ts: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Integral action on ``y1 = C1 x``: ``z' = r - C1 x`` or ``z+ = z + ts (r - C1 x)``.

    Returns the augmented ``(Aa, Ba)`` (states ``(x, z)``; ``z`` in output units times s).

    Parameters
    ----------
    A : ndarray, shape (n, n)
        State matrix (continuous [1/s] or discrete [-]).
    B : ndarray, shape (n, m)
        Input matrix.
    C1 : ndarray, shape (p, n)
        Rows of the outputs to integrate.
    domain : {"continuous", "discrete"}
        Time domain of ``A`` and ``B``.
    ts : float or None
        Sampling period [s] (discrete time; None in continuous time).
    """
    n, m = B.shape
    p = C1.shape[0]
    if domain == "discrete":
        if ts is None:
            raise SpecError("a discrete-time design needs a sampling period", key="sampling.ts")
        Aa = np.block([[A, np.zeros((n, p))], [-float(ts) * C1, np.eye(p)]])
    else:
        Aa = np.block([[A, np.zeros((n, p))], [-C1, np.zeros((p, p))]])
    return Aa, np.vstack([B, np.zeros((p, m))])
