"""The closed loops and observers of an artefact as python-control ``StateSpace`` objects.

THE one implementation behind `tanksynth.load(...)[name].to_statespace()` (and
`artefact_statespace` for an artefact read as JSON), so that a python-control
user can ``step``, ``bode`` or ``margin`` a tanksynth design in one line::

    import control, tanksynth
    control.bode(tanksynth.load("out")["hinf_controller"].to_statespace())

Built from the artefact's gains (the model stored with every linear gain:
``F``, ``B``, ``C`` in continuous time, ``Ad``, ``Bd``, ``C`` in discrete
time, written ``A``, ``B``, ``C`` below; and ``Bw`` (``Bwd``), ``Cz``,
``Dzu`` / ``Dv`` where the design has them), in deviation variables about
the operating point. Where the artefact
stores no linear model (EKF-type filters, ``luenberger``, ``integral_tracking``,
the Takagi-Sugeno designs' premises) the plant is rebuilt from ``spec.toml``
beside the artefact (or the ``spec`` given).

Signals are named after the plant's (`spec` or ``plant.json``): states, inputs ``u`` and
outputs ``y`` by their names; disturbance inputs ``w_<state>`` and measurement noise
``v_<output>`` (where a channel enters one state / output, else ``w_<i>``, ``v_<i>``,
0-based), estimation errors ``e_<state>``, estimates ``<state>_hat``, references
``r_<output>``, integrator states ``z_<output>``, performance outputs ``z_<state>``,
``z_<input>`` (controllers) or ``z_e_<state>`` (observers: ``z`` weighs the error), else
``z_<i>``.

The systems (``system``):

``"closed_loop"`` (default of the other controllers; ``"reference"`` is the same system)
    ``(A - B K, B, C, 0)`` from an input offset to the measured outputs; with
    integral action the augmented loop ``(Aa - Ba K, Br, [C1 0], 0)`` from
    the references to the tracked outputs, the integrator states named
    ``z_<output>``.

``"performance"`` (default of the H2 / H-infinity / multi-objective designs, which declare ``Bw``)
    state feedback: ``(A - B K, Bw, Cz - Dzu K, 0)`` from ``w`` to ``z``;
    observer: the error system ``(A - L C, [Bw, -L Dv], Cz, 0)``.
``"loop"``
    the loop transfer ``(A, B, K, 0)`` broken at the plant input, for
    ``control.margin`` (augmented ``(Aa, Ba, K, 0)`` with integral action).
``"error"`` (default of the other observers and the estimators)
    ``e+ = (A - L C) e - L v`` (``v`` measurement noise), output ``e``;
    ``luenberger`` by its form; Kalman filters at steady state on the
    linearisation (``K`` from the discrete Riccati equation of the artefact's
    ``Q`` (``Q0``; ``G Q G'``) and ``R``); ``ts_observer`` the linear part
    ``A0 - L C``.
``"observer"``
    the observer itself ``(A - L C, [B, L], I, 0)`` from ``(u, y)`` to the
    estimate.
``"model"`` (``linearize``)
    the ZOH model ``(Ad, Bd, C, 0)``.

Polytopic robust designs give the nominal model's loop, or with ``vertex=i``
the loop of the i-th stored vertex model. Takagi-Sugeno PDC designs
(``ts_state_feedback``, ``ts_output_feedback``) are not LTI: they give the
linearisation of the nonlinear closed loop at the operating point (memberships
at ``x0``) and warn (`tanksynth.errors.TanksynthWarning`).
Discrete-time designs get ``dt = ts`` (s), continuous ones ``dt = 0``.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, Mapping

import control
import numpy as np
from scipy.linalg import solve_discrete_are

from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.analysis.statespace import model_names
from tanksynth.errors import ArtefactError, TanksynthWarning
from tanksynth.spec import Spec, parse_spec_text
from tanksynth.verify.numerics import integral_augmentation
from tanksynth.verify.takagi_sugeno.model import rebuild_model

__all__ = ["artefact_statespace", "SYSTEMS", "DEFAULT_SYSTEM"]

#: The systems `artefact_statespace` builds.
SYSTEMS = ("closed_loop", "reference", "performance", "loop", "error", "observer", "model")

#: The system given when none is asked for, by the gain the artefact holds; designs declaring
#: disturbances ``Bw`` (H2, H-infinity, multi-objective) give their ``"performance"`` system.
DEFAULT_SYSTEM = {"K": "closed_loop", "L": "error", "Bw": "performance"}

_CONTROLLERS = ("pole_placement", "lmi_placement", "h2_state_feedback", "hinf_state_feedback",
                "multiobjective", "robust_state_feedback")
_OBSERVERS = ("pole_placement", "lmi_placement", "canonical_observer", "h2_observer",
              "hinf_observer", "multiobjective", "robust_observer")
_KALMAN = ("kalman", "ekf", "ukf", "adaptive_kalman", "adaptive_scaling_kalman")
_TS = ("ts_state_feedback", "ts_output_feedback")


class _Artefact:
    """The artefact's gains as arrays, its diagnostics, names and (lazily) its spec."""

    def __init__(self, doc: Mapping[str, Any], spec: Spec | None, plant_record: Mapping[str, Any] | None,
                 source: Path | None):
        self.name = str(doc.get("name", "artefact"))
        self.method = str(doc.get("method", ""))
        self.gains = {k: np.asarray(v, dtype=float) for k, v in (doc.get("gains") or {}).items()}
        self.diag = doc.get("diagnostics") or {}
        self.doc, self._spec, self.record, self.source = doc, spec, plant_record, source
        self.label = f"{source}" if source is not None else f"artefact '{self.name}'"

    def g(self, key: str) -> np.ndarray | None:
        v = self.gains.get(key)
        return None if v is None else (np.atleast_2d(v) if v.ndim < 2 else v)

    @property
    def discrete(self) -> bool:
        return self.diag.get("time_domain", "discrete") == "discrete"

    def need(self, key: str) -> np.ndarray:
        """Gain ``key`` as `g` reads it; an `ArtefactError` naming it when the artefact lacks it."""
        value = self.g(key)
        if value is None:
            raise ArtefactError(f"{self.label}: no gain {key!r}")
        return value

    def model(self, role: str) -> np.ndarray | None:
        """The model matrix ``role`` (``"A"``, ``"B"``, ``"Bw"``, ``"C"``) under its name (`model_names`)."""
        return self.g(model_names("discrete" if self.discrete else "continuous")[role])

    def dt(self, discrete: bool) -> float:
        if not discrete:
            return 0
        ts = self.diag.get("ts", self.diag.get("sampling_period", (self.record or {}).get("ts")))
        if ts is None and self._spec is not None:
            ts = getattr(self._spec, "ts", None)
        if not isinstance(ts, (int, float)) or ts <= 0:
            raise ArtefactError(f"{self.label}: a discrete design without a sampling period ts")
        return float(ts)

    @property
    def spec(self) -> Any:
        if self._spec is None:
            path = None if self.source is None else Path(self.source).parent / "spec.toml"
            if path is None or not path.is_file():
                raise ArtefactError(f"{self.label}: no spec.toml beside it (or spec given), needed "
                                    f"to rebuild the plant of a {self.method!r} design")
            self._spec = parse_spec_text(path.read_bytes(), source=str(path))
        return self._spec

    def names(self, kind: str) -> list[str] | None:
        if self._spec is not None:
            return [s.name for s in getattr(self._spec.plant, kind)]
        entries = ((self.record or {}).get("plant") or {}).get(kind)
        return None if not entries else [s["name"] for s in entries]

    def linearisation(self) -> Any:
        """The ZOH linearisation at the spec's operating point."""
        spec = self.spec
        eq = equilibrium_input(spec.plant, spec.x0, spec.given_u0)
        return linearize(spec.plant, spec.x0, eq.u0, ts=spec.ts)


