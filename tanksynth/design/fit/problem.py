"""The estimation data and residuals: experiments mapped onto the plant, single- and multiple-shooting.

`FitData` is one experiment in the plant's order (inputs reordered, output columns mapped to
the plant's outputs, masks of exact / censored / missing samples). `Intervals` builds, on a
`FitModel`, the residual vector of all experiments (exact samples ``yhat - y``, censored
samples the hinge ``min(yhat - hi, 0)`` / ``max(yhat - lo, 0)``, missing ones left out), each
output divided by its noise level, from one CasADi function per shooting interval, in two
forms: the multiple-shooting map of the NLP (``theta``, node states -> ``r``, continuity
gaps) and the single-shooting chain ``(theta, x0) -> r`` (statistics, validation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import casadi as ca
import numpy as np

from tanksynth.design.fit.model import FitModel
from tanksynth.errors import SpecError
from tanksynth.measurements.experiment import Experiment
from tanksynth.plants.base import Plant

__all__ = ["FitData", "fit_data", "Intervals", "nodes", "noise_guess"]


@dataclass(frozen=True)
class FitData:
    """One experiment in the plant's order.

    Attributes
    ----------
    name : str
        The experiment's name.
    t : ndarray, shape (N,)
        Sample times (s).
    dt : ndarray, shape (N - 1,)
        Sampling intervals (s).
    u : ndarray, shape (N, m)
        Inputs in the plant's input order (input units).
    y : ndarray, shape (N, p)
        Measured output columns (output units; NaN where missing).
    columns : tuple of int
        Plant output index of each column of ``y``.
    output_names : tuple of str
        Plant output name of each column.
    exact, low, high : ndarray of bool, shape (N, p)
        Exact samples; samples censored at the lower / upper limit.
    limits : ndarray, shape (p, 2)
        Sensor range per column (output units).
    """

    name: str
    t: np.ndarray
    dt: np.ndarray
    u: np.ndarray
    y: np.ndarray
    columns: tuple[int, ...]
    output_names: tuple[str, ...]
    exact: np.ndarray
    low: np.ndarray
    high: np.ndarray
    limits: np.ndarray

    @property
    def samples(self) -> int:
        """Number of samples N."""
        return int(self.t.shape[0])


def fit_data(plant: Plant, experiment: Experiment) -> FitData:
    """Map an experiment onto the plant's inputs and outputs.

    Parameters
    ----------
    plant : Plant
        The plant.
    experiment : Experiment
        One logged run (plant names and units).

    Returns
    -------
    FitData

    Raises
    ------
    SpecError
        An input of the plant missing, an output name unknown, fewer than 2 samples, times
        not strictly increasing, non-finite inputs (naming the experiment's source).
    """
    src = experiment.source or experiment.name
    inputs = [q.name for q in plant.inputs]
    outputs = [q.name for q in plant.outputs]
    missing = [nm for nm in inputs if nm not in experiment.input_names]
    if missing:
        raise SpecError(f"experiment {experiment.name}: input {missing[0]!r} of plant "
                        f"'{plant.name}' is not in the data", source=src)
    for nm in experiment.output_names:
        if nm not in outputs:
            raise SpecError(f"experiment {experiment.name}: column {nm!r} is not an output of plant "
                            f"'{plant.name}' (outputs: {', '.join(outputs)})", source=src)
    t = np.asarray(experiment.t, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
        raise SpecError(f"experiment {experiment.name}: time must have >= 2 finite, strictly "
                        "increasing samples", source=src)
    u_all = np.asarray(experiment.u, dtype=float).reshape(t.size, -1)
    u = u_all[:, [experiment.input_names.index(nm) for nm in inputs]] if inputs else np.zeros((t.size, 0))
    if not np.all(np.isfinite(u)):
        row = int(np.flatnonzero(~np.all(np.isfinite(u), axis=1))[0])
        raise SpecError(f"experiment {experiment.name}: non-finite input at row {row}", source=src)
    y = np.asarray(experiment.y, dtype=float).reshape(t.size, -1)
    low = np.asarray(experiment.censored_low, dtype=bool).reshape(y.shape)
    high = np.asarray(experiment.censored_high, dtype=bool).reshape(y.shape)
    present = ~np.isnan(y)
    return FitData(experiment.name, t, np.diff(t), u, y,
                   tuple(outputs.index(nm) for nm in experiment.output_names),
                   tuple(experiment.output_names), present & ~low & ~high, present & low & ~high,
                   present & high, np.array(experiment.limits, dtype=float).reshape(-1, 2))


def _censor_level(data: FitData, j: int, upper: bool) -> np.ndarray:
    """The limit a censored sample of column ``j`` stands for (the declared limit, else the value)."""
    lim = data.limits[j, 1 if upper else 0]
    return np.where(np.isfinite(lim), lim, data.y[:, j])


def nodes(samples: int, length: int) -> int:
    """Number of shooting intervals of an experiment: ``ceil(N / L)`` (nodes at 0, L, 2L, ...).

    Parameters
    ----------
    samples : int
        Samples N (>= 2).
    length : int
        Samples per shooting interval L (>= 1).
    """
    return -(-int(samples) // int(length))


class Intervals:
    """The fit problem cut into shooting intervals of ``L`` samples, all experiments at once.

    One CasADi SX function integrates one interval from its node state: at each of its ``L``
    samples the model's outputs and the weighted residuals, then one step to the next
    sample; it returns the state after the last step (the next node's, a continuity gap in
    the NLP). Intervals are padded to ``L`` samples (``dt = 0``, nothing measured). Residual
    of output ``i`` at a sample: ``w_i (a (yhat - y) + b min(yhat - z, 0) + c max(yhat - z, 0))``
    with ``a``, ``b``, ``c`` the exact / censored-high / censored-low flags and ``z`` the
    sensor limit; 0 at a missing sample.

    Parameters
    ----------
    model : FitModel
        The sampled model.
    data : sequence of FitData
        The experiments.
    length : int
        Samples per interval L.

    Attributes
    ----------
    outputs : tuple of str
        Plant output names (rows of the residuals, ``q``).
    counts : ndarray of int, shape (q,)
        Exact samples per output.
    intervals : list of int
        Intervals per experiment.
    function : casadi.Function
        ``(s, U, DT, theta, Y, A, B, C, Z, w) -> (x_end, r, yhat)`` of one interval.
    """

    def __init__(self, model: FitModel, data: Sequence[FitData], length: int):
        self.model = model
        self.data = tuple(data)
        self.length = L = int(length)
        n, m, q, k = model.n, model.m, model.q, len(model.names)
        s, U, DT = ca.SX.sym("s", n), ca.SX.sym("U", m, L), ca.SX.sym("DT", 1, L)
        th, w = ca.SX.sym("theta", k), ca.SX.sym("w", q)
        Y, A, B, C, Z = (ca.SX.sym(nm, q, L) for nm in "YABCZ")
        x = s
        rs, ys = [], []
        for i in range(L):
            yh = model.output(x, th)
            r = (A[:, i] * (yh - Y[:, i]) + B[:, i] * ca.fmin(yh - Z[:, i], 0)
                 + C[:, i] * ca.fmax(yh - Z[:, i], 0))
            rs.append(w * r)
            ys.append(yh)
            x = model.step(x, U[:, i], DT[0, i], th)
        self.function = ca.Function("interval", [s, U, DT, th, Y, A, B, C, Z, w],
                                    [x, ca.vertcat(*rs), ca.horzcat(*ys)])
        # the same interval in the NLP's scaled parameters, with its block Jacobians
        # d(x_end, r)/d(s, sc), theta = lower + width * sc (forward AD in SX, k + n directions)
        sc, lo, wd = ca.SX.sym("sc", k), ca.SX.sym("lo", k), ca.SX.sym("wd", k)
        x_end, r_all, _ = self.function(s, U, DT, lo + wd * sc, Y, A, B, C, Z, w)
        zj = ca.vertcat(s, sc)
        self.blocks = ca.Function("interval_blocks", [s, U, DT, sc, lo, wd, Y, A, B, C, Z, w],
                                  [x_end, r_all, ca.jacobian(x_end, zj), ca.jacobian(r_all, zj)])
        self.outputs = tuple(o for o in model.output_names)
        self.intervals = [nodes(d.samples, L) for d in self.data]
        self.packed = [self._pack(d, J) for d, J in zip(self.data, self.intervals)]
        self.counts = np.array([int(sum(p["A"][i].sum() for p in self.packed)) for i in range(q)])
        self._accum: dict[int, ca.Function] = {}

    def _pack(self, d: FitData, J: int) -> dict[str, np.ndarray]:
        """The data of ``d`` laid out by interval: (rows, J L), padded."""
        q, L, N = self.model.q, self.length, d.samples
        width = J * L
        U = np.zeros((self.model.m, width))
        U[:, :N] = d.u.T
        U[:, N:] = d.u[-1][:, None]
        DT = np.zeros((1, width))
        DT[0, :N - 1] = d.dt
        Y, A, B, C, Z = (np.zeros((q, width)) for _ in range(5))
        for j, col in enumerate(d.columns):
            A[col, :N] = d.exact[:, j]
            B[col, :N] = d.high[:, j]
            C[col, :N] = d.low[:, j]
            Y[col, :N] = np.where(d.exact[:, j], d.y[:, j], 0.0)
            Z[col, :N] = np.where(d.high[:, j], _censor_level(d, j, True),
                                  np.where(d.low[:, j], _censor_level(d, j, False), 0.0))
        return {"U": U, "DT": DT, "Y": Y, "A": A, "B": B, "C": C, "Z": Z}

    def nlp(self, theta: Any, S: Sequence[Any], w: Any) -> tuple[Any, Any]:
        """Weighted residuals and continuity gaps of all experiments (multiple shooting).

        Parameters
        ----------
        theta : casadi.MX, shape (k, 1) or (k, M)
            Free parameter values, or one copy per interval (``M`` intervals of all
            experiments, in order: the lifted form, whose derivatives stay block-sparse).
        S : sequence of casadi.MX, shape (n, J_e)
            Node states of each experiment.
        w : casadi.MX, shape (q, 1)
            ``1 / sigma`` per output.

        Returns
        -------
        r : casadi.MX
            Residual vector.
        gaps : casadi.MX
            ``x_end(node j) - node j+1`` of every experiment.
        """
        M = sum(self.intervals)
        fn = self.function.map(M, "thread", 2)
        cat = lambda key: np.hstack([p[key] for p in self.packed])  # noqa: E731
        th = theta if theta.shape[1] == M else ca.repmat(theta, 1, M)
        x_end, r, _ = fn(ca.horzcat(*S), cat("U"), cat("DT"), th, cat("Y"),
                         cat("A"), cat("B"), cat("C"), cat("Z"), ca.repmat(w, 1, M))
        gaps, pos = [], 0
        for Se, J in zip(S, self.intervals):
            if J > 1:
                gaps.append(ca.vec(x_end[:, pos:pos + J - 1] - Se[:, 1:]))
            pos += J
        return ca.vec(r), (ca.vertcat(*gaps) if gaps else ca.MX(0, 1))

    def single(self, e: int, x0: Any, theta: Any, w: Any) -> tuple[Any, Any]:
        """Weighted residuals (vector) and outputs (q, N) of experiment ``e`` from ``x0``.

        Parameters
        ----------
        e : int
            Experiment index.
        x0 : casadi.MX, shape (n, 1)
            Initial state.
        theta : casadi.MX, shape (k, 1)
            Free parameter values.
        w : casadi.MX, shape (q, 1)
            ``1 / sigma`` per output.
        """
        J = self.intervals[e]
        if J not in self._accum:
            self._accum[J] = self.function.mapaccum(f"acc{J}", J)
        p = self.packed[e]
        _, r, Y = self._accum[J](x0, p["U"], p["DT"], ca.repmat(theta, 1, J), p["Y"], p["A"],
                                 p["B"], p["C"], p["Z"], ca.repmat(w, 1, J))
        # mapaccum returns the states after each interval; the residuals and outputs per interval
        return ca.vec(r), Y[:, :self.data[e].samples]

    def flags(self, e: int) -> np.ndarray:
        """Entries of the residual vector of experiment ``e`` that are samples (exact or censored).

        Parameters
        ----------
        e : int
            Experiment index.

        Returns
        -------
        ndarray of bool
            One per entry of `single`'s residual vector (sample-major, outputs inside).
        """
        p = self.packed[e]
        return ((p["A"] + p["B"] + p["C"]) > 0).T.ravel()


def noise_guess(data: Sequence[FitData], outputs: Sequence[str]) -> np.ndarray:
    """A noise level per output from the data alone: ``median |diff y| / (0.6745 sqrt 2)``.

    The robust spread of the sample-to-sample differences (a white noise of standard
    deviation ``sigma`` gives differences of standard deviation ``sigma sqrt 2``), floored at
    1e-6 of the output's range; 1 for an output without data.

    Parameters
    ----------
    data : sequence of FitData
        The experiments.
    outputs : sequence of str
        Output names.

    Returns
    -------
    ndarray, shape (len(outputs),)
        Output units.
    """
    out = []
    for nm in outputs:
        diffs, values = [], []
        for d in data:
            if nm in d.output_names:
                j = d.output_names.index(nm)
                y = np.where(d.exact[:, j], d.y[:, j], np.nan)
                diffs.append(np.diff(y))
                values.append(y)
        if not diffs:
            out.append(1.0)
            continue
        dv = np.concatenate(diffs)
        dv = np.abs(dv[np.isfinite(dv)])
        allv = np.concatenate(values)
        allv = allv[np.isfinite(allv)]
        spread = float(np.ptp(allv)) if allv.size else 1.0
        guess = float(np.median(dv)) / (0.6745 * np.sqrt(2.0)) if dv.size else 0.0
        out.append(max(guess, 1e-6 * max(spread, 1e-12), 1e-12))
    return np.array(out)
