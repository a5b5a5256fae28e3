"""Report figures (matplotlib, vector PDF): pole maps of the artefacts' eigenvalues.

Eigenvalue lists are found in an artefact's diagnostics by name (any key
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
simply has no time-domain figure.

Figures are drawn on `matplotlib.figure.Figure` objects and saved with
``Figure.savefig``: no pyplot state, no backend selection (``matplotlib.use``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np

from tanksynth.artefacts.atomic import atomic_write

__all__ = ["EigenvalueSet", "eigenvalue_sets", "is_pole_key", "FigureFile", "pole_map", "TraceFigure",
           "time_domain_figure"]

#: Keys whose eigenvalues are not poles of a dynamic system (LMI blocks, matrices P, Q, X ...).
_NOT_POLES = ("lmi", "residual", "covariance", "_P", "_Q", "_X", "hessian")


@dataclass(frozen=True)
class EigenvalueSet:
    """Eigenvalues found in an artefact.

    Attributes
    ----------
    path : str
        Dotted key path in the diagnostics (``lmi.closed_loop_eigenvalues``).
    values : tuple of complex
    discrete : bool
        z-plane (True) or s-plane (False).
    """

    path: str
    values: tuple[complex, ...]
    discrete: bool


def _as_complex(values: Any) -> tuple[complex, ...] | None:
    if not isinstance(values, list) or not values:
        return None
    out = []
    for v in values:
        if isinstance(v, (list, tuple)) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v):
            out.append(complex(float(v[0]), float(v[1])))
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(complex(float(v), 0.0))
        else:
            return None
    return tuple(out)


def is_pole_key(key: str) -> bool:
    """True for diagnostics keys that name eigenvalues or poles of a dynamic system.

    ``*eigenvalue*``, ``poles``, ``*_poles``, ``achieved``, ``requested``;
    not LMI-block or matrix eigenvalues (``lmi_eigenvalues`` ...).
    """
    k = str(key)
    if any(bad in k for bad in _NOT_POLES):
        return False
    return "eigenvalue" in k or k in ("poles", "achieved", "requested") or k.endswith("_poles")


def _walk(node: Any, path: str, discrete: bool | None) -> Iterator[EigenvalueSet]:
    if not isinstance(node, Mapping):
        return
    dom = node.get("time_domain", node.get("domain"))
    if isinstance(dom, str) and dom in ("discrete", "continuous"):
        discrete = dom == "discrete"
    for key, value in node.items():
        sub = f"{path}.{key}" if path else str(key)
        k = str(key)
        if is_pole_key(k):
            vals = _as_complex(value)
            if vals:
                if "Ad" in k or "discrete" in k:
                    disc = True
                elif k.endswith("_F") or "continuous" in k:
                    disc = False
                else:
                    disc = bool(discrete)
                yield EigenvalueSet(sub, vals, disc)
        elif isinstance(value, Mapping):
            yield from _walk(value, sub, discrete)


def eigenvalue_sets(artefact: Mapping[str, Any]) -> tuple[EigenvalueSet, ...]:
    """Every eigenvalue list in an artefact's diagnostics (see module docstring)."""
    diag = artefact.get("diagnostics") or {}
    return tuple(_walk(diag, "", None))


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


