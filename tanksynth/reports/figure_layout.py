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
from typing import TYPE_CHECKING, Any, Sequence, cast

import numpy as np

if TYPE_CHECKING:  # annotations only (matplotlib loads where a figure is drawn)
    from matplotlib.typing import MarkerType

# matplotlib is imported inside the functions that draw (about 0.4 s), not at the top: the report
# imports this module for its records and helpers too, and needs matplotlib only for a figure it
# draws itself (not for those drawn ahead by `tanksynth.report_worker`).
__all__ = ["text_size", "visible_tick_labels", "legend_width", "stacked_layout", "square_panels_layout",
           "square_grid_layout", "place_axis_labels", "draw_decorations", "TraceCanvas"]

#: Padding around the figure and between panels (pt): tight_layout's default, 1.08 font sizes.
PAD_FACTOR = 1.08


def _rc(key: str) -> Any:
    """The matplotlib setting ``key``, named at run time (``xtick.major.size`` from the axis)."""
    from matplotlib import rcParams

    return rcParams[key]  # type: ignore[index]  # the stubs accept literal keys only


@lru_cache(maxsize=4096)
def text_size(text: str, size: float) -> tuple[float, float]:
    """Width and height (pt) of one line of text as the PDF backend lays it out.

    Measured as `matplotlib.backends.backend_pdf` measures text: the font at ``size`` pt and
    72 dpi, unhinted, its box rounded to whole points by FreeType; the height is at least that
    of ``"lp"`` (matplotlib's line box). Text with a pair of unescaped ``$`` is measured as
    mathtext, as `matplotlib.text.Text` would draw it.

    Parameters
    ----------
    text : str
        One line of text.
    size : float
        Font size (pt) of the default font family.
    """
    from matplotlib.font_manager import FontProperties

    prop = FontProperties(size=size)
    dollars = text.count("$") - text.count(r"\$")
    if dollars >= 2 and dollars % 2 == 0:
        w, h, _ = _text_to_path().get_text_width_height_descent(text, prop, ismath=True)
        return float(w), float(max(h, _measure("lp", size)[1]))
    w, h, _ = _measure(text, size)
    return w, max(h, _measure("lp", size)[1])


@lru_cache(maxsize=4096)
def _measure(text: str, size: float) -> tuple[float, float, float]:
    from matplotlib.font_manager import FontProperties, findfont, get_font
    from matplotlib.ft2font import LoadFlags

    font = get_font(findfont(FontProperties(size=size)))
    font.set_size(size, 72)
    font.set_text(text, 0.0, flags=LoadFlags.NO_HINTING)
    w, h = font.get_width_height()
    return w / 64.0, h / 64.0, font.get_descent() / 64.0


def _above_baseline(text: str, size: float) -> float:
    """Height (pt) of a line's box above its baseline (a title sits on its baseline)."""
    dollars = text.count("$") - text.count(r"\$")
    if dollars >= 2 and dollars % 2 == 0:
        return text_size(text, size)[1]
    _, h, d = _measure(text, size)
    _, lh, ld = _measure("lp", size)
    return max(h, lh) - max(d, ld)


@lru_cache(maxsize=1)
def _text_to_path() -> Any:
    from matplotlib.textpath import TextToPath

    return TextToPath()


def _visible_ticks(axis: Any) -> tuple[list[float], list[str], str]:
    """Locations, labels and offset text of the major ticks inside the view limits (as matplotlib
    selects them: its locator's ticks, 1e-10 relative tolerance)."""
    locs = np.asarray(axis.get_majorticklocs(), dtype=float)
    fmt = axis.get_major_formatter()
    labels = fmt.format_ticks(locs)
    lo, hi = sorted(axis.get_view_interval())
    tol = 1e-10 * (hi - lo)
    keep = [(float(v), lab) for v, lab in zip(locs, labels) if lo - tol <= v <= hi + tol]
    offset = fmt.get_offset() if hasattr(fmt, "get_offset") else ""
    return [v for v, _ in keep], [lab for _, lab in keep], str(offset or "")


