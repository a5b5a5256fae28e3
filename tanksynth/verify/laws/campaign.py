"""Closed loops of controller artefacts for Monte-Carlo campaigns.

A controller artefact runs closed loop from what it ships: the state
feedback gains of a placement artefact (`IntegralStateFeedback`,
`StateFeedback`) or the serialised CasADi law of ``feedback_linearization``,
``integral_tracking`` and ``inverse_dynamics`` (`ArtefactLaw` ``u, zeta =
law(x, y_r)`` / ``u = law(x_hat, h_sp)``, `ArtefactIntegralLaw` ``u, z_next
= law(x, z, y_r)`` with the integrator state kept per run), evaluated on the
M runs at once with ``Function.map``. The true state is fed back unless the
loop carries an estimator.

A `ClosedLoop` is one kind of campaign run (see `tanksynth.verify.campaign`):
`ClosedLoop.evaluate` simulates a scenario and returns the tracking metrics
of the controlled variables (named after the plant's outputs), and the
estimation RMSE when an estimator closes the loop.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from tanksynth.errors import ArtefactError
from tanksynth.plants.base import Plant
from tanksynth.runtime.laws import inverse_dynamics_law, law_from_document
from tanksynth.sim.closed_loop import LoopLaw
from tanksynth.sim.metrics import Metric, compute_metrics
from tanksynth.sim.scenarios import Scenario, run_scenario
from tanksynth.sim.simulate import BatchEstimator
from tanksynth.spec import Spec
from tanksynth.verify.batch_call import CasadiControlLaw, CasadiIntegralLaw
from tanksynth.verify.common import (operating_point, output_at, sampling_period,
                                     stored_operating_point)
from tanksynth.verify.simulations import IntegralStateFeedback, StateFeedback  # noqa: F401 (re-export)

__all__ = [
    "ClosedLoop",
    "IntegralStateFeedback",
    "StateFeedback",
    "InverseDynamicsLaw",
    "ArtefactLaw",
    "ArtefactIntegralLaw",
    "OutputSetpoints",
    "output_setpoint_law",
    "state_feedback_loop",
    "feedback_linearization_loop",
    "integral_tracking_loop",
    "inverse_dynamics_loop",
    "closed_loop_for",
]


@dataclass(frozen=True)
class ClosedLoop:
    """A controller artefact in closed loop (a campaign run of kind ``"controller"``).

    Attributes
    ----------
    controller : callable
        Control law ``(x_hat, reference, t) -> u`` (batch over runs).
    estimator_factory : callable or None
        ``factory() -> BatchEstimator`` (a fresh one per simulation); None:
        the true state is fed back.
    x_op, u_op : ndarray
        Operating point (initial state and set-points; input held before t = 0),
        in state and input units.
    tracked : tuple of int
        Controlled states.
    description : str
    kind : str
        ``"controller"``.
    """

    controller: Callable
    estimator_factory: Callable[[], BatchEstimator] | None
    x_op: np.ndarray
    u_op: np.ndarray
    tracked: tuple[int, ...]
    description: str
    kind: str = field(default="controller", init=False)

    def evaluate(self, sc: Scenario, plant: Plant, *, ts: float, seeds: Sequence[int],
                 substeps: int = 4) -> dict[str, Metric]:
        """Simulate the scenario in closed loop and return its metrics.

        The artefact's controller always acts (a scenario's open-loop input
        schedule is for artefacts without one); set-points start at the
        operating point of the controlled states.

        Parameters
        ----------
        sc : Scenario
        plant : Plant
        ts : float
            Sampling period (s).
        seeds : sequence of int
            One per run.
        substeps : int
            RK4 steps per period.

        Returns
        -------
        dict of str to Metric
            ``ise_<y>``, ``offset_<y>``, tracking/rejection times, the
            controller time, and ``rmse_<state>`` with an estimator.
        """
        setup = sc.setup(plant, self.x_op, self.u_op, self.tracked, ts=ts)
        estimator = self.estimator_factory() if self.estimator_factory is not None else None
        result = run_scenario(setup, plant, ts=ts, seeds=list(seeds), controller=self.controller,
                              estimator=estimator, substeps=substeps)
        return compute_metrics(result, setup, plant, estimated=estimator is not None,
                               controlled=True)


@dataclass
class InverseDynamicsLaw:
    """Inverse-dynamics control (seed 002 eq. 46-47) as a batch `ControlLaw`.

    The law is `tanksynth.runtime.laws.inverse_dynamics_law` (``u =
    G_c(x_hat)^-1 (c (r - x_hat_c) - f0_c(x_hat))``, nominal parameters,
    saturated to the pumps' range), evaluated on the M runs at once by
    `tanksynth.verify.batch_call.CasadiControlLaw`.

    Attributes
    ----------
    plant : Plant
    tracked : tuple of int
        Controlled states (as many as inputs).
    gains : tuple of float
        ``c_i`` (1/s).
    saturate : bool
        Clip to the plant's input range inside the law (the simulator
        saturates anyway).
    """

    plant: Plant
    tracked: tuple[int, ...]
    gains: tuple[float, ...]
    saturate: bool = True
    _law: Any = field(init=False, default=None, repr=False)

    def __post_init__(self) -> None:
        names = [s.name for s in self.plant.states]
        law = inverse_dynamics_law(self.plant, np.asarray(self.gains, dtype=float),
                                   [names[i] for i in self.tracked], saturate=self.saturate)
        self._law = CasadiControlLaw(law.law)

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m) from the estimate (M, n) and the set-points (M, m)."""
        return self._law(x_hat, reference, t)

    def loop_law(self, runs: int) -> LoopLaw | None:
        """The law for the closed-loop kernel (`tanksynth.sim.closed_loop`).

        Parameters
        ----------
        runs : int
            Number of runs M.
        """
        return self._law.loop_law(runs)


