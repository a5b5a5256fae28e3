"""The uncertain parameter box of a robust design, and linearisations of one plant at many
parameter values in it, compiled once.

The robust verdicts linearise the plant at the box corners, at ``samples`` uniform draws and at the
Monte-Carlo draws (hundreds of parameter points). Compiling a fresh plant per point (sympy
substitution, CasADi translation, automatic differentiation) cost about 25 ms each; here the plant's
vector field and output map are compiled ONCE with the uncertain parameters as a third argument
``p`` (the others substituted, exact), and every point is evaluated in one mapped call.

`linear_models` does what `tanksynth.analysis.linearize.equilibrium_input` and
`tanksynth.analysis.linearize.linearize` do for each point of a `Plant.with_parameters` copy
(least-squares input balancing with up to five Newton refinements, each point stopping on its own;
Jacobians by automatic differentiation), so the models agree with them to rounding (about 1e-15
relative: the parameters enter as floats instead of exact rationals).
"""

from __future__ import annotations

import itertools
from typing import Any, Mapping, Sequence

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from tanksynth.plants.base import Plant
from tanksynth.plants.compile import compile_matrix, evaluate_map
from tanksynth.spec import Spec
from tanksynth.spec.method_options.robust import parse_uncertain
from tanksynth.verify.common import option

__all__ = ["uncertain_box", "box_corners", "box_samples", "ParametricPlant", "linear_models"]


class ParametricPlant:
    """``f(x, u, p)``, ``h(x, p)`` and their Jacobians with the named parameters as inputs.

    Parameters
    ----------
    plant : Plant
        The plant (parameters other than ``names`` keep their values, substituted exactly).
    names : sequence of str
        The parameters passed per point (each in its own unit).
    """

    def __init__(self, plant: Plant, names: Sequence[str]) -> None:
        self.plant = plant
        self.names = tuple(names)
        n, m = plant.n, plant.m
        psyms = [plant.p[nm] for nm in self.names]
        fixed = {s: v for s, v in plant.parameter_values.items() if s not in set(psyms)}
        f = compile_matrix("f", plant.f.xreplace(fixed), [plant.x, plant.u, psyms], ["x", "u", "p"])
        h = compile_matrix("h", plant.h.xreplace(fixed), [plant.x, psyms], ["x", "p"])
        xs, us, ps = ca.SX.sym("x", n), ca.SX.sym("u", m), ca.SX.sym("p", len(psyms))
        fx = f(xs, us, ps)
        self._fns = {
            "f": f,
            "jac_x": ca.Function("jac_x", [xs, us, ps], [ca.jacobian(fx, xs)]),
            "jac_u": ca.Function("jac_u", [xs, us, ps], [ca.jacobian(fx, us)]),
            "jac_h": ca.Function("jac_h", [xs, ps], [ca.jacobian(h(xs, ps), xs)]),
        }
        self._maps: dict = {}

    def evaluate(self, name: str, *arrays: np.ndarray) -> np.ndarray:
        """One of ``f``, ``jac_x``, ``jac_u``, ``jac_h`` at M points.

        Parameters
        ----------
        name : str
            Function name.
        *arrays : ndarray, shape (M, k_i)
            ``x`` (state units, m), ``u`` (input units, m^3/s; not for ``jac_h``) and ``p``
            (parameter units) at each point.

        Returns
        -------
        ndarray, shape (M, rows, cols)
        """
        count = arrays[0].shape[0]
        key = (name, count)
        if key not in self._maps:
            self._maps[key] = self._fns[name].map(count, "serial")
        return evaluate_map(self._maps[key], *arrays)


_CACHE: dict = {}


def _parametric(plant: Plant, names: tuple[str, ...]) -> ParametricPlant:
    """One compilation per (plant object, parameter names); the plant is kept alive with it."""
    key = (id(plant), names)
    hit = _CACHE.get(key)
    if hit is None or hit.plant is not plant:
        if len(_CACHE) >= 8:
            _CACHE.pop(next(iter(_CACHE)))
        hit = _CACHE[key] = ParametricPlant(plant, names)
    return hit


