"""Exact feedback linearisation with input-output decoupling (seed 000, section II-C).

For a square control-affine plant ``dx/dt = f0(x) + G(x) u``, ``y = h(x)``
(``q = m``) the relative degrees ``theta_i`` (eq. 19), the decoupling matrix
``Lambda(x)`` (eq. 22) and ``Lambda_0(x)`` (eq. 23) come from the symbolic
core (`tanksynth.analysis.symbolic.relative_degree`) on the plant's smooth form
(``sgn``/``abs`` resolved on the operating region). The law (eq. 24)::

    u = alpha(x) + beta(x) zeta,   alpha = -Lambda^-1 Lambda_0,   beta = Lambda^-1

gives ``y_i^(theta_i) = zeta_i`` (eq. 25); the outer loop::

    zeta_i = c_i0 (y_r,i - y_i) - c_i1 y_i' - ... - c_i,theta_i-1 y_i^(theta_i - 1)

places the roots of ``s^theta_i + c_i,theta_i-1 s^(theta_i-1) + ... + c_i0``
(for ``theta_i = 1``: ``zeta_i = K_i (y_r,i - y_i)`` and ``y_i/y_r,i = K_i/(s
+ K_i)``, eq. 27-28), with ``y_i^(k) = L_f^k h_i`` computed from the state.

What the design checks before giving a law:

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

The law is compiled once into a CasADi Function ``(x, y_r) -> (u, zeta)``
(saturated to the actuator range when asked), which `tanksynth.design.laws.tracking`
exports (serialised Function, generated C). The analysis (relative degrees,
``Lambda``, zero dynamics) is `tanksynth.design.laws.decoupling`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import casadi as ca
import numpy as np
import sympy as sp

from tanksynth.analysis.region import batch_eval, batch_eval2, region_points
from tanksynth.analysis.symbolic import control_affine, jacobian, lie_derivatives
from tanksynth.design.laws.decoupling import RANK_TOL as RANK_TOL
from tanksynth.design.laws.decoupling import (Decoupling, ZeroDynamics, decoupling_analysis,
                                              point_text, select_outputs, simplify_if_small)
from tanksynth.errors import InfeasibleDesign, SpecError
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import compile_matrix

__all__ = [
    "select_outputs",
    "ZeroDynamics",
    "Decoupling",
    "decoupling_analysis",
    "OuterLoop",
    "outer_loop",
    "FeedbackLinearization",
    "feedback_linearization",
]


# ------------------------------------------------------------------ outer loop
@dataclass(frozen=True)
class OuterLoop:
    """Outer-loop gains ``zeta_i = c_i0 (y_r,i - y_i) - sum_k c_ik y_i^(k)``.

    Attributes
    ----------
    coefficients : tuple of ndarray
        Per output ``(c_i0, ..., c_i,theta_i-1)`` (units 1/s^(theta_i - k)).
    poles : tuple of ndarray
        Per output the closed-loop poles (1/s), roots of ``s^theta_i + ... + c_i0``.
    """

    coefficients: tuple[np.ndarray, ...]
    poles: tuple[np.ndarray, ...]

    @property
    def matrix(self) -> np.ndarray:
        """Coefficients as an (m, max theta) array, zero-padded."""
        width = max(len(c) for c in self.coefficients)
        out = np.zeros((len(self.coefficients), width))
        for i, c in enumerate(self.coefficients):
            out[i, :len(c)] = c
        return out

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"coefficients": [c.tolist() for c in self.coefficients],
                "poles": [[[float(p.real), float(p.imag)] for p in ps] for ps in self.poles]}


def outer_loop(degrees: Sequence[int], poles: Sequence[Any] | None = None,
               bandwidth: float | Sequence[float] | None = None) -> OuterLoop:
    """Outer-loop coefficients from poles or a bandwidth.

    Parameters
    ----------
    degrees : sequence of int
        Relative degrees ``theta_i``.
    poles : sequence of complex, optional
        ``sum theta_i`` closed-loop poles (1/s, negative real parts), the
        first ``theta_1`` for output 1 and so on; complex poles in conjugate
        pairs within one output. For ``theta_i = 1`` the pole ``-K_i`` gives
        ``zeta_i = K_i (y_r,i - y_i)``.
    bandwidth : float or sequence of float, optional
        ``omega_i`` (1/s, > 0): all poles of output ``i`` at ``-omega_i``.

    Returns
    -------
    OuterLoop

    Raises
    ------
    SpecError
        Neither or both given, wrong count, unstable or unpaired poles.
    """
    if (poles is None) == (bandwidth is None):
        raise SpecError("give the outer loop either 'poles' or 'bandwidth' (not both)", key="poles")
    total = sum(degrees)
    if poles is not None:
        try:
            p = np.asarray(poles, dtype=complex).reshape(-1)
        except (TypeError, ValueError):
            raise SpecError(f"poles must be numbers, got {poles!r}", key="poles") from None
        if p.size != total:
            raise SpecError(f"{p.size} poles given, expected sum of relative degrees = {total} "
                            f"(degrees {list(degrees)})", key="poles")
        if not np.all(np.isfinite(p)) or not np.all(p.real < 0):
            raise SpecError(f"outer-loop poles must be finite with negative real part (1/s), got "
                            f"{p.tolist()}", key="poles")
        split = np.split(p, np.cumsum(degrees)[:-1])
    else:
        bw = np.atleast_1d(np.asarray(bandwidth, dtype=float))
        if bw.size == 1:
            bw = np.repeat(bw, len(degrees))
        if bw.size != len(degrees) or not np.all(np.isfinite(bw)) or not np.all(bw > 0):
            raise SpecError(f"bandwidth must be > 0 (1/s), one value or one per output, got "
                            f"{np.asarray(bandwidth).tolist()}", key="bandwidth")
        split = [np.full(theta, -w, dtype=complex) for theta, w in zip(degrees, bw)]
    coeffs = []
    for i, ps in enumerate(split):
        c = np.poly(ps)
        if np.max(np.abs(c.imag)) > 1e-9 * np.max(np.abs(c)):
            raise SpecError(f"complex poles of output {i + 1} are not in conjugate pairs: {ps.tolist()}",
                            key="poles")
        coeffs.append(np.real(c)[1:][::-1].copy())           # c_0 .. c_{theta-1}
    return OuterLoop(tuple(coeffs), tuple(np.asarray(ps) for ps in split))


# ------------------------------------------------------------------------ law
@dataclass(frozen=True)
class FeedbackLinearization:
    """Exact feedback-linearising, decoupling tracking law with its evidence.

    Attributes
    ----------
    decoupling : Decoupling
    outer : OuterLoop
    law : casadi.Function
        ``(x[n], y_r[m]) -> (u[m], zeta[m])``: ``u`` in the input units
        (clipped to the actuator range when ``saturated``), ``zeta`` the
        outer-loop signal (output units / s^theta).
    saturated : bool
    input_limits : ndarray, shape (m, 2)
    law_expression : sympy.Matrix
        Unsaturated ``u(x, y_r)`` (parameter values substituted; smooth
        model), for the report.
    reference_symbols : tuple of sympy.Symbol
        ``y_r`` symbols used in ``law_expression``.
    diagnostics : dict
        JSON-friendly evidence (degrees, rank check, zero dynamics, outer
        loop, law/model consistency).
    """

    decoupling: Decoupling
    outer: OuterLoop
    law: ca.Function
    saturated: bool
    input_limits: np.ndarray
    law_expression: sp.Matrix
    reference_symbols: tuple[sp.Symbol, ...]
    diagnostics: dict = field(default_factory=dict)

    def latex(self) -> dict[str, str]:
        """LaTeX of the decoupling quantities and of the law."""
        dec = self.decoupling
        out = dec.latex()
        out["u"] = sp.latex(self.law_expression)
        zeta = sp.Matrix(sp.symbols(f"zeta_1:{len(dec.degrees) + 1}", real=True))
        out["law"] = "u = " + sp.latex(dec.alpha + dec.beta * zeta)
        outer = []
        for i, (theta, c) in enumerate(zip(dec.degrees, self.outer.coefficients)):
            y = sp.latex(dec.h[i])
            terms = [rf"{c[0]:.6g}\,(y_{{r,{i + 1}}} - {y})"]
            terms += [rf" - {c[k]:.6g}\,{y}^{{({k})}}" for k in range(1, theta)]
            outer.append(rf"\zeta_{{{i + 1}}} = " + "".join(terms))
        out["outer_loop"] = r",\quad ".join(outer)
        return out


def _law_general(plant: Plant, h: sp.Matrix, degrees: Sequence[int], outer: OuterLoop,
                 refs: Sequence[sp.Symbol]) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    """``Lambda``, ``Lambda_0`` and ``u`` from the general (sgn/abs) model, parameters substituted."""
    f0, G = control_affine(plant.f_numeric, plant.u)
    vals = plant.parameter_values
    rows, drift, zeta = [], [], []
    for i, theta in enumerate(degrees):
        lie = lie_derivatives(sp.Matrix([h[i].xreplace(vals)]), f0, plant.x, theta)
        grad = jacobian(lie[-1], plant.x)
        rows.append(grad * G)
        drift.append((grad * f0)[0])
        c = outer.coefficients[i]
        zeta.append(c[0] * refs[i] - sum(c[k] * lie[k][0] for k in range(theta)))
    Lam = sp.Matrix.vstack(*rows)
    Lam0 = sp.Matrix(drift)
    u = Lam.inv(method="LU") * (sp.Matrix(zeta) - Lam0)
    return Lam, Lam0, u


def feedback_linearization(plant: Plant, outputs: Sequence[str] | None = None, *,
                           poles: Sequence[Any] | None = None,
                           bandwidth: float | Sequence[float] | None = None,
                           saturate: bool = True, allow_unstable_zero_dynamics: bool = False,
                           per_axis: int = 11, samples: int = 400, seed: int = 0,
                           margin: float = 0.02,
                           analysis: Decoupling | None = None) -> FeedbackLinearization:
    """Design the decoupling law ``u = alpha(x) + beta(x) zeta`` with its outer loop.

    Parameters
    ----------
    plant : Plant
    outputs : sequence of str, optional
        Outputs to decouple (default: all; must be ``m`` of them).
    poles, bandwidth
        Outer loop (see `outer_loop`), 1/s.
    saturate : bool
        Clip ``u`` to the plant's actuator range in the compiled law.
    allow_unstable_zero_dynamics : bool
        Give the law even when the zero dynamics are unstable (recorded in
        the diagnostics).
    per_axis, samples, seed, margin
        Region points for the checks (see `region_points`).
    analysis : Decoupling, optional
        A `decoupling_analysis` of the same plant and outputs to reuse (the
        symbolic analysis is the expensive part); ``outputs`` and the region
        options are then ignored.

    Returns
    -------
    FeedbackLinearization

    Raises
    ------
    DimensionError, InfeasibleDesign
        See `decoupling_analysis`; also unstable zero dynamics (naming the
        worst point and eigenvalue) unless overridden.
    SpecError
        Bad outer-loop options.
    """
    if analysis is None:
        dec = decoupling_analysis(plant, outputs, per_axis=per_axis, samples=samples, seed=seed,
                                  margin=margin)
    elif analysis.plant != plant.name:
        raise SpecError(f"analysis is of plant {analysis.plant!r}, not {plant.name!r}", key="analysis")
    else:
        dec = analysis
    zd = dec.zero_dynamics
    states = [s.name for s in plant.states]
    if zd.dimension and not zd.stable and not allow_unstable_zero_dynamics:
        k = int(np.argmax(zd.eigenvalues.real.max(axis=1)))
        lam = zd.eigenvalues[k][np.argmax(zd.eigenvalues[k].real)]
        where = "?" if zd.worst_point is None else point_text(zd.worst_point, states)
        unstable = int(np.sum(zd.eigenvalues.real.max(axis=1) >= 0))
        raise InfeasibleDesign(
            f"zero dynamics of plant '{plant.name}' (internal states {list(zd.coordinates)}, dimension "
            f"{zd.dimension}) are unstable: Jacobian eigenvalue {complex(lam):.4g} 1/s at x = "
            f"{where} ({unstable} of {len(zd.points)} region points with "
            "Re >= 0); exact decoupling would make them diverge (non-minimum phase). Set "
            "allow_unstable_zero_dynamics = true to design anyway")
    outer = outer_loop(dec.degrees, poles, bandwidth)
    refs = tuple(sp.Symbol(f"r_{nm}", real=True) for nm in dec.outputs)
    Lam_g, Lam0_g, u_gen = _law_general(plant, dec.h, dec.degrees, outer, refs)
    core = compile_matrix("fl_core", u_gen, [plant.x, refs], ["x", "y_r"])
    xs = ca.SX.sym("x", plant.n)
    rs = ca.SX.sym("y_r", plant.m)
    u = core(xs, rs)
    limits = plant.input_limits
    if saturate:
        for i, (lo, hi) in enumerate(limits):
            if np.isfinite(lo):
                u[i] = ca.fmax(u[i], lo)
            if np.isfinite(hi):
                u[i] = ca.fmin(u[i], hi)
    # zeta from the same expressions (outer loop only)
    vals = plant.parameter_values
    zeta_expr = []
    for i, theta in enumerate(dec.degrees):
        c = outer.coefficients[i]
        lie = dec.lie[i].xreplace(vals)
        zeta_expr.append(c[0] * refs[i] - sum(c[k] * lie[k] for k in range(theta)))
    zeta_fn = compile_matrix("fl_zeta", sp.Matrix(zeta_expr), [plant.x, refs], ["x", "y_r"])
    law = ca.Function("fl_law", [xs, rs], [u, zeta_fn(xs, rs)], ["x", "y_r"], ["u", "zeta"])
    # Law from the smooth model (analysed) for the report, and consistency on the region.
    alpha_n = dec.alpha.xreplace(vals)
    beta_n = dec.beta.xreplace(vals)
    u_smooth = (alpha_n + beta_n * sp.Matrix(zeta_expr)).applyfunc(lambda e: simplify_if_small(e, 200))
    smooth_fn = compile_matrix("fl_smooth", u_smooth, [plant.x, refs], ["x", "y_r"])
    pts = region_points(plant, 0, 200, seed + 1, margin)
    h_fn = compile_matrix("h_sel", dec.h.xreplace(vals), [plant.x], ["x"])
    r = batch_eval(h_fn, pts[::-1])[0][:, :, 0]                # references: outputs elsewhere in the region
    ug = batch_eval2(core, pts, r)
    us = batch_eval2(smooth_fn, pts, r)
    consistency = float(np.max(np.abs(ug - us)) / max(np.max(np.abs(us)), 1e-300))
    diagnostics = {
        "outputs": list(dec.outputs), "degrees": list(dec.degrees), "sum_degrees": dec.total,
        "n": plant.n, "m": plant.m,
        "decouplable": True, "rank_check": dec.rank_check,
        "zero_dynamics": zd.as_dict(states),
        "zero_dynamics_override": bool(zd.dimension and not zd.stable),
        "outer_loop": outer.as_dict(),
        "Lambda": str(dec.Lambda.tolist()), "Lambda0": str(dec.Lambda0.tolist()),
        "alpha": str(dec.alpha.tolist()), "beta": str(dec.beta.tolist()),
        "law_model": "general model (sgn/abs kept): valid when flows reverse; equals the smooth "
                     "(analysed) law on the region",
        "law_smooth_vs_general_max_relative_difference": consistency,
        "saturated": bool(saturate), "input_limits": limits.tolist(),
        "assumptions": [a.text for a in plant.assumptions],
    }
    return FeedbackLinearization(dec, outer, law, bool(saturate), limits, u_smooth, refs, diagnostics)
