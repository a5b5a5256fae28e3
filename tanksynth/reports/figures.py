"""Report figures (matplotlib, vector PDF): pole maps of the artefacts' eigenvalues.

Eigenvalue lists are found in an artefact's diagnostics by name (`tanksynth.reports.eigen_sets`: any key
containing ``eigenvalues``, at any depth, in the ``[re, im]`` pair
convention of `tanksynth.artefacts.io.to_jsonable`). Discrete-time sets (keys
naming ``Ad``, or diagnostics declaring a discrete domain) are drawn in the
z-plane with the unit circle, continuous ones in the s-plane with the
imaginary axis.

Time-domain figures (`time_domain_figure`) draw the trace that ``tanksynth
verify`` stores beside each artefact (``DIR/<name>.traces.npz``, see
`tanksynth.verify.traces.TraceRecorder.record`): levels with their references,
estimates against the true states and the estimation error when the
artefact is an estimator, and the inputs. An artefact without a trace file
simply has no time-domain figure; `time_domain_figures` also draws the file's
extra traces (another check's simulation, e.g. the H-infinity disturbance step).
A trace with further named signals (e.g. the fault detector's residual and
threshold) gets one more panel drawing them (`tanksynth.reports.signal_panel`).

Figures are drawn on `matplotlib.figure.Figure` objects and saved with
``Figure.savefig``: no pyplot state, no backend selection (``matplotlib.use``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.linalg import expm

from tanksynth.artefacts.atomic import atomic_write
from tanksynth.artefacts.traces import read_trace, trace_path
from tanksynth.reports.check_names import check_title
from tanksynth.reports.diagnostics.common import LmiRegion, lmi_region_of
from tanksynth.reports.eigen_sets import EigenvalueSet, eigen_label, eigenvalue_sets, is_pole_key
from tanksynth.reports.figure_layout import (TraceCanvas, draw_decorations, square_panels_layout,
                                              stacked_layout)
from tanksynth.reports.signal_panel import draw_signals
from tanksynth.reports.trace_lines import PanelLines

# matplotlib is imported inside the functions that draw (about 0.4 s), not at the top: the report
# imports this module for its records and helpers too, and needs matplotlib only for a figure it
# draws itself (not for those drawn ahead by `tanksynth.report_worker`).
__all__ = ["EigenvalueSet", "eigenvalue_sets", "eigen_label", "is_pole_key", "FigureFile", "pole_map",
           "TraceFigure", "time_domain_figure", "time_domain_figures", "ordinal", "figure_stem",
           "drawn_file_is"]


def ordinal(k: int) -> str:
    """``2`` -> ``2nd``, ``11`` -> ``11th``, ``23`` -> ``23rd``.

    Parameters
    ----------
    k : int
        The number.
    """
    k = int(k)
    suffix = "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")
    return f"{k}{suffix}"


def figure_stem(kind: str, index: int, name: str) -> str:
    """The file stem of a figure of the ``index``-th artefact: ``<kind>-<index>-<name>``, the
    name cut to 40 ASCII letters and digits (anything else a '-'), ``design`` when none is left.

    Parameters
    ----------
    kind : str
        The figure's kind (``"poles"``, ``"traces"``, ``"region"``, ``"linear"``).
    index : int
        The artefact's position in the report.
    name : str
        The artefact's name.
    """
    safe = "".join(c if (c.isascii() and c.isalnum()) else "-" for c in name).strip("-")[:40]
    return f"{kind}-{index:02d}-{safe or 'design'}"


@dataclass(frozen=True)
class FigureFile:
    """A figure written for the report.

    Attributes
    ----------
    path : Path
        The PDF file.
    relpath : str
        Path relative to the report directory, for ``\\includegraphics``.
    caption : str
        Plain text (escape before typesetting).
    sets : tuple of EigenvalueSet
    """

    path: Path
    relpath: str
    caption: str
    sets: tuple[EigenvalueSet, ...]


def _atomic_savefig(fig, target: Path) -> None:
    atomic_write(target, lambda fh: fig.savefig(fh, format="pdf",
                                                 metadata={"CreationDate": None, "Creator": "tanksynth"}))


_MARKERS = ("x", "o", "s", "^", "D", "v", "P", "*")
#: The pole maps' legends hang this fraction of the panel height below the panel.
_LEGEND_DROP = 0.2


def _region_margin(L: np.ndarray, M: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """``-lambda_max(L + M z + M' conj(z))`` on a grid of complex points (positive inside)."""
    z = Z.ravel()
    F = L[None, :, :] + M[None, :, :] * z[:, None, None] + M.T[None, :, :] * np.conj(z)[:, None, None]
    F = 0.5 * (F + np.conj(np.transpose(F, (0, 2, 1))))
    if F.shape[1] == 1:          # half-planes, vertical strips' sides ...: the entry itself
        return -F[:, 0, 0].real.reshape(Z.shape)
    if F.shape[1] == 2:          # disks, sectors' halves ...: the larger root of the 2 x 2 Hermitian
        a, d, b = F[:, 0, 0].real, F[:, 1, 1].real, F[:, 0, 1]
        top = 0.5 * (a + d) + np.hypot(0.5 * (a - d), np.abs(b))
        return -top.reshape(Z.shape)
    return -np.linalg.eigvalsh(F)[:, -1].reshape(Z.shape)


def _view(points: np.ndarray, disc: bool) -> tuple[float, float, float, float]:
    """Square axis limits around the poles (not the whole unit circle)."""
    re_, im = points.real, points.imag
    span = max(float(np.ptp(re_)), 2 * float(np.max(np.abs(im))),
               0.02 * max(1.0, float(np.max(np.abs(points)))))
    side = 1.5 * span
    cx = 0.5 * (float(re_.min()) + float(re_.max()))
    if not disc and float(re_.max()) < 0 and abs(float(re_.max())) <= span:
        side = max(side, 1.15 * abs(float(re_.min())))   # show the imaginary axis when near
        cx = float(re_.min()) / 2
    return cx - side / 2, cx + side / 2, -side / 2, side / 2


def _same_sets_merged(sets: Sequence[EigenvalueSet]) -> list[tuple[np.ndarray, str]]:
    """The sets to draw, equal ones (same eigenvalues to 1e-9 relative, e.g. ``requested`` and
    ``achieved`` of an exact placement) drawn once under their joined labels."""
    out: list[tuple[np.ndarray, list[str], np.ndarray]] = []
    for s in sets:
        v = np.array(s.values)
        key = np.sort_complex(v)
        for _, labels, other in out:
            if other.shape == key.shape and np.allclose(other, key, rtol=1e-9, atol=1e-12):
                if s.label not in labels:
                    labels.append(s.label)
                break
        else:
            out.append((v, [s.label], key))
    return [(v, " = ".join(labels)) for v, labels, _ in out]


def _pole_figure(artefact: Mapping[str, Any], sets: tuple[EigenvalueSet, ...],
                 region: LmiRegion | None) -> Any:
    """The pole map of `pole_map`, laid out, not saved (a `matplotlib.figure.Figure`)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch
    from matplotlib.ticker import MaxNLocator

    planes = [p for p in (False, True) if any(s.discrete == p for s in sets)]
    fig = Figure(figsize=(3.6 * len(planes) + 0.4, 4.1))
    for k, disc in enumerate(planes):
        ax = fig.add_subplot(1, len(planes), k + 1)
        chosen = [s for s in sets if s.discrete == disc]
        pts = np.concatenate([np.array(s.values) for s in chosen])
        x0, x1, y0, y1 = _view(pts, disc)
        handles: list[Any] = []   # the region's patch, then the poles' markers
        if region is not None and (region.domain == "discrete") == disc:
            L, M, desc = region.L, region.M, region.description
            X, Y = np.meshgrid(np.linspace(x0, x1, 240), np.linspace(y0, y1, 240))
            marg = _region_margin(L, M, X + 1j * Y)
            ax.contourf(X, Y, marg, levels=[0.0, np.inf], colors=["#cfe3f5"], alpha=0.8)
            ax.contour(X, Y, marg, levels=[0.0], colors=["#2a6db0"], linewidths=0.8)
            handles.append(Patch(facecolor="#cfe3f5", edgecolor="#2a6db0",
                                 label="requested region" + (f": {desc}" if desc and len(desc) < 50
                                                             else "")))
        for m, (v, label) in enumerate(_same_sets_merged(chosen)):
            (line,) = ax.plot(v.real, v.imag, linestyle="none", marker=_MARKERS[m % len(_MARKERS)],
                              markersize=7 - m, fillstyle="none", markeredgewidth=1.1, label=label)
            handles.append(line)
        if disc:
            t = np.linspace(0, 2 * np.pi, 2000)
            ax.plot(np.cos(t), np.sin(t), color="0.45", linewidth=0.8, label="_unit circle")
            ax.set_title("z-plane (discrete time)", fontsize=9, y=1.0)
        else:
            ax.axvline(0.0, color="0.45", linewidth=0.8)
            ax.set_title("s-plane (continuous time)", fontsize=9, y=1.0)
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal", adjustable="box")
        ax.axhline(0.0, color="0.85", linewidth=0.6)
        ax.set_xlabel("real part" + (" [1/s]" if not disc else ""), fontsize=8)
        ax.set_ylabel("imaginary part" + (" [1/s]" if not disc else ""), fontsize=8)
        ax.tick_params(labelsize=7)
        ax.ticklabel_format(useOffset=False)
        ax.xaxis.set_major_locator(MaxNLocator(5))
        ax.yaxis.set_major_locator(MaxNLocator(5))
        ax.legend(handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -_LEGEND_DROP),
                  ncol=1, frameon=False)
    # Square panels placed from the texts' metrics and the figure's height fitted to them (no
    # layout engine: tight_layout lays every tick out once more before savefig draws them, and
    # with equal aspect it left the legends below the panels cut off).
    square_panels_layout(fig, fig.axes, tick_size=7, legend_drop=_LEGEND_DROP)
    for ax in fig.axes:      # ticks, tick labels, grid and axis labels as a few plain artists
        draw_decorations(ax, tick_size=7, grid={"linewidth": 0.3, "color": "0.9"})
    return fig


def pole_map(artefact: Mapping[str, Any], directory: Path, stem: str) -> FigureFile | None:
    """Draw the eigenvalues of one artefact (s- and/or z-plane) to ``directory/stem.pdf``.

    Each plane is zoomed to its eigenvalues; the LMI region requested for
    the design (when the diagnostics record one) is shaded; the legend,
    with the sets named in words (`eigen_label`), sits below the axes.

    Parameters
    ----------
    artefact : mapping
        As read by `tanksynth.artefacts.io.read_artefact`.
    directory : Path
        Figure directory (created if missing).
    stem : str
        File name without extension (a safe ASCII name chosen by the caller).

    Returns
    -------
    FigureFile or None
        None when the artefact has no eigenvalues.
    """
    sets = eigenvalue_sets(artefact)
    if not sets:
        return None
    region = lmi_region_of(artefact.get("diagnostics") or {})
    fig = _pole_figure(artefact, sets, region)
    directory.mkdir(parents=True, exist_ok=True)
    target = directory / f"{stem}.pdf"
    _atomic_savefig(fig, target)
    caption = (f"Eigenvalues of design {artefact.get('name', '')} ({artefact.get('method', '')}), "
               "zoomed to the eigenvalues" + ("; shaded: the LMI region requested in the spec"
                                                if region is not None else "") + ".")
    return FigureFile(target, f"{directory.name}/{stem}.pdf", caption, sets)


def _linear_prediction(artefact: Mapping[str, Any], head: Mapping[str, Any], t: np.ndarray,
                       x: np.ndarray, u: np.ndarray) -> dict | None:
    """For a linearisation's verdict trace (first-order agreement): the deviation the stored
    linear model ``(F, B)`` predicts for the perturbed run (run 2 minus run 1), exact ZOH."""
    gains = artefact.get("gains") or {}
    if head.get("check") != "first_order_agreement" or "F" not in gains or "B" not in gains:
        return None
    if x.shape[0] < 2 or u.ndim != 3 or u.shape[0] < 2 or u.shape[1] < 1:
        return None
    F, B = np.asarray(gains["F"], float), np.asarray(gains["B"], float)
    n, m = F.shape[0], B.shape[1]
    if x.shape[2] != n or u.shape[2] != m:
        return None
    dx0 = x[1, 0] - x[0, 0]
    du = u[1, 0] - u[0, 0]
    aug = np.zeros((n + m, n + m))
    aug[:n, :n], aug[:n, n:] = F, B
    z0 = np.concatenate([dx0, du])
    steps = np.diff(t)
    if steps.size and np.allclose(steps, steps[0], rtol=1e-9, atol=0.0):
        # uniform samples: one expm, then z(k+1) = Phi z(k) (not one expm per sample)
        Phi = expm(aug * steps[0])
        z = np.empty((t.size, n + m))
        z[0] = z0
        for k in range(1, t.size):
            z[k] = Phi @ z[k - 1]
        pred = z[:, :n]
    else:
        pred = np.array([(expm(aug * (tk - t[0])) @ z0)[:n] for tk in t])
    nl = x[1] - x[0]
    return {"prediction": pred, "gap": float(np.max(np.abs(nl - pred))),
            "scale": float(np.max(np.abs(nl)))}


@dataclass(frozen=True)
class TraceFigure:
    """A time-domain figure of an artefact's verdict simulation.

    Attributes
    ----------
    path : Path
        The PDF file.
    relpath : str
        Path relative to the report directory, for ``\\includegraphics``.
    caption : str
        Plain text (escape before typesetting): the scenario and the verdict.
    scenario : str
    check : str
        The check the simulation decides.
    passed : bool or None
        That check's verdict.
    estimator : bool
        The figure shows estimates and estimation errors.
    """

    path: Path
    relpath: str
    caption: str
    scenario: str
    check: str
    passed: bool | None
    estimator: bool



def drawn_file_is(fig: Any, target: Path, kind: type[FigureFile] | type[TraceFigure] = FigureFile) -> bool:
    """Whether ``fig`` (a figure drawn ahead, e.g. by another process) is a ``kind`` whose file is
    ``target`` and exists: only then may it stand for the figure drawn here.

    Parameters
    ----------
    fig : object
        The figure drawn ahead (anything: a wrong type is not usable).
    target : Path
        ``DIR/report-figures/<stem>.pdf``.
    kind : type
        `FigureFile` or `TraceFigure`.

    Returns
    -------
    bool
    """
    if not isinstance(fig, kind):
        return False
    try:
        return Path(fig.path).resolve() == Path(target).resolve() and Path(target).is_file()
    except (OSError, TypeError):
        return False


def _word(passed: Any) -> str:
    if passed is True:
        return "pass"
    return "FAIL" if passed is False else "undecided"


#: Display units of the time-domain figures: SI unit -> (factor, shown unit).
_DISPLAY_UNITS = {"m^3/s": (1e3, "l/s"), "m3/s": (1e3, "l/s")}


def _display(unit: str) -> tuple[float, str]:
    return _DISPLAY_UNITS.get(str(unit).replace(" ", ""), (1.0, str(unit)))


def _plain_axis(ax) -> None:
    """No offset/multiplier text on the y axis (a constant signal reads 0.0278, not 1e-12+2.78e-5)."""
    from matplotlib.ticker import ScalarFormatter

    fmt = ScalarFormatter(useOffset=False)
    fmt.set_scientific(False)
    ax.yaxis.set_major_formatter(fmt)
    lo, hi = ax.dataLim.y0, ax.dataLim.y1
    if np.isfinite(lo) and np.isfinite(hi):
        mid = 0.5 * (lo + hi)
        if hi - lo <= 1e-6 * max(abs(mid), 1e-300):   # a constant signal (round-off only)
            half = 0.05 * abs(mid) if mid != 0 else 1.0
            ax.set_ylim(mid - half, mid + half)


def _unit_label(names: list, units: list, i: int) -> str:
    name = str(names[i]) if i < len(names) else f"#{i + 1}"
    unit = str(units[i]) if i < len(units) else ""
    return f"{name} [{unit}]" if unit else name


#: Legend entries of a time-domain panel before entries sharing a colour and line style merge.
_LEGEND_ROWS = 12
#: Text sizes (pt) of the time-domain figures, drawn 7.2 in wide and scaled to about 0.86 of that
#: in the report (0.95 of a 16.6 cm text width): tick labels and legends print at about 7.3 pt,
#: axis labels at 7.8 pt, titles at 8.6 pt.
_TICK_PT, _LEGEND_PT, _LABEL_PT, _TITLE_PT = 8.5, 8.5, 9.0, 10.0
#: Grey of the legend entries that name the runs (not a signal's colour).
_RUN_GREY = "0.35"


def _run_styles(runs: int) -> dict:
    """Line style of the runs after the first: one further run dashed, a bundle thin and faded."""
    if runs == 2:
        return {"linewidth": 0.8, "linestyle": "--", "alpha": 0.85}
    return {"linewidth": 0.5, "linestyle": "-", "alpha": 0.45}


def _run_handles(runs: int) -> tuple[list, list]:
    """Legend entries marking the runs (first run solid, the others as `_run_styles`); none for one
    run."""
    from matplotlib.lines import Line2D

    if runs < 2:
        return [], []
    st = _run_styles(runs)
    first = Line2D([], [], color=_RUN_GREY, linewidth=1.0)
    rest = Line2D([], [], color=_RUN_GREY, linewidth=st["linewidth"], linestyle=st["linestyle"],
                  alpha=None if st["alpha"] == 1.0 else st["alpha"])
    return [first, rest], ["run 1", "run 2" if runs == 2 else f"runs 2-{runs}"]


def _legend(ax, handles: list, labels: list, extra: tuple[list, list] = ([], [])) -> None:
    """Legend right of the panel; with more than `_LEGEND_ROWS` entries (the 10 colours repeat), one
    entry per colour and line style naming the signals drawn with it (``h1, h11, h21``)."""
    if len(handles) > _LEGEND_ROWS:
        from matplotlib.colors import to_hex

        groups: dict = {}
        for h, lab in zip(handles, labels):
            key = (to_hex(h.get_color()), str(h.get_linestyle()))
            groups.setdefault(key, (h, []))[1].append(lab)
        handles = [g[0] for g in groups.values()]
        labels = [", ".join(g[1]) if len(g[1]) <= 4 else
                  f"{g[1][0]}, {g[1][1]}, ..., {g[1][-1]} ({len(g[1])})" for g in groups.values()]
    ax.legend(handles + list(extra[0]), labels + list(extra[1]), fontsize=_LEGEND_PT, loc="upper left",
              bbox_to_anchor=(1.01, 1.0), frameon=False)


def time_domain_figure(artefact: Mapping[str, Any], artefact_dir: Path, directory: Path,
                       stem: str, *, canvas: TraceCanvas | None = None) -> TraceFigure | None:
    """Draw the stored verdict trace of one artefact to ``directory/stem.pdf`` (vector PDF).

    Subplots: states (levels) with their references, or, when the references are outputs that
    are not states (``y = kc h1`` in V), the states alone and the outputs with their references
    on an axis of their own, in output units; estimates against the
    true states and the estimation error when the trace has estimates; the
    inputs, each held to the end of the horizon (zero-order hold); the trace's further signals and
    their events when it has some (`tanksynth.reports.signal_panel.draw_signals`). The first run of
    the trace is drawn solid, a second run dashed, a bundle of further runs thin; the
    legends of the panels drawing runs name them (``run 1``, ``run 2``).

    Parameters
    ----------
    artefact : mapping
        As read by `tanksynth.artefacts.io.read_artefact` (its ``name``).
    artefact_dir : Path
        Directory holding the artefact and its ``<name>.traces.npz``.
    directory : Path
        Figure directory (created if missing).
    stem : str
        File name without extension (a safe ASCII name chosen by the caller).
    canvas : tanksynth.reports.figure_layout.TraceCanvas, optional
        Figures to reuse (`trace_figures` passes one for all the figures of a report); a new
        figure when omitted.

    Returns
    -------
    TraceFigure or None
        None when the artefact has no (readable) trace file.
    """
    figures = time_domain_figures(artefact, artefact_dir, directory, stem, canvas=canvas, extras=False)
    return figures[0] if figures else None


def time_domain_figures(artefact: Mapping[str, Any], artefact_dir: Path, directory: Path, stem: str, *,
                        canvas: TraceCanvas | None = None, extras: bool = True) -> tuple[TraceFigure, ...]:
    """Draw every trace stored for one artefact: the main one to ``directory/stem.pdf`` (as
    `time_domain_figure`), the K-th extra trace (`tanksynth.artefacts.traces`) to
    ``directory/stem-K.pdf``.

    Parameters
    ----------
    artefact, artefact_dir, directory, stem, canvas
        As `time_domain_figure`.
    extras : bool
        Draw the extra traces too.

    Returns
    -------
    tuple of TraceFigure
        The main figure first, then the extras drawn (an unreadable one is left out); empty
        when the artefact has no (readable) main trace.
    """
    name = str(artefact.get("name", ""))
    trace = read_trace(trace_path(Path(artefact_dir) / f"{name}.json", name))
    if trace is None:
        return ()
    main = _trace_figure(artefact, trace, directory, stem, canvas, False)
    if main is None:
        return ()
    more = [_trace_figure(artefact, tr, directory, f"{stem}-{k}", canvas, True)
            for k, tr in enumerate(trace["more"] if extras else [], start=1)]
    return (main, *(f for f in more if f is not None))


def _outputs_of(head: Mapping[str, Any], arr: Mapping[str, Any],
                x: np.ndarray) -> tuple[np.ndarray, list[str], list[str]] | None:
    """The trace's outputs ``(y, names, units)`` (`tanksynth.verify.traces.trace_of` keeps them when
    a reference names an output that is not a state); None when it has none or they do not fit
    (runs and samples of ``x``, one name per output)."""
    y = arr.get("y")
    names, units = head.get("output_names"), head.get("output_units")
    if y is None or arr.get("reference") is None or not isinstance(names, list):
        return None
    y = np.asarray(y, float)
    if y.ndim != 3 or y.shape[:2] != x.shape[:2] or len(names) != y.shape[2]:
        return None
    units = [str(v) for v in units] if isinstance(units, list) and len(units) == len(names) else [""] * len(names)
    return y, [str(v) for v in names], units


def _draw_references(lines: PanelLines, t: np.ndarray, ref: Any, rnames: list, names: list,
                     colors: list[str]) -> None:
    """The references, dashed, each in the colour of the signal it names (of ``names``)."""
    if ref is None or np.ndim(ref) != 2 or np.shape(ref)[0] != t.size:
        return
    for j in range(np.shape(ref)[1]):
        k = names.index(rnames[j]) if j < len(rnames) and rnames[j] in names else j
        lines.line(t, np.asarray(ref, float)[:, j], color=colors[k % len(colors)], linestyle="--",
                   linewidth=0.8, label=f"ref. {rnames[j] if j < len(rnames) else j + 1}")


def _trace_figure(artefact: Mapping[str, Any], trace: Mapping[str, Any], directory: Path, stem: str,
                  canvas: TraceCanvas | None, is_extra: bool) -> TraceFigure | None:
    """One trace (``{"header", "arrays"}``) drawn to ``directory/stem.pdf``; None if it is not
    drawable. ``is_extra``: an extra simulation of the verdict (its caption says so)."""
    name = str(artefact.get("name", ""))
    head, arr = trace["header"], trace["arrays"]
    t, x = np.asarray(arr["t"], float), np.asarray(arr["x"], float)
    if x.ndim != 3 or x.shape[1] != t.size or t.size < 2 or x.shape[0] < 1:
        return None
    u = np.asarray(arr.get("u", np.zeros((x.shape[0], 0, 0))), float)
    t_u = np.asarray(arr.get("t_u", t[:-1]), float)
    x_hat = arr.get("x_hat")
    if x_hat is not None and np.shape(x_hat) != x.shape:   # an edited file: not drawable
        return None
    ref = arr.get("reference")
    snames, sunits = list(head.get("state_names", [])), list(head.get("state_units", []))
    inames, iunits = list(head.get("input_names", [])), list(head.get("input_units", []))
    rnames = list(head.get("reference_names", []))
    # the inputs the header names as disturbances (a disturbance-step run) get a panel of their own
    m_u = u.shape[2] if u.ndim == 3 and u.shape[1] == t_u.size else 0
    dist = set(head.get("disturbance_names") or [])
    cols = {"inputs": [j for j in range(m_u) if j >= len(inames) or inames[j] not in dist]}
    cols["disturbances"] = [j for j in range(m_u) if j not in cols["inputs"]]
    outputs = _outputs_of(head, arr, x)
    panels = ["levels"] + (["outputs"] if outputs is not None else []) \
        + (["estimates", "error"] if x_hat is not None else []) \
        + [p for p in ("inputs", "disturbances") if cols[p]]
    lin = _linear_prediction(artefact, head, t, x, u)
    if lin is not None:
        panels = ["linear"] + [p for p in panels if p in cols]
    signals = arr.get("signals")     # further named signals (read_trace checked their shape)
    if signals is not None:
        panels.append("signals")
    fig, axes = (canvas or TraceCanvas()).axes(len(panels))
    colors = [f"C{i % 10}" for i in range(max(x.shape[2], u.shape[2] if u.ndim == 3 else 0, 1))]
    n = x.shape[2]
    state_unit = sunits[0] if sunits and all(v == sunits[0] for v in sunits) else ""
    runs_drawn = x.shape[0]
    further = _run_styles(runs_drawn)
    run_marks = _run_handles(runs_drawn)

    def sname(i: int) -> str:   # a state's legend entry: no unit when the axis label gives it
        return (str(snames[i]) if i < len(snames) else str(i + 1)) if state_unit else \
            _unit_label(snames, sunits, i)

    for ax, panel in zip(axes, panels):
        lines = PanelLines()      # every line of the panel: one collection, drawn in this order
        if panel != "signals" and ax.get_yscale() != "linear":   # a reused canvas' signal panel
            ax.set_yscale("linear")
        if panel == "signals":     # tick size first: a logarithmic panel fixes its ticks by it
            ax.tick_params(labelsize=_TICK_PT)
            lines, *events, several = draw_signals(ax, t, signals, head, further, label_size=_LABEL_PT,
                                                   title_size=_TITLE_PT)
            if ax.get_yscale() == "linear":
                _plain_axis(ax)
            marks = run_marks if several else ([], [])
            _legend(ax, lines.handles, lines.labels, (events[0] + marks[0], events[1] + marks[1]))
            continue
        if panel == "linear" and lin is not None:   # (listed only with a prediction)
            scale = float(lin["scale"])
            for i in range(n):
                lines.line(t, x[1, :, i] - x[0, :, i], color=colors[i], linewidth=1.1,
                           label=f"{snames[i] if i < len(snames) else i + 1} nonlinear")
                lines.line(t, lin["prediction"][:, i], color=colors[i], linewidth=1.0, linestyle="--",
                           label=f"{snames[i] if i < len(snames) else i + 1} linear model")
            ax.set_ylabel(f"deviation from $x_0$ [{state_unit}]" if state_unit else "deviation from $x_0$",
                          fontsize=_LABEL_PT)
            ax.set_title("response to a small step: nonlinear plant (solid) and linear model (dashed); "
                         f"largest gap {100 * float(lin['gap']) / max(scale, 1e-300):.2g} %", fontsize=_LABEL_PT,
                         y=1.0)
        elif panel == "levels":
            for i in range(n):
                lines.line(t, x[0, :, i], color=colors[i], linewidth=1.0, label=sname(i))
                lines.runs(t, x[1:, :, i], color=colors[i], **further)
            refs_here = ref is not None and outputs is None   # else drawn with the outputs
            if refs_here:
                _draw_references(lines, t, ref, rnames, snames, colors)
            ax.set_ylabel(f"states [{state_unit}]" if state_unit else "states", fontsize=_LABEL_PT)
            ax.set_title("plant (nonlinear)" + (" and references" if refs_here else ""), fontsize=_TITLE_PT,
                         y=1.0)
        elif panel == "outputs" and outputs is not None:   # (listed only with outputs)
            y, onames, ounits = outputs
            out_unit = ounits[0] if ounits and all(v == ounits[0] for v in ounits) else ""
            for i in range(y.shape[2]):
                lines.line(t, y[0, :, i], color=colors[i % len(colors)], linewidth=1.0,
                           label=onames[i] if out_unit else _unit_label(onames, ounits, i))
                lines.runs(t, y[1:, :, i], color=colors[i % len(colors)], **further)
            _draw_references(lines, t, ref, rnames, onames, colors)
            ax.set_ylabel(f"outputs [{out_unit}]" if out_unit else "outputs", fontsize=_LABEL_PT)
            ax.set_title("outputs y = h(x) and their references (dashed)", fontsize=_TITLE_PT, y=1.0)
        elif panel == "estimates":
            xh = np.asarray(x_hat, float)
            for i in range(n):
                lines.line(t, x[0, :, i], color=colors[i], linewidth=1.0,
                           label=f"{snames[i] if i < len(snames) else i + 1}")
                lines.line(t, xh[0, :, i], color=colors[i], linewidth=0.9, linestyle="--")
            ax.set_ylabel(f"state and estimate [{state_unit}]" if state_unit else "state and estimate",
                          fontsize=_LABEL_PT)
            ax.set_title("estimates (dashed) against the true states", fontsize=_TITLE_PT, y=1.0)
        elif panel == "error":
            err = np.asarray(x_hat, float) - x
            for i in range(n):
                lines.line(t, err[0, :, i], color=colors[i], linewidth=1.0,
                           label=f"{snames[i] if i < len(snames) else i + 1}")
                lines.runs(t, err[1:, :, i], color=colors[i], **further)
            ax.axhline(0.0, color="0.6", linewidth=0.6)
            ax.set_ylabel(f"estimate - state [{state_unit}]" if state_unit else "estimate - state",
                          fontsize=_LABEL_PT)
            ax.set_title("estimation error", fontsize=_TITLE_PT, y=1.0)
        else:
            shown = [_display(iunits[j] if j < len(iunits) else "") for j in cols[panel]]
            for k, j in enumerate(cols[panel]):
                lines.line(t_u, shown[k][0] * u[0, :, j], step=True, end=t[-1], color=colors[k % len(colors)],
                           linewidth=1.0, label=inames[j] if j < len(inames) else f"#{j + 1}")
                lines.runs(t_u, shown[k][0] * u[1:, :, j], step=True, end=t[-1],
                           color=colors[k % len(colors)], **further)
            same = {sh[1] for sh in shown}
            unit = same.pop() if len(same) == 1 else ""
            what = "flow" if unit == "l/s" else "input"
            if panel == "disturbances":   # normalised: w = 1 is one declared standard deviation
                what, unit = "disturbance w", "normalised"
            if unit == "l/s":     # the text and tables give m^3/s: name the conversion on the axis
                unit = r"l/s $= 10^{-3}\,$m$^3$/s"
            ax.set_ylabel(f"{what} [{unit}]" if unit else what, fontsize=_LABEL_PT)
            ax.set_title(f"{'declared disturbances' if panel == 'disturbances' else 'inputs'} (zero-order hold)",
                         fontsize=_TITLE_PT, y=1.0)
        lines.draw(ax)
        ax.tick_params(labelsize=_TICK_PT)    # also sets how many ticks fit (the locator's tick space)
        _plain_axis(ax)
        extra = run_marks if panel in ("levels", "outputs", "error", "inputs", "disturbances") else ([], [])
        if panel == "estimates":     # one entry for every dashed estimate
            from matplotlib.lines import Line2D

            extra = ([Line2D([], [], color=_RUN_GREY, linewidth=0.9, linestyle="--")], ["estimate"])
        _legend(ax, lines.handles, lines.labels, extra)
    axes[-1].set_xlabel("time t [s]", fontsize=_LABEL_PT)
    # Margins and label positions from the texts' metrics: no layout engine (tight_layout lays every
    # tick and legend out once more before savefig draws them); titles at y = 1 (no tick labels
    # above the panels: matplotlib's automatic title position would measure the ticks again).
    stacked_layout(fig, axes, tick_size=_TICK_PT)
    for ax in axes:      # ticks, tick labels, grid and axis labels as a few plain artists
        draw_decorations(ax, tick_size=_TICK_PT, grid={"linewidth": 0.3, "color": "0.9"})
    directory.mkdir(parents=True, exist_ok=True)
    target = directory / f"{stem}.pdf"
    _atomic_savefig(fig, target)
    scenario = str(head.get("scenario", ""))
    check = str(head.get("check", ""))
    passed = head.get("check_passed")
    verdict = head.get("verdict_passed")
    runs = int(head.get("runs", x.shape[0]))
    check_word = _word(passed) if passed is not None else "info"   # as the check tables say
    caption = (f"{'Further v' if is_extra else 'V'}erdict simulation of design {name} "
               f"({artefact.get('method', '')}) on the nonlinear "
               f"plant: {scenario}. Check {check_title(check)}: {check_word}; artefact verdict: {_word(verdict)}. "
               f"{runs} run{'s' if runs != 1 else ''} shown"
               + (" (the upper panel: run 2 minus run 1)" if lin is not None and runs == 2 else "")
               + (f", every {ordinal(int(head['stride']))} sample" if int(head.get("stride", 1)) > 1
                  else "") + ".")
    return TraceFigure(target, f"{directory.name}/{stem}.pdf", caption, scenario, check,
                       passed if isinstance(passed, bool) else None, x_hat is not None)
