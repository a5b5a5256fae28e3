"""The panel of a trace's named signals: residual solid, threshold dashed, the fault onset marked."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts.traces import read_trace, trace_path, write_trace
from tanksynth.cli import main
from tanksynth.reports.figure_layout import TraceCanvas
from tanksynth.reports.figures import time_domain_figure
from tanksynth.reports.signal_panel import LOG_DECADES

ROOT = Path(__file__).resolve().parents[2]


def _signal_trace(directory: Path, name: str, *, decades: float, runs: int = 2, samples: int = 3001,
                  signals: bool = True) -> dict:
    """A hand-made observer trace (3 levels, 1 input) with a residual and a threshold decaying over
    ``decades`` decades, the fault at t = 2 s."""
    t = np.linspace(0.0, 5.0, samples)
    x = np.stack([np.column_stack([1.0 + 0.1 * r + 0.0 * t, 2.0 + np.sin(t), 3.0 - 0.1 * t]) for r in range(runs)])
    rate = decades * np.log(10.0) / 5.0
    threshold = 10.0 * np.exp(-rate * t)
    residual = np.stack([0.5 * threshold * (1 + 0.1 * r) + np.where(t >= 2.0, 1e-2 * 10.0 ** -decades * 50, 0.0)
                         for r in range(runs)])
    arrays = {"t": t, "x": x, "t_u": t[:-1], "u": np.ones((runs, samples - 1, 1)), "x_hat": x + 0.01 * np.exp(-t)[None, :, None]}
    header = {"artefact": name, "scenario": "hand-made fault", "check": "fault_detected", "check_passed": True,
              "verdict_passed": True, "runs": runs, "stride": 1, "state_names": ["x1", "x2", "x3"],
              "state_units": ["1"] * 3, "input_names": ["u"], "input_units": ["1"], "reference_names": []}
    if signals:
        arrays["signals"] = np.stack([residual, np.broadcast_to(threshold, residual.shape)], axis=-1)
        header.update({"signal_names": ["|epsilon|", "threshold"], "signal_units": ["1", "1"],
                       "signal_styles": ["-", "--"], "signal_title": "residual against its threshold",
                       "events": [[2.0, "fault at t_f = 2 s"], [99.0, "outside the horizon"]]})
    write_trace(directory / f"{name}.traces.npz", {"header": header, "arrays": arrays})
    return arrays


def _last_panel(tmp_path: Path, name: str, canvas: TraceCanvas):
    fig = time_domain_figure({"name": name, "method": "fault_detection"}, tmp_path, tmp_path / "figs", name,
                             canvas=canvas)
    assert fig is not None
    return fig, canvas.last.axes


def test_the_signal_panel_draws_residual_threshold_and_the_fault(tmp_path):
    arrays = _signal_trace(tmp_path, "fd", decades=8.0)
    fig, axes = _last_panel(tmp_path, "fd", TraceCanvas())
    assert len(axes) == 5       # levels, estimates, error, inputs, signals
    ax = axes[-1]
    assert ax.get_title() == "residual against its threshold"
    assert ax.get_ylabel() == "|epsilon|, threshold [1]" and ax.get_yscale() == "log"
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    # the event outside the horizon is not drawn; the runs are named (the residual differs per run)
    assert legend == ["|epsilon|", "threshold", "fault at t_f = 2 s", "run 1", "run 2"]
    coll = ax.collections[0]
    segs = coll.get_segments()
    assert len(segs) == 3        # residual run 1, residual run 2, threshold once (equal in both runs)
    dashes = [d for _, d in coll.get_linestyles()]
    assert dashes[0] is None and dashes[1] and dashes[2]          # residual solid (run 2 dashed), threshold dashed
    assert [str(h.get_linestyle()) for h in ax.get_legend().legend_handles[:3]] == ["-", "--", ":"]
    np.testing.assert_allclose(segs[0][[0, -1], 1], arrays["signals"][0, [0, -1], 0])
    np.testing.assert_allclose(segs[1][[0, -1], 1], arrays["signals"][1, [0, -1], 0])
    np.testing.assert_allclose(segs[2][[0, -1], 1], arrays["signals"][0, [0, -1], 1])
    marks = [ln for ln in ax.lines if np.allclose(ln.get_xdata(), 2.0)]
    assert len(marks) == 1 and marks[0].get_linestyle() == ":"
    lo, hi = ax.get_ylim()
    assert lo <= arrays["signals"][..., 1].min() and hi >= arrays["signals"].max()
    assert fig.path.read_bytes().startswith(b"%PDF")


@pytest.mark.slow
def test_a_narrow_range_is_linear_and_a_reused_canvas_draws_the_fresh_figure(tmp_path):
    _signal_trace(tmp_path, "single", decades=0.5 * LOG_DECADES, runs=1)
    _, axes = _last_panel(tmp_path, "single", TraceCanvas())
    assert axes[-1].get_yscale() == "linear"
    legend = [t.get_text() for t in axes[-1].get_legend().get_texts()]
    assert legend == ["|epsilon|", "threshold", "fault at t_f = 2 s"]      # one run: no run entries
    # signals over few and many decades: the signal panel switches scale on a reused canvas and back
    # and reads as on a fresh one. (Its PDF bytes are not compared: a five-panel figure drawn on a
    # reused canvas differs from a fresh one in the last bits of the error panel's limits, as it did
    # before signals existed, e.g. with a disturbance panel.)
    _signal_trace(tmp_path, "narrow", decades=0.5 * LOG_DECADES)
    _signal_trace(tmp_path, "wide", decades=10.0)
    _signal_trace(tmp_path, "plain", decades=10.0, signals=False)

    def panel(canvas: TraceCanvas) -> tuple:
        ax = canvas.last.axes[-1]
        return (ax.get_yscale(), ax.get_ylim(), tuple(ax.yaxis.get_major_locator()()), ax.get_title(),
                [t.get_text() for t in ax.get_legend().get_texts()],
                [seg.tobytes() for seg in ax.collections[0].get_segments()])

    canvas = TraceCanvas()
    for name, scale in (("wide", "log"), ("narrow", "linear"), ("wide", "log"), ("plain", "linear")):
        time_domain_figure({"name": name, "method": "m"}, tmp_path, tmp_path / "reused", name, canvas=canvas)
        reused = panel(canvas)
        fresh_canvas = TraceCanvas()
        time_domain_figure({"name": name, "method": "m"}, tmp_path, tmp_path / "fresh", name, canvas=fresh_canvas)
        assert reused == panel(fresh_canvas) and reused[0] == scale, name


def test_the_log_panel_shows_only_ticks_inside_its_limits(tmp_path):
    from tanksynth.reports.figure_layout import visible_tick_labels

    _signal_trace(tmp_path, "fd", decades=11.0)
    _, axes = _last_panel(tmp_path, "fd", TraceCanvas())
    ax = axes[-1]
    lo, hi = ax.get_ylim()
    ticks = ax.yaxis.get_major_locator()()
    assert ticks.size >= 3 and np.all((ticks >= lo) & (ticks <= hi))
    assert len(visible_tick_labels(ax.yaxis)) == ticks.size


@pytest.mark.slow
def test_the_seed004_report_has_the_residual_figure(tmp_path):
    d = tmp_path / "s4"
    assert main(["run", str(ROOT / "examples" / "seed004_fault_detection.toml"), "-o", str(d), "--no-pdf"]) == 0
    name = "residual_fault_detector"
    tex = (d / "report.tex").read_text(encoding="utf-8")
    figures = sorted((d / "report-figures").glob(f"traces-*-{name.replace('_', '-')}.pdf"))
    assert len(figures) == 1 and f"report-figures/{figures[0].name}" in tex
    tr = read_trace(trace_path(d / f"{name}.json", name))
    canvas = TraceCanvas()
    art = {"name": name, "method": "fault_detection"}
    fig = time_domain_figure(art, d, tmp_path / "again", figures[0].stem, canvas=canvas)
    assert fig.path.read_bytes() == figures[0].read_bytes()      # the report's figure, drawn again
    ax = canvas.last.axes[-1]
    assert ax.get_title() == tr["header"]["signal_title"] and ax.get_yscale() == "log"
    assert "fault onset, 2 s" in [t.get_text() for t in ax.get_legend().get_texts()]   # no t_f markup
    # the panel draws the stored residual of run 1 (decimated for drawing: its extremes kept)
    seg = ax.collections[0].get_segments()[0]
    sig = tr["arrays"]["signals"]
    assert seg[:, 1].max() == pytest.approx(sig[0, :, 0].max())
    assert "Check Fault detected: pass" in fig.caption and "t_f = 2 s" in fig.caption


def test_signals_of_one_quantity_share_a_colour():
    """Measured and simulated outputs of one quantity are drawn in one colour, told apart by the
    line style (the fit's figure drew 'h1 measured' and 'h1 simulated' in two colours, on top of
    each other); distinct quantities (a residual and its threshold) keep distinct colours."""
    import matplotlib
    from matplotlib.colors import to_rgba
    from matplotlib.figure import Figure

    from tanksynth.reports.signal_panel import draw_signals

    matplotlib.use("Agg")
    t = np.linspace(0.0, 1.0, 11)
    sig = np.stack([np.sin(t), np.sin(t) + 0.01, np.cos(t), np.cos(t) - 0.01], axis=-1)[None]
    head = {"signal_names": ["h1 measured", "h1 simulated", "h2 measured", "h2 simulated"],
            "signal_units": ["m"] * 4, "signal_styles": ["-", "--", "-", "--"]}
    ax = Figure().add_subplot()
    lines, *_ = draw_signals(ax, t, sig, head, {}, label_size=8.0, title_size=9.0)
    colours = {}
    for handle, label in zip(lines.handles, lines.labels):
        rgba = handle.get_color()
        colours[label] = tuple(np.ravel(to_rgba(rgba[0] if np.ndim(rgba) == 2 else rgba)))
    assert colours["h1 measured"] == colours["h1 simulated"]
    assert colours["h2 measured"] == colours["h2 simulated"]
    assert colours["h1 measured"] != colours["h2 measured"]
