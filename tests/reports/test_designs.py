"""The design section's view of one artefact (`tanksynth.reports.designs`)."""

from __future__ import annotations

from tanksynth.methods import STATEMENTS
from tanksynth.reports.designs import design_view


def _pole_placement_artefact() -> dict:
    # the diagnostics a pole placement records: the placement's own numbers, copied again by
    # its accuracy check and its robustness analysis (same keys, same values)
    err, cond, norm = 7.589e-12, 129.17227877763986, 0.0024707195603124793
    return {"name": "pp", "method": "pole_placement", "gains": {}, "diagnostics": {
        "placement": {"max_pole_error": err, "eigenvector_condition": cond, "gain_norm": norm,
                      "accuracy": {"max_pole_error": err, "passed": True}},
        "robustness": {"eigenvector_condition": cond, "gain_norm": norm,
                       "stability_radius": 0.0027}}}


def test_margins_show_each_quantity_once_with_the_plain_label():
    view = design_view(_pole_placement_artefact(), None, STATEMENTS)
    labels = [str(k) for k, _ in view.margins]
    assert labels == ["largest error of the placed poles", "norm of the gain",
                      "condition number of the closed-loop eigenvectors"]
    assert not any("robustness" in k or "accuracy" in k for k in labels)


def test_margins_keep_different_values_of_one_key():
    art = _pole_placement_artefact()
    art["diagnostics"]["robustness"]["gain_norm"] = 0.5  # a different gain: a different quantity
    labels = [str(k) for k, _ in design_view(art, None, STATEMENTS).margins]
    assert labels.count("norm of the gain") == 1 and "gain norm (robustness)" in labels
    assert len(labels) == 4


def test_lmi_gain_norm_duplicate_is_dropped():
    art = {"name": "lmi", "method": "lmi_placement", "gains": {}, "diagnostics": {
        "lmi": {"margin": 1e-6, "achieved_margin": 0.0131, "gain_norm": 0.00138},
        "robustness": {"gain_norm": 0.00138, "eigenvector_condition": 456.5}}}
    labels = [str(k) for k, _ in design_view(art, None, STATEMENTS).margins]
    assert sum("gain" in k for k in labels) == 1 and len(labels) == 4
    assert "norm of the gain" in labels      # the plain label, not "gain norm (robustness)"
    # the same diagnostics with the robustness record first: the same rows
    art["diagnostics"] = {"robustness": art["diagnostics"]["robustness"], "lmi": art["diagnostics"]["lmi"]}
    again = [str(k) for k, _ in design_view(art, None, STATEMENTS).margins]
    assert sorted(again) == sorted(labels)