class ArtefactLaw:
    """An artefact's serialised CasADi law as a batch `ControlLaw` (stateless).

    For the laws ``u, zeta = law(x, y_r)`` (``feedback_linearization``) and
    ``u = law(x_hat, h_sp)`` (``inverse_dynamics``): the Function from
    ``doc["diagnostics"]["law"]`` (`tanksynth.runtime.laws.law_from_document`,
    which refuses an edited serialisation) is evaluated on the M runs at
    once (``Function.map``); its first output is the input.

    Parameters
    ----------
    function : casadi.Function
        Inputs ``(x, reference)``, first output ``u``.
    signature : str
        ``doc["diagnostics"]["law_signature"]``.
    """

    def __init__(self, function: Any, signature: str = ""):
        self.function = function
        self.signature = signature
        self._law = CasadiControlLaw(function)

    @classmethod
    def from_document(cls, doc: Mapping[str, Any]) -> "ArtefactLaw":
        """The law serialised in an artefact's diagnostics.

        Parameters
        ----------
        doc : mapping
            The artefact.

        Raises
        ------
        ArtefactError
            No law in the diagnostics, or an altered serialisation.
        """
        fn, signature = _law_of(doc)
        return cls(fn, signature)

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m) from the state (M, n) and the reference (M, r)."""
        return self._law(np.asarray(x_hat, float), np.asarray(reference, float), t)

    def loop_law(self, runs: int) -> LoopLaw | None:
        """The law for the closed-loop kernel (`tanksynth.sim.closed_loop`).

        Parameters
        ----------
        runs : int
            Number of runs M.
        """
        return self._law.loop_law(runs)


class ArtefactIntegralLaw(ArtefactLaw):
    """An artefact's serialised integral-tracking law ``u, z_next = law(x, z, y_r)`` (stateful).

    The integrator state ``z`` is kept per run: `reset` (called by the
    simulator before the first sample) zeroes it for M runs, each call
    advances it.

    Parameters
    ----------
    function : casadi.Function
        Inputs ``(x, z, y_r)``, outputs ``(u, z_next)``.
    signature : str
    """

    _law: CasadiIntegralLaw

    def __init__(self, function: Any, signature: str = ""):
        self.function = function
        self.signature = signature
        self._law = CasadiIntegralLaw(function)

    @property
    def z(self) -> np.ndarray:
        """Integrator states, shape (M, p)."""
        return self._law.z

    def reset(self, runs: int) -> None:
        """Zero the integrators of ``runs`` runs.

        Parameters
        ----------
        runs : int
            Number of runs M.
        """
        self._law.reset(runs)

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m); advances the integrator state of every run."""
        return self._law(np.asarray(x_hat, float), np.asarray(reference, float), t)


