"""Drawing long, many-run time traces cheaply without losing what is visible.

A time-domain figure is a vector PDF whose axes are a few inches wide: a line of 10,000 samples
puts thousands of vertices in every device pixel column. `envelope` keeps, for each of ``bins``
equal index slices of a trace, the samples where it is smallest and largest (in time order) plus
the first and last samples, so every extreme a pixel column shows is still drawn (min/max
decimation, as oscilloscopes do). `draw_runs` draws the runs of one signal as ONE
`matplotlib.collections.LineCollection` (one artist instead of one `Line2D` per run), each run
decimated the same way, optionally as a zero-order-hold staircase. `PanelLines` collects every
line of one panel (first runs, further runs, references, in drawing order) and draws them as ONE
collection with per-line colour, width and dash pattern; the legend gets proxy handles, so a panel
costs one artist and one autoscale instead of one `Line2D` per signal.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import numpy as np

if TYPE_CHECKING:  # annotations only (matplotlib loads where a figure is drawn)
    from matplotlib.typing import LineStyleType

# matplotlib is imported inside the functions that draw (about 0.4 s), not at the top: the report
# imports this module for its records and helpers too, and needs matplotlib only for a figure it
# draws itself (not for those drawn ahead by `tanksynth.report_worker`).
__all__ = ["ENVELOPE_BINS", "envelope", "staircase", "draw_runs", "PanelLines"]

#: Index slices per trace: about the pixel width of a 5 in axis at 200 dpi (the figures are 7.2 in wide).
ENVELOPE_BINS = 1000


def envelope(t: np.ndarray, y: np.ndarray, bins: int = ENVELOPE_BINS) -> tuple[np.ndarray, np.ndarray]:
    """Min/max decimation of sampled signals along the last axis.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times (s), increasing.
    y : ndarray, shape (N,) or (R, N)
        One signal or R signals on the same times (any unit); NaN samples are kept where a slice's
        extremes are NaN.
    bins : int
        Number of equal index slices. Traces of at most ``2 bins + 2`` samples are returned as given.

    Returns
    -------
    t_kept : ndarray, shape (K,) or (R, K)
        Times of the kept samples, in time order (per signal when ``y`` is 2-D).
    y_kept : ndarray, same shape as ``t_kept``
        The kept samples: first, last, and each slice's minimum and maximum.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    one = y.ndim == 1
    Y = y[None] if one else y
    N = t.size
    if Y.shape[-1] != N:
        raise ValueError(f"envelope: {Y.shape[-1]} samples for {N} times")
    if N <= 2 * bins + 2:
        return (t, y) if one else (np.broadcast_to(t, Y.shape), Y)
    k = -(-N // bins)                      # samples per slice
    nb = -(-N // k)
    pad = nb * k - N
    P = np.concatenate([Y, np.repeat(Y[:, -1:], pad, axis=1)], axis=1) if pad else Y
    blocks = P.reshape(Y.shape[0], nb, k)
    base = (np.arange(nb) * k)[None, :]
    lo = np.minimum(base + np.nanargmin(np.where(np.isnan(blocks), np.inf, blocks), axis=2), N - 1)
    hi = np.minimum(base + np.nanargmax(np.where(np.isnan(blocks), -np.inf, blocks), axis=2), N - 1)
    first = np.zeros((Y.shape[0], 1), dtype=int)
    last = np.full((Y.shape[0], 1), N - 1)
    idx = np.sort(np.concatenate([first, np.minimum(lo, hi), np.maximum(lo, hi), last], axis=1), axis=1)
    rows = np.arange(Y.shape[0])[:, None]
    tk, yk = t[idx], Y[rows, idx]
    return (tk[0], yk[0]) if one else (tk, yk)


def staircase(t: np.ndarray, y: np.ndarray, end: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold ("post") staircase vertices of samples along the last axis.

    Parameters
    ----------
    t : ndarray, shape (..., N)
        Sample times (s).
    y : ndarray, shape (..., N)
        Held values.
    end : float, optional
        End of the horizon (s): the last value ``y[N-1]`` is held from ``t[N-1]`` to ``end``
        (a zero-order hold's last input acts until the end of the simulation, one sample after
        its sample time). Ignored unless later than ``t[N-1]``.

    Returns
    -------
    ts : ndarray, shape (..., 2 N - 1), or (..., 2 N) with ``end``
        Vertex times (s): every sample time twice but the first (and ``end``).
    ys : ndarray, shape (..., 2 N - 1), or (..., 2 N) with ``end``
        Vertex values (the unit of ``y``): ``y[k]`` held from ``t[k]`` to ``t[k+1]``.
    """
    t, y = np.broadcast_arrays(np.asarray(t, float), np.asarray(y, float))
    ts = np.repeat(t, 2, axis=-1)[..., 1:]
    ys = np.repeat(y, 2, axis=-1)[..., :-1]
    if end is not None and t.shape[-1] and float(end) > float(np.max(t[..., -1])):
        ts = np.concatenate([ts, np.full(ts.shape[:-1] + (1,), float(end))], axis=-1)
        ys = np.concatenate([ys, y[..., -1:]], axis=-1)
    return ts, ys


def draw_runs(ax: Any, t: np.ndarray, Y: np.ndarray, *, step: bool = False, bins: int = ENVELOPE_BINS,
              **style: Any) -> Any:
    """Draw R runs of one signal as one decimated `LineCollection` on ``ax``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    t : ndarray, shape (N,)
        Sample times (s).
    Y : ndarray, shape (R, N)
        The runs (any unit). Nothing is drawn when R = 0.
    step : bool
        Draw each run as a zero-order-hold staircase (as ``ax.step(where="post")``).
    bins : int
        `envelope` slices.
    **style
        ``color``, ``linewidth``, ``alpha``, ``linestyle``, ``label`` ... of the collection.

    Returns
    -------
    matplotlib.collections.LineCollection or None
    """
    from matplotlib.collections import LineCollection

    Y = np.asarray(Y, dtype=float)
    if Y.ndim != 2 or Y.shape[0] == 0:
        return None
    tk, yk = envelope(t, Y, bins)
    if step:
        tk, yk = staircase(tk, yk)
    segments = np.stack([tk, yk], axis=-1)
    coll = LineCollection(list(segments), **style)
    ax.add_collection(coll, autolim=True)
    ax.autoscale_view()
    return coll


class PanelLines:
    """The lines of one panel, drawn as ONE `LineCollection` in the order they were added.

    Each line keeps its own colour, alpha, width and dash pattern (the collection's per-segment
    properties), so the panel looks as if every line were a `Line2D` drawn in turn; lines given a
    ``label`` get a proxy `Line2D` (not added to the axes) for the legend.

    Parameters
    ----------
    bins : int
        `envelope` slices of every line.
    """

    def __init__(self, bins: int = ENVELOPE_BINS) -> None:
        self.bins = int(bins)
        self._segments: list[np.ndarray] = []
        self._colors: list[tuple[float, float, float, float]] = []
        self._widths: list[float] = []
        self._styles: list[str] = []
        self.handles: list[Any] = []
        self.labels: list[str] = []

    def _add(self, tk: np.ndarray, yk: np.ndarray, step: bool, color: Any, linewidth: float,
             linestyle: str, alpha: float, end: float | None = None) -> None:
        from matplotlib.colors import to_rgba

        if step:
            tk, yk = staircase(tk, yk, end)
        rgba = to_rgba(color, alpha)
        for tr, yr in zip(np.atleast_2d(tk), np.atleast_2d(yk)):
            self._segments.append(np.column_stack([tr, yr]))
            self._colors.append(rgba)
            self._widths.append(float(linewidth))
            self._styles.append(linestyle)

    def line(self, t: np.ndarray, y: np.ndarray, *, color: Any, linewidth: float, linestyle: str = "-",
             alpha: float = 1.0, step: bool = False, end: float | None = None,
             label: str | None = None) -> None:
        """Add one signal (decimated by `envelope`).

        Parameters
        ----------
        t : ndarray, shape (N,)
            Sample times (s).
        y : ndarray, shape (N,)
            The signal (any unit).
        color, linewidth, linestyle, alpha
            Matplotlib line properties: width in points, alpha an opacity in [0, 1]
            (dimensionless).
        step : bool
            Zero-order-hold staircase (as ``ax.step(where="post")``).
        end : float, optional
            With ``step``: end of the horizon (s), the last value is held until then
            (`staircase`).
        label : str, optional
            Legend entry (a proxy handle with the same colour, width and dash pattern).
        """
        tk, yk = envelope(t, np.asarray(y, dtype=float), self.bins)
        self._add(tk, yk, step, color, linewidth, linestyle, alpha, end)
        if label is not None:
            from matplotlib.lines import Line2D

            # the style is read from a trace file: matplotlib checks it (the stubs list literals)
            self.handles.append(Line2D([], [], color=color, linewidth=linewidth,
                                       linestyle=cast("LineStyleType", linestyle),
                                       alpha=None if alpha == 1.0 else alpha))
            self.labels.append(str(label))

    def runs(self, t: np.ndarray, Y: np.ndarray, *, color: Any, linewidth: float, linestyle: str = "-",
             alpha: float = 1.0, step: bool = False, end: float | None = None) -> None:
        """Add R runs of one signal (each decimated by `envelope`; nothing for R = 0).

        Parameters
        ----------
        t : ndarray, shape (N,)
            Sample times (s).
        Y : ndarray, shape (R, N)
            The runs (any unit).
        color, linewidth, linestyle, alpha, step, end
            As in `line` (width in points, alpha dimensionless, end in s).
        """
        Y = np.asarray(Y, dtype=float)
        if Y.ndim != 2 or Y.shape[0] == 0:
            return
        tk, yk = envelope(t, Y, self.bins)
        self._add(tk, yk, step, color, linewidth, linestyle, alpha, end)

    def draw(self, ax: Any) -> Any:
        """Add the collection to ``ax`` and autoscale once.

        Parameters
        ----------
        ax : matplotlib.axes.Axes

        Returns
        -------
        matplotlib.collections.LineCollection or None
            None when no line was added.
        """
        from matplotlib.collections import LineCollection

        if not self._segments:
            return None
        coll = LineCollection(self._segments, colors=self._colors, linewidths=self._widths,
                              linestyles=self._styles)
        ax.add_collection(coll, autolim=True)
        ax.autoscale_view()
        return coll