def pole_map(artefact: Mapping[str, Any], directory: Path, stem: str) -> FigureFile | None:
    """Draw the eigenvalues of one artefact (s- and/or z-plane) to ``directory/stem.pdf``.

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
    from matplotlib.figure import Figure

    planes = [p for p in (False, True) if any(s.discrete == p for s in sets)]
    fig = Figure(figsize=(3.4 * len(planes) + 0.4, 3.4))
    for k, disc in enumerate(planes):
        ax = fig.add_subplot(1, len(planes), k + 1)
        chosen = [s for s in sets if s.discrete == disc]
        for m, s in enumerate(chosen):
            v = np.array(s.values)
            ax.plot(v.real, v.imag, linestyle="none", marker=_MARKERS[m % len(_MARKERS)],
                    markersize=6, fillstyle="none", label=s.path.replace("_", " "))
        if disc:
            t = np.linspace(0, 2 * np.pi, 400)
            ax.plot(np.cos(t), np.sin(t), color="0.6", linewidth=0.8)
            ax.set_title("z-plane (discrete time)", fontsize=9)
            ax.set_aspect("equal", adjustable="datalim")
        else:
            ax.axvline(0.0, color="0.6", linewidth=0.8)
            ax.set_title("s-plane (continuous time)", fontsize=9)
        ax.axhline(0.0, color="0.85", linewidth=0.6)
        ax.set_xlabel("Re", fontsize=8)
        ax.set_ylabel("Im", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, linewidth=0.3, color="0.9")
        ax.legend(fontsize=6, loc="best")
    fig.tight_layout()
    directory.mkdir(parents=True, exist_ok=True)
    target = directory / f"{stem}.pdf"
    _atomic_savefig(fig, target)
    caption = f"Eigenvalues of design {artefact.get('name', '')} ({artefact.get('method', '')})."
    return FigureFile(target, f"{directory.name}/{stem}.pdf", caption, sets)


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


def _word(passed: Any) -> str:
    if passed is True:
        return "pass"
    return "FAIL" if passed is False else "undecided"


def _unit_label(names: list, units: list, i: int) -> str:
    name = str(names[i]) if i < len(names) else f"#{i + 1}"
    unit = str(units[i]) if i < len(units) else ""
    return f"{name} [{unit}]" if unit else name


def time_domain_figure(artefact: Mapping[str, Any], artefact_dir: Path, directory: Path,
                       stem: str) -> TraceFigure | None:
    """Draw the stored verdict trace of one artefact to ``directory/stem.pdf`` (vector PDF).

    Subplots: states (levels) with their references; estimates against the
    true states and the estimation error when the trace has estimates; the
    inputs. The first run of the trace is drawn solid, further runs thin.

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

    Returns
    -------
    TraceFigure or None
        None when the artefact has no (readable) trace file.
    """
    from tanksynth.artefacts.traces import read_trace, trace_path

    name = str(artefact.get("name", ""))
    trace = read_trace(trace_path(Path(artefact_dir) / f"{name}.json", name))
    if trace is None:
        return None
    head, arr = trace["header"], trace["arrays"]
    t, x = np.asarray(arr["t"], float), np.asarray(arr["x"], float)
    if x.ndim != 3 or x.shape[1] != t.size or t.size < 2:
        return None
    u = np.asarray(arr.get("u", np.zeros((x.shape[0], 0, 0))), float)
    t_u = np.asarray(arr.get("t_u", t[:-1]), float)
    x_hat = arr.get("x_hat")
    ref = arr.get("reference")
    snames, sunits = list(head.get("state_names", [])), list(head.get("state_units", []))
    inames, iunits = list(head.get("input_names", [])), list(head.get("input_units", []))
    rnames = list(head.get("reference_names", []))
    from matplotlib.figure import Figure

    panels = ["levels"] + (["estimates", "error"] if x_hat is not None else []) \
        + (["inputs"] if u.ndim == 3 and u.shape[2] > 0 and u.shape[1] == t_u.size else [])
    fig = Figure(figsize=(6.4, 1.9 * len(panels) + 0.4))
    axes = [fig.add_subplot(len(panels), 1, k + 1) for k in range(len(panels))]
    colors = [f"C{i % 10}" for i in range(max(x.shape[2], u.shape[2] if u.ndim == 3 else 0, 1))]
    n = x.shape[2]
    state_unit = sunits[0] if sunits and all(v == sunits[0] for v in sunits) else ""
    for ax, panel in zip(axes, panels):
        if panel == "levels":
            for r in range(x.shape[0]):
                for i in range(n):
                    ax.plot(t, x[r, :, i], color=colors[i], linewidth=1.0 if r == 0 else 0.5,
                            alpha=1.0 if r == 0 else 0.45,
                            label=_unit_label(snames, sunits, i) if r == 0 else None)
            if ref is not None and np.ndim(ref) == 2 and np.shape(ref)[0] == t.size:
                for j in range(np.shape(ref)[1]):
                    k = snames.index(rnames[j]) if j < len(rnames) and rnames[j] in snames else j
                    ax.plot(t, np.asarray(ref)[:, j], color=colors[k % len(colors)], linestyle="--",
                            linewidth=0.8, label=f"ref. {rnames[j] if j < len(rnames) else j + 1}")
            ax.set_ylabel(f"states [{state_unit}]" if state_unit else "states", fontsize=8)
            ax.set_title("plant (nonlinear)" + (" and references" if ref is not None else ""), fontsize=9)
        elif panel == "estimates":
            xh = np.asarray(x_hat, float)
            for i in range(n):
                ax.plot(t, x[0, :, i], color=colors[i], linewidth=1.0, label=f"{snames[i] if i < len(snames) else i + 1}")
                ax.plot(t, xh[0, :, i], color=colors[i], linewidth=0.9, linestyle="--",
                        label=f"{snames[i] if i < len(snames) else i + 1} estimate")
            ax.set_ylabel(f"x, x_hat [{state_unit}]" if state_unit else "x, x_hat", fontsize=8)
            ax.set_title("estimates (dashed) against the true states", fontsize=9)
        elif panel == "error":
            err = np.asarray(x_hat, float) - x
            for r in range(err.shape[0]):
                for i in range(n):
                    ax.plot(t, err[r, :, i], color=colors[i], linewidth=1.0 if r == 0 else 0.5,
                            alpha=1.0 if r == 0 else 0.45,
                            label=f"{snames[i] if i < len(snames) else i + 1}" if r == 0 else None)
            ax.axhline(0.0, color="0.6", linewidth=0.6)
            ax.set_ylabel(f"x_hat - x [{state_unit}]" if state_unit else "x_hat - x", fontsize=8)
            ax.set_title("estimation error", fontsize=9)
        else:
            for r in range(u.shape[0]):
                for j in range(u.shape[2]):
                    ax.step(t_u, u[r, :, j], where="post", color=colors[j % len(colors)],
                            linewidth=1.0 if r == 0 else 0.5, alpha=1.0 if r == 0 else 0.45,
                            label=_unit_label(inames, iunits, j) if r == 0 else None)
            ax.set_ylabel("inputs", fontsize=8)
            ax.set_title("inputs (zero-order hold)", fontsize=9)
        ax.tick_params(labelsize=7)
        ax.grid(True, linewidth=0.3, color="0.9")
        ax.legend(fontsize=6, loc="best", ncol=2)
    axes[-1].set_xlabel("t [s]", fontsize=8)
    fig.tight_layout()
    directory.mkdir(parents=True, exist_ok=True)
    target = directory / f"{stem}.pdf"
    _atomic_savefig(fig, target)
    scenario = str(head.get("scenario", ""))
    check = str(head.get("check", ""))
    passed = head.get("check_passed")
    verdict = head.get("verdict_passed")
    runs = int(head.get("runs", x.shape[0]))
    caption = (f"Verdict simulation of design {name} ({artefact.get('method', '')}) on the nonlinear "
               f"plant: {scenario}. Check {check}: {_word(passed)}; artefact verdict: {_word(verdict)}. "
               f"{runs} run{'s' if runs != 1 else ''} shown"
               + (f", every {int(head['stride'])}th sample" if int(head.get("stride", 1)) > 1 else "")
               + ".")
    return TraceFigure(target, f"{directory.name}/{stem}.pdf", caption, scenario, check,
                       passed if isinstance(passed, bool) else None, x_hat is not None)
