"""Margins of the report figures from text metrics (tanksynth.reports.figure_layout).

The layouts are checked against matplotlib's own renderer: after a draw, every text, tick label and
legend must lie inside the figure, y labels left of their tick labels, legends right of (or below)
their panels, titles above them and clear of the panel above.
"""

from __future__ import annotations

import io

import numpy as np
import pytest

from tanksynth.reports.figure_layout import (legend_width, square_panels_layout, stacked_layout,
                                             text_size, visible_tick_labels)


def _figure(panels: int):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.2, 1.9 * panels + 0.4))
    return fig, [fig.add_subplot(panels, 1, k + 1) for k in range(panels)]


def _pdf_renderer(fig):
    """The PDF backend's renderer (72 dpi, unhinted font metrics), drawing into memory."""
    from matplotlib.backends.backend_pdf import PdfFile, RendererPdf

    fig.set_dpi(72)
    w, h = fig.get_size_inches()
    pdf = PdfFile(io.BytesIO())
    pdf.newPage(w, h)
    return RendererPdf(pdf, 72, h, w)


def _drawn_tick_labels(axis):
    lo, hi = sorted(axis.get_view_interval())
    k = 0 if axis.axis_name == "x" else 1
    return [t for t in axis.get_ticklabels() if t.get_text() and lo <= t.get_position()[k] <= hi]


def _extents(fig):
    """Renderer, figure box and the window extent of every text drawn (pt), as the PDF draws them."""
    r = _pdf_renderer(fig)
    fig.draw(r)
    texts = []
    for ax in fig.axes:
        texts += [ax.title, ax.xaxis.label, ax.yaxis.label, *_drawn_tick_labels(ax.xaxis),
                  *_drawn_tick_labels(ax.yaxis)]
        if ax.get_legend() is not None:
            texts += list(ax.get_legend().get_texts())
    texts = [t for t in texts if t.get_visible() and t.get_text()]
    return r, fig.bbox, {id(t): t.get_window_extent(r) for t in texts}, texts


def _inside(box, outer, tol=0.5):
    return (box.x0 >= outer.x0 - tol and box.x1 <= outer.x1 + tol and box.y0 >= outer.y0 - tol
            and box.y1 <= outer.y1 + tol)


def test_text_size_matches_matplotlib_text_extents():
    from matplotlib.figure import Figure

    fig = Figure()
    r = _pdf_renderer(fig)
    for s, size, tol in [("time t [s]", 8.0, 0.1), ("0.0315", 7.0, 0.1), ("h1 estimate, h11 estimate", 6.0, 0.1),
                         ("$x_1$ [m]", 8.0, 1.5)]:        # mathtext: measured by the mathtext parser
        t = fig.text(0.1, 0.5, s, fontsize=size)
        box = t.get_window_extent(r)
        w, h = text_size(s, size)
        assert w == pytest.approx(box.width, abs=tol) and h == pytest.approx(box.height, abs=1.5)
    assert text_size("ab", 14.0)[0] == pytest.approx(2 * text_size("ab", 7.0)[0], rel=0.05)


def test_visible_tick_labels_are_those_matplotlib_draws():
    fig, (ax,) = _figure(1)
    ax.plot([0.0, 613.0], [0.0301, 0.0349])
    fig.subplots_adjust(left=0.2, right=0.8)
    fig.draw(_pdf_renderer(fig))
    drawn = [t.get_text() for t in ax.get_yticklabels() if t.get_visible() and t.get_text()
             and ax.get_ylim()[0] <= t.get_position()[1] <= ax.get_ylim()[1]]
    assert visible_tick_labels(ax.yaxis) == drawn and len(drawn) >= 3


