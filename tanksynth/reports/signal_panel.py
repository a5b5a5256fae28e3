"""The panel of a trace's further named signals (e.g. a fault detector's residual and threshold).

A verdict trace may carry signals beside the states (`tanksynth.artefacts.traces`: array
``signals`` (runs, samples, k), header ``signal_names``, ``signal_units``, ``signal_styles``,
``signal_title``, ``events``). `draw_signals` draws them in one panel of a time-domain figure:
each signal in its own colour and line style, its first run as given and its further runs as the
figure's other panels draw further runs (a signal equal in every run, such as a threshold, once);
every event as a dotted vertical line named in the legend. Signals that are never negative and
span more than `LOG_DECADES` decades are drawn on a logarithmic axis (a decaying threshold and a
residual a thousand times smaller stay readable); their non-positive samples are left out there.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.reports.trace_lines import PanelLines

# matplotlib is imported inside the functions that draw (about 0.4 s), not at the top: the report
# imports this module for its records and helpers too, and needs matplotlib only for a figure it
# draws itself (not for those drawn ahead by `tanksynth.report_worker`).
__all__ = ["LOG_DECADES", "LOG_FLOOR", "draw_signals"]

#: Decades of positive values above which a never-negative signal panel is logarithmic.
LOG_DECADES = 3.0
#: Lowest value of a logarithmic signal panel, relative to its largest value (dimensionless).
LOG_FLOOR = 1e-12
#: Grey of the event markers (vertical dotted lines).
_EVENT_GREY = "0.4"


def _axis_label(names: list, units: list) -> str:
    shown = ", ".join(str(v) for v in names)
    same = {str(u) for u in units}
    if len(same) == 1 and units and str(units[0]):
        # many signals of one unit: the legend names them, the axis gives the unit
        return f"{shown} [{units[0]}]" if len(shown) <= 30 else f"[{units[0]}]"
    return ", ".join(f"{n} [{u}]" if u else str(n) for n, u in zip(names, units)) or shown


def draw_signals(ax: Any, t: np.ndarray, signals: np.ndarray, head: Mapping[str, Any],
                 further: Mapping[str, Any], *, label_size: float,
                 title_size: float) -> tuple[PanelLines, list, list, bool]:
    """Draw a trace's signals and events on ``ax`` (one line collection, see `PanelLines`).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        An empty panel with its tick label size set (its y scale is set here: linear or
        logarithmic; a logarithmic one gets the major ticks its locator chooses for that size).
    t : ndarray, shape (N,)
        Sample times (s).
    signals : ndarray, shape (R, N, k)
        The runs of the k signals (their units).
    head : mapping
        The trace header: ``signal_names``, ``signal_units``, ``signal_styles`` (matplotlib line
        styles, default solid), ``signal_title``, ``events`` (``[[t, label], ...]``, s).
        Signals whose names begin with the same word (``h1 measured``, ``h1 simulated``)
        are one quantity: they share a colour and differ by line style.
    further : mapping
        Line style of the runs after the first (width, dash pattern, alpha of the figure).
    label_size, title_size : float
        Font sizes (pt) of the axis label and the title.

    Returns
    -------
    lines : PanelLines
        The panel's lines, already drawn (their legend handles and labels).
    handles, labels : list, list
        Legend entries of the event markers.
    several_runs : bool
        Some signal differs between runs (the legend should name the runs).
    """
    from matplotlib.lines import Line2D

    sig = np.asarray(signals, dtype=float)
    k = sig.shape[2]
    names = [str(v) for v in head.get("signal_names", [])][:k]
    names += [f"signal {j + 1}" for j in range(len(names), k)]
    units = [str(v) for v in (head.get("signal_units") or [])][:k]
    units += [""] * (k - len(units))
    styles = [str(v) for v in (head.get("signal_styles") or [])][:k]
    styles += ["-"] * (k - len(styles))
    finite = sig[np.isfinite(sig)]
    positive = finite[finite > 0]
    log = bool(finite.size and positive.size and finite.min() >= 0
               and np.log10(positive.max() / positive.min()) > LOG_DECADES)
    ax.set_yscale("log" if log else "linear")
    shown = np.where(sig > 0, sig, np.nan) if log else sig
    lines = PanelLines()
    several = False
    # signals of one quantity ("h1 measured", "h1 simulated") share a colour, told apart by style
    quantity = [name.split(" ", 1)[0] for name in names]
    palette = {q: i for i, q in enumerate(dict.fromkeys(quantity))}
    for j in range(k):
        color = f"C{palette[quantity[j]] % 10}"
        lines.line(t, shown[0, :, j], color=color, linewidth=1.0, linestyle=styles[j], label=names[j])
        rest = sig[1:, :, j]
        if rest.size and not np.array_equal(rest, np.broadcast_to(sig[:1, :, j], rest.shape), equal_nan=True):
            several = True
            style = dict(further)
            if styles[j] != "-":
                style["linestyle"] = ":"
            lines.runs(t, shown[1:, :, j], color=color, **style)
    lines.draw(ax)
    if log:
        from matplotlib.ticker import FixedLocator

        top = float(positive.max())     # a factor 2 of room above and below the values
        lo, hi = max(float(positive.min()), LOG_FLOOR * top) / 2.0, 2.0 * top
        ax.set_ylim(lo, hi)
        # the locator's decades inside the limits only (its list reaches a decade beyond them)
        ticks = [v for v in ax.yaxis.get_major_locator().tick_values(lo, hi) if lo <= v <= hi]
        ax.yaxis.set_major_locator(FixedLocator(ticks))
    handles: list = []
    labels: list = []
    for event in head.get("events") or []:
        try:
            te, text = float(event[0]), str(event[1])
        except (TypeError, ValueError, IndexError):
            continue
        if not (np.isfinite(te) and t[0] <= te <= t[-1]):
            continue
        ax.axvline(te, color=_EVENT_GREY, linestyle=":", linewidth=0.9)
        handles.append(Line2D([], [], color=_EVENT_GREY, linestyle=":", linewidth=0.9))
        labels.append(text)
    ax.set_ylabel(_axis_label(names, units), fontsize=label_size)
    ax.set_title(str(head.get("signal_title") or "further signals"), fontsize=title_size, y=1.0)
    return lines, handles, labels, several
