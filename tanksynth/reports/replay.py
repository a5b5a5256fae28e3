"""The report's section "On measured data": the replay of ``tanksynth replay`` (``DIR/replay.json``).

Each artefact replayed on each logged experiment gets its checks (verdict, detail) and a figure
of the measured outputs against the estimator's one-step predictions, with the NIS and its 95 %
chi-square quantile below for an estimator with a covariance, or the residual against the
threshold for a detector. The figures are drawn from the replay traces
(``DIR/replay/<artefact>__<experiment>.npz``, read bounded and only when their sha256 matches
the record: `tanksynth.verify.replay.read_replay`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from tanksynth.reports.check_names import check_title
from tanksynth.reports.figures import FigureFile, figure_stem
from tanksynth.reports.latex import Tex
from tanksynth.reports.prose import prose_latex

__all__ = ["replay_figures", "replay_view"]

_VERDICT = {True: r"\textcolor{passgreen}{pass}", False: r"\textcolor{failred}{\textbf{FAIL}}",
            None: r"\textcolor{infoblue}{info}"}


def _figure(entry: Mapping[str, Any], trace: Mapping[str, Any], target: Path) -> bool:
    """Draw one replay figure (outputs, then NIS or residual) into ``target``; False if nothing."""
    from matplotlib.figure import Figure

    from tanksynth.artefacts.atomic import atomic_write

    arr = trace.get("arrays") or {}
    head = trace.get("header") or {}
    t, y, yp = (np.asarray(arr.get(k), dtype=float) for k in ("t", "y", "y_pred"))
    if t.ndim != 1 or y.ndim != 2 or yp.shape != y.shape or y.shape[0] != t.size:
        return False
    names = [str(n) for n in head.get("y_names") or []][:y.shape[1]]
    names += [f"y{j + 1}" for j in range(len(names), y.shape[1])]
    units = [str(u) for u in head.get("y_units") or []][:y.shape[1]]
    units += [""] * (y.shape[1] - len(units))
    nis = np.asarray(arr.get("nis", np.full(t.size, np.nan)), dtype=float)
    residual = arr.get("residual")
    lower = residual is not None or bool(np.isfinite(nis).any())
    rows = y.shape[1] + (1 if lower else 0)
    fig = Figure(figsize=(6.4, 1.55 * rows + 0.6))
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    for j, ax in enumerate(axes[:y.shape[1]]):
        ax.plot(t, y[:, j], ".", ms=2.0, color="0.55", label="measured")
        ax.plot(t, yp[:, j], "-", lw=1.0, color="C0", label="one-step prediction")
        ax.set_ylabel(f"{names[j]} ({units[j]})" if units[j] else names[j])
        ax.grid(alpha=0.3)
        if j == 0:
            ax.legend(loc="best", fontsize=7, frameon=False)
    if lower:
        ax = axes[-1]
        if residual is not None:
            ax.plot(t, np.asarray(residual, dtype=float), "-", lw=0.8, color="C3", label="residual")
            ax.plot(t, np.asarray(arr.get("threshold"), dtype=float), "--", lw=1.0, color="k",
                    label="threshold")
            ax.set_ylabel(r"$\max_j\,|y_j - h_j(\hat{x})|$")
        else:
            from scipy import stats

            ax.plot(t, nis, ".", ms=2.0, color="C3", label="NIS")
            dofs = np.asarray(arr.get("nis_dof", np.full(t.size, np.nan)), dtype=float)
            if dofs.shape == t.shape and np.any(dofs > 0):
                # the quantile for the outputs actually used at each sample (a censored or
                # missing output leaves the update: fewer degrees of freedom there)
                used = dofs > 0
                q = np.where(used, stats.chi2.ppf(0.95, np.where(used, dofs, 1.0)), np.nan)
                kinds = sorted({int(d) for d in dofs[used]})
                label = ("95 % quantile, " + f"{kinds[0]} dof" if len(kinds) == 1 else
                         "95 % quantile for the outputs used at each sample ("
                         + ", ".join(str(k) for k in kinds) + " dof)")
                ax.plot(t, q, ls="--", lw=1.0, color="k", drawstyle="steps-mid", label=label)
            else:   # a trace written before the degrees of freedom were recorded
                dof = max(1, y.shape[1])
                ax.axhline(float(stats.chi2.ppf(0.95, dof)), ls="--", lw=1.0, color="k",
                           label=f"95 % quantile, {dof} dof")
            ax.set_yscale("log")
            ax.set_ylabel("NIS")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=7, frameon=False)
    axes[-1].set_xlabel("t (s)")
    fig.tight_layout()
    target.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(target, lambda fh: fig.savefig(fh, format="pdf",
                                                 metadata={"CreationDate": None, "Creator": "tanksynth"}))
    return True


def replay_figures(doc: Mapping[str, Any] | None, directory: Path, figdir: str) -> dict[int, FigureFile]:
    """Draw the figure of every replay entry whose trace was read (by entry index).

    Parameters
    ----------
    doc : mapping or None
        `tanksynth.verify.replay.read_replay`'s document (None: no replay, no figure).
    directory : Path
        The result directory.
    figdir : str
        The report's figure sub-directory (relative to ``directory``).

    Returns
    -------
    dict of int to FigureFile
    """
    out: dict[int, FigureFile] = {}
    if not doc:
        return out
    for i, entry in enumerate(doc.get("replays") or []):
        trace = entry.get("trace_data")
        if not trace:
            continue
        stem = figure_stem("replay", i, f"{entry.get('artefact', '')}-{entry.get('experiment', '')}")
        target = directory / figdir / f"{stem}.pdf"
        if _figure(entry, trace, target):
            caption = (f"{entry.get('artefact')} on {entry.get('experiment')}: measured outputs (dots) "
                       "and the one-step predictions of the estimate (lines)"
                       + ("; below, the residual and the stored threshold" if entry.get("kind") == "detector"
                          else "; below, the NIS per sample and its 95 % chi-square quantile"
                          if entry.get("kind") == "estimator" else ""))
            out[i] = FigureFile(target, f"{figdir}/{target.name}", caption, ())
    return out


def replay_view(doc: Mapping[str, Any] | None, figures: Mapping[int, FigureFile],
                current: Mapping[str, str] | None = None) -> dict[str, Any] | None:
    """The template's view of the replay: per artefact and log, the checks and the figure.

    Parameters
    ----------
    doc : mapping or None
        `tanksynth.verify.replay.read_replay`'s document.
    figures : mapping of int to FigureFile
        `replay_figures`.
    current : mapping of str to str, optional
        Each artefact's ``provenance.content_sha256`` now: an entry recorded for other content (the
        artefact was designed again after the replay, or is gone) is marked stale.

    Returns
    -------
    dict or None
        ``passed`` (Tex), ``files`` (name, samples, sha256), ``entries`` (artefact, method,
        experiment, verdict, checks, figure, caption, stale); None without a replay.
    """
    if not doc:
        return None
    entries = []
    for i, e in enumerate(doc.get("replays") or []):
        checks = [{"name": prose_latex(check_title(c.get("check", ""))),
                   "verdict": Tex(_VERDICT.get(c.get("passed"), _VERDICT[None])),
                   "detail": prose_latex(str(c.get("detail", "")))}
                  for c in e.get("checks") or [] if isinstance(c, Mapping)]
        fig = figures.get(i)
        stale = current is not None and current.get(str(e.get("artefact"))) != e.get("artefact_sha256")
        entries.append({"artefact": str(e.get("artefact", "")), "method": str(e.get("method", "")),
                        "experiment": str(e.get("experiment", "")), "kind": str(e.get("kind", "")),
                        "verdict": Tex(_VERDICT.get(e.get("passed"), _VERDICT[None])),
                        "checks": checks, "figure": fig,
                        "caption": prose_latex(fig.caption) if fig is not None else None,
                        "label": f"replay-{i}", "stale": stale})
    files = [{"name": str(f.get("name", "")), "samples": f.get("samples"),
              "sha256": str(f.get("sha256") or "")[:16]}
             for f in doc.get("files") or [] if isinstance(f, Mapping)]
    return {"passed": Tex(_VERDICT.get(doc.get("passed"), _VERDICT[None])), "files": files,
            "entries": entries}