@pytest.mark.parametrize("panels", [1, 2, 4])
def test_stacked_layout_keeps_every_text_on_the_page_and_apart(panels):
    fig, axes = _figure(panels)
    t = np.linspace(0.0, 600.0, 50)
    for k, ax in enumerate(axes):
        for i in range(3):
            ax.plot(t, (1e-5 if k == 1 else 1.0) * (i + np.sin(t / 90.0)), label=f"signal {i} with a long name [m]")
        ax.set_ylabel("a y label [m]", fontsize=8)
        ax.set_title("title " * (18 if k == 0 else 2), fontsize=9, y=1.0)   # the first one wider than the panel
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    axes[-1].set_xlabel("time t [s]", fontsize=8)
    stacked_layout(fig, axes, tick_size=7)
    r, page, ext, texts = _extents(fig)
    for txt in texts:
        assert _inside(ext[id(txt)], page), f"{txt.get_text()!r} leaves the page"
    for k, ax in enumerate(axes):
        box = ax.get_window_extent(r)
        leg = ax.get_legend().get_window_extent(r)
        assert _inside(leg, page) and leg.x0 >= box.x1
        ticks = [ext[id(t)] for t in _drawn_tick_labels(ax.yaxis)]
        ylab = ext[id(ax.yaxis.label)]
        assert ylab.x1 <= min(b.x0 for b in ticks) + 0.5          # label left of its tick labels
        assert ext[id(ax.title)].y0 >= box.y1 - 0.5                 # title above the panel
        if k:
            above = [ext[id(t)] for t in _drawn_tick_labels(axes[k - 1].xaxis)]
            assert ext[id(ax.title)].y1 <= min(b.y0 for b in above) + 0.5   # clear of the panel above


def test_stacked_layout_grows_the_figure_for_a_tall_legend():
    """A legend longer than its panel would run into the next panel's legend (or off the page):
    the figure grows so that every legend ends above the next one and on the page."""
    fig, axes = _figure(3)
    h0 = fig.get_size_inches()[1]
    t = np.linspace(0.0, 40.0, 20)
    for ax in axes:
        for i in range(14):
            ax.plot(t, i + np.sin(t), label=f"h{i + 1}, h{i + 11}, h{i + 21}")
        ax.tick_params(labelsize=8.5)
        ax.legend(fontsize=8.5, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    stacked_layout(fig, axes, tick_size=8.5)
    assert fig.get_size_inches()[1] > h0
    r, page, ext, texts = _extents(fig)
    legs = [ax.get_legend().get_window_extent(r) for ax in axes]
    for k, leg in enumerate(legs):
        assert _inside(leg, page)
        if k + 1 < len(legs):
            assert leg.y0 >= legs[k + 1].y1 - 0.5, k       # above the next panel's legend


def test_square_panels_fit_their_legends_and_titles():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.6, 4.1))
    for k in range(2):
        ax = fig.add_subplot(1, 2, k + 1)
        for m in range(4):
            ax.plot([-1.0 + 0.1 * m], [0.2], marker="x", linestyle="none", label=f"set number {m} of poles")
        ax.set_xlim(-1.5, 0.5)
        ax.set_ylim(-1.0, 1.0)
        ax.set_aspect("equal", adjustable="box")
        ax.set_title("s-plane (continuous time)", fontsize=9, y=1.0)
        ax.set_xlabel("real part [1/s]", fontsize=8)
        ax.set_ylabel("imaginary part [1/s]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    side = square_panels_layout(fig, fig.axes, tick_size=7, legend_drop=0.2)
    r, page, ext, texts = _extents(fig)
    for txt in texts:
        assert _inside(ext[id(txt)], page), f"{txt.get_text()!r} leaves the page"
    for ax in fig.axes:
        box = ax.get_window_extent(r)
        assert box.width == pytest.approx(box.height, rel=1e-6)
        assert box.width == pytest.approx(side, rel=1e-6)
        leg = ax.get_legend().get_window_extent(r)
        assert _inside(leg, page) and leg.y1 <= box.y0
    a, b = (ax.get_window_extent(r) for ax in fig.axes)
    assert ext[id(fig.axes[1].yaxis.label)].x0 >= a.x1                # panels apart


def test_legend_width_matches_the_drawn_legend():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.0, 3.0))
    ax = fig.add_axes([0.1, 0.1, 0.5, 0.8])
    for i in range(5):
        ax.plot([0, 1], [i, i], label=f"h{i} estimate, h{i + 10} estimate" if i % 2 else f"q{i}")
    leg = ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    r = _pdf_renderer(fig)
    fig.draw(r)
    box = leg.get_window_extent(r)
    anchor = ax.get_window_extent(r).x0 + 1.01 * ax.get_window_extent(r).width
    assert legend_width(leg) == pytest.approx(box.x1 - anchor, abs=1.0)
