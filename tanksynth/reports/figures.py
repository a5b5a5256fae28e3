"""Report figures (matplotlib, vector PDF): pole maps of the artefacts' eigenvalues.

Eigenvalue lists are found in an artefact's diagnostics by name (any key
containing ``eigenvalues``, at any depth, in the ``[re, im]`` pair
convention of `tanksynth.artefact.to_jsonable`). Discrete-time sets (keys
naming ``Ad``, or diagnostics declaring a discrete domain) are drawn in the
z-plane with the unit circle, continuous ones in the s-plane with the
imaginary axis. Time-domain figures arrive with the simulator.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np

__all__ = ["EigenvalueSet", "eigenvalue_sets", "is_pole_key", "FigureFile", "pole_map"]

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
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fig.savefig(fh, format="pdf", metadata={"CreationDate": None, "Creator": "tanksynth"})
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


_MARKERS = ("x", "o", "s", "^", "D", "v", "P", "*")


def pole_map(artefact: Mapping[str, Any], directory: Path, stem: str) -> FigureFile | None:
    """Draw the eigenvalues of one artefact (s- and/or z-plane) to ``directory/stem.pdf``.

    Parameters
    ----------
    artefact : mapping
        As read by `tanksynth.artefact.read_artefact`.
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
    import matplotlib

    matplotlib.use("Agg", force=False)
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
