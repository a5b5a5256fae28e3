"""Classical linear analysis of a designed loop: stability margins, step and frequency responses.

The loop is ``L(s) = C_out (sI - A)^{-1} B_in`` broken at its ``m`` channels
(``z`` and the sampling time ``ts`` replace ``s`` for a discrete design):

* state feedback ``u = -K x`` (also an integral servo on its augmented model):
  broken at the plant input, ``L(s) = K (sI - A)^{-1} B`` (`input_loop`);
* an observer with output injection ``L (y - C x_hat)``: broken at the
  injected output, ``L_o(s) = C (sI - A)^{-1} L`` (`output_injection_loop`), whose
  closed loop ``A - L C`` is the error dynamics.

`loop_margins` gives, per channel with the other channels closed, the gain
margin, phase margin and delay margin (python-control's `stability_margins`
on the single-channel loop), and for the whole loop the smallest singular
value of the return difference ``I + L`` over frequency (``1/||S||_inf``,
computed exactly with `tanksynth.analysis.statespace.hinf_norm`) with the
simultaneous gain and phase variations it guarantees in every channel.
`closed_loop_step` and `loop_frequency_response` give the curves a report
draws. Arrays in, frozen dataclasses out; nothing here reads a file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import warnings

import numpy as np
from scipy.linalg import block_diag

from tanksynth.analysis.statespace import hinf_norm
from tanksynth.errors import DimensionError

__all__ = ["ChannelMargins", "LoopMargins", "FrequencyResponse", "StepResponse", "input_loop",
           "output_injection_loop", "loop_margins", "loop_frequency_response", "closed_loop_step",
           "frequency_grid"]

#: Relative width of the H-infinity bracket: a return difference this close to 1 counts as 1
#: (the loop then tolerates any gain increase).
_UNIT_TOLERANCE = 1e-6


@dataclass(frozen=True)
class ChannelMargins:
    """Margins of one channel of a loop, the other channels closed.

    Attributes
    ----------
    channel : int
        Channel index (0-based).
    gain_margin : float
        Factor by which the channel's loop gain may grow (or shrink, when below 1) before
        instability (dimensionless; ``inf`` when the phase never crosses -180 deg).
    gain_margin_db : float
        The same in dB.
    phase_margin_deg : float
        Phase margin (deg; ``inf`` when ``|L|`` never crosses 1).
    delay_margin_s : float
        Smallest added input delay that destabilises the loop, the minimum over
        every gain crossover of ``phase margin / crossover frequency`` (s; ``inf``
        without a crossover, 0 when a phase margin is negative).
    gain_crossover : float
        Frequency where ``|L| = 1`` of the phase margin (rad/s; nan if none).
    phase_crossover : float
        Frequency where the phase is -180 deg of the gain margin (rad/s; nan if none).
    """

    channel: int
    gain_margin: float
    gain_margin_db: float
    phase_margin_deg: float
    delay_margin_s: float
    gain_crossover: float
    phase_crossover: float


@dataclass(frozen=True)
class LoopMargins:
    """Stability margins of a loop ``L = C_out (sI - A)^{-1} B_in`` broken at its channels.

    Attributes
    ----------
    ts : float or None
        Sampling time (s) of a discrete loop; None in continuous time.
    closed_loop_stable : bool
        ``A - B_in C_out`` is Hurwitz (continuous) or Schur (discrete).
    channels : tuple of ChannelMargins
        One per channel, the other channels closed.
    min_return_difference : float
        ``min over w of sigma_min(I + L(jw))`` = ``1 / ||(I + L)^{-1}||_inf``
        (dimensionless; 0 when the closed loop is unstable).
    guaranteed_gain : tuple of float
        Simultaneous, independent gain factors (dimensionless) in every channel that keep the loop stable,
        ``(1 / (1 + r), 1 / (1 - r))`` with ``r = min_return_difference`` (``inf`` upper end
        when ``r >= 1``).
    guaranteed_phase_deg : float
        Simultaneous phase variation in every channel that keeps the loop stable,
        ``2 arcsin(r / 2)`` (deg).
    """

    ts: float | None
    closed_loop_stable: bool
    channels: tuple[ChannelMargins, ...]
    min_return_difference: float
    guaranteed_gain: tuple[float, float]
    guaranteed_phase_deg: float

    @property
    def delay_margin_samples(self) -> tuple[float, ...]:
        """Each channel's delay margin in sampling periods (discrete loops; empty otherwise)."""
        if self.ts is None:
            return ()
        return tuple(c.delay_margin_s / self.ts for c in self.channels)


