"""Routes of `simulate` that integrate the whole horizon at once: the affine state feedback
(`tanksynth.sim.affine`) and a plant whose inputs do not depend on the estimate; both against
the period-by-period loop (forced with a plain callable, which offers neither route)."""

import sys

import numpy as np
import pytest

from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.plants import hybrid_three_tank, three_tank
from tanksynth.plants.hybrid_three_tank import LPH
from tanksynth.runtime.estimators.luenberger import LuenbergerObserver, LuenbergerTuning
from tanksynth.sim.affine import affine_horizon
from tanksynth.sim.integrate import Integrator, input_limits, param_arrays
from tanksynth.sim.simulate import EstimatorAdapter, InputSequence, simulate

TANK = three_tank()
X0 = np.array([0.30, 0.20, 0.25])
U0 = equilibrium_input(TANK, X0).u0


class _Feedback:
    """``u_k = b_k - K (x_k - x0)`` offering the affine description."""

    def __init__(self, b, K, x0):
        self.b, self.K, self.x0, self.k = b, K, x0, 0

    def reset(self, runs):
        self.k = 0

    def __call__(self, x_hat, reference, t):
        u = self.b[self.k] - (x_hat - self.x0) @ self.K.T
        self.k += 1
        return u

    def affine(self, steps, ts):
        return self.b[:steps], self.K, self.x0


class _Plain(_Feedback):
    """The same law without the description: the loop route."""

    affine = None


def _gain():
    return 200.0 * linearize(TANK, X0, U0).B.T      # u = u0 - 200 B' (x - x0): damping feedback


@pytest.mark.parametrize("runs", [1, 3])
def test_affine_route_equals_the_loop(runs):
    K = _gain()
    N = 300
    b = np.tile(U0, (N, 1))
    b[100:200] += 0.3 * U0                       # a step of the feed-forward, saturating at times
    starts = X0 + np.linspace(-0.03, 0.03, runs)[:, None]
    fast = simulate(TANK, ts=2.0, steps=N, x0=starts, seeds=np.arange(runs),
                    controller=_Feedback(b, K, X0), u_init=U0)
    slow = simulate(TANK, ts=2.0, steps=N, x0=starts, seeds=np.arange(runs),
                    controller=_Plain(b, K, X0), u_init=U0)
    assert "casadi" in fast.backend
    scale = np.max(np.abs(slow.x))
    # the law's product may be summed in another order (BLAS): rounding only
    assert np.max(np.abs(fast.x - slow.x)) <= 1e-13 * scale
    assert np.max(np.abs(fast.u - slow.u)) <= 1e-13 * np.max(np.abs(slow.u))
    assert np.array_equal(fast.x, fast.x_hat) and fast.y.shape == slow.y.shape
    assert np.max(np.abs(fast.y - slow.y)) <= 1e-13 * scale
    assert (fast.clipped_low, fast.clipped_high) == (slow.clipped_low, slow.clipped_high)
    lo, hi = input_limits(TANK, param_arrays(TANK, None, runs), runs)
    assert np.all(fast.u >= lo[:, None, :]) and np.all(fast.u <= hi[:, None, :])
    assert np.any(fast.u == hi[:, None, :])     # the saturation was active: tested, not vacuous


def test_affine_route_declines_a_hybrid_crossing():
    """A run that changes hybrid mode in a period sends the caller back to the loop (None)."""
    plant = hybrid_three_tank()
    integ = Integrator.for_plant(plant)
    params = param_arrays(plant, None, 1)
    lo, hi = input_limits(plant, params, 1)
    x = np.array([[0.25, 0.25, 0.2]])
    b = np.tile([110 * LPH, 100 * LPH], (600, 1))
    assert affine_horizon(integ, x, b, np.zeros((2, 3)), x[0], params, lo, hi, 1.0, 2) is None
    assert integ.clipped_low == 0 and not integ.backends
    # the simulation itself still runs (the loop locates the crossings)
    res = simulate(plant, ts=1.0, steps=600, x0=x[0], seeds=[0], u_init=b[0],
                   controller=_Feedback(b, np.zeros((2, 3)), x[0]), substeps=2)
    assert res.events == 3