@dataclass
class OutputSetpoints:
    """A law on the tracked OUTPUTS' set-points driven by a scenario's STATE set-points.

    A campaign scenario moves the set-points of the controlled states; an integral
    law integrates the error of the measured outputs ``y = h(x)``. The state
    set-points ``r`` are handed to the law as the outputs they give on the model
    linearised at the operating point, ``y_r = y0 + C1s (r - xs0)`` (exact for an
    affine ``h``: a sensor offset or gain), so the loop holds the states at ``r``.

    Attributes
    ----------
    law : callable
        ``(x_hat (M, n), y_r (M, p), t) -> u (M, m)``, stateful or not.
    y0 : ndarray, shape (p,)
        Tracked outputs at the operating point, ``h(x0)`` (output units).
    C1s : ndarray, shape (p, p)
        Columns of the controlled states in the tracked rows of the linearised
        output map (output units per state unit).
    xs0 : ndarray, shape (p,)
        Controlled states at the operating point (state units).
    """

    law: Callable
    y0: np.ndarray
    C1s: np.ndarray
    xs0: np.ndarray

    def reset(self, runs: int) -> None:
        """Reset the wrapped law for ``runs`` runs (when it keeps a state).

        Parameters
        ----------
        runs : int
            Number of runs M.
        """
        if hasattr(self.law, "reset"):
            self.law.reset(runs)

    def __call__(self, x_hat: np.ndarray, reference: np.ndarray, t: float) -> np.ndarray:
        """Input (M, m) from the state (M, n) and the state set-points (M, p)."""
        yr = self.y0 + np.einsum("ij,kj->ik", np.asarray(reference, float) - self.xs0, self.C1s)
        return self.law(x_hat, yr, t)

    def loop_law(self, runs: int) -> LoopLaw | None:
        """The wrapped law's (`tanksynth.sim.closed_loop`) on the state set-points, or None.

        Parameters
        ----------
        runs : int
            Number of runs M.
        """
        offer = getattr(self.law, "loop_law", None)
        inner = offer(runs) if offer is not None else None
        if inner is None:
            return None
        import casadi as ca

        fn = inner.function
        C1s = np.atleast_2d(np.asarray(self.C1s, dtype=float))
        y0 = np.asarray(self.y0, dtype=float).reshape(-1)
        xs0 = np.asarray(self.xs0, dtype=float).reshape(-1)
        key = (fn, C1s.tobytes(), C1s.shape, y0.tobytes(), xs0.tobytes())
        held = self.__dict__.get("_loop_fn")
        if held is not None and held[0][0] is fn and held[0][1:] == key[1:]:
            return LoopLaw(held[1], inner.state, inner.commit)
        try:
            x, z = ca.SX.sym("x", fn.nnz_in(0)), ca.SX.sym("z", fn.nnz_in(1))
            r = ca.SX.sym("r", C1s.shape[1])
            d = [r[j] - xs0[j] for j in range(C1s.shape[1])]
            yr = []
            for i in range(C1s.shape[0]):
                acc = d[0] * C1s[i, 0]
                for j in range(1, len(d)):
                    acc = acc + d[j] * C1s[i, j]
                yr.append(y0[i] + acc)
            outs = fn(x, z, ca.vertcat(*yr))
            wrapped = ca.Function("output_setpoints", [x, z, r], [outs[0], outs[1]])
        except (RuntimeError, NotImplementedError, TypeError):
            return None
        self.__dict__["_loop_fn"] = (key, wrapped)
        return LoopLaw(wrapped, inner.state, inner.commit)


def output_setpoint_law(law: Callable, C1: Any, y0: Any, x0: Any, states: Sequence[int]) -> Callable:
    """`OutputSetpoints` around ``law``, or ``law`` itself when outputs and states coincide.

    Parameters
    ----------
    law : callable
        The integral law on output set-points.
    C1 : array_like, shape (p, n)
        Tracked rows of the output map linearised at ``x0`` (output units per state unit).
    y0 : array_like, shape (p,)
        Tracked outputs at ``x0`` (output units).
    x0 : array_like, shape (n,)
        Operating state (state units).
    states : sequence of int
        The controlled states (p of them), whose set-points the scenario moves.

    Returns
    -------
    callable
        ``law`` unchanged when ``C1s`` is the identity and ``y0`` the controlled states
        at ``x0`` (levels measured as they are: the set-points are already the outputs'),
        else the `OutputSetpoints` wrapper.
    """
    C1 = np.atleast_2d(np.asarray(C1, dtype=float))
    y0 = np.asarray(y0, dtype=float).reshape(-1)
    xs0 = np.asarray(x0, dtype=float).reshape(-1)[list(states)]
    C1s = C1[:, list(states)]
    if C1s.shape == (y0.size, y0.size) and np.array_equal(C1s, np.eye(y0.size)) and np.array_equal(y0, xs0):
        return law
    return OutputSetpoints(law, y0, C1s, xs0)