@dataclass(frozen=True)
class FrequencyResponse:
    """Largest singular values of ``L``, ``S = (I + L)^{-1}`` and ``T = L (I + L)^{-1}``.

    Attributes
    ----------
    omega : ndarray, shape (N,)
        Frequencies (rad/s; up to the Nyquist frequency ``pi / ts`` of a discrete loop).
    loop, sensitivity, complementary : ndarray, shape (N,)
        ``sigma_max`` of ``L``, ``S`` and ``T`` at each frequency (dimensionless when the
        loop is broken where it is closed: ``L`` maps a channel to the same channel).
    """

    omega: np.ndarray
    loop: np.ndarray
    sensitivity: np.ndarray
    complementary: np.ndarray


@dataclass(frozen=True)
class StepResponse:
    """Step responses of a linear closed loop, one step per input.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Time (s).
    outputs : ndarray, shape (p, m, N)
        Output ``i`` for a unit step on input ``j`` (output unit per input unit).
    """

    time: np.ndarray
    outputs: np.ndarray


def _arrays(A: Any, B: Any, C: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    A, B, C = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (A, B, C))
    n = A.shape[0]
    if A.shape != (n, n) or B.shape[0] != n or C.shape[1] != n:
        raise DimensionError(f"loop matrices do not fit: A {A.shape}, B {B.shape}, C {C.shape} "
                             "(expected A n x n, B n x m, C p x n)")
    return A, B, C


def _loop(A: Any, B_in: Any, C_out: Any, ts: float | None) -> Any:
    import control
    A, B, C = _arrays(A, B_in, C_out)
    if C.shape[0] != B.shape[1]:
        raise DimensionError(f"a loop maps its {B.shape[1]} channel(s) back to themselves: C_out has "
                             f"{C.shape[0]} rows (expected {B.shape[1]})")
    return control.ss(A, B, C, np.zeros((C.shape[0], B.shape[1])), 0 if ts is None else float(ts))


def input_loop(A: Any, B: Any, K: Any, ts: float | None = None) -> Any:
    """The state-feedback loop broken at the plant input, ``L(s) = K (sI - A)^{-1} B``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (1/s; dimensionless in discrete time).
    B : array_like, shape (n, m)
        Input matrix (state unit per input unit, per second in continuous time).
    K : array_like, shape (m, n)
        Gain of ``u = -K x`` (input unit per state unit).
    ts : float, optional
        Sampling time (s) of a discrete design (``z`` replaces ``s``).

    Returns
    -------
    control.StateSpace
        ``L`` with ``m`` inputs and outputs.
    """
    return _loop(A, B, K, ts)


def output_injection_loop(A: Any, L: Any, C: Any, ts: float | None = None) -> Any:
    """An observer's output-injection loop broken at the output, ``L_o(s) = C (sI - A)^{-1} L``.

    Its closed loop ``A - L C`` is the observer's error dynamics.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (1/s; dimensionless in discrete time).
    L : array_like, shape (n, p)
        Observer gain (state unit per output unit, per second in continuous time).
    C : array_like, shape (p, n)
        Output matrix (output unit per state unit).
    ts : float, optional
        Sampling time (s) of a discrete design.

    Returns
    -------
    control.StateSpace
        ``L_o`` with ``p`` inputs and outputs.
    """
    return _loop(A, L, C, ts)


def _is_stable(M: np.ndarray, ts: float | None) -> bool:
    eig = np.linalg.eigvals(M) if M.size else np.zeros(0)
    return bool(np.all(np.abs(eig) < 1.0) if ts is not None else np.all(eig.real < 0.0))


