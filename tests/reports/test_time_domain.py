"""Time-domain figures of the verdict simulations (issue 8, section 1)."""

from __future__ import annotations

import hashlib
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact
from tanksynth.artefacts.io import rehash
from tanksynth.cli import main
from tanksynth.reports.figures import time_domain_figure
from tanksynth.artefacts.traces import read_trace, trace_path

from reports_helpers import needs_latex

ROOT = Path(__file__).resolve().parents[2]


def _run(tmp: Path, *spec: str) -> Path:
    assert main(["run", *spec, "-o", str(tmp)]) == 0
    return tmp


def _check_trace(directory: Path, name: str, estimator: bool) -> dict:
    path = directory / f"{name}.traces.npz"
    assert path.is_file()
    assert trace_path(directory / f"{name}.json", name) == path
    trace = read_trace(path)
    assert trace is not None
    head, arr = trace["header"], trace["arrays"]
    assert head["artefact"] == name and head["scenario"] and head["check"]
    assert arr["t"].size <= 2000 and arr["x"].shape[1] == arr["t"].size
    assert 1 <= arr["x"].shape[0] <= 2
    assert ("x_hat" in arr) is estimator
    assert len(head["state_names"]) == arr["x"].shape[2]
    assert len(head["input_names"]) == arr["u"].shape[2]
    raw = json.loads((directory / f"{name}.json").read_text(encoding="utf-8"))
    # not part of the artefact JSON: only its sha256, in the verification (issue 31)
    assert "traces" not in json.dumps({k: v for k, v in raw.items() if k != "verification"})
    assert set(raw["verification"]) == {"passed", "checks", "traces_sha256"}
    assert raw["verification"]["traces_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    read_artefact(directory / f"{name}.json")  # provenance hash still valid
    return trace


@pytest.mark.slow
def test_linearisation_trace_and_figure(tmp_path):
    d = _run(tmp_path / "demo", str(ROOT / "examples" / "seed000_three_tank.toml"))
    _check_trace(d, "linear_model", estimator=False)
    tex = (d / "report.tex").read_text(encoding="utf-8")
    assert "report-figures/traces-00-linear-model.pdf" in tex
    assert (d / "report-figures" / "traces-00-linear-model.pdf").read_bytes().startswith(b"%PDF")
    assert "time-domain figures" in tex
    # the linearisation's figure is the linear model's prediction against the nonlinear response
    from tanksynth.artefacts.traces import read_trace, trace_path
    from tanksynth.reports import read_report_inputs
    from tanksynth.reports.figures import _linear_prediction

    art = read_report_inputs(d).by_method("linearize")[0]
    tr = read_trace(trace_path(d / "linear_model.json", "linear_model"))
    arr = tr["arrays"]
    lin = _linear_prediction(art, tr["header"], arr["t"], arr["x"], arr["u"])
    assert lin is not None
    assert lin["scale"] > 0                        # the perturbed run moves: no flat lines
    assert lin["gap"] < 0.05 * lin["scale"]        # first-order agreement near x0


@pytest.mark.slow
@needs_latex
def test_seed004_observer_trace_and_pdf(tmp_path):
    d = _run(tmp_path / "s4", str(ROOT / "examples" / "seed004_fault_detection.toml"))
    trace = _check_trace(d, "luenberger_canonical", estimator=True)
    assert trace["header"]["check"] == "observer_convergence"
    assert trace["header"]["check_passed"] is True
    tex = (d / "report.tex").read_text(encoding="utf-8")
    assert "traces-01-luenberger-canonical.pdf" in tex
    assert main(["report", str(d), "--pdf"]) == 0
    text = subprocess.run(["pdftotext", str(d / "report.pdf"), "-"], capture_output=True, text=True,
                          check=True).stdout
    assert "time-domain figures" in text
    assert "initial-state mismatch" in text and "Observer convergence" in text   # the check in words


@pytest.mark.slow
def test_missing_trace_means_no_figure(tmp_path):
    d = _run(tmp_path / "demo", str(ROOT / "examples" / "seed000_three_tank.toml"))
    (d / "linear_model.traces.npz").unlink()
    art = {"name": "linear_model", "method": "linearize"}
    assert time_domain_figure(art, d, d / "report-figures", "x") is None
    (d / "linear_model.traces.npz").write_bytes(b"not an npz")
    assert time_domain_figure(art, d, d / "report-figures", "x") is None
    assert main(["report", str(d)]) == 2          # not the trace verify wrote (traces_sha256)
    rehash(d / "linear_model.json")               # recorded as it is: unreadable, no figure
    assert main(["report", str(d)]) == 0
    tex = (d / "report.tex").read_text(encoding="utf-8")
    assert "traces-00-linear-model.pdf" not in tex
    assert not (d / "report-figures" / "traces-00-linear-model.pdf").exists()
    assert "no time-domain figure" in tex


def test_trace_decimated(tmp_path):
    from tanksynth.artefacts.traces import TRACE_MAX_SAMPLES, write_trace
    from tanksynth.verify.traces import TraceRecorder
    from tanksynth.plants import three_tank
    from tanksynth.sim.simulate import run_seeds, simulate

    plant = three_tank()
    x0 = np.array([0.4, 0.2, 0.3])
    res = simulate(plant, ts=0.5, steps=4500, x0=x0, seeds=run_seeds(0, 3), u_init=np.full(plant.m, 1e-5))
    rec = TraceRecorder()
    rec.record(res, plant, scenario="s", check="c")
    rec.record(res, plant, scenario="second", check="c2")  # the first simulation only
    tr = rec.trace
    assert tr["header"]["scenario"] == "s"
    assert tr["arrays"]["t"].size <= TRACE_MAX_SAMPLES and tr["arrays"]["x"].shape[0] == 2
    out = write_trace(tmp_path / "a.traces.npz", tr)
    back = read_trace(out)
    assert np.array_equal(back["arrays"]["x"], tr["arrays"]["x"])
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.slow
@needs_latex
def test_trace_figure_without_pole_map_reaches_pdf(tmp_path):
    """seed 002 inverse dynamics records no eigenvalues: the time-domain figure alone is typeset."""
    d = tmp_path / "s2"
    assert main(["run", str(ROOT / "examples" / "seed002_inverse_dynamics.toml"), "-o", str(d),
                 "--pdf"]) == 0
    _check_trace(d, "inverse_dynamics", estimator=False)
    assert not list((d / "report-figures").glob("poles-*.pdf"))
    text = subprocess.run(["pdftotext", str(d / "report.pdf"), "-"], capture_output=True, text=True,
                          check=True).stdout
    assert "Verdict simulation of design" in text and "servo scenario" in text


def _synthetic_trace(directory: Path, name: str, *, estimator: bool, n: int = 3, m: int = 2,
                     runs: int = 2, samples: int = 4001) -> dict:
    """A verdict trace written by hand: n levels (m), m inputs (m^3/s), ``runs`` runs."""
    from tanksynth.artefacts.traces import write_trace

    t = np.linspace(0.0, 400.0, samples)
    rng = np.random.default_rng(3)
    x = np.stack([[0.2 + 0.05 * i + 0.01 * r + 0.02 * np.exp(-t / (50.0 + 10 * i)) for i in range(n)]
                  for r in range(runs)]).transpose(0, 2, 1)
    u = 1e-5 * (3.0 + rng.standard_normal((runs, samples - 1, m)).cumsum(axis=1) * 1e-3)
    arrays = {"t": t, "x": x, "t_u": t[:-1], "u": u}
    if estimator:
        arrays["x_hat"] = x + 0.01 * np.exp(-t / 30.0)[None, :, None]
    header = {"artefact": name, "scenario": "a hand-made scenario", "check": "made_up_check",
              "check_passed": True, "verdict_passed": True, "runs": runs, "stride": 2,
              "state_names": [f"h{i + 1}" for i in range(n)], "state_units": ["m"] * n,
              "input_names": [f"q{j + 1}" for j in range(m)], "input_units": ["m^3/s"] * m,
              "reference_names": []}
    write_trace(directory / f"{name}.traces.npz", {"header": header, "arrays": arrays})
    return arrays


def test_time_domain_figure_content(tmp_path):
    """Every panel keeps its lines (one collection: first run, further runs), legend, title, units."""
    import shutil

    from tanksynth.reports.figure_layout import TraceCanvas

    arrays = _synthetic_trace(tmp_path, "obs", estimator=True)
    canvas = TraceCanvas()
    art = {"name": "obs", "method": "luenberger_observer"}
    fig = time_domain_figure(art, tmp_path, tmp_path / "figs", "traces-00-obs", canvas=canvas)
    assert fig is not None and fig.estimator and "2nd sample" in fig.caption
    axes = canvas.last.axes
    assert [a.get_title() for a in axes] == ["plant (nonlinear)", "estimates (dashed) against the true states",
                                             "estimation error", "inputs (zero-order hold)"]
    assert [a.get_ylabel() for a in axes] == ["states [m]", "state and estimate [m]", "estimate - state [m]",
                                              r"flow [l/s $= 10^{-3}\,$m$^3$/s]"]   # the text's m^3/s named
    assert axes[-1].get_xlabel() == "time t [s]"
    # lines per panel: levels and error: first run + further run per state; estimates: state and
    # estimate per state; inputs: first run + further run per input
    segs = [len(a.collections[0].get_segments()) for a in axes]
    assert [len(a.collections) for a in axes] == [1, 1, 1, 1] and segs == [6, 6, 6, 4]
    legends = [[t.get_text() for t in a.get_legend().get_texts()] for a in axes]
    # the unit is on the axis label; the two runs are named (run 1 solid, run 2 dashed) where drawn
    assert legends[0] == ["h1", "h2", "h3", "run 1", "run 2"] and legends[3] == ["q1", "q2", "run 1", "run 2"]
    assert legends[2] == ["h1", "h2", "h3", "run 1", "run 2"]
    assert legends[1] == ["h1", "h2", "h3", "estimate"]     # one entry for the dashed estimates
    styles = [str(h.get_linestyle()) for h in axes[0].get_legend().legend_handles]
    assert styles[-2:] == ["-", "--"]
    dashes = [d for _, d in axes[0].collections[0].get_linestyles()]   # (offset, dash pattern or None)
    assert all(d is None for d in dashes[::2]) and all(d for d in dashes[1::2])   # run 1 solid, run 2 dashed
    # the data shown: levels span the trace's range; flows shown in l/s (x 1e3)
    lo, hi = axes[0].dataLim.y0, axes[0].dataLim.y1
    assert lo == pytest.approx(arrays["x"].min()) and hi == pytest.approx(arrays["x"].max())
    assert axes[3].dataLim.y1 == pytest.approx(1e3 * arrays["u"].max())
    if shutil.which("pdftotext"):
        text = subprocess.run(["pdftotext", "-raw", str(fig.path), "-"], capture_output=True, text=True,
                              check=True).stdout
        text = " ".join(text.split())
        for words in ("plant (nonlinear)", "estimation error", "inputs (zero-order hold)", "time t [s]",
                      "estimate", "run 2", "q2"):     # horizontal texts (rotated ones split)
            assert words in text, words


def test_time_domain_text_reads_at_print_size_and_inputs_reach_the_horizon_end(tmp_path):
    """Scaled into the report (0.95 text width, at most 0.72 text height, template's geometry), the
    legend and tick labels print at 7 pt or more; the held inputs are drawn to the last state sample."""
    import re

    from tanksynth.reports.figure_layout import TraceCanvas

    arrays = _synthetic_trace(tmp_path, "obs", estimator=True, samples=41)
    canvas = TraceCanvas()
    time_domain_figure({"name": "obs", "method": "m"}, tmp_path, tmp_path / "figs", "t", canvas=canvas)
    fig = canvas.last
    template = (Path(__file__).parents[2] / "tanksynth/reports/templates/report.tex.j2").read_text()
    assert "a4paper" in template
    margin_cm = float(re.search(r"\\usepackage\[margin=([0-9.]+)cm\]\{geometry\}", template).group(1))
    text_w = (21.0 - 2 * margin_cm) / 2.54 * 72.0      # pt (1/72 in, as the figure's size)
    text_h = (29.7 - 2 * margin_cm) / 2.54 * 72.0
    w, h = (72.0 * v for v in fig.get_size_inches())
    scale = min(0.95 * text_w / w, 0.72 * text_h / h)
    for ax in fig.axes:
        legend_pt = ax.get_legend().get_texts()[0].get_fontsize()
        tick_pt = ax.yaxis.get_major_ticks()[0].label1.get_fontsize()
        assert legend_pt * scale >= 7.0 and tick_pt * scale >= 7.0, (legend_pt, tick_pt, scale)
    inputs = fig.axes[-1]
    assert inputs.get_title() == "inputs (zero-order hold)"
    assert inputs.dataLim.x1 == pytest.approx(arrays["t"][-1]) and arrays["t_u"][-1] < arrays["t"][-1]


@pytest.mark.slow
def test_reused_canvas_draws_the_same_pdf(tmp_path):
    """Figures drawn on a reused canvas are byte-identical to figures drawn on a fresh one."""
    from tanksynth.reports.figure_layout import TraceCanvas

    for k, (name, est) in enumerate([("a", True), ("b", False), ("c", True), ("d", False)]):
        _synthetic_trace(tmp_path, name, estimator=est, n=2 + k, runs=1 + k % 2, samples=500 + 900 * k)
    canvas = TraceCanvas()
    for name in "abcd":
        art = {"name": name, "method": "m"}
        reused = time_domain_figure(art, tmp_path, tmp_path / "reused", name, canvas=canvas)
        fresh = time_domain_figure(art, tmp_path, tmp_path / "fresh", name)
        assert reused.path.read_bytes() == fresh.path.read_bytes(), name


@pytest.mark.slow
def test_outputs_not_states_are_drawn_with_their_references_in_output_units(tmp_path):
    """Issue 30.1: y = kc h (V, kc = 0.5 V/cm) tracked on the quadruple tank: the references (V)
    are drawn beside the outputs on an axis in V, not on the levels' axis in cm."""
    from tanksynth.reports.figure_layout import TraceCanvas

    spec = ROOT / "examples" / "quadruple_tank_sensor_gain.toml"
    d = tmp_path / "q"
    assert main(["design", str(spec), "-o", str(d)]) == 0
    assert main(["verify", str(d)]) == 0
    canvas = TraceCanvas()
    art = read_artefact(d / "quadruple_servo.json")
    assert time_domain_figure(art, d, tmp_path / "figs", "servo", canvas=canvas) is not None
    trace = read_trace(d / "quadruple_servo.traces.npz")
    x, ref = trace["arrays"]["x"][0], trace["arrays"]["reference"]
    axes = {a.get_ylabel(): a for a in canvas.last.axes}
    assert set(axes) >= {"states [cm]", "outputs [V]"}
    # the levels' axis holds the levels only (cm) ...
    levels = axes["states [cm]"]
    assert (levels.dataLim.y0, levels.dataLim.y1) == pytest.approx((x.min(), x.max()))
    assert not [t.get_text() for t in levels.get_legend().get_texts() if t.get_text().startswith("ref")]
    # ... the outputs' axis the sensor voltages kc h1, kc h2 (independent of the stored y) and the
    # references, in the same units: every line within the union of both ranges
    kc = 0.5
    volts = kc * x[:, :2]
    out = axes["outputs [V]"]
    lo, hi = min(volts.min(), ref.min()), max(volts.max(), ref.max())
    assert (out.dataLim.y0, out.dataLim.y1) == pytest.approx((lo, hi), rel=1e-9)
    segments = out.collections[0].get_segments()
    drawn = np.concatenate([s[:, 1] for s in segments])
    assert drawn.min() == pytest.approx(lo) and drawn.max() == pytest.approx(hi)
    legend = [t.get_text() for t in out.get_legend().get_texts()]
    assert {"y1", "y2", "ref. y1", "ref. y2"} <= set(legend)
    # the set-points track within the servo tolerance: reference and output meet at the end (V)
    assert np.max(np.abs(volts[-1] - ref[-1])) < 0.02 * np.max(np.abs(ref[-1] - ref[0]))