def visible_tick_labels(axis: Any) -> list[str]:
    """The major tick labels an axis will draw: its locator's ticks inside the view limits.

    Parameters
    ----------
    axis : matplotlib.axis.Axis
        With its final limits, locator and formatter.
    """
    return [lab for lab in _visible_ticks(axis)[1] if lab]


def place_axis_labels(ax: Any, *, tick_size: float) -> None:
    """Put an axes' x and y labels where matplotlib's automatic placement would (labelpad beyond
    the tick labels), for an axes already positioned (after ``apply_aspect``).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Final position and limits.
    tick_size : float
        Font size of the tick labels (pt).
    """
    from matplotlib import rcParams

    ax.apply_aspect()
    W, H = (float(v) * 72.0 for v in ax.get_figure(root=True).get_size_inches())
    pos = ax.get_position()
    aw, ah = max(pos.width * W, 1.0), max(pos.height * H, 1.0)
    widest = max((text_size(s, tick_size)[0] for s in visible_tick_labels(ax.yaxis)), default=0.0)
    ytick = float(rcParams["ytick.major.size"]) + float(rcParams["ytick.major.pad"])
    xtick = float(rcParams["xtick.major.size"]) + float(rcParams["xtick.major.pad"]) \
        + text_size("0123456789", tick_size)[1]
    labelpad = float(rcParams["axes.labelpad"])
    ax.yaxis.set_label_coords(-(ytick + widest + labelpad) / aw, 0.5)
    ax.xaxis.set_label_coords(0.5, -(xtick + labelpad) / ah)