def _law_of(doc: Mapping[str, Any]) -> tuple[Any, str]:
    diag = doc.get("diagnostics") or {}
    law = diag.get("law") if isinstance(diag, Mapping) else None
    if not isinstance(law, Mapping):
        raise ArtefactError(f"artefact '{doc.get('name', '')}' ({doc.get('method', '')}) has no "
                            "serialised law in diagnostics.law")
    signature = diag.get("law_signature", "")
    return law_from_document(dict(law)), str(signature) if isinstance(signature, str) else ""


def _named_states(spec: Spec, doc: Mapping[str, Any], keys: Sequence[str]) -> tuple[int, ...] | None:
    """State indices of the names listed under one of ``keys`` (diagnostics, then design options)."""
    names = [s.name for s in spec.plant.states]
    diag = doc.get("diagnostics") or {}
    sources: list[Mapping[str, Any]] = [diag] if isinstance(diag, Mapping) else []
    for d in getattr(spec, "designs", ()) or ():
        if getattr(d, "name", None) == doc.get("name"):
            opts = getattr(d, "options", None)
            if isinstance(opts, Mapping):
                sources.append(opts)
    for src in sources:
        for key in keys:
            listed = src.get(key)
            if isinstance(listed, (list, tuple)) and listed and all(str(v) in names for v in listed):
                return tuple(names.index(str(v)) for v in listed)
    return None


def _tracked(spec: Spec, doc: Mapping[str, Any]) -> tuple[int, ...]:
    names = [s.name for s in spec.plant.states]
    integ = (doc.get("diagnostics") or {}).get("integral") or {}
    C1 = integ.get("C1") if isinstance(integ, Mapping) else None
    if C1:
        return tuple(int(np.argmax(np.abs(row))) for row in np.asarray(C1, dtype=float))
    tracked = integ.get("tracked") if isinstance(integ, Mapping) else None
    if tracked:
        return tuple(names.index(t) for t in tracked)
    return tuple(range(min(spec.plant.m, spec.plant.n)))


def _tracked_outputs_at(spec: Spec, doc: Mapping[str, Any], x0: np.ndarray, C1: np.ndarray,
                        states: Sequence[int]) -> np.ndarray:
    """``h(x0)`` of the tracked outputs named in the artefact, else ``C1 x0``."""
    diag = doc.get("diagnostics") or {}
    integ = diag.get("integral") if isinstance(diag, Mapping) else None
    names = (integ.get("tracked") if isinstance(integ, Mapping) else None) or \
        (diag.get("tracked") if isinstance(diag, Mapping) else None)
    outputs = [s.name for s in spec.plant.outputs]
    if isinstance(names, (list, tuple)) and len(names) == C1.shape[0] and all(t in outputs for t in names):
        return output_at(spec.plant, x0)[[outputs.index(t) for t in names]]
    return C1 @ np.asarray(x0, dtype=float)