def linear_models(plant: Plant, names: Sequence[str], values: np.ndarray,
                  x0: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Equilibrium input and linearisation at the levels ``x0`` for each parameter point.

    Parameters
    ----------
    plant : Plant
    names : sequence of str
        Parameter names (columns of ``values``).
    values : ndarray, shape (M, len(names))
        Parameter values, one point a row (parameter units). Each point is checked by
        `Plant.with_parameters` (range errors as there).
    x0 : sequence of float, length n
        Operating levels (state units, m).

    Returns
    -------
    u0 : ndarray, shape (M, m)
        Balancing input of each point (input units).
    F : ndarray, shape (M, n, n)
        ``df/dx`` (1/s).
    B : ndarray, shape (M, n, m)
        ``df/du`` (state units per input unit per s).
    C : ndarray, shape (M, q, n)
        ``dh/dx``.
    """
    names = tuple(names)
    values = np.asarray(values, dtype=float)
    values = values.reshape(values.shape[0] if values.ndim else 1, len(names))
    for row in values:  # validation only (cheap: no compilation)
        plant.with_parameters(dict(zip(names, map(float, row))), key="uncertain")
    pp = _parametric(plant, names)
    M, m = values.shape[0], plant.m
    X = np.tile(np.asarray(x0, dtype=float), (M, 1))
    U = np.zeros((M, m))
    f0 = pp.evaluate("f", X, U, values)[:, :, 0]
    G = pp.evaluate("jac_u", X, U, values)
    u0 = np.array([np.linalg.lstsq(G[i], -f0[i], rcond=None)[0] for i in range(M)]).reshape(M, m)
    active = np.ones(M, dtype=bool)
    for _ in range(5 if m else 0):  # Newton refinement, each point stopping on its own
        r = pp.evaluate("f", X, u0, values)[:, :, 0]
        Gk = pp.evaluate("jac_u", X, u0, values)
        for i in np.flatnonzero(active):
            step = np.linalg.lstsq(Gk[i], -r[i], rcond=None)[0]
            u0[i] = u0[i] + step
            if np.max(np.abs(step)) <= 1e-15 * (1 + np.max(np.abs(u0[i]))):
                active[i] = False
        if not active.any():
            break
    F = pp.evaluate("jac_x", X, u0, values)
    B = pp.evaluate("jac_u", X, u0, values)
    C = pp.evaluate("jac_h", X, values)
    return u0, F, B, C


def box_corners(box: Sequence[Sequence[Any]]) -> np.ndarray:
    """The 2^k corners of a parameter box, one row each (the parameters' units).

    Parameters
    ----------
    box : sequence of (str, float, float)
        Parameter name, lower and upper bound (`uncertain_box`).
    """
    if not box:
        return np.zeros((1, 0))
    return np.array(list(itertools.product(*[(float(b[1]), float(b[2])) for b in box])))


def uncertain_box(doc: Mapping[str, Any], spec: Spec) -> list[tuple[str, float, float]]:
    """The design's uncertain parameters and their intervals (option ``uncertain``; with
    ``uncertain = "fit"`` the box recorded in the artefact, read from the fit file at design).

    Parameters
    ----------
    doc : mapping
        The artefact.
    spec : Spec
        The validated spec (or one read without its methods: the option as written is parsed).

    Returns
    -------
    list of (str, float, float)
        Parameter name, lower and upper bound (the parameter's units).
    """
    raw = option(doc, spec, "uncertain", ())
    diag = doc.get("diagnostics") or {}
    if raw == "fit" or (not raw and isinstance(diag, Mapping) and "uncertain_source" in diag):
        # uncertain = "fit": the box the design read from the fit file (its sha256 recorded beside
        # it); a result directory's spec copy does not read the fit file again
        raw = diag.get("uncertain") or ()
    elif isinstance(raw, Mapping):  # a spec read without its methods (campaign workers): as written
        raw = parse_uncertain(raw, "uncertain", spec.plant)
    return [(str(b[0]), float(b[1]), float(b[2])) for b in raw]


def box_samples(box: Sequence[Sequence[Any]], count: int, seed: int) -> np.ndarray:
    """``count`` parameter values drawn uniformly in a box, one row each (the parameters' units).

    Parameters
    ----------
    box : sequence of (str, float, float)
        Parameter name, lower and upper bound (`uncertain_box`).
    count, seed : int
        How many draws; the seed (mixed with a constant, ``default_rng([seed, 20261201])``).
    """
    rng = np.random.default_rng([int(seed), 20261201])
    lo = np.array([b[1] for b in box], dtype=float)
    hi = np.array([b[2] for b in box], dtype=float)
    return lo + rng.random((count, len(box))) * (hi - lo)
