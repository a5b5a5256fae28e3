"""Control laws as CasADi Functions: integral tracking, inverse dynamics, serialisation.

Built from gains (by the design stage, and again from an artefact by the
verdicts and campaigns); `law_document` / `law_from_document` carry a
serialised law inside artefact diagnostics.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from typing import Any, Sequence

import casadi as ca
import numpy as np
import sympy as sp

from tanksynth.analysis.region import batch_eval, region_points
from tanksynth.analysis.symbolic import control_affine
from tanksynth.errors import ArtefactError, DimensionError, InfeasibleDesign, SpecError
from tanksynth.plants.base import Plant
from tanksynth.plants.compile import compile_matrix

__all__ = ['ANTI_WINDUP', 'IntegralTracking', 'integral_tracking_law', 'tracking_error', 'InverseDynamicsLaw', 'inverse_dynamics_law', 'law_document', 'law_from_document', 'rename_law', 'c_identifier']


#: Anti-windup schemes of `integral_tracking_law`.
ANTI_WINDUP = ("back_calculation", "clamping", "none")



def _vec(value: Any, size: int, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be numbers, got {value!r}") from None
    if arr.size != size:
        raise DimensionError(f"{name} has {arr.size} entries, expected {size}")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be finite, got {arr.tolist()}")
    return arr



def _mat(value: Any, shape: tuple[int, int], name: str) -> np.ndarray:
    try:
        arr = np.atleast_2d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a real matrix") from None
    if arr.shape != shape:
        raise DimensionError(f"{name} has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be finite")
    return arr



def _limits(limits: Any, m: int) -> np.ndarray:
    if limits is None:
        return np.tile([-np.inf, np.inf], (m, 1))
    arr = np.asarray(limits, dtype=float).reshape(m, 2)
    if np.any(arr[:, 0] > arr[:, 1]):
        raise DimensionError(f"input limits must be (lower, upper) with lower <= upper, got {arr.tolist()}")
    return arr



def _saturate(u: ca.SX, limits: np.ndarray) -> ca.SX:
    out = ca.SX(u)
    for i, (lo, hi) in enumerate(limits):
        if np.isfinite(lo):
            out[i] = ca.fmax(out[i], lo)
        if np.isfinite(hi):
            out[i] = ca.fmin(out[i], hi)
    return out



def tracking_error(r: Any, x: Any, C1: np.ndarray, x0: np.ndarray, y0: np.ndarray) -> Any:
    """The tracking error the integrators integrate, ``y_r - y0 - C1 (x - x0)`` (CasADi).

    The measured outputs ``y = h(x)`` linearised at the operating point, offsets
    and sensor gains included: exactly ``y_r - h(x)`` when ``h`` is affine. Formed
    as ``y_r - C1 x - (y0 - C1 x0)``, the last term left out when it is zero (an
    output map linear in the state without offset: the law is then ``y_r - C1 x``,
    term for term).

    Parameters
    ----------
    r : casadi.SX, shape (p, 1)
        References of the tracked outputs (output units).
    x : casadi.SX, shape (n, 1)
        State (state units).
    C1 : ndarray, shape (p, n)
        Tracked rows of the linearised output map (output units per state unit).
    x0 : ndarray, shape (n,)
        Operating state (state units).
    y0 : ndarray, shape (p,)
        Tracked outputs at ``x0``, ``h(x0)`` (output units).

    Returns
    -------
    casadi.SX, shape (p, 1)
        The error (output units).
    """
    C1 = np.atleast_2d(np.asarray(C1, dtype=float))
    d = np.asarray(y0, dtype=float).reshape(-1) - C1 @ np.asarray(x0, dtype=float).reshape(-1)
    e = r - ca.mtimes(ca.DM(C1), x)
    return e - ca.DM(d) if np.any(d != 0) else e


@dataclass(frozen=True)
class IntegralTracking:
    """Sampled linear tracking law with integral action, saturation and anti-windup.

    Attributes
    ----------
    K1 : ndarray, shape (m, n)
        State gain (input unit per state unit).
    K2 : ndarray, shape (m, p)
        Integrator gain (input unit per state unit second).
    Kaw : ndarray, shape (p, m)
        Back-calculation gain (zero unless ``anti_windup == "back_calculation"``), in
        integrator-state units per input unit.
    x0, u0 : ndarray
        Operating point (state units, input units).
    C1 : ndarray, shape (p, n)
        Tracked outputs, linearised at ``x0`` (output units per state unit).
    ts : float
        Sampling period (s).
    input_limits : ndarray, shape (m, 2)
    anti_windup : str
        One of `ANTI_WINDUP`.
    tracked : tuple of str
    law : casadi.Function
        ``(x[n], z[p], y_r[p]) -> (u[m], z_next[p])``, absolute units
        (levels, references and inputs; deviations are formed inside).
    diagnostics : dict
    y0 : ndarray, shape (p,), optional
        The tracked outputs at ``x0``, ``h(x0)`` (output units, offsets and sensor
        gains included); the integrators integrate ``y_r - y0 - C1 (x - x0)``.
        None: ``C1 x0`` (an output map linear in the state, without offset).
    """

    K1: np.ndarray
    K2: np.ndarray
    Kaw: np.ndarray
    x0: np.ndarray
    u0: np.ndarray
    C1: np.ndarray
    ts: float
    input_limits: np.ndarray
    anti_windup: str
    tracked: tuple[str, ...]
    law: ca.Function
    diagnostics: dict = field(default_factory=dict)
    y0: np.ndarray | None = None

    @property
    def K(self) -> np.ndarray:
        """``[K1 K2]``, shape (m, n + p)."""
        return np.hstack([self.K1, self.K2])

    def latex(self) -> dict[str, str]:
        """LaTeX of the law (report)."""
        return {"law": r"u(k) = \mathrm{sat}\big(u_0 - K_1 (x(k) - x_0) - K_2 z(k)\big),\quad "
                       r"z(k+1) = z(k) + t_s \big(y_r(k) - y_0 - C_1 (x(k) - x_0)\big) "
                       r"+ K_{aw} (u(k) - v(k))",
                "K": sp.latex(sp.Matrix(self.K).evalf(6))}



def integral_tracking_law(K1: Any, K2: Any, x0: Any, u0: Any, C1: Any, ts: float,
                          input_limits: Any = None, *, anti_windup: str = "back_calculation",
                          aw_gain: float = 1.0, tracked: Sequence[str] | None = None,
                          name: str = "integral_tracking", y0: Any = None) -> IntegralTracking:
    """Build the sampled integral-action law (seed 000 eq. 13-16) with saturation.

    Parameters
    ----------
    K1 : array_like, shape (m, n)
        State gain (input units per state unit).
    K2 : array_like, shape (m, p)
        Integrator gain (input units per integrator-state unit); both act in
        deviation variables, ``u = -[K1 K2] [x; z]``.
    x0 : array_like, shape (n,)
        Operating state (state units).
    u0 : array_like, shape (m,)
        Equilibrium input (input units).
    C1 : array_like, shape (p, n)
        The tracked outputs' rows of the output map linearised at ``x0``, ``y1 ~ y0 +
        C1 (x - x0)`` (output units per state unit).
    ts : float
        Sampling period (s, > 0).
    input_limits : array_like, shape (m, 2), optional
        Actuator range (input units); None = unbounded.
    anti_windup : {"back_calculation", "clamping", "none"}
    aw_gain : float
        ``gamma`` in ``Kaw = -gamma pinv(K2)`` (0 < gamma <= 1).
    tracked : sequence of str, optional
        Names of the tracked outputs.
    name : str
        Name of the CasADi Function.
    y0 : array_like, shape (p,), optional
        The tracked outputs at ``x0``, ``h(x0)`` (output units; offsets and sensor
        gains of the output map included). The integrators integrate the tracking
        error of the measured outputs, ``y_r - y0 - C1 (x - x0)``, so that the loop
        settles with the outputs, not the states, at their references. Default
        ``C1 x0`` (an output map linear in the state, without offset).

    Returns
    -------
    IntegralTracking

    Raises
    ------
    DimensionError, SpecError
    """
    K1 = np.atleast_2d(np.asarray(K1, dtype=float))
    m, n = K1.shape
    K2 = np.atleast_2d(np.asarray(K2, dtype=float))
    p = K2.shape[1]
    K2 = _mat(K2, (m, p), "K2")
    K1 = _mat(K1, (m, n), "K1")
    x0 = _vec(x0, n, "x0")
    u0 = _vec(u0, m, "u0")
    C1 = _mat(C1, (p, n), "C1")
    y0 = C1 @ x0 if y0 is None else _vec(y0, p, "y0")
    if not (isinstance(ts, (int, float)) and np.isfinite(ts) and ts > 0):
        raise SpecError(f"sampling period must be > 0 s, got {ts!r}", key="sampling.ts")
    if anti_windup not in ANTI_WINDUP:
        raise SpecError(f"anti_windup must be one of {list(ANTI_WINDUP)}, got {anti_windup!r}",
                        key="anti_windup")
    if not (isinstance(aw_gain, (int, float)) and 0 < aw_gain <= 1):
        raise SpecError(f"aw_gain must be in (0, 1], got {aw_gain!r}", key="aw_gain")
    limits = _limits(input_limits, m)
    Kaw = -float(aw_gain) * np.linalg.pinv(K2) if anti_windup == "back_calculation" else np.zeros((p, m))
    x = ca.SX.sym("x", n)
    z = ca.SX.sym("z", p)
    r = ca.SX.sym("y_r", p)
    v = ca.DM(u0) - ca.mtimes(ca.DM(K1), x - ca.DM(x0)) - ca.mtimes(ca.DM(K2), z)
    u = _saturate(v, limits)
    e = tracking_error(r, x, C1, x0, y0)
    if anti_windup == "back_calculation":
        z_next = z + ts * e + ca.mtimes(ca.DM(Kaw), u - v)
    elif anti_windup == "clamping":
        active = ca.SX(0)
        for i in range(m):
            active = ca.fmax(active, ca.if_else(ca.fabs(u[i] - v[i]) > 0, 1, 0))
        z_next = z + (1 - active) * ts * e
    else:
        z_next = z + ts * e
    law = ca.Function(_c_ident(name), [x, z, r], [u, z_next], ["x", "z", "y_r"], ["u", "z_next"])
    names = tuple(tracked) if tracked is not None else tuple(f"y{i + 1}" for i in range(p))
    diagnostics = {"anti_windup": anti_windup, "aw_gain": float(aw_gain), "ts": float(ts),
                   "input_limits": limits.tolist(), "tracked": list(names),
                   "y0": y0.tolist(),
                   "law": "v = u0 - K1 (x - x0) - K2 z; u = sat(v); z+ = z + ts (y_r - y0 - C1 (x - x0)) "
                          + {"back_calculation": "+ Kaw (u - v), Kaw = -gamma pinv(K2)",
                             "clamping": "(frozen while any input saturates)", "none": ""}[anti_windup]}
    return IntegralTracking(K1, K2, Kaw, x0, u0, C1, float(ts), limits, anti_windup, names, law,
                            diagnostics, y0)



@dataclass(frozen=True)
class InverseDynamicsLaw:
    """Estimator-based inverse-dynamics law (seed 002 eq. 46-47).

    Attributes
    ----------
    plant : str
    controlled : tuple of str
        Controlled states (one per input), e.g. ``("h1", "h2")``.
    C : ndarray, shape (m,)
        Closed-loop rates ``C_i`` (1/s): ``dh_i/dt = C_i (h_i,sp - h_i)``.
    input_limits : ndarray, shape (m, 2)
        Pump range (input units).
    saturated : bool
    law : casadi.Function
        ``(x_hat[n], h_sp[m]) -> u[m]`` with ``C`` fixed.
    parametric : casadi.Function
        ``(x_hat[n], h_sp[m], C[m]) -> u[m]`` (used by the tuning).
    expression : sympy.Matrix
        Unsaturated law in state, set-point, ``C_i`` and parameter symbols.
    setpoint_symbols, gain_symbols : tuple of sympy.Symbol
    diagnostics : dict
    """

    plant: str
    controlled: tuple[str, ...]
    C: np.ndarray
    input_limits: np.ndarray
    saturated: bool
    law: ca.Function
    parametric: ca.Function
    expression: sp.Matrix
    setpoint_symbols: tuple[sp.Symbol, ...]
    gain_symbols: tuple[sp.Symbol, ...]
    diagnostics: dict = field(default_factory=dict)

    def latex(self) -> dict[str, str]:
        """LaTeX of the law (report)."""
        return {"law": sp.latex(self.expression), "C": sp.latex(sp.Matrix(self.C).evalf(6).T)}

    def with_gains(self, C: Any) -> "InverseDynamicsLaw":
        """The same law with other rates ``C`` (1/s).

        Parameters
        ----------
        C : array_like
            Rates ``C_i`` (1/s), one per controlled state.
        """
        C = _gains(C, len(self.controlled))
        law = _fix_gains(self.parametric, C, self.law.name())
        diag = dict(self.diagnostics, C=C.tolist())
        return InverseDynamicsLaw(self.plant, self.controlled, C, self.input_limits, self.saturated,
                                  law, self.parametric, self.expression, self.setpoint_symbols,
                                  self.gain_symbols, diag)



def _gains(C: Any, m: int) -> np.ndarray:
    C = _vec(C, m, "C")
    if np.any(C < 0):
        raise SpecError(f"inverse-dynamics rates C must be >= 0 (1/s), got {C.tolist()}", key="C")
    return C



def _fix_gains(parametric: ca.Function, C: np.ndarray, name: str) -> ca.Function:
    x = ca.SX.sym("x_hat", parametric.size1_in(0))
    r = ca.SX.sym("h_sp", parametric.size1_in(1))
    return ca.Function(_c_ident(name), [x, r], [parametric(x, r, ca.DM(C))], ["x_hat", "h_sp"], ["u"])



def _default_controlled(plant: Plant, G: sp.Matrix) -> list[str]:
    rows = [i for i in range(plant.n) if any(G[i, j] != 0 for j in range(plant.m))]
    if len(rows) != plant.m:
        raise DimensionError(
            f"cannot choose the controlled states of plant '{plant.name}' automatically: "
            f"{len(rows)} states ({[plant.states[i].name for i in rows]}) are fed by the "
            f"{plant.m} inputs; give 'controlled' (one state per input)")
    return [plant.states[i].name for i in rows]



def inverse_dynamics_law(plant: Plant, C: Any, controlled: Sequence[str] | None = None, *,
                         saturate: bool = True, name: str = "inverse_dynamics",
                         per_axis: int = 9, samples: int = 200) -> InverseDynamicsLaw:
    """Inverse-dynamics law ``u = G_c^-1 (diag(C) (h_sp - x_c) - f0_c(x_hat))``.

    For the hybrid three-tank this is seed 002 eq. (46)-(47): ``Q1in = A C1
    (h1sp - h1) + Q1 + Q3 + Q5``, ``Q2in = A C2 (h2sp - h2) + Q2 + Q4 +
    Q7``, the flows evaluated at the estimate (general model: ``sgn``,
    ``max`` and the middle-pipe switching kept).

    Parameters
    ----------
    plant : Plant
        Control-affine in its inputs.
    C : array_like, shape (m,)
        Rates ``C_i`` (1/s, >= 0).
    controlled : sequence of str, optional
        One state per input (default: the states the inputs enter).
    saturate : bool
        Clip to ``plant.input_limits`` (0-240 lph for the hybrid plant).
    name : str
        Name of the CasADi Function.
    per_axis, samples : int
        Region points on which ``G_c(x)`` is checked invertible.

    Returns
    -------
    InverseDynamicsLaw

    Raises
    ------
    DimensionError
        Wrong number of controlled states.
    SpecError
        Unknown state, negative rate.
    InfeasibleDesign
        ``G_c(x)`` singular somewhere on the region (named).
    """
    f0, G = control_affine(plant.f, plant.u)
    names = [s.name for s in plant.states]
    chosen = list(controlled) if controlled is not None else _default_controlled(plant, G)
    unknown = [c for c in chosen if c not in names]
    if unknown:
        raise SpecError(f"unknown state(s) {unknown}; expected some of {names}", key="controlled")
    if len(chosen) != plant.m:
        raise DimensionError(f"{len(chosen)} controlled states {chosen} for {plant.m} inputs "
                             f"{[s.name for s in plant.inputs]}: the inversion needs one per input")
    idx = [names.index(c) for c in chosen]
    Gc = G.extract(idx, list(range(plant.m)))
    f0c = f0.extract(idx, [0])
    if Gc.free_symbols & set(plant.x):
        pts = region_points(plant, per_axis, samples, 0, 0.02)
        fn = compile_matrix("Gc", Gc.xreplace(plant.parameter_values), [plant.x], ["x"])
        dets = np.linalg.det(batch_eval(fn, pts)[0])
        k = int(np.argmin(np.abs(dets)))
        if not np.all(np.isfinite(dets)) or np.abs(dets[k]) <= 1e-12 * np.max(np.abs(dets)) or \
                (dets.max() > 0 > dets.min()):
            raise InfeasibleDesign(f"cannot invert the dynamics of {chosen}: the input matrix is "
                                   f"singular near x = {dict(zip(names, pts[k].tolist()))}")
    elif Gc.det() == 0:
        raise InfeasibleDesign(f"cannot invert the dynamics of {chosen}: the inputs do not act "
                               f"independently on them (input matrix {Gc.tolist()} is singular "
                               "everywhere)")
    sps = tuple(sp.Symbol(f"{c}sp", real=True) for c in chosen)
    Cs = tuple(sp.Symbol(f"C{i + 1}", nonnegative=True) for i in range(plant.m))
    desired = sp.Matrix([Cs[i] * (sps[i] - plant.x[j]) for i, j in enumerate(idx)])
    # Gc^-1 as Matrix.inv(method="LU") computes it (LUsolve of the identity), without its
    # symbolic re-check of invertibility (det.equals(0) -> simplify, 0.1-0.4 s and an import of
    # sympy.physics): invertibility is checked above (numerically over the region when Gc
    # depends on the state, else by its determinant)
    expr = (Gc.LUsolve(Gc.eye(Gc.rows)) * (desired - f0c)).applyfunc(sp.expand)
    numeric = expr.xreplace(plant.parameter_values)
    core = compile_matrix("id_core", numeric, [plant.x, sps, Cs], ["x_hat", "h_sp", "C"])
    x = ca.SX.sym("x_hat", plant.n)
    r = ca.SX.sym("h_sp", plant.m)
    c = ca.SX.sym("C", plant.m)
    limits = plant.input_limits
    u = core(x, r, c)
    if saturate:
        u = _saturate(u, limits)
    parametric = ca.Function(_c_ident(name) + "_parametric", [x, r, c], [u], ["x_hat", "h_sp", "C"], ["u"])
    Cv = _gains(C, plant.m)
    law = _fix_gains(parametric, Cv, name)
    diagnostics = {"controlled": chosen, "C": Cv.tolist(), "saturated": bool(saturate),
                   "input_limits": limits.tolist(),
                   "law": [f"{plant.inputs[i].name} = {e}" for i, e in enumerate(expr)],
                   "flows_at": "the estimate x_hat (any estimator; the true state in the tuning)"}
    return InverseDynamicsLaw(plant.name, tuple(chosen), Cv, limits, bool(saturate), law, parametric,
                              expr, sps, Cs, diagnostics)



def law_document(law: ca.Function) -> dict:
    """The law as a JSON-friendly document (serialised CasADi Function).

    Parameters
    ----------
    law : casadi.Function
        The law (an SX Function).

    Returns
    -------
    dict
        ``function`` (name), ``inputs``/``outputs`` (names and sizes),
        ``casadi_serialized`` (``Function.serialize()``) and its sha256.
    """
    text = law.serialize()
    return {"function": law.name(),
            "inputs": [{"name": law.name_in(i), "size": int(law.nnz_in(i))} for i in range(law.n_in())],
            "outputs": [{"name": law.name_out(i), "size": int(law.nnz_out(i))}
                        for i in range(law.n_out())],
            "casadi_serialized": text,
            "sha256": hashlib.sha256(text.encode("ascii")).hexdigest()}



def law_from_document(doc: dict) -> ca.Function:
    """Rebuild the CasADi Function from `law_document` output (checks the sha256).

    Parameters
    ----------
    doc : dict
        The output of `law_document` (from an artefact's diagnostics).

    Raises
    ------
    ArtefactError
        Missing or altered serialisation.
    """
    text = doc.get("casadi_serialized") if isinstance(doc, dict) else None
    if not isinstance(text, str):
        raise ArtefactError("law document has no 'casadi_serialized' string")
    if doc.get("sha256") and hashlib.sha256(text.encode("ascii")).hexdigest() != doc["sha256"]:
        raise ArtefactError("serialised law does not match its sha256 (edited after design?)")
    try:
        return ca.Function.deserialize(text)
    except RuntimeError as exc:
        raise ArtefactError(f"cannot deserialise the law: {exc}") from None



def _c_ident(text: str) -> str:
    """A name CasADi and C accept: a letter, then letters, digits and single underscores,
    not a CasADi keyword (``null``, ``jac``, ``hess``); a design name such as ``inv-dyn``
    or ``it--2`` is mapped to one."""
    ident = "".join(c if (c.isascii() and c.isalnum()) else "_" for c in str(text))
    ident = re.sub(r"_+", "_", ident)
    if not ident[:1].isalpha() or ident in ("null", "jac", "hess"):
        ident = "law_" + ident.lstrip("_")
    return ident



def c_identifier(text: str) -> str:
    """The C identifier (and CasADi Function name) a law named ``text`` gets.

    Parameters
    ----------
    text : str
        Any name, e.g. a design name such as ``1a`` or ``inv-dyn`` (not valid in C).

    Returns
    -------
    str
        A letter, then letters, digits and single underscores (``law_1a``, ``inv_dyn``).
    """
    return _c_ident(text)


def rename_law(law: ca.Function, name: str) -> ca.Function:
    """The same law (SX, or MX for a table-driven one) under another (C-identifier) name.

    Parameters
    ----------
    law : casadi.Function
        The law.
    name : str
        New name (made a C identifier).
    """
    sym = ca.MX.sym if law.is_a("MXFunction") else ca.SX.sym
    ins: list[Any] = [sym(law.name_in(i), law.sparsity_in(i))   # all MX or all SX, as the law's
                      for i in range(law.n_in())]
    outs = law.call(ins)
    return ca.Function(_c_ident(name), ins, outs, law.name_in(), law.name_out())
