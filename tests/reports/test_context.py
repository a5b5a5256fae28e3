"""The report's time-domain figures of a verdict's extra traces (`tanksynth.reports.context`): the
H2 / H-infinity disturbance-step run drawn beside the main run, from the arrays the verdict
simulated; stale extra figures removed."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts.io import rehash
from tanksynth.artefacts.traces import TRACE_MAX_SAMPLES, read_trace, write_trace
from tanksynth.cli import main
from tanksynth.methods import METHODS, write_report
from tanksynth.reports.context import draw_trace_figures, trace_figures, trace_jobs
from tanksynth.reports.figures import TraceFigure
from tanksynth.reports.inputs import read_report_inputs

ROOT = Path(__file__).resolve().parents[2]
#: The designs of examples/three_tank_hinf.toml, in artefact (name) order.
DESIGNS = ("h2_controller", "h2_observer", "hinf_controller", "hinf_observer", "multiobjective_disk")


pytestmark = pytest.mark.slow   # every test uses a designed, verified and reported H-infinity example


@pytest.fixture(scope="module")
def hinf_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hinf") / "out"
    assert main(["run", str(ROOT / "examples" / "three_tank_hinf.toml"), "-o", str(d), "--no-pdf"]) == 0
    return d


def _subsection(tex: str, name: str) -> str:
    """The verification subsection of one design in report.tex."""
    escaped = name.replace("_", "\\_")
    head = r"\subsection{\texorpdfstring{\texttt{" + escaped + "}}"
    start = tex.index(head, tex.index(r"\section{Verification}"))
    nxt = tex.find(r"\subsection", start + 1)
    return tex[start:nxt if nxt > 0 else len(tex)]


def test_each_design_has_its_disturbance_step_figure(hinf_dir):
    tex = (hinf_dir / "report.tex").read_text(encoding="utf-8")
    for i, name in enumerate(DESIGNS):
        stem = f"traces-{i:02d}-{name.replace('_', '-')}"
        part = _subsection(tex, name)
        assert part.index(f"report-figures/{stem}.pdf}}") < part.index(f"report-figures/{stem}-1.pdf}}")
        captions = re.findall(r"\\caption\{(.*?)\}\\label\{(fig:time-[^}]*)\}", part)
        assert len(captions) == 2
        (main_cap, main_label), (extra_cap, extra_label) = captions
        assert main_cap.startswith("Verdict simulation") and extra_cap.startswith("Further verdict simulation")
        assert "Check Disturbance step: pass" in extra_cap   # the check in words, not its key
        assert "declared disturbances stepped to" in extra_cap and extra_label == main_label + "-1"
        pdf = hinf_dir / "report-figures" / f"{stem}-1.pdf"
        assert pdf.read_bytes().startswith(b"%PDF")
    assert "disturbance step), the first simulation of up to two of them" in tex


def test_the_figure_draws_what_the_verdict_simulated(hinf_dir, monkeypatch):
    """Run each verdict again with the simulator wrapped: the stored extra trace holds the
    disturbance step's runs (every stride-th sample), and the figure drawn from it is that check's."""
    import tanksynth.verify.synthesis.verdicts as synthesis
    from tanksynth.verify.runner import load_directory

    spec, docs = load_directory(hinf_dir, METHODS)
    real, runs = synthesis.simulate, []
    monkeypatch.setattr(synthesis, "simulate", lambda *a, **k: runs.append(real(*a, **k)) or runs[-1])
    figures = trace_figures(read_report_inputs(hinf_dir))
    for path, doc in docs:
        runs.clear()
        checks = {c.name: c for c in METHODS[doc["method"]].verdict(doc, spec)}
        (res,) = runs                                     # the disturbance step
        stored = read_trace(hinf_dir / f"{doc['name']}.traces.npz")
        (extra,) = stored["more"]
        stride = int(np.ceil(res.t.size / TRACE_MAX_SAMPLES))
        assert extra["header"]["stride"] == stride
        for key, sim in (("t", res.t), ("x", res.x[0]), ("u", res.u[0])):
            np.testing.assert_array_equal(np.squeeze(extra["arrays"][key]), sim[::stride])
        main_fig, step_fig = figures[doc["name"]]
        assert isinstance(step_fig, TraceFigure) and step_fig.check == "disturbance_step"
        assert step_fig.passed is checks["disturbance_step"].passed is True
        assert step_fig.path.name == main_fig.path.stem + "-1.pdf"
        assert step_fig.estimator is ("x_hat" in extra["arrays"])


def test_stale_extra_figures_are_removed_and_the_main_figure_is_unchanged(hinf_dir, tmp_path):
    d = Path(shutil.copytree(hinf_dir, tmp_path / "out"))
    figs = d / "report-figures"
    main_before = (figs / "traces-02-hinf-controller.pdf").read_bytes()
    trace = read_trace(d / "hinf_controller.traces.npz")
    write_trace(d / "hinf_controller.traces.npz", {"header": trace["header"], "arrays": trace["arrays"]})
    rehash(d / "hinf_controller.json")                         # recorded as verify would
    res = write_report(d)
    assert not (figs / "traces-02-hinf-controller-1.pdf").exists()
    assert (figs / "traces-02-hinf-controller.pdf").read_bytes() == main_before   # same figure, bytes
    assert (figs / "traces-03-hinf-observer-1.pdf").is_file()                    # the others stay
    tex = (d / "report.tex").read_text(encoding="utf-8")
    assert "traces-02-hinf-controller-1.pdf" not in tex and "traces-03-hinf-observer-1.pdf" in tex
    assert "traces-02-hinf-controller-1.pdf" not in {p.name for p in res.figures}
    (d / "hinf_observer.traces.npz").unlink()                   # no trace at all: no figure either
    write_report(d)
    assert not list(figs.glob("traces-03-*"))


def test_drawn_ahead_the_extras_come_with_their_artefact(hinf_dir, tmp_path):
    d = Path(shutil.copytree(hinf_dir, tmp_path / "out"))
    shutil.rmtree(d / "report-figures")
    inputs = read_report_inputs(d)
    jobs = trace_jobs(inputs)
    assert len(jobs) == len(DESIGNS)                          # one job per artefact, extras included
    stem, index = jobs[0]
    drawn = draw_trace_figures(inputs, [index])
    assert [f.path.stem for f in drawn[stem]] == [stem, f"{stem}-1"]
    assert {p.stem for p in (d / "report-figures").glob("*.pdf")} == {stem, f"{stem}-1"}
    # a lone figure given for a stem is read as that figure alone
    lone = trace_figures(inputs, {stem: drawn[stem][0]})
    assert [f.path.stem for f in lone[inputs.artefacts[index]["name"]]] == [stem]
    # None for an artefact that has a trace is not taken at its word: drawn here (drawn_usable)
    again = trace_figures(inputs, {stem: None})[inputs.artefacts[index]["name"]]
    assert [f.path.stem for f in again] == [stem, f"{stem}-1"]


def test_an_edited_trace_file_does_not_stop_the_report(hinf_dir, tmp_path):
    """Trace arrays edited between verify and report (strings, an estimate of the wrong shape, no
    runs): that figure is left out, the report is written (each of these crashed write_report)."""
    d = Path(shutil.copytree(hinf_dir, tmp_path / "out"))
    edits = {"hinf_controller": {"extra1.x": np.array("garbage")}, "h2_observer": {"x_hat": np.zeros((5, 3))},
             "hinf_observer": {"extra1.x_hat": np.zeros((1, 5))}, "h2_controller": {"x": None}}
    for name, edit in edits.items():
        path = d / f"{name}.traces.npz"
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        with open(path, "wb") as fh:
            np.savez_compressed(fh, **{**arrays, **{k: arrays[k][:0] if v is None else v   # no runs
                                                       for k, v in edit.items()}})
        rehash(d / f"{name}.json")     # recorded as it is (an unrecorded edit is refused, issue 31)
    write_report(d)
    tex = (d / "report.tex").read_text(encoding="utf-8")
    assert "traces-02-hinf-controller.pdf" in tex and "traces-02-hinf-controller-1.pdf" not in tex
    assert "traces-01-h2-observer" not in tex and "traces-00-h2-controller" not in tex
    assert "traces-03-hinf-observer.pdf" in tex and "traces-03-hinf-observer-1.pdf" not in tex
    assert "traces-04-multiobjective-disk-1.pdf" in tex