def _channel(A: np.ndarray, B: np.ndarray, C: np.ndarray, i: int, ts: float | None,
             points: int) -> ChannelMargins:
    """Margins of channel ``i`` with the others closed (``A - B_j C_j`` for every j != i).

    python-control's `stability_margins` on the channel's exact frequency response (state-space
    evaluation on a dense grid, its ``frd`` method): its polynomial method loses the crossovers of
    a discrete loop whose poles cluster near ``z = 1`` (slow tanks sampled fast).
    """
    import control
    others = [j for j in range(B.shape[1]) if j != i]
    Ai = A - B[:, others] @ C[others, :]
    sys = control.ss(Ai, B[:, [i]], C[[i], :], [[0.0]], 0 if ts is None else float(ts))
    omega = frequency_grid(block_diag(Ai, Ai - B[:, [i]] @ C[[i], :]), ts, points)
    if ts is not None:
        omega = omega[omega < np.pi / float(ts)]
    data = control.frd(sys, omega, smooth=True)
    with warnings.catch_warnings(), np.errstate(divide="ignore", invalid="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        gms, pms, _, wpcs, wgcs, _ = control.stability_margins(data, returnall=True, method="frd")
    gms, pms, wpcs, wgcs = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (gms, pms, wpcs, wgcs))
    # python-control's choice without returnall: the gain margin nearest 1 (in log), the smallest |pm|
    gm, wpc, pm, wgc = float("inf"), float("nan"), float("inf"), float("nan")
    if gms.size:
        j = int(np.argmin(np.abs(np.log(gms))))
        gm, wpc = float(gms[j]), float(wpcs[j])
    if pms.size:
        j = int(np.argmin(np.abs(pms)))
        pm, wgc = float(pms[j]), float(wgcs[j])
    # every gain crossover: the delay margin is the smallest phase margin / crossover frequency
    if ts is not None:     # the grid stops short of the Nyquist frequency, where L(-1) may be real
        nyquist = complex(np.squeeze(sys(-1.0)))
        if nyquist.real < 0 and abs(nyquist.imag) <= 1e-9 * abs(nyquist):
            at_nyquist = -1.0 / nyquist.real
            if not np.isfinite(gm) or abs(np.log(at_nyquist)) < abs(np.log(gm)):
                gm, wpc = at_nyquist, np.pi / float(ts)
    delays = []
    for p, w in zip(np.atleast_1d(pms), np.atleast_1d(wgcs)):
        if np.isfinite(p) and np.isfinite(w) and w > 0:
            delays.append(0.0 if p < 0 else np.deg2rad(float(p)) / float(w))
    delay = min(delays) if delays else float("inf")
    gm_db = 20.0 * np.log10(gm) if np.isfinite(gm) and gm > 0 else float("inf")
    return ChannelMargins(i, gm, float(gm_db), pm, float(delay), wgc, wpc)


def loop_margins(A: Any, B_in: Any, C_out: Any, ts: float | None = None, points: int = 800) -> LoopMargins:
    """Margins of ``L = C_out (sI - A)^{-1} B_in`` broken at its channels (negative feedback).

    For state feedback pass ``(A, B, K)`` (`input_loop`), for an observer
    ``(A, L, C)`` (`output_injection_loop`).

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (1/s; dimensionless in discrete time).
    B_in : array_like, shape (n, m)
        Where the loop enters the states.
    C_out : array_like, shape (m, n)
        What the loop feeds back.
    ts : float, optional
        Sampling time (s) of a discrete loop; None in continuous time.
    points : int, optional
        Frequencies of each channel's response (`frequency_grid`), between which
        python-control interpolates its crossovers.

    Returns
    -------
    LoopMargins

    Raises
    ------
    DimensionError
        The matrices do not make a square loop.
    """
    A, B, C = _arrays(A, B_in, C_out)
    _loop(A, B, C, ts)       # shape checks
    m = B.shape[1]
    Acl = A - B @ C
    stable = _is_stable(Acl, ts)
    channels = tuple(_channel(A, B, C, i, ts, points) for i in range(m))
    # S = (I + L)^{-1} = I - C (sI - A + B C)^{-1} B: ||S||_inf = 1 / min sigma(I + L)
    s_norm = hinf_norm(Acl, B, -C, np.eye(m), dt=ts) if stable else float("inf")
    r = 1.0 / s_norm if np.isfinite(s_norm) and s_norm > 0 else 0.0
    upper = 1.0 / (1.0 - r) if r < 1.0 - _UNIT_TOLERANCE else float("inf")
    phase = float(np.rad2deg(2.0 * np.arcsin(min(r, 1.0 + _UNIT_TOLERANCE) / 2.0)))
    return LoopMargins(None if ts is None else float(ts), stable, channels, float(r),
                       (1.0 / (1.0 + r), float(upper)), phase)