def test_affine_route_declining_after_a_chunk_leaves_the_start_state():
    """A crossing after the first chunk: the loop that takes over starts from the given x0.

    Regression: the route advanced the caller's state array in place chunk by chunk, so the
    fallback loop started from the state at the end of the last chunk without a crossing.
    """
    plant = hybrid_three_tank()
    integ = Integrator.for_plant(plant)
    params = param_arrays(plant, None, 1)
    lo, hi = input_limits(plant, params, 1)
    K = 1e-2 * np.ones((2, 3))                  # far below x_ref: the pumps saturate high
    xop = np.array([0.31918677, 0.3209075, 0.30968861])
    b = np.tile([100 * LPH, 100 * LPH], (200, 1))
    x = np.zeros((1, 3))
    assert affine_horizon(integ, x, b, K, xop, params, lo, hi, 1.0, 4) is None
    assert np.array_equal(x, np.zeros((1, 3)))
    x0 = np.zeros(3)
    fast = simulate(plant, ts=1.0, steps=200, x0=x0, seeds=[0], controller=_Feedback(b, K, xop))
    slow = simulate(plant, ts=1.0, steps=200, x0=x0, seeds=[0], controller=_Plain(b, K, xop))
    assert np.array_equal(fast.x[:, 0], np.zeros((1, 3)))
    assert fast.events > 0                      # crossings: the loop did take over
    assert np.max(np.abs(fast.x - slow.x)) <= 1e-13 * np.max(np.abs(slow.x))


@pytest.mark.parametrize("backend", ["auto", "numpy"])
def test_estimator_does_not_change_a_plant_with_known_inputs(backend, monkeypatch):
    """Held input or input sequence with an observer: plant first, then the observer; the same
    numbers bit for bit as the loop (a plain callable replaying the sequence). ``numpy``: no
    compiled kernel, the open loop goes through `affine_horizon` with K = 0."""
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", backend)
    L = 0.02 * np.eye(3)[:, : TANK.q]
    tuning = LuenbergerTuning(L=L, x0=X0, ts=2.0, operating_point=(X0, U0), form="predictor")
    est = lambda: EstimatorAdapter(LuenbergerObserver(TANK, tuning))  # noqa: E731
    N = 200
    seq = np.tile(U0, (N, 1))
    seq[50:] *= 1.2
    start = X0 + 0.01
    for controller, plain in ((None, lambda xh, r, t: np.tile(U0, (xh.shape[0], 1))),
                              (InputSequence(seq), _Plain(seq, np.zeros((TANK.m, 3)), X0))):
        fast = simulate(TANK, ts=2.0, steps=N, x0=start, seeds=[0], u_init=U0,
                        controller=controller, estimator=est(), x_hat0=X0)
        slow = simulate(TANK, ts=2.0, steps=N, x0=start, seeds=[0], u_init=U0,
                        controller=plain, estimator=est(), x_hat0=X0)
        for name in ("x", "y", "u", "x_hat"):
            assert np.array_equal(getattr(fast, name), getattr(slow, name)), name
        assert not np.array_equal(fast.x_hat, fast.x)      # the observer ran


@pytest.mark.parametrize("name, samples", [("delta_bar", (0,)), ("delta_bar", (70,)),
                                           ("delta_bar", (70, 140)), ("psi3", (200,))])
