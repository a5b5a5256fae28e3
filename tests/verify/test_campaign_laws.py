"""Campaign closed loops of the serialised-law artefacts (issue 7, section 4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact
from tanksynth.cli import main
from tanksynth.errors import ArtefactError
from tanksynth.sim.metrics import compute_metrics
from tanksynth.sim.scenarios import run_scenario, scenario
from tanksynth.sim.simulate import ConstantInput, run_seeds
from tanksynth.verify.campaign import campaign_tasks, run_campaign
from tanksynth.verify.laws.campaign import ArtefactIntegralLaw, ArtefactLaw, closed_loop_for

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def seed000(tmp_path_factory):
    d = tmp_path_factory.mktemp("seed000")
    assert main(["design", str(ROOT / "examples" / "seed000_feedback_linearization.toml"), "-o",
                 str(d)]) == 0
    docs = {doc["method"]: doc for doc in (read_artefact(p) for p in sorted(d.glob("*.json"))
                                           if p.name not in ("plant.json", "checks.json"))}
    return (d / "spec.toml").read_text(encoding="utf-8"), docs


def test_registered(runners):
    for method in ("feedback_linearization", "integral_tracking", "inverse_dynamics"):
        assert method in runners


def _final_errors(table, artefact):
    out = {}
    for key, value in table.summary().items():
        if key[0] == artefact and key[2].startswith("offset_"):
            out[key[1], key[2]] = abs(value)
    return out


def test_feedback_linearization_campaign_tracks(seed000, runners):
    text, docs = seed000
    doc = docs["feedback_linearization"]
    loop = closed_loop_for(doc, _spec(text), runners[doc['method']])
    assert isinstance(loop.controller, ArtefactLaw) and loop.tracked == (0, 1)
    assert "serialised CasADi law" in loop.description
    closed = run_campaign(campaign_tasks(text, [doc], ["servo"], runs=3, chunk=2, runners=runners),
                          local=True)
    assert {r["loop"] for r in closed.rows} == {loop.description}
    assert len({r["run"] for r in closed.rows}) == 3
    assert {r["kind"] for r in closed.rows} == {"controller"}
    # the same scenario in open loop at the operating input, by hand: the step is not followed
    spec = _spec(text)
    setup = scenario("servo").setup(spec.plant, loop.x_op, loop.u_op, loop.tracked, ts=float(spec.ts))
    opened = run_scenario(setup, spec.plant, ts=float(spec.ts), seeds=run_seeds(0, 3),
                          controller=ConstantInput(tuple(loop.u_op)), substeps=4)
    theirs = {("servo", k): float(np.mean(np.abs(m.values)))
              for k, m in compute_metrics(opened, setup, spec.plant).items() if k.startswith("offset_")}
    ours = _final_errors(closed, doc["name"])
    assert ours and set(ours) == set(theirs) == {("servo", "offset_h1"), ("servo", "offset_h2")}
    for key in ours:
        assert ours[key] < 1e-3, key  # the 0.04 m step is tracked
        assert theirs[key] > 0.02, key  # open loop does not follow it
    # per-run results do not depend on how runs are chunked (one batch vs several)
    again = run_campaign(campaign_tasks(text, [doc], ["servo"], runs=3, chunk=3, runners=runners), local=True)
    a, b = ({k: v for k, v in t.summary().items() if not k[2].endswith("_time") or "tracking" in k[2]}
            for t in (closed, again))
    assert a == pytest.approx(b, rel=1e-9, abs=1e-12)


def test_integral_tracking_campaign_stateful(seed000, runners):
    text, docs = seed000
    doc = docs["integral_tracking"]
    loop = closed_loop_for(doc, _spec(text), runners[doc['method']])
    assert isinstance(loop.controller, ArtefactIntegralLaw)
    law = loop.controller
    law.reset(4)
    assert law.z.shape == (4, 2) and not law.z.any()
    x = np.tile(loop.x_op, (4, 1))
    r = np.tile(loop.x_op[list(loop.tracked)], (4, 1))
    r[1] += 0.01
    u = law(x, r, 0.0)
    assert u.shape == (4, len(loop.u_op))
    assert np.allclose(u[0], loop.u_op) and not law.z[0].any() and law.z[1].any()
    table = run_campaign(campaign_tasks(text, [doc], ["servo"], runs=2, chunk=2, runners=runners), local=True)
    errors = _final_errors(table, doc["name"])
    assert errors and max(errors.values()) < 2e-3


def test_missing_law_is_refused(seed000, runners):
    text, docs = seed000
    doc = dict(docs["feedback_linearization"])
    doc["diagnostics"] = {k: v for k, v in doc["diagnostics"].items() if k != "law"}
    with pytest.raises(ArtefactError):
        closed_loop_for(doc, _spec(text), runners[doc['method']])


@pytest.mark.slow
def test_inverse_dynamics_campaign(tmp_path, runners):
    assert main(["design", str(ROOT / "examples" / "seed002_inverse_dynamics.toml"), "-o",
                 str(tmp_path)]) == 0
    docs = [read_artefact(p) for p in sorted(tmp_path.glob("*.json")) if p.name != "plant.json"]
    docs = [d for d in docs if d["method"] == "inverse_dynamics"]
    assert docs
    text = (tmp_path / "spec.toml").read_text(encoding="utf-8")
    loop = closed_loop_for(docs[0], _spec(text), runners[docs[0]['method']])
    assert isinstance(loop.controller, ArtefactLaw) and len(loop.tracked) == len(loop.u_op)
    table = run_campaign(campaign_tasks(text, docs[:1], ["servo"], runs=2, chunk=2, runners=runners),
                         local=True)
    errors = _final_errors(table, docs[0]["name"])
    assert errors and max(errors.values()) < 5e-3


def _spec(text):
    from tanksynth.methods import parse_spec_text

    return parse_spec_text(text.encode("utf-8"), source="<test>")


@pytest.mark.parametrize("method", ["integral_tracking", "feedback_linearization"])
def test_campaign_runs_through_the_closed_loop_kernel(seed000, runners, method, tmp_path,
                                                      monkeypatch):
    """A task's runs through the closed-loop kernel give the loop's metrics (the plant, the
    noise, the faults and jumps of every scenario of the plant), the computation time aside."""
    from tanksynth.sim import closed_loop, tape
    from tanksynth.sim.scenarios import SCENARIOS
    from tanksynth.verify.campaign import run_task

    text, docs = seed000
    plant = _spec(text).plant
    names = [s for s in SCENARIOS if SCENARIOS[s].applies_to(plant)]
    tasks = campaign_tasks(text, [docs[method]], names, runs=9, chunk=9, runners=runners)
    monkeypatch.setenv("TANKSYNTH_CACHE_DIR", str(tmp_path))
    tape.clear_cache()
    closed_loop.clear_cache()
    rows = {}
    for backend in ("native", "numpy"):
        monkeypatch.setenv("TANKSYNTH_SIM_BACKEND", backend)
        rows[backend] = {(r["scenario"], r["run"], r["metric"]): r["value"]
                         for task in tasks for r in run_task(task)
                         if r["metric"] != "controller_time"}
    assert closed_loop.cache_info()["loaded"] >= 1           # the kernel ran
    assert rows["native"].keys() == rows["numpy"].keys()
    for key, value in rows["numpy"].items():
        assert rows["native"][key] == pytest.approx(value, rel=1e-12, abs=1e-15), key
    tape.clear_cache()
    closed_loop.clear_cache()