def draw_decorations(ax: Any, *, tick_size: float, grid: dict | None = None) -> None:
    """Draw an axes' ticks, tick labels, grid and axis labels as a few plain artists.

    Matplotlib's axis objects keep one `Tick` (five artists) per tick and lay every tick label
    out twice per draw; here the limits are frozen, the visible ticks computed once by the
    axis' own locator and formatter, and drawn as one marker line per axis (tick marks), one
    NaN-separated line per axis (grid lines), one text per tick label and per axis label, at
    the places and with the properties matplotlib uses (``get_xaxis_text1_transform`` ...).
    The axis objects are then hidden. Call it last, after the layout (label coordinates set).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Linear scales, final limits and label positions (``set_label_coords``).
    tick_size : float
        Font size of the tick labels (pt).
    grid : dict, optional
        Properties of the major grid lines (``linewidth``, ``color``); no grid when omitted.
    """
    from matplotlib import rcParams
    from matplotlib.lines import Line2D
    from matplotlib.markers import TICKDOWN, TICKLEFT  # ints, which the stubs type as any int
    from matplotlib.transforms import ScaledTranslation

    ax.set_xlim(ax.get_xlim())      # frozen: the ticks below are those of these limits
    ax.set_ylim(ax.get_ylim())
    z = 1.5 if rcParams["axes.axisbelow"] == "line" else (0.5 if rcParams["axes.axisbelow"] else 2.5)
    for axis in (ax.xaxis, ax.yaxis):
        name = axis.axis_name
        locs, labels, offset = _visible_ticks(axis)
        size = float(_rc(f"{name}tick.major.size"))
        pad = float(_rc(f"{name}tick.major.pad"))
        color = _rc(f"{name}tick.color")
        lcolor = _rc(f"{name}tick.labelcolor")
        lcolor = color if lcolor == "inherit" else lcolor
        nan = [np.nan] * len(locs)
        ends = np.ravel(np.column_stack([np.zeros(len(locs)), np.ones(len(locs)), nan]))
        at = np.ravel(np.column_stack([locs, locs, nan]))
        tick_xy: tuple[Any, Any]
        grid_xy: tuple[Any, Any]
        if name == "x":
            tick_xy, marker = (locs, np.zeros(len(locs))), TICKDOWN
            grid_xy, gtrans = (at, ends), ax.get_xaxis_transform("grid")
            ttrans, va, ha = ax.get_xaxis_text1_transform(size + pad)
            mtrans = ax.get_xaxis_transform("tick1")
        else:
            tick_xy, marker = (np.zeros(len(locs)), locs), TICKLEFT
            grid_xy, gtrans = (ends, at), ax.get_yaxis_transform("grid")
            ttrans, va, ha = ax.get_yaxis_text1_transform(size + pad)
            mtrans = ax.get_yaxis_transform("tick1")
        if grid and locs:
            ax.add_artist(Line2D(*grid_xy, transform=gtrans, zorder=z, linestyle=rcParams["grid.linestyle"],
                                 alpha=rcParams["grid.alpha"], **grid))
        if locs:
            ax.add_artist(Line2D(*tick_xy, transform=mtrans, marker=cast("MarkerType", marker), markersize=size,
                                 markeredgewidth=float(_rc(f"{name}tick.major.width")), color=color,
                                 markeredgecolor=color, linestyle="none", clip_on=False, zorder=z))
        for v, lab in zip(locs, labels):
            if lab:
                xy = (v, 0.0) if name == "x" else (0.0, v)
                ax.text(*xy, lab, transform=ttrans, va=va, ha=ha, fontsize=tick_size, color=lcolor,
                        clip_on=False)
        if offset:       # matplotlib's offset / multiplier text (right below, or above left)
            fs = tick_size
            if name == "x":
                shift = ScaledTranslation(0, -(size + pad + text_size("0", tick_size)[1] + 3.0) / 72.0,
                                          ax.get_figure(root=True).dpi_scale_trans)
                ax.text(1.0, 0.0, offset, transform=ax.transAxes + shift, va="top", ha="right", fontsize=fs,
                        color=lcolor)
            else:
                shift = ScaledTranslation(0, 3.0 / 72.0, ax.get_figure(root=True).dpi_scale_trans)
                ax.text(0.0, 1.0, offset, transform=ax.transAxes + shift, va="baseline", ha="left",
                        fontsize=fs, color=lcolor)
        label = axis.label
        if label.get_text():
            x, y = label.get_position()
            ax.text(x, y, label.get_text(), transform=ax.transAxes, fontsize=label.get_fontsize(),
                    color=label.get_color(), rotation=label.get_rotation(), rotation_mode="anchor",
                    va=label.get_verticalalignment(), ha=label.get_horizontalalignment(), clip_on=False)
        axis.set_visible(False)


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


def _ticks_state(axes: Sequence[Any]) -> list:
    return [(visible_tick_labels(ax.xaxis), visible_tick_labels(ax.yaxis)) for ax in axes]


