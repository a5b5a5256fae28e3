"""Margins of the stacked time-domain figures, computed once from the text they show.

`matplotlib.figure.Figure.tight_layout` finds the margins by laying out every tick, label,
title and legend of every axes (a draw without output), and ``savefig`` then draws it all
again; for the report's figures that first pass was about a third of their cost.
`stacked_layout` computes the same margins directly: the widths of the y tick labels the
locator will show, the heights of the titles and labels and the width of each legend, all
measured with the font's metrics (`matplotlib.textpath.TextToPath`, at 72 dpi as the PDF
backend measures them), then sets them with ``subplots_adjust``. Everything is in points.
`square_panels_layout` does the same for the pole maps' square panels. `TraceCanvas` keeps the
figures of one report's time-domain figures for reuse (axes and tick artists made once).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any, Sequence

import numpy as np

__all__ = ["text_size", "visible_tick_labels", "legend_width", "stacked_layout", "square_panels_layout",
           "TraceCanvas"]

#: Padding around the figure and between panels (pt): tight_layout's default, 1.08 font sizes.
PAD_FACTOR = 1.08


@lru_cache(maxsize=4096)
def text_size(text: str, size: float) -> tuple[float, float]:
    """Width and height (pt) of one line of text as matplotlib lays it out.

    The height is at least that of ``"lp"`` (matplotlib's line box); text with a pair of
    unescaped ``$`` is measured as mathtext, as `matplotlib.text.Text` would draw it.

    Parameters
    ----------
    text : str
        One line of text.
    size : float
        Font size (pt) of the default font family.
    """
    from matplotlib.font_manager import FontProperties

    prop = FontProperties(size=size)
    ttp = _text_to_path()
    dollars = text.count("$") - text.count(r"\$")
    ismath = dollars >= 2 and dollars % 2 == 0
    w, h, _ = ttp.get_text_width_height_descent(text, prop, ismath=ismath)
    _, lp, _ = ttp.get_text_width_height_descent("lp", prop, ismath=False)
    return float(w), float(max(h, lp))


@lru_cache(maxsize=1)
def _text_to_path() -> Any:
    from matplotlib.textpath import TextToPath

    return TextToPath()


def visible_tick_labels(axis: Any) -> list[str]:
    """The major tick labels an axis will draw: its locator's ticks inside the view limits.

    Parameters
    ----------
    axis : matplotlib.axis.Axis
        With its final limits, locator and formatter.
    """
    locs = np.asarray(axis.get_majorticklocs(), dtype=float)
    labels = axis.get_major_formatter().format_ticks(locs)
    lo, hi = sorted(axis.get_view_interval())
    tol = 1e-9 * max(hi - lo, 1e-300)
    return [lab for v, lab in zip(locs, labels) if lo - tol <= v <= hi + tol and lab]


def legend_width(legend: Any) -> float:
    """Width (pt) of a one-column legend without a frame, from its anchor to its right edge.

    Parameters
    ----------
    legend : matplotlib.legend.Legend
    """
    from matplotlib import rcParams

    texts = legend.get_texts()
    if not texts:
        return 0.0
    fs = float(texts[0].get_fontsize())
    widest = max(text_size(t.get_text(), fs)[0] for t in texts)
    fixed = (rcParams["legend.borderaxespad"] + 2 * rcParams["legend.borderpad"]
             + rcParams["legend.handlelength"] + rcParams["legend.handletextpad"])
    return fs * fixed + widest


def _label_height(label: Any) -> float:
    text = label.get_text()
    return text_size(text, float(label.get_fontsize()))[1] if text else 0.0


def stacked_layout(fig: Any, axes: Sequence[Any], *, tick_size: float, legend_anchor: float = 1.01,
                   slack: float = 1.0) -> dict[str, float]:
    """Set the margins of a column of panels (``fig.add_subplot(P, 1, k)``) from their text.

    Left: y label, y tick labels, tick marks; right: the legends anchored at ``legend_anchor``
    (axes fraction) outside each panel; top and between panels: titles, x tick labels; bottom:
    x tick labels and x label of the last panel. A title wider than its panel widens both
    margins so that it stays on the page.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    axes : sequence of matplotlib.axes.Axes
        The panels, top to bottom, with their final limits, texts and legends.
    tick_size : float
        Font size of the tick labels (pt).
    legend_anchor : float
        x of the legends' upper-left anchor in axes fraction.
    slack : float
        Extra room (pt) on every side, against rounding of the font metrics.

    Returns
    -------
    dict
        The ``subplots_adjust`` fractions (``left``, ``right``, ``top``, ``bottom``, ``hspace``).
    """
    from matplotlib import rcParams

    W, H = (float(v) * 72.0 for v in fig.get_size_inches())
    pad = PAD_FACTOR * float(rcParams["font.size"]) + slack
    tick_h = text_size("0123456789", tick_size)[1]
    ytick = float(rcParams["ytick.major.size"]) + float(rcParams["ytick.major.pad"])
    xtick = float(rcParams["xtick.major.size"]) + float(rcParams["xtick.major.pad"]) + tick_h
    labelpad = float(rcParams["axes.labelpad"])
    titlepad = float(rcParams["axes.titlepad"])
    left = right = pad
    titles, legends, title_w, widths = [], [], [], []
    for ax in axes:
        widest = max((text_size(s, tick_size)[0] for s in visible_tick_labels(ax.yaxis)), default=0.0)
        widths.append(widest)
        yl = _label_height(ax.yaxis.label)
        left = max(left, pad + (yl + labelpad if yl else 0.0) + widest + ytick)
        leg = ax.get_legend()
        legends.append(legend_width(leg) if leg is not None else 0.0)
        th = _label_height(ax.title)
        titles.append(th + titlepad if th else 0.0)
        title_w.append(text_size(ax.title.get_text(), float(ax.title.get_fontsize()))[0]
                       if ax.title.get_text() else 0.0)
    last = axes[-1].xaxis.label
    xl = _label_height(last)
    bottom = pad + xtick + (xl + labelpad if xl else 0.0)
    top = pad + titles[0]
    gap = max([xtick + pad + titles[k] for k in range(1, len(axes))], default=0.0)
    for _ in range(8):      # the legends' anchor and a wide title depend on the panel width
        aw = max(W - left - right, 1.0)
        need_r = max([pad + lw + (legend_anchor - 1.0) * aw for lw in legends if lw] + [pad])
        over = max([(tw - aw) / 2.0 for tw in title_w] + [0.0])
        new_l, new_r = max(left, pad + over), max(need_r, pad + over)
        if abs(new_l - left) < 0.01 and abs(new_r - right) < 0.01:
            break
        left, right = new_l, new_r
    P = len(axes)
    ah = max((H - top - bottom - (P - 1) * gap) / P, 1.0)
    frac = {"left": left / W, "right": 1.0 - right / W, "top": 1.0 - top / H, "bottom": bottom / H,
            "hspace": gap / ah}
    fig.subplots_adjust(**frac)
    # The axis labels where matplotlib's automatic placement puts them (labelpad beyond the tick
    # labels), set once: placed by hand, a label needs no tick-label boxes at draw time.
    aw = W - left - right
    for ax, widest in zip(axes, widths):
        ax.yaxis.set_label_coords(-(ytick + widest + labelpad) / aw, 0.5)
    if xl:
        axes[-1].xaxis.set_label_coords(0.5, -(xtick + labelpad) / ah)
    return frac


def _legend_height(legend: Any) -> float:
    """Height (pt) of a one-column legend: rows of text or handle, label spacing, border padding."""
    from matplotlib import rcParams

    texts = legend.get_texts()
    if not texts:
        return 0.0
    fs = float(texts[0].get_fontsize())
    rows = [max(text_size(t.get_text(), fs)[1], rcParams["legend.handleheight"] * fs) for t in texts]
    return sum(rows) + (len(rows) - 1) * rcParams["legend.labelspacing"] * fs \
        + 2 * rcParams["legend.borderpad"] * fs


def square_panels_layout(fig: Any, axes: Sequence[Any], *, tick_size: float, legend_drop: float,
                         slack: float = 1.0) -> float:
    """Place a row of square panels (equal aspect) with a legend below each; size the figure to fit.

    The figure keeps its width; its height becomes what the panels need: title above, x tick labels,
    x label and the legend (anchored ``legend_drop`` panel heights below each panel, upper centre)
    below. Panels are squares of one side, side by side, each with room on its left for its y label
    and tick labels.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    axes : sequence of matplotlib.axes.Axes
        The panels, left to right, with their final limits, texts and legends.
    tick_size : float
        Font size of the tick labels (pt).
    legend_drop : float
        Where the legends hang: ``bbox_to_anchor = (0.5, -legend_drop)`` in axes fraction.
    slack : float
        Extra room (pt) on every side, against rounding of the font metrics.

    Returns
    -------
    float
        The side of the panels (pt).
    """
    from matplotlib import rcParams

    W = float(fig.get_size_inches()[0]) * 72.0
    pad = PAD_FACTOR * float(rcParams["font.size"]) + slack
    tick_h = text_size("0123456789", tick_size)[1]
    ytick = float(rcParams["ytick.major.size"]) + float(rcParams["ytick.major.pad"])
    xtick = float(rcParams["xtick.major.size"]) + float(rcParams["xtick.major.pad"]) + tick_h
    labelpad = float(rcParams["axes.labelpad"])
    titlepad = float(rcParams["axes.titlepad"])
    lefts, widths, below_fixed, below_drop, legend_w = [], [], [], [], []
    top = pad
    for ax in axes:
        widest = max((text_size(s, tick_size)[0] for s in visible_tick_labels(ax.yaxis)), default=0.0)
        widths.append(widest)
        yl = _label_height(ax.yaxis.label)
        lefts.append((yl + labelpad if yl else 0.0) + widest + ytick)
        th = _label_height(ax.title)
        top = max(top, pad + (th + titlepad if th else 0.0))
        xl = _label_height(ax.xaxis.label)
        below_fixed.append(xtick + (xl + labelpad if xl else 0.0))
        leg = ax.get_legend()
        if leg is not None and leg.get_texts():
            fs = float(leg.get_texts()[0].get_fontsize())
            below_drop.append(rcParams["legend.borderaxespad"] * fs + _legend_height(leg))
            legend_w.append(legend_width(leg) - rcParams["legend.borderaxespad"] * fs)
        else:
            below_drop.append(0.0)
            legend_w.append(0.0)
    P = len(axes)
    side = (W - (P + 1) * pad - sum(lefts)) / P
    for _ in range(4):   # a legend wider than its panel needs room on both sides
        over = max([(lw - side) / 2.0 for lw in legend_w] + [0.0])
        side = (W - (P + 1) * pad - sum(lefts) - 2 * P * over) / P
    side = max(side, 36.0)
    below = max(max(f, legend_drop * side + d) for f, d in zip(below_fixed, below_drop))
    H = top + side + below + pad
    fig.set_size_inches(W / 72.0, H / 72.0)
    used = sum(lefts) + P * side + (P - 1) * pad
    x = (W - used) / 2.0
    for ax, left, widest in zip(axes, lefts, widths):
        x += left
        ax.set_position([x / W, (H - top - side) / H, side / W, side / H])
        ax.yaxis.set_label_coords(-(ytick + widest + labelpad) / side, 0.5)
        ax.xaxis.set_label_coords(0.5, -(xtick + labelpad) / side)
        x += side + pad
    return side


class TraceCanvas:
    """Figures reused by the time-domain figures of one report, one per panel count.

    Creating the axes and their tick artists is a good part of a figure's cost; a figure with
    as many panels as an earlier one is drawn on the earlier one's axes, emptied (its lines,
    legends, texts and data limits reset), keeping the axes and their ticks. Pass one canvas to
    successive `time_domain_figure` calls; each figure is saved before the next one reuses it.

    Attributes
    ----------
    last : matplotlib.figure.Figure or None
        The figure handed out last (the one just drawn, until the next call of `axes`).
    """

    def __init__(self) -> None:
        self._figures: dict[int, tuple[Any, list]] = {}
        self.last: Any = None

    def axes(self, panels: int) -> tuple[Any, list]:
        """A figure of ``panels`` stacked empty panels (7.2 in wide, 1.9 in per panel).

        Parameters
        ----------
        panels : int
            Number of panels.

        Returns
        -------
        (Figure, list of Axes)
        """
        from matplotlib.transforms import Bbox

        if panels in self._figures:
            fig, axes = self._figures[panels]
            for ax in axes:
                for artist in [*ax.collections, *ax.lines]:
                    artist.remove()
                if ax.get_legend() is not None:
                    ax.get_legend().remove()
                ax.set_title("")
                ax.set_xlabel("")
                ax.set_ylabel("")
                ax.dataLim = Bbox.null()
                ax.ignore_existing_data_limits = True
                ax.set_autoscale_on(True)
            self.last = fig
            return fig, axes
        from matplotlib.figure import Figure

        fig = Figure(figsize=(7.2, 1.9 * panels + 0.4))
        axes = [fig.add_subplot(panels, 1, k + 1) for k in range(panels)]
        self._figures[panels] = (fig, axes)
        self.last = fig
        return fig, axes