def _fit(names: list[str] | None, size: int, prefix: str) -> list[str]:
    return list(names) if names is not None and len(names) == size else [f"{prefix}{i}" for i in range(size)]


def _channels(prefix: str, columns: list[np.ndarray], names: list[list[str] | None]) -> list[str]:
    """Names of the channels whose matrix columns are ``columns``: ``<prefix>_<signal>`` when a
    column has one nonzero entry, on a signal with a name (``names`` gives, per block of rows,
    the signal names or None), else ``<prefix>_<index>`` (0-based); distinct either way."""
    out = []
    for j, col in enumerate(columns):
        hits = np.flatnonzero(np.abs(np.asarray(col, dtype=float)) > 0)
        label, offset = f"{prefix}_{j}", 0
        for block in names:
            size = len(block) if block is not None else 0
            if len(hits) == 1 and block is not None and offset <= hits[0] < offset + size:
                label = f"{prefix}_{block[hits[0] - offset]}"
            offset += size
        out.append(label)
    return [n if out.count(n) == 1 else f"{prefix}_{j}" for j, n in enumerate(out)]


def _w_columns(a: _Artefact, Bw: np.ndarray) -> list[np.ndarray]:
    """The columns naming the disturbances: the continuous-time ``Bw`` the design records
    (``diagnostics.disturbances.Bw_continuous``; a ZOH ``Bwd`` mixes the states), else ``Bw``."""
    dist = a.diag.get("disturbances")
    raw = dist.get("Bw_continuous") if isinstance(dist, Mapping) else None
    try:
        cont = np.atleast_2d(np.asarray(raw, dtype=float)) if raw is not None else None
    except (TypeError, ValueError):
        cont = None
    return list((cont if cont is not None and cont.shape == Bw.shape else Bw).T)


