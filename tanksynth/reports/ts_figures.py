"""Certified-region figures of the Takagi-Sugeno PDC designs (matplotlib, vector PDF).

The certificate of ``ts_state_feedback`` / ``ts_output_feedback`` is the
level set ``{x : (x - x_op)' P (x - x_op) <= c}`` (the slice ``eps = 0``
with an observer) inside the TS domain. `region_figure` draws it in the
plant's units, one panel per pair of states: the slice through the
operating point (solid) and the projection of the whole ellipsoid
(dashed, shaded), the domain box and the flow orderings that involve only
that pair, the operating point, and, from the verdict's trace
(``DIR/<name>.traces.npz``), the sampled initial states and their
trajectories. A design with a set-point change adds the region about
``x_op2``, the new operating point and the switched trajectories.

Read from the artefact's gains (``P``, ``x0``, ``region_c``, and ``sp_``
for the set-point) and diagnostics (the domain); nothing is recomputed
but the ellipses' parametrisation.
"""

from __future__ import annotations

from itertools import combinations
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from tanksynth.artefacts.atomic import atomic_write
from tanksynth.artefacts.traces import read_trace, trace_path
from tanksynth.reports.diagnostics.takagi_sugeno import certified_region_of, ts_model_of
from tanksynth.reports.figure_layout import draw_decorations, square_grid_layout
from tanksynth.reports.figures import FigureFile, drawn_file_is, figure_stem
from tanksynth.reports.latex import NOTATION

# matplotlib is imported inside the functions that draw (about 0.4 s), not at the top: the report
# imports this module for its records and helpers too, and needs matplotlib only for a figure it
# draws itself (not for those drawn ahead by `tanksynth.report_worker`).
__all__ = ["REGION_METHODS", "ellipse_outline", "region_figure", "region_figures"]

#: Methods whose artefacts have a certified-region figure.
REGION_METHODS = ("ts_state_feedback", "ts_output_feedback")
#: The operating point and the set-point as the report writes them (matplotlib mathtext).
X0, X02 = NOTATION["x_op"], NOTATION["x_op2"]

_FIGURE_DIR = "report-figures"


def ellipse_outline(M: np.ndarray, c: float, centre: np.ndarray, points: int = 240) -> np.ndarray:
    """Points of the ellipse ``{z : (z - centre)' M (z - centre) = c}`` in the plane, shape (points, 2).

    Parameters
    ----------
    M : ndarray, shape (2, 2)
        Positive definite matrix (per squared state unit).
    c : float
        Level (dimensionless: the units of ``e' P e``).
    centre : ndarray, shape (2,)
        Centre (state units).
    points : int, optional
        Number of points on the outline.
    """
    lam, V = np.linalg.eigh(0.5 * (M + M.T))
    t = np.linspace(0.0, 2.0 * np.pi, points)
    circle = np.stack([np.cos(t), np.sin(t)], axis=1) * np.sqrt(c / lam)
    return centre + circle @ V.T


def _gain(art: Mapping[str, Any], key: str) -> np.ndarray | None:
    v = (art.get("gains") or {}).get(key)
    return None if v is None else np.asarray(v, dtype=float)


def _certificate(art: Mapping[str, Any], prefix: str = "") -> tuple[np.ndarray, np.ndarray, float] | None:
    """``(P, x_op, c)`` of the region stored as the gains ``<prefix>P``, ``<prefix>x_op`` and
    ``<prefix>region_c``; None when one is missing or their sizes do not match."""
    P, x0, c = (_gain(art, prefix + key) for key in ("P", "x_op", "region_c"))
    if P is None or x0 is None or c is None or P.size != x0.size ** 2 or c.size == 0:
        return None
    n = x0.size
    return P.reshape(n, n), x0.ravel(), float(np.ravel(c)[0])


