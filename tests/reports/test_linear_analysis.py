"""The report's linear analysis: which loops apply, the numbers against an independent derivation,
and the section in the PDF.

The three-tank pole placement (seed 000, integral servo, ZOH at ts = 1 s) is re-derived here
from the artefact's K and the plant record's continuous linearisation (ZOH by
scipy.signal.cont2discrete, augmented model written from its definition), and each channel's
phase margin is checked against python-control's own `stability_margins` (its FRD method, on a
grid chosen here) and a brute-force numpy crossover search.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.signal import cont2discrete

from reports_helpers import needs_latex
from tanksynth.cli import main
from tanksynth.reports.linear_analysis import linear_loops

_ROOT = Path(__file__).resolve().parents[2]


def _artefact(gains, passed=True, **diag):
    return {"name": "d", "method": "pole_placement", "gains": gains, "diagnostics": diag,
            "verification": {"passed": passed, "checks": []}}


_REC = {"plant": {"inputs": [{"name": "q1"}], "outputs": [{"name": "h1"}]}}


def test_loops_follow_the_gains_and_the_verdict():
    sf = _artefact({"F": [[-1.0]], "B": [[1.0]], "C": [[1.0]], "K": [[4.0]]})
    (loop,) = linear_loops(sf, _REC)
    assert loop.kind == "state feedback" and loop.ts is None and loop.channels == ("q1",)
    np.testing.assert_allclose(loop.step_A, [[-5.0]])
    assert linear_loops(_artefact(sf["gains"], passed=False), _REC) == ()      # trusted only if verified
    assert linear_loops({**sf, "verification": None}, _REC) == ()
    obs = _artefact({"Ad": [[0.9]], "Bd": [[1.0]], "C": [[2.0]], "L": [[0.2]]}, time_domain="discrete", ts=0.5)
    (loop,) = linear_loops(obs, _REC)
    assert loop.kind == "observer" and loop.ts == 0.5 and loop.channels == ("h1",)
    np.testing.assert_allclose(loop.step_A, [[0.9 - 0.4]])


def test_model_from_the_plant_record_when_the_artefact_has_none():
    rec = {**_REC, "ts": 2.0, "linearization": {"A": [[-0.5]], "B": [[1.0]], "C": [[1.0]]}}
    art = _artefact({"K": [[0.3]]}, time_domain="discrete", ts=2.0)
    (loop,) = linear_loops(art, rec)
    np.testing.assert_allclose(loop.A, [[np.exp(-1.0)]])                 # ZOH of -0.5 at 2 s
    np.testing.assert_allclose(loop.B_in, [[(1 - np.exp(-1.0)) / 0.5]])


@pytest.fixture(scope="module")
def seed000_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("lin-seed000")
    assert main(["run", str(_ROOT / "examples" / "seed000_pole_placement.toml"), "-o", str(d),
                 "--no-pdf"]) == 0
    return d


def _channel_reference(A, B, K, i, ts):
    """Phase margin (deg) and crossover (rad/s) of channel i, others closed, by brute force."""
    others = [j for j in range(B.shape[1]) if j != i]
    Ai = A - B[:, others] @ K[others, :]
    n = A.shape[0]

    def L(w):
        return (K[[i], :] @ np.linalg.solve(np.exp(1j * w * ts) * np.eye(n) - Ai, B[:, [i]]))[0, 0]

    w = np.logspace(-6, np.log10(np.pi / ts) - 1e-9, 20000)
    mag = np.array([abs(L(x)) for x in w]) - 1.0
    k = int(np.flatnonzero(np.sign(mag[:-1]) != np.sign(mag[1:]))[0])
    wc = brentq(lambda x: abs(L(x)) - 1.0, w[k], w[k + 1], xtol=1e-14)
    return 180.0 + np.degrees(np.angle(L(wc))), wc


@pytest.mark.slow
def test_three_tank_pole_placement_margins_independently(seed000_dir):
    import control

    art = json.loads((seed000_dir / "integral_pole_placement.json").read_text())
    rec = json.loads((seed000_dir / "plant.json").read_text())
    assert art["verification"]["passed"] is True
    ts = float(rec["ts"])
    lin = rec["linearization"]
    Ad, Bd, *_ = cont2discrete((np.array(lin["A"]), np.array(lin["B"]), np.array(lin["C"]),
                                np.array(lin["D"])), ts, method="zoh")
    C1 = np.array(art["diagnostics"]["integral"]["C1"])
    n, m, q = Ad.shape[0], Bd.shape[1], C1.shape[0]
    # x[k+1] = Ad x + Bd u, z[k+1] = z + r - C1 x: the augmented model from its definition
    Aa = np.block([[Ad, np.zeros((n, q))], [-C1, np.eye(q)]])
    Ba = np.vstack([Bd, np.zeros((q, m))])
    K = np.array(art["gains"]["K"])
    from tanksynth.reports.inputs import read_report_inputs
    inputs = read_report_inputs(seed000_dir)
    (loop,) = linear_loops(next(a for a in inputs.artefacts if a["name"] == "integral_pole_placement"),
                           inputs.plant)
    assert loop.kind == "integral servo" and loop.ts == ts
    np.testing.assert_allclose(loop.A, Aa, atol=1e-12)
    np.testing.assert_allclose(loop.B_in, Ba, rtol=1e-9, atol=1e-12)
    from tanksynth.analysis.linear_margins import loop_margins
    margins = loop_margins(loop.A, loop.B_in, loop.C_out, loop.ts)
    for i in range(m):
        others = [j for j in range(m) if j != i]
        sys = control.ss(Aa - Ba[:, others] @ K[others, :], Ba[:, [i]], K[[i], :], 0, ts)
        omega = np.logspace(-5, np.log10(np.pi / ts) - 1e-6, 5000)
        _, pm, _, _, wgc, _ = control.stability_margins(control.frd(sys, omega, smooth=True), method="frd")
        pm_ref, wc_ref = _channel_reference(Aa, Ba, K, i, ts)
        assert pm == pytest.approx(pm_ref, abs=1e-3)          # python-control agrees with brute force
        c = margins.channels[i]
        assert c.phase_margin_deg == pytest.approx(pm_ref, abs=1e-3)
        assert c.gain_crossover == pytest.approx(wc_ref, rel=1e-4)
        assert c.delay_margin_s == pytest.approx(np.radians(pm_ref) / wc_ref, rel=1e-4)
        assert c.phase_margin_deg >= margins.guaranteed_phase_deg
    # the return difference, independently: 1 / max over the grid of ||(I + L)^-1||
    S_peak = max(np.linalg.norm(np.linalg.inv(np.eye(m) + K @ np.linalg.solve(
        np.exp(1j * w * ts) * np.eye(n + q) - Aa, Ba)), 2) for w in np.linspace(1e-4, np.pi / ts, 4000))
    assert margins.min_return_difference == pytest.approx(1.0 / S_peak, rel=1e-4)
    tex = (seed000_dir / "report.tex").read_text()
    assert "Linear analysis" in tex and "linear-" in tex
    assert sorted(p.name for p in (seed000_dir / "report-figures").glob("linear-*.pdf")) == \
        ["linear-00-integral-lmi-disk.pdf", "linear-01-integral-pole-placement.pdf"]


@needs_latex
@pytest.mark.slow
def test_the_pdf_has_the_linear_analysis(example_pdfs):
    d = example_pdfs["seed000_pole_placement"]
    text = subprocess.run(["pdftotext", "-layout", str(d / "report.pdf"), "-"], check=True,
                          capture_output=True, text=True).stdout
    for words in ("Linear analysis", "Gain margin", "Phase margin", "Delay margin",
                  "return difference", "Bode magnitude", "step response"):
        assert words in text, words


def test_integral_servo_without_a_recorded_augmentation():
    """A robust integral design records only C1: z+ = z + ts (r - C1 x) closes Aa - Ba K."""
    K = [[0.5, 0.2]]
    art = _artefact({"Ad": [[0.9]], "Bd": [[1.0]], "C": [[1.0]], "K": K}, time_domain="discrete", ts=2.0,
                    integral={"tracked": ["h1"], "C1": [[1.0]]})
    (loop,) = linear_loops(art, _REC)
    assert loop.kind == "integral servo" and loop.step_outputs == ("h1",)
    Aa = np.array([[0.9, 0.0], [-2.0, 1.0]])
    np.testing.assert_allclose(loop.A, Aa)
    np.testing.assert_allclose(loop.step_A, Aa - np.array([[1.0], [0.0]]) @ np.array(K))
    np.testing.assert_allclose(loop.step_B, [[0.0], [2.0]])


def test_step_response_axis_in_the_outputs_units():
    """The step-response panel is labelled in the plant's output units (issue 30: it said
    "[output units]"); outputs of different units name their unit in the legend instead."""
    from tanksynth.reports.linear_analysis import step_axis_label

    rec = {"plant": {"inputs": [{"name": "q1", "unit": "m^3/s"}], "outputs": [{"name": "y1", "unit": "V"}],
                     "states": [{"name": "h1", "unit": "m"}]}}
    sf = _artefact({"F": [[-1.0]], "B": [[1.0]], "C": [[0.5]], "K": [[4.0]]})
    (loop,) = linear_loops(sf, rec)
    assert loop.step_units == ("V",)
    servo = _artefact({"Ad": [[0.9]], "Bd": [[1.0]], "C": [[1.0]], "K": [[0.5, 0.2]]}, time_domain="discrete",
                      ts=2.0, integral={"tracked": ["h1"], "C1": [[1.0]]})
    (loop,) = linear_loops(servo, rec)
    assert loop.step_units == ("m",)                      # a tracked state: the state's unit
    assert step_axis_label(("V", "V")) == "response [V]"
    assert step_axis_label(("V", "m")) == "response (units in the legend)"
    assert step_axis_label(("", "")) == "response"
