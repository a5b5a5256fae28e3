"""The report's linear analysis of a design: margins, step response and Bode magnitude.

Beside the nonlinear verdict a reviewer expects the classical linear picture
of the same loop. For every artefact whose verification passed (a gain is
trusted only through its verdict) and whose gains and model make a loop:

* state feedback ``u = -K x``: the loop broken at the plant input,
  ``L(s) = K (sI - A)^{-1} B``; the closed-loop step response to a unit step of
  an input disturbance (each input, outputs ``C x``);
* integral servo (``K`` on the augmented model of ``diagnostics.integral``):
  the same loop on the augmented model, and the step response of the tracked
  outputs to a unit step of each reference;
* observer with output injection ``L``: the loop broken at the injected output,
  ``L_o(s) = C (sI - A)^{-1} L``; the step response of the output estimation
  error ``C e`` of the error dynamics ``A - L C`` to a unit step of an unmeasured
  input disturbance (each input).

A discrete design is analysed in ``z`` with its sampling time. The model is
the artefact's own (gains ``F, B`` or ``Ad, Bd`` and ``C``, the naming rule of
`tanksynth.analysis.statespace.model_names`), else the plant record's
linearisation (zero-order hold at ``ts`` for a discrete design). Numbers come
from `tanksynth.analysis.linear_margins` at report time; nothing is stored in
the artefact.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.analysis.linear_margins import (LoopMargins, closed_loop_step, loop_frequency_response,
                                              loop_margins)
from tanksynth.analysis.statespace import model_names
from tanksynth.artefacts.atomic import atomic_write
from tanksynth.reports.figures import FigureFile, drawn_file_is, figure_stem
from tanksynth.reports.latex import Tex, escape_latex, format_number
from tanksynth.verify.numerics import integral_augmentation

__all__ = ["LinearLoop", "LinearAnalysisView", "linear_loops", "step_axis_label", "linear_analysis_view",
           "linear_analysis_views"]

_FIGURE_DIR = "report-figures"
#: Largest state dimension analysed (bounded work per artefact).
_MAX_STATES = 60


@dataclass(frozen=True)
class LinearLoop:
    """One loop of a design, ready for `tanksynth.analysis.linear_margins`.

    Attributes
    ----------
    kind : str
        ``"state feedback"``, ``"integral servo"`` or ``"observer"``.
    A, B_in, C_out : ndarray
        The loop ``C_out (sI - A)^{-1} B_in`` (plant units; 1/s or per sample).
    channels : tuple of str
        Channel names (inputs for a controller, outputs for an observer).
    step_A, step_B, step_C : ndarray
        The closed loop whose step response is drawn (state matrix, step input, observed output).
    step_inputs, step_outputs : tuple of str
        Names of the step inputs and of the outputs drawn.
    step_words : str
        What the step is, in words.
    ts : float or None
        Sampling time (s) of a discrete design.
    step_units : tuple of str
        Unit of each output drawn (the plant's output units; ``""`` where unknown).
    """

    kind: str
    A: np.ndarray
    B_in: np.ndarray
    C_out: np.ndarray
    channels: tuple[str, ...]
    step_A: np.ndarray
    step_B: np.ndarray
    step_C: np.ndarray
    step_inputs: tuple[str, ...]
    step_outputs: tuple[str, ...]
    step_words: str
    ts: float | None
    step_units: tuple[str, ...] = ()


@dataclass(frozen=True)
class LinearAnalysisView:
    """One design's linear analysis as the report shows it.

    Attributes
    ----------
    loops : tuple of LinearLoop
    margins : tuple of LoopMargins
        One per loop.
    rows : list of dict
        Table rows (Tex): loop, channel, gain margin, phase margin, delay margin, crossover.
    summary : list of Tex
        One sentence per loop: the return difference and the margins it guarantees.
    figure : FigureFile
        Step responses (top) and Bode magnitudes (bottom), one column per loop.
    """

    loops: tuple[LinearLoop, ...]
    margins: tuple[LoopMargins, ...]
    rows: list
    summary: list
    figure: FigureFile


def _names(rec: Mapping[str, Any], key: str, count: int, prefix: str) -> tuple[str, ...]:
    items = (rec.get("plant") or {}).get(key) or []
    names = [str(i.get("name", "")) for i in items if isinstance(i, Mapping)]
    return tuple(names) if len(names) == count else tuple(f"{prefix}{k + 1}" for k in range(count))


def _units(rec: Mapping[str, Any], key: str, count: int) -> tuple[str, ...]:
    items = (rec.get("plant") or {}).get(key) or []
    units = [str(i.get("unit", "")) for i in items if isinstance(i, Mapping)]
    return tuple(units) if len(units) == count else ("",) * count


def _unit_of(rec: Mapping[str, Any], name: str) -> str:
    """The unit of a plant state or output named ``name`` (``""`` when the record has none)."""
    for key in ("outputs", "states"):
        for item in (rec.get("plant") or {}).get(key) or []:
            if isinstance(item, Mapping) and item.get("name") == name:
                return str(item.get("unit", ""))
    return ""


def step_axis_label(units: Sequence[str]) -> str:
    """The y label of a step-response panel: ``response [m]`` when the outputs share a unit.

    Outputs of different units name their unit in the legend instead.

    Parameters
    ----------
    units : sequence of str
        Unit of each output drawn (``""`` where unknown).

    Returns
    -------
    str
    """
    shown = {u for u in units if u}
    if len(shown) == 1 and len(set(units)) == 1:
        return f"response [{shown.pop()}]"
    return "response (units in the legend)" if shown else "response"


def _matrix(v: Any) -> np.ndarray | None:
    if v is None:
        return None
    try:
        M = np.atleast_2d(np.asarray(v, dtype=float))
    except (TypeError, ValueError):
        return None
    return M if M.ndim == 2 and np.all(np.isfinite(M)) else None


def _zoh(A: np.ndarray, B: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    from scipy.linalg import expm
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n], aug[:n, n:] = A, B
    E = expm(aug * ts)
    return E[:n, :n], E[:n, n:]


def _model(art: Mapping[str, Any], rec: Mapping[str, Any], ts: float | None
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(A, B, C)`` of the design's time domain: the artefact's gains, else the plant record's."""
    gains = art.get("gains") or {}
    names = model_names("continuous" if ts is None else "discrete")
    A, B, C = (_matrix(gains.get(names[k])) for k in ("A", "B", "C"))
    lin = rec.get("linearization") or {}
    if A is None or B is None:
        A, B = _matrix(lin.get("A")), _matrix(lin.get("B"))
        if A is None or B is None or A.shape[0] != A.shape[1] or B.shape[0] != A.shape[0]:
            return None
        if ts is not None:
            A, B = _zoh(A, B, ts)
    if C is None:
        C = _matrix(lin.get("C"))
    n = A.shape[0]
    if A.shape != (n, n) or B.shape[0] != n or n > _MAX_STATES:
        return None
    if C is None or C.shape[1] != n:
        C = np.eye(n)
    return A, B, C


def linear_loops(art: Mapping[str, Any], rec: Mapping[str, Any]) -> tuple[LinearLoop, ...]:
    """The loops of an artefact that the linear analysis applies to (none when unverified).

    Parameters
    ----------
    art : mapping
        The artefact (gains as arrays or nested lists).
    rec : mapping
        The plant record (``plant.json``: names, linearisation, ``ts``).

    Returns
    -------
    tuple of LinearLoop
        Empty for a design that failed or has no verdict, or whose gains make no loop.
    """
    if (art.get("verification") or {}).get("passed") is not True:
        return ()
    diag = art.get("diagnostics") or {}
    gains = art.get("gains") or {}
    discrete = diag.get("time_domain") == "discrete" or (diag.get("form") == "discrete")
    ts_raw = diag.get("ts", rec.get("ts")) if discrete else None
    ts = float(ts_raw) if isinstance(ts_raw, (int, float)) and ts_raw > 0 else None
    if discrete and ts is None:
        return ()
    model = _model(art, rec, ts)
    if model is None:
        return ()
    A, B, C = model
    n, m = B.shape
    inputs = _names(rec, "inputs", m, "u")
    outputs = _names(rec, "outputs", C.shape[0], "y")
    output_units = _units(rec, "outputs", C.shape[0])
    out: list[LinearLoop] = []
    u_op = _matrix(gains.get("u_op", (rec.get("linearization") or {}).get("u0")))
    # disturbance steps of 10 % of the operating input (a unit step of 1 m^3/s means nothing for a
    # tank); a unit step where the operating input is unknown or zero
    if u_op is not None and u_op.size == m and np.all(u_op != 0):
        scale, step_words = 0.1 * np.abs(u_op.ravel()), "a step of 10 % of the operating input"
    else:
        scale, step_words = np.ones(m), "a unit step"
    K = _matrix(gains.get("K"))
    if K is not None and K.shape == (m, n):
        out.append(LinearLoop("state feedback", A, B, K, inputs, A - B @ K, B * scale, C, inputs, outputs,
                              f"{step_words} as an input disturbance at each plant input", ts, output_units))
    elif K is not None and K.shape[0] == m and K.shape[1] > n:
        found = diag.get("integral")
        integral: Mapping[str, Any] = found if isinstance(found, Mapping) else {}
        Aa, C1, Br = (_matrix(v) for v in (integral.get("augmented_A"), integral.get("C1"), gains.get("Br")))
        na = K.shape[1]
        if Aa is None and C1 is not None and C1.shape == (na - n, n):
            # no recorded augmentation: z' = r - C1 x, or z+ = z + ts (r - C1 x) (as the verdict builds it)
            Aa = integral_augmentation(A, B, C1, ts)[0]
            Br = np.vstack([np.zeros((n, na - n)), (ts or 1.0) * np.eye(na - n)])
        if Aa is not None and Aa.shape == (na, na) and C1 is not None and C1.shape[1] == n:
            Ba = np.vstack([B, np.zeros((na - n, m))])
            if Br is None or Br.shape[0] != na:
                Br = np.vstack([np.zeros((n, na - n)), np.eye(na - n)])
            Ca = np.hstack([C1, np.zeros((C1.shape[0], na - n))])
            tracked = [str(t) for t in integral.get("tracked") or []]
            tracked_names = tuple(tracked) if len(tracked) == C1.shape[0] else \
                tuple(f"y{k + 1}" for k in range(C1.shape[0]))
            tracked_units = tuple(_unit_of(rec, name) for name in tracked_names)
            out.append(LinearLoop("integral servo", Aa, Ba, K, inputs, Aa - Ba @ K, Br, Ca,
                                  tuple(f"{t} reference" for t in tracked_names)[:Br.shape[1]]
                                  if Br.shape[1] == len(tracked_names) else
                                  tuple(f"r{k + 1}" for k in range(Br.shape[1])),
                                  tracked_names, "a unit step of each reference", ts, tracked_units))
    Lg = _matrix(gains.get("L"))
    if Lg is not None and Lg.shape == (n, C.shape[0]):
        out.append(LinearLoop("observer", A, Lg, C, outputs, A - Lg @ C, B * scale, C, inputs,
                              tuple(f"{o} error" for o in outputs),
                              f"{step_words} as an unmeasured input disturbance at each plant input", ts,
                              output_units))
    return tuple(out)


def _m(v: float, digits: int = 4) -> Tex:
    return Tex("$" + format_number(v, digits) + "$")


def _inf(v: float, fmt: Any) -> Tex:
    return Tex(r"$\infty$") if not np.isfinite(v) else fmt(v)


def _rows(loop: LinearLoop, lm: LoopMargins) -> list[dict[str, Tex]]:
    rows = []
    for c in lm.channels:
        name = loop.channels[c.channel] if c.channel < len(loop.channels) else f"{c.channel + 1}"
        delay = _inf(c.delay_margin_s, lambda v: _m(v))
        if lm.ts is not None and np.isfinite(c.delay_margin_s):
            delay = Tex(delay + " (" + _m(c.delay_margin_s / lm.ts, 3) + " samples)")
        rows.append({
            "loop": escape_latex(loop.kind),
            "channel": Tex(r"\texttt{" + escape_latex(name) + "}"),
            "gm": _inf(c.gain_margin_db, lambda v: Tex(_m(v, 3) + " dB (" + _m(c.gain_margin, 3) + r"$\times$)")),
            "pm": _inf(c.phase_margin_deg, lambda v: Tex(_m(v, 4) + r"$^\circ$")),
            "dm": delay,
            "wc": _inf(c.gain_crossover, lambda v: _m(v, 4)) if np.isfinite(c.gain_crossover) else Tex("--"),
        })
    return rows


def _summary(loop: LinearLoop, lm: LoopMargins) -> Tex:
    where = "plant input" if loop.kind != "observer" else "injected output"
    lo, hi = lm.guaranteed_gain
    if not lm.closed_loop_stable:
        return Tex(escape_latex(loop.kind) + ": the linear closed loop is not stable; no margin applies.")
    hi_tex = r"\infty" if not np.isfinite(hi) else format_number(hi, 3)
    return Tex(escape_latex(loop.kind).capitalize() + f" (loop broken at the {where}): minimum singular "
               r"value of the return difference $\min_\omega \underline{\sigma}(I + L) = 1/\|S\|_\infty = "
               + format_number(lm.min_return_difference, 4) + "$, so every channel may take at once "
               r"an independent gain factor in $[" + format_number(lo, 3) + ",\\ " + hi_tex + r"]$ or a phase of $\pm"
               + format_number(lm.guaranteed_phase_deg, 3) + r"^\circ$ without losing stability.")


def _draw(loops: Sequence[LinearLoop], directory: Path, stem: str, name: str) -> FigureFile:
    from matplotlib.figure import Figure
    cols = len(loops)
    # constrained layout: axis labels never drawn over a neighbour's tick labels (values of
    # very different sizes make the tick labels of some panels wide)
    fig = Figure(figsize=(3.4 * cols + 0.6, 5.2), layout="constrained")
    for j, loop in enumerate(loops):
        step = closed_loop_step(loop.step_A, loop.step_B, loop.step_C, loop.ts)
        ax = fig.add_subplot(2, cols, j + 1)
        p, m = step.outputs.shape[:2]
        drawn = 0
        for i in range(p):
            for k in range(m):
                if drawn >= 12:
                    break
                y = step.outputs[i, k]
                label = (f"{loop.step_inputs[k] if k < len(loop.step_inputs) else k + 1} \u2192 "
                         f"{loop.step_outputs[i] if i < len(loop.step_outputs) else i + 1}")
                if len({*loop.step_units}) > 1 and i < len(loop.step_units) and loop.step_units[i]:
                    label += f" [{loop.step_units[i]}]"
                if loop.ts is None:
                    ax.plot(step.time, y, linewidth=1.0, label=label)
                else:
                    ax.step(step.time, y, where="post", linewidth=1.0, label=label)
                drawn += 1
        ax.set_title(f"{loop.kind}: step response", fontsize=8)
        ax.set_xlabel("time [s]", fontsize=8)
        ax.set_ylabel(step_axis_label(loop.step_units), fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(linewidth=0.3, color="0.85")
        ax.legend(fontsize=6, frameon=False)
        fr = loop_frequency_response(loop.A, loop.B_in, loop.C_out, loop.ts)
        bx = fig.add_subplot(2, cols, cols + j + 1)
        several = loop.B_in.shape[1] > 1
        for curve, sym, words in ((fr.loop, "L", "loop"), (fr.sensitivity, "S", "sensitivity"),
                                  (fr.complementary, "T", "complementary sensitivity")):
            bx.semilogx(fr.omega, 20.0 * np.log10(np.maximum(curve, 1e-300)), linewidth=1.0,
                        label=(f"max \u03c3({sym})" if several else f"|{sym}|") + f" {words}")
        bx.axhline(0.0, color="0.5", linewidth=0.6)
        bx.set_ylim(max(bx.get_ylim()[0], -120.0), bx.get_ylim()[1])
        bx.set_title(f"{loop.kind}: Bode magnitude" + (f" (z, ts = {loop.ts:g} s)" if loop.ts else ""),
                     fontsize=8)
        bx.set_xlabel("frequency [rad/s]", fontsize=8)
        bx.set_ylabel("magnitude [dB]", fontsize=8)
        bx.tick_params(labelsize=7)
        bx.grid(linewidth=0.3, color="0.85")
        bx.legend(fontsize=6, frameon=False)
    directory.mkdir(parents=True, exist_ok=True)
    target = directory / f"{stem}.pdf"
    atomic_write(target, lambda fh: fig.savefig(fh, format="pdf",
                                                 metadata={"CreationDate": None, "Creator": "tanksynth"}))
    kinds = " and ".join(lp.kind for lp in loops)
    domain = (f"discrete time (z, ts = {loops[0].ts:g} s; frequencies up to Nyquist)" if loops[0].ts
              else "continuous time")
    caption = (f"Linear analysis of design {name} ({kinds}, {domain}): step responses of the linear "
               "closed loop (top; " + "; ".join(lp.step_words for lp in loops) + ") and Bode magnitude "
               "of the loop L, the sensitivity S and the complementary sensitivity T (bottom; largest "
               "singular value for several channels).")
    return FigureFile(target, f"{directory.name}/{stem}.pdf", caption, ())


def linear_analysis_view(art: Mapping[str, Any], rec: Mapping[str, Any], directory: Path,
                         stem: str) -> LinearAnalysisView | None:
    """The linear analysis of one artefact, its figure drawn to ``directory/stem.pdf``.

    Parameters
    ----------
    art : mapping
        The artefact.
    rec : mapping
        The plant record.
    directory : Path
        Figure directory (created if missing).
    stem : str
        Figure file name without extension.

    Returns
    -------
    LinearAnalysisView or None
        None when no loop applies (`linear_loops`).
    """
    loops = linear_loops(art, rec)
    if not loops:
        return None
    margins = tuple(loop_margins(lp.A, lp.B_in, lp.C_out, lp.ts) for lp in loops)
    rows = [r for lp, lm in zip(loops, margins) for r in _rows(lp, lm)]
    summary = [_summary(lp, lm) for lp, lm in zip(loops, margins)]
    figure = _draw(loops, directory, stem, str(art.get("name", "")))
    return LinearAnalysisView(loops, margins, rows, summary, figure)


def linear_analysis_views(inputs: Any, drawn: Mapping[str, Any] | None = None
                          ) -> dict[str, LinearAnalysisView]:
    """The linear analysis of every artefact of a report that has one.

    Figures go to ``DIR/report-figures/linear-NN-<name>.pdf``; figures of
    artefacts that no longer have one are removed.

    Parameters
    ----------
    inputs : ReportInputs
        The report's inputs.
    drawn : mapping, optional
        Views computed ahead from these inputs (file stem ``linear-NN-<name>`` ->
        LinearAnalysisView, e.g. by another process): used when its figure is this
        directory's file of that stem; the others are computed here.

    Returns
    -------
    dict
        Artefact name -> LinearAnalysisView.
    """
    figdir = Path(inputs.directory) / _FIGURE_DIR
    drawn = drawn or {}
    out: dict[str, LinearAnalysisView] = {}
    for i, art in enumerate(inputs.artefacts):
        name = str(art.get("name", ""))
        stem = figure_stem("linear", i, name)
        view = drawn.get(stem)
        if not (isinstance(view, LinearAnalysisView) and drawn_file_is(view.figure, figdir / f"{stem}.pdf")):
            view = linear_analysis_view(art, inputs.plant, figdir, stem)
        if view is not None:
            out[name] = view
    if figdir.is_dir():
        keep = {v.figure.path.name for v in out.values()}
        for stale in figdir.glob("linear-*.pdf"):
            if stale.name not in keep:
                stale.unlink(missing_ok=True)
    return out
