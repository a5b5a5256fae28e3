"""The residual autocorrelation figure of a fit (MATLAB's ``resid``), from its artefact.

The fit records, per output, the sample autocorrelation of its estimation residuals at lags
1..L and the 95 % band of white noise, ``+-1.96/sqrt(N)`` (``diagnostics.estimation.whiteness``,
the numbers of its Ljung-Box test). The figure draws them: one panel per output, the
autocorrelation as stems against the lag, the band dashed; residuals whose stems leave the band
are not white (unmodelled dynamics or coloured noise).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from tanksynth.artefacts.atomic import atomic_write
from tanksynth.reports.figure_layout import draw_decorations, stacked_layout
from tanksynth.reports.figures import FigureFile, figure_stem

__all__ = ["residual_acf", "residual_acf_figure", "acf_figures"]

_FIGURE_DIR = "report-figures"


def residual_acf(art: Mapping[str, Any]) -> list[tuple[str, np.ndarray, float, dict[str, Any]]]:
    """Each output's residual autocorrelation of a fit artefact, as recorded.

    Parameters
    ----------
    art : mapping
        An artefact (any method: only ``fit`` has the record).

    Returns
    -------
    list of (str, ndarray, float, dict)
        Output name, autocorrelation at lags 1..L (dimensionless), the white-noise band
        (dimensionless) and the output's whole whiteness record (``statistic``, ``bound``,
        ``samples``...); empty for another method or an artefact without the record.
    """
    diag = art.get("diagnostics")
    if art.get("method") != "fit" or not isinstance(diag, Mapping):
        return []
    est = diag.get("estimation")
    white = est.get("whiteness") if isinstance(est, Mapping) else None
    if not isinstance(white, Mapping):
        return []
    out = []
    for name, rec in white.items():
        if not isinstance(rec, Mapping):
            continue
        raw_band = rec.get("band")
        if not isinstance(raw_band, (int, float)) or isinstance(raw_band, bool):
            continue
        try:
            acf = np.asarray(rec.get("autocorrelation"), dtype=float).ravel()
        except (TypeError, ValueError):
            continue
        band = float(raw_band)
        if acf.size and np.all(np.isfinite(acf)) and np.isfinite(band):
            out.append((str(name), acf, band, dict(rec)))
    return out


def residual_acf_figure(art: Mapping[str, Any], directory: Path, stem: str) -> FigureFile | None:
    """Draw the residual autocorrelation of a fit artefact (`residual_acf`).

    Parameters
    ----------
    art : mapping
        The artefact.
    directory : Path
        The figures' directory (``DIR/report-figures``).
    stem : str
        File name without ``.pdf``.

    Returns
    -------
    FigureFile or None
        None when the artefact has no record.
    """
    series = residual_acf(art)
    if not series:
        return None
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 1.3 * len(series) + 0.7))
    axes = [fig.add_subplot(len(series), 1, k + 1) for k in range(len(series))]
    for ax, (name, acf, band, rec) in zip(axes, series):
        lags = np.arange(1, acf.size + 1)
        ax.vlines(lags, 0.0, acf, color="C0", linewidth=1.2)
        ax.plot(lags, acf, linestyle="none", marker="o", markersize=3, color="C0")
        ax.axhline(0.0, color="0.3", linewidth=0.6)
        for sign in (1.0, -1.0):
            ax.axhline(sign * band, color="C3", linestyle="--", linewidth=0.8)
        top = max(float(np.max(np.abs(acf))), band) * 1.15
        ax.set_ylim(-top, top)
        ax.set_xlim(0.3, acf.size + 0.7)
        q, bound = rec.get("statistic"), rec.get("bound")
        verdict = ""
        if isinstance(q, (int, float)) and isinstance(bound, (int, float)):
            verdict = f": Q = {q:.4g} {'>' if q > bound else '<='} {bound:.4g}"
        ax.set_title(f"{name} residual{verdict}", fontsize=8, y=1.0)
        ax.set_ylabel("autocorrelation", fontsize=7)
    axes[-1].set_xlabel("lag [samples]", fontsize=8)
    stacked_layout(fig, axes, tick_size=7)
    for ax in axes:
        draw_decorations(ax, tick_size=7, grid={"linewidth": 0.3, "color": "0.9"})
    directory.mkdir(parents=True, exist_ok=True)
    target = directory / f"{stem}.pdf"
    atomic_write(target, lambda fh: fig.savefig(fh, format="pdf",
                                                 metadata={"CreationDate": None, "Creator": "tanksynth"}))
    n = series[0][3].get("samples")
    caption = (f"Residual autocorrelation of design {art.get('name', '')} (fit) on the estimation data: "
               "sample autocorrelation of each output's residual (measured minus simulated) at lags 1 to "
               f"{series[0][1].size}, with the 95 % band of white noise, +-1.96/sqrt(N)"
               + (f" (N = {n})" if isinstance(n, int) else "") + " (dashed); stems outside the band: "
               "the residuals are not white (unmodelled dynamics or coloured noise). Q is the "
               "Ljung-Box statistic against its 95 % bound.")
    return FigureFile(target, f"{directory.name}/{stem}.pdf", caption, ())


def acf_figures(inputs: Any) -> dict[str, FigureFile]:
    """Draw the residual autocorrelation figure of every fit artefact of a report.

    Figures go to ``DIR/report-figures/acf-NN-<name>.pdf``; figures of artefacts that are gone
    are removed.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs (artefacts of the output directory).

    Returns
    -------
    dict
        Artefact name -> FigureFile.
    """
    figdir = Path(inputs.directory) / _FIGURE_DIR
    out: dict[str, FigureFile] = {}
    for i, art in enumerate(inputs.artefacts):
        fig = residual_acf_figure(art, figdir, figure_stem("acf", i, str(art.get("name", ""))))
        if fig is not None:
            out[str(art.get("name", ""))] = fig
    if figdir.is_dir():
        keep = {f.path.name for f in out.values()}
        for stale in figdir.glob("acf-*.pdf"):
            if stale.name not in keep:
                stale.unlink(missing_ok=True)
    return out