def test_parameter_changes_with_known_inputs_equal_the_loop(name, samples, monkeypatch):
    """Faults (parameter changes) with a held input: stretch by stretch, the loop's numbers
    (a change at the last sample changes only its measurement, y = x3 / psi3)."""
    from tanksynth.plants import hydraulic_fault
    from tanksynth.sim.simulate import ParameterChange

    plant = hydraulic_fault()
    base = {p.name: p.value for p in plant.parameters}[name]
    x0, u0 = np.array([4.0, 4.0 / 3.0, 4.0]), np.array([2.0])       # the healthy equilibrium
    changes = [ParameterChange(k, {name: np.array([base, base + 0.2 * (1 + i)])})
               for i, k in enumerate(samples)]
    common = dict(ts=1.0, steps=200, x0=np.tile(x0, (2, 1)), seeds=[0, 1], u_init=u0,
                  changes=changes)
    module = sys.modules["tanksynth.sim.simulate"]
    used = []
    route = module._open_loop_changes
    monkeypatch.setattr(module, "_open_loop_changes", lambda *a: used.append(route(*a)) or used[-1])
    fast = simulate(plant, **common)
    assert len(used) == 1 and used[0] is not None                # the stretch route ran
    slow = simulate(plant, controller=lambda xh, r, t: np.tile(u0, (xh.shape[0], 1)), **common)
    for field in ("x", "y", "u", "modes"):
        assert np.array_equal(getattr(fast, field), getattr(slow, field)), field
    assert (fast.clipped_low, fast.clipped_high, fast.events) == \
        (slow.clipped_low, slow.clipped_high, slow.events)
    k = min(samples)
    assert np.array_equal(fast.y[0, :k], fast.y[1, :k])           # before the change: the same
    assert not np.array_equal(fast.y[0, k:], fast.y[1, k:])       # from it on: the fault shows


@pytest.mark.parametrize("what", ["x0", "gain", "parameter", "feedforward"])
def test_affine_route_sends_non_finite_data_to_the_loop(what):
    """NaN must not be laundered by the CasADi saturation/clipping (fmin/fmax return the other
    operand): the route declines and the loop reports the non-finite state (or, for a NaN law, the
    non-finite input it computes), as without the route.

    Regression: a NaN start, gain, parameter or feed-forward gave a finite trajectory (NaN turned
    into an input or state bound) where the loop raised `SimulationError`.
    """
    from tanksynth.errors import SimulationError

    N = 100
    K = np.ones((TANK.m, 3)) if what != "gain" else np.full((TANK.m, 3), np.inf)
    b = np.tile(U0, (N, 1))
    if what == "feedforward":
        b[:] = np.nan
    start = np.array([np.nan, 0.2, 0.25]) if what == "x0" else X0 + 0.01
    params = {TANK.parameters[1].name: np.nan} if what == "parameter" else None
    integ = Integrator.for_plant(TANK)
    p = param_arrays(TANK, params, 1)
    lo, hi = input_limits(TANK, p, 1)
    assert affine_horizon(integ, integ.clip(start[None]), b, K, X0, p, lo, hi, 2.0, 4) is None
    for law in (_Feedback(b, K, X0), _Plain(b, K, X0)):
        with pytest.raises(SimulationError, match="non-finite (state|input)"):
            simulate(TANK, ts=2.0, steps=N, x0=start, seeds=[0], controller=law, parameters=params)


@pytest.mark.parametrize("backend", ["auto", "numpy"])
def test_open_loop_with_a_non_finite_start_raises(backend, monkeypatch):
    """Known inputs and a NaN start: the loop's error, on either backend (not a result with NaN
    at sample 0 and finite states after, the NaN clipped away by the CasADi route)."""
    from tanksynth.errors import SimulationError

    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", backend)
    with pytest.raises(SimulationError, match="sample 0"):
        simulate(TANK, ts=2.0, steps=50, x0=[np.nan, 0.2, 0.25], seeds=[0], u_init=U0)


@pytest.mark.parametrize("route", ["advance", "horizon"])
def test_casadi_routes_do_not_clip_a_nan_parameter_away(route, monkeypatch):
    """Without a native kernel, a NaN parameter propagates as in the numpy code (the CasADi
    clipping's fmax would make the state a bound: a finite trajectory).

    Regression: the loop's CasADi period route gave finite states of 0 for a NaN parameter.
    """
    monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", "numpy")             # no native kernel
    integ = Integrator.for_plant(TANK)
    p = param_arrays(TANK, {TANK.parameters[1].name: np.nan}, 1)
    x = integ.clip((X0 + 0.01)[None])
    if route == "advance":
        assert not np.isfinite(integ.advance(x, U0[None], p, 2.0, 4)).all()
        assert "casadi" not in integ.backends
    else:
        assert integ.horizon(x, np.tile(U0, (5, 1, 1)), p, 2.0, 4) is None
