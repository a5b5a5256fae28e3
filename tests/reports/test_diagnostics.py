"""Reading an artefact's diagnostics by name (`tanksynth.reports.diagnostics`): typed values as
the designs write them, and an edited entry read as missing, never as an exception."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.reports.diagnostics.common import (entries, entry, integral_of, is_flag, is_json_number,
                                                  is_number, is_text, lmi_region_of, references_of, section)
from tanksynth.reports.diagnostics.fault import detections_of, fault_size_of, initial_states_of
from tanksynth.reports.diagnostics.laws import controlled_outputs_of
from tanksynth.reports.diagnostics.model import linearization_of
from tanksynth.reports.diagnostics.placement import design_poles_of, exact_placement_of, region_placement_of
from tanksynth.reports.diagnostics.robust import robustness_of
from tanksynth.reports.diagnostics.synthesis import synthesis_of
from tanksynth.reports.diagnostics.takagi_sugeno import (certified_region_of, pdc_design_of, setpoint_change_of,
                                                          ts_model_of)


def test_entries_are_read_by_type_and_kept_as_written():
    node = {"n": 3, "x": 0.5, "yes": True, "s": "text", "empty": "", "inf": "inf", "list": [1, "nan", None]}
    assert entry(node, "n", is_number) == 3 and isinstance(entry(node, "n", is_number), int)
    assert entry(node, "yes", is_number) is None          # JSON true is no number
    assert entry(node, "yes", is_flag) is True and entry(node, "x", is_flag) is None
    assert entry(node, "s", is_text) == "text" and entry(node, "empty", is_text) is None
    assert entry(node, "inf", is_json_number) == "inf" and entry(node, "s", is_json_number) is None
    assert entries(node, "list", is_json_number) == (1, "nan", None)
    assert entries(node, "list", is_number) is None and entries(node, "missing", is_number) is None
    assert entry("not a mapping", "n", is_number) is None and section(node, "n") == {}


def test_linearization_and_equilibrium():
    lin = linearization_of({"eigenvalues_F": [[-0.01, 0.0], [-0.02, 0.003]], "ts": 5, "smooth_form_valid": True,
                            "equilibrium": {"residual": [0.0, 1e-12], "max_abs_residual": 1e-12,
                                            "is_equilibrium": True, "given_u0": [1e-4, 2e-4]}})
    assert lin.eigenvalues_F == ((-0.01, 0.0), (-0.02, 0.003)) and lin.eigenvalues_Ad is None
    assert lin.ts == 5 and lin.smooth_form_valid is True
    assert lin.equilibrium.residual == (0.0, 1e-12) and lin.equilibrium.given_u0 == (1e-4, 2e-4)
    assert lin.equilibrium.given_u0_balances is None
    edited = linearization_of({"eigenvalues_F": [[1, 2, 3]], "ts": "5", "equilibrium": [1, 2]})
    assert edited.eigenvalues_F is None and edited.ts is None and edited.equilibrium.residual is None


def test_placement_records():
    exact = exact_placement_of({"placement": {"kind": "observer_canonical", "method": "acker",
                                              "requested": [-1.0, [-2.0, 0.5]]}})
    assert exact.observer and exact.method == "acker" and exact.requested == ((-1.0, 0.0), (-2.0, 0.5))
    assert not exact_placement_of({}).observer and exact_placement_of({"placement": 3}).requested is None
    region = region_placement_of({"lmi": {"region": {"description": "|z| < 0.9"}, "margin": 1e-6}})
    assert region.region == "|z| < 0.9" and region.margin == 1e-6 and region.domain is None
    assert design_poles_of({"achieved_poles": [[0.0, 2.0], -1]}) == (2j, -1 + 0j)
    assert design_poles_of({"placement": {"requested": ["x"]}, "poles": [0.5]}) == (0.5 + 0j,)


def test_lmi_region_is_found_where_the_design_put_it():
    diag = {"time_domain": "discrete",
            "robust": {"region": {"L": [[-0.5]], "M": [[1.0]], "description": "Re z < 0.5"}}}
    region = lmi_region_of(diag)
    assert region is not None and region.domain == "discrete" and region.description == "Re z < 0.5"
    assert region.L.shape == (1, 1) and region.M[0, 0] == 1.0
    assert lmi_region_of({"region": {"L": [[1.0, 0.0]], "M": [[1.0, 0.0]]}}) is None   # not square
    assert lmi_region_of({"region": {"L": "x", "M": [[1.0]]}}) is None


def test_references_keep_what_the_comparison_needs():
    diag = {"reference_gain": {"reference": [[1.0, 2.0]], "derived": [[1.0, 2.1]],
                               "reference_eigenvalues": [[-1.0, 0.5], [-1.0, -0.5]],
                               "reference_max_pole_error": 0.01, "note": "not unique"},
            "reference_bad": {"reference": "x", "derived": [1.0]}, "reference_none": 3}
    (ref,) = references_of(diag)
    assert ref.label == "gain" and ref.reference.shape == (1, 2) and ref.note == "not unique"
    assert ref.eigenvalues == (((-1.0, 0.5), (-1.0, -0.5)),) and ref.max_pole_error == 0.01


def test_takagi_sugeno_records():
    diag = {"relaxation": "tuan", "decay_rate": 0.01, "composite": {"beta": 2.0}, "premises": "measured",
            "region": {"c": 1, "states": ["h1", "h2"], "extents": [0.1, "inf"], "binding": "face 1"},
            "setpoint": {"x_op2": [0.4, 0.3], "switch_level": 0.5, "region": {"c": 0.9}},
            "ts_model": {"r": 4, "domain": {"lower": [0.0, 0.0], "upper": [1.0, 1.0],
                                            "inequalities": [{"G": [1.0, -1.0], "g": 0.0}, {"G": "x"}]}}}
    design = pdc_design_of(diag)
    assert design.relaxation == "tuan" and design.composite and design.composite_beta == 2.0
    region = certified_region_of(diag)
    assert region.c == 1 and region.states == ("h1", "h2") and region.extents == (0.1, "inf")
    change = setpoint_change_of(diag)
    assert change is not None and change.x_op2 == (0.4, 0.3) and change.region_c == 0.9
    model = ts_model_of(diag)
    assert model.vertices == 4 and model.domain.lower == (0.0, 0.0)
    assert [q.G for q in model.domain.inequalities] == [(1.0, -1.0)]
    assert setpoint_change_of({"setpoint": {"x_op2": [0.4], "switch_level": "half"}}) is None
    assert ts_model_of({"ts_model": {"r": True}}).vertices is None


def test_robustness_record():
    robust = robustness_of({"uncertain": [["a", 1e-5, 2e-5], ["broken"]],
                            "vertex_models": {"balanced": [True, False, "no"]},
                            "robust": {"hinf": {"gamma": 2.0, "imposed": False, "lyapunov_scale": 1.2}},
                            "hinf_channel": {"observer": False, "given": ["Bw"]},
                            "saturation": {"ellipsoid_axes": {"lengths": [0.1, 0.2]}}})
    assert [(u.name, u.low, u.high) for u in robust.uncertain] == [("a", 1e-5, 2e-5)]
    assert robust.balanced == (True, False)
    assert robust.hinf is not None and robust.hinf.imposed is False and robust.hinf.lyapunov_scale == 1.2
    assert robust.channel is not None and robust.channel.given == frozenset({"Bw"})
    assert robust.saturation and robust.ellipsoid_axes == (0.1, 0.2)
    empty = robustness_of({"robust": {"hinf": {"gamma": None}}, "hinf_channel": {"given": ["Bw"]}})
    assert empty.hinf is None and empty.channel is None and not empty.saturation


def test_synthesis_record():
    syn = synthesis_of({"target": "observer", "route": "riccati",
                        "synthesis": {"gamma": 2.5, "achieved_hinf": [2.4, 2.6], "achieved_h2": ["x"],
                                      "scaling": {"backoff": 0.1}}})
    assert syn.observer and syn.route == "riccati" and syn.gamma == 2.5 and syn.achieved_hinf == 2.4
    assert syn.achieved_h2 is None and syn.backoff == 0.1 and syn.objective == "hinf"
    assert synthesis_of({"synthesis": {"objective": None}}).objective is None


def test_fault_detections_and_laws():
    records = {"detection": [{"x0": [0.1, 0.2], "t_detect": 2.5}, {"x0": [0.3, 0.4], "t_detect": -1},
                             {"x0": "bad"}], "delta_bar": 0.2}
    found = detections_of(records)
    assert [t for _, t in found] == [2.5, None] and np.allclose(found[0][0], [0.1, 0.2])
    assert fault_size_of(records) == 0.2 and fault_size_of({"detection": {"delta_bar": 1}}) == 1.0
    assert initial_states_of({"starts": [[0.1]]}) == [[0.1]] and initial_states_of({"starts": 3}) is None
    assert integral_of({"integral": {"tracked": ["h1"]}}).tracked == ("h1",)
    assert integral_of({"integral": ["h1"]}) is None
    assert controlled_outputs_of({"outputs": ["h1", "h2"]}) == ("h1", "h2")
    assert controlled_outputs_of({}) is None and controlled_outputs_of({"outputs": "h1"}) == ()


@pytest.mark.parametrize("garbage", [None, 3, "text", [1, 2], {"x": {}}])
def test_every_accessor_reads_garbage_as_missing(garbage):
    for key in ("equilibrium", "placement", "lmi", "region", "setpoint", "ts_model", "robust", "synthesis",
                "uncertain", "vertex_models", "hinf_channel", "saturation", "offsets", "composite",
                "observer", "integral", "detection", "outputs"):
        diag = {key: garbage}
        for read in (linearization_of, exact_placement_of, region_placement_of, design_poles_of, lmi_region_of,
                     references_of, pdc_design_of, certified_region_of, setpoint_change_of, ts_model_of,
                     robustness_of, synthesis_of, detections_of, fault_size_of, integral_of):
            read(diag)