def _pair_views(P: np.ndarray, c: float, x0: np.ndarray, i: int, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Slice through ``x0`` (other deviations zero) and projection of the ellipsoid on (i, j)."""
    idx = [i, j]
    slice_ = ellipse_outline(P[np.ix_(idx, idx)], c, x0[idx])
    proj = ellipse_outline(np.linalg.inv(np.linalg.inv(P)[np.ix_(idx, idx)]), c, x0[idx])
    return slice_, proj


def region_figure(art: Mapping[str, Any], artefact_dir: Path, directory: Path,
                  stem: str) -> FigureFile | None:
    """Draw the certified region of a TS PDC artefact to ``directory/stem.pdf``.

    Parameters
    ----------
    art : mapping
        The artefact (as read by `tanksynth.artefacts.io.read_artefact`).
    artefact_dir : Path
        Directory holding the artefact and its trace.
    directory : Path
        Figure directory (created if missing).
    stem : str
        File name without extension.

    Returns
    -------
    FigureFile or None
        None for other methods or an artefact without a region.
    """
    if str(art.get("method", "")) not in REGION_METHODS:
        return None
    region = _certificate(art)
    if region is None:
        return None
    P, x0, c = region
    n = x0.size
    diag = art.get("diagnostics") or {}
    states = certified_region_of(diag).states
    names = list(states) if len(states) == n else [f"x{k + 1}" for k in range(n)]
    domain = ts_model_of(diag).domain
    # names or a box of another size than the state belong to another model: not used
    lo = domain.lower if domain.lower is not None and len(domain.lower) == n else None
    hi = domain.upper if domain.upper is not None and len(domain.upper) == n else None
    name = str(art.get("name", ""))
    trace = read_trace(trace_path(Path(artefact_dir) / f"{name}.json", name))
    units = [""] * n
    X = Xs = None
    if trace is not None:
        units = (list(trace["header"].get("state_units") or []) + [""] * n)[:n]
        X = np.asarray(trace["arrays"]["x"], float)
        if "setpoint_x" in trace["arrays"]:
            Xs = np.asarray(trace["arrays"]["setpoint_x"], float)
    second = _certificate(art, "sp_")      # the region about the set-point x_op2, if any
    if second is not None and second[1].size != n:
        second = None
    has_sp = second is not None
    pairs = list(combinations(range(n), 2))[:6]
    if not pairs:
        return None
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    cols = min(3, len(pairs))
    rows = int(np.ceil(len(pairs) / cols))
    fig = Figure(figsize=(2.75 * cols + 0.3, 2.75 * rows + 0.9))
    for k, (i, j) in enumerate(pairs):
        ax = fig.add_subplot(rows, cols, k + 1)
        if lo is not None and hi is not None:
            ax.add_patch(Rectangle((lo[i], lo[j]), hi[i] - lo[i], hi[j] - lo[j], fill=False,
                                   edgecolor="0.35", linewidth=0.9, label="TS domain"))
        for row in domain.inequalities:   # orderings G x >= g involving only this pair
            G = np.asarray(row.G, float)
            if G.size == n and np.count_nonzero(G) == 2 and G[i] != 0 and G[j] != 0:
                xs = np.linspace(lo[i] if lo else x0[i] - 1, hi[i] if hi else x0[i] + 1, 2)
                ax.plot(xs, (row.g - G[i] * xs) / G[j], color="0.35", linestyle=":",
                        linewidth=0.9, label="domain ordering")
        if X is not None and X.ndim == 3 and X.shape[2] == n:   # every run: one collection
            ax.add_collection(LineCollection(list(X[:, :, [i, j]]), colors="C0", linewidths=0.4, alpha=0.55,
                                             label="verdict trajectories"), autolim=False)
            ax.plot(X[:, 0, i], X[:, 0, j], linestyle="none", marker="o", markersize=2.2, color="C0",
                    label="sampled initial states")
        sl, pr = _pair_views(P, c, x0, i, j)
        ax.fill(pr[:, 0], pr[:, 1], color="C2", alpha=0.12, linewidth=0)
        ax.plot(pr[:, 0], pr[:, 1], color="C2", linestyle="--", linewidth=0.8, label="region (projection)")
        ax.plot(sl[:, 0], sl[:, 1], color="C2", linewidth=1.2, label=f"region (slice at ${X0}$)")
        ax.plot([x0[i]], [x0[j]], marker="+", markersize=9, color="k", linestyle="none",
                label=f"operating point ${X0}$")
        if second is not None:
            P2, x2, c2 = second
            if Xs is not None and Xs.ndim == 3 and Xs.shape[2] == n:
                ax.add_collection(LineCollection(list(Xs[:, :, [i, j]]), colors="C3", linewidths=0.4, alpha=0.5,
                                                 label="set-point runs"), autolim=False)
            sl2, pr2 = _pair_views(P2, c2, x2, i, j)
            ax.plot(pr2[:, 0], pr2[:, 1], color="C1", linestyle="--", linewidth=0.8,
                    label=f"region about ${X02}$ (projection)")
            ax.plot(sl2[:, 0], sl2[:, 1], color="C1", linewidth=1.2, label=f"region about ${X02}$ (slice)")
            ax.plot([x2[i]], [x2[j]], marker="x", markersize=7, color="C1", linestyle="none",
                    label=f"set-point ${X02}$")
        ax.set_xlabel(f"{names[i]} [{units[i]}]" if units[i] else names[i], fontsize=8)
        ax.set_ylabel(f"{names[j]} [{units[j]}]" if units[j] else names[j], fontsize=8)
        box = np.vstack([pr] + ([pr2] if has_sp else []))
        bmin, bmax = box.min(axis=0), box.max(axis=0)
        if lo is not None and hi is not None:
            dspan = max(hi[i] - lo[i], hi[j] - lo[j])
            if float(np.max(bmax - bmin)) >= 0.4 * dspan:      # the region fills the domain
                bmin, bmax = np.array([lo[i], lo[j]]), np.array([hi[i], hi[j]])
        half = 0.5 * float(np.max(bmax - bmin)) * 1.12
        mid = 0.5 * (bmin + bmax)
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[1] - half, mid[1] + half)
        ax.set_aspect("equal", adjustable="box")
        ax.tick_params(labelsize=7)
    handles, labels = fig.axes[0].get_legend_handles_labels()
    seen = dict(zip(labels, handles))
    for ax in fig.axes[1:]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    legend = fig.legend(list(seen.values()), list(seen.keys()), loc="lower center", ncol=3, fontsize=7,
                        frameon=False)
    # panels placed from the texts' metrics above the legend (no layout engine: tight_layout lays
    # every tick out once more before savefig draws them)
    square_grid_layout(fig, fig.axes, cols=cols, tick_size=7, legend=legend)
    for ax in fig.axes:          # ticks, tick labels, grid and axis labels as a few plain artists
        draw_decorations(ax, tick_size=7, grid={"linewidth": 0.3, "color": "0.9"})
    directory.mkdir(parents=True, exist_ok=True)
    target = directory / f"{stem}.pdf"
    atomic_write(target, lambda fh: fig.savefig(fh, format="pdf",
                                                 metadata={"CreationDate": None, "Creator": "tanksynth"}))
    slice_word = "the slice eps = 0 of the composite certificate, " if art.get("method") == \
        "ts_output_feedback" else ""
    zoom = ("; panels zoomed to the region where it is small against the domain"
            if lo is not None else "")
    caption = (f"Certified region of design {name} ({art.get('method', '')}): {{(x - x_op)' P (x - x_op) "
               f"<= c}} with c = {c:.4g}, {slice_word}cut through the operating point (solid) and "
               "projected (dashed, shaded) on each pair of states, inside the TS domain (grey)"
               + ("; the verdict's sampled initial states and their trajectories on the nonlinear "
                  "plant" if X is not None else "; no verdict trace yet (tanksynth verify)")
               + ("; the region about the set-point x_op2 (orange) and the set-point runs (red)"
                  if has_sp else "") + zoom + ".")
    return FigureFile(target, f"{directory.name}/{stem}.pdf", caption, ())


def region_figures(inputs: Any, drawn: Mapping[str, Any] | None = None) -> dict[str, FigureFile]:
    """Draw the certified-region figure of every TS PDC artefact of a report.

    Figures go to ``DIR/report-figures/region-NN-<name>.pdf``; figures of
    artefacts that are gone are removed.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (artefacts of the output directory).
    drawn : mapping, optional
        Figures drawn ahead from these inputs (file stem ``region-NN-<name>`` ->
        FigureFile, e.g. by another process): used when one is this directory's
        file of that stem; the others are drawn here.

    Returns
    -------
    dict
        Artefact name -> FigureFile.
    """
    figdir = Path(inputs.directory) / _FIGURE_DIR
    drawn = drawn or {}
    out: dict[str, FigureFile] = {}
    for i, art in enumerate(inputs.artefacts):
        name = str(art.get("name", ""))
        stem = figure_stem("region", i, name)
        fig = drawn.get(stem)
        if not drawn_file_is(fig, figdir / f"{stem}.pdf"):
            fig = region_figure(art, Path(inputs.directory), figdir, stem)
        if fig is not None:
            out[name] = fig
    if figdir.is_dir():
        keep = {f.path.name for f in out.values()}
        for stale in figdir.glob("region-*.pdf"):
            if stale.name not in keep:
                stale.unlink(missing_ok=True)
    return out