def _operating_point(spec: Spec, doc: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The artefact's operating point, else the spec's."""
    stored = stored_operating_point(doc)
    return stored if stored is not None else operating_point(spec)


def state_feedback_loop(doc: Mapping[str, Any], spec: Spec) -> ClosedLoop:
    """State feedback of a placement artefact (integral action when it has ``K1``, ``K2``), true state.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.

    Raises
    ------
    ArtefactError
        The artefact has neither ``K1``/``K2`` nor ``K`` (an observer gain
        ``L`` is run by `tanksynth.verify.estimators.campaign.placement_run`).
    """
    gains = doc["gains"]
    x0, u0 = _operating_point(spec, doc)
    n = spec.plant.n
    if {"K1", "K2"} <= set(gains):
        tracked = _tracked(spec, doc)
        integ = (doc.get("diagnostics") or {}).get("integral") or {}
        C1 = np.asarray(integ.get("C1") or [], dtype=float) if isinstance(integ, Mapping) else np.zeros(0)
        if C1.shape != (len(tracked), n):
            C1 = np.zeros((len(tracked), n))
            C1[range(len(tracked)), tracked] = 1.0
        # the measured outputs at x0 (offsets, sensor gains): the designed integrators' y_op
        y0 = _tracked_outputs_at(spec, doc, x0, C1, tracked)
        law = IntegralStateFeedback(np.atleast_2d(gains["K1"]), np.atleast_2d(gains["K2"]), C1, x0,
                                    u0, sampling_period(spec), y0=y0)
        return ClosedLoop(output_setpoint_law(law, C1, y0, x0, tracked), None, x0, u0, tracked,
                          "the artefact's state feedback K1, K2 with integral action "
                          "(u = u0 - K1 (x - x0) - K2 z), true state fed back")
    if "K" in gains:
        K = np.atleast_2d(np.asarray(gains["K"], dtype=float)).reshape(spec.plant.m, n)
        return ClosedLoop(StateFeedback(K, x0, u0), None, x0, u0, tuple(range(min(spec.plant.m, n))),
                          "the artefact's state feedback u = u0 - K (x - x0) (a regulator: it "
                          "ignores set-point changes), true state fed back")
    raise ArtefactError(f"artefact '{doc.get('name', '')}' ({doc.get('method', '')}) has no state "
                        "feedback gain (K, or K1 and K2)")


def _serialized_loop(doc: Mapping[str, Any], spec: Spec, law: ArtefactLaw, keys: Sequence[str],
                     what: str) -> ClosedLoop:
    x0, u0 = _operating_point(spec, doc)
    tracked = _named_states(spec, doc, keys)
    p = int(law.function.nnz_in(law.function.n_in() - 1))
    if tracked is None or len(tracked) != p:
        tracked = tuple(range(min(p, spec.plant.n)))
    sig = f" ({re.split(r'[:;]', law.signature)[0].strip()})" if law.signature else ""
    return ClosedLoop(law, None, x0, u0, tracked, f"{what}, the artefact's serialised CasADi law{sig}, "
                                                  "true state fed back")


def feedback_linearization_loop(doc: Mapping[str, Any], spec: Spec) -> ClosedLoop:
    """The serialised feedback-linearising law of the artefact, true state.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    return _serialized_loop(doc, spec, ArtefactLaw.from_document(doc), ("outputs", "tracked"),
                            "input-output feedback linearisation")


def integral_tracking_loop(doc: Mapping[str, Any], spec: Spec) -> ClosedLoop:
    """The serialised integral-tracking law with anti-windup, integrator state per run.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    loop = _serialized_loop(doc, spec, ArtefactIntegralLaw(*_law_of(doc)), ("tracked", "outputs"),
                            "state feedback with integral action and anti-windup")
    gains = doc.get("gains") or {}
    n = spec.plant.n
    C1 = np.asarray(gains.get("C1", []), dtype=float)
    p = len(loop.tracked)
    if C1.size != p * n:
        return loop
    C1 = C1.reshape(p, n)
    if p and not np.array_equal(np.argmax(np.abs(C1), axis=1), np.asarray(loop.tracked)):
        # the law tracks outputs (y1 = kc h1, h1 + b1, ...) not named as states: their states
        loop = ClosedLoop(loop.controller, None, loop.x_op, loop.u_op,
                          tuple(int(i) for i in np.argmax(np.abs(C1), axis=1)), loop.description)
    y0 = _tracked_outputs_at(spec, doc, loop.x_op, C1, loop.tracked)
    return ClosedLoop(output_setpoint_law(loop.controller, C1, y0, loop.x_op, loop.tracked), None,
                      loop.x_op, loop.u_op, loop.tracked, loop.description)


def inverse_dynamics_loop(doc: Mapping[str, Any], spec: Spec) -> ClosedLoop:
    """The serialised inverse-dynamics law, true state fed back.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    """
    return _serialized_loop(doc, spec, ArtefactLaw.from_document(doc), ("controlled", "tracked"),
                            "inverse-dynamics control (u = G_c(x)^-1 (diag(C) (x_sp - x_c) - f0_c(x)))")


def closed_loop_for(doc: Mapping[str, Any], spec: Spec,
                    builder: Callable[[Mapping[str, Any], Any], Any]) -> ClosedLoop:
    """The closed loop of a controller artefact from its method's campaign runner.

    Parameters
    ----------
    doc, spec : mapping, Spec
        The artefact and the validated spec.
    builder : callable
        The method's campaign runner ``(doc, spec) -> CampaignRun``.

    Raises
    ------
    ArtefactError
        The runner builds no closed loop for this artefact (an estimator,
        an observer, a detector or a model).
    """
    run = builder(doc, spec)
    if not isinstance(run, ClosedLoop):
        raise ArtefactError(f"artefact '{doc.get('name', '')}' ({doc.get('method', '')}) is not run in "
                            f"closed loop: its campaign runs a {getattr(run, 'kind', type(run).__name__)}")
    return run