def frequency_grid(A: Any, ts: float | None = None, points: int = 400) -> np.ndarray:
    """Log-spaced frequencies two decades either side of the modes of ``A`` (rad/s).

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (1/s; dimensionless in discrete time, whose modes count as
        ``|log z| / ts``).
    ts : float, optional
        Sampling time (s); the grid then ends at the Nyquist frequency ``pi / ts``.
    points : int, optional
        Number of frequencies.
    """
    eig = np.linalg.eigvals(np.atleast_2d(np.asarray(A, dtype=float)))
    if ts is not None:
        eig = np.log(eig[np.abs(eig) > 0].astype(complex)) / float(ts)
    speeds = np.abs(eig[np.abs(eig) > 1e-12])
    lo = float(speeds.min()) / 100.0 if speeds.size else 1e-3
    hi = float(speeds.max()) * 100.0 if speeds.size else 1e3
    if ts is not None:
        hi = np.pi / float(ts)
        lo = min(lo, hi / 1e4)
    return np.logspace(np.log10(lo), np.log10(hi), int(points))


def loop_frequency_response(A: Any, B_in: Any, C_out: Any, ts: float | None = None,
                            points: int = 400) -> FrequencyResponse:
    """``sigma_max`` of ``L``, ``S`` and ``T`` on `frequency_grid` (Bode magnitude, MIMO).

    Parameters
    ----------
    A, B_in, C_out : array_like
        The loop, as in `loop_margins`.
    ts : float, optional
        Sampling time (s) of a discrete loop.
    points : int, optional
        Number of frequencies.

    Returns
    -------
    FrequencyResponse
    """
    A, B, C = _arrays(A, B_in, C_out)
    sys = _loop(A, B, C, ts)
    omega = frequency_grid(block_diag(A, A - B @ C), ts, points)   # open- and closed-loop modes
    points_s = 1j * omega if ts is None else np.exp(1j * omega * float(ts))
    resp = np.asarray(sys(points_s, squeeze=False)).reshape(C.shape[0], B.shape[1], -1)
    eye = np.eye(B.shape[1])
    sl, ss_, st = (np.empty(omega.size) for _ in range(3))
    for k in range(omega.size):
        Lk = resp[:, :, k]
        S = np.linalg.inv(eye + Lk)
        sl[k] = np.linalg.norm(Lk, 2)
        ss_[k] = np.linalg.norm(S, 2)
        st[k] = np.linalg.norm(Lk @ S, 2)
    return FrequencyResponse(omega, sl, ss_, st)


def closed_loop_step(A: Any, B: Any, C: Any, ts: float | None = None, points: int = 400) -> StepResponse:
    """Unit-step responses of the linear system ``(A, B, C)`` over eight of its slowest time constants.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Closed-loop state matrix (1/s; dimensionless in discrete time).
    B : array_like, shape (n, m)
        Where the step enters.
    C : array_like, shape (p, n)
        What is observed.
    ts : float, optional
        Sampling time (s) of a discrete system (the response is then sampled at ``ts``).
    points : int, optional
        Number of samples of a continuous response (a discrete one has at most 10000).

    Returns
    -------
    StepResponse
    """
    import control
    A, B, C = _arrays(A, B, C)
    eig = np.linalg.eigvals(A)
    rates = -eig.real if ts is None else -np.log(np.maximum(np.abs(eig), 1e-300)) / float(ts)
    slowest = float(np.min(rates)) if rates.size else 1.0
    horizon = 8.0 / slowest if slowest > 0 else 10.0 * (ts or 1.0)
    t = (np.linspace(0.0, horizon, int(points)) if ts is None
         else np.arange(0, min(int(np.ceil(horizon / ts)), 10000) + 1) * float(ts))
    sys = control.ss(A, B, C, np.zeros((C.shape[0], B.shape[1])), 0 if ts is None else float(ts))
    res = control.step_response(sys, T=t)
    y = np.asarray(res.outputs).reshape(C.shape[0], B.shape[1], -1)
    return StepResponse(np.asarray(res.time, dtype=float), y)