def stacked_layout(fig: Any, axes: Sequence[Any], *, tick_size: float, legend_anchor: float = 1.01,
                   slack: float = 0.0) -> dict[str, float]:
    """Set the margins of a column of panels (``fig.add_subplot(P, 1, k)``) from their text.

    A legend taller than the room below its panel's top (down to the next panel's top, or to the
    figure's bottom edge for the last panel) makes the figure taller, the panels with it.

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
    # The locator's ticks depend on the panel size: laid out again until the tick labels measured
    # are those of the final panels (twice, rarely three times).
    before = _ticks_state(axes)
    for _ in range(3):
        frac = _stacked_once(fig, axes, tick_size=tick_size, legend_anchor=legend_anchor, slack=slack)
        after = _ticks_state(axes)
        if after == before:
            break
        before = after
    return frac


def _stacked_once(fig: Any, axes: Sequence[Any], *, tick_size: float, legend_anchor: float,
                  slack: float) -> dict[str, float]:
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
        th = _above_baseline(ax.title.get_text(), float(ax.title.get_fontsize())) if ax.title.get_text() else 0.0
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
    # A legend hangs from its panel's top: it must end above the next panel's legend (one panel
    # and one gap lower) or, for the last panel, above the figure's bottom edge. A taller legend
    # makes the figure taller (the panels grow, the text keeps its size).
    tall = [_legend_height(ax.get_legend()) if ax.get_legend() is not None else 0.0 for ax in axes]
    need = max([tall[k] - gap for k in range(P - 1)] + [tall[-1] - bottom + pad] + [0.0])
    if need > ah:
        ah = need
        H = top + bottom + (P - 1) * gap + P * ah
        fig.set_size_inches(W / 72.0, H / 72.0)
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
                         slack: float = 1.0, keep_height: bool = True) -> float:
    """Place a row of square panels (equal aspect) with a legend below each; size the figure to fit.

    The figure keeps its width; its height becomes what the panels need: title above, x tick labels,
    x label and the legend (anchored ``legend_drop`` panel heights below each panel, upper centre)
    below. Panels are squares of one side, side by side, each with room on its left for its y label
    and tick labels; with ``keep_height`` they are made smaller (to 60 % at most) rather than the
    figure taller than it was.

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
    keep_height : bool
        Prefer smaller panels to a taller figure (see above).

    Returns
    -------
    float
        The side of the panels (pt).
    """
    H0 = float(fig.get_size_inches()[1]) * 72.0
    before = _ticks_state(axes)
    for _ in range(3):     # again until the tick labels measured are those of the final panels
        side = _square_once(fig, axes, tick_size=tick_size, legend_drop=legend_drop, slack=slack,
                            keep_height=keep_height, H0=H0)
        after = _ticks_state(axes)
        if after == before:
            break
        before = after
    return side


def _square_once(fig: Any, axes: Sequence[Any], *, tick_size: float, legend_drop: float, slack: float,
                 keep_height: bool, H0: float) -> float:
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
        th = _above_baseline(ax.title.get_text(), float(ax.title.get_fontsize())) if ax.title.get_text() else 0.0
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
    if keep_height:          # no taller than the figure was, unless the panels would shrink below 60 %
        fit = min(min(H0 - top - pad - f, (H0 - top - pad - d) / (1.0 + legend_drop))
                  for f, d in zip(below_fixed, below_drop))
        side = min(side, max(fit, 0.6 * side))
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
            fig.set_size_inches(7.2, 1.9 * panels + 0.4)    # `stacked_layout` may have grown it
            for ax in axes:
                for artist in [*ax.collections, *ax.lines, *ax.texts, *ax.artists]:
                    artist.remove()
                ax.xaxis.set_visible(True)
                ax.yaxis.set_visible(True)
                if ax.get_legend() is not None:
                    ax.get_legend().remove()
                ax.set_title("")
                ax.set_xlabel("")
                ax.set_ylabel("")
                ax.dataLim = Bbox.null()
                ax.ignore_existing_data_limits = True
                ax.set_autoscale_on(True)
            from matplotlib import rcParams

            fig.subplots_adjust(**{k: _rc(f"figure.subplot.{k}")     # as a new figure starts
                                   for k in ("left", "right", "top", "bottom", "hspace", "wspace")})
            self.last = fig
            return fig, axes
        from matplotlib.figure import Figure

        fig = Figure(figsize=(7.2, 1.9 * panels + 0.4))
        axes = [fig.add_subplot(panels, 1, k + 1) for k in range(panels)]
        self._figures[panels] = (fig, axes)
        self.last = fig
        return fig, axes


def square_grid_layout(fig: Any, axes: Sequence[Any], *, cols: int, tick_size: float,
                       legend: Any = None, slack: float = 1.0) -> float:
    """Place square panels (equal aspect) on a grid of ``cols`` columns, above a figure legend.

    Each column has room on its left for its panels' y labels and tick labels, each row room above
    for its titles and below for its x tick labels and x labels; the figure keeps its size and the
    grid is centred in it, above ``legend`` (a figure legend at the lower centre, if any).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    axes : sequence of matplotlib.axes.Axes
        The panels, row by row, with their final limits and texts.
    cols : int
        Panels per row.
    tick_size : float
        Font size of the tick labels (pt).
    legend : matplotlib.legend.Legend, optional
        The figure's legend below the panels (``ncols`` columns).
    slack : float
        Extra room (pt) on every side, against rounding of the font metrics.

    Returns
    -------
    float
        The side of the panels (pt).
    """
    before = _ticks_state(axes)
    for _ in range(3):     # again until the tick labels measured are those of the final panels
        side = _grid_once(fig, axes, cols=cols, tick_size=tick_size, legend=legend, slack=slack)
        after = _ticks_state(axes)
        if after == before:
            break
        before = after
    return side


def _grid_once(fig: Any, axes: Sequence[Any], *, cols: int, tick_size: float, legend: Any,
               slack: float) -> float:
    from matplotlib import rcParams

    W, H = (float(v) * 72.0 for v in fig.get_size_inches())
    pad = PAD_FACTOR * float(rcParams["font.size"]) + slack
    xtick = float(rcParams["xtick.major.size"]) + float(rcParams["xtick.major.pad"]) \
        + text_size("0123456789", tick_size)[1]
    ytick = float(rcParams["ytick.major.size"]) + float(rcParams["ytick.major.pad"])
    labelpad = float(rcParams["axes.labelpad"])
    titlepad = float(rcParams["axes.titlepad"])
    rows = -(-len(axes) // cols)
    lefts, tops, belows = [0.0] * cols, [0.0] * rows, [0.0] * rows
    for k, ax in enumerate(axes):
        r, c = divmod(k, cols)
        widest = max((text_size(s, tick_size)[0] for s in visible_tick_labels(ax.yaxis)), default=0.0)
        yl = _label_height(ax.yaxis.label)
        lefts[c] = max(lefts[c], (yl + labelpad if yl else 0.0) + widest + ytick)
        t = ax.title.get_text()
        tops[r] = max(tops[r], _above_baseline(t, float(ax.title.get_fontsize())) + titlepad if t else 0.0)
        xl = _label_height(ax.xaxis.label)
        belows[r] = max(belows[r], xtick + (xl + labelpad if xl else 0.0))
    bottom = 0.0
    if legend is not None and legend.get_texts():
        texts = legend.get_texts()
        fs = float(texts[0].get_fontsize())
        per_row = -(-len(texts) // max(int(getattr(legend, "_ncols", 1)), 1))
        row_h = max(max(text_size(t.get_text(), fs)[1] for t in texts), rcParams["legend.handleheight"] * fs)
        bottom = rcParams["legend.borderaxespad"] * fs + 2 * rcParams["legend.borderpad"] * fs \
            + per_row * row_h + (per_row - 1) * rcParams["legend.labelspacing"] * fs
    side_w = (W - (cols + 1) * pad - sum(lefts)) / cols
    side_h = (H - (rows + 1) * pad - bottom - sum(tops) - sum(belows)) / rows
    side = max(min(side_w, side_h), 36.0)
    x0 = (W - (sum(lefts) + cols * side + (cols - 1) * pad)) / 2.0
    used_h = sum(tops) + sum(belows) + rows * side + (rows - 1) * pad
    y_top = H - (H - bottom - used_h) / 2.0          # grid centred in the room above the legend
    for k, ax in enumerate(axes):
        r, c = divmod(k, cols)
        x = x0 + sum(lefts[:c + 1]) + c * (side + pad)
        y = y_top - sum(tops[:r + 1]) - r * (side + pad) - sum(belows[:r]) - side
        ax.set_position([x / W, y / H, side / W, side / H])
    for ax in axes:
        place_axis_labels(ax, tick_size=tick_size)
    return side
