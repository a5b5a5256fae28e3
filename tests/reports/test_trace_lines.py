"""Min/max decimation and run collections of the time-domain figures (reports/trace_lines.py)."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.reports.trace_lines import draw_runs, envelope, staircase


def test_short_traces_are_kept_as_given():
    t = np.linspace(0.0, 1.0, 50)
    y = np.sin(t)
    tk, yk = envelope(t, y, bins=30)
    assert tk is t and yk is y


def test_every_slice_keeps_its_extremes_in_time_order():
    rng = np.random.default_rng(1)
    N, bins = 10_000, 100
    t = np.arange(N) * 0.01
    y = np.cumsum(rng.standard_normal(N))
    y[4321] = 1e3            # a one-sample spike must survive
    tk, yk = envelope(t, y, bins)
    assert tk.size <= 2 * bins + 2 and np.all(np.diff(tk) >= 0)
    assert tk[0] == t[0] and tk[-1] == t[-1] and 1e3 in yk
    k = N // bins            # slices of 100 samples, by hand
    for b in range(bins):
        sl = y[b * k:(b + 1) * k]
        kept = yk[(tk >= t[b * k]) & (tk <= t[min((b + 1) * k, N) - 1])]
        assert sl.min() in kept and sl.max() in kept
    # the kept points are samples of the trace
    idx = np.searchsorted(t, tk)
    np.testing.assert_array_equal(y[idx], yk)


def test_several_runs_are_decimated_each_on_its_own():
    t = np.linspace(0.0, 10.0, 5001)
    Y = np.vstack([np.sin(t), -np.sin(3 * t), np.zeros_like(t)])
    tk, yk = envelope(t, Y, bins=50)
    assert tk.shape == yk.shape and tk.shape[0] == 3
    for r in range(3):
        assert yk[r].max() == Y[r].max() and yk[r].min() == Y[r].min()


def test_envelope_refuses_mismatched_lengths():
    with pytest.raises(ValueError):
        envelope(np.arange(5.0), np.arange(4.0))


def test_staircase_holds_each_value_until_the_next_sample():
    ts, ys = staircase(np.array([0.0, 1.0, 3.0]), np.array([5.0, 6.0, 7.0]))
    np.testing.assert_array_equal(ts, [0.0, 1.0, 1.0, 3.0, 3.0])
    np.testing.assert_array_equal(ys, [5.0, 5.0, 6.0, 6.0, 7.0])


def test_staircase_holds_the_last_value_to_the_end_of_the_horizon():
    # inputs sampled at t = 0, 1 (zero-order hold) on a horizon ending at t = 2: u[1] acts on [1, 2]
    ts, ys = staircase(np.array([[0.0, 1.0]]), np.array([[5.0, 6.0]]), end=2.0)
    np.testing.assert_array_equal(ts, [[0.0, 1.0, 1.0, 2.0]])
    np.testing.assert_array_equal(ys, [[5.0, 5.0, 6.0, 6.0]])
    # an end not after the last sample adds nothing
    np.testing.assert_array_equal(staircase(np.array([0.0, 1.0]), np.array([5.0, 6.0]), end=1.0)[0],
                                  [0.0, 1.0, 1.0])


def test_draw_runs_adds_one_collection_with_the_data_limits():
    from matplotlib.figure import Figure

    fig = Figure()
    ax = fig.add_subplot()
    t = np.linspace(0.0, 2.0, 3001)
    Y = np.vstack([t, 2 * t, -t])
    coll = draw_runs(ax, t, Y, step=True, color="C1", linewidth=0.5, alpha=0.4)
    assert len(ax.collections) == 1 and len(coll.get_segments()) == 3
    assert ax.dataLim.y0 == pytest.approx(-2.0) and ax.dataLim.y1 == pytest.approx(4.0)
    assert draw_runs(ax, t, np.zeros((0, t.size))) is None