def _ss(a: _Artefact, system: str, A: np.ndarray, B: np.ndarray, C: np.ndarray, dt: float, *,
        states: list[str] | None = None, inputs: list[str] | None = None,
        outputs: list[str] | None = None) -> Any:
    n = A.shape[0]
    D = np.zeros((C.shape[0], B.shape[1]))
    states = _fit(states if states is not None else a.names("states"), n, "x")
    return control.ss(A, B, C, D, dt, name=f"{a.name}_{system}".replace(".", "_"), states=states,
                      inputs=_fit(inputs, B.shape[1], "u"), outputs=_fit(outputs, C.shape[0], "y"))


def _error(a: _Artefact, system: str, Ae: np.ndarray, Lin: np.ndarray, dt: float) -> Any:
    states = _fit(a.names("states"), Ae.shape[0], "x")
    return _ss(a, system, Ae, -np.asarray(Lin), np.eye(Ae.shape[0]), dt,
               inputs=[f"v_{o}" for o in _fit(a.names("outputs"), Lin.shape[1], "y")],
               outputs=[f"e_{s}" for s in states])


def _model(a: _Artefact, vertex: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``A, B, C`` of the design (nominal, or the stored vertex model ``vertex``)."""
    if vertex is not None:
        vm = a.diag.get("vertex_models") or {}
        if not all(k in vm for k in ("A", "B", "C")):
            raise ArtefactError(f"{a.label}: {a.method!r} stores no vertex models; vertex= applies "
                                "to robust_state_feedback / robust_observer artefacts")
        count = len(vm["A"])
        if not isinstance(vertex, int) or not 0 <= vertex < count:
            raise ArtefactError(f"{a.label}: vertex must be an integer in [0, {count - 1}], got {vertex!r}")
        stored = [np.atleast_2d(np.asarray(vm[k][vertex], dtype=float)) for k in ("A", "B", "C")]
        return stored[0], stored[1], stored[2]
    A, B, C = (a.model(k) for k in ("A", "B", "C"))
    if A is not None and B is not None and C is not None and A.ndim == 2:
        return A, B, C
    lin = a.linearisation()
    return (lin.Ad, lin.Bd, lin.C) if a.discrete else (lin.F, lin.B, lin.C)


def _augmented(a: _Artefact, A: np.ndarray, B: np.ndarray, C: np.ndarray, K: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """``Aa, Ba, Br, Ca`` and the tracked outputs of a loop with integral action."""
    n = A.shape[0]
    integral = a.diag.get("integral")
    if not isinstance(integral, Mapping) or ("C1" not in integral and "augmented_A" not in integral):
        raise ArtefactError(f"{a.label}: K has {K.shape[1]} columns, the model {n} states, and the "
                            "artefact records no integral action (diagnostics.integral.C1)")
    C1 = np.atleast_2d(np.asarray(integral["C1"], dtype=float))
    p = C1.shape[0]
    tracked = list(integral.get("tracked") or [f"y{i}" for i in range(p)])
    if "augmented_A" in integral:   # pole_placement / lmi_placement record their augmentation
        Aa = np.asarray(integral["augmented_A"], dtype=float)
        Ba = (np.asarray(integral["augmented_B"], dtype=float) if "augmented_B" in integral
              else np.vstack([B, np.zeros((Aa.shape[0] - n, B.shape[1]))]))
        Br = a.g("Br")
    else:                           # z+ = z + ts (r - C1 x) / z' = r - C1 x
        ts = a.dt(True) if a.discrete else None
        Aa, Ba = integral_augmentation(A, B, C1, ts)
        Br = np.vstack([np.zeros((n, p)), (ts or 1.0) * np.eye(p)])
    if Br is None or Aa.shape[0] != K.shape[1]:
        raise ArtefactError(f"{a.label}: the augmented model ({Aa.shape[0]} states) does not fit K "
                            f"({K.shape[1]} columns) or has no reference input Br")
    Ca = np.hstack([C1, np.zeros((p, Aa.shape[0] - C1.shape[1]))])
    return Aa, Ba, Br, Ca, tracked


def _controller(a: _Artefact, system: str, vertex: int | None) -> Any:
    K = a.need("K")
    A, B, C = _model(a, vertex)
    n, dt = A.shape[0], a.dt(a.discrete)
    states, inputs, outputs = a.names("states"), a.names("inputs"), a.names("outputs")
    if system == "performance":
        Bw, Cz, Dzu = a.model("Bw"), a.g("Cz"), a.g("Dzu")
        if Bw is None or Cz is None or Dzu is None or K.shape[1] != n:
            raise ArtefactError(f"{a.label}: no Bw, Cz, Dzu with a state feedback on the model "
                                f"({a.method!r} is not an H2 / H-infinity design): system "
                                "'performance' does not apply")
        return _ss(a, system, A - B @ K, Bw, Cz - Dzu @ K, dt,
                   inputs=_channels("w", _w_columns(a, Bw), [_fit(states, n, "x")]),
                   outputs=_channels("z", list(np.hstack([Cz, Dzu])),
                                     [_fit(states, n, "x"), _fit(inputs, Dzu.shape[1], "u")]))
    if system not in ("closed_loop", "reference", "loop"):
        usable = "'closed_loop', 'performance' or 'loop'" if a.model("Bw") is not None \
            else "'closed_loop' or 'loop'"
        raise ArtefactError(f"{a.label} is a state feedback: system {system!r} does not apply "
                            f"(use {usable})")
    if K.shape[1] == n:
        if system == "loop":
            return _ss(a, system, A, B, K, dt, inputs=inputs, outputs=[f"{u}_fb" for u in
                                                                       _fit(inputs, K.shape[0], "u")])
        return _ss(a, system, A - B @ K, B, C, dt, inputs=inputs, outputs=outputs)
    Aa, Ba, Br, Ca, tracked = _augmented(a, A, B, C, K)
    names = _fit(states, n, "x") + [f"z_{t}" for t in tracked]
    if system == "loop":
        return _ss(a, system, Aa, Ba, K, dt, states=names, inputs=inputs,
                   outputs=[f"{u}_fb" for u in _fit(inputs, K.shape[0], "u")])
    return _ss(a, system, Aa - Ba @ K, Br, Ca, dt, states=names,
               inputs=[f"r_{t}" for t in tracked], outputs=tracked)


def _observer(a: _Artefact, system: str, vertex: int | None) -> Any:
    L = a.need("L")
    A, B, C = _model(a, vertex)
    discrete = a.discrete and a.method != "canonical_observer"
    dt, n = a.dt(discrete), A.shape[0]
    if system == "error":
        return _error(a, system, A - L @ C, L, dt)
    if system == "performance":
        Bw, Dv, Cz = a.model("Bw"), a.g("Dv"), a.g("Cz")
        if Bw is None or Dv is None or Cz is None:
            raise ArtefactError(f"{a.label}: no Bw, Dv, Cz ({a.method!r} is not an H2 / H-infinity "
                                "design): system 'performance' does not apply")
        Bcl = np.hstack([Bw, -L @ Dv])
        states = _fit(a.names("states"), n, "x")
        return _ss(a, system, A - L @ C, Bcl, Cz, dt,
                   inputs=_channels("w", _w_columns(a, Bw), [states])
                   + _channels("v", list(Dv.T), [_fit(a.names("outputs"), Dv.shape[0], "y")]),
                   outputs=_channels("z", list(Cz), [[f"e_{x}" for x in states]]))
    if system == "observer":
        Bo = np.hstack([B, L])
        states = _fit(a.names("states"), n, "x")
        return _ss(a, system, A - L @ C, Bo, np.eye(n), dt,
                   inputs=_fit(a.names("inputs"), B.shape[1], "u") + _fit(a.names("outputs"), L.shape[1], "y"),
                   outputs=[f"{s}_hat" for s in states])
    usable = "'error', 'performance' or 'observer'" if a.model("Bw") is not None \
        else "'error' or 'observer'"
    raise ArtefactError(f"{a.label} is an observer: system {system!r} does not apply "
                        f"(use {usable})")


def _ts_memberships(a: _Artefact) -> tuple[np.ndarray, np.ndarray]:
    """``mu_i(x0)`` (the memberships at the operating point, premises at their limit slopes), ``C``."""
    model = rebuild_model(a.spec.plant, a.doc)
    return model.memberships(model.x0[None, :])[0], np.atleast_2d(model.C)


def _ts_pdc(a: _Artefact, system: str) -> Any:
    if system not in ("closed_loop", "error") or (system == "error" and a.method == "ts_state_feedback"):
        raise ArtefactError(f"{a.label}: a Takagi-Sugeno PDC design gives its linearisation at the "
                            f"operating point, system 'closed_loop' (or 'error' for "
                            f"ts_output_feedback), not {system!r}")
    Ai, B, Ki = a.gains["F"], a.need("B"), a.gains["K"]
    if Ai.ndim != 3 or Ki.ndim != 3 or Ai.shape[0] != Ki.shape[0]:
        raise ArtefactError(f"{a.label}: expected vertex matrices F (r, n, n) and PDC gains K "
                            f"(r, m, n), got F {Ai.shape}, K {Ki.shape}")
    mu, C = _ts_memberships(a)
    A0 = np.einsum("i,ijk->jk", mu, Ai)       # = the plant's Jacobian at x0 (the TS model is exact)
    K0 = np.einsum("i,ijk->jk", mu, Ki)
    states, inputs = a.names("states"), a.names("inputs")
    n, dt = A0.shape[0], 0
    warnings.warn(f"{a.name} ({a.method}): the PDC closed loop is not LTI; the StateSpace is its "
                  "linearisation at the operating point x0 (memberships at x0: "
                  f"{np.array2string(mu, precision=3)}), valid near x0 only", TanksynthWarning,
                  stacklevel=4)
    if a.method == "ts_state_feedback":
        return _ss(a, system, A0 - B @ K0, B, C, dt, inputs=inputs, outputs=a.names("outputs"))
    L = a.gains["L"]
    L0 = np.einsum("i,ijk->jk", mu, L) if L.ndim == 3 else np.atleast_2d(L)
    if system == "error":
        return _error(a, system, A0 - L0 @ C, L0, dt)
    # states (x - x0, e = x - x_hat): u = u0 - K0 (x_hat - x0)
    Acl = np.block([[A0 - B @ K0, B @ K0], [np.zeros((n, n)), A0 - L0 @ C]])
    Bcl = np.vstack([B, np.zeros((n, B.shape[1]))])
    names = _fit(states, n, "x")
    return _ss(a, system, Acl, Bcl, np.hstack([C, np.zeros_like(C)]), dt,
               states=names + [f"e_{s}" for s in names], inputs=inputs, outputs=a.names("outputs"))


def _kalman(a: _Artefact, system: str) -> Any:
    if system != "error":
        raise ArtefactError(f"{a.label}: a Kalman filter gives its steady-state error system "
                            f"('error'), not {system!r}")
    g = a.gains
    if "Ad" in g and "C" in g:
        Ad, C = a.need("Ad"), a.need("C")
    else:
        lin = a.linearisation()
        Ad, C = lin.Ad, lin.C
    Q = a.need("Q0") if "Q0" in g else a.need("Q")
    if a.method == "adaptive_scaling_kalman" and "G" in g:
        Q = a.need("G") @ Q @ a.need("G").T
    R = a.need("R")
    P = solve_discrete_are(Ad.T, C.T, Q, R)     # predicted covariance
    K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    return _error(a, system, (np.eye(Ad.shape[0]) - K @ C) @ Ad, Ad @ K, a.dt(True))


def _luenberger(a: _Artefact, system: str) -> Any:
    if system != "error":
        raise ArtefactError(f"{a.label}: luenberger gives its error system ('error'), not {system!r}")
    lin, L, form = a.linearisation(), a.need("L"), a.diag.get("form")
    if form == "continuous":
        return _error(a, system, lin.F - L @ lin.C, L, 0)
    if form == "predictor":
        return _error(a, system, lin.Ad - L @ lin.C, L, a.dt(True))
    return _error(a, system, (np.eye(L.shape[0]) - L @ lin.C) @ lin.Ad, lin.Ad @ L, a.dt(True))


def _integral_tracking(a: _Artefact, system: str) -> Any:
    if system not in ("closed_loop", "reference"):
        raise ArtefactError(f"{a.label}: integral_tracking gives its closed loop, not {system!r}")
    lin, C1, K = a.linearisation(), a.need("C1"), a.need("K")
    n, p, ts = lin.Ad.shape[0], C1.shape[0], a.dt(True)
    # x+ = Ad x + Bd u, z+ = z + ts (r - C1 x), u = -K1 x - K2 z (deviations, no saturation)
    Aa = np.block([[lin.Ad, np.zeros((n, p))], [-ts * C1, np.eye(p)]])
    Ba = np.vstack([lin.Bd, np.zeros((p, lin.Bd.shape[1]))])
    Br = np.vstack([np.zeros((n, p)), ts * np.eye(p)])
    tracked = [str(t) for t in (a.diag.get("tracked") or [f"y{i}" for i in range(p)])]
    names = _fit(a.names("states"), n, "x") + [f"z_{t}" for t in tracked]
    return _ss(a, system, Aa - Ba @ K, Br, np.hstack([C1, np.zeros((p, p))]), ts, states=names,
               inputs=[f"r_{t}" for t in tracked], outputs=tracked if len(tracked) == p else None)


def artefact_statespace(doc: Mapping[str, Any], system: str | None = None, spec: Spec | None = None, *,
                        plant_record: Mapping[str, Any] | None = None, source: str | Path | None = None,
                        vertex: int | None = None) -> Any:
    """A closed loop, error system or observer of an artefact as a `control.StateSpace`.

    Parameters
    ----------
    doc : mapping
        The artefact (``name``, ``method``, ``gains``, ``diagnostics``), as read from its JSON file.
    system : {"closed_loop", "reference", "performance", "loop", "error", "observer", "model"}, optional
        See the module docstring; default ``"performance"`` (``w -> z``) for an
        H2 / H-infinity / multi-objective design, ``"closed_loop"`` for another
        controller, ``"error"`` for another observer or an estimator,
        ``"model"`` for ``linearize``.
    spec : Spec, optional
        The spec: names the states, inputs and outputs after the plant's and
        gives the plant where the artefact holds no linear model.
    plant_record : mapping, optional
        ``plant.json`` of the result directory (names, when ``spec`` is not given).
    source : str or Path, optional
        The artefact's file: ``spec.toml`` beside it is read when the plant is needed.
    vertex : int, optional
        Robust designs: the loop of the stored vertex model ``vertex`` (0-based)
        instead of the nominal model.

    Returns
    -------
    control.StateSpace
        ``dt = ts`` (s) for a discrete design, 0 for a continuous one.

    Raises
    ------
    ArtefactError
        The method has no linear closed loop or error system, the system asked
        for does not apply to it, or the artefact lacks the gains it needs.

    Warns
    -----
    TanksynthWarning
        Takagi-Sugeno PDC designs: the system is the linearisation at ``x0``.
    """
    a = _Artefact(doc, spec, plant_record, None if source is None else Path(source))
    if system is not None and system not in SYSTEMS:
        raise ArtefactError(f"{a.label}: system must be one of {', '.join(SYSTEMS)}, got {system!r}")
    method, g = a.method, a.gains
    if vertex is not None and method not in ("robust_state_feedback", "robust_observer"):
        raise ArtefactError(f"{a.label}: vertex= applies to robust_state_feedback / robust_observer "
                            f"designs, not {method!r}")
    if method == "linearize":
        if system not in (None, "model"):
            raise ArtefactError(f"{a.label}: linearize gives its model ('model'), not {system!r}")
        return _ss(a, "model", a.need("Ad"), a.need("Bd"), a.need("C"), a.dt(True), inputs=a.names("inputs"),
                   outputs=a.names("outputs"))
    if method in _TS:
        return _ts_pdc(a, system or "closed_loop")
    if method in _CONTROLLERS and "K" in g and g["K"].ndim <= 2:
        return _controller(a, system or DEFAULT_SYSTEM["Bw" if a.model("Bw") is not None else "K"], vertex)
    if method in _OBSERVERS and "L" in g and g["L"].ndim <= 2:
        return _observer(a, system or DEFAULT_SYSTEM["Bw" if a.model("Bw") is not None else "L"], vertex)
    if method == "ts_observer":
        if system not in (None, "error"):
            raise ArtefactError(f"{a.label}: ts_observer gives its error system ('error'), not {system!r}")
        return _error(a, "error", a.need("A0") - a.need("L") @ a.need("C"), a.need("L"), 0)
    if method == "integral_tracking":
        return _integral_tracking(a, system or "closed_loop")
    if method == "luenberger":
        return _luenberger(a, system or "error")
    if method in _KALMAN:
        return _kalman(a, system or "error")
    raise ArtefactError(f"{a.label}: method {method!r} has no linear closed loop or error system to "
                        "give as a StateSpace (nonlinear law, time-varying or decentralised gains, "
                        "a detector or a neural estimator)")
